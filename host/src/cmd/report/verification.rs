//! The certificate's verifications (ISO/IEC 17025 §7.8.2.1, §7.8.6): the condition on receipt
//! (as found), the decision rule and conformity statement, and each verification's table of
//! positions and of the parameters its ±axis positions measure.

use std::fmt::Write as _;

use accelcal_line::verify::VerifyReport;

use super::{esc, plain};
use crate::report::plot::lines_svg;

/// The as-found verification: the record the unit came in with, its decision (against a
/// specification: out of tolerance stands out) and, against a specification, each position.
pub(super) fn as_found(v: &VerifyReport) -> String {
    let failed = v.positions.iter().filter(|p| !p.pass).count();
    let max = v.max_abs_error_m_s2();
    let crc = v.record["crc"].as_str().unwrap_or("(none)");
    let n = v.positions.len();
    let verdict = match v.decision {
        Some(d) if d.accepted() => {
            format!("<span class=\"pass\">PASS</span>: every one of {n} positions accepted by the decision rule")
        }
        Some(d) if d.out_of_tolerance() => format!(
            "<span class=\"fail\">OUT OF TOLERANCE ({})</span>: {failed} of {n} positions not accepted",
            d.name()
        ),
        Some(d) => format!(
            "<span class=\"fail\">{}</span>: {failed} of {n} positions within the limit but not by the guard band",
            d.name().to_uppercase()
        ),
        None if v.pass => {
            format!("<span class=\"pass\">PASS</span>: every one of {n} positions within its tolerance")
        }
        None => format!("<span class=\"fail\">FAIL</span>: {failed} of {n} positions outside tolerance"),
    };
    let rule = if v.specification.is_some() { "specification" } else { "pass" };
    let table = if v.specification.is_some() { position_table(v) } else { String::new() };
    format!(
        "<h2>As found (before recalibration), with the record in force then (CRC {})</h2><p>{verdict}; largest error {:.5} m/s²; {rule}: {}</p>{table}",
        esc(crc),
        max,
        esc(&plain(&v.tolerance_rule))
    )
}

/// The unit's condition on receipt: its as-found verification.
pub(super) fn receipt(v: Option<&VerifyReport>) -> String {
    let Some(v) = v else {
        return "no calibration record in force, or not verified as found".into();
    };
    let crc = v.record["crc"].as_str().unwrap_or("(none)");
    let max = v.max_abs_error_m_s2();
    let outcome = match v.decision {
        Some(d) if d.out_of_tolerance() => format!("OUT OF TOLERANCE ({})", d.name()),
        Some(d) => d.name().to_string(),
        None if v.pass => "within the consistency bound".into(),
        None => "outside the consistency bound".into(),
    };
    format!("verified as found with its record in force (CRC {crc}): {outcome}, largest error {max:.4} m/s²")
}

/// The decision rule and the statement of conformity it supports (ILAC-G8).
pub(super) fn decision_rule(v: Option<&VerifyReport>) -> String {
    match v.and_then(|v| v.specification.as_ref().map(|s| (v, s))) {
        Some((v, s)) => {
            let w = match s.guard_band_m_s2 {
                Some(w) => format!("guard band w = {w} m/s²"),
                None => "guard band w = U of each result".into(),
            };
            let rule = match s.rule {
                accelcal_core::conformity::RuleKind::Simple => "simple acceptance (ILAC-G8 §4.2.1): accepted when the error is within the limit".to_string(),
                accelcal_core::conformity::RuleKind::GuardBand => {
                    format!("guard band (ILAC-G8 §4.2.2): accepted when the error is within the limit less the guard band, {w}")
                }
            };
            let params = match s.describe_parameters() {
                p if p.is_empty() => String::new(),
                p => format!(" and {p} (from the ±axis positions; the guard band for these is U)"),
            };
            format!(
                "specification of {}: |error| ≤ T = {} m/s² on each component at each position{params}; {rule}; conformity: {}",
                s.unit_type,
                s.acceleration_error_m_s2,
                v.decision.map_or("-", |d| d.name())
            )
        }
        None => "no specification: the verification is a consistency check of the calibration, not a statement of conformity".into(),
    }
}

/// The temperature of a verification in words: the node's mean over the positions and their
/// range, and the chamber setpoint when one was set.
pub(super) fn verification_temperature(v: &VerifyReport) -> String {
    let temps: Vec<f64> = v.positions.iter().filter_map(|p| p.temp_c).collect();
    let chamber = v.chamber_c.map(|c| format!(", chamber set to {c} °C")).unwrap_or_default();
    if temps.is_empty() {
        return format!("temperature not reported by the node{chamber}");
    }
    let mean = temps.iter().sum::<f64>() / temps.len() as f64;
    let (lo, hi) = temps.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &t| (l.min(t), h.max(t)));
    format!("at {mean:.1} °C (the node's sensor, {lo:.1} to {hi:.1} °C over the positions{chamber})")
}

/// The verification: each position's error and tolerance per axis, and the plot.
pub(super) fn verification(v: &VerifyReport, temp: &str) -> anyhow::Result<String> {
    let mut h = String::new();
    let rule = if v.specification.is_some() { "Specification" } else { "Pass" };
    let _ = write!(
        h,
        "<h2>As left: verification on the head after flashing, {}: error of the calibrated output, m/s²</h2><p class=\"small\">{rule}: {}</p><div class=\"cols\"><div class=\"wide\">",
        esc(temp),
        esc(&plain(&v.tolerance_rule))
    );
    h.push_str(&position_table(v));
    h.push_str("</div><div>");
    let series: Vec<(String, Vec<(f64, f64)>)> = ["x", "y", "z"]
        .iter()
        .enumerate()
        .map(|(i, n)| {
            (format!("error {n}"), v.positions.iter().map(|p| (p.position as f64, p.error_m_s2[i])).collect())
        })
        .collect();
    h.push_str(&lines_svg("Verification error per position", "position", "m/s²", &series, (640, 330))?);
    h.push_str("</div></div>");
    Ok(h)
}

/// A verification's positions: error per axis and, against a specification, the expanded
/// uncertainty U of each and the decision; else the consistency bound.
fn position_table(v: &VerifyReport) -> String {
    let judged = v.specification.is_some();
    let bound = if judged { "U" } else { "tol." };
    let mut h = format!(
        "<table><tr><th>pos.</th><th>&alpha;, &beta; (deg)</th><th>error x</th><th>error y</th><th>error z</th><th>{bound} x</th><th>{bound} y</th><th>{bound} z</th><th></th></tr>"
    );
    for p in &v.positions {
        let e = p.error_m_s2;
        let t = p.u_expanded_m_s2.unwrap_or(p.tolerance_m_s2);
        let word = match p.decisions.and_then(|d| d.into_iter().max()) {
            Some(d) if d.accepted() => d.name().to_string(),
            Some(d) => d.name().to_uppercase(),
            None if p.pass => "pass".into(),
            None => "FAIL".into(),
        };
        let _ = write!(
            h,
            "<tr><td>{}</td><td>{}, {}</td><td>{:+.5}</td><td>{:+.5}</td><td>{:+.5}</td><td>{:.5}</td><td>{:.5}</td><td>{:.5}</td><td class=\"{}\">{}</td></tr>",
            p.position,
            p.alpha_deg,
            p.beta_deg,
            e[0],
            e[1],
            e[2],
            t[0],
            t[1],
            t[2],
            if p.pass { "pass" } else { "fail" },
            word
        );
    }
    h.push_str("</table>");
    h.push_str(&parameter_table(v));
    h
}

/// The triad's parameters a verification measured against the specification's limits, when it
/// limits them.
fn parameter_table(v: &VerifyReport) -> String {
    let Some(params) = v.parameters.as_ref().filter(|p| !p.is_empty()) else { return String::new() };
    let mut h = String::from(
        "<table><tr><th class=\"l\">parameter (from the ±axis positions)</th><th>axis</th><th>error</th><th>U</th><th>limit</th><th>decision</th></tr>",
    );
    for c in params {
        let word = if c.decision.accepted() {
            c.decision.name().to_string()
        } else {
            c.decision.name().to_uppercase()
        };
        // ILAC-P14: U to two significant digits, the value to U's last digit; each cell says its
        // unit, which differs from row to row.
        let unit = esc(&c.unit);
        let (value, u) = match crate::report::Ilac::of(c.value, c.u_expanded) {
            Some(r) => (r.value(true), r.u()),
            None => (format!("{:+}", c.value), format!("{}", c.u_expanded)),
        };
        let _ = write!(
            h,
            "<tr><td class=\"l\">{}</td><td>{}</td><td>{value} {unit}</td><td>{u} {unit}</td><td>{} {unit}</td><td class=\"{}\">{word}</td></tr>",
            esc(&c.parameter.replace('_', " ")),
            esc(&c.axis),
            c.limit,
            if c.decision.accepted() { "pass" } else { "fail" }
        );
    }
    h.push_str("</table>");
    h
}
