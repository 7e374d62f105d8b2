//! The station's bookkeeping (`accelcal station`): which steps of a unit's line are done, with
//! what, so that a run stopped by Ctrl-C or by a crash of the station PC goes on where it stopped
//! and never repeats a step whose result is on disk; and the decisions between the steps that are
//! not a command's own (is the selected model one the node can apply?).
//!
//! The binary runs each step as the command a person would type (`accelcal info ...`), so each
//! step's checks, refusals, prompts and output are the command's own; this module holds no I/O
//! but the journal file.
//!
//! **The journal** (`station.json` in the unit's directory, written atomically after each step):
//! the unit's serial and device id, and per finished step its command line, the time and the
//! SHA-256 of each file it wrote. A step is skipped on a later run when its record is there and
//! its files still have those hashes; a file changed since is refused (bad input: the unit's
//! record of what was done no longer matches the files). A journal of another unit (serial), or a
//! node on the port that is another device than the journal's, is refused.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use accelcal_core::campaign::head_at::HeadAt;
use accelcal_core::document::SelectDoc;
use accelcal_core::error::{Classify, Kind};

/// The journal's file name in a unit's directory.
pub const JOURNAL: &str = "station.json";
/// The journal format (a journal of another version is refused).
pub const JOURNAL_VERSION: u32 = 1;

/// The steps of the line, in order. Their names are the journal's and the progress lines'.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Step {
    /// `info`: who the node is, and the record in force.
    Info,
    /// `verify` with the record in force, before anything changes (only when one is in force).
    AsFound,
    /// `acquire`: the campaign.
    Acquire,
    /// `select`: GMDH; the selection must be one the node applies.
    Select,
    /// `fit --record`: coefficients and the record.
    Fit,
    /// `flash`: the record into the node.
    Flash,
    /// `verify` with the new record.
    AsLeft,
    /// `report`: the certificate.
    Certificate,
}

impl Step {
    /// Every step, in order.
    pub const ALL: [Step; 8] = [
        Step::Info,
        Step::AsFound,
        Step::Acquire,
        Step::Select,
        Step::Fit,
        Step::Flash,
        Step::AsLeft,
        Step::Certificate,
    ];

    /// The step's name (journal, progress).
    pub fn name(self) -> &'static str {
        match self {
            Step::Info => "info",
            Step::AsFound => "as-found",
            Step::Acquire => "acquire",
            Step::Select => "select",
            Step::Fit => "fit",
            Step::Flash => "flash",
            Step::AsLeft => "as-left",
            Step::Certificate => "certificate",
        }
    }
}

/// What the station refuses or finds.
#[derive(Debug, thiserror::Error)]
pub enum StationError {
    /// The station's check standard is out of control: production runs are refused until a
    /// check is in control again (the station, not a unit, is in question: exit code 3).
    #[error(
        "station {station}: its check standard {serial} is out of control ({why}): production runs are \
         refused until a check of it is in control again (station --check-standard {serial})"
    )]
    OutOfControl {
        /// The station.
        station: String,
        /// The check standard's serial.
        serial: String,
        /// The rule broken, at which check, with the value and the limits.
        why: String,
    },
    /// The journal cannot be read or is not one.
    #[error("{path}: not a station journal: {reason}")]
    BadJournal {
        /// The journal.
        path: PathBuf,
        /// Why.
        reason: String,
    },
    /// The directory holds another unit's line.
    #[error("{dir} holds the line of unit {journal}, not of --serial {given}: choose another --out")]
    OtherUnit {
        /// The unit directory.
        dir: PathBuf,
        /// The journal's serial.
        journal: String,
        /// The serial given.
        given: String,
    },
    /// The node on the port is not the journal's device.
    #[error(
        "the node on the port is device {node}, but {dir} holds the line of device {journal} (unit {serial})"
    )]
    OtherDevice {
        /// The unit directory.
        dir: PathBuf,
        /// The journal's device id.
        journal: String,
        /// The node's device id.
        node: String,
        /// The unit's serial.
        serial: String,
    },
    /// A file a finished step wrote has changed since.
    #[error("{file} changed since step {step} wrote it: the journal no longer matches the unit's files (restore the file, or start the unit in a new --out)")]
    Changed {
        /// The file.
        file: PathBuf,
        /// The step that wrote it.
        step: &'static str,
    },
    /// The selection is not a model the node applies: the unit is rejected.
    #[error("{0}")]
    NotDeployable(String),
    /// Units of a station with several nodes were rejected (each said why as it was).
    #[error("{units} rejected ({total} units on the head; the others passed)")]
    Rejected {
        /// The rejected units' serials, comma-separated.
        units: String,
        /// The units on the head.
        total: usize,
    },
    /// The node runs another record than the one its run certified.
    #[error("unit {serial}: the node no longer runs its certified record: it runs {node}, but run {run_id} certified record CRC {certified} (someone flashed another record since): recalibrate it in a new --out, or flash the certified record back")]
    RecordReplaced {
        /// The unit's serial.
        serial: String,
        /// What the node runs: `record CRC xxxxxxxx`, or `no record`.
        node: String,
        /// The certified record's CRC-32 (8 hex digits).
        certified: String,
        /// The run that certified it.
        run_id: String,
    },
    /// The unit's run ended rejected; its line is closed.
    #[error("unit {serial} was rejected in run {run_id} (`accelcal history {serial}` says why): its line in {dir} is closed; to try the unit again, start it in a new --out")]
    RejectedBefore {
        /// The unit's serial.
        serial: String,
        /// The run.
        run_id: String,
        /// The unit directory.
        dir: PathBuf,
    },
}

impl Classify for StationError {
    fn kind(&self) -> Kind {
        match self {
            StationError::NotDeployable(_)
            | StationError::RecordReplaced { .. }
            | StationError::RejectedBefore { .. }
            | StationError::Rejected { .. } => Kind::Rejected,
            StationError::OutOfControl { .. } => Kind::Environment,
            _ => Kind::BadInput,
        }
    }
}

/// `accelcal` and `words` as one line to paste into a POSIX shell: each word quoted where it
/// must be (a path with a space, a `$`, a quote). A word holding a NUL, which no shell passes,
/// is written with its NUL escaped as `\0` (the line then does not run as it is).
pub fn shell_line(words: &[String]) -> String {
    let quoted: Vec<String> = words
        .iter()
        .map(|w| match shlex::try_quote(w) {
            Ok(q) => q.into_owned(),
            Err(_) => format!("'{}'", w.replace('\0', "\\0").replace('\'', "'\\''")),
        })
        .collect();
    std::iter::once("accelcal".to_string()).chain(quoted).collect::<Vec<_>>().join(" ")
}

/// One finished step.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct StepRecord {
    /// Which.
    pub step: Step,
    /// The command line it ran (after `accelcal`).
    pub command: Vec<String>,
    /// The same command line as one line a shell reads back (`accelcal` and each word quoted
    /// where it must be: [`shell_line`]); empty in a journal written before it was kept.
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub shell: String,
    /// When it finished, UTC (RFC 3339).
    pub finished: String,
    /// What it found, in one line (e.g. `PASS`, `FAIL: 2 of 6 positions`, `skipped: no record`).
    pub outcome: String,
    /// SHA-256 (hex) of each file it wrote, by name in the unit's directory.
    pub outputs: BTreeMap<String, String>,
    /// The wall time of its command, s (`null`: the step ran no command, or a journal written
    /// before steps were timed).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub seconds: Option<f64>,
    /// The head at each position of the step (acquire, and the verifications): the angles
    /// commanded and the angles the head read back once the move was done.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub positions: Vec<HeadAt>,
}

/// The head's commanded and read-back angles at each position of a verification's report
/// (positions of a report written before heads read back are left out).
pub fn verified_positions(report: &crate::verify::VerifyReport) -> Vec<HeadAt> {
    report
        .positions
        .iter()
        .filter_map(|p| {
            Some(HeadAt {
                position: p.position,
                alpha_deg: p.alpha_deg,
                beta_deg: p.beta_deg,
                read_back_alpha_deg: p.read_back_alpha_deg?,
                read_back_beta_deg: p.read_back_beta_deg?,
            })
        })
        .collect()
}

/// A unit's journal.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Journal {
    /// [`JOURNAL_VERSION`].
    pub version: u32,
    /// The unit's serial.
    pub serial: String,
    /// The node's device id (hex), once `info` has run.
    pub device_id: Option<String>,
    /// The calibration run in the database (a UUID), once begun.
    #[serde(default)]
    pub run_id: Option<String>,
    /// When the run began, seconds since the Unix epoch.
    #[serde(default)]
    pub started_unix_s: Option<i64>,
    /// The finished steps, in order.
    pub steps: Vec<StepRecord>,
    /// The database's chain heads after the steps (`accelcal-anchor seq=N chain_sha256=HEX`),
    /// oldest first: anchors kept outside the database (`db verify --anchors JOURNAL`).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub anchors: Vec<String>,
}

impl Journal {
    /// A new journal of unit `serial`.
    pub fn new(serial: &str) -> Journal {
        Journal {
            version: JOURNAL_VERSION,
            serial: serial.into(),
            device_id: None,
            run_id: None,
            started_unix_s: None,
            steps: Vec::new(),
            anchors: Vec::new(),
        }
    }

    /// Keeps a chain head after a step (the same one twice in a row once).
    pub fn anchor(&mut self, text: String) {
        if self.anchors.last() != Some(&text) {
            self.anchors.push(text);
        }
    }

    /// The journal in `dir` for unit `serial`: a new one when there is none, refused when it is
    /// another unit's or not a journal.
    pub fn open(dir: &Path, serial: &str) -> Result<Journal, StationError> {
        let path = dir.join(JOURNAL);
        let text = match std::fs::read_to_string(&path) {
            Ok(t) => t,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(Journal::new(serial)),
            Err(e) => return Err(StationError::BadJournal { path, reason: e.to_string() }),
        };
        let j: Journal = serde_json::from_str(&text)
            .map_err(|e| StationError::BadJournal { path: path.clone(), reason: e.to_string() })?;
        if j.version != JOURNAL_VERSION {
            return Err(StationError::BadJournal {
                path,
                reason: format!("version {}, this accelcal writes {JOURNAL_VERSION}", j.version),
            });
        }
        if j.serial != serial {
            return Err(StationError::OtherUnit { dir: dir.into(), journal: j.serial, given: serial.into() });
        }
        Ok(j)
    }

    /// Records the node's device id; refuses another device than the one recorded.
    pub fn set_device(&mut self, dir: &Path, device_id: &str) -> Result<(), StationError> {
        match &self.device_id {
            Some(d) if d != device_id => Err(StationError::OtherDevice {
                dir: dir.into(),
                journal: d.clone(),
                node: device_id.into(),
                serial: self.serial.clone(),
            }),
            _ => {
                self.device_id = Some(device_id.into());
                Ok(())
            }
        }
    }

    /// The record of `step` when it finished and its files in `dir` are as it wrote them;
    /// `Changed` when one differs or is gone.
    pub fn done(&self, dir: &Path, step: Step) -> Result<Option<&StepRecord>, StationError> {
        let Some(r) = self.steps.iter().find(|r| r.step == step) else { return Ok(None) };
        for (name, hash) in &r.outputs {
            let file = dir.join(name);
            if sha256_file(&file).as_deref() != Some(hash.as_str()) {
                return Err(StationError::Changed { file, step: step.name() });
            }
        }
        Ok(Some(r))
    }

    /// Adds a finished step (replacing an earlier record of it).
    pub fn finish(&mut self, record: StepRecord) {
        self.steps.retain(|r| r.step != record.step);
        self.steps.push(record);
        self.steps.sort_by_key(|r| r.step);
    }
}

/// SHA-256 of a file's bytes, hex ([`accelcal_core::digest::sha256_hex`]); `None` when it cannot be read.
pub fn sha256_file(path: &Path) -> Option<String> {
    std::fs::read(path).ok().map(|bytes| accelcal_core::digest::sha256_hex(&bytes))
}

/// The terms a node applies: model 4 (`1, ax, ay, az`), the only structure of the node's
/// uncompensated records (a thermal record adds terms in t, which a station run without a chamber
/// does not fit).
pub const DEPLOYABLE_TERMS: [&str; 4] = ["1", "ax", "ay", "az"];

/// Whether `select --json`'s document selects, on every channel, a model the node applies: its
/// terms within [`DEPLOYABLE_TERMS`] (a channel that needs fewer is fitted with model 4 all the
/// same: the extra coefficients come out near zero). Refused with the channels and terms that are
/// not, and the reason: the unit's output is not linear enough for the node's model within the
/// selection's tolerance.
pub fn deployable(select: &SelectDoc) -> Result<(), StationError> {
    let bad_doc =
        || StationError::NotDeployable("the select JSON has no channels with selected terms".into());
    if select.channels.is_empty() {
        return Err(bad_doc());
    }
    let tolerance = select.tolerance;
    let mut refused = Vec::new();
    for c in &select.channels {
        let name = &c.channel;
        let terms = &c.selected.terms;
        if terms.is_empty() {
            return Err(bad_doc());
        }
        let extra: Vec<&str> =
            terms.iter().map(String::as_str).filter(|t| !DEPLOYABLE_TERMS.contains(t)).collect();
        if !extra.is_empty() {
            let model4 = c.candidates.iter().find(|k| k.terms == DEPLOYABLE_TERMS).and_then(|k| k.criterion);
            refused.push(format!(
                "channel {name} selects {} (criterion {:.2} codes; model 4: {}): {} beyond model 4",
                terms.join(","),
                c.selected.criterion,
                model4.map_or("not scored".into(), |m| format!("{m:.2} codes")),
                extra.join(",")
            ));
        }
    }
    if refused.is_empty() {
        Ok(())
    } else {
        Err(StationError::NotDeployable(format!(
            "unit rejected: {}; the node applies model 4 (1,ax,ay,az) only, and it scores more than the selection's tolerance ({tolerance} codes) above the best (a noisy criterion: more --samples or positions; a nonlinear unit: not deployable)",
            refused.join("; ")
        )))
    }
}

#[cfg(test)]
mod tests {
    /// A journalled command line pastes back into a shell as the same words.
    #[test]
    fn a_shell_line_reads_back_as_its_words() {
        let words: Vec<String> = [
            "report",
            "--out",
            "/tmp/unit 42/cert.html",
            "--customer",
            "O'Neil & Sons $HOME",
            "--place",
            "a;b",
        ]
        .map(String::from)
        .to_vec();
        let line = super::shell_line(&words);
        assert!(line.starts_with("accelcal report --out "), "{line}");
        let back = shlex::split(&line).unwrap();
        assert_eq!(back[0], "accelcal");
        assert_eq!(back[1..], words[..], "{line}");
    }

    use super::*;
    use serde_json::json;

    fn record(step: Step, outputs: &[(&str, &str)]) -> StepRecord {
        StepRecord {
            step,
            command: vec![step.name().into()],
            shell: String::new(),
            finished: "2026-12-02T00:00:00Z".into(),
            outcome: "ok".into(),
            outputs: outputs.iter().map(|(n, h)| (n.to_string(), h.to_string())).collect(),
            seconds: None,
            positions: Vec::new(),
        }
    }

    #[test]
    fn a_journal_round_trips_and_refuses_another_unit_or_device() {
        let d = tempfile::tempdir().unwrap();
        let mut j = Journal::open(d.path(), "U-1").unwrap();
        assert_eq!(j, Journal::new("U-1"));
        j.set_device(d.path(), "aa").unwrap();
        std::fs::write(d.path().join("info.json"), b"{}").unwrap();
        let h = sha256_file(&d.path().join("info.json")).unwrap();
        j.finish(record(Step::Info, &[("info.json", &h)]));
        std::fs::write(d.path().join(JOURNAL), serde_json::to_vec(&j).unwrap()).unwrap();
        let mut back = Journal::open(d.path(), "U-1").unwrap();
        assert_eq!(back, j);
        assert!(back.done(d.path(), Step::Info).unwrap().is_some());
        assert!(back.done(d.path(), Step::Acquire).unwrap().is_none());
        let e = Journal::open(d.path(), "U-2").unwrap_err();
        assert!(matches!(e, StationError::OtherUnit { .. }) && e.kind() == Kind::BadInput, "{e}");
        let e = back.set_device(d.path(), "bb").unwrap_err();
        assert!(e.to_string().contains("device bb") && e.to_string().contains("device aa (unit U-1)"), "{e}");
        // A file changed since its step: refused, naming it and the step.
        std::fs::write(d.path().join("info.json"), b"{ }").unwrap();
        let e = back.done(d.path(), Step::Info).unwrap_err();
        assert!(e.to_string().contains("info.json changed since step info"), "{e}");
        std::fs::write(d.path().join(JOURNAL), b"not json").unwrap();
        assert!(matches!(Journal::open(d.path(), "U-1"), Err(StationError::BadJournal { .. })));
    }

    #[test]
    fn steps_keep_their_order_and_a_repeated_step_replaces_its_record() {
        let mut j = Journal::new("U");
        j.finish(record(Step::Fit, &[]));
        j.finish(record(Step::Info, &[]));
        j.finish(record(Step::Fit, &[("record.rec", "00")]));
        let order: Vec<Step> = j.steps.iter().map(|r| r.step).collect();
        assert_eq!(order, [Step::Info, Step::Fit]);
        assert_eq!(j.steps[1].outputs.len(), 1);
        let names: Vec<&str> = Step::ALL.iter().map(|s| s.name()).collect();
        assert_eq!(
            names,
            ["info", "as-found", "acquire", "select", "fit", "flash", "as-left", "certificate"]
        );
    }

    #[test]
    fn only_model_4_terms_are_deployable() {
        let channel = |name: &str, x: &[&str], criterion: f64, candidates: serde_json::Value| {
            json!({"channel": name, "selected": {"terms": x, "coefficients": [], "criterion": criterion},
                   "best_criterion": 3.0, "candidates_total": 2, "search_seconds": 0.0,
                   "models_per_second": 0.0, "unidentifiable": 0, "candidates": candidates})
        };
        let select = |channels: Vec<serde_json::Value>| -> SelectDoc {
            serde_json::from_value(json!({"basis": "paper", "criterion": "regularity", "split": "alternate",
                                          "tolerance": 1.0, "channels": channels}))
            .unwrap()
        };
        let doc = |x: &[&str]| {
            select(vec![
                channel(
                    "x",
                    x,
                    3.5,
                    json!([{"terms": ["1", "ax", "ay", "az"], "criterion": 5.25, "identifiable": true}]),
                ),
                channel("y", &["1", "ax", "ay", "az"], 3.4, json!([])),
            ])
        };
        deployable(&doc(&["1", "ax", "ay", "az"])).unwrap();
        deployable(&doc(&["1", "ax"])).unwrap();
        let e = deployable(&doc(&["1", "ax", "ay", "az", "ax^2"])).unwrap_err();
        assert_eq!(e.kind(), Kind::Rejected);
        let msg = e.to_string();
        assert!(
            msg.starts_with(
                "unit rejected: channel x selects 1,ax,ay,az,ax^2 (criterion 3.50 codes; model 4: 5.25 codes): ax^2 beyond model 4"
            ),
            "{msg}"
        );
        assert!(!msg.contains("channel y"), "{msg}");
        assert!(deployable(&select(vec![])).is_err());
    }
}
