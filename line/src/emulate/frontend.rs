//! The emulated analog front end: the code sets a [`Unit`] on the emulated head gives
//! ([`FrontEnd`]), the loop that sends them to the QEMU node paced by the host clock
//! ([`run_frontend`]), and the reader of the node's rate messages ([`read_ctl`]). The channel's
//! contract is `accelcal_shared::frontend`.
//!
//! Invariants:
//! - A code set is computed by [`accelcal_core::sim::unit::sample_set`], the function `simulate` uses:
//!   standing at position p (p = moves completed), the block sees
//!   [`Unit::standing_accel`]`(p, angles)` exactly as `simulate` at plan position p, with
//!   `t_in_dwell_s` the time since the head stopped, `prev_accel` the acceleration at position
//!   p − 1 (None at p = 0) and `temp_c` the sensor's temperature on the bench
//!   ([`super::head::SensorTemp`]: the chamber setpoint followed with a first-order lag), which is
//!   also the set's temperature channel.
//! - While the head moves from position p to p + 1 the angles are those of the head's motion,
//!   and the kinematic effects' angles are interpolated between those of position p and of
//!   position p + 1 (continuous at both ends). Effects of the step (settling, hysteresis) keep
//!   seeing the step of the completed move p − 1 → p: `prev_accel` is shifted with the
//!   orientation so that [`accelcal_core::sim::SampleCtx::step`] stays that step.
//! - Set `n` is the `n`-th sampling period since the loop started (across rate changes, each
//!   period at the rate in force), sent with index `n mod 2¹⁶`. The loop never sends a set ahead
//!   of its time; when it falls behind by more than [`PaceOptions::backlog_s`] (a writer that
//!   blocks), the older sets are skipped, never sent late, so the node sees a jump in the index,
//!   as an ADC that keeps converting. Skipped sets are counted.
//! - The noise comes from a ChaCha8 RNG seeded with the front end's seed, one draw per channel
//!   per set computed (skipped sets draw none).

use std::io::{Read, Write};
use std::sync::atomic::{AtomicBool, AtomicU32, AtomicU64, Ordering};
use std::time::Duration;

use accelcal_shared::frontend::{FeCtl, FeSet, FE_MAX_FRAME};
use accelcal_shared::wire::{self, Codes, FrameDecoder};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::Normal;

use super::head::{Head, HeadPose, POLL};
use accelcal_core::error::{Classify, Kind};
use accelcal_core::sim::effects::Kinematics;
use accelcal_core::sim::unit::{SetCtx, Unit, UnitError};

/// The emulated front end of one unit: computes the code set of a sampling period.
pub struct FrontEnd {
    unit: Unit,
    noise: Normal<f64>,
    rng: ChaCha8Rng,
    /// Position of the current dwell and its first set's index (for `SetCtx::sample`).
    dwell: Option<(usize, u64)>,
}

impl FrontEnd {
    /// A front end for `unit` (a triad: `x`, `y`, `z` along axes 0, 1, 2), noise seeded with `seed`.
    pub fn new(unit: Unit, seed: u64) -> Result<FrontEnd, UnitError> {
        unit.check_triad()?;
        let noise = unit.noise_distribution();
        Ok(FrontEnd { unit, noise, rng: ChaCha8Rng::seed_from_u64(seed), dwell: None })
    }

    /// The unit.
    pub fn unit(&self) -> &Unit {
        &self.unit
    }

    /// The acceleration the block sees in `pose`, and the `prev_accel` its effects see.
    pub fn accel(&self, pose: &HeadPose) -> ([f64; 3], Option<[f64; 3]>) {
        let u = &self.unit;
        let p = pose.moves_completed;
        let a_stand = u.standing_accel(p, pose.stand);
        let prev = pose.prev_stand.map(|s| u.standing_accel(p.saturating_sub(1), s));
        let Some((target, f)) = pose.moving else {
            return (a_stand, prev);
        };
        let ka = u.kinematics(p, pose.stand);
        let kb = u.kinematics(p + 1, target);
        let now = if ka.changed || kb.changed {
            Kinematics {
                alpha_rad: ka.alpha_rad + f * (kb.alpha_rad - ka.alpha_rad),
                beta_rad: ka.beta_rad + f * (kb.beta_rad - ka.beta_rad),
                ..kb
            }
            .accel(u.g)
        } else {
            accelcal_shared::gravity(pose.alpha_deg, pose.beta_deg, u.g)
        };
        // Keep `step()` at the completed move's step while the orientation changes.
        let prev = prev.map(|pa| [0, 1, 2].map(|j| now[j] - (a_stand[j] - pa[j])));
        (now, prev)
    }

    /// The context of set `n`, taken at `t_s` on the bench clock with the head in `pose` and the
    /// block at `temp_c` (°C; NaN: no temperature).
    pub fn set_ctx(&mut self, pose: &HeadPose, n: u64, t_s: f64, temp_c: f64) -> SetCtx {
        let p = pose.moves_completed;
        let first = match self.dwell {
            Some((q, first)) if q == p => first,
            _ => {
                self.dwell = Some((p, n));
                n
            }
        };
        let (accel, prev_accel) = self.accel(pose);
        SetCtx {
            t_s,
            position: p,
            sample: (n - first) as usize,
            accel,
            t_in_dwell_s: (t_s - pose.stopped_at_s).max(0.0),
            temp_c,
            prev_accel,
        }
    }

    /// The codes of set `n` (channels x, y, z), at `t_s` with the head in `pose` and the block at
    /// `temp_c` (°C).
    pub fn codes(&mut self, pose: &HeadPose, n: u64, t_s: f64, temp_c: f64) -> Codes {
        let set = self.set_ctx(pose, n, t_s, temp_c);
        let mut out = [0.0; 3];
        self.unit.sample(&set, &self.noise, &mut self.rng, &mut out);
        // `sample` rounds and clips to 0..=65535, so the cast is exact.
        out.map(|u| u as u16)
    }
}

/// Options of the pacing loop.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PaceOptions {
    /// Send at this factor times the node's rate (> 0; above 1 provokes overruns in the node).
    pub rate_factor: f64,
    /// How far behind the loop may fall and still send the sets it owes, s (a FIFO absorbing the
    /// host's scheduling jitter); older sets are skipped.
    pub backlog_s: f64,
}

impl Default for PaceOptions {
    /// Factor 1, 20 ms of backlog.
    fn default() -> PaceOptions {
        PaceOptions { rate_factor: 1.0, backlog_s: 0.02 }
    }
}

/// Counters of the pacing loop, readable while it runs.
#[derive(Debug, Default)]
pub struct FeCounters {
    /// Sets sent.
    pub sent: AtomicU64,
    /// Sets skipped because the writer fell behind.
    pub skipped: AtomicU64,
}

/// What the pacing loop did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct FeStats {
    /// Sets sent.
    pub sent: u64,
    /// Sets skipped because the writer fell behind.
    pub skipped: u64,
}

/// Why the front end stopped.
#[derive(Debug, thiserror::Error)]
pub enum FrontendError {
    /// Writing a set failed (the node's end closed).
    #[error("front end: writing to the node failed: {0}")]
    Write(std::io::Error),
    /// Reading the node's messages failed.
    #[error("front end: reading from the node failed: {0}")]
    Read(std::io::Error),
    /// The pacing options are out of range.
    #[error("front end: {0}")]
    Options(String),
}

impl Classify for FrontendError {
    fn kind(&self) -> Kind {
        match self {
            FrontendError::Write(_) | FrontendError::Read(_) => Kind::Environment,
            FrontendError::Options(_) => Kind::BadInput,
        }
    }
}

/// Sends a set per sampling period of `rate_hz` × `opts.rate_factor` to `writer`, paced by the
/// head's clock, until `stop` is set (or the writer fails). A rate of 0 pauses the loop (the
/// node has not told its rate yet); a change of rate takes effect at the next set.
pub fn run_frontend<W: Write>(
    fe: &mut FrontEnd,
    head: &Head,
    rate_hz: &AtomicU32,
    mut writer: W,
    stop: &AtomicBool,
    opts: &PaceOptions,
    counters: &FeCounters,
) -> Result<FeStats, FrontendError> {
    if !(opts.rate_factor.is_finite() && opts.rate_factor > 0.0) {
        return Err(FrontendError::Options(format!("rate factor must be > 0, got {}", opts.rate_factor)));
    }
    if !(opts.backlog_s.is_finite() && opts.backlog_s >= 0.0) {
        return Err(FrontendError::Options(format!("backlog must be >= 0 s, got {}", opts.backlog_s)));
    }
    let clock = head.clock();
    let mut stats = FeStats::default();
    let mut buf = [0u8; FE_MAX_FRAME];
    // The rate in force: (node's rate, sets per second, its start time, the first set at it).
    let mut cur: Option<(u32, f64, f64, u64)> = None;
    let mut next: u64 = 0;
    while !stop.load(Ordering::Relaxed) {
        let hz = rate_hz.load(Ordering::Relaxed);
        let now = clock.now_s();
        if hz == 0 {
            cur = None;
            std::thread::sleep(Duration::from_millis(1));
            continue;
        }
        if cur.map(|c| c.0) != Some(hz) {
            cur = Some((hz, hz as f64 * opts.rate_factor, now, next));
        }
        let Some((_, per_s, t0, n0)) = cur else { continue };
        let time_of = |n: u64| t0 + (n - n0) as f64 / per_s;
        let due = n0 + ((now - t0) * per_s).floor() as u64;
        if due < next {
            let wait = (time_of(next) - now).clamp(0.0, POLL.as_secs_f64());
            std::thread::sleep(Duration::from_secs_f64(wait));
            continue;
        }
        let backlog = ((opts.backlog_s * per_s) as u64).max(1);
        let first = next.max((due + 1).saturating_sub(backlog));
        stats.skipped += first - next;
        counters.skipped.store(stats.skipped, Ordering::Relaxed);
        for n in first..=due {
            let t = time_of(n);
            let pose = head.pose_at(t);
            let temp_c = head.sensor_temp_at(t);
            let set = FeSet {
                index: n as u16,
                codes: fe.codes(&pose, n, t, temp_c),
                temp_cc: FeSet::temp_field(temp_c),
            };
            let frame = wire::encode(&set, &mut buf).map_err(|e| FrontendError::Options(format!("{e:?}")))?;
            writer.write_all(frame).map_err(FrontendError::Write)?;
            stats.sent += 1;
            counters.sent.store(stats.sent, Ordering::Relaxed);
        }
        writer.flush().map_err(FrontendError::Write)?;
        next = due + 1;
    }
    Ok(stats)
}

/// What the reader of the node's messages saw.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct CtlStats {
    /// Rate messages received.
    pub rates: u64,
    /// Frames that did not decode (counted, skipped).
    pub bad_frames: u64,
    /// The last rate received, Hz.
    pub last_rate_hz: Option<u32>,
}

/// Reads the node's front-end messages ([`FeCtl`], USART2 TX) from `reader` and stores each rate
/// in `rate_hz`, until the end of the stream or `stop` (checked whenever a read returns, so give
/// a blocking reader a timeout). Bad frames are counted and skipped.
pub fn read_ctl<R: Read>(
    mut reader: R,
    rate_hz: &AtomicU32,
    stop: &AtomicBool,
) -> Result<CtlStats, FrontendError> {
    let mut dec = FrameDecoder::<FE_MAX_FRAME>::new();
    let mut stats = CtlStats::default();
    let mut buf = [0u8; 64];
    while !stop.load(Ordering::Relaxed) {
        let n = match reader.read(&mut buf) {
            Ok(0) => break,
            Ok(n) => n,
            Err(e) if crate::node::read_again(&e) => continue,
            Err(e) => return Err(FrontendError::Read(e)),
        };
        dec.push(&buf[..n], |m: Result<FeCtl, _>| match m {
            Ok(FeCtl::Rate { hz }) => {
                rate_hz.store(hz, Ordering::Relaxed);
                stats.rates += 1;
                stats.last_rate_hz = Some(hz);
            }
            Err(_) => stats.bad_frames += 1,
        });
    }
    Ok(stats)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::emulate::head::{Clock, HeadState, Motion};
    use accelcal_core::sim::{effects, simulate, Plan, SimConfig};
    use accelcal_shared::frontend::lost_between;
    use std::sync::Arc;
    use std::time::Instant;

    fn unit(cfg: &SimConfig) -> Unit {
        Unit::for_node(&simulate(cfg).1).unwrap()
    }

    #[test]
    fn standing_codes_average_to_bias_plus_k_times_the_kinematics() {
        let cfg = SimConfig { seed: 11, samples: 1, ..SimConfig::default() };
        let u = unit(&cfg);
        let chans = u.channels.clone();
        let mut fe = FrontEnd::new(u, 5).unwrap();
        let pose = HeadState::new(Motion::default(), (30.0, -60.0)).pose(1.0);
        let n = 4000u64;
        let mut sum = [0.0f64; 3];
        for i in 0..n {
            let c = fe.codes(&pose, i, 1.0 + i as f64 * 1e-3, 25.0);
            (0..3).for_each(|ch| sum[ch] += c[ch] as f64);
        }
        let a = accelcal_shared::gravity(30.0, -60.0, cfg.g);
        let tol = 5.0 * cfg.noise / (n as f64).sqrt();
        for (ch, t) in chans.iter().enumerate() {
            let expect = t.bias + (0..3).map(|j| t.k[j] * a[j]).sum::<f64>();
            let mean = sum[ch] / n as f64;
            assert!((mean - expect).abs() < tol, "{}: {mean} vs {expect} ± {tol}", t.name);
        }
    }

    #[test]
    fn standing_dwells_are_the_codes_of_simulate() {
        // Noise 0, so the two RNGs do not matter; the head reaches plan position p at the time
        // `simulate` starts its dwell p.
        let effects =
            ["settling=gain:3.5,tau:0.25", "hysteresis=h:7", "angle_error=sd_mrad:2", "bias_drift=rate:0.3"];
        let cfg = SimConfig {
            seed: 9,
            samples: 25,
            noise: 0.0,
            plan: Plan::head(),
            effects: effects.iter().map(|s| effects::parse(s).unwrap()).collect(),
            ..SimConfig::default()
        };
        let (c, truth) = simulate(&cfg);
        let mut fe = FrontEnd::new(Unit::for_node(&truth).unwrap(), 1).unwrap();
        let motion = Motion { speed_deg_s: 360.0, overhead_s: 0.1 };
        let mut head = HeadState::new(motion, cfg.plan.positions[0]);
        let dt = 1.0 / cfg.rate_hz;
        let dwell = cfg.samples as f64 * dt + cfg.move_s;
        let (mut row, mut n, mut mismatches) = (0, 0u64, 0);
        for (p, &angles) in cfg.plan.positions.iter().enumerate() {
            let t_p = p as f64 * dwell;
            if p > 0 {
                let from = cfg.plan.positions[p - 1];
                let end = head.start_move(t_p - motion.duration_s(from, angles), angles).unwrap();
                assert!((end - t_p).abs() < 1e-9);
            }
            for s in 0..cfg.samples {
                let t = t_p + s as f64 * dt;
                let pose = head.pose(t.max(t_p));
                assert_eq!(pose.moves_completed, p);
                // `simulate` without a temperature profile: no temperature.
                let codes = fe.codes(&pose, n, t, f64::NAN);
                mismatches += (0..3).filter(|&ch| codes[ch] as f64 != c.channels[ch].codes[row]).count();
                row += 1;
                n += 1;
            }
        }
        assert_eq!(mismatches, 0);
    }

    #[test]
    fn moving_orientation_is_interpolated_and_steps_stay_those_of_the_completed_move() {
        let cfg = SimConfig {
            seed: 2,
            samples: 1,
            effects: vec![effects::parse("settling=gain:5,tau:1").unwrap()],
            ..SimConfig::default()
        };
        let fe = FrontEnd::new(unit(&cfg), 1).unwrap();
        let mut head = HeadState::new(Motion::default(), (0.0, 0.0));
        head.start_move(0.0, (0.0, 90.0)).unwrap();
        let at1 = head.pose(2.0);
        head.start_move(3.0, (0.0, -90.0)).unwrap();
        let mid = head.pose(4.6);
        let (a, prev) = fe.accel(&mid);
        let exact = accelcal_shared::gravity(0.0, mid.beta_deg, cfg.g);
        assert!(mid.beta_deg.abs() < 5.0 && mid.moving.is_some(), "{mid:?}");
        assert!((0..3).all(|j| (a[j] - exact[j]).abs() < 1e-12), "{a:?} {exact:?}");
        let (a1, prev1) = fe.accel(&at1);
        let step = |a: [f64; 3], p: Option<[f64; 3]>| [0, 1, 2].map(|j| a[j] - p.unwrap()[j]);
        let (s_mid, s_1) = (step(a, prev), step(a1, prev1));
        assert!((0..3).all(|j| (s_mid[j] - s_1[j]).abs() < 1e-12), "{s_mid:?} {s_1:?}");
    }

    fn run_for(
        rate_hz: u32,
        opts: PaceOptions,
        seconds: f64,
        writer: &mut (dyn Write + Send),
    ) -> (FeStats, f64, FeCounters) {
        let head = Arc::new(Head::new(Clock::start(), Motion::default(), (0.0, 0.0)));
        let mut fe = FrontEnd::new(unit(&SimConfig { samples: 1, ..SimConfig::default() }), 3).unwrap();
        let rate = AtomicU32::new(rate_hz);
        let (stop, counters) = (AtomicBool::new(false), FeCounters::default());
        let t0 = Instant::now();
        let stats = std::thread::scope(|s| {
            let h = s.spawn(|| run_frontend(&mut fe, &head, &rate, writer, &stop, &opts, &counters));
            std::thread::sleep(Duration::from_secs_f64(seconds));
            stop.store(true, Ordering::Relaxed);
            h.join().unwrap().unwrap()
        });
        (stats, t0.elapsed().as_secs_f64(), counters)
    }

    fn indices(bytes: &[u8]) -> Vec<u16> {
        let mut d = FrameDecoder::<FE_MAX_FRAME>::new();
        let mut v = Vec::new();
        d.push(bytes, |m: Result<FeSet, _>| v.push(m.unwrap().index));
        v
    }

    #[test]
    fn the_loop_sends_rate_times_duration_sets_in_order() {
        for factor in [1.0, 2.0] {
            let mut out = Vec::new();
            let opts = PaceOptions { rate_factor: factor, backlog_s: 0.5 };
            let (stats, elapsed, counters) = run_for(1000, opts, 0.4, &mut out);
            let idx = indices(&out);
            assert_eq!(idx.len() as u64, stats.sent);
            assert_eq!(counters.sent.load(Ordering::Relaxed), stats.sent);
            assert!(idx.iter().enumerate().all(|(i, &x)| x == i as u16), "sets out of order or lost");
            let expect = 1000.0 * factor * elapsed;
            assert!((stats.sent as f64) <= expect + 1.0, "{stats:?} in {elapsed} s: ahead of time");
            // (Generous: the loop's thread may start late on a loaded machine.)
            assert!((stats.sent as f64) > 0.5 * 1000.0 * factor * 0.4, "{stats:?} in {elapsed} s");
        }
    }

    /// A writer that takes 20 ms per write.
    struct Slow(Vec<u8>);
    impl Write for Slow {
        fn write(&mut self, b: &[u8]) -> std::io::Result<usize> {
            std::thread::sleep(Duration::from_millis(20));
            self.0.extend_from_slice(b);
            Ok(b.len())
        }
        fn flush(&mut self) -> std::io::Result<()> {
            Ok(())
        }
    }

    #[test]
    fn a_slow_writer_makes_the_index_jump_by_the_sets_skipped() {
        let mut w = Slow(Vec::new());
        let opts = PaceOptions { rate_factor: 1.0, backlog_s: 0.005 };
        let (stats, elapsed, counters) = run_for(1000, opts, 0.4, &mut w);
        let idx = indices(&w.0);
        assert_eq!(idx.len() as u64, stats.sent);
        let lost: u64 = idx.windows(2).map(|p| lost_between(p[0], p[1]) as u64).sum();
        assert!(lost > 100, "{stats:?}");
        assert_eq!(counters.skipped.load(Ordering::Relaxed), stats.skipped);
        // Sets lost between two sent ones are the ones skipped then (none after the last).
        assert!(lost <= stats.skipped && stats.skipped - lost <= 1000, "{lost} {stats:?}");
        assert!((stats.sent as f64) < 0.5 * 1000.0 * elapsed, "{stats:?}");
    }

    #[test]
    fn the_reader_takes_the_node_s_rate_and_counts_bad_frames() {
        let mut bytes = Vec::new();
        let mut buf = [0u8; FE_MAX_FRAME];
        bytes.extend_from_slice(wire::encode(&FeCtl::Rate { hz: 2000 }, &mut buf).unwrap());
        bytes.extend_from_slice(&[0x05, 0xff, 0x00]);
        bytes.extend_from_slice(wire::encode(&FeCtl::Rate { hz: 500 }, &mut buf).unwrap());
        let rate = AtomicU32::new(0);
        let stats = read_ctl(&bytes[..], &rate, &AtomicBool::new(false)).unwrap();
        assert_eq!(rate.load(Ordering::Relaxed), 500);
        assert_eq!(stats, CtlStats { rates: 2, bad_frames: 1, last_rate_hz: Some(500) });
    }

    #[test]
    fn bad_options_and_non_triads_are_refused() {
        let head = Head::new(Clock::start(), Motion::default(), (0.0, 0.0));
        let mut fe = FrontEnd::new(unit(&SimConfig { samples: 1, ..SimConfig::default() }), 3).unwrap();
        let opts = PaceOptions { rate_factor: 0.0, ..PaceOptions::default() };
        let (rate, stop) = (AtomicU32::new(100), AtomicBool::new(false));
        let r = run_frontend(&mut fe, &head, &rate, std::io::sink(), &stop, &opts, &FeCounters::default());
        assert!(matches!(r, Err(FrontendError::Options(_))));
        let mut u = unit(&SimConfig { samples: 1, ..SimConfig::default() });
        u.channels.pop();
        assert!(FrontEnd::new(u, 1).is_err());
    }
}
