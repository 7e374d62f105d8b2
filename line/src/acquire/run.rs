//! The acquisition loop: one head, one or more nodes on it (one unit each, acquired together).
//!
//! The head is set once per position; every node that lacks the position is then captured at
//! once (a thread each, each with its own session, static test and settling), and each node's
//! campaign file gets its rows as one node's acquisition writes them (same header and format per
//! file). The checks of a position (static in time, moved as the plan says) apply per node: a
//! node that fails them is retried alone (a manual head's operator is asked) or ends the
//! acquisition, naming its port when there are several; the nodes that passed keep the position.
//! With `--resume` each file continues from its own complete positions: the head revisits a
//! position as long as a node lacks it, and only the nodes lacking it record it.

use std::fs::OpenOptions;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

use accelcal_shared::wire::Output;

use super::{
    ensure_node, header, open_resumed, record_position, reports_temperature, set_rate, soak_nodes,
    AcquireConfig, AcquireSummary, CampaignFile, Clock, MotionCheck, Progress, Recorded,
};
use crate::head::{Positioner, Target};
use crate::node::session::{device_id_hex, firmware_version, Session};
use accelcal_core::campaign::head_at::HeadAt;
use accelcal_core::error::{bad, environment};

/// One node of an acquisition: its session, its settings (its own `out` and `serial`; the rest
/// must be the other nodes'), and where its progress goes.
pub struct NodeRun<'a> {
    /// The node's open session.
    pub node: &'a mut Session,
    /// The node's acquisition.
    pub cfg: &'a AcquireConfig,
    /// Its progress.
    pub progress: &'a mut dyn Progress,
}

/// Runs an acquisition on an open node session. The node is switched to raw output for the
/// acquisition and back to what it streamed before at the end (also when it fails).
pub fn acquire(
    node: &mut Session,
    head: &mut dyn Positioner,
    cfg: &AcquireConfig,
    progress: &mut dyn Progress,
    stop: &AtomicBool,
) -> anyhow::Result<AcquireSummary> {
    let mut runs = [NodeRun { node, cfg, progress }];
    let mut sums = acquire_nodes(&mut runs, head, stop)?;
    Ok(sums.remove(0))
}

/// Runs one acquisition of several nodes on one head (see the module's documentation); the
/// summaries are in the order of `runs`. Each node is switched to raw output and back at the end,
/// as by [`acquire`].
pub fn acquire_nodes(
    runs: &mut [NodeRun],
    head: &mut dyn Positioner,
    stop: &AtomicBool,
) -> anyhow::Result<Vec<AcquireSummary>> {
    check_shared(runs)?;
    let mut ids = Vec::with_capacity(runs.len());
    for r in runs.iter_mut() {
        let info = r.node.info()?;
        if info.rate_hz == 0 {
            return Err(bad(format!(
                "{}: the node reports a sampling rate of 0 Hz: it has no live sample source",
                r.node.port()
            )));
        }
        if !r.cfg.resume && r.cfg.out.exists() {
            return Err(bad(format!(
                "{} exists: continue it with --resume, or choose another --out",
                r.cfg.out.display()
            )));
        }
        ids.push(info);
    }
    // Each node streams raw codes from here on, and is put back as it was whatever happens.
    let mut switched = 0;
    let mut result = Ok(Vec::new());
    for r in runs.iter_mut() {
        if let Err(e) = r.node.set_output(Output::Raw) {
            result = Err(e.into());
            break;
        }
        switched += 1;
    }
    if result.is_ok() {
        result = (|| {
            let mut states = Vec::with_capacity(runs.len());
            for (r, info) in runs.iter_mut().zip(&ids) {
                states.push(open_node(r, info)?);
            }
            run_positions(runs, &mut states, head, stop)
        })();
    }
    let mut restored = Ok(());
    for (r, info) in runs.iter_mut().zip(&ids).take(switched) {
        if info.output != Output::Raw {
            let back = r.node.set_output(info.output).map(|_| ());
            restored = restored.and(back);
        }
    }
    let done = result?;
    restored?;
    Ok(runs
        .iter()
        .zip(&ids)
        .zip(done)
        .map(|((r, info), (positions, lost, interrupted))| AcquireSummary {
            positions,
            planned: r.cfg.positions().len(),
            interrupted,
            lost,
            device_id: device_id_hex(&info.device_id),
        })
        .collect())
}

/// The nodes of one acquisition share everything but their campaign file and serial.
fn check_shared(runs: &[NodeRun]) -> anyhow::Result<()> {
    let Some(first) = runs.first() else {
        return Err(bad("an acquisition needs at least one node"));
    };
    let f = first.cfg;
    for (i, r) in runs.iter().enumerate().skip(1) {
        let c = r.cfg;
        let same = c.plan.positions == f.plan.positions
            && c.plan_name == f.plan_name
            && c.samples == f.samples
            && c.rate_hz == f.rate_hz
            && c.rule == f.rule
            && c.settle_timeout == f.settle_timeout
            && c.g == f.g
            && c.resume == f.resume
            && c.chamber == f.chamber;
        if !same {
            return Err(bad(format!(
                "node {} of the acquisition has other settings than node 1: the nodes on one head share the plan, \
                 samples, rate, static rule, g, chamber and --resume",
                i + 1
            )));
        }
        if runs[..i].iter().any(|o| o.cfg.out == c.out) {
            return Err(bad(format!("{}: two nodes cannot write one campaign", c.out.display())));
        }
    }
    Ok(())
}

/// Where one node's acquisition stands.
struct NodeState {
    out: CampaignFile,
    /// Positions complete in its file.
    done: usize,
    /// Positions complete when this run began.
    done_before: usize,
    rate_hz: u32,
    with_temp: bool,
    motion: MotionCheck,
    clock: Clock,
    lost: u64,
}

/// Sets a node's rate, opens (or resumes) its campaign file and reports the start.
fn open_node(r: &mut NodeRun, info: &accelcal_shared::wire::Info) -> anyhow::Result<NodeState> {
    let (node, cfg) = (&mut *r.node, r.cfg);
    let device_id = device_id_hex(&info.device_id);
    let rate_hz = match cfg.rate_hz {
        Some(hz) if hz != info.rate_hz => {
            if cfg.resume {
                r.progress.note(&format!(
                    "the node streams at {} Hz, the campaign's rate is {hz} Hz: set to {hz} Hz",
                    info.rate_hz
                ));
            }
            set_rate(node, hz)?
        }
        Some(hz) => hz,
        None => info.rate_hz,
    };
    let positions = cfg.positions();
    let per_pass = cfg.plan.positions.len();
    let accel = |k: usize| accelcal_shared::gravity(positions[k].0, positions[k].1, cfg.g);
    let mut motion = MotionCheck::new(cfg.g);
    let (out, done, with_temp, last_t) = if cfg.resume {
        let r2 = open_resumed(cfg, &device_id)?;
        r.progress.resumed(r2.done, r2.truncated_rows);
        // The positions of the pass under way that the file already holds are the reference.
        for (i, m) in r2.means.iter().enumerate().skip(r2.done - r2.done % per_pass) {
            motion.accept(accel(i), *m, i + 1);
        }
        (CampaignFile { file: r2.file, path: cfg.out.clone() }, r2.done, r2.with_temp, r2.last_t)
    } else {
        // The campaign records the node's temperature when its blocks carry one.
        let with_temp = reports_temperature(node)?;
        // The header first: a value it refuses leaves no file behind.
        let text = header(cfg, &device_id, &firmware_version(info.firmware), rate_hz, with_temp)?;
        let d = cfg.out.display();
        let file = OpenOptions::new().write(true).create_new(true).open(&cfg.out).map_err(|e| {
            if e.kind() == std::io::ErrorKind::AlreadyExists {
                bad(format!("{d} exists: continue it with --resume, or choose another --out"))
            } else {
                environment(format!("creating {d}"), e)
            }
        })?;
        let mut f = CampaignFile { file, path: cfg.out.clone() };
        f.append(&text)?;
        (f, 0, with_temp, f64::NEG_INFINITY)
    };
    if cfg.chamber.is_some() && !with_temp {
        return Err(bad(format!(
            "{}: the node reports no temperature with its samples (or {} has no `temp_c` column): a thermal \
             acquisition (--chamber) needs a node with a temperature input (link protocol 4)",
            node.port(),
            cfg.out.display()
        )));
    }
    r.progress.started(done, positions.len(), &cfg.rule);
    Ok(NodeState {
        out,
        done,
        done_before: done,
        rate_hz,
        with_temp,
        motion,
        clock: Clock { offset: 0.0, last: last_t },
        lost: 0,
    })
}

/// Runs the positions every node still lacks; per node: (positions in its file, sets lost,
/// interrupted).
fn run_positions(
    runs: &mut [NodeRun],
    states: &mut [NodeState],
    head: &mut dyn Positioner,
    stop: &AtomicBool,
) -> anyhow::Result<Vec<(usize, u64, bool)>> {
    let cfg = runs[0].cfg;
    let positions = cfg.positions();
    let n = positions.len();
    let per_pass = cfg.plan.positions.len();
    let several = runs.len() > 1;
    let from = states.iter().map(|s| s.done).min().unwrap_or(n);
    let accel = |k: usize| accelcal_shared::gravity(positions[k].0, positions[k].1, cfg.g);
    let t0 = Instant::now();
    if from < n {
        head.home()?;
    }
    for k in from..n {
        let angles = positions[k];
        let expected = accel(k);
        // The nodes lacking position k (the others hold it in their file already).
        let mut pending: Vec<usize> = (0..runs.len()).filter(|&i| states[i].done == k).collect();
        if k % per_pass == 0 {
            for &i in &pending {
                states[i].motion.reset();
            }
        }
        // A new chamber setpoint (or a resumed pass): set it and soak.
        if let Some(c) = cfg.chamber.as_ref().filter(|_| k % per_pass == 0 || k == from) {
            let mut nodes: Vec<&mut Session> = runs.iter_mut().map(|r| &mut *r.node).collect();
            if !soak_nodes(&mut nodes, head, c.setpoints_c[k / per_pass], c.soak, stop)? {
                return end(states, true);
            }
        }
        while !pending.is_empty() {
            let target = Target { k, n, angles: angles.into(), expected_m_s2: expected };
            let read_back = head.set(&target)?;
            if stop.load(Ordering::Relaxed) {
                return end(states, true);
            }
            // The settled rule: the read-back within the tolerance, then the wait, then (in the
            // capture) the node's static test. A read-back off the commanded angles ends the
            // acquisition before anything of the position is recorded.
            crate::head::settled(&head.describe(), &target, read_back, cfg.settle.tolerance_arcsec)?;
            let head_at = HeadAt {
                position: k + 1,
                alpha_deg: angles.0,
                beta_deg: angles.1,
                read_back_alpha_deg: read_back.alpha_deg,
                read_back_beta_deg: read_back.beta_deg,
            };
            let mut nodes: Vec<&mut Session> = runs
                .iter_mut()
                .enumerate()
                .filter(|(i, _)| pending.contains(i))
                .map(|(_, r)| &mut *r.node)
                .collect();
            if !crate::acquire::dwell(&mut nodes, cfg.settle.wait, stop)? {
                return end(states, true);
            }
            for &i in &pending {
                let r = &mut runs[i];
                ensure_node(r.node, states[i].rate_hz, r.progress)?;
            }
            let recorded = capture_all(runs, states, &pending, k, angles, stop);
            let mut refused = Vec::new();
            let mut accepted = Vec::new();
            for (i, rec) in pending.iter().copied().zip(recorded) {
                match rec? {
                    Recorded::Done(text, report, last_t) => {
                        match states[i].motion.check(expected, report.mean) {
                            Ok(()) => accepted.push((i, text, report, last_t)),
                            Err(why) => {
                                refused.push((i, format!("the head did not move as the plan says: {why}")))
                            }
                        }
                    }
                    Recorded::Stopped => return end(states, true),
                    Recorded::Unsettled(why) => refused.push((i, why)),
                }
            }
            for (i, text, report, last_t) in accepted {
                let (r, s) = (&mut runs[i], &mut states[i]);
                s.out.append(&(head_at.line() + &text))?;
                s.motion.accept(expected, report.mean, k + 1);
                s.lost += report.lost;
                s.clock.last = last_t;
                s.done = k + 1;
                let finished = k + 1 - s.done_before;
                let per = t0.elapsed() / finished as u32;
                r.progress.position_done(&report, k + 1, n, per * (n - k - 1) as u32);
            }
            pending = refused.iter().map(|(i, _)| *i).collect();
            if refused.is_empty() {
                break;
            }
            let why = if several {
                let each: Vec<String> =
                    refused.iter().map(|(i, why)| format!("{}: {why}", runs[*i].node.port())).collect();
                each.join("; ")
            } else {
                refused[0].1.clone()
            };
            if !head.retry(k, &why)? {
                let keeps = if several {
                    let files: Vec<String> = refused
                        .iter()
                        .map(|(i, _)| {
                            format!("{} keeps its {k} positions before it", runs[*i].cfg.out.display())
                        })
                        .collect();
                    files.join(", ")
                } else {
                    format!("the campaign keeps the {k} positions before it")
                };
                return Err(bad(format!(
                    "position {} of {n} (alpha {} deg, beta {} deg) refused: {why}; {keeps}: retry with --resume",
                    k + 1,
                    angles.0,
                    angles.1
                )));
            }
            if stop.load(Ordering::Relaxed) {
                return end(states, true);
            }
        }
    }
    end(states, false)
}

/// Records position `k` on each node of `pending` at once, a thread each; the results in the
/// order of `pending`.
fn capture_all(
    runs: &mut [NodeRun],
    states: &mut [NodeState],
    pending: &[usize],
    k: usize,
    angles: (f64, f64),
    stop: &AtomicBool,
) -> Vec<anyhow::Result<Recorded>> {
    let cfg = runs[0].cfg;
    if let [i] = pending {
        // One node: no thread needed.
        let (r, s) = (&mut runs[*i], &mut states[*i]);
        return vec![record_position(r.node, cfg, s.rate_hz, k, angles, stop, s.with_temp, &mut s.clock)];
    }
    std::thread::scope(|scope| {
        let handles: Vec<_> = runs
            .iter_mut()
            .zip(states.iter_mut())
            .enumerate()
            .filter(|(i, _)| pending.contains(i))
            .map(|(_, (r, s))| {
                let node = &mut *r.node;
                scope.spawn(move || {
                    record_position(node, cfg, s.rate_hz, k, angles, stop, s.with_temp, &mut s.clock)
                })
            })
            .collect();
        handles
            .into_iter()
            .map(|h| h.join().unwrap_or_else(|_| Err(anyhow::anyhow!("a node's capture thread panicked"))))
            .collect()
    })
}

/// What [`run_positions`] returns when it ends (`interrupted`: on a stop request).
fn end(states: &[NodeState], interrupted: bool) -> anyhow::Result<Vec<(usize, u64, bool)>> {
    Ok(states.iter().map(|s| (s.done, s.lost, interrupted)).collect())
}
