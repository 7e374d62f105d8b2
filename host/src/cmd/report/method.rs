//! The certificate's method sections: the coefficients with their standard errors, the model
//! structure GMDH selected, the paper's Table 2 (LSQ against test turns) and its plot.

use std::fmt::Write as _;

use accelcal_core::calibrate::Method;
use accelcal_core::document::FitDoc;
use accelcal_shared::record::Record;

use super::{esc, label};
use crate::report::plot::lines_svg;

/// The record's coefficients with the standard errors of the fit that made them (the fit JSON).
pub(super) fn coefficients(rec: &Record, fit: &FitDoc, method: Method) -> anyhow::Result<String> {
    let mut h = String::new();
    let _ = write!(
        h,
        "<h2>Coefficients in force (record) &plusmn; standard error of the {} fit</h2><table><tr><th class=\"l\">channel</th>",
        label(method)
    );
    let terms: Vec<String> = rec.structure.terms().map(|t| t.to_string()).collect();
    for (i, t) in terms.iter().enumerate() {
        let head = match (i, t.as_str()) {
            (0, _) => "u0, codes".to_string(),
            (1, _) => "k·ax, codes/(m/s²)".to_string(),
            (2, _) => "k·ay".to_string(),
            (3, _) => "k·az".to_string(),
            (_, "t") => "t, codes/°C".to_string(),
            (_, "t^2") => "t², codes/°C²".to_string(),
            (_, name) => format!("{name}, codes/(m/s²)/°C"),
        };
        let _ = write!(h, "<th>{}</th>", esc(&head));
    }
    h.push_str("<th>residual RMS, codes</th></tr>");
    for (c, row) in rec.coefficients.iter().take(rec.n_channels as usize).enumerate() {
        let ch = fit.channels.get(c);
        let name = ch.map_or("?", |ch| ch.channel.as_str());
        let _ = write!(h, "<tr><td class=\"l\">{}</td>", esc(name));
        for (i, t) in terms.iter().enumerate() {
            let se = ch
                .and_then(|ch| ch.std_errors.get(ch.term_index(t)?).copied().flatten())
                .map_or("-".to_string(), |s| format!("{s:.4}"));
            let _ = write!(h, "<td>{:.4} &plusmn; {se}</td>", row[i]);
        }
        let rms = ch.and_then(|ch| ch.rms_codes).map_or("-".to_string(), |r| format!("{r:.2}"));
        let _ = write!(h, "<td>{rms}</td></tr>");
    }
    h.push_str("</table>");
    Ok(h)
}

/// A record coefficient of channel `c` and its standard error in the fit JSON (by term name).
fn coefficient(rec: &Record, fit: &FitDoc, c: usize, term: &str) -> (f64, Option<f64>) {
    let at = rec.structure.terms().position(|t| t.to_string() == term);
    let v = at.map_or(f64::NAN, |i| rec.coefficients[c][i]);
    let se = fit.channels.get(c).and_then(|ch| ch.std_errors.get(ch.term_index(term)?).copied().flatten());
    (v, se)
}

/// GMDH's choice per channel next to the record's structure, and why the record holds its terms
/// where GMDH chose others: the terms GMDH leaves out with their fitted values in standard errors,
/// the terms it adds that the node cannot apply.
pub(super) fn structure(sel: &[accelcal_core::gmdh::Selection], rec: &Record, fit: &FitDoc) -> String {
    let mut h = String::new();
    h.push_str("<h2>Model structure: GMDH (paper's 11 models, regularity criterion, 1-code tolerance) and the record</h2><table><tr><th class=\"l\">channel</th><th class=\"l\">GMDH selects</th><th>criterion, codes</th><th>best, codes</th><th class=\"l\">why</th><th>record's terms: criterion, codes</th></tr>");
    let mut notes = Vec::new();
    let record_terms: Vec<String> = rec.structure.terms().map(|t| t.to_string()).collect();
    for (c, s) in sel.iter().enumerate() {
        let chosen = s.selected();
        let best = s
            .candidates
            .iter()
            .filter(|c| c.criterion.is_some())
            .min_by(|a, b| a.criterion.partial_cmp(&b.criterion).expect("finite criteria"))
            .expect("a selection has an identifiable candidate");
        let why = if chosen.structure == best.structure {
            "the best candidate".to_string()
        } else {
            format!("simplest within 1 code of the best ({})", best.structure)
        };
        let record_crit =
            s.candidates.iter().find(|k| k.structure == rec.structure).and_then(|k| k.criterion);
        let _ = write!(
            h,
            "<tr><td class=\"l\">{}</td><td class=\"l\">{}</td><td>{:.2}</td><td>{:.2}</td><td class=\"l\">{}</td><td>{}</td></tr>",
            esc(&s.channel),
            chosen.structure,
            chosen.criterion.unwrap_or(f64::NAN),
            s.best,
            esc(&why),
            record_crit.map_or("-".to_string(), |v| format!("{v:.2}"))
        );
        if chosen.structure == rec.structure {
            continue;
        }
        let gmdh_terms: Vec<String> = chosen.structure.terms().map(|t| t.to_string()).collect();
        let mut parts = Vec::new();
        for t in record_terms.iter().filter(|t| !gmdh_terms.contains(t)) {
            let (v, se) = coefficient(rec, fit, c, t);
            parts.push(match se {
                Some(se) if se > 0.0 => format!(
                    "GMDH leaves out {t}; the record's {t} term is {v:.4} &plusmn; {se:.4} ({:.1} standard errors from zero)",
                    (v / se).abs()
                ),
                _ => format!("GMDH leaves out {t}; the record's {t} term is {v:.4}"),
            });
        }
        let added: Vec<&String> = gmdh_terms.iter().filter(|t| !record_terms.contains(t)).collect();
        if !added.is_empty() {
            parts.push(format!(
                "GMDH adds {}, which the node cannot apply: what they would explain is in the residual RMS above",
                added.iter().map(|t| t.as_str()).collect::<Vec<_>>().join(", ")
            ));
        }
        notes.push(format!(
            "{}: {}{}",
            esc(&s.channel),
            parts.join("; "),
            record_crit.map_or(String::new(), |r| format!(
                "; the record's terms score {r:.2} codes against GMDH's {:.2}",
                chosen.criterion.unwrap_or(f64::NAN)
            ))
        ));
    }
    h.push_str("</table>");
    let _ = write!(
        h,
        "<p class=\"small\">The record holds {} on every channel: the node applies one structure to the triad, model 4 \
         (the sensitivity matrix it inverts){}. {}</p>",
        rec.structure,
        if rec.structure.is_thermal() { " with its thermal terms" } else { "" },
        if notes.is_empty() {
            "GMDH selects the same terms.".to_string()
        } else {
            format!(
                "Where GMDH selects other terms: {}. The verification, not this table, shows whether the record meets \
                 its tolerance.",
                notes.join(". ")
            )
        }
    );
    h
}

/// The paper's Table 2 on held-out positions: the record's method and the other one, for
/// information.
pub(super) fn table2(
    cmp: Option<&accelcal_core::compare::Comparison>,
    method: Method,
) -> anyhow::Result<String> {
    let mut h = String::new();
    let Some(r) = cmp else {
        h.push_str("<h2>LSQ and test turns (Table 2)</h2><p class=\"small\">Not computed: the plan has no test-turn pairs.</p>");
        return Ok(h);
    };
    let other = match method {
        Method::Lsq => Method::TestTurns,
        Method::TestTurns => Method::Lsq,
    };
    let _ = write!(
        h,
        "<div class=\"cols\"><div><h2>For information, the paper's Table 2: {} (the record's method) and {}, each fitted on the other positions and scored on {} held-out ones, m/s²</h2><table><tr><th class=\"l\">channel</th><th>mean, {}</th><th>worst position</th><th>mean, {}</th><th>worst position</th><th>sample sd</th></tr>",
        label(method),
        label(other),
        r.validation_positions,
        label(method),
        label(other)
    );
    use accelcal_core::compare::{CompareChannel, ErrorStats};
    /// Each held-out position's mean error per channel, and a channel's Table 2 row, of a method.
    type Of<'a> = (&'a [(String, Vec<f64>)], fn(&CompareChannel) -> ErrorStats);
    fn per(r: &accelcal_core::compare::Comparison, m: Method) -> Of<'_> {
        match m {
            Method::Lsq => (&r.per_position.lsq, |c| c.lsq),
            Method::TestTurns => (&r.per_position.test_turns, |c| c.test_turns),
        }
    }
    let per = |m: Method| per(r, m);
    let worst = |m: Method, k: usize| {
        per(m).0.get(k).map_or(f64::NAN, |(_, ys)| ys.iter().fold(0.0f64, |w, y| w.max(y.abs())))
    };
    for (k, ch) in r.channels.iter().enumerate() {
        let _ = write!(
            h,
            "<tr><td class=\"l\">{}</td><td>{:+.5}</td><td>{:.5}</td><td>{:+.5}</td><td>{:.5}</td><td>{:.5}</td></tr>",
            esc(&ch.channel),
            per(method).1(ch).mean_error,
            worst(method, k),
            per(other).1(ch).mean_error,
            worst(other, k),
            per(method).1(ch).std_error
        );
    }
    h.push_str("</table>");
    h.push_str(
        "<p class=\"small\">Both methods refitted on the other positions and scored on these: mean, the \
         calibration's systematic error; worst position, the largest error of a held-out position's mean. \
         Sample sd is the scatter of single samples about the true acceleration, the sensor's noise \
         (the verification averages hundreds of sets): it is not a calibration error. Neither column is the \
         record's pass criterion; the verification is.</p></div><div>",
    );
    h.push_str(&fit_plot(Some(r))?);
    h.push_str("</div></div>");
    Ok(h)
}

/// The LSQ calibration's error per held-out position (Table 2's data), inline SVG.
fn fit_plot(cmp: Option<&accelcal_core::compare::Comparison>) -> anyhow::Result<String> {
    let Some(r) = cmp else { return Ok(String::new()) };
    let series: Vec<(String, Vec<(f64, f64)>)> = r
        .per_position
        .lsq
        .iter()
        .map(|(n, ys)| (n.clone(), ys.iter().enumerate().map(|(k, &y)| (k as f64 + 1.0, y)).collect()))
        .collect();
    lines_svg("LSQ: error per held-out position", "held-out position", "m/s²", &series, (640, 330))
}
