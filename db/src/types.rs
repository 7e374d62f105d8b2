//! What the database stores and gives back: run ids, a run's start, its progress and summary,
//! the verification phases and outcomes, the stored record token.

use serde::{Deserialize, Serialize};

use super::DbError;
use accelcal_core::document::verify::VerifyReport;

/// A calibration run's id: a UUID the station chooses before storing anything, and keeps to
/// resume the run.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct RunId(uuid::Uuid);

impl RunId {
    /// A new random id.
    pub fn new() -> RunId {
        RunId(uuid::Uuid::new_v4())
    }

    /// Reads an id (`--run-id`, a resume file).
    pub fn parse(s: &str) -> Result<RunId, DbError> {
        uuid::Uuid::parse_str(s.trim()).map(RunId).map_err(|e| DbError::BadPiece {
            run_id: s.into(),
            piece: "run id",
            cause: e.to_string(),
        })
    }
}

impl Default for RunId {
    fn default() -> RunId {
        RunId::new()
    }
}

impl std::fmt::Display for RunId {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        self.0.hyphenated().fmt(f)
    }
}

/// What is known when a run begins.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RunStart {
    /// The run's id.
    pub run_id: RunId,
    /// The unit's MCU unique id, 24 hex digits (lower case).
    pub device_id: String,
    /// The unit's serial number (empty when not known).
    pub serial: String,
    /// The station's name.
    pub station: String,
    /// The dividing head (`manual`, `sim:ADDR`, a rig's name).
    pub head: String,
    /// Who ran it.
    pub operator: String,
    /// When it started, seconds since the Unix epoch.
    pub started_unix_s: i64,
    /// accelcal's version.
    pub software_version: String,
    /// The node's firmware version as it reports it (empty when not asked).
    pub firmware_version: String,
    /// Local gravity the run uses, m/s².
    pub g_m_s2: f64,
    /// Where g came from (`--g`, `--latitude 48.1 --height 520`, the campaign's header…).
    pub g_source: String,
}

/// Whether a store wrote a row or found the same piece there already (a resumed run).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stored {
    /// The row was written.
    New,
    /// The run already held this very piece; nothing was written.
    Already,
}

/// Which verification.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Phase {
    /// With the record in force when the unit came in, before anything is changed.
    AsFound,
    /// With the new record, after it was flashed.
    AsLeft,
}

impl Phase {
    pub(super) fn sql(self) -> &'static str {
        match self {
            Phase::AsFound => "as_found",
            Phase::AsLeft => "as_left",
        }
    }
}

/// How a run ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Outcome {
    /// Calibrated, flashed and verified.
    Pass,
    /// The unit was rejected (the reason says why).
    Rejected,
}

impl Outcome {
    pub(super) fn sql(self) -> &'static str {
        match self {
            Outcome::Pass => "pass",
            Outcome::Rejected => "rejected",
        }
    }

    pub(super) fn from_sql(s: &str) -> Result<Outcome, DbError> {
        match s {
            "pass" => Ok(Outcome::Pass),
            "rejected" => Ok(Outcome::Rejected),
            other => Err(DbError::schema(format!("run_end.outcome `{other}`"))),
        }
    }
}

/// A record that is in the database: the only way to the bytes the flash step writes.
#[derive(Clone, Debug, PartialEq)]
pub struct StoredRecord {
    pub(super) run_id: RunId,
    pub(super) crc32: u32,
    pub(super) bytes: Vec<u8>,
}

impl StoredRecord {
    /// The run that stored it.
    pub fn run_id(&self) -> RunId {
        self.run_id
    }

    /// The record's CRC-32 (its last four bytes).
    pub fn crc32(&self) -> u32 {
        self.crc32
    }

    /// The record's bytes, as stored: what is flashed.
    pub fn bytes(&self) -> &[u8] {
        &self.bytes
    }
}

/// What a run holds: where a resumed run goes on.
#[derive(Clone, Debug, PartialEq)]
pub struct Progress {
    /// How it began.
    pub start: RunStart,
    /// The campaign is stored.
    pub campaign: bool,
    /// The fit is stored.
    pub fit: bool,
    /// The record, when stored.
    pub record: Option<StoredRecord>,
    /// The record was flashed.
    pub flashed: bool,
    /// The as-found verification is stored.
    pub as_found: bool,
    /// The as-left verification is stored.
    pub as_left: bool,
    /// The certificate is stored.
    pub certificate: bool,
    /// How it ended, when it did.
    pub outcome: Option<Outcome>,
    /// Why it was voided, when it was.
    pub voided: Option<String>,
}

/// Everything stored about one run, for the unit's history.
#[derive(Clone, Debug)]
pub struct RunSummary {
    /// How it began.
    pub start: RunStart,
    /// SHA-256 of the campaign (uncompressed), when stored.
    pub campaign_sha256: Option<String>,
    /// `fit --json`, when stored.
    pub fit_json: Option<String>,
    /// The record's CRC-32, when stored.
    pub record_crc32: Option<u32>,
    /// When the record was flashed.
    pub flashed_unix_s: Option<i64>,
    /// The as-found verification.
    pub as_found: Option<VerifyReport>,
    /// The as-left verification.
    pub as_left: Option<VerifyReport>,
    /// How it ended: outcome, reason, time.
    pub end: Option<(Outcome, String, i64)>,
    /// Voided: the reason and when.
    pub voided: Option<(String, i64)>,
    /// `Some`: the run's rows (or the assets it used) do not match their hash chain, the first
    /// mismatch in words. Such a run is listed and never used.
    pub tampered: Option<String>,
    /// Where its certificate in force stands (`None`: no certificate stored).
    pub certificate_state: Option<super::signer::CertificateState>,
    /// The number of its certificate in force (its newest amendment's, else its first).
    pub certificate_number: Option<String>,
    /// The numbers of its certificates that amendments replaced, oldest first.
    pub superseded_certificates: Vec<String>,
}

/// The latest flash into a device ([`Db::last_flash`]).
#[derive(Clone, Debug, PartialEq)]
pub struct LastFlash {
    /// The run that flashed.
    pub run_id: RunId,
    /// The record's CRC-32.
    pub crc32: u32,
    /// When.
    pub flashed_unix_s: i64,
    /// How the run ended (`None`: not finished).
    pub outcome: Option<Outcome>,
}
