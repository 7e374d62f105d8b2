//! The calibration database's failures, each with its kind (exit code).

use std::path::PathBuf;

use super::engine;
use super::label::LabelClash;
use super::Mismatch;
use accelcal_core::error::{Classify, Kind};

/// A failure of the calibration database.
#[derive(Debug, thiserror::Error)]
pub enum DbError {
    /// `--db` / `ACCELCAL_DB` is not a database this build can open.
    #[error("database `{spec}`: {why}")]
    BadTarget {
        /// The value, password hidden.
        spec: String,
        /// What is wrong with it.
        why: String,
    },
    /// A reader was given a SQLite file that does not exist.
    #[error("{}: no such database (it is created by the first run that stores into it)", path.display())]
    NoDatabase {
        /// The path given.
        path: PathBuf,
    },
    /// A reader was given a database that holds no accelcal schema yet (a new PostgreSQL
    /// database, an empty file): like [`DbError::NoDatabase`], nothing was stored there.
    #[error("database {target}: it holds no calibration yet (its tables are created by the first command that stores into it)")]
    NotCreated {
        /// The target, password hidden.
        target: String,
    },
    /// The database cannot be opened or reached.
    #[error("database {target} cannot be reached: {cause}")]
    Unreachable {
        /// The target, password hidden.
        target: String,
        /// The engine's message.
        cause: String,
    },
    /// The SQLite file (or its directory, where SQLite writes its `-wal` and `-shm` files) does
    /// not take writes.
    #[error("{}: the database is read-only (the file or its directory cannot be written): a command that stores into it needs write access", path.display())]
    ReadOnly {
        /// The database file.
        path: PathBuf,
    },
    /// The schema could not be brought to this build's version.
    #[error("migrating the database's schema failed: {cause}")]
    Migration {
        /// refinery's message.
        cause: String,
    },
    /// The migration history (`refinery_schema_history`) is not this build's migrations as
    /// applied: a row deleted or edited. Nothing trusts it until it is recorded again (`db
    /// migrate`, when the schema is exactly one version's) or the database restored.
    #[error("database {target}: its migration history (table refinery_schema_history) is damaged: {what}: {}", if *repairable {
        format!("run `accelcal db migrate --db {target}` once (it records the history again when the schema is exactly that of one of this build's versions), or restore the database from a backup")
    } else {
        "restore the database from a backup".to_string()
    })]
    MigrationHistory {
        /// The target, password hidden.
        target: String,
        /// What is wrong with it.
        what: String,
        /// Whether `db migrate` may record it again (the schema one version's).
        repairable: bool,
    },
    /// A reader met a database at another schema version than this build's: it never migrates.
    #[error("database {target}: {why}: run `accelcal db migrate --db {target}` once (it migrates the schema and writes what the migration asks); readers never write")]
    NeedsMigration {
        /// The target, password hidden.
        target: String,
        /// Which version it is at.
        why: String,
    },
    /// The ledger does not have the shape the rows need: emptied, shortened, or rows without an
    /// entry. A writer stores nothing into such a database.
    #[error("database {target}: the hash chain is broken: {what}; rows were written or removed behind accelcal's back (`accelcal db verify` lists them): nothing is stored until the database is restored")]
    ChainBroken {
        /// The target, password hidden.
        target: String,
        /// What was found.
        what: String,
    },
    /// The anchor log cannot be read or appended to.
    #[error(transparent)]
    AnchorLog(#[from] super::anchor::AnchorLogError),
    /// Asset `asset_id`'s register rows do not match their hash chain.
    #[error("asset {asset_id}: its register rows do not match their hash chain: {first}{} (`db verify` lists them); the asset is not used", if *more > 0 { format!(", and {more} more") } else { String::new() })]
    AssetTampered {
        /// The asset.
        asset_id: String,
        /// The first row that does not match.
        first: Box<Mismatch>,
        /// How many more.
        more: usize,
    },
    /// A statement failed (the connection was lost, a constraint or an append-only trigger
    /// refused it).
    #[error("database: {cause}")]
    Engine {
        /// The engine's message.
        cause: String,
    },
    /// Another writer stored the same key at the same moment (the store is tried again once).
    #[error("database: {cause}")]
    Raced {
        /// The engine's message.
        cause: String,
    },
    /// The run's rows do not match their hash chain: a row was changed behind accelcal's back.
    #[error("run {run_id}: the database's rows do not match their hash chain: {first}{} (`db verify` lists them); nothing of the run is used", if *more > 0 { format!(", and {more} more") } else { String::new() })]
    Tampered {
        /// The run.
        run_id: String,
        /// The first row that does not match.
        first: Box<Mismatch>,
        /// How many more.
        more: usize,
    },
    /// The serial or device of a new run contradicts the labels the database holds.
    #[error("{0}")]
    Label(Box<LabelClash>),
    /// A registered asset the command cannot use, or an asset the register refuses.
    #[error(transparent)]
    Asset(super::AssetError),
    /// A signer or a decision the register refuses.
    #[error(transparent)]
    Release(super::signer::ReleaseError),
    /// A cell holds another type than its column's (SQLite), named.
    #[error("database {target}: a cell does not read as its column's type: {first}{} (`db verify` lists them)", if *more > 0 { format!(", and {more} more") } else { String::new() })]
    BadCell {
        /// The target, password hidden.
        target: String,
        /// The first such cell.
        first: Box<super::cells::BadCell>,
        /// How many more.
        more: usize,
    },
    /// A value read back is not what the schema says.
    #[error("database schema mismatch: {what}")]
    Schema {
        /// What was read.
        what: String,
    },
    /// The run has no row yet.
    #[error("run {run_id}: not in the database (begin it first)")]
    NoRun {
        /// The run.
        run_id: String,
    },
    /// A piece differs from the one the run already holds, or the run is finished.
    #[error("run {run_id}: {what}")]
    Conflict {
        /// The run.
        run_id: String,
        /// What conflicts.
        what: String,
    },
    /// A piece belongs to another unit (or another g) than its run.
    #[error("run {run_id}: {what}")]
    Mismatch {
        /// The run.
        run_id: String,
        /// Both values, named.
        what: String,
    },
    /// A piece is not what it claims to be (a record that does not parse, a fit that is not
    /// `fit --json` output, a campaign that does not decompress).
    #[error("run {run_id}: the {piece} cannot be stored: {cause}")]
    BadPiece {
        /// The run.
        run_id: String,
        /// Which piece.
        piece: &'static str,
        /// Why.
        cause: String,
    },
    /// No run of the database names this unit.
    #[error(
        "no unit `{key}` in the database {target} (neither a serial number nor a device id of a stored run)"
    )]
    NoUnit {
        /// The serial or device id asked for.
        key: String,
        /// The database.
        target: String,
    },
    /// A serial number shared by runs of several device ids.
    #[error("`{key}` is the serial number of several devices ({devices}): give the device id")]
    Ambiguous {
        /// The serial asked for.
        key: String,
        /// The device ids, comma-separated.
        devices: String,
    },
}

impl Classify for DbError {
    fn kind(&self) -> Kind {
        match self {
            DbError::BadTarget { .. }
            | DbError::NoDatabase { .. }
            | DbError::NotCreated { .. }
            | DbError::NoRun { .. }
            | DbError::Conflict { .. }
            | DbError::Mismatch { .. }
            | DbError::BadPiece { .. }
            | DbError::NoUnit { .. }
            | DbError::ReadOnly { .. }
            | DbError::Tampered { .. }
            | DbError::AssetTampered { .. }
            | DbError::Label(_)
            | DbError::Ambiguous { .. } => Kind::BadInput,
            DbError::Asset(e) => e.kind(),
            DbError::Release(e) => e.kind(),
            DbError::Raced { .. } => Kind::Environment,
            DbError::Unreachable { .. }
            | DbError::Migration { .. }
            | DbError::NeedsMigration { .. }
            | DbError::MigrationHistory { .. }
            | DbError::AnchorLog(_)
            | DbError::ChainBroken { .. }
            | DbError::Engine { .. }
            | DbError::BadCell { .. }
            | DbError::Schema { .. } => Kind::Environment,
        }
    }
}

impl DbError {
    pub(super) fn sqlite(e: rusqlite::Error) -> DbError {
        let cause = e.to_string();
        match e.sqlite_error_code() {
            Some(rusqlite::ErrorCode::ConstraintViolation) if cause.contains("UNIQUE constraint") => {
                DbError::Raced { cause }
            }
            _ => DbError::Engine { cause },
        }
    }

    pub(super) fn pg(e: postgres::Error) -> DbError {
        // The server's own message (e.g. the append-only trigger's), not the client's "db error".
        let cause = engine::pg_cause(&e);
        if e.code() == Some(&postgres::error::SqlState::UNIQUE_VIOLATION) {
            return DbError::Raced { cause };
        }
        DbError::Engine { cause }
    }

    pub(super) fn schema(what: String) -> DbError {
        DbError::Schema { what }
    }
}
