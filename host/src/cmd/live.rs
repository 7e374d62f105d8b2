//! The commands that talk to a running node over its link: `accelcal info`, `accelcal output`,
//! `accelcal acquire`.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Duration;

use accelcal_core::campaign::identity::Identity;
use accelcal_core::error::{bad, Interrupted};
use accelcal_core::output::write_json;
use accelcal_line::acquire::{self, AcquireConfig, NodeRun, PositionReport, Progress, StaticRule};
use accelcal_line::head::{HeadSettings, Positioner};
use accelcal_line::node::session::{device_id_hex, firmware_version, Session};
use accelcal_line::verify::{
    calibrated_rule, uncertainty_from_fit_json, verify, PositionCheck, Tolerance, VerifyConfig, VerifyReport,
};
use accelcal_shared::wire::{Info, Output, RecordStatus};

use super::{Gravity, Source};
use crate::settings::line::{self, Acquire, Judged, Link, SetOutput, Verify};

fn open(link: &Link) -> anyhow::Result<Session> {
    Ok(Session::open(&link.port, link.baud, link.timeout)?)
}

/// The reset cause's variant name (`PowerOn`, `IndependentWatchdog`, ...).
fn reset_name(i: &Info) -> String {
    format!("{:?}", i.reset_cause)
}

/// `accelcal info`'s JSON document (the field names are an interface).
pub fn info_json(i: &Info) -> accelcal_core::document::InfoDoc {
    accelcal_core::document::InfoDoc {
        version: accelcal_core::document::INFO_VERSION,
        device_id: device_id_hex(&i.device_id),
        firmware: firmware_version(i.firmware),
        record: accelcal_core::document::RecordInForceDoc::of(i.record),
        rate_hz: i.rate_hz,
        overruns: i.overruns,
        reset_cause: reset_name(i),
    }
}

/// What `accelcal info` prints.
pub fn info_text(i: &Info) -> String {
    let record = match i.record {
        RecordStatus::InUse { slot, sequence, created_unix_s, crc } => format!(
            "slot {slot}, sequence {sequence}, created {} ({created_unix_s}), CRC {crc:08x}",
            super::record::utc(created_unix_s)
        ),
        RecordStatus::Missing(f) => format!("none ({f}): the node streams UNCALIBRATED codes"),
    };
    format!(
        "device id   {}\nfirmware    {} (link protocol {})\nrecord      {record}\nrate        {} Hz per channel\n\
         overruns    {} sample sets lost since boot\nlast reset  {}\noutput      {}",
        device_id_hex(&i.device_id),
        firmware_version(i.firmware),
        i.protocol,
        i.rate_hz,
        i.overruns,
        i.reset_cause,
        i.output.name()
    )
}

/// Runs `accelcal info`.
pub fn run_info(a: &line::Info) -> anyhow::Result<()> {
    let mut s = open(&a.link)?;
    let info = s.info()?;
    outln!("{}", info_text(&info))?;
    if let Some(p) = &a.json {
        write_json(p, &info_json(&info))?;
    }
    Ok(())
}

/// Runs `accelcal output`.
pub fn run_output(a: &SetOutput) -> anyhow::Result<()> {
    let mut s = open(&a.link)?;
    let st = s.set_output(a.mode)?;
    outln!("output: the node now streams {}", st.output.name())?;
    if let (Output::Calibrated, RecordStatus::Missing(f)) = (st.output, st.record) {
        outln!(
            "note: the node has no record ({f}): its calibrated stream is raw codes flagged uncalibrated"
        )?;
    }
    Ok(())
}

/// Progress lines on stderr.
struct Lines;

fn duration(d: Duration) -> String {
    let s = d.as_secs();
    if s >= 60 {
        format!("{} min {:02} s", s / 60, s % 60)
    } else {
        format!("{s} s")
    }
}

impl Progress for Lines {
    fn position_done(&mut self, r: &PositionReport, done: usize, total: usize, left: Duration) {
        errln!(
            "position {done}/{total} (alpha {} deg, beta {} deg): static after {:.2} s ({} sets dropped), recorded; \
             {} sets lost; mean codes {:.1} {:.1} {:.1}; about {} left",
            r.angles.0,
            r.angles.1,
            r.settle_s,
            r.dropped,
            r.lost,
            r.mean[0],
            r.mean[1],
            r.mean[2],
            duration(left)
        );
    }
    fn started(&mut self, from: usize, total: usize, rule: &StaticRule) {
        errln!("acquire: positions {} to {total}; {}", from + 1, rule.describe());
    }
    fn note(&mut self, line: &str) {
        errln!("note: {line}");
    }
    fn resumed(&mut self, done: usize, truncated_rows: usize) {
        errln!(
            "resume: {done} complete positions kept{}",
            if truncated_rows > 0 {
                format!(", {truncated_rows} rows of an unfinished position removed")
            } else {
                String::new()
            }
        );
    }
}

/// The gravity of a command at the rig: the user's (`--g`, `--latitude`), or the announced 9.81
/// fallback, announced here, once.
fn rig_gravity(stated: Option<&Gravity>) -> Gravity {
    stated.cloned().unwrap_or_else(|| {
        errln!(
            "note: {}",
            super::g_fallback("neither --g nor --latitude/--height was given for the rig's site")
        );
        Gravity::assumed()
    })
}

/// A flag set by Ctrl-C or SIGTERM.
pub fn stop_flag() -> anyhow::Result<Arc<AtomicBool>> {
    let stop = Arc::new(AtomicBool::new(false));
    let s = stop.clone();
    ctrlc::set_handler(move || s.store(true, Ordering::Relaxed))
        .map_err(|e| anyhow::anyhow!("cannot install the Ctrl-C handler: {e}"))?;
    Ok(stop)
}

/// The head the settings name, connected; an operator is prompted on stderr. The acquisition
/// and the verification home it before their first move.
fn connect_head(head: &HeadSettings, stop: &Arc<AtomicBool>) -> anyhow::Result<Box<dyn Positioner>> {
    accelcal_line::head::open(head, stop.clone(), Box::new(std::io::stderr()))
}

/// `acquire --samples` when it is not given (and not resumed).
pub const DEFAULT_SAMPLES: usize = 400;

/// `--resume`'s samples, rate and g: the campaign's (its header), whatever the defaults; an
/// option that contradicts them is refused, naming both (checked before the node is opened).
/// With several campaigns (one per node), they must agree.
fn resumed_settings(a: &Acquire) -> anyhow::Result<(usize, Option<u32>, (f64, String))> {
    let stated = a.stated.as_ref();
    let mut first: Option<(&std::path::Path, acquire::ResumeSettings)> = None;
    for out in a.nodes.iter().map(|n| &n.out) {
        let file = acquire::resume_settings(out)?;
        let d = out.display();
        let clash = |option: String, key: &str, have: String| {
            bad(format!(
                "{option} contradicts {d}'s `# {key}: {have}`: --resume continues with the campaign's settings \
                 (leave the option out)"
            ))
        };
        if let Some(n) = a.samples.filter(|&n| n != file.samples) {
            return Err(clash(format!("--samples {n}"), "samples", file.samples.to_string()));
        }
        if let Some(hz) = a.rate_hz.filter(|&hz| hz != file.rate_hz) {
            return Err(clash(format!("--rate-hz {hz}"), "rate_hz", file.rate_hz.to_string()));
        }
        if let Some(g) = stated.filter(|g| g.g != file.g) {
            return Err(clash(g.option(), "g_m_s2", file.g.to_string()));
        }
        match &first {
            None => first = Some((out, file)),
            Some((p, f)) => {
                for (key, mine, theirs) in [
                    ("samples", file.samples.to_string(), f.samples.to_string()),
                    ("rate_hz", file.rate_hz.to_string(), f.rate_hz.to_string()),
                    ("g_m_s2", file.g.to_string(), f.g.to_string()),
                ] {
                    if mine != theirs {
                        return Err(bad(format!(
                            "{d}'s `# {key}: {mine}` is not {}'s `{theirs}`: the nodes of one acquisition share it \
                             (resume them one at a time)",
                            p.display()
                        )));
                    }
                }
            }
        }
    }
    let (_, file) = first.expect("--out is required");
    Ok((file.samples, Some(file.rate_hz), (file.g, file.g_source)))
}

/// A node's progress lines, prefixed with its port when several nodes are acquired.
struct NodeLines(String);

impl Progress for NodeLines {
    fn position_done(&mut self, r: &PositionReport, done: usize, total: usize, left: Duration) {
        err!("{}", self.0);
        Lines.position_done(r, done, total, left);
    }
    fn started(&mut self, from: usize, total: usize, rule: &StaticRule) {
        err!("{}", self.0);
        Lines.started(from, total, rule);
    }
    fn note(&mut self, line: &str) {
        err!("{}", self.0);
        Lines.note(line);
    }
    fn resumed(&mut self, done: usize, truncated_rows: usize) {
        err!("{}", self.0);
        Lines.resumed(done, truncated_rows);
    }
}

/// Runs `accelcal acquire`.
pub fn run_acquire(a: &Acquire) -> anyhow::Result<()> {
    let (samples, rate_hz, (g, g_source)) = if a.resume {
        resumed_settings(a)?
    } else {
        let g = rig_gravity(a.stated.as_ref());
        (a.samples.unwrap_or(DEFAULT_SAMPLES), a.rate_hz, (g.g, g.stored()))
    };
    let stop = stop_flag()?;
    let mut nodes = Vec::with_capacity(a.nodes.len());
    for n in &a.nodes {
        nodes.push(Session::open(&n.port, a.baud, a.answer_timeout)?);
    }
    let mut head = connect_head(&a.head, &stop)?;
    let cfg = AcquireConfig {
        settle: a.settle,
        out: a.nodes[0].out.clone(),
        plan: a.plan.clone(),
        plan_name: a.plan_spec.clone(),
        samples,
        rate_hz,
        rule: a.rule,
        settle_timeout: a.settle_timeout,
        g,
        g_source,
        serial: a.nodes[0].serial.clone(),
        resume: a.resume,
        date: super::record::utc(super::created(None)),
        tool_version: env!("CARGO_PKG_VERSION").into(),
        chamber: a.chamber.clone(),
    };
    let several = a.nodes.len() > 1;
    let cfgs: Vec<AcquireConfig> = a
        .nodes
        .iter()
        .map(|n| AcquireConfig { out: n.out.clone(), serial: n.serial.clone(), ..cfg.clone() })
        .collect();
    let mut lines: Vec<NodeLines> = a
        .nodes
        .iter()
        .map(|n| NodeLines(if several { format!("{}: ", n.port) } else { String::new() }))
        .collect();
    let mut runs: Vec<NodeRun> = nodes
        .iter_mut()
        .zip(&cfgs)
        .zip(lines.iter_mut())
        .map(|((node, cfg), progress)| NodeRun { node, cfg, progress })
        .collect();
    let sums = acquire::acquire_nodes(&mut runs, head.as_mut(), &stop)?;
    if sums.iter().any(|s| s.interrupted) {
        let held: Vec<String> = sums
            .iter()
            .zip(&a.nodes)
            .map(|(s, n)| format!("{} holds {} of {} positions", n.out.display(), s.positions, s.planned))
            .collect();
        return Err(anyhow::Error::new(Interrupted(format!(
            "interrupted: {}; continue with --resume",
            held.join(", ")
        ))));
    }
    for (sum, out) in sums.iter().zip(a.nodes.iter().map(|n| &n.out)) {
        outln!(
            "acquire: {} positions of device {} written to {} ({} sets each, {} sets lost while recording)",
            sum.positions,
            sum.device_id,
            out.display(),
            samples,
            sum.lost
        )?;
    }
    Ok(())
}

/// One row of the verification table.
fn check_line(c: &PositionCheck, n: usize) -> String {
    let e = c.error_m_s2;
    let t = c.tolerance_m_s2;
    let temp = match (c.temp_c, c.out_of_range) {
        (Some(t), false) => format!(", {t:.1} °C"),
        (Some(t), true) => format!(", {t:.1} °C OUTSIDE the record's range"),
        (None, _) => String::new(),
    };
    let head = format!(
        "position {}/{n} (alpha {} deg, beta {} deg{temp}): error {:+.5} {:+.5} {:+.5} m/s²",
        c.position, c.alpha_deg, c.beta_deg, e[0], e[1], e[2]
    );
    match (c.u_expanded_m_s2, c.decisions) {
        (Some(u), Some(d)) => {
            let worst = d.iter().max().copied().unwrap_or(accelcal_core::conformity::Decision::Pass);
            format!(
                "{head}, U {:.5} {:.5} {:.5} m/s²: {} ({})",
                u[0],
                u[1],
                u[2],
                if worst.accepted() { "pass".to_string() } else { worst.name().to_uppercase() },
                d.map(|d| d.name()).join(", ")
            )
        }
        _ => format!(
            "{head}, tolerance {:.5} {:.5} {:.5} m/s²: {}",
            t[0],
            t[1],
            t[2],
            if c.pass { "pass" } else { "FAIL" }
        ),
    }
}

/// Runs `accelcal verify`.
pub fn run_verify(a: &Verify) -> anyhow::Result<()> {
    // Opened first: an unreachable database, or a survey it refuses, stops the command here.
    let mut db = super::store::open(a.store.as_ref())?;
    let (stated, survey) = match &a.stated {
        Some(g) => {
            let (g, survey) = crate::app::gravity::resolve(g, db.as_mut().map(|r| &mut r.db))?;
            (Some(g), survey)
        }
        None => (None, None),
    };
    let stated = stated.as_ref();
    let mut fit = None;
    let tolerance = match &a.judged {
        Judged::Tolerance(t) => Tolerance::Fixed(*t),
        Judged::Derived { fit: Some(p), k } => {
            let k = *k;
            let text = std::fs::read_to_string(p)
                .map_err(|e| bad(format!("{}: cannot read the fit JSON: {e}", p.display())))?;
            let what = p.display().to_string();
            let doc: serde_json::Value =
                serde_json::from_str(&text).map_err(|e| bad(format!("{what}: not a JSON document: {e}")))?;
            let cal = uncertainty_from_fit_json(&text, &what)?;
            fit = Some((what.clone(), Identity::of_fit_json(&doc, &what)?));
            Tolerance::Derived { cal: Some(Box::new(cal)), k }
        }
        Judged::Derived { fit: None, k } => Tolerance::Derived { cal: None, k: *k },
    };
    // Without --g or --latitude, the g of the fit (the rig's, where the unit was calibrated).
    let gravity = match (stated, &fit) {
        (None, Some((what, id))) => Gravity {
            g: id.g_m_s2,
            source: Source::Fit { what: what.clone(), g_source: id.g_source.clone() },
        },
        _ => rig_gravity(stated),
    };
    let (g, g_source, g_words) = (gravity.g, gravity.stored(), gravity.words());
    let spec = a.spec.as_deref().map(super::spec::read).transpose()?;
    if let Some(s) = &spec {
        accelcal_line::verify::plan_measures_parameters(s, &a.plan.positions, g)?;
    }
    let (refs, not_included) = super::spec::references(&gravity, a.head_angle_u, a.head_orthogonality_u);
    let stop = stop_flag()?;
    let mut node = open(&a.link)?;
    let mut head = connect_head(&a.head, &stop)?;
    let serial = fit.as_ref().and_then(|(_, id)| id.serial.clone()).unwrap_or_default();
    let cfg = VerifyConfig {
        settle: a.settle,
        plan: a.plan.clone(),
        samples: a.samples,
        rule: calibrated_rule(),
        settle_timeout: a.settle_timeout,
        g,
        tolerance,
        chamber: a.chamber,
        fit,
        spec: spec.map(|s| (s, refs)),
    };
    match &cfg.spec {
        Some((s, _)) => {
            outln!("verify: g = {g} m/s² ({g_words}); specification {}", s.describe())?;
            if !not_included.is_empty() {
                outln!("verify: U of each measured error does not include {}", not_included.join(", nor "))?;
            }
        }
        None => outln!("verify: g = {g} m/s² ({g_words}); pass rule: {}", cfg.tolerance.describe())?,
    }
    // A position's line that cannot be written does not stop the node half-way: the first
    // failure is returned once the report is written and stored.
    let mut out_failed = None;
    let report = verify(
        &mut node,
        head.as_mut(),
        &cfg,
        &mut |c, n| {
            if let Err(e) = outln!("{}", check_line(c, n)) {
                out_failed.get_or_insert(e);
            }
        },
        &stop,
    )?;
    if let Some(p) = &a.json {
        write_json(p, &report)?;
    }
    if let (Some(rdb), false) = (&mut db, report.interrupted) {
        let run = rdb.begin_or_continue(super::store::Begin {
            device_id: report.device_id.clone(),
            serial,
            head: super::store::head_text(&a.head.spec),
            firmware_version: String::new(),
            g: (g, g_source.clone()),
        })?;
        if let Some(survey) = &survey {
            rdb.db.store_run_asset(run, survey)?;
        }
        let phase = a.phase;
        // The stored report is the file's, as `report --verify` and the station read it back.
        let stored = match &a.json {
            Some(p) => VerifyReport::read(p)?,
            None => report.clone(),
        };
        rdb.db.store_verification(run, phase, &stored)?;
        // A failed as-left verification rejects the unit, as at the station.
        let rejected = match (phase, report.failure().filter(|_| !report.interrupted)) {
            (accelcal_db::Phase::AsLeft, Some(f)) => {
                let why = format!("as-left verification: {f}");
                rdb.db.finish_run(run, accelcal_db::Outcome::Rejected, &why)?;
                Some(why)
            }
            _ => None,
        };
        // Said once the database holds everything: an output that fails leaves no run half-stored.
        outln!(
            "db: run {run}: {} verification stored in {}",
            super::store::phase_name(phase),
            rdb.db.target()
        )?;
        if let Some(why) = rejected {
            outln!("db: run {run} ended rejected ({why})")?;
        }
    }
    if let Some(e) = out_failed {
        return Err(e);
    }
    for c in report.parameters.iter().flatten() {
        outln!(
            "verify: {} {}: {:+.4} {} ± {:.4} (limit {} {}): {}",
            c.parameter.replace('_', " "),
            c.axis,
            c.value,
            c.unit,
            c.u_expanded,
            c.limit,
            c.unit,
            c.decision.name()
        )?;
    }
    if report.interrupted {
        return Err(anyhow::Error::new(Interrupted(format!(
            "interrupted after {} of {} positions: the node is not verified",
            report.positions.len(),
            cfg.plan.positions.len()
        ))));
    }
    if let Some(f) = report.failure() {
        let e = anyhow::Error::new(f);
        return Err(match report.decision {
            Some(d) => e.context(format!(
                "{}: the decision rule does not accept the unit ({})",
                d.name().to_uppercase(),
                report.tolerance_rule
            )),
            None => e,
        });
    }
    outln!(
        "verify: {}, {} positions of device {} (record {})",
        report.decision.map_or("PASS", |_| "PASS (every component accepted by the decision rule)"),
        report.positions.len(),
        report.device_id,
        report.record["crc"].as_str().map(|c| format!("CRC {c}")).unwrap_or_default()
    )?;
    Ok(())
}
