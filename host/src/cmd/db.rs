//! `accelcal void` (a run taken out of history, never deleted) and `accelcal db verify` (every
//! row against the hash chain, `core::db::chain`).

use accelcal_core::output::write_json;
use accelcal_db::{Db, Stored};
use accelcal_line::verify::Failed;

use super::store::{reader_spec, user_name};
use crate::settings::reader::{DbVerify, Void};

/// Runs `accelcal void`.
pub fn run_void(a: &Void) -> anyhow::Result<()> {
    let run = a.run;
    let mut db = Db::open(&reader_spec(a.db.as_deref())?)?;
    let operator = a.operator.clone().unwrap_or_else(user_name);
    let stored = db.void_run(run, a.reason.as_str(), &operator)?;
    let p = db.progress(run)?;
    outln!(
        "void: run {run} of device {} ({}) {} in {}: {}; it stays in the database, listed as voided, and counts in no history, fleet or interval",
        p.start.device_id,
        if p.start.serial.is_empty() { "no serial" } else { p.start.serial.as_str() },
        if stored == Stored::New { "voided" } else { "was voided already" },
        db.target(),
        a.reason.as_str()
    )?;
    Ok(())
}

/// Runs `accelcal db verify`: exit code 1 when a row does not match.
pub fn run_verify(a: &DbVerify) -> anyhow::Result<()> {
    let mut db = Db::open_existing(&reader_spec(a.db.as_deref())?)?;
    let r = db.verify_chain()?;
    if let Some(j) = &a.json {
        write_json(j, &r)?;
    }
    outln!(
        "db verify: {}: {} runs, {} rows, {} ledger entries checked",
        db.target(),
        r.runs,
        r.rows,
        r.entries
    )?;
    match r.mismatches.first() {
        None => {
            outln!("db verify: every row matches its hash chain")?;
            Ok(())
        }
        Some(first) => {
            outln!("db verify: the first row that does not match is {first}")?;
            for m in r.mismatches.iter().skip(1) {
                outln!("  also: {m}")?;
            }
            Err(anyhow::Error::new(Failed {
                failed: r.mismatches.len(),
                total: r.rows.max(r.entries),
                parameters: Vec::new(),
            })
            .context(format!("{} does not match its hash chain: {first}", db.target())))
        }
    }
}
