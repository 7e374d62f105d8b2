//! The search box of every page (`/search?q=…`): a serial, a device id, a certificate number
//! (`2026-000003`, an amendment's too), a run id or its first 8 or more hex digits goes to the
//! unit's page (at the run's row for a run or a certificate); a miss is a 404 that says what was
//! looked for, and a beginning of several run ids, or a serial of several devices, lists them.

use accelcal_core::output::utc_date_time;
use accelcal_db::{Db, DbError, RunId};
use askama::Template;

use super::pages::VERSION;
use super::{links, PageError};
use crate::settings::reader::is_run_prefix;

/// At most this many candidates are listed.
const CANDIDATES: i64 = 20;

/// Where a search goes.
pub(super) enum Found {
    /// The one page it names.
    Go(String),
    /// Several: the page that lists them.
    Several(String),
}

/// One candidate: where it goes, and it in words.
struct Candidate {
    href: String,
    words: String,
}

#[derive(Template)]
#[template(path = "serve/search.html")]
struct SearchPage<'a> {
    db: &'a str,
    version: &'a str,
    unreadable: Vec<String>,
    q: &'a str,
    message: String,
    candidates: Vec<Candidate>,
}

/// The run's row on its unit's page (`/unit/DEVICE#run-ID`); a run that is not there is 404.
pub(super) fn run_row(db: &mut Db, run: RunId) -> Result<String, PageError> {
    let device = match db.progress(run) {
        Ok(p) => p.start.device_id,
        Err(DbError::NoRun { .. }) => {
            return Err(PageError::not_found(format!("no run {run} in the database")))
        }
        Err(e) => return Err(PageError::unavailable(e)),
    };
    Ok(format!("{}#run-{run}", links::unit(&device)))
}

/// The run in words for a list: its id, its unit and when it started.
fn run_words(db: &mut Db, run: RunId) -> Result<Candidate, PageError> {
    let p = db.progress(run).map_err(PageError::unavailable)?;
    let s = &p.start;
    let unit = if s.serial.is_empty() { "-" } else { &s.serial };
    Ok(Candidate {
        href: format!("{}#run-{run}", links::unit(&s.device_id)),
        words: format!(
            "run {run}: unit {unit} ({}), started {}",
            s.device_id,
            utc_date_time(s.started_unix_s)
        ),
    })
}

/// Where the search `q` goes.
pub(super) fn find(db: &mut Db, target: &str, q: &str) -> Result<Found, PageError> {
    let q = q.trim();
    if q.is_empty() {
        return Err(PageError::bad("search: give a serial, a device id, a certificate number or a run id"));
    }
    // A number no certificate carries may still be a serial.
    let number = accelcal_db::certificate::is_number(q);
    if number {
        if let Some(run) = db.run_of_certificate(q).map_err(PageError::unavailable)? {
            return Ok(Found::Go(run_row(db, run)?));
        }
    }
    if let Ok(run) = RunId::parse(q) {
        return Ok(Found::Go(run_row(db, run)?));
    }
    if is_run_prefix(q) {
        let prefix = q.to_ascii_lowercase();
        let runs = db.runs_with_prefix(&prefix, CANDIDATES + 1).map_err(PageError::unavailable)?;
        match runs.as_slice() {
            [] => {}
            [one] => return Ok(Found::Go(run_row(db, *one)?)),
            many => {
                let candidates = many
                    .iter()
                    .take(CANDIDATES as usize)
                    .map(|&r| run_words(db, r))
                    .collect::<Result<_, _>>()?;
                let more = if many.len() > CANDIDATES as usize { " (the first 20)" } else { "" };
                let message = format!("{q} begins several run ids{more}: which one?");
                return Ok(Found::Several(page(target, q, message, candidates)?));
            }
        }
    }
    match db.unit_runs(q) {
        Ok(_) => Ok(Found::Go(links::unit(q))),
        Err(DbError::NoUnit { .. }) if number => Err(PageError::not_found(format!(
            "no certificate is numbered {q} in the database, and no unit has the serial {q}"
        ))),
        Err(DbError::NoUnit { .. }) => Err(PageError::not_found(format!(
            "nothing found for `{q}`: it is no serial, device id, certificate number or run id (nor the \
             beginning of one) in the database"
        ))),
        Err(DbError::Ambiguous { devices, .. }) => {
            let candidates = devices
                .split(", ")
                .map(|d| Candidate { href: links::unit(d), words: format!("device {d}") })
                .collect();
            let message = format!("`{q}` is the serial of several devices: which one?");
            Ok(Found::Several(page(target, q, message, candidates)?))
        }
        Err(e) => Err(PageError::unavailable(e)),
    }
}

fn page(target: &str, q: &str, message: String, candidates: Vec<Candidate>) -> Result<String, PageError> {
    SearchPage { db: target, version: VERSION, unreadable: Vec::new(), q, message, candidates }
        .render()
        .map_err(PageError::internal)
}
