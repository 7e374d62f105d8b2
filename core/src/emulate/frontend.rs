//! The emulated analog front end: the code sets a [`Unit`] on the emulated head gives
//! ([`FrontEnd`]), the loop that sends them to the QEMU node paced by the host clock
//! ([`run_frontend`]), and the reader of the node's rate messages ([`read_ctl`]). The channel's
//! contract is `accelcal_shared::frontend`.
//!
//! Invariants:
//! - A code set is computed by [`crate::sim::unit::sample_set`], the function `simulate` uses:
//!   standing at position p (p = moves completed), the block sees
//!   [`Unit::standing_accel`]`(p, angles)` exactly as `simulate` at plan position p, with
//!   `t_in_dwell_s` the time since the head stopped, `prev_accel` the acceleration at position
//!   p − 1 (None at p = 0) and `temp_c` NaN.
//! - While the head moves from position p to p + 1 the angles are those of the head's motion,
//!   and the kinematic effects' angles are interpolated between those of position p and of
//!   position p + 1 (continuous at both ends). Effects of the step (settling, hysteresis) keep
//!   seeing the step of the completed move p − 1 → p: `prev_accel` is shifted with the
//!   orientation so that [`crate::sim::SampleCtx::step`] stays that step.
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
use crate::sim::effects::Kinematics;
use crate::sim::unit::{SetCtx, Unit, UnitError};

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

    /// The context of set `n`, taken at `t_s` on the bench clock with the head in `pose`.
    pub fn set_ctx(&mut self, pose: &HeadPose, n: u64, t_s: f64) -> SetCtx {
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
            temp_c: f64::NAN,
            prev_accel,
        }
    }

    /// The codes of set `n` (channels x, y, z), at `t_s` with the head in `pose`.
    pub fn codes(&mut self, pose: &HeadPose, n: u64, t_s: f64) -> Codes {
        let set = self.set_ctx(pose, n, t_s);
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
    Write(#[source] std::io::Error),
    /// Reading the node's messages failed.
    #[error("front end: reading from the node failed: {0}")]
    Read(#[source] std::io::Error),
    /// The pacing options are out of range.
    #[error("front end: {0}")]
    Options(String),
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
            let set = FeSet { index: n as u16, codes: fe.codes(&pose, n, t) };
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
            Err(e)
                if matches!(
                    e.kind(),
                    std::io::ErrorKind::WouldBlock
                        | std::io::ErrorKind::TimedOut
                        | std::io::ErrorKind::Interrupted
                ) =>
            {
                continue
            }
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
