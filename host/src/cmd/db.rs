//! `accelcal void` (a run taken out of history, never deleted) and `accelcal db verify` (every
//! row against the hash chain, `core::db::chain`).

use accelcal_core::error::bad;
use accelcal_core::output::write_json;
use accelcal_db::{Anchor, AnchorFinding, Db, Stored};
use anyhow::Context;

use super::store::{reader_spec, user_name};
use crate::settings::reader::{DbVerify, Void};

/// Runs `accelcal void`.
pub fn run_void(a: &Void) -> anyhow::Result<()> {
    let run = a.run;
    let mut db =
        super::store::with_anchor_log(Db::open(&reader_spec(a.db.as_deref())?)?, a.anchor_log.as_deref())?;
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

/// Runs `accelcal db migrate`: the one command that writes what a migration asks.
pub fn run_migrate(db: Option<&str>) -> anyhow::Result<()> {
    let spec = reader_spec(db)?;
    if let Some(done) = accelcal_db::repair_schema_history(&accelcal_db::Target::parse(&spec)?)? {
        outln!("db migrate: the migration history (table refinery_schema_history): {done}")?;
    }
    let mut db = Db::open(&spec)?;
    let versions = db.schema_versions()?;
    outln!(
        "db migrate: {} is at schema version {} (this build's)",
        db.target(),
        versions.last().copied().unwrap_or_default()
    )?;
    for e in db.verify_chain()?.events {
        outln!("db migrate: chain event {}: {}", e.kind, e.detail)?;
    }
    Ok(())
}

/// Runs `accelcal db verify`: exit code 1 when a row, a cell or an anchor does not match.
pub fn run_verify(a: &DbVerify) -> anyhow::Result<()> {
    // Every anchor file is read before the database is opened: a file that is missing or holds
    // no anchor is the user's to fix.
    let mut found: Vec<(String, Anchor)> = Vec::new();
    for p in &a.anchors {
        let bytes = std::fs::read(p).with_context(|| format!("--anchors {}", p.display()))?;
        let anchors = accelcal_db::anchor::scan(&String::from_utf8_lossy(&bytes));
        if anchors.is_empty() {
            return Err(bad(format!(
                "--anchors {}: the file holds no anchor (`{} seq=N chain_sha256=HEX`)",
                p.display(),
                accelcal_db::anchor::MARK
            )));
        }
        found.extend(anchors.into_iter().map(|x| (p.display().to_string(), x)));
    }
    let mut db = Db::open_existing(&reader_spec(a.db.as_deref())?)?;
    let r = db.verify_chain()?;
    let anchors = db.check_anchors(&found)?;
    if let Some(j) = &a.json {
        write_json(j, &Report { chain: &r, anchors: &anchors })?;
    }
    outln!(
        "db verify: {}: {}, {}, {} checked{}",
        db.target(),
        crate::out::count(r.runs, "run"),
        crate::out::count(r.rows, "row"),
        if r.entries == 1 { "1 ledger entry".to_string() } else { format!("{} ledger entries", r.entries) },
        if found.is_empty() {
            String::new()
        } else {
            format!(", {} anchors from {} files", found.len(), a.anchors.len())
        }
    )?;
    for e in &r.events {
        outln!("db verify: chain event {}: {}", e.kind, e.detail)?;
    }
    for c in &r.bad_cells {
        outln!("db verify: bad cell: {c}")?;
    }
    let broken: Vec<&AnchorFinding> = anchors.iter().filter(|f| f.problem.is_some()).collect();
    for f in &broken {
        outln!(
            "db verify: anchor {} (entry {}): {}",
            f.source,
            f.anchor.seq,
            f.problem.as_deref().unwrap_or_default()
        )?;
    }
    if let Some(first) = r.mismatches.first() {
        outln!("db verify: the first row that does not match is {first}")?;
        for m in r.mismatches.iter().skip(1) {
            outln!("  also: {m}")?;
        }
    }
    let findings = r.mismatches.len() + r.bad_cells.len() + broken.len();
    if findings == 0 {
        outln!(
            "db verify: every row matches its hash chain{}",
            if found.is_empty() { "" } else { ", and every anchor is in it" }
        )?;
        return Ok(());
    }
    let first = r
        .mismatches
        .first()
        .map(ToString::to_string)
        .or_else(|| r.bad_cells.first().map(|c| format!("bad cell: {c}")))
        .or_else(|| {
            broken
                .first()
                .map(|f| format!("anchor {}: {}", f.source, f.problem.as_deref().unwrap_or_default()))
        })
        .unwrap_or_default();
    Err(anyhow::anyhow!(
        "db verify: {} does not match its hash chain: {findings} finding{} ({} rows, {} cells, {} anchors), the first: {first}",
        db.target(),
        if findings == 1 { "" } else { "s" },
        r.mismatches.len(),
        r.bad_cells.len(),
        broken.len()
    ))
}

/// `db verify --json`: the chain's report and each anchor's finding.
#[derive(serde::Serialize)]
struct Report<'a> {
    #[serde(flatten)]
    chain: &'a accelcal_db::ChainReport,
    anchors: &'a [AnchorFinding],
}
