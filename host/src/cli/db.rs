//! The commands on the calibration database: history, void, db verify.

use std::path::PathBuf;

use clap::{Args, Subcommand};

use super::ReaderDb;

/// `accelcal history`: a unit's runs from the calibration database.
#[derive(Debug, Args)]
pub struct HistoryArgs {
    /// The unit: its serial number, or its device id (24 hex digits, the MCU's unique id).
    #[arg(value_name = "SERIAL|DEVICE")]
    pub unit: String,
    /// The calibration database: a SQLite file, or postgres://USER@HOST[:PORT]/DB for a line of
    /// several stations [default: the ACCELCAL_DB environment variable, else calibration.sqlite
    /// in the current directory when there is one, as `station --out UNIT` makes it].
    #[arg(long, value_name = "FILE|URL")]
    pub db: Option<String>,
    /// The tolerance T the drift of a coefficient may reach before the unit is recalibrated,
    /// as an acceleration error at 1 g, m/s².
    #[arg(long = "tolerance-m-s2", value_name = "M_S2", default_value_t = accelcal_db::history::DEFAULT_RULE.tolerance_m_s2)]
    pub tolerance_m_s2: f64,
    /// Coverage factor k on the drift rate's standard error.
    #[arg(long, value_name = "K", default_value_t = accelcal_db::history::DEFAULT_RULE.coverage)]
    pub coverage: f64,
    /// The longest recommended interval between calibrations, days (also the interval after a
    /// single calibration; at most 36525, a century).
    #[arg(long, value_name = "DAYS", default_value_t = accelcal_db::history::DEFAULT_RULE.max_interval_days)]
    pub max_interval_days: f64,
    /// Write the history as JSON to this file.
    #[arg(long, value_name = "FILE")]
    pub json: Option<PathBuf>,
}

/// `accelcal void`.
#[derive(Debug, Args)]
pub struct VoidArgs {
    /// The run to void (a UUID, as `station` and `fit --db` print it and `history --json` lists
    /// it under `runs`).
    #[arg(value_name = "RUN_ID")]
    pub run_id: String,
    /// Why the run is voided (stored with it; `history` shows it).
    #[arg(long, value_name = "TEXT", required = true)]
    pub reason: String,
    #[command(flatten)]
    pub reader: ReaderDb,
    /// Who voids it [default: the account running the command].
    #[arg(long, value_name = "NAME")]
    pub operator: Option<String>,
}

/// `accelcal db`: the calibration database itself.
#[derive(Debug, Subcommand)]
pub enum DbCommand {
    /// Recompute every row's digest and the hash chain that links each run's rows and the runs
    /// to each other, and the rows' content hashes; name the first row that does not match.
    /// Exit code 0 when everything matches, 1 when a row does not.
    Verify(DbVerifyArgs),
}

/// `accelcal db verify`.
#[derive(Debug, Args)]
pub struct DbVerifyArgs {
    #[command(flatten)]
    pub reader: ReaderDb,
    /// Write what was checked and every row that does not match as JSON to this file.
    #[arg(long, value_name = "FILE")]
    pub json: Option<PathBuf>,
}
