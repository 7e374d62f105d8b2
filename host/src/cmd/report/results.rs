//! The certificate's results (ISO/IEC 17025 §7.8.2.1 j, §7.8.4.1): the expanded uncertainty `U`
//! of the calibrated acceleration per axis, the model-4 coefficients under their IEEE Std 1293
//! names (bias K0, scale factor K1, input-axis misalignments δ) each with its expanded
//! uncertainty, and the uncertainty budget.
//!
//! The uncertainties come from the fit JSON's `uncertainty` (the combined 12 × 12 covariance of
//! the model-4 coefficients, `k`); a fit without one (test turns) gives its standard errors of
//! the fit's noise only, and the page says so.

use std::fmt::Write as _;

use accelcal_core::document::FitDoc;
use accelcal_core::uncertainty::UncertaintyJson;
use accelcal_shared::record::Record;

use super::esc;

use accelcal_core::ieee1293::{Parameters, G_N, MID_SCALE_CODES};

const AXES: [&str; 3] = ["x", "y", "z"];

/// The covariance of the model-4 coefficients of channels x, y, z × terms 1, ax, ay, az, and its
/// coverage factor: the budget's, else the fit's standard errors alone (diagonal, k = 2).
struct Cov {
    m: [[f64; 12]; 12],
    k: f64,
    from_budget: bool,
}

impl Cov {
    fn of(fit: &FitDoc, budget: Option<&UncertaintyJson>) -> Cov {
        let mut m = [[0.0; 12]; 12];
        if let Some(b) =
            budget.filter(|b| b.covariance.len() == 12 && b.covariance.iter().all(|r| r.len() == 12))
        {
            for (i, row) in b.covariance.iter().enumerate() {
                m[i].copy_from_slice(row);
            }
            return Cov { m, k: b.k, from_budget: true };
        }
        for c in 0..3 {
            let ch = fit.channels.get(c);
            for (t, term) in ["1", "ax", "ay", "az"].iter().enumerate() {
                let at = ch.and_then(|ch| ch.term_index(term));
                let se = at.and_then(|i| ch?.std_errors.get(i).copied().flatten()).unwrap_or(f64::NAN);
                m[4 * c + t][4 * c + t] = se * se;
            }
        }
        Cov { m, k: 2.0, from_budget: false }
    }

    /// The expanded uncertainty of `f` whose gradient over the 12 coefficients is `grad`
    /// (non-zero at the indices given).
    fn expanded(&self, grad: &[(usize, f64)]) -> f64 {
        let mut v = 0.0;
        for &(i, gi) in grad {
            for &(j, gj) in grad {
                v += gi * self.m[i][j] * gj;
            }
        }
        self.k * v.max(0.0).sqrt()
    }
}

/// `v ± U` as ILAC-P14 asks ([`crate::report::Ilac`]); the value alone, to four significant
/// digits, when U is not known.
pub fn stated(v: f64, u: f64, signed: bool) -> String {
    match crate::report::Ilac::of(v, u) {
        Some(r) => format!("{} &plusmn; {}", r.value(signed), r.u()),
        None if signed && v >= 0.0 => format!("+{}", crate::report::sig(v, 4)),
        None => crate::report::sig(v, 4),
    }
}

/// The results section: U per axis, the IEEE 1293 parameters with their U, the budget.
pub fn section(rec: &Record, fit: &FitDoc, budget: Option<&UncertaintyJson>) -> String {
    let cov = Cov::of(fit, budget);
    let mut h = String::new();
    let k = cov.k;
    match budget {
        Some(b) => {
            let _ = write!(
                h,
                "<h2>Results: expanded uncertainty U (k = {k}, about 95 % coverage) of the calibrated acceleration, the largest over the orientations at 1 g</h2><table><tr><th class=\"l\">axis</th>"
            );
            for a in AXES {
                let _ = write!(h, "<th>{a}</th>");
            }
            h.push_str("</tr><tr><td class=\"l\">U, m/s²</td>");
            for u in b.u_m_s2 {
                let _ = write!(h, "<td>{}</td>", crate::report::sig(u, 2));
            }
            h.push_str("</tr><tr><td class=\"l\">U, mg</td>");
            for u in b.u_m_s2 {
                let _ = write!(h, "<td>{}</td>", crate::report::sig(u / G_N * 1e3, 2));
            }
            h.push_str("</tr></table>");
        }
        None => h.push_str(
            "<h2>Results</h2><p>The expanded uncertainty of the calibrated acceleration is not evaluated: its budget is made for a \
             least-squares fit of model 4, and this record was fitted otherwise. The coefficients' uncertainties below are \
             those of the fit's noise alone (k = 2).</p>",
        ),
    }
    let _ = write!(
        h,
        "<table><tr><th class=\"l\">channel</th><th>bias K0, mg &plusmn; U</th><th>scale factor K1, codes/g &plusmn; U</th><th colspan=\"2\">input-axis misalignment δ, µrad &plusmn; U</th></tr>"
    );
    for c in 0..3.min(rec.n_channels as usize) {
        let row = &rec.coefficients[c];
        let (u0, kc) = (row[0], row[c + 1]);
        let (i0, ik) = (4 * c, 4 * c + c + 1);
        let b = u0 - MID_SCALE_CODES;
        let p = Parameters::of(c, [row[0], row[1], row[2], row[3]]);
        let (k0_mg, k1) = (p.k0_mg, p.k1_codes_per_g);
        let u_k0 = cov.expanded(&[(i0, 1.0 / kc), (ik, -b / (kc * kc))]) / G_N * 1e3;
        let u_k1 = cov.expanded(&[(ik, G_N)]);
        let _ = write!(
            h,
            "<tr><td class=\"l\">{}</td><td>{}</td><td>{}</td>",
            AXES[c],
            stated(k0_mg, u_k0, true),
            stated(k1, u_k1, false)
        );
        for j in (0..3).filter(|&j| j != c) {
            let kj = row[j + 1];
            let d = p.delta_urad[j];
            let u_d = cov.expanded(&[(4 * c + j + 1, 1.0 / kc), (ik, -kj / (kc * kc))]) * 1e6;
            let _ = write!(h, "<td>toward {}: {}</td>", AXES[j], stated(d, u_d, true));
        }
        h.push_str("</tr>");
    }
    h.push_str("</table>");
    let _ = write!(
        h,
        "<p class=\"small\">IEEE Std 1293 names for the record's model 4 (u = u0 + k·a per channel, codes): K1 = k along the \
         channel's own axis, per g (g<sub>n</sub> = {G_N} m/s²); K0 = (u0 − {MID_SCALE_CODES:.0}) / K1, the input at which the \
         output is the converter's mid-scale; δ = k toward another axis / k along its own. {}</p>",
        if cov.from_budget {
            "Their U comes from the budget's combined covariance."
        } else {
            "Their U comes from the fit's standard errors alone."
        }
    );
    if let Some(b) = budget {
        h.push_str(&budget_table(b));
    }
    h
}

/// The budget: each contributor's standard uncertainty of the calibrated acceleration and its
/// share of the combined variance, and what it leaves out.
fn budget_table(b: &UncertaintyJson) -> String {
    let mut h = String::from(
        "<table class=\"budget\"><tr><th class=\"l\">uncertainty contributor</th><th>type</th><th>u, m/s²</th><th>share</th><th class=\"l\">from</th></tr>",
    );
    for c in &b.contributors {
        let _ = write!(
            h,
            "<tr><td class=\"l\">{}</td><td>{}</td><td>{}</td><td>{:.1} %</td><td class=\"l\">{}</td></tr>",
            esc(&contributor_words(&c.name)),
            esc(&c.kind),
            crate::report::sig(c.u_m_s2, 2),
            100.0 * c.share,
            esc(&super::plain(&c.source))
        );
    }
    h.push_str("</table>");
    if !b.not_included.is_empty() {
        let words: Vec<String> = b.not_included.iter().map(|n| esc(&super::plain(n))).collect();
        let _ = write!(h, "<p class=\"small\">Not included in U: {}.</p>", words.join("; "));
    }
    h
}

/// A contributor's name in words.
fn contributor_words(name: &str) -> String {
    match name {
        "dwell_scatter" => "scatter of the dwell means (repeatability)".into(),
        "head_angle" => "dividing head: angle setting".into(),
        "head_orthogonality" => "dividing head: axis orthogonality".into(),
        "gravity" => "local gravity g".into(),
        "quantisation" => "ADC quantisation".into(),
        "temperature" => "temperature against the reference temperature".into(),
        "lack_of_fit" => "model 4's lack of fit (against the quadratic model)".into(),
        other => other.replace('_', " "),
    }
}
