//! The calibration database: every calibration run of every unit, kept for its history and for
//! recalibration. One schema (`db/migrations/<engine>/`, versioned, applied by refinery on
//! open) for an embedded SQLite file (one station, nothing to start) and a PostgreSQL server
//! (several stations).
//!
//! How a station uses it: [`Db::open`] (connects and migrates) → [`Db::begin_run`] with a
//! [`RunId`] chosen at the start → one `store_*` per piece as the run produces it (campaign, fit,
//! record, verifications, certificate) → [`Db::finish_run`]. Each piece is one row written in
//! one transaction, so a crash leaves whole rows or none. Storing a piece the run already holds
//! is a no-op when it is the same (its content hash) and refused when it differs, so a killed
//! run resumed under its id ([`Db::progress`] says what it holds) stores nothing twice. The
//! record is flashed only through the [`StoredRecord`] that [`Db::store_record`] returns: a
//! unit is never flashed with a record that was not stored first. Rows are never updated or
//! deleted (the engines' triggers refuse it).
//!
//! What may import what inside this crate (no cycle: `rscycles.py db/src` prints nothing):
//! `val` and `content` import only this file's items and `val`; `cells` → `val`; `engine` →
//! `cells`, `val` (its child `engine::schema_history` → `engine`); `chain` → `engine`,
//! `cells`, `content`, never a module that stores pieces; `piece` → `chain`, `derived`,
//! `engine`; `asset`, `certificate`, `label`, `signer` → `chain`, `engine` (and `content`,
//! `piece` or `derived` as they need; `certificate` also → `signer`, whose `superseded` says
//! which amendment replaced a certificate); `recall` → `asset`, `certificate`, `chain`,
//! `content`, `engine`, `piece`, `signer` (never the other way); `anchor` → `chain`; `derived` → `engine`, `history`;
//! `history` → `cells`, `signer`; `fleet` → `chain`, `check`, `derived`, `engine`, `signer`;
//! `check` → this file's `Db`.

// Index loops mirror the math (channels × terms), as in the core.
#![allow(clippy::needless_range_loop)]
pub mod anchor;
pub mod asset;
pub mod cells;
pub mod certificate;
pub mod chain;
pub mod check;
mod content;
pub mod derived;
mod engine;
mod error;
pub mod fleet;
pub mod history;
mod label;
mod piece;
pub mod recall;
pub mod signer;
mod types;
mod val;

use std::io::Read;

pub use anchor::{Anchor, AnchorFinding, AnchorLog};
pub use asset::{Asset, AssetError, AssetKind, StatedValue};
pub use certificate::{CertificateNumber, RecalibrationDue};
pub use chain::{ChainEvent, ChainReport, Mismatch, RunSeal};
pub use engine::{repair_schema_history, schema_version, Access, Target, LEDGER_LOCK};
use engine::{Conn, Tx, Val};
pub use error::DbError;
pub use label::{Label, LabelClash, Relabel};
use piece::{insert_row, Piece};
pub use recall::{AffectedRun, FoundBad, Recall, RecallState};
pub use signer::{CertificateState, ReleaseError, Signer};
pub use types::{LastFlash, Outcome, Phase, Progress, RunId, RunStart, RunSummary, Stored, StoredRecord};

use accelcal_core::document::verify::VerifyReport;

/// The environment variable that names the database when `--db` is not given.
pub const DB_ENV: &str = "ACCELCAL_DB";

/// An open database, migrated to this build's schema.
pub struct Db {
    conn: Conn,
    target: Target,
    /// `--anchor-log`: where each write's new chain head is appended ([`Db::with_anchor_log`]).
    anchor_log: Option<anchor::AnchorLog>,
    /// Whether a run whose rows do not read as their types is set aside and listed
    /// ([`Db::listing_unreadable`]) instead of failing the read.
    list_unreadable: bool,
    /// The runs set aside so far, and why each ([`Db::unreadable`]).
    unreadable: std::collections::BTreeMap<String, String>,
}

use accelcal_core::digest::hex;
/// Hex SHA-256 (the core's one definition, re-exported: the database's content hashes).
pub use accelcal_core::digest::sha256_hex;

/// Seconds since the Unix epoch (0 before it), as the database stores times.
pub fn now_unix_s() -> i64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_secs() as i64)
        .unwrap_or(0)
}

/// The gzip magic number.
const GZIP_MAGIC: [u8; 2] = [0x1f, 0x8b];

impl Db {
    /// Opens (a SQLite file is created when missing) and migrates the database `spec` names:
    /// `postgres://…` or a file path.
    /// The database must take writes (checked here, so a read-only file stops the command
    /// before it does anything else).
    pub fn open(spec: &str) -> Result<Db, DbError> {
        Db::open_target(Target::parse(spec)?, Access::Write)
    }

    /// Opens an existing database for reading (a missing SQLite file is refused, not created; a
    /// read-only file or mount is read as it is).
    pub fn open_existing(spec: &str) -> Result<Db, DbError> {
        Db::open_target(Target::parse(spec)?, Access::Read)
    }

    /// Whether the connection still answers (`SELECT 1`): a pool's check before it hands out a
    /// connection it kept (the server may have restarted meanwhile).
    pub fn ping(&mut self) -> Result<(), DbError> {
        self.conn.transaction(|tx| tx.query("SELECT 1", &[]))?;
        Ok(())
    }

    /// A second connection to the same database, for reading (a reader that queries on
    /// several connections at once).
    pub fn open_again(&self) -> Result<Db, DbError> {
        let mut db = Db::open_target(self.target.clone(), Access::Read)?;
        db.list_unreadable = self.list_unreadable;
        Ok(db)
    }

    /// A reader that lists runs (`history`, `fleet`, `serve`): a run whose rows do not read as
    /// their types (a SQLite cell written behind accelcal's back) is set aside, and the others
    /// are listed; [`Db::unreadable`] names what was set aside. Without it, such a run fails
    /// the read (what a writer, or a command that uses the run, needs).
    pub fn listing_unreadable(mut self) -> Db {
        self.list_unreadable = true;
        self
    }

    /// The runs set aside since the last call ([`Db::listing_unreadable`]), each with the cells
    /// that do not read as their column's type (one scan of the database's cells, made only
    /// when a run was set aside), by run id.
    pub fn unreadable(&mut self) -> Result<Vec<cells::UnreadableRun>, DbError> {
        if self.unreadable.is_empty() {
            return Ok(Vec::new());
        }
        let cells = self.conn.reading(engine::scan_cells)?;
        Ok(std::mem::take(&mut self.unreadable)
            .into_iter()
            .map(|(run_id, error)| cells::UnreadableRun {
                bad_cells: cells.iter().filter(|c| c.run_id() == Some(run_id.as_str())).cloned().collect(),
                run_id,
                error,
            })
            .collect())
    }

    /// How many runs were set aside since the last [`Db::unreadable`].
    pub fn unreadable_count(&self) -> usize {
        self.unreadable.len()
    }

    /// Forgets the runs set aside (a pooled connection handing itself to the next request).
    pub fn forget_unreadable(&mut self) {
        self.unreadable.clear();
    }

    /// Takes over the runs `other` (a connection of [`Db::open_again`]) set aside.
    pub fn unreadable_from(&mut self, other: &mut Db) {
        self.unreadable.append(&mut other.unreadable);
    }

    /// Notes runs set aside ([`cells::each_row`]).
    fn set_aside(&mut self, runs: cells::SetAside) {
        for (run, why) in runs {
            self.unreadable.entry(run).or_insert(why);
        }
    }

    /// The rows of a listing read by `f` ([`cells::each_row`]): with
    /// [`Db::listing_unreadable`], a run whose row does not read is set aside (its id in column
    /// `run_col`); otherwise such a row is the failure, its bad cell named.
    fn listed<T>(
        &mut self,
        rows: &[Vec<engine::Val>],
        run_col: usize,
        f: impl FnMut(&[engine::Val]) -> Result<T, DbError>,
    ) -> Result<Vec<T>, DbError> {
        match cells::each_row(self.list_unreadable, rows, run_col, f) {
            Ok((out, aside)) => {
                self.set_aside(aside);
                Ok(out)
            }
            Err(e) => Err(self.conn.name_bad_cell(e)),
        }
    }

    fn open_target(target: Target, access: Access) -> Result<Db, DbError> {
        // A writer, under the migration's lock once the schema is current: the rows of a
        // database that predates the ledger (schema 1) are chained once, recorded in the chain
        // as a `legacy-seal` event; on a chained schema an emptied or shortened ledger is
        // tampering, never sealed again ([`chain::shape`]). Rows derived from pieces stored
        // before schema 6 are derived then. What there is to do is asked in a reading
        // transaction, so that opening a database a station is writing into does not wait for
        // the station's lock. A reader does none of this ([`Access::Read`]).
        let shown = target.display();
        let conn = Conn::open(&target, access, |c, before| {
            let legacy = before.is_some_and(|v| v < chain::LEDGER_SCHEMA);
            let (shape, pending) = c.reading(|tx| Ok((chain::shape(tx)?, derived::pending(tx)?)))?;
            if legacy && shape.unsealed() {
                c.transaction(|tx| chain::seal_legacy(tx).map(drop))?;
            } else if let Some(what) = shape.broken() {
                return Err(DbError::ChainBroken { target: shown.clone(), what });
            }
            if pending {
                derived::backfill(c)?;
            }
            Ok(())
        })?;
        // A reader of a database whose pieces still wait for their derived rows would show a
        // part of them: a writer derives them first.
        let mut conn = conn;
        if access == Access::Read && conn.reading(derived::pending)? {
            return Err(DbError::NeedsMigration {
                target: shown,
                why: "rows stored before schema 6 still wait for their derived rows".into(),
            });
        }
        Ok(Db { conn, target, anchor_log: None, list_unreadable: false, unreadable: Default::default() })
    }

    /// The database, for messages (password hidden).
    pub fn target(&self) -> String {
        self.target.display()
    }

    /// `sqlite` or `postgres`.
    pub fn engine(&self) -> &'static str {
        self.conn.engine()
    }

    /// The schema versions applied, oldest first.
    pub fn schema_versions(&mut self) -> Result<Vec<i64>, DbError> {
        self.conn.applied_versions()
    }

    /// Begins a run (no-op when it is already there with the same start, refused when the id
    /// began another run). A new run's serial must be its device's and no other device's label
    /// ([`label`]'s rule), unless `relabel` moves it on purpose (the relabel rows are stored with
    /// the run).
    pub fn begin_run(&mut self, s: &RunStart, relabel: Option<&Relabel>) -> Result<Stored, DbError> {
        let device_id = s.device_id.to_ascii_lowercase();
        if device_id.len() != 24 || !device_id.bytes().all(|b| b.is_ascii_hexdigit()) {
            return Err(DbError::BadPiece {
                run_id: s.run_id.to_string(),
                piece: "run",
                cause: format!("device id `{}` is not 24 hex digits", s.device_id),
            });
        }
        let s = RunStart { device_id, ..s.clone() };
        // What goes into the database is one line each (an operator or station name from the
        // environment too): no forged line in a certificate, a journal or a header made from it.
        one_line(s.run_id, "run", accelcal_core::text::header_value("serial", &s.serial))?;
        for (field, v) in [
            ("station", &s.station),
            ("head", &s.head),
            ("operator", &s.operator),
            ("firmware version", &s.firmware_version),
            ("g source", &s.g_source),
        ] {
            one_line(s.run_id, "run", accelcal_core::text::single_line(field, v))?;
        }
        if let Some(r) = relabel {
            one_line(s.run_id, "run", accelcal_core::text::single_line("relabel reason", &r.reason))?;
            one_line(s.run_id, "run", accelcal_core::text::single_line("operator", &r.operator))?;
        }
        let sha = chain::run_content(&s);
        let row: Vec<Val> = vec![
            s.run_id.to_string().into(),
            s.device_id.clone().into(),
            s.serial.clone().into(),
            s.station.clone().into(),
            s.head.clone().into(),
            s.operator.clone().into(),
            s.started_unix_s.into(),
            s.software_version.clone().into(),
            s.firmware_version.clone().into(),
            s.g_m_s2.into(),
            s.g_source.clone().into(),
            sha.clone().into(),
        ];
        let run_id = s.run_id;
        self.retried(|conn| {
            conn.transaction(|tx| {
                let found =
                    tx.query("SELECT content_sha256 FROM run WHERE run_id = $1", &[run_id.to_string().into()])?;
                match found.first() {
                    Some(r) if r[0].text()? == sha => Ok(Stored::Already),
                    Some(_) => Err(DbError::Conflict {
                        run_id: run_id.to_string(),
                        what: "began already with another unit, station, operator, time or g (a run id is used once)"
                            .into(),
                    }),
                    None => {
                        label::check_new_run(tx, &s.device_id, &s.serial, relabel)?;
                        insert_row(tx, chain::table("run"), &row)?;
                        Ok(Stored::New)
                    }
                }
            })
        })
    }

    /// Runs a write `f`, again once when another writer stored the same key at the same moment
    /// (the second try sees its row: the same piece, or a conflict); then appends the chain head
    /// to the anchor log, when there is one.
    fn retried<T>(&mut self, mut f: impl FnMut(&mut Conn) -> Result<T, DbError>) -> Result<T, DbError> {
        let out = match f(&mut self.conn) {
            Err(DbError::Raced { .. }) => f(&mut self.conn),
            r => r,
        }?;
        if let Some(log) = &self.anchor_log {
            if let Some(head) = self.conn.reading(chain::head)? {
                log.append(&anchor::Anchor { seq: head.seq, chain_sha256: head.chain_sha256 }, now_unix_s())?;
            }
        }
        Ok(out)
    }

    /// Appends every new chain head this connection writes to `log` (`--anchor-log`), after
    /// checking the log's latest anchor against the ledger: a writer refuses a database whose
    /// ledger was cut short or rewritten behind the anchor.
    pub fn with_anchor_log(mut self, log: anchor::AnchorLog) -> Result<Db, DbError> {
        if let Some(last) = log.read()?.pop() {
            let source = log.path().display().to_string();
            if let Some(problem) = self.anchor_problem(&last)? {
                return Err(DbError::ChainBroken {
                    target: self.target(),
                    what: format!("the anchor log {source}'s latest anchor: {problem}"),
                });
            }
        }
        self.anchor_log = Some(log);
        Ok(self)
    }

    /// Whether the ledger was emptied under the rows (laundering's first step), asked in two
    /// one-row lookups: cheap enough for every report of the line (`fleet`, serve's overview),
    /// which says so instead of presenting the numbers as good. Not counted here (a writer's
    /// open counts rows against entries, `db verify` checks every row): at the line's scale the
    /// counts would cost a report a third of its second.
    pub fn chain_broken(&mut self) -> Result<Option<String>, DbError> {
        let (entry, run) = self.conn.reading(|tx| {
            Ok((
                !tx.query("SELECT 1 FROM ledger LIMIT 1", &[])?.is_empty(),
                !tx.query("SELECT 1 FROM run LIMIT 1", &[])?.is_empty(),
            ))
        })?;
        Ok((run && !entry).then(|| "the ledger is empty and the database holds runs".to_string()))
    }

    /// The chain head: the ledger's latest entry (`None`: nothing stored yet).
    pub fn chain_head(&mut self) -> Result<Option<anchor::Anchor>, DbError> {
        Ok(self
            .conn
            .reading(chain::head)?
            .map(|h| anchor::Anchor { seq: h.seq, chain_sha256: h.chain_sha256 }))
    }

    /// Checks anchors read from files (an anchor log, certificates, journals) against the
    /// ledger: each must be the entry at its place. Also what the chain itself does not show:
    /// a ledger cut short behind an anchor.
    pub fn check_anchors(
        &mut self,
        found: &[(String, anchor::Anchor)],
    ) -> Result<Vec<anchor::AnchorFinding>, DbError> {
        found
            .iter()
            .map(|(source, a)| {
                Ok(anchor::AnchorFinding {
                    source: source.clone(),
                    anchor: a.clone(),
                    problem: self.anchor_problem(a)?,
                })
            })
            .collect()
    }

    fn anchor_problem(&mut self, a: &anchor::Anchor) -> Result<Option<String>, DbError> {
        let (at, head) = self.conn.reading(|tx| Ok((chain::chain_at(tx, a.seq)?, chain::head(tx)?)))?;
        Ok(match at {
            Some(c) if c == a.chain_sha256 => None,
            Some(_) => Some(format!(
                "ledger entry {} is not the one anchored (its chain value differs): the ledger was rewritten from there on",
                a.seq
            )),
            None => Some(match head {
                Some(h) if h.seq < a.seq => format!(
                    "the ledger ends at entry {}, but entry {} was anchored: entries were removed from its end",
                    h.seq, a.seq
                ),
                None => format!("the ledger is empty, but entry {} was anchored", a.seq),
                Some(_) => format!("ledger entry {} is gone", a.seq),
            }),
        })
    }

    /// Takes run `run` out of the unit's history, the fleet's statistics and the recalibration
    /// intervals: an appended row with the reason (the run's rows all stay). Voiding it again
    /// with the same reason is a no-op; with another, refused.
    pub fn void_run(&mut self, run: RunId, reason: &str, operator: &str) -> Result<Stored, DbError> {
        for (field, v) in [("void reason", reason), ("operator", operator)] {
            one_line(run, "void", accelcal_core::text::single_line(field, v))?;
        }
        let sha = sha256_hex(reason.as_bytes());
        let row: Vec<Val> = vec![
            run.to_string().into(),
            reason.into(),
            operator.into(),
            now_unix_s().into(),
            sha.clone().into(),
        ];
        self.retried(|conn| {
            conn.transaction(|tx| {
                let id = Val::from(run.to_string());
                if tx.query("SELECT 1 FROM run WHERE run_id = $1", std::slice::from_ref(&id))?.is_empty() {
                    return Err(DbError::NoRun { run_id: run.to_string() });
                }
                if let Some(r) = tx
                    .query(
                        "SELECT content_sha256, reason FROM void WHERE run_id = $1",
                        std::slice::from_ref(&id),
                    )?
                    .first()
                {
                    return if r[0].text()? == sha {
                        Ok(Stored::Already)
                    } else {
                        Err(DbError::Conflict {
                            run_id: run.to_string(),
                            what: format!("it was voided already ({})", r[1].text()?),
                        })
                    };
                }
                insert_row(tx, chain::table("void"), &row)?;
                let device =
                    tx.query("SELECT device_id FROM run WHERE run_id = $1", std::slice::from_ref(&id))?;
                derived::refresh_device_certificate(tx, &device[0][0].text()?)?;
                Ok(Stored::New)
            })
        })
    }

    /// Run `run`'s verification of `phase` as stored: whether it passed, and its JSON.
    pub fn verification(&mut self, run: RunId, phase: Phase) -> Result<Option<(bool, String)>, DbError> {
        let rows = self.conn.transaction(|tx| {
            tx.query(
                "SELECT pass, report_json FROM verification WHERE run_id = $1 AND phase = $2",
                &[run.to_string().into(), phase.sql().into()],
            )
        })?;
        rows.first()
            .map(|r| {
                let pass = match &r[0] {
                    Val::Bool(b) => *b,
                    v => v.int()? != 0,
                };
                Ok((pass, r[1].text()?))
            })
            .transpose()
    }

    /// The SHA-256 of run `run`'s stored certificate (its HTML), if it has one.
    pub fn certificate_sha256(&mut self, run: RunId) -> Result<Option<String>, DbError> {
        let rows = self.conn.transaction(|tx| {
            tx.query("SELECT content_sha256 FROM certificate WHERE run_id = $1", &[run.to_string().into()])
        })?;
        rows.first().map(|r| r[0].text()).transpose()
    }

    /// The label (current serial) of a device, if it has one.
    pub fn label_of(&mut self, device_id: &str) -> Result<Option<Label>, DbError> {
        let d = device_id.trim().to_ascii_lowercase();
        self.conn.transaction(|tx| label::current(tx, &d))
    }

    /// Checks the whole database against its hash chain, and the rows derived from the pieces
    /// ([`derived`]) against the pieces.
    pub fn verify_chain(&mut self) -> Result<ChainReport, DbError> {
        self.conn.reading(|tx| {
            let cells = engine::scan_cells(tx)?;
            let mut r = chain::verify_all(tx)?;
            r.bad_cells = cells;
            r.mismatches.extend(certificate::gaps(tx)?);
            r.mismatches.extend(
                derived::check(tx)?.into_iter().map(|(run_id, piece, what)| chain::Mismatch {
                    seq: 0,
                    run_id,
                    piece: piece.into(),
                    what,
                }),
            );
            Ok(r)
        })
    }

    /// Checks run `run`'s rows against their hash chain: its seal, or [`DbError::Tampered`].
    pub fn verify_run(&mut self, run: RunId) -> Result<RunSeal, DbError> {
        let id = run.to_string();
        match self.conn.reading(|tx| chain::verify_run(tx, &id))? {
            Ok(seal) => Ok(seal),
            Err(mut m) => {
                let first = m.remove(0);
                Err(DbError::Tampered { run_id: id, first: Box::new(first), more: m.len() })
            }
        }
    }

    /// The latest flash of a record into `device_id` (voided runs left out), other than run
    /// `except`'s: the run, the record's CRC-32, when, and how the run ended.
    pub fn last_flash(
        &mut self,
        device_id: &str,
        except: Option<RunId>,
    ) -> Result<Option<LastFlash>, DbError> {
        let params = [
            Val::from(device_id.trim().to_ascii_lowercase()),
            Val::from(except.map(|r| r.to_string()).unwrap_or_default()),
        ];
        let rows = self.conn.transaction(|tx| {
            tx.query(
                "SELECT f.run_id, f.crc32, f.flashed_unix_s, e.outcome FROM flash f \
                 JOIN run ON run.run_id = f.run_id LEFT JOIN run_end e ON e.run_id = f.run_id \
                 WHERE run.device_id = $1 AND f.run_id <> $2 AND f.run_id NOT IN (SELECT run_id FROM void) \
                 ORDER BY f.flashed_unix_s DESC, f.run_id DESC LIMIT 1",
                &params,
            )
        })?;
        rows.first()
            .map(|r| {
                Ok(LastFlash {
                    run_id: RunId::parse(&r[0].text()?).map_err(|e| DbError::schema(e.to_string()))?,
                    crc32: crc_of(&r[1])?,
                    flashed_unix_s: r[2].int()?,
                    outcome: match &r[3] {
                        Val::Null => None,
                        v => Some(Outcome::from_sql(&v.text()?)?),
                    },
                })
            })
            .transpose()
    }

    /// Stores the run's campaign file (plain or gzip; kept gzip-compressed, hashed
    /// uncompressed).
    pub fn store_campaign(&mut self, run: RunId, file: &[u8]) -> Result<Stored, DbError> {
        let bad = |cause: String| DbError::BadPiece { run_id: run.to_string(), piece: "campaign", cause };
        let (plain, gzip) = if file.starts_with(&GZIP_MAGIC) {
            let mut plain = Vec::new();
            flate2::read::GzDecoder::new(file)
                .read_to_end(&mut plain)
                .map_err(|e| bad(format!("it starts as gzip but does not decompress: {e}")))?;
            (plain, file.to_vec())
        } else {
            let mut z = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
            std::io::Write::write_all(&mut z, file)
                .and_then(|()| z.try_finish())
                .map_err(|e| bad(e.to_string()))?;
            (file.to_vec(), z.finish().map_err(|e| bad(e.to_string()))?)
        };
        let sha = sha256_hex(&plain);
        // Observed before the store's transaction, which holds the ledger's lock.
        let seen = derived::observation(&plain, self.start_of(run)?.g_m_s2);
        self.store_deriving(
            run,
            Piece {
                table: "campaign",
                what: "campaign",
                second: None,
                values: vec![sha.clone().into(), gzip.into(), now_unix_s().into()],
                sha,
            },
            &|tx, run| derived::insert_observation(tx, run, &seen),
        )
    }

    /// Stores the run's fit (`fit --json` output: the coefficients and their covariance). A
    /// document that names a device id, serial or g refuses to go with a run of another.
    pub fn store_fit(&mut self, run: RunId, fit_json: &str) -> Result<Stored, DbError> {
        let bad = |cause: String| DbError::BadPiece { run_id: run.to_string(), piece: "fit", cause };
        let doc = accelcal_core::document::FitDoc::parse(fit_json)
            .map_err(|e| bad(format!("not `fit --json` output: {e}")))?;
        let start = self.start_of(run)?;
        if let Some(id) = doc.identity.as_ref().and_then(|i| i.device_id.as_deref()) {
            self.check_same(run, "the fit's device id", id, "the run's", &start.device_id)?;
        }
        if let (Some(serial), false) =
            (doc.identity.as_ref().and_then(|i| i.serial.as_deref()), start.serial.is_empty())
        {
            self.check_same(run, "the fit's serial", serial, "the run's", &start.serial)?;
        }
        if let Some(g) = doc.identity.as_ref().map(|i| i.g_m_s2) {
            if (g - start.g_m_s2).abs() > 1e-9 * start.g_m_s2.abs() {
                return Err(DbError::Mismatch {
                    run_id: run.to_string(),
                    what: format!("the fit's g {g} m/s² is not the run's g {} m/s²", start.g_m_s2),
                });
            }
        }
        self.store_deriving(
            run,
            Piece {
                table: "fit",
                what: "fit",
                second: None,
                values: vec![fit_json.into(), now_unix_s().into()],
                sha: sha256_hex(fit_json.as_bytes()),
            },
            &|tx, run| derived::insert_fit(tx, run, &doc),
        )
    }

    /// Stores the run's calibration record and returns the token the flash step writes from.
    /// The record must parse and be made for the run's unit.
    pub fn store_record(&mut self, run: RunId, bytes: &[u8]) -> Result<StoredRecord, DbError> {
        let rec = accelcal_shared::record::Record::parse(bytes).map_err(|e| DbError::BadPiece {
            run_id: run.to_string(),
            piece: "record",
            cause: e.to_string(),
        })?;
        let start = self.start_of(run)?;
        let id = accelcal_core::digest::hex(&rec.device_id);
        self.check_same(run, "the record's device id", &id, "the run's", &start.device_id)?;
        let crc32 = record_crc(bytes);
        self.store(
            run,
            Piece {
                table: "cal_record",
                what: "record",
                second: None,
                values: vec![bytes.to_vec().into(), i64::from(crc32).into(), now_unix_s().into()],
                sha: sha256_hex(bytes),
            },
        )?;
        Ok(StoredRecord { run_id: run, crc32, bytes: bytes.to_vec() })
    }

    /// Notes that the stored record was flashed into the unit (once: a resumed run's second
    /// flash of the same record keeps the first time).
    pub fn record_flashed(&mut self, rec: &StoredRecord) -> Result<Stored, DbError> {
        self.store(
            rec.run_id,
            Piece {
                table: "flash",
                what: "flash",
                second: None,
                values: vec![i64::from(rec.crc32).into(), now_unix_s().into()],
                sha: sha256_hex(&rec.crc32.to_le_bytes()),
            },
        )
    }

    /// Stores a verification (`verify --json`): as found, with the record the unit came in
    /// with, or as left, with the new one. It must be of the run's unit.
    pub fn store_verification(
        &mut self,
        run: RunId,
        phase: Phase,
        report: &VerifyReport,
    ) -> Result<Stored, DbError> {
        let start = self.start_of(run)?;
        self.check_same(
            run,
            "the verification's device id",
            &report.device_id,
            "the run's",
            &start.device_id,
        )?;
        let json = serde_json::to_string(report).expect("a verification report serialises");
        self.store_deriving(
            run,
            Piece {
                table: "verification",
                what: match phase {
                    Phase::AsFound => "as-found verification",
                    Phase::AsLeft => "as-left verification",
                },
                second: Some(("phase", phase.sql())),
                values: vec![report.pass.into(), json.clone().into(), now_unix_s().into()],
                sha: sha256_hex(json.as_bytes()),
            },
            &|tx, run| derived::insert_verification(tx, run, phase.sql(), report),
        )
    }

    /// Stores the run's certificate (`report`'s HTML page).
    pub fn store_certificate(&mut self, run: RunId, html: &str) -> Result<Stored, DbError> {
        self.store(
            run,
            Piece {
                table: "certificate",
                what: "certificate",
                second: None,
                values: vec![html.into(), now_unix_s().into()],
                sha: sha256_hex(html.as_bytes()),
            },
        )
    }

    /// Ends the run; nothing more is stored under it afterwards.
    pub fn finish_run(&mut self, run: RunId, outcome: Outcome, reason: &str) -> Result<Stored, DbError> {
        let sha = sha256_hex(format!("{}\n{reason}", outcome.sql()).as_bytes());
        self.store(
            run,
            Piece {
                table: "run_end",
                what: "end",
                second: None,
                values: vec![outcome.sql().into(), reason.into(), now_unix_s().into()],
                sha,
            },
        )
    }

    /// What the run holds, to resume it.
    pub fn progress(&mut self, run: RunId) -> Result<Progress, DbError> {
        let start = self.start_of(run)?;
        let id = Val::from(run.to_string());
        self.conn.transaction(|tx| {
            let has = |tx: &mut Tx<'_>, sql: &str| -> Result<bool, DbError> {
                Ok(!tx.query(sql, std::slice::from_ref(&id))?.is_empty())
            };
            let record =
                tx.query("SELECT bytes, crc32 FROM cal_record WHERE run_id = $1", std::slice::from_ref(&id))?;
            let record = match record.first() {
                Some(r) => Some(StoredRecord { run_id: run, bytes: r[0].bytes()?, crc32: crc_of(&r[1])? }),
                None => None,
            };
            let outcome =
                tx.query("SELECT outcome FROM run_end WHERE run_id = $1", std::slice::from_ref(&id))?;
            let voided = tx.query("SELECT reason FROM void WHERE run_id = $1", std::slice::from_ref(&id))?;
            Ok(Progress {
                voided: voided.first().map(|r| r[0].text()).transpose()?,
                campaign: has(tx, "SELECT 1 FROM campaign WHERE run_id = $1")?,
                fit: has(tx, "SELECT 1 FROM fit WHERE run_id = $1")?,
                record,
                flashed: has(tx, "SELECT 1 FROM flash WHERE run_id = $1")?,
                as_found: has(tx, "SELECT 1 FROM verification WHERE run_id = $1 AND phase = 'as_found'")?,
                as_left: has(tx, "SELECT 1 FROM verification WHERE run_id = $1 AND phase = 'as_left'")?,
                certificate: has(tx, "SELECT 1 FROM certificate WHERE run_id = $1")?,
                outcome: outcome.first().map(|r| Outcome::from_sql(&r[0].text()?)).transpose()?,
                start,
            })
        })
    }

    /// The stored fit (`fit --json`) of the record with CRC-32 `crc32` made for device
    /// `device_id`: the fit of the record a unit came in with, for its as-found tolerance.
    /// `None` when no run stored that record.
    pub fn fit_of_record(&mut self, device_id: &str, crc32: u32) -> Result<Option<String>, DbError> {
        let params = [Val::from(device_id.trim().to_ascii_lowercase()), Val::from(i64::from(crc32))];
        let rows = self.conn.transaction(|tx| {
            tx.query(
                "SELECT f.fit_json FROM fit f JOIN cal_record r ON r.run_id = f.run_id \
                 JOIN run ON run.run_id = f.run_id WHERE run.device_id = $1 AND r.crc32 = $2 \
                 ORDER BY run.started_unix_s DESC",
                &params,
            )
        })?;
        rows.first().map(|r| r[0].text()).transpose()
    }

    /// Every run of the unit `key` names, oldest first: a device id (24 hex digits), or a
    /// serial — the device it labels now ([`label`]), else the one device that ever carried it.
    pub fn unit_runs(&mut self, key: &str) -> Result<Vec<RunSummary>, DbError> {
        let key = key.trim();
        let target = self.target();
        let tolerant = self.list_unreadable;
        let (runs, aside) = self.conn.transaction(|tx| {
            let lower = key.to_ascii_lowercase();
            let is_device = !tx
                .query("SELECT 1 FROM run WHERE device_id = $1 LIMIT 1", &[lower.clone().into()])?
                .is_empty();
            let device = if is_device {
                lower
            } else {
                let now: Vec<String> =
                    label::devices_labelled(tx, key)?.into_iter().map(|l| l.device_id).collect();
                let candidates = if now.is_empty() { label::devices_ever(tx, key)? } else { now };
                match candidates.as_slice() {
                    [] => return Err(DbError::NoUnit { key: key.into(), target }),
                    [one] => one.clone(),
                    many => return Err(DbError::Ambiguous { key: key.into(), devices: many.join(", ") }),
                }
            };
            let rows = tx.query(
                &format!(
                    "SELECT {RUN_COLUMNS} FROM run WHERE device_id = $1 ORDER BY started_unix_s, run_id"
                ),
                &[device.into()],
            )?;
            cells::each_row(tolerant, &rows, 0, |r| summary(tx, run_start(r)?))
        })?;
        self.set_aside(aside);
        Ok(runs)
    }

    /// The run's start, or [`DbError::NoRun`].
    fn start_of(&mut self, run: RunId) -> Result<RunStart, DbError> {
        let rows = self.conn.transaction(|tx| {
            tx.query(&format!("SELECT {RUN_COLUMNS} FROM run WHERE run_id = $1"), &[run.to_string().into()])
        })?;
        rows.first().map(|r| run_start(r)).unwrap_or_else(|| Err(DbError::NoRun { run_id: run.to_string() }))
    }

    fn check_same(&self, run: RunId, what: &str, got: &str, theirs: &str, want: &str) -> Result<(), DbError> {
        if got.trim().eq_ignore_ascii_case(want.trim()) {
            Ok(())
        } else {
            Err(DbError::Mismatch {
                run_id: run.to_string(),
                what: format!("{what} {got} is not {theirs} {want}"),
            })
        }
    }
}

/// A text field's check ([`accelcal_core::text`]) as the refusal of the piece it would go into.
fn one_line(
    run: RunId,
    piece: &'static str,
    checked: Result<&str, accelcal_core::text::TextError>,
) -> Result<(), DbError> {
    checked.map(drop).map_err(|e| DbError::BadPiece { run_id: run.to_string(), piece, cause: e.to_string() })
}

/// The `run` columns [`run_start`] reads, in its order.
const RUN_COLUMNS: &str =
    "run_id, device_id, serial, station, head, operator, started_unix_s, software_version, \
                           firmware_version, g_m_s2, g_source";

pub(crate) fn run_start(r: &[Val]) -> Result<RunStart, DbError> {
    Ok(RunStart {
        run_id: RunId::parse(&r[0].text()?).map_err(|e| DbError::schema(e.to_string()))?,
        device_id: r[1].text()?,
        serial: r[2].text()?,
        station: r[3].text()?,
        head: r[4].text()?,
        operator: r[5].text()?,
        started_unix_s: r[6].int()?,
        software_version: r[7].text()?,
        firmware_version: r[8].text()?,
        g_m_s2: r[9].real()?,
        g_source: r[10].text()?,
    })
}

fn crc_of(v: &Val) -> Result<u32, DbError> {
    u32::try_from(v.int()?).map_err(|_| DbError::schema(format!("a CRC-32 out of range: {v:?}")))
}

/// A record's CRC-32: its last four bytes, little-endian (a parsed record is longer).
pub(crate) fn record_crc(bytes: &[u8]) -> u32 {
    let n = bytes.len();
    u32::from_le_bytes(bytes[n - 4..].try_into().expect("four bytes"))
}

/// The rest of a run's rows.
fn summary(tx: &mut Tx<'_>, start: RunStart) -> Result<RunSummary, DbError> {
    let id = [Val::from(start.run_id.to_string())];
    let one = |tx: &mut Tx<'_>, sql: &str| -> Result<Option<Vec<Val>>, DbError> {
        Ok(tx.query(sql, &id)?.into_iter().next())
    };
    let report = |v: Option<Vec<Val>>| -> Result<Option<VerifyReport>, DbError> {
        v.map(|r| {
            serde_json::from_str(&r[0].text()?)
                .map_err(|e| DbError::schema(format!("a stored verification: {e}")))
        })
        .transpose()
    };
    let campaign_sha256 = one(tx, "SELECT campaign_sha256 FROM campaign WHERE run_id = $1")?
        .map(|r| r[0].text())
        .transpose()?;
    let fit_json = one(tx, "SELECT fit_json FROM fit WHERE run_id = $1")?.map(|r| r[0].text()).transpose()?;
    let record_crc32 =
        one(tx, "SELECT crc32 FROM cal_record WHERE run_id = $1")?.map(|r| crc_of(&r[0])).transpose()?;
    let flashed_unix_s =
        one(tx, "SELECT flashed_unix_s FROM flash WHERE run_id = $1")?.map(|r| r[0].int()).transpose()?;
    let as_found =
        report(one(tx, "SELECT report_json FROM verification WHERE run_id = $1 AND phase = 'as_found'")?)?;
    let as_left =
        report(one(tx, "SELECT report_json FROM verification WHERE run_id = $1 AND phase = 'as_left'")?)?;
    let end = match one(tx, "SELECT outcome, reason, ended_unix_s FROM run_end WHERE run_id = $1")? {
        Some(r) => Some((Outcome::from_sql(&r[0].text()?)?, r[1].text()?, r[2].int()?)),
        None => None,
    };
    let voided = match one(tx, "SELECT reason, voided_unix_s FROM void WHERE run_id = $1")? {
        Some(r) => Some((r[0].text()?, r[1].int()?)),
        None => None,
    };
    // A run whose rows do not match their chain is listed as such and never used.
    let tampered = match chain::verify_run(tx, &start.run_id.to_string())? {
        Ok(_) => None,
        Err(m) => m.first().map(|m| format!("its rows do not match their hash chain: {m}")),
    };
    // The certificate in force (the newest amendment's, else the first) and its decision.
    let in_force = one(
        tx,
        &format!(
            "SELECT {IN_FORCE}, (SELECT a.meaning FROM approval a WHERE a.number = {IN_FORCE}) \
             WHERE EXISTS (SELECT 1 FROM certificate c WHERE c.run_id = $1)",
            IN_FORCE = certificate::IN_FORCE
        ),
    )?;
    let (certificate_number, certificate_state) = match in_force {
        Some(r) => (r[0].opt_text()?, Some(signer::CertificateState::of(r[1].opt_text()?.as_deref()))),
        None => (None, None),
    };
    let superseded_certificates = tx
        .query(
            "SELECT replaces FROM amendment WHERE run_id = $1 ORDER BY sequence",
            &[start.run_id.to_string().into()],
        )?
        .iter()
        .map(|r| r[0].text())
        .collect::<Result<Vec<_>, _>>()?;
    Ok(RunSummary {
        certificate_number,
        superseded_certificates,
        certificate_state,
        tampered,
        start,
        campaign_sha256,
        fit_json,
        record_crc32,
        flashed_unix_s,
        as_found,
        as_left,
        end,
        voided,
    })
}
