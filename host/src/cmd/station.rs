//! `accelcal station`: the line for one unit, each step the command of its name run as a child
//! process (`accelcal info ...`, its stdin, stdout and stderr the station's, so a manual head's
//! prompts reach the operator), journalled in the unit's directory
//! ([`accelcal_core::station::Journal`]) so that the same command again goes on where a Ctrl-C or
//! a crash stopped it.
//!
//! A child's exit code says what happened: 0 done, 2 its input was refused, 130 stopped; 1 is a
//! rejection when the step is a verification whose JSON lists a failed position, else the
//! environment. Ctrl-C reaches the child (one process group) and the station alike: the station
//! lets the child finish its own stop (acquire keeps its complete positions) and then stops.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

use accelcal_core::error::{bad, environment, Interrupted};
use accelcal_core::output::write_json;
use accelcal_core::station::{deployable, sha256_file, Journal, Step, StepRecord, JOURNAL};
use accelcal_core::verify::Failed;
use anyhow::Context;

use crate::cli::StationArgs;

/// File names in the unit's directory.
const INFO: &str = "info.json";
const AS_FOUND: &str = "as-found.json";
const CAMPAIGN: &str = "campaign.csv";
const SELECT: &str = "select.json";
const FIT: &str = "fit.json";
const RECORD: &str = "record.rec";
const AS_LEFT: &str = "as-left.json";
const CERTIFICATE: &str = "certificate.html";

/// Plan of the verifications: the six test-turn positions.
const VERIFY_PLAN: &str = "six";

/// One run of the line.
struct Station<'a> {
    a: &'a StationArgs,
    dir: &'a Path,
    journal: Journal,
    stop: Arc<AtomicBool>,
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

    /// The node's link options.
    fn link(&self) -> Vec<String> {
        let l = &self.a.link;
        vec![
            "--port".into(),
            l.port.clone(),
            "--baud".into(),
            l.baud.to_string(),
            "--timeout-s".into(),
            l.timeout_s.to_string(),
        ]
    }

    /// The gravity options as given (the steps announce their source themselves).
    fn gravity(&self) -> Vec<String> {
        let a = self.a;
        match (a.local.latitude, a.g) {
            (Some(lat), _) => {
                let mut v = vec!["--latitude".into(), lat.to_string()];
                if let Some(h) = a.local.height {
                    v.extend(["--height".into(), h.to_string()]);
                }
                v
            }
            (None, Some(g)) => vec!["--g".into(), g.to_string()],
            (None, None) => vec![],
        }
    }

    /// A verification's command line (`fit`: the fit JSON of the record under test).
    fn verify_args(&self, json: &str, fit: Option<String>) -> Vec<String> {
        let mut v = vec!["verify".into()];
        v.extend(self.link());
        v.extend(["--head".into(), self.a.head.clone(), "--plan".into(), VERIFY_PLAN.into()]);
        v.extend(["--samples".into(), self.a.samples.to_string(), "--json".into(), self.p(json)]);
        if let Some(f) = fit {
            v.extend(["--fit".into(), f]);
        }
        if let Some(k) = self.a.coverage {
            v.extend(["--coverage".into(), k.to_string()]);
        }
        v.extend(self.gravity());
        v
    }

    /// Runs `accelcal ARGS` as step `step`; `Failed` on exit code 1, an error on anything but 0.
    fn run(&self, step: Step, args: &[String]) -> anyhow::Result<Exit> {
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
        eprintln!("station: step {n}/{} {}: accelcal {}", Step::ALL.len(), step.name(), args.join(" "));
        let exe = std::env::current_exe().context("finding the accelcal executable")?;
        let status = Command::new(exe)
            .args(args)
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

    /// Records `step` as finished with `outcome` and the hashes of `outputs`, and saves the
    /// journal.
    fn finish(
        &mut self,
        step: Step,
        command: Vec<String>,
        outcome: String,
        outputs: &[&str],
    ) -> anyhow::Result<()> {
        let outputs = outputs
            .iter()
            .map(|n| {
                let h = sha256_file(&self.path(n))
                    .with_context(|| format!("step {} did not write {}", step.name(), self.p(n)))?;
                Ok((n.to_string(), h))
            })
            .collect::<anyhow::Result<_>>()?;
        let finished = super::record::utc(super::created(None));
        eprintln!("station: {} {outcome}", step.name());
        self.journal.finish(StepRecord { step, command, finished, outcome, outputs });
        write_json(&self.path(JOURNAL), &self.journal)
    }

    /// Whether `step` is done (its files unchanged), saying so.
    fn done(&self, step: Step) -> anyhow::Result<bool> {
        Ok(match self.journal.done(self.dir, step)? {
            Some(r) => {
                eprintln!("station: {} done at {} ({}), kept", step.name(), r.finished, r.outcome);
                true
            }
            None => false,
        })
    }

    /// A verification's outcome from its JSON: `Ok` when every position passed, the count of
    /// failed positions otherwise; an error when the JSON is missing (the command did not get as
    /// far as checking: the environment).
    fn verdict(&self, json: &str) -> anyhow::Result<Result<usize, Failed>> {
        let text = std::fs::read_to_string(self.path(json))
            .map_err(|e| environment(format!("the verification wrote no {}", self.p(json)), e))?;
        let v: serde_json::Value = serde_json::from_str(&text).with_context(|| self.p(json))?;
        let positions = v["positions"].as_array().map(Vec::as_slice).unwrap_or_default();
        let failed = positions.iter().filter(|p| p["pass"] != serde_json::Value::Bool(true)).count();
        Ok(if failed == 0 && !positions.is_empty() {
            Ok(positions.len())
        } else {
            Err(Failed { failed, total: positions.len() })
        })
    }

    /// Step `info`, run every time: the node on the port must be the journal's device.
    fn info(&mut self) -> anyhow::Result<serde_json::Value> {
        let mut args = vec!["info".to_string()];
        args.extend(self.link());
        args.extend(["--json".into(), self.p(INFO)]);
        if let Exit::Failed = self.run(Step::Info, &args)? {
            return Err(anyhow::anyhow!("step info failed (its error is above)"));
        }
        let text = std::fs::read_to_string(self.path(INFO)).with_context(|| self.p(INFO))?;
        let info: serde_json::Value = serde_json::from_str(&text).with_context(|| self.p(INFO))?;
        let device = info["device_id"].as_str().context("info.json has no device_id")?.to_string();
        self.journal.set_device(self.dir, &device)?;
        let record = match info["record"]["crc"].as_str() {
            Some(crc) => format!("record CRC {crc} in force"),
            None => "no record in force".into(),
        };
        self.finish(Step::Info, args, format!("device {device}, {record}"), &[INFO])?;
        Ok(info)
    }

    /// Step `as-found`: the record in force, verified before anything changes. Its failure is
    /// the as-found result, not the station's.
    fn as_found(&mut self, info: &serde_json::Value) -> anyhow::Result<()> {
        if self.done(Step::AsFound)? {
            return Ok(());
        }
        if info["record"].is_null() {
            return self.finish(Step::AsFound, vec![], "skipped: no record in force".into(), &[]);
        }
        let _ = std::fs::remove_file(self.path(AS_FOUND));
        let fit = self.a.as_found_fit.as_ref().map(|p| p.display().to_string());
        let args = self.verify_args(AS_FOUND, fit);
        self.run(Step::AsFound, &args)?;
        let outcome = match self.verdict(AS_FOUND)? {
            Ok(n) => format!("PASS ({n} positions)"),
            Err(f) => format!("FAIL ({f})"),
        };
        self.finish(Step::AsFound, args, outcome, &[AS_FOUND])
    }

    fn acquire(&mut self) -> anyhow::Result<()> {
        if self.done(Step::Acquire)? {
            return Ok(());
        }
        let a = self.a;
        let mut args = vec!["acquire".to_string()];
        args.extend(self.link());
        args.extend(["--head".into(), a.head.clone(), "--plan".into(), a.plan.clone()]);
        args.extend(["--samples".into(), a.samples.to_string(), "--serial".into(), a.serial.clone()]);
        args.extend(["--out".into(), self.p(CAMPAIGN)]);
        if let Some(hz) = a.rate_hz {
            args.extend(["--rate-hz".into(), hz.to_string()]);
        }
        args.extend(self.gravity());
        if self.path(CAMPAIGN).exists() {
            args.push("--resume".into());
        }
        if let Exit::Failed = self.run(Step::Acquire, &args)? {
            return Err(anyhow::anyhow!("step acquire failed (its error is above)"));
        }
        self.finish(Step::Acquire, args, "campaign recorded".into(), &[CAMPAIGN])
    }

    fn select(&mut self) -> anyhow::Result<()> {
        if self.done(Step::Select)? {
            return Ok(());
        }
        let args: Vec<String> = vec![
            "select".into(),
            self.p(CAMPAIGN),
            "--json".into(),
            self.p(SELECT),
            "--tolerance".into(),
            self.a.select_tolerance.to_string(),
        ];
        if let Exit::Failed = self.run(Step::Select, &args)? {
            return Err(anyhow::anyhow!("step select failed (its error is above)"));
        }
        let text = std::fs::read_to_string(self.path(SELECT)).with_context(|| self.p(SELECT))?;
        let doc: serde_json::Value = serde_json::from_str(&text).with_context(|| self.p(SELECT))?;
        // Not journalled when rejected: the same command again selects again, and rejects again.
        deployable(&doc)?;
        self.finish(Step::Select, args, "model 4 deployable on every channel".into(), &[SELECT])
    }

    fn fit(&mut self) -> anyhow::Result<()> {
        if self.done(Step::Fit)? {
            return Ok(());
        }
        let device = self.journal.device_id.clone().context("no device id: step info has not run")?;
        let args: Vec<String> = vec![
            "fit".into(),
            self.p(CAMPAIGN),
            "--record".into(),
            self.p(RECORD),
            "--json".into(),
            self.p(FIT),
            "--device-id".into(),
            device,
        ];
        if let Exit::Failed = self.run(Step::Fit, &args)? {
            return Err(anyhow::anyhow!("step fit failed (its error is above)"));
        }
        self.finish(Step::Fit, args, "record written".into(), &[FIT, RECORD])
    }

    fn flash(&mut self) -> anyhow::Result<()> {
        if self.done(Step::Flash)? {
            return Ok(());
        }
        let a = self.a;
        let mut args = vec!["flash".to_string(), self.p(RECORD)];
        match &a.gdb {
            Some(g) => args.extend(["--gdb".into(), g.clone()]),
            None => {
                args.extend(["--chip".into(), a.chip.clone()]);
                if let Some(p) = &a.probe {
                    args.extend(["--probe".into(), p.clone()]);
                }
            }
        }
        args.extend(["--port".into(), a.link.port.clone(), "--baud".into(), a.link.baud.to_string()]);
        if let Exit::Failed = self.run(Step::Flash, &args)? {
            return Err(anyhow::anyhow!(
                "step flash failed (its error is above): the node runs the record it had"
            ));
        }
        self.finish(Step::Flash, args, "the node runs the new record".into(), &[])
    }

    /// Step `as-left`; its failure rejects the unit.
    fn as_left(&mut self) -> anyhow::Result<()> {
        if self.done(Step::AsLeft)? {
            return Ok(());
        }
        let _ = std::fs::remove_file(self.path(AS_LEFT));
        let args = self.verify_args(AS_LEFT, Some(self.p(FIT)));
        self.run(Step::AsLeft, &args)?;
        // Not journalled when rejected: the same command again verifies again.
        let n = self.verdict(AS_LEFT)??;
        self.finish(Step::AsLeft, args, format!("PASS ({n} positions)"), &[AS_LEFT])
    }

    fn certificate(&mut self) -> anyhow::Result<()> {
        if self.done(Step::Certificate)? {
            return Ok(());
        }
        let args: Vec<String> = vec![
            "report".into(),
            "--campaign".into(),
            self.p(CAMPAIGN),
            "--record".into(),
            self.p(RECORD),
            "--fit".into(),
            self.p(FIT),
            "--verify".into(),
            self.p(AS_LEFT),
            "--out".into(),
            self.p(CERTIFICATE),
        ];
        if let Exit::Failed = self.run(Step::Certificate, &args)? {
            return Err(anyhow::anyhow!("step certificate failed (its error is above)"));
        }
        self.finish(Step::Certificate, args, "written".into(), &[CERTIFICATE])
    }
}

/// Runs `accelcal station`.
pub fn run(a: &StationArgs) -> anyhow::Result<()> {
    let dir = a.out.as_path();
    std::fs::create_dir_all(dir).map_err(|e| environment(format!("creating {}", dir.display()), e))?;
    let journal = Journal::open(dir, &a.serial)?;
    // Ctrl-C goes to the step (same process group); the station waits for it to stop cleanly.
    let stop = super::live::stop_flag()?;
    let mut s = Station { a, dir, journal, stop };
    let info = s.info()?;
    s.as_found(&info)?;
    s.acquire()?;
    s.select()?;
    s.fit()?;
    s.flash()?;
    s.as_left()?;
    s.certificate()?;
    println!(
        "station: unit {} (device {}) PASS; certificate {}; journal {}",
        a.serial,
        s.journal.device_id.as_deref().unwrap_or("?"),
        s.p(CERTIFICATE),
        s.p(JOURNAL)
    );
    Ok(())
}
