//! `accelcal history SERIAL|DEVICE`: a unit's runs from the calibration database, the drift
//! between its calibrations and the recommended recalibration date (`core::db::history`).

use accelcal_core::output::write_json;
use accelcal_db::history::{history, History, VerifySummary};
use accelcal_db::{Db, Outcome};
use anyhow::Context;

use super::record::utc;
use crate::report::sig;
use crate::settings::reader::History as HistorySettings;

/// Runs `accelcal history`.
pub fn run(a: &HistorySettings) -> anyhow::Result<()> {
    let spec = super::store::reader_spec(a.db.as_deref())?;
    let mut db = Db::open_existing(&spec)?.listing_unreadable();
    let runs = db.unit_runs(&a.unit)?;
    let mut h = history(&runs, a.rule);
    h.unreadable = db.unreadable()?;
    print(&h, &db.target())?;
    if let Some(j) = &a.json {
        write_json(j, &h).with_context(|| format!("writing {}", j.display()))?;
        outln!("wrote {}", j.display())?;
    }
    Ok(())
}

/// A run's outcome in one word: `voided`, `pass`, `rejected` or `unfinished`, or `TAMPERED` when
/// its rows do not match their hash chain (whatever they say).
pub(crate) fn outcome(r: &accelcal_db::history::RunLine) -> &'static str {
    if r.tampered.is_some() {
        return "TAMPERED";
    }
    match (r.outcome, &r.voided) {
        (_, Some(_)) => "voided",
        (Some(Outcome::Pass), None) => "pass",
        (Some(Outcome::Rejected), None) => "rejected",
        (None, None) => "unfinished",
    }
}

/// A verification in one cell.
pub(crate) fn verification(v: &Option<VerifySummary>) -> String {
    match v {
        None => "-".into(),
        Some(v) if v.pass => format!("pass {0}/{0}, max {1} m/s²", v.positions, sig(v.max_abs_error_m_s2, 2)),
        // "FAIL 1/6" read as one failed: say which is counted.
        Some(v) => format!(
            "FAIL, {} of {} accepted, max {} m/s²",
            v.positions - v.failed,
            v.positions,
            sig(v.max_abs_error_m_s2, 2)
        ),
    }
}

fn print(h: &History, target: &str) -> anyhow::Result<()> {
    let n_cal = h.runs.iter().filter(|r| r.calibration.is_some()).count();
    let serials = if h.serials.is_empty() { "no serial number".to_string() } else { h.serials.join(", ") };
    outln!(
        "unit {} ({serials}): {} run{}, {n_cal} calibration{} in {target}{}",
        h.device_id,
        h.runs.len(),
        if h.runs.len() == 1 { "" } else { "s" },
        if n_cal == 1 { "" } else { "s" },
        match h.unreadable.len() {
            0 => String::new(),
            n => format!(" (and {n} run{} that do not read, below)", if n == 1 { "" } else { "s" }),
        }
    )?;
    outln!(
        "{:>3}  {:<20}  {:<10}  {:<10}  {:<9}  {:<8}  {:<24}  {:<24}",
        "cal",
        "started (UTC)",
        "station",
        "operator",
        "outcome",
        "record",
        "as found",
        "as left"
    )?;
    for r in &h.runs {
        let outcome = outcome(r);
        outln!(
            "{:>3}  {:<20}  {:<10}  {:<10}  {:<9}  {:<8}  {:<24}  {:<24}",
            r.calibration.map_or("-".to_string(), |n| n.to_string()),
            utc(r.started_unix_s.max(0) as u64),
            r.station,
            r.operator,
            outcome,
            r.record_crc32.as_deref().unwrap_or("-"),
            verification(&r.as_found),
            verification(&r.as_left),
        )?;
        if let Some(why) = &r.tampered {
            outln!("     TAMPERED, not used: {why} (run {})", r.run_id)?;
        } else if let (Some(why), Some(t)) = (&r.voided, r.voided_unix_s) {
            outln!("     voided {}: {why} (run {})", utc(t.max(0) as u64), r.run_id)?;
        } else if let Some(why) = &r.not_a_calibration {
            outln!("     not a calibration: {why}")?;
        }
        if let (Some(state), None) = (r.certificate_state, &r.tampered) {
            let number = r.certificate_number.as_deref().map(|n| format!("{n} ")).unwrap_or_default();
            let replaced = if r.superseded_certificates.is_empty() {
                String::new()
            } else {
                format!("; superseded: {}", r.superseded_certificates.join(", "))
            };
            outln!("     certificate: {number}{}{replaced}", state.words())?;
        }
        if matches!(r.outcome, Some(Outcome::Rejected)) {
            outln!("     rejected: {}", r.reason)?;
        }
    }
    for u in &h.unreadable {
        outln!("UNREADABLE, not used: {u}")?;
    }
    if !h.drifts.is_empty() {
        outln!("drift between consecutive calibrations, m/s² at 1 g ± standard uncertainty (the fits' covariances):")?;
        for d in &h.drifts {
            outln!("  {} -> {} ({:.1} days)", d.from, d.to, d.days)?;
            for ch in ["x", "y", "z"] {
                let cells: Vec<String> = d
                    .terms
                    .iter()
                    .filter(|t| t.channel == ch)
                    .map(|t| {
                        format!("{:>2} {:>10} ± {:<8}", t.term, sig(t.delta_m_s2, 3), sig(t.sigma_m_s2, 2))
                    })
                    .collect();
                outln!("    {ch}: {}", cells.join("  "))?;
            }
        }
    }
    let rc = &h.recalibration;
    match rc.due_unix_s {
        Some(t) => outln!("recalibrate by {} ({})", &utc(t.max(0) as u64)[..10], rc.basis)?,
        None => outln!("recalibration: {}", rc.basis)?,
    }
    outln!(
        "  rule: tolerance {} m/s² at 1 g, k = {}, at most {} days (method: accelcal history --help)",
        rc.rule.tolerance_m_s2,
        rc.rule.coverage,
        rc.rule.max_interval_days
    )?;
    Ok(())
}
