//! `--db`: a command's result into the calibration database ([`accelcal_core::db`]), for `fit`,
//! `verify`, `flash`, `report` and the station.
//!
//! The database is opened (connected, migrated) before the command does anything else, so an
//! unreachable database stops it before it touches a node or writes a file. Each piece is stored
//! after the command's own output is complete; storing it again is a no-op
//! ([`Stored::Already`]), so a command run again after a crash stores nothing twice.

use std::path::Path;

use accelcal_core::error::bad;
use accelcal_db::{Db, Outcome, Phase, Progress, Relabel, RunId, RunStart, Stored, StoredRecord, DB_ENV};
use accelcal_line::verify::VerifyReport;

use crate::settings::values::RunStore;

/// The station's database file when neither --db nor ACCELCAL_DB names one (beside the units'
/// directories), and the readers' when it is in the current directory.
pub const DEFAULT_DB: &str = "calibration.sqlite";

/// The reason a run that passed ends with, whichever command ends it (`station`, `report --db`):
/// the same words, so that ending it again is a no-op.
pub const PASS_REASON: &str = "as-left verification passed; certificate issued";

/// The database a reader (`history`, `void`, `db verify`) uses: `--db`, else `ACCELCAL_DB`, else
/// the station's default file in the current directory when it is there.
pub fn reader_spec(given: Option<&str>) -> anyhow::Result<String> {
    if let Some(s) = named_db(given) {
        return Ok(s);
    }
    if Path::new(DEFAULT_DB).is_file() {
        return Ok(DEFAULT_DB.into());
    }
    Err(bad(format!(
        "no calibration database: give --db FILE|URL, set {DB_ENV}, or run where the station's {DEFAULT_DB} is"
    )))
}

/// The database `--db` names, else `ACCELCAL_DB` (when set and not empty).
pub fn named_db(given: Option<&str>) -> Option<String> {
    given.map(str::to_string).or_else(|| std::env::var(DB_ENV).ok().filter(|s| !s.trim().is_empty()))
}

/// Fault injection for the crash tests: when the environment variable `ACCELCAL_CRASH_AT`
/// names `point`, the process group (the station and its step) is killed with SIGKILL right
/// here, as a power cut would stop them. No effect when it is not set.
pub fn crash_point(point: &str) {
    if std::env::var_os("ACCELCAL_CRASH_AT").is_some_and(|v| v == point) {
        errln!("crash point {point}: killed (ACCELCAL_CRASH_AT)");
        // SAFETY: kill(2) on the caller's own process group; nothing is read or written.
        unsafe {
            libc::kill(0, libc::SIGKILL);
        }
    }
}

/// An open database and the run `--run-id` names.
pub struct RunDb {
    /// The database.
    pub db: Db,
    /// `--run-id`, parsed.
    pub run: Option<RunId>,
    /// `--relabel`: the relabel a run begun now stores.
    pub relabel: Option<Relabel>,
}

/// Opens the database a command stores into, when it has one.
pub fn open(a: Option<&RunStore>) -> anyhow::Result<Option<RunDb>> {
    let Some(a) = a else { return Ok(None) };
    let db = with_anchor_log(Db::open(&a.spec)?, a.anchor_log.as_deref())?;
    let relabel = a.relabel.clone().map(|reason| Relabel { reason, operator: user_name() });
    Ok(Some(RunDb { db, run: a.run, relabel }))
}

/// `db`, appending each chain head it writes to `log` (`--anchor-log`) when one is given.
pub fn with_anchor_log(db: Db, log: Option<&Path>) -> anyhow::Result<Db> {
    Ok(match log {
        Some(l) => db.with_anchor_log(accelcal_db::AnchorLog::new(l))?,
        None => db,
    })
}

/// What a command that may begin a run knows about it.
pub struct Begin {
    /// The unit's device id (24 hex digits).
    pub device_id: String,
    /// The unit's serial (empty: not known).
    pub serial: String,
    /// The head.
    pub head: String,
    /// The node's firmware version (empty: not asked).
    pub firmware_version: String,
    /// g, m/s², and where it came from.
    pub g: (f64, String),
}

/// The station's name: the host name.
pub fn host_name() -> String {
    whoami::hostname().unwrap_or_else(|_| "unknown".into())
}

/// The operator: the account running the command.
pub fn user_name() -> String {
    whoami::username().unwrap_or_else(|_| "unknown".into())
}

impl RunDb {
    /// The run `--run-id` names when the database holds it (its device must be `device_id`),
    /// else a run begun now under `--run-id` or a new id. Says which on stderr.
    pub fn begin_or_continue(&mut self, b: Begin) -> anyhow::Result<RunId> {
        if let Some(run) = self.run {
            if let Some(p) = self.progress_if_any(run)? {
                if !p.start.device_id.eq_ignore_ascii_case(&b.device_id) {
                    return Err(bad(format!(
                        "--run-id {run} is a run of device {}, not of this unit's device {}",
                        p.start.device_id, b.device_id
                    )));
                }
                errln!("db: run {run} in {}", self.db.target());
                return Ok(run);
            }
        }
        let run = self.run.unwrap_or_default();
        let start = RunStart {
            run_id: run,
            device_id: b.device_id,
            serial: b.serial,
            station: host_name(),
            head: b.head,
            operator: user_name(),
            started_unix_s: accelcal_db::now_unix_s(),
            software_version: env!("CARGO_PKG_VERSION").into(),
            firmware_version: b.firmware_version,
            g_m_s2: b.g.0,
            g_source: b.g.1,
        };
        self.db.begin_run(&start, self.relabel.as_ref())?;
        crash_point("db:run");
        self.run = Some(run);
        errln!(
            "db: run {run} begun in {} (give --run-id {run} to the line's next commands)",
            self.db.target()
        );
        Ok(run)
    }

    /// The run `--run-id` names, which must be in the database (`command` says who needs it).
    pub fn existing(&mut self, command: &str) -> anyhow::Result<(RunId, Progress)> {
        let run = self.run.ok_or_else(|| {
            bad(format!(
                "{command} --db needs --run-id: the run this belongs to (begun by `fit --db`, `verify --db` or `station`)"
            ))
        })?;
        Ok((run, self.db.progress(run)?))
    }

    fn progress_if_any(&mut self, run: RunId) -> anyhow::Result<Option<Progress>> {
        match self.db.progress(run) {
            Ok(p) => Ok(Some(p)),
            Err(accelcal_db::DbError::NoRun { .. }) => Ok(None),
            Err(e) => Err(e.into()),
        }
    }
}

/// The verification's name in messages.
pub fn phase_name(p: Phase) -> &'static str {
    match p {
        Phase::AsFound => "as-found",
        Phase::AsLeft => "as-left",
    }
}

/// A head as the command line names it (the spec's one spelling, its `Display`).
pub fn head_text(h: &accelcal_line::head::HeadSpec) -> String {
    h.to_string()
}

/// Stores a verification, read back from its JSON file (what `verify --json` wrote).
pub fn verification(db: &mut Db, run: RunId, phase: Phase, json: &Path) -> anyhow::Result<Stored> {
    Ok(db.store_verification(run, phase, &VerifyReport::read(json)?)?)
}

/// Stores a fit's pieces: the campaign file, the fit JSON and, when written, the record.
pub fn fit_pieces(
    db: &mut Db,
    run: RunId,
    campaign: &Path,
    fit_json: &str,
    record: Option<&[u8]>,
) -> anyhow::Result<Option<StoredRecord>> {
    let bytes = std::fs::read(campaign).map_err(|e| bad(format!("{}: {e}", campaign.display())))?;
    db.store_campaign(run, &bytes)?;
    db.store_fit(run, fit_json)?;
    Ok(record.map(|r| db.store_record(run, r)).transpose()?)
}

/// The record `flash --db` may write: the one the run holds, which must be the file's; a run
/// without a record stores the file's first (a unit is never flashed with a record that is not
/// stored).
pub fn record_to_flash(rdb: &mut RunDb, file: &Path, bytes: &[u8]) -> anyhow::Result<StoredRecord> {
    let (run, p) = rdb.existing("flash")?;
    // The run's rows must still be the ones stored: a record forged in the database is not flashed.
    rdb.db.verify_run(run)?;
    match p.record {
        Some(stored) if stored.bytes() == bytes => Ok(stored),
        Some(stored) => Err(bad(format!(
            "{} is not the record run {run} stored (CRC {:08x}): flash the stored one, or give the run it belongs to",
            file.display(),
            stored.crc32()
        ))),
        None => Ok(rdb.db.store_record(run, bytes)?),
    }
}

/// What `report --db` needs before it certifies run `run`: its rows as stored (the hash chain),
/// the record flashed, and a passing as-left verification that is the one `verify` names.
pub fn check_certifiable(db: &mut Db, run: RunId, p: &Progress, verify: &VerifyReport) -> anyhow::Result<()> {
    db.verify_run(run)?;
    if let Some(why) = &p.voided {
        return Err(bad(format!("run {run} is voided ({why}): it is not certified")));
    }
    if p.outcome == Some(Outcome::Rejected) {
        return Err(bad(format!("run {run} ended rejected: it is not certified")));
    }
    if !p.flashed {
        return Err(bad(format!(
            "run {run} holds no flash of its record: flash it with `flash --db --run-id {run}` before certifying"
        )));
    }
    match db.verification(run, Phase::AsLeft)? {
        None => Err(bad(format!(
            "run {run} holds no as-left verification: verify the flashed node with `verify --phase as-left --db --run-id {run}` before certifying"
        ))),
        Some((false, _)) => Err(bad(format!("run {run}'s as-left verification failed: the unit is not certified"))),
        Some((true, json)) if json != serde_json::to_string(verify)? => Err(bad(format!(
            "the --verify report is not run {run}'s stored as-left verification: certify with the one stored"
        ))),
        Some(_) => Ok(()),
    }
}
