//! `accelcal station`: the line for one unit, each step the command of its name run as a child
//! process (`accelcal info ...`, its stdin, stdout and stderr the station's, so a manual head's
//! prompts reach the operator), journalled in the unit's directory
//! ([`accelcal_line::station::Journal`]) so that the same command again goes on where a Ctrl-C or
//! a crash stopped it.
//!
//! A child's exit code says what happened: 0 done, 2 its input was refused, 130 stopped; 1 is a
//! rejection when the step is a verification whose JSON lists a failed position, else the
//! environment. Ctrl-C reaches the child (one process group) and the station alike: the station
//! lets the child finish its own stop (acquire keeps its complete positions) and then stops.
//!
//! A step's command is a value (`step_cmd::StepCommand`: paths, link, head, gravity and the
//! database run as typed fields); `StepCommand::args` is the one place that spells it as the
//! child's command line, and `journalled` the same line with the database named without its
//! password, as the journal keeps it.
//!
//! The database (`--db`, `ACCELCAL_DB`, else `calibration.sqlite` beside `--out`) is opened
//! before the node is touched; a database that cannot be written is refused there, and so is an
//! overdue or unknown `--head-asset`, before any unit's directory is made. The run begins after
//! `info`: its id and start time are journalled before the run's row, so a resume continues the
//! same run and a crash leaves no orphan; the serial is checked against the database's labels
//! (or moved by `--relabel REASON`), and the head asset's stated uncertainties go to the fit
//! step. The station stores each step's piece itself right after journalling the step (a resume
//! stores the kept steps' pieces again: a no-op, or the first store after a crash between journal
//! and database); the flash and certificate steps get `--db --run-id` and store their own, and
//! `report --db` ends the run `pass` with `store::PASS_REASON`. A node that does not run the
//! record its last run flashed is said plainly, naming both CRCs: a warning at a new unit's
//! as-found, `StationError::RecordReplaced` for a finished unit's directory.
//! `store::crash_point` is the fault injection of the crash tests.
//!
//! With several `--port`s there is one `Station` per unit (its own directory, journal, database
//! connection and run): `info` and as-found run unit by unit, `acquire_together` runs one
//! `acquire` over every unit that has not recorded its campaign, then each unit's remaining steps
//! run in turn (a rejection is collected, anything else stops the station).

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

use accelcal_core::campaign::head_at::HeadAt;
use accelcal_core::document::InfoDoc;
use accelcal_core::error::{bad, environment, Interrupted};
use accelcal_core::output::write_json;
use accelcal_db::{Asset, AssetError, AssetKind, Db, DbError, Outcome, Phase, Relabel, RunId, RunStart};
use accelcal_line::station::{
    deployable, sha256_file, shell_line, verified_positions, Journal, StationError, Step, StepRecord, JOURNAL,
};
use accelcal_line::verify::{Failed, VerifyReport};
use anyhow::Context;

use super::store::{crash_point, PASS_REASON};
use crate::settings::station::{Station as StationSettings, StationUnit};

mod check;
mod finish;
mod step_cmd;
mod steps;

use step_cmd::{Against, DbRun, FlashRoute, GravityGiven, Head, HeadU, Link, StepCommand};

/// File names in the unit's directory.
const INFO: &str = "info.json";
const AS_FOUND: &str = "as-found.json";
const AS_FOUND_FIT: &str = "as-found-fit.json";
const CAMPAIGN: &str = "campaign.csv";
const SELECT: &str = "select.json";
const FIT: &str = "fit.json";
const RECORD: &str = "record.rec";
const AS_LEFT: &str = "as-left.json";
const CERTIFICATE: &str = "certificate.html";
/// The certificate as a PDF, written beside the HTML page.
const CERTIFICATE_PDF: &str = "certificate.pdf";

/// Plan of the verifications: the six test-turn positions.
const VERIFY_PLAN: &str = "six";

/// One unit's run of the line.
struct Station<'a> {
    a: &'a StationSettings,
    /// The gravity `--g` or `--latitude`/`--height` (or the settings file) gave.
    gravity: Option<&'a super::Gravity>,
    u: &'a StationUnit,
    dir: &'a Path,
    journal: Journal,
    stop: Arc<AtomicBool>,
    /// The calibration database, and its spec as given (the children open it too).
    db: Db,
    db_spec: String,
    /// The run, once begun.
    run: Option<RunId>,
    /// The run ended `pass` (a finished unit run again: its steps are checked, nothing stored).
    ended: bool,
    /// `SERIAL: ` before the unit's progress lines when the head carries several units.
    tag: String,
    /// What step info found on the node (`info --json`), once it has run.
    info: Option<InfoDoc>,
    /// `--head-asset`'s certificate in force (checked before any node is touched).
    head_asset: Option<&'a Asset>,
    /// The gravity survey of `--gravity-asset`, which each run stores.
    survey: Option<&'a Asset>,
    /// The thermometer of `--thermometer-asset`, which each run stores.
    thermometer: Option<&'a Asset>,
    /// The head's angle error as its own units measure it, when that exceeds its certificate's
    /// (arcsec): what the budgets take instead.
    head_measured_u: Option<f64>,
    /// When the command of the step being run started (`run`), for the journal's `seconds`.
    step_start: std::cell::Cell<Option<std::time::Instant>>,
}

/// How a child ended.
enum Exit {
    Done,
    /// Exit code 1: the step's own failure (a verification's rejection, or the environment).
    Failed,
}

impl Station<'_> {
    fn path(&self, name: &str) -> PathBuf {
        self.dir.join(name)
    }

    fn p(&self, name: &str) -> String {
        self.path(name).display().to_string()
    }

    /// The node's link.
    fn link(&self) -> Link {
        link_of(self.a, std::slice::from_ref(&self.u.port))
    }

    /// The gravity as given (the steps announce its source themselves).
    fn gravity(&self) -> Option<GravityGiven> {
        use accelcal_core::campaign::GSource;
        self.gravity.map(|g| match g.provenance() {
            GSource::Normal { latitude_deg, height_m } => {
                GravityGiven::Site { latitude: latitude_deg, height: height_m }
            }
            GSource::Given { u_m_s2 } => GravityGiven::G { g: g.g, u: u_m_s2 },
            // A survey's value and uncertainty: the run stores the survey itself.
            p => GravityGiven::G { g: g.g, u: Some(p.standard_u(g.g).0) },
        })
    }

    /// A verification's command (`fit`: the fit JSON of the record under test).
    fn verify_cmd(&self, json: &str, fit: Option<PathBuf>) -> StepCommand {
        StepCommand::Verify {
            link: self.link(),
            head: head_of(self.a),
            plan: VERIFY_PLAN.into(),
            samples: self.a.verify_samples,
            json: self.path(json),
            fit,
            // `--spec` and `--coverage` exclude each other (clap, and the settings file's check).
            against: match &self.a.spec {
                Some(file) => Against::Spec { file: file.clone(), head_u: self.head_u() },
                None => Against::Scatter { coverage: self.a.coverage },
            },
            gravity: self.gravity(),
        }
    }

    /// The head asset's stated uncertainties as `fit` and `verify` take them (none without
    /// `--head-asset`), the angle's replaced by what the head's units measure when that is
    /// larger.
    fn head_u(&self) -> Option<HeadU> {
        self.head_asset.map(|h| HeadU {
            angle_arcsec: self.head_measured_u.unwrap_or(h.angle_u_arcsec),
            orthogonality_arcsec: h.orthogonality_u_arcsec,
        })
    }

    /// The database and run for a step that stores its own piece.
    fn db_run(&self) -> anyhow::Result<DbRun> {
        let run = self.run.context("no run: step info has not run")?;
        Ok(DbRun { spec: self.db_spec.clone(), run, anchor_log: self.a.anchor_log.clone() })
    }

    /// Runs `accelcal` with the command `cmd` as step `step`; `Failed` on exit code 1, an error
    /// on anything but 0.
    fn run(&self, step: Step, cmd: &StepCommand) -> anyhow::Result<Exit> {
        let n = Step::ALL.iter().position(|s| *s == step).unwrap_or(0) + 1;
        let stopped = || {
            anyhow::Error::new(Interrupted(format!(
                "stopped at step {}: run the same command again to go on from there ({} keeps what is done)",
                step.name(),
                self.p(JOURNAL)
            )))
        };
        if self.stop.load(Ordering::Relaxed) {
            return Err(stopped());
        }
        errln!(
            "station: {}step {n}/{} {}: {}",
            // The campaign is one step of every unit on the head.
            if step == Step::Acquire { "" } else { self.tag.as_str() },
            Step::ALL.len(),
            step.name(),
            shell_line(&cmd.journalled(&self.db.target()))
        );
        let exe = std::env::current_exe().context("finding the accelcal executable")?;
        self.step_start.set(Some(std::time::Instant::now()));
        let status = Command::new(exe)
            .args(cmd.args())
            .status()
            .map_err(|e| environment(format!("starting step {}", step.name()), e))?;
        match status.code() {
            Some(0) => Ok(Exit::Done),
            Some(130) => Err(stopped()),
            None if self.stop.load(Ordering::Relaxed) => Err(stopped()),
            Some(2) => Err(bad(format!("step {} refused its input (its error is above)", step.name()))),
            Some(1) => Ok(Exit::Failed),
            other => Err(anyhow::anyhow!(
                "step {} ended with {}",
                step.name(),
                other.map_or("a signal".to_string(), |c| format!("exit code {c}"))
            )),
        }
    }

    /// Records `step` as finished by `command` (none when nothing had to run) with `outcome` and
    /// the hashes of `outputs`, and saves the journal.
    fn finish(
        &mut self,
        step: Step,
        command: Option<&StepCommand>,
        outcome: String,
        outputs: &[&str],
    ) -> anyhow::Result<()> {
        let outputs: std::collections::BTreeMap<String, String> = outputs
            .iter()
            .map(|n| {
                let h = sha256_file(&self.path(n))
                    .with_context(|| format!("step {} did not write {}", step.name(), self.p(n)))?;
                Ok((n.to_string(), h))
            })
            .collect::<anyhow::Result<_>>()?;
        let finished = super::record::utc(super::created(None));
        errln!("station: {}{} {outcome}", self.tag, step.name());
        let command = command.map(|c| c.journalled(&self.db.target())).unwrap_or_default();
        let seconds = self.step_start.take().map(|t| t.elapsed().as_secs_f64());
        let positions = match step {
            Step::Acquire => HeadAt::read_all(&self.path(CAMPAIGN))?,
            Step::AsFound | Step::AsLeft => {
                let name = if step == Step::AsFound { AS_FOUND } else { AS_LEFT };
                match outputs.contains_key(name) {
                    true => verified_positions(&VerifyReport::read(&self.path(name))?),
                    false => Vec::new(),
                }
            }
            _ => Vec::new(),
        };
        let shell = if command.is_empty() { String::new() } else { shell_line(&command) };
        self.journal.finish(StepRecord {
            step,
            command,
            shell,
            finished,
            outcome,
            outputs,
            seconds,
            positions,
        });
        // The chain head after the step: the journal is an anchor kept outside the database.
        if let Some(anchor) = self.db.chain_head()? {
            self.journal.anchor(anchor.text());
        }
        write_json(&self.path(JOURNAL), &self.journal)?;
        crash_point(&format!("journal:{}", step.name()));
        Ok(())
    }

    /// Whether `step` is done (its files unchanged), saying so.
    fn done(&self, step: Step) -> anyhow::Result<bool> {
        Ok(match self.journal.done(self.dir, step)? {
            Some(r) => {
                errln!("station: {}{} done at {} ({}), kept", self.tag, step.name(), r.finished, r.outcome);
                true
            }
            None => false,
        })
    }

    /// A verification's outcome from its JSON: `Ok` when every position passed, the count of
    /// failed positions otherwise; an error when the JSON is missing (the command did not get as
    /// far as checking: the environment).
    fn verdict(&self, json: &str) -> anyhow::Result<(VerifyReport, Result<usize, Failed>)> {
        if let Err(e) = std::fs::metadata(self.path(json)) {
            return Err(environment(format!("the verification wrote no {}", self.p(json)), e));
        }
        let v = VerifyReport::read(&self.path(json))?;
        let verdict = match v.failure() {
            None => Ok(v.positions.len()),
            Some(f) => Err(f),
        };
        Ok((v, verdict))
    }

    /// Step `info`, run every time: the node on the port must be the journal's device.
    fn info(&mut self) -> anyhow::Result<InfoDoc> {
        let cmd = StepCommand::Info { link: self.link(), json: self.path(INFO) };
        if let Exit::Failed = self.run(Step::Info, &cmd)? {
            return Err(anyhow::anyhow!("step info failed (its error is above)"));
        }
        let text = std::fs::read_to_string(self.path(INFO)).with_context(|| self.p(INFO))?;
        let info = InfoDoc::parse(&text).with_context(|| self.p(INFO))?;
        let device = info.device_id.clone();
        self.journal.set_device(self.dir, &device)?;
        let record = match &info.record {
            Some(r) => format!("record CRC {} in force", r.crc),
            None => "no record in force".into(),
        };
        self.finish(Step::Info, Some(&cmd), format!("device {device}, {record}"), &[INFO])?;
        self.info = Some(info.clone());
        self.begin(&info, &device)?;
        Ok(info)
    }

    /// The CRC (8 hex digits) of the record the node runs, from step info.
    fn crc_in_force(&self) -> Option<String> {
        self.info.as_ref()?.record.as_ref().map(|r| r.crc.to_ascii_lowercase())
    }

    /// Whether the node runs the record with CRC-32 `crc` (step info says).
    fn runs_record(&self, crc: u32) -> bool {
        self.crc_in_force().as_deref() == Some(format!("{crc:08x}").as_str())
    }

    /// What the node runs, in words.
    fn in_force_words(&self) -> String {
        self.crc_in_force().map_or("no record".into(), |c| format!("record CRC {c}"))
    }

    /// A new run: says plainly when the node does not run the record its last flash in the
    /// database wrote (another unit's record flashed since, or a record written by hand).
    fn warn_replaced(&mut self) -> anyhow::Result<()> {
        let (Some(device), Some(run)) = (self.journal.device_id.clone(), self.run) else { return Ok(()) };
        // A resumed run whose own record the node runs (flashed before the stop, noted or not).
        let p = self.db.progress(run)?;
        if p.record.is_some_and(|rec| self.runs_record(rec.crc32())) {
            return Ok(());
        }
        let Some(last) = self.db.last_flash(&device, Some(run))? else { return Ok(()) };
        if !self.runs_record(last.crc32) {
            let last_crc = format!("{:08x}", last.crc32);
            let what = match last.outcome {
                Some(Outcome::Pass) => "its certified record",
                _ => "the record its last run flashed",
            };
            errln!(
                "station: {}WARNING: the node no longer runs {what}: it runs {}, but run {} flashed record CRC {last_crc} on {}",
                self.tag,
                self.in_force_words(),
                last.run_id,
                accelcal_core::output::utc_date_time(last.flashed_unix_s)
            );
        }
        Ok(())
    }

    /// Begins the run in the database (the journal keeps its id and time: the same run on a
    /// resume), or refuses one that has ended.
    fn begin(&mut self, info: &InfoDoc, device: &str) -> anyhow::Result<()> {
        let run = match &self.journal.run_id {
            Some(r) => RunId::parse(r)?,
            None => RunId::new(),
        };
        let started = *self.journal.started_unix_s.get_or_insert_with(accelcal_db::now_unix_s);
        let gravity = self.gravity.cloned().unwrap_or_else(super::Gravity::assumed);
        let (g, g_source) = (gravity.g, gravity.stored());
        let start = RunStart {
            run_id: run,
            device_id: device.to_string(),
            serial: self.u.serial.clone(),
            station: self.a.station_name.clone().unwrap_or_else(super::store::host_name),
            head: self.a.head.to_string(),
            operator: self.a.operator.clone().unwrap_or_else(super::store::user_name),
            started_unix_s: started,
            software_version: env!("CARGO_PKG_VERSION").into(),
            firmware_version: info.firmware.clone(),
            g_m_s2: g,
            g_source,
        };
        // The journal keeps the id before the database has the run: a crash in between resumes
        // the same run, never a second one.
        if self.journal.run_id.is_none() {
            self.journal.run_id = Some(run.to_string());
            write_json(&self.path(JOURNAL), &self.journal)?;
            crash_point("journal:run");
        }
        let relabel =
            self.a.relabel.clone().map(|reason| Relabel { reason, operator: start.operator.clone() });
        let new = self.db.begin_run(&start, relabel.as_ref())? == accelcal_db::Stored::New;
        crash_point("db:run");
        let p = self.db.progress(run)?;
        if p.outcome == Some(Outcome::Rejected) {
            return Err(StationError::RejectedBefore {
                serial: self.u.serial.clone(),
                run_id: run.to_string(),
                dir: self.dir.to_path_buf(),
            }
            .into());
        }
        if let Some(why) = &p.voided {
            return Err(bad(format!(
                "run {run} of unit {} was voided ({why}): its line in {} is closed; start the unit in a new --out",
                self.u.serial,
                self.dir.display()
            )));
        }
        self.ended = p.outcome.is_some();
        if !self.ended {
            for asset in [self.head_asset, self.survey, self.thermometer].into_iter().flatten() {
                self.db.store_run_asset(run, asset)?;
                crash_point("db:run_asset");
            }
        }
        self.run = Some(run);
        errln!(
            "station: {}run {run} {} in {}",
            self.tag,
            if new { "begun" } else { "continued" },
            self.db.target()
        );
        Ok(())
    }

    fn run_id(&self) -> anyhow::Result<RunId> {
        self.run.context("no run: step info has not run")
    }

    /// Ends the run rejected, and returns the rejection.
    fn reject(&mut self, e: anyhow::Error) -> anyhow::Error {
        let run = match self.run_id() {
            Ok(r) => r,
            Err(e2) => return e2,
        };
        match self.db.finish_run(run, Outcome::Rejected, &crate::words::line(&e)) {
            Ok(_) => {
                crash_point("db:rejected");
                e
            }
            Err(db) => {
                anyhow::Error::new(db).context(format!("storing the rejection ({})", crate::words::line(&e)))
            }
        }
    }
}

/// The head, with the time a move may take and the read-back tolerance when it is driven (a
/// manual head has neither).
fn head_of(a: &StationSettings) -> Head {
    let driven = a.head != accelcal_line::head::HeadSpec::Manual;
    Head {
        spec: a.head.clone(),
        timeout_s: driven.then_some(a.head_timeout_s),
        tolerance_arcsec: a.head_tolerance_arcsec.filter(|_| driven),
        settle_s: a.settle_s,
        zaber: a.zaber.clone(),
    }
}

/// The link to the nodes on `ports`.
fn link_of(a: &StationSettings, ports: &[String]) -> Link {
    Link { ports: ports.to_vec(), baud: a.baud, timeout_s: a.timeout_s }
}

/// Step `acquire` of every unit that has not done it, in one `acquire` over all their nodes (one
/// head move per position, every node recorded there), then each unit's campaign stored.
fn acquire_together(units: &mut [&mut Station<'_>]) -> anyhow::Result<()> {
    let mut todo = Vec::new();
    for (i, s) in units.iter().enumerate() {
        if !s.done(Step::Acquire)? {
            todo.push(i);
        }
    }
    if let Some(&first) = todo.first() {
        let a = units[first].a;
        let ports: Vec<String> = todo.iter().map(|&i| units[i].u.port.clone()).collect();
        let cmd = StepCommand::Acquire {
            link: link_of(a, &ports),
            head: head_of(a),
            plan: a.plan.clone(),
            samples: a.samples,
            units: todo.iter().map(|&i| (units[i].u.serial.clone(), units[i].path(CAMPAIGN))).collect(),
            rate_hz: a.rate_hz,
            gravity: units[first].gravity(),
            resume: todo.iter().any(|&i| units[i].path(CAMPAIGN).exists()),
        };
        if let Exit::Failed = units[first].run(Step::Acquire, &cmd)? {
            return Err(anyhow::anyhow!("step acquire failed (its error is above)"));
        }
        // One campaign for every unit on the head: each journal states its time.
        let started = units[first].step_start.get();
        for &i in &todo {
            units[i].step_start.set(started);
            units[i].finish(Step::Acquire, Some(&cmd), "campaign recorded".into(), &[CAMPAIGN])?;
        }
    }
    for s in units.iter_mut() {
        s.store_campaign()?;
    }
    Ok(())
}

/// The database whose register holds asset `id`: an asset is unknown where no database is yet.
fn register(db_spec: &str, id: &str) -> anyhow::Result<Db> {
    match Db::open_existing(db_spec) {
        Err(DbError::NoDatabase { .. } | DbError::NotCreated { .. }) => {
            Err(DbError::Asset(AssetError::Unknown {
                asset_id: id.into(),
                target: format!(
                    "{} (no calibration there yet)",
                    accelcal_db::Target::parse(db_spec).map(|t| t.display()).unwrap_or_default()
                ),
            })
            .into())
        }
        r => Ok(r?),
    }
}

/// The thermometer `--thermometer-asset` names, read from the register before any node is
/// touched.
fn thermometer_in_force(db_spec: &str, id: &str) -> anyhow::Result<Asset> {
    let t =
        register(db_spec, id)?.asset_in_force(id, AssetKind::Thermometer, accelcal_db::asset::today_utc())?;
    errln!(
        "station: thermometer {} (certificate {}, due {}{})",
        t.asset_id,
        t.certificate,
        t.due_date,
        t.value.map(|v| format!("; u {} K per reading", v.u)).unwrap_or_default()
    );
    Ok(t)
}

/// The gravity survey `--gravity-asset` names, read from the register before any node is
/// touched: the station's gravity, and the asset each run stores.
fn survey_in_force(
    db_spec: &str,
    gravity: Option<&super::Gravity>,
) -> anyhow::Result<(Option<super::Gravity>, Option<Asset>)> {
    match gravity {
        Some(g @ super::Gravity { source: super::Source::Asset { id }, .. }) => {
            let mut db = register(db_spec, id)?;
            let (g, survey) = crate::app::gravity::resolve(g, Some(&mut db))?;
            errln!("station: g = {} m/s² ({}; u {:.1e} m/s²)", g.g, g.words(), g.standard_u().0);
            Ok((Some(g), survey))
        }
        g => Ok((g.cloned(), None)),
    }
}

/// What the station took from its plan file's header, when it states anything.
fn plan_dwell_words(p: &crate::resolved::PlanDwell) -> Option<String> {
    let what = match (p.samples, p.rate_hz) {
        (None, None) => return None,
        (Some(n), Some(r)) => format!("{n} sample sets per position at {r} Hz"),
        (Some(n), None) => format!("{n} sample sets per position"),
        (None, Some(r)) => format!("{r} Hz"),
    };
    Some(format!("plan {}: {what}, from its header", p.path.display()))
}

/// Runs `accelcal station`: every unit's `info` and as-found verification, one node after the
/// other; the campaigns together; then each unit's line to its certificate. A rejected unit does
/// not stop the others (the station ends with exit code 1 after them); any other error stops the
/// station.
pub fn run(
    a: &StationSettings,
    gravity: Option<&super::Gravity>,
    config: Option<&crate::resolved::ConfigUse>,
) -> anyhow::Result<()> {
    if let Some(c) = config {
        let overridden = match c.overridden.as_slice() {
            [] => String::new(),
            keys => format!("; the command line overrides {}", keys.join(", ")),
        };
        errln!("station: settings {} ({}){overridden}", c.path.display(), c.keys.join(", "));
    }
    if let Some(line) = a.plan_dwell.as_ref().and_then(plan_dwell_words) {
        errln!("station: {line}");
    }
    let t0 = std::time::Instant::now();
    let specs = &a.units;
    let db_spec = a.db.clone();
    let mut stations = Vec::with_capacity(specs.len());
    // Ctrl-C goes to the step (same process group); the station waits for it to stop cleanly.
    let stop = super::live::stop_flag()?;
    // The head's register entry first: an overdue or unknown head stops the station here.
    let head = a.head_asset.as_deref().map(|id| head_in_force(&db_spec, id)).transpose()?;
    let (head_asset, head_measured_u) = match head {
        Some((h, m)) => (Some(h), m),
        None => (None, None),
    };
    let (gravity, survey) = survey_in_force(&db_spec, gravity)?;
    let thermometer =
        a.thermometer_asset.as_deref().map(|id| thermometer_in_force(&db_spec, id)).transpose()?;
    let gravity = gravity.as_ref();
    // A station whose check standard is out of control makes no calibration.
    let station_name = a.station_name.clone().unwrap_or_else(super::store::host_name);
    if a.check_standard.is_none() {
        check::refuse_out_of_control(&db_spec, &station_name)?;
    }
    if let Some(p) = &a.spec {
        let s = super::spec::read(p)?;
        errln!("station: specification {}", s.describe());
    }
    for u in specs {
        let journal = Journal::open(&u.dir, &u.serial)?;
        std::fs::create_dir_all(&u.dir)
            .map_err(|e| environment(format!("creating {}", u.dir.display()), e))?;
        // Opened before the node is touched: an unreachable database stops the station there.
        let db = super::store::with_anchor_log(Db::open(&db_spec)?, a.anchor_log.as_deref())?;
        stations.push(Station {
            a,
            gravity,
            u,
            dir: &u.dir,
            journal,
            stop: stop.clone(),
            db,
            db_spec: db_spec.clone(),
            run: None,
            ended: false,
            info: None,
            head_asset: head_asset.as_ref(),
            survey: survey.as_ref(),
            thermometer: thermometer.as_ref(),
            head_measured_u,
            step_start: std::cell::Cell::new(None),
            tag: if specs.len() > 1 { format!("{}: ", u.serial) } else { String::new() },
        });
    }
    if a.check_standard.is_some() {
        return stations[0].check_standard(&station_name);
    }
    let mut open: Vec<&mut Station<'_>> = Vec::new();
    for s in stations.iter_mut() {
        let info = s.info()?;
        if s.ended {
            s.passed_before()?;
            continue;
        }
        s.warn_replaced()?;
        s.as_found(&info)?;
        open.push(s);
    }
    if open.is_empty() {
        return Ok(());
    }
    acquire_together(&mut open)?;
    let mut rejected = Vec::new();
    let result = after_acquire_all(open, specs.len(), &mut rejected);
    errln!("station: {}", time_summary(&stations, t0.elapsed().as_secs_f64()));
    result?;
    if rejected.is_empty() {
        Ok(())
    } else {
        Err(StationError::Rejected { units: rejected.join(", "), total: specs.len() }.into())
    }
}

/// Each unit's steps after the campaign; a rejected unit among several is named in `rejected`
/// and does not stop the others.
///
/// With several units the steps run in two lanes, so that the head waits only for the first
/// unit's flash: this thread prepares the units one after the other (select, fit, flash), and a
/// second thread takes each prepared unit in turn to the head (as-left verification) and to its
/// certificate. While the head verifies one unit the next one is being flashed. A lane's error
/// that is not a rejection ends it: the other lane finishes the unit it is on (and the head lane
/// the units already prepared, each journalled), then the station stops with the error.
fn after_acquire_all(
    open: Vec<&mut Station<'_>>,
    units: usize,
    rejected: &mut Vec<String>,
) -> anyhow::Result<()> {
    // A rejection among several units is noted; anything else is returned.
    let note = |s: &Station<'_>, r: anyhow::Result<()>, rejected: &mut Vec<String>| match r {
        Err(e) if units > 1 && is_rejection(&e) => {
            errln!("station: unit {} REJECTED: {}", s.u.serial, crate::words::line(&e));
            rejected.push(s.u.serial.clone());
            Ok(())
        }
        r => r,
    };
    if open.len() < 2 {
        for s in open {
            let r = s.after_acquire();
            note(s, r, rejected)?;
        }
        return Ok(());
    }
    // The lanes note their rejections apart: the station names them in the units' order.
    let order: Vec<String> = open.iter().map(|s| s.u.serial.clone()).collect();
    let result = std::thread::scope(|scope| {
        let (ready, prepared) = std::sync::mpsc::channel::<&mut Station<'_>>();
        let head = scope.spawn(move || {
            let mut rejected = Vec::new();
            for s in prepared {
                let r = s.conclude();
                note(s, r, &mut rejected)?;
            }
            Ok::<_, anyhow::Error>(rejected)
        });
        let mut prep = Ok(());
        for s in open {
            match s.prepare() {
                // A send fails when the head lane has ended (its error follows): this unit
                // waits, flashed and journalled, for the next run.
                Ok(()) => {
                    if ready.send(s).is_err() {
                        break;
                    }
                }
                // A rejected unit is not for the head.
                Err(e) => {
                    if let Err(e) = note(s, Err(e), rejected) {
                        prep = Err(e);
                        break;
                    }
                }
            }
        }
        drop(ready);
        let head = head.join().unwrap_or_else(|p| std::panic::resume_unwind(p));
        match (prep, head) {
            (Ok(()), Ok(r)) => {
                rejected.extend(r);
                Ok(())
            }
            (Err(e), Ok(r)) => {
                rejected.extend(r);
                Err(e)
            }
            (Ok(()), Err(e)) => Err(e),
            (Err(p), Err(h)) => {
                errln!("station: {}", crate::words::line(&p));
                Err(h)
            }
        }
    });
    rejected.sort_by_key(|r| order.iter().position(|o| o == r));
    result
}

/// How the station's `wall` seconds were spent, from the units' journals: each step's command
/// time summed over the units (the campaign, one for every unit on the head, once), and the
/// share of the run during which the head was neither moving nor dwelling (the steps that use
/// the head are the as-found verifications, the campaign and the as-left verifications; the
/// rest of the time the head waits).
fn time_summary(stations: &[Station<'_>], wall: f64) -> String {
    let mut busy = 0.0;
    let steps: Vec<String> = Step::ALL
        .iter()
        .map(|&step| {
            let times =
                stations.iter().filter_map(|s| s.journal.steps.iter().find(|r| r.step == step)?.seconds);
            // (+ 0.0: an empty sum of f64 is −0.0.)
            let t = if step == Step::Acquire { times.fold(0.0, f64::max) } else { times.sum::<f64>() + 0.0 };
            if matches!(step, Step::AsFound | Step::Acquire | Step::AsLeft) {
                busy += t;
            }
            format!("{} {t:.1} s", step.name())
        })
        .collect();
    let idle = (wall - busy).max(0.0);
    format!(
        "time {wall:.1} s: {}; the head moving or dwelling {busy:.1} s, waiting {idle:.1} s ({:.0} % of the run)",
        steps.join(", "),
        100.0 * idle / wall.max(1e-9)
    )
}

/// `--head-asset`'s certificate in force, read from the database without creating it (a missing
/// database holds no asset), and the head's angle error as its own units measure it when that
/// exceeds the certificate's angle uncertainty (arcsec; `fit --head-asset` takes it the same way).
fn head_in_force(db_spec: &str, id: &str) -> anyhow::Result<(Asset, Option<f64>)> {
    let mut db = register(db_spec, id)?;
    let h = db.asset_in_force(id, AssetKind::Head, accelcal_db::asset::today_utc())?;
    errln!(
        "station: head {} (certificate {}, due {}; angle u {} arcsec, orthogonality u {} arcsec)",
        h.asset_id,
        h.certificate,
        h.due_date,
        h.angle_u_arcsec,
        h.orthogonality_u_arcsec
    );
    let measured = super::fleet::measured_head_angle(&mut db, id)?;
    let over = match measured {
        Some(m) => match super::fleet::over_certificate(&h, &m) {
            Some(warning) => {
                errln!("warning: {warning}");
                Some((m.rms_arcsec * 10.0).ceil() / 10.0)
            }
            None => {
                errln!(
                    "station: head {}: its last {} units measure {:.1}″ of angle error, within its certificate's",
                    h.asset_id, m.units, m.rms_arcsec
                );
                None
            }
        },
        None => None,
    };
    Ok((h, over))
}

/// Whether `e` rejects the unit (rather than failing the environment).
fn is_rejection(e: &anyhow::Error) -> bool {
    crate::exit::kind(e) == accelcal_core::error::Kind::Rejected
}
