//! `accelcal asset found-bad` (a reference found out of tolerance at its own recalibration) and
//! `accelcal affected` (the runs it affects, their units' certificates and customers, what became
//! of each; `--dismiss`): recalls, [`accelcal_db::recall`].

use accelcal_core::output::{utc_date_time, write_atomic, write_json};
use accelcal_db::asset::{start_of_day_unix_s, Date};
use accelcal_db::recall::{AffectedRun, FoundBad, Recall, RecallState};
use accelcal_db::Db;
use anyhow::Context;
use serde::Serialize;

use super::fleet::spreadsheet_text;
use super::store::{reader_spec, user_name, with_anchor_log};
use crate::app::recall as words;
use crate::out::count;
use crate::settings::asset as settings;
use accelcal_core::error::bad;

/// Runs `accelcal asset found-bad`.
pub fn found_bad(a: &settings::FoundBad) -> anyhow::Result<()> {
    let mut db = with_anchor_log(Db::open(&reader_spec(a.db.as_deref())?)?, a.anchor_log.as_deref())?;
    let operator = a.operator.clone().unwrap_or_else(user_name);
    let f = db.record_found_bad(&a.id, &a.certificate, a.since, &a.reason, &operator)?;
    outln!(
        "asset: {} ({}) certificate {} found out of tolerance, its runs from {} on affected ({}): recorded in {}",
        f.asset_id,
        f.kind.name(),
        f.certificate,
        f.since,
        f.reason,
        db.target()
    )?;
    let recall = db
        .recall(&a.id)?
        .into_iter()
        .find(|r| r.found_bad.certificate == f.certificate)
        .context("the finding just recorded")?;
    let (runs, units, open) = counts(&recall);
    outln!(
        "affected: {} of {}, {open} open (`accelcal affected {}` lists them)",
        count(runs, "run"),
        count(units, "unit"),
        f.asset_id
    )?;
    Ok(())
}

/// A finding's affected runs (voided ones aside), units and units still open.
fn counts(r: &Recall) -> (usize, usize, usize) {
    let units = r.units();
    let open = units.iter().filter(|u| u.state == RecallState::Open).count();
    (r.runs.iter().filter(|x| x.voided.is_none()).count(), units.len(), open)
}

/// `affected --json`.
#[derive(Serialize)]
struct AffectedJson<'a> {
    asset_id: &'a str,
    /// `--since`, else the earliest finding's day.
    since: Option<Date>,
    /// Distinct devices among the runs.
    units: usize,
    /// The findings listed (none with --since when the asset was not found out of tolerance).
    found_bad: Vec<&'a FoundBad>,
    /// Units still open: neither recalibrated on another reference nor dismissed.
    open_units: usize,
    runs: Vec<&'a AffectedRun>,
}

/// Runs `accelcal affected`.
pub fn run_affected(a: &settings::Affected) -> anyhow::Result<()> {
    match &a.action {
        settings::AffectedAction::List { since, json, csv } => {
            list(a, *since, json.as_deref(), csv.as_deref())
        }
        settings::AffectedAction::Dismiss { unit, reason, operator, anchor_log } => {
            let mut db = with_anchor_log(Db::open(&reader_spec(a.db.as_deref())?)?, anchor_log.as_deref())?;
            let operator = operator.clone().unwrap_or_else(user_name);
            let d = db.dismiss(&a.asset, a.certificate.as_deref(), unit, reason, &operator)?;
            outln!(
                "affected: unit {} ({}) dismissed from asset {}'s finding under certificate {} ({}): recorded in {}; \
                 it needs no recall",
                if d.serial.is_empty() { "-" } else { &d.serial },
                d.device_id,
                d.asset_id,
                d.certificate,
                d.reason,
                db.target()
            )?;
            Ok(())
        }
    }
}

fn list(
    a: &settings::Affected,
    since: Option<Date>,
    json: Option<&std::path::Path>,
    csv: Option<&std::path::Path>,
) -> anyhow::Result<()> {
    let mut db = Db::open_existing(&reader_spec(a.db.as_deref())?)?;
    let kept = |c: &str| a.certificate.as_deref().is_none_or(|w| w == c);
    // Each block: its header line, and its runs.
    let mut blocks: Vec<(String, Vec<AffectedRun>)> = Vec::new();
    let found: Vec<FoundBad>;
    match since {
        Some(day) => {
            found = db.found_bad(&a.asset)?.into_iter().filter(|f| kept(&f.certificate)).collect();
            let mut runs: Vec<AffectedRun> = db
                .affected(&a.asset, start_of_day_unix_s(day))?
                .into_iter()
                .filter(|r| kept(&r.certificate))
                .collect();
            db.customers(&mut runs)?;
            let mut devices: Vec<&str> = runs.iter().map(|r| r.device_id.as_str()).collect();
            devices.sort_unstable();
            devices.dedup();
            let only = a.certificate.as_ref().map(|c| format!(" certificate {c}")).unwrap_or_default();
            let header = format!(
                "affected: asset {}{only} since {day} (UTC) in {}: {} of {}",
                a.asset,
                db.target(),
                count(runs.len(), "run"),
                count(devices.len(), "unit")
            );
            blocks.push((header, runs));
        }
        None => {
            let recalls: Vec<Recall> =
                db.recall(&a.asset)?.into_iter().filter(|r| kept(&r.found_bad.certificate)).collect();
            if recalls.is_empty() {
                let under =
                    a.certificate.as_ref().map(|c| format!(" under certificate {c}")).unwrap_or_default();
                return Err(bad(format!(
                    "asset `{}` was not found out of tolerance{under} in {} (`accelcal asset found-bad {} --certificate N \
                     --since DATE --reason TEXT` records it): give --since DATE to list every run that used it from a \
                     day on",
                    a.asset,
                    db.target(),
                    a.asset
                )));
            }
            found = recalls.iter().map(|r| r.found_bad.clone()).collect();
            for r in recalls {
                let (runs, units, open) = counts(&r);
                let header = format!(
                    "affected: asset {} ({}) in {}: {}: {} of {}, {open} open",
                    a.asset,
                    r.found_bad.kind.name(),
                    db.target(),
                    words::under(&r.found_bad),
                    count(runs, "run"),
                    count(units, "unit")
                );
                let mut listed = r.runs;
                db.customers(&mut listed)?;
                blocks.push((header, listed));
            }
        }
    }
    for (header, runs) in &blocks {
        outln!("{header}")?;
        if runs.is_empty() {
            continue;
        }
        outln!(
            "  {:<36} {:<20} {:<12} {:<24} {:<10} {:<16} {:<9} {:<28} {:<20} recall",
            "run",
            "started (UTC)",
            "serial",
            "device",
            "station",
            "asset cert.",
            "outcome",
            "unit's certificate",
            "customer"
        )?;
        for r in runs {
            outln!(
                "  {:<36} {:<20} {:<12} {:<24} {:<10} {:<16} {:<9} {:<28} {:<20} {}",
                r.run_id,
                utc_date_time(r.started_unix_s),
                if r.serial.is_empty() { "-" } else { &r.serial },
                r.device_id,
                r.station,
                r.certificate,
                outcome(r),
                words::certificate(r),
                r.customer.as_deref().unwrap_or("-"),
                words::state(r)
            )?;
        }
    }
    let all: Vec<&AffectedRun> = blocks.iter().flat_map(|(_, runs)| runs.iter()).collect();
    let open: Vec<&&AffectedRun> = {
        // A unit is open by its latest affected run (a later one on the bad reference does not
        // supersede an earlier one).
        let mut latest: Vec<&&AffectedRun> = Vec::new();
        for r in all.iter().filter(|r| r.recall.is_some() && r.voided.is_none()) {
            match latest.iter_mut().find(|l| l.device_id == r.device_id && l.certificate == r.certificate) {
                Some(l) => *l = r,
                None => latest.push(r),
            }
        }
        latest.retain(|r| r.recall == Some(RecallState::Open));
        latest
    };
    if !open.is_empty() {
        outln!(
            "affected: {} unit{} open: recall each (a letter to its certificate's customer), or dismiss it with \
             `accelcal affected {} --dismiss SERIAL --reason TEXT`",
            open.len(),
            if open.len() == 1 { "" } else { "s" },
            a.asset
        )?;
    } else if found.is_empty() && all.iter().any(|r| r.certified && r.voided.is_none()) {
        outln!(
            "affected: if {} was found out of tolerance, assess each certified unit above (recall it, or \
             verify it as found on another reference); `accelcal asset found-bad` records the finding",
            a.asset
        )?;
    }
    if let Some(c) = csv {
        write_atomic(c, csv_of(&a.asset, &all)?.as_bytes())?;
        outln!("wrote {} ({})", c.display(), count(all.len(), "run"))?;
    }
    if let Some(j) = json {
        let mut devices: Vec<&str> = all.iter().map(|r| r.device_id.as_str()).collect();
        devices.sort_unstable();
        devices.dedup();
        let doc = AffectedJson {
            asset_id: &a.asset,
            since: since.or_else(|| found.iter().map(|f| f.since).min()),
            units: devices.len(),
            found_bad: found.iter().collect(),
            open_units: open.len(),
            runs: all,
        };
        write_json(j, &doc).with_context(|| format!("writing {}", j.display()))?;
        outln!("wrote {}", j.display())?;
    }
    Ok(())
}

/// How the run ended, in a word.
fn outcome(r: &AffectedRun) -> &'static str {
    match (&r.voided, r.outcome) {
        (Some(_), _) => "voided",
        (None, Some(accelcal_db::Outcome::Pass)) => "pass",
        (None, Some(accelcal_db::Outcome::Rejected)) => "rejected",
        (None, None) => "open",
    }
}

/// `affected --csv`: one row per run, the columns a recall letter takes. Text cells are
/// neutralised for spreadsheets ([`spreadsheet_text`]) and quoted.
fn csv_of(asset: &str, runs: &[&AffectedRun]) -> anyhow::Result<String> {
    let mut w = csv::WriterBuilder::new().quote_style(csv::QuoteStyle::NonNumeric).from_writer(Vec::new());
    w.write_record([
        "run_id",
        "serial",
        "device_id",
        "station",
        "started_utc",
        "asset_id",
        "asset_certificate",
        "outcome",
        "certified",
        "certificate_number",
        "certificate_state",
        "customer",
        "recall",
        "superseded_by_run",
        "superseded_utc",
        "superseded_by_asset",
        "superseded_by_certificate",
        "dismissed_reason",
        "dismissed_by",
        "dismissed_utc",
    ])?;
    for r in runs {
        let text = |s: &str| spreadsheet_text(s);
        let s = r.superseded_by.as_ref();
        let d = r.dismissed.as_ref();
        w.write_record([
            text(&r.run_id),
            text(&r.serial),
            text(&r.device_id),
            text(&r.station),
            utc_date_time(r.started_unix_s),
            text(asset),
            text(&r.certificate),
            outcome(r).to_string(),
            if r.certified { "yes" } else { "no" }.to_string(),
            text(r.certificate_number.as_deref().unwrap_or_default()),
            text(r.certificate_state.map(|c| c.words()).unwrap_or_default()),
            text(r.customer.as_deref().unwrap_or_default()),
            r.recall.map(|s| s.words()).unwrap_or_default().to_string(),
            text(s.map(|s| s.run_id.as_str()).unwrap_or_default()),
            s.map(|s| utc_date_time(s.started_unix_s)).unwrap_or_default(),
            text(s.map(|s| s.asset_id.as_str()).unwrap_or_default()),
            text(s.map(|s| s.certificate.as_str()).unwrap_or_default()),
            text(d.map(|d| d.reason.as_str()).unwrap_or_default()),
            text(d.map(|d| d.operator.as_str()).unwrap_or_default()),
            d.map(|d| utc_date_time(d.dismissed_unix_s)).unwrap_or_default(),
        ])?;
    }
    let bytes = w.into_inner().map_err(|e| anyhow::anyhow!("writing the CSV: {e}"))?;
    String::from_utf8(bytes).context("the CSV is UTF-8")
}
