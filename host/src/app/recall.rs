//! A recall in words ([`accelcal_db::recall`]), as `affected`, `fleet` and `serve` state it: the
//! finding, a unit's certificate, and what became of an affected run.

use accelcal_core::output::utc_date_time;
use accelcal_db::recall::{AffectedRun, FoundBad, RecallState};

/// A finding: `HEAD-1 (head) certificate DKD-17-001, out of tolerance from 2026-01-05 on (worn
/// bearing)`.
pub fn finding(f: &FoundBad) -> String {
    format!("{} ({}) {}", f.asset_id, f.kind.name(), under(f))
}

/// A finding of an asset already named: `certificate DKD-17-001, out of tolerance from 2026-01-05
/// on (worn bearing)`.
pub fn under(f: &FoundBad) -> String {
    format!("certificate {}, out of tolerance from {} on ({})", f.certificate, f.since, f.reason)
}

/// The unit's certificate in force for the run: `2026-000003 approved`, `issued, awaiting
/// approval` (a page stored without a number), or `none`.
pub fn certificate(r: &AffectedRun) -> String {
    match (&r.certificate_number, r.certificate_state) {
        (Some(n), Some(s)) => format!("{n} {}", s.words()),
        (Some(n), None) => format!("{n} (no page stored)"),
        (None, Some(s)) => format!("issued, {}", s.words()),
        (None, None) => "none".into(),
    }
}

/// The day (UTC) of `unix_s`.
fn day(unix_s: i64) -> String {
    utc_date_time(unix_s).chars().take(10).collect()
}

/// What became of an affected run: `open`, `recalibrated 2026-02-01 by run … (HEAD-2,
/// certificate …)`, `dismissed 2026-02-03 by ana: …`, `voided: …`, or `-` when no finding covers
/// it.
pub fn state(r: &AffectedRun) -> String {
    match r.recall {
        None => "-".into(),
        Some(RecallState::Open) => "open".into(),
        Some(RecallState::Voided) => format!("voided: {}", r.voided.as_deref().unwrap_or_default()),
        Some(RecallState::Dismissed) => match &r.dismissed {
            Some(d) => format!("dismissed {} by {}: {}", day(d.dismissed_unix_s), d.operator, d.reason),
            None => "dismissed".into(),
        },
        Some(RecallState::Recalibrated) => match &r.superseded_by {
            Some(s) => format!(
                "recalibrated {} by run {} ({}, certificate {})",
                day(s.started_unix_s),
                s.run_id,
                s.asset_id,
                s.certificate
            ),
            None => "recalibrated".into(),
        },
    }
}

/// How a unit is named: its serial, else its device id.
pub fn unit_key(r: &AffectedRun) -> &str {
    if r.serial.is_empty() {
        &r.device_id
    } else {
        &r.serial
    }
}
