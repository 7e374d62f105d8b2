//! Acquisition: a campaign recorded from a live node on a dividing head (`accelcal acquire`).
//!
//! For each position of a plan the head is set (by an operator or an emulated head, through a
//! [`Positioner`]), the node's raw stream is watched until it is static ([`StaticRule`]), the
//! settling part is dropped, and `samples` sets are recorded with `t_s` from the node's sample
//! counter (`first / rate_hz`, so lost sets leave a gap in time, never a shifted row).
//!
//! Invariants (what makes it crash-safe):
//! - a position's rows reach the file only once the position is complete, in one write followed
//!   by a flush and an fsync; the campaign on disk is therefore always the header plus whole
//!   positions, except for a write cut by a crash, which `--resume` truncates;
//! - `--resume` checks that the file was acquired from the same node with the same plan and sample
//!   count, truncates an incomplete last position and continues with the next one;
//! - a stop request (Ctrl-C) is seen within the link's poll interval; the position under way is
//!   discarded and the file keeps the completed ones;
//! - before each position the node is checked to stream raw codes at the campaign's rate (a node
//!   that reset meanwhile is set back, and its restarted sample counter continues `t_s` after the
//!   last row), and each recorded position must have moved as the plan says ([`MotionCheck`]),
//!   else it is refused (the operator of a manual head may retry it).
//!
//! Several nodes on one head (one unit each) are acquired together by [`acquire_nodes`]: one head
//! move per position, the nodes captured at once, one campaign per node (module `run`).

use std::fs::File;
use std::io::Write;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use accelcal_shared::wire::{Block, Codes, Output};

use crate::head::Positioner;
use crate::node::session::Session;
use accelcal_core::error::{bad, environment};
use accelcal_core::sim::Plan;
use accelcal_core::text::TextError;

mod motion;
mod resume;
mod run;
pub use motion::MotionCheck;
use resume::open_resumed;
pub use resume::{resume_settings, ResumeSettings};
pub use run::{acquire, acquire_nodes, NodeRun};

/// When the stream counts as static: two consecutive windows of `window` sets whose means differ,
/// on every channel, by at most `z` standard errors of the difference (the standard error from the
/// two windows' own scatter, at least `min_sd` codes per set so that a quiet, quantised channel is
/// not held to zero).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StaticRule {
    /// Sets per window.
    pub window: usize,
    /// Largest accepted change of the window means, standard errors.
    pub z: f64,
    /// Floor of the per-set standard deviation, codes.
    pub min_sd: f64,
}

impl Default for StaticRule {
    fn default() -> StaticRule {
        StaticRule { window: 64, z: 3.0, min_sd: 0.5 }
    }
}

impl StaticRule {
    /// The rule in words, as the campaign header and the command's output state it.
    pub fn describe(&self) -> String {
        format!(
            "static once two consecutive windows of {} sets have means within {} standard errors on every channel \
             (per-set sd floor {} codes); the sets up to the end of the second window are dropped",
            self.window, self.z, self.min_sd
        )
    }
}

/// Watches a stream of code sets and says when it has become static ([`StaticRule`]).
#[derive(Clone, Debug)]
pub struct SettleDetector {
    rule: StaticRule,
    prev: Option<WindowStats>,
    cur: WindowAcc,
    /// Sets seen.
    pub seen: usize,
    /// The largest change of the means of the last compared windows, in standard errors (for the
    /// message of a position that does not settle).
    pub last_z: f64,
}

#[derive(Clone, Copy, Debug)]
struct WindowStats {
    mean: [f64; 3],
    var: [f64; 3],
}

#[derive(Clone, Debug, Default)]
struct WindowAcc {
    n: usize,
    first: [f64; 3],
    sum: [f64; 3],
    sum2: [f64; 3],
}

impl WindowAcc {
    fn push(&mut self, c: [f64; 3]) {
        for k in 0..3 {
            let v = c[k];
            if self.n == 0 {
                self.first[k] = v;
            }
            // Shifted sums: exact for whole codes, and no cancellation for any values.
            let d = v - self.first[k];
            self.sum[k] += d;
            self.sum2[k] += d * d;
        }
        self.n += 1;
    }

    fn stats(&self) -> WindowStats {
        let n = self.n as f64;
        let mut s = WindowStats { mean: [0.0; 3], var: [0.0; 3] };
        for k in 0..3 {
            let m = self.sum[k] / n;
            s.mean[k] = self.first[k] + m;
            s.var[k] = ((self.sum2[k] - n * m * m) / (n - 1.0).max(1.0)).max(0.0);
        }
        s
    }
}

impl SettleDetector {
    /// A detector at the start of a position.
    pub fn new(rule: StaticRule) -> SettleDetector {
        SettleDetector { rule, prev: None, cur: WindowAcc::default(), seen: 0, last_z: f64::INFINITY }
    }

    /// Feeds one set (codes or m/s², in the unit of the rule's `min_sd`); true once the stream is
    /// static (from the next set on, sets are recorded).
    pub fn push(&mut self, c: [f64; 3]) -> bool {
        self.seen += 1;
        self.cur.push(c);
        if self.cur.n < self.rule.window.max(2) {
            return false;
        }
        let now = std::mem::take(&mut self.cur).stats();
        let verdict = match self.prev {
            Some(p) => {
                let w = self.rule.window.max(2) as f64;
                let floor = self.rule.min_sd * self.rule.min_sd;
                let z = (0..3)
                    .map(|k| {
                        let se = ((p.var[k].max(floor) + now.var[k].max(floor)) / w).sqrt();
                        (now.mean[k] - p.mean[k]).abs() / se
                    })
                    .fold(0.0, f64::max);
                self.last_z = z;
                z <= self.rule.z
            }
            None => false,
        };
        self.prev = Some(now);
        verdict
    }
}

/// A thermal acquisition's chamber: the plan is run once at each setpoint, after a soak.
#[derive(Clone, Debug, PartialEq)]
pub struct Chamber {
    /// Setpoints, °C.
    pub setpoints_c: Vec<f64>,
    /// Wait after each change of the setpoint before the first position, s.
    pub soak: Duration,
}

impl Chamber {
    /// The header's words for it.
    pub fn describe(&self) -> String {
        let list: Vec<String> = self.setpoints_c.iter().map(|t| t.to_string()).collect();
        format!("{} °C, soak {} s", list.join(","), self.soak.as_secs_f64())
    }
}

/// Sets the chamber to `setpoint_c` and waits `soak`, reading (and dropping) the node's stream
/// meanwhile; returns early (false) when `stop` is set.
pub fn soak(
    node: &mut Session,
    head: &mut dyn Positioner,
    setpoint_c: f64,
    soak: Duration,
    stop: &AtomicBool,
) -> anyhow::Result<bool> {
    soak_nodes(&mut [node], head, setpoint_c, soak, stop)
}

/// [`soak`] with several nodes on the head, their streams read in turn.
fn soak_nodes(
    nodes: &mut [&mut Session],
    head: &mut dyn Positioner,
    setpoint_c: f64,
    soak: Duration,
    stop: &AtomicBool,
) -> anyhow::Result<bool> {
    head.chamber(setpoint_c)?;
    dwell(nodes, soak, stop)
}

/// Waits `wait`, reading (and dropping) the nodes' streams in turn meanwhile, so that no node's
/// buffer fills; returns early (false) when `stop` is set.
pub fn dwell(nodes: &mut [&mut Session], wait: Duration, stop: &AtomicBool) -> anyhow::Result<bool> {
    let t0 = Instant::now();
    let mut waits: Vec<_> = nodes.iter().map(|n| n.block_wait()).collect();
    while t0.elapsed() < wait {
        for (node, w) in nodes.iter_mut().zip(&mut waits) {
            if stop.load(Ordering::Relaxed) {
                return Ok(false);
            }
            node.poll_samples(w)?;
        }
    }
    Ok(!stop.load(Ordering::Relaxed))
}

/// Settings of an acquisition (checked by the caller before any I/O).
#[derive(Clone, Debug)]
pub struct AcquireConfig {
    /// The campaign file written.
    pub out: PathBuf,
    /// The positions.
    pub plan: Plan,
    /// How the plan was given (`head`, `six`, a file name), for the header.
    pub plan_name: String,
    /// Sets recorded per position.
    pub samples: usize,
    /// The node's sampling rate for the campaign, Hz: set first, and set again before a position
    /// when the node streams at another (it reset); `None`: the node's rate at the start.
    pub rate_hz: Option<u32>,
    /// When the stream is static.
    pub rule: StaticRule,
    /// How long a position may take to become static.
    pub settle_timeout: Duration,
    /// The head's part of the settled rule (read-back tolerance, wait after the move).
    pub settle: crate::head::Settle,
    /// Local gravity, m/s².
    pub g: f64,
    /// How g was obtained (for the header: `--g`, `--latitude/--height`, or the 9.81 fallback).
    pub g_source: String,
    /// The unit's serial number, when given.
    pub serial: Option<String>,
    /// Continue an interrupted acquisition in `out`.
    pub resume: bool,
    /// The acquisition's date (UTC, ISO 8601).
    pub date: String,
    /// This tool's version.
    pub tool_version: String,
    /// A thermal acquisition: the plan at each chamber setpoint, with the node's temperature
    /// recorded as `temp_c`.
    pub chamber: Option<Chamber>,
}

impl AcquireConfig {
    /// The positions in acquisition order: the plan, once per chamber setpoint.
    pub fn positions(&self) -> Vec<(f64, f64)> {
        let passes = self.chamber.as_ref().map_or(1, |c| c.setpoints_c.len());
        (0..passes).flat_map(|_| self.plan.positions.iter().copied()).collect()
    }

    /// The header's plan: its name and the number of positions acquired.
    fn plan_words(&self) -> String {
        let n = self.positions().len();
        match &self.chamber {
            None => format!("{} ({n} positions)", self.plan_name),
            Some(c) => {
                format!("{} at {} chamber setpoints ({n} positions)", self.plan_name, c.setpoints_c.len())
            }
        }
    }
}

/// How one position went.
#[derive(Clone, Debug, PartialEq)]
pub struct PositionReport {
    /// Index in the plan.
    pub index: usize,
    /// Angles, degrees.
    pub angles: (f64, f64),
    /// Sets dropped before the stream was static.
    pub dropped: usize,
    /// Time from the head's arrival to static, s (node's clock).
    pub settle_s: f64,
    /// Sets lost by the node while recording (gaps in its sample counter).
    pub lost: u64,
    /// Mean codes of the recorded sets.
    pub mean: [f64; 3],
}

/// Progress callbacks of an acquisition.
pub trait Progress {
    /// Position `report.index` is on disk; `done` of `total` positions are; `left` is the expected
    /// time for the rest.
    fn position_done(&mut self, report: &PositionReport, done: usize, total: usize, left: Duration);
    /// Positions found complete in the file that is resumed.
    fn resumed(&mut self, done: usize, truncated_rows: usize);
    /// The campaign file is ready and the acquisition begins with position `from` (0-based).
    fn started(&mut self, from: usize, total: usize, rule: &StaticRule);
    /// Something the operator should know (the node was set back after a reset).
    fn note(&mut self, line: &str);
}

/// What an acquisition did.
#[derive(Clone, Debug)]
pub struct AcquireSummary {
    /// Positions complete in the file.
    pub positions: usize,
    /// Positions in the plan.
    pub planned: usize,
    /// Whether it stopped on request before the end.
    pub interrupted: bool,
    /// Sets lost while recording, all positions of this run.
    pub lost: u64,
    /// The node's device id.
    pub device_id: String,
}

/// The header of an acquired campaign: `# key: value` lines before the CSV header, each written
/// by [`accelcal_core::campaign::header_line`], so that a value (the serial, the plan's name, the node's
/// firmware string) that is not one line of text is refused instead of adding lines.
fn header(
    cfg: &AcquireConfig,
    device_id: &str,
    firmware: &str,
    rate_hz: u32,
    with_temp: bool,
) -> Result<String, TextError> {
    let mut h = String::new();
    let mut line = |k: &str, v: &str| -> Result<(), TextError> {
        h.push_str(&accelcal_core::campaign::header_line(k, v)?);
        Ok(())
    };
    line("acquired_by", &format!("accelcal {} acquire", cfg.tool_version))?;
    use accelcal_core::campaign::identity::{DEVICE_ID_KEY, G_KEY, G_SOURCE_KEY, SERIAL_KEY};
    line(DEVICE_ID_KEY, device_id)?;
    line(SERIAL_KEY, cfg.serial.as_deref().unwrap_or("-"))?;
    line("firmware", firmware)?;
    line(G_KEY, &format!("{}", cfg.g))?;
    line(G_SOURCE_KEY, &cfg.g_source)?;
    line("plan", &cfg.plan_words())?;
    if let Some(c) = &cfg.chamber {
        line("chamber", &c.describe())?;
    }
    line("samples", &cfg.samples.to_string())?;
    line("rate_hz", &rate_hz.to_string())?;
    line("static_rule", &cfg.rule.describe())?;
    line("date", &cfg.date)?;
    line(accelcal_core::campaign::CODES_KEY, accelcal_core::campaign::CodeRange::Unsigned16.name())?;
    h.push_str(if with_temp {
        "t_s,alpha_deg,beta_deg,temp_c,x,y,z\n"
    } else {
        "t_s,alpha_deg,beta_deg,x,y,z\n"
    });
    Ok(h)
}

/// Writes whole positions to the campaign file, each made durable before the next begins.
struct CampaignFile {
    file: File,
    path: PathBuf,
}

impl CampaignFile {
    fn append(&mut self, text: &str) -> anyhow::Result<()> {
        let d = self.path.display();
        self.file.write_all(text.as_bytes()).map_err(|e| environment(format!("writing {d}"), e))?;
        self.file.flush().map_err(|e| environment(format!("writing {d}"), e))?;
        self.file.sync_data().map_err(|e| environment(format!("syncing {d}"), e))?;
        Ok(())
    }
}

/// Whether the node's live blocks carry a temperature: the first block within 3 s says (false
/// when none comes: the acquisition then fails at its first position, saying why; an error when
/// none comes within the node's answer timeout, if that is shorter).
fn reports_temperature(node: &mut Session) -> anyhow::Result<bool> {
    let t0 = Instant::now();
    let mut wait = node.block_wait();
    while t0.elapsed() < Duration::from_secs(3) {
        if let Some(s) = node.poll_samples(&mut wait)? {
            return Ok(s.temp.is_some());
        }
    }
    Ok(false)
}

/// Sets the node's rate to `hz` and checks that it took it; returns it.
fn set_rate(node: &mut Session, hz: u32) -> anyhow::Result<u32> {
    let st = node.set_rate(hz)?;
    if st.rate_hz != hz {
        return Err(anyhow::anyhow!(
            "{}: the node was asked for {hz} Hz and reports {} Hz",
            node.port(),
            st.rate_hz
        ));
    }
    Ok(hz)
}

/// Before a position: the node must stream raw codes at the campaign's rate. A node that reset
/// since (it returns to its default rate and output) is set back, with a note.
fn ensure_node(node: &mut Session, rate_hz: u32, progress: &mut dyn Progress) -> anyhow::Result<()> {
    let info = node.info()?;
    if info.rate_hz != rate_hz {
        progress.note(&format!(
            "the node streams at {} Hz, the campaign's rate is {rate_hz} Hz (did it reset? last reset: {}): set back \
             to {rate_hz} Hz",
            info.rate_hz, info.reset_cause
        ));
        set_rate(node, rate_hz)?;
    }
    if info.output != Output::Raw {
        progress.note(&format!(
            "the node streams {} output (did it reset?): set back to raw",
            info.output.name()
        ));
        node.set_output(Output::Raw)?;
    }
    Ok(())
}

/// The `t_s` of recorded sets: the node's sample counter over the rate, plus an offset that keeps
/// `t_s` increasing when the counter restarted (the node reset).
#[derive(Clone, Copy, Debug)]
struct Clock {
    offset: f64,
    /// `t_s` of the last row written.
    last: f64,
}

impl Clock {
    /// `t_s` of the set numbered `counter`; the first set of a position moves the offset when the
    /// counter went back.
    fn start(&mut self, counter: u32, rate_hz: u32) {
        let t = counter as f64 / rate_hz as f64;
        if t + self.offset <= self.last {
            self.offset = self.last + 1.0 / rate_hz as f64 - t;
        }
    }

    fn t(&self, counter: u32, rate_hz: u32) -> f64 {
        counter as f64 / rate_hz as f64 + self.offset
    }
}

/// The sets of one position, recorded once the stream was static.
#[derive(Clone, Debug, PartialEq)]
pub struct Capture {
    /// Each recorded set with the node's sample counter.
    pub sets: Vec<(u32, [f64; 3])>,
    /// The temperature of each recorded set (its block's mean, °C), when the node reports one.
    pub temps: Vec<Option<f32>>,
    /// A recorded block was calibrated outside the record's temperature range.
    pub out_of_range: bool,
    /// Sets watched before the stream was static (dropped).
    pub dropped: usize,
    /// Sets from the first one after the head's arrival to static (divide by the rate for
    /// seconds).
    pub settle_sets: u32,
    /// Sets the node lost while recording.
    pub lost: u64,
}

impl Capture {
    /// Mean temperature of the recorded sets, °C, when every set has one.
    pub fn mean_temp_c(&self) -> Option<f64> {
        let t: Option<Vec<f32>> = self.temps.iter().copied().collect();
        t.filter(|t| !t.is_empty()).map(|t| t.iter().map(|&v| v as f64).sum::<f64>() / t.len() as f64)
    }

    /// Mean of the recorded sets.
    pub fn mean(&self) -> [f64; 3] {
        let n = self.sets.len().max(1) as f64;
        let mut m = [0.0; 3];
        for (_, v) in &self.sets {
            for k in 0..3 {
                m[k] += v[k] / n;
            }
        }
        m
    }

    /// Standard deviation of the recorded sets (n − 1).
    pub fn sd(&self) -> [f64; 3] {
        let m = self.mean();
        let n = self.sets.len() as f64;
        let mut s = [0.0; 3];
        for (_, v) in &self.sets {
            for k in 0..3 {
                s[k] += (v[k] - m[k]).powi(2);
            }
        }
        s.map(|x| (x / (n - 1.0).max(1.0)).sqrt())
    }
}

/// How waiting for one position ended.
pub enum Captured {
    /// Recorded.
    Done(Capture),
    /// A stop was requested.
    Stopped,
    /// The stream did not become static in time; why.
    Unsettled(String),
}

/// What the values of a live block are, or why the block is not what the caller records.
pub type BlockValues = fn(&Block) -> Result<Vec<[f64; 3]>, String>;

/// Raw code blocks as values (what `acquire` records).
pub fn raw_values(b: &Block) -> Result<Vec<[f64; 3]>, String> {
    match b {
        Block::Raw(v) => Ok(v.iter().map(|c: &Codes| c.map(f64::from)).collect()),
        other => {
            Err(format!("the node streams {} blocks after it was switched to raw output", block_kind(other)))
        }
    }
}

/// Waits for a static stream at the position the head has just reached, drops the settling part
/// and records `samples` sets, converted by `values`.
pub fn capture(
    node: &mut Session,
    rule: StaticRule,
    settle_timeout: Duration,
    samples: usize,
    stop: &AtomicBool,
    values: BlockValues,
) -> anyhow::Result<Captured> {
    // Blocks produced before the head stood still are dropped.
    node.flush_stream()?;
    let started = Instant::now();
    let mut blocks = node.block_wait();
    let mut det = SettleDetector::new(rule);
    let mut settled_at: Option<u32> = None;
    let mut arrival: Option<u32> = None;
    let mut next_first: Option<u32> = None;
    let mut cap = Capture {
        sets: Vec::with_capacity(samples),
        temps: Vec::with_capacity(samples),
        out_of_range: false,
        dropped: 0,
        settle_sets: 0,
        lost: 0,
    };
    while cap.sets.len() < samples {
        if stop.load(Ordering::Relaxed) {
            return Ok(Captured::Stopped);
        }
        if settled_at.is_none() && started.elapsed() > settle_timeout {
            return Ok(Captured::Unsettled(format!(
                "the stream did not become static within {} s (last change of the window means: {:.1} standard errors, \
                 the rule allows {}); is the head still moving, or the unit vibrating?",
                settle_timeout.as_secs_f64(),
                det.last_z,
                rule.z
            )));
        }
        let Some(msg) = node.poll_samples(&mut blocks)? else { continue };
        let vals = values(&msg.data).map_err(|e| bad(format!("{}: {e}", node.port())))?;
        arrival.get_or_insert(msg.first);
        if let (Some(exp), Some(_)) = (next_first, settled_at) {
            cap.lost += msg.first.wrapping_sub(exp) as u64;
        }
        next_first = Some(msg.first.wrapping_add(vals.len() as u32));
        for (i, v) in vals.into_iter().enumerate() {
            let counter = msg.first.wrapping_add(i as u32);
            if settled_at.is_none() {
                if det.push(v) {
                    settled_at = Some(counter.wrapping_add(1));
                }
                continue;
            }
            if cap.sets.len() == samples {
                break;
            }
            cap.sets.push((counter, v));
            cap.temps.push(msg.temp.map(|t| t.mean_c));
            cap.out_of_range |= msg.temp.is_some_and(|t| t.out_of_range);
        }
    }
    cap.dropped = det.seen;
    cap.settle_sets = settled_at.unwrap_or(0).wrapping_sub(arrival.unwrap_or(0));
    Ok(Captured::Done(cap))
}

/// Waits for a static stream at one position and records its raw sets as campaign rows.
#[allow(clippy::too_many_arguments)]
fn record_position(
    node: &mut Session,
    cfg: &AcquireConfig,
    rate_hz: u32,
    k: usize,
    angles: (f64, f64),
    stop: &AtomicBool,
    with_temp: bool,
    clock: &mut Clock,
) -> anyhow::Result<Recorded> {
    let cap = match capture(node, cfg.rule, cfg.settle_timeout, cfg.samples, stop, raw_values)? {
        Captured::Done(c) => c,
        Captured::Stopped => return Ok(Recorded::Stopped),
        Captured::Unsettled(why) => return Ok(Recorded::Unsettled(why)),
    };
    let mut text = String::new();
    clock.start(cap.sets.first().map_or(0, |s| s.0), rate_hz);
    let mut last_t = clock.last;
    for ((counter, c), temp) in cap.sets.iter().zip(&cap.temps) {
        let t_s = clock.t(*counter, rate_hz);
        last_t = t_s;
        match (with_temp, temp) {
            (false, _) => {
                text.push_str(&format!("{t_s:.6},{},{},{},{},{}\n", angles.0, angles.1, c[0], c[1], c[2]))
            }
            (true, Some(tc)) => text.push_str(&format!(
                "{t_s:.6},{},{},{tc:.2},{},{},{}\n",
                angles.0, angles.1, c[0], c[1], c[2]
            )),
            (true, None) => {
                return Err(bad(format!(
                    "{}: a block came without the temperature the node reported before: the campaign \
                     records `temp_c`",
                    node.port()
                )))
            }
        }
    }
    let report = PositionReport {
        index: k,
        angles,
        dropped: cap.dropped,
        settle_s: cap.settle_sets as f64 / rate_hz as f64,
        lost: cap.lost,
        mean: cap.mean(),
    };
    Ok(Recorded::Done(text, report, last_t))
}

enum Recorded {
    /// The rows, what they were, and the `t_s` of the last row.
    Done(String, PositionReport, f64),
    Stopped,
    Unsettled(String),
}

/// The kind of a block, in words.
pub fn block_kind(b: &Block) -> &'static str {
    match b {
        Block::Calibrated(_) => "calibrated",
        Block::CalibratedFixed(_) => "calibrated (fixed-point)",
        Block::Uncalibrated(_) => "uncalibrated",
        Block::Raw(_) => "raw",
    }
}

#[cfg(test)]
mod tests;
