//! A seeded simulator of the rig: a dividing head stepping through a position plan, a block of
//! analog accelerometers (bias, scale, misalignment, noise) read by a 16-bit ADC (quantisation and
//! clipping), and pluggable error effects.
//!
//! [`plan`]: position plans; [`effects`]: the `Effect` trait and the models of the registry's
//! effects (`crate::effects`), with `from_description`, which rebuilds an effect from its truth
//! JSON through the registry's parser; [`unit`]: `Truth`, the per-sample model `sample_set` and
//! `standing_accel` that `simulate` and the emulated front end both call, and `Unit`, a truth
//! file rebuilt to be sampled one set at a time. [`ThermalPlan`]: the plan repeated per chamber
//! setpoint after a soak, the sensor following the chamber with a first-order lag.

pub mod effects;
pub mod plan;
pub mod unit;

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

use crate::campaign::{Campaign, Channel};
pub use effects::{Effect, Kinematics, SampleCtx};
pub use plan::{Plan, PlanHeader};
pub use unit::{sample_set, standing_accel, ChannelTruth, SetCtx, Truth, Unit, UnitError};

/// Nominal MS9002-class sensitivity: ±2 g over the 16-bit range, i.e. 16384 codes per g.
pub const NOMINAL_CODES_PER_G: f64 = 16384.0;

/// Channel layouts.
#[derive(Clone, Debug, PartialEq)]
pub enum Layout {
    /// Three channels `x`, `y`, `z` along the block's axes.
    Triad,
    /// `n` single-axis sensors `a1..an`, sensitive axes cycling x, y, z.
    Block(usize),
}

impl std::str::FromStr for Layout {
    type Err = String;
    fn from_str(s: &str) -> Result<Layout, String> {
        if s == "triad" {
            return Ok(Layout::Triad);
        }
        match s.strip_prefix("block:").map(str::parse::<usize>) {
            Some(Ok(n)) if (1..=8).contains(&n) => Ok(Layout::Block(n)),
            _ => Err(format!("`{s}`: expected `triad` or `block:N` with N in 1..=8")),
        }
    }
}

impl Layout {
    /// Names and nominal sensitive axes of the channels.
    pub fn channels(&self) -> Vec<(String, usize)> {
        match self {
            Layout::Triad => vec![("x".into(), 0), ("y".into(), 1), ("z".into(), 2)],
            Layout::Block(n) => (0..*n).map(|i| (format!("a{}", i + 1), i % 3)).collect(),
        }
    }
}

/// Settings of a simulation.
pub struct SimConfig {
    /// Seed of every random draw.
    pub seed: u64,
    /// Position plan.
    pub plan: Plan,
    /// Channel layout.
    pub layout: Layout,
    /// Gravity, m/s².
    pub g: f64,
    /// Sample sets per position.
    pub samples: usize,
    /// Sample rate, Hz.
    pub rate_hz: f64,
    /// Time the head takes to move between positions, s.
    pub move_s: f64,
    /// White noise per sample, codes (one sigma).
    pub noise: f64,
    /// Spread of the biases around mid-scale, codes (one sigma).
    pub bias_sd: f64,
    /// Relative spread of the scale factors (one sigma).
    pub scale_sd: f64,
    /// Spread of each sensitive axis' misalignment angles, rad (one sigma).
    pub misalign_sd: f64,
    /// Error effects added to the ideal output.
    pub effects: Vec<Box<dyn Effect>>,
    /// Round to whole codes and clip to the ADC range (false: an ideal, infinitely fine ADC).
    pub quantize: bool,
    /// Temperature of the block over the campaign; when set, the campaign has a `temp_c` column.
    pub temp: Option<TempProfile>,
    /// A thermal campaign: the plan repeated at several chamber temperatures (exclusive with
    /// `temp`); the campaign then has a `temp_c` column, the sensor's temperature.
    pub thermal: Option<ThermalPlan>,
}

/// A thermal campaign's chamber: before each pass of the plan the chamber steps to the next
/// setpoint and the rig waits `soak_s`; the sensor follows the chamber as a first-order lag with
/// time constant `tau_s` the whole time (starting soaked at 25 °C), so a short soak leaves the
/// sensor still moving during the pass.
#[derive(Clone, Debug, PartialEq)]
pub struct ThermalPlan {
    /// Chamber setpoints, °C, one pass of the plan at each.
    pub chamber_c: Vec<f64>,
    /// Wait after each step of the chamber before the pass starts, s.
    pub soak_s: f64,
    /// Thermal time constant between chamber and sensor, s.
    pub tau_s: f64,
}

impl std::str::FromStr for ThermalPlan {
    type Err = String;
    /// Parses `T1,T2,…:SOAK_S:TAU_S` (°C, s, s).
    fn from_str(s: &str) -> Result<ThermalPlan, String> {
        let err = || {
            format!("`{s}`: expected T1,T2,…:SOAK_S:TAU_S (°C list, soak s, lag s; e.g. -10,20,50:900:120)")
        };
        let parts: Vec<&str> = s.split(':').collect();
        let [temps, soak, tau] = parts[..] else { return Err(err()) };
        let chamber_c: Vec<f64> =
            temps.split(',').map(|x| x.trim().parse::<f64>()).collect::<Result<_, _>>().map_err(|_| err())?;
        let soak_s: f64 = soak.trim().parse().map_err(|_| err())?;
        let tau_s: f64 = tau.trim().parse().map_err(|_| err())?;
        let ok = !chamber_c.is_empty()
            && chamber_c.iter().all(|t| t.is_finite() && (-60.0..=150.0).contains(t))
            && soak_s.is_finite()
            && soak_s >= 0.0
            && tau_s.is_finite()
            && tau_s >= 0.0;
        if ok {
            Ok(ThermalPlan { chamber_c, soak_s, tau_s })
        } else {
            Err(err())
        }
    }
}

/// The sensor's temperature after `dt` s of following `chamber_c` from `from_c` with time
/// constant `tau_s`.
pub fn lag(from_c: f64, chamber_c: f64, dt: f64, tau_s: f64) -> f64 {
    if tau_s > 0.0 {
        chamber_c + (from_c - chamber_c) * (-dt / tau_s).exp()
    } else {
        chamber_c
    }
}

/// A temperature profile: `base + amp·sin(2π·cycles·t/T + phase)` over a campaign of duration T.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TempProfile {
    /// Mean temperature, °C.
    pub base_c: f64,
    /// Amplitude, °C.
    pub amp_c: f64,
    /// Cycles over the campaign.
    pub cycles: f64,
    /// Phase, rad.
    pub phase: f64,
}

impl TempProfile {
    /// Temperature at time `t` of a campaign lasting `duration` s.
    pub fn at(&self, t: f64, duration: f64) -> f64 {
        self.base_c
            + self.amp_c * (std::f64::consts::TAU * self.cycles * t / duration.max(1e-9) + self.phase).sin()
    }
}

impl std::str::FromStr for TempProfile {
    type Err = String;
    /// Parses `BASE:AMP:CYCLES` (°C, °C, cycles over the campaign; the phase is 0).
    fn from_str(s: &str) -> Result<TempProfile, String> {
        let v: Vec<f64> =
            s.split(':').filter_map(|x| x.trim().parse().ok()).filter(|x: &f64| x.is_finite()).collect();
        match v[..] {
            [base_c, amp_c, cycles] if s.split(':').count() == 3 => {
                Ok(TempProfile { base_c, amp_c, cycles, phase: 0.0 })
            }
            _ => Err(format!("`{s}`: expected BASE:AMP:CYCLES, three finite numbers (e.g. 25:5:1.5)")),
        }
    }
}

impl Default for SimConfig {
    fn default() -> SimConfig {
        SimConfig {
            seed: 1,
            plan: Plan::head(),
            layout: Layout::Triad,
            g: accelcal_shared::G_STANDARD,
            samples: 400,
            rate_hz: 100.0,
            move_s: 2.0,
            noise: 80.0,
            bias_sd: 300.0,
            scale_sd: 0.01,
            misalign_sd: 0.01,
            effects: Vec::new(),
            quantize: true,
            temp: None,
            thermal: None,
        }
    }
}

fn normal(sd: f64) -> Normal<f64> {
    unit::noise_distribution(sd)
}

/// Runs the simulation.
pub fn simulate(cfg: &SimConfig) -> (Campaign, Truth) {
    let mut rng = ChaCha8Rng::seed_from_u64(cfg.seed);
    let nominal = NOMINAL_CODES_PER_G / cfg.g;
    let chans: Vec<ChannelTruth> = cfg
        .layout
        .channels()
        .into_iter()
        .map(|(name, axis)| {
            let bias = 32768.0 + normal(cfg.bias_sd).sample(&mut rng);
            let scale = nominal * (1.0 + normal(cfg.scale_sd).sample(&mut rng));
            let mut dir = [0.0; 3];
            dir[axis] = 1.0;
            for (j, d) in dir.iter_mut().enumerate() {
                if j != axis {
                    *d = normal(cfg.misalign_sd).sample(&mut rng);
                }
            }
            let norm = dir.iter().map(|d| d * d).sum::<f64>().sqrt();
            ChannelTruth { name, axis, bias, k: dir.map(|d| scale * d / norm) }
        })
        .collect();
    let mut c = Campaign {
        channels: chans.iter().map(|t| Channel { name: t.name.clone(), codes: Vec::new() }).collect(),
        g_m_s2: Some(cfg.g),
        ..Campaign::default()
    };
    let noise = normal(cfg.noise);
    let dt = 1.0 / cfg.rate_hz;
    let duration = cfg.plan.positions.len() as f64 * (cfg.samples as f64 * dt + cfg.move_s);
    if cfg.temp.is_some() || cfg.thermal.is_some() {
        c.temp_c = Some(Vec::new());
    }
    let mut t = 0.0f64;
    let mut prev_accel: Option<[f64; 3]> = None;
    // The thermal plan's chamber and sensor: (chamber setpoint, sensor temperature, its time).
    let passes = cfg.thermal.as_ref().map_or(1, |th| th.chamber_c.len());
    let mut sensor = (25.0f64, 25.0f64, 0.0f64);
    let n_plan = cfg.plan.positions.len();
    for (p, &(alpha, beta)) in (0..passes).flat_map(|_| cfg.plan.positions.iter()).enumerate() {
        if let Some(th) = cfg.thermal.as_ref().filter(|_| p % n_plan == 0) {
            sensor.1 = lag(sensor.1, sensor.0, t - sensor.2, th.tau_s);
            sensor = (th.chamber_c[p / n_plan], sensor.1, t);
            t += th.soak_s;
        }
        let accel = standing_accel(&cfg.effects, cfg.seed, p, (alpha, beta), cfg.g);
        for s in 0..cfg.samples {
            c.t_s.push((t * 1e6).round() / 1e6);
            c.alpha_deg.push(alpha);
            c.beta_deg.push(beta);
            let temp_c = match (&cfg.thermal, cfg.temp) {
                (Some(th), _) => lag(sensor.1, sensor.0, t - sensor.2, th.tau_s),
                (None, Some(tp)) => tp.at(t, duration),
                (None, None) => f64::NAN,
            };
            if let Some(v) = c.temp_c.as_mut() {
                v.push((temp_c * 1000.0).round() / 1000.0);
            }
            let set = SetCtx {
                t_s: t,
                position: p,
                sample: s,
                accel,
                t_in_dwell_s: s as f64 * dt,
                temp_c,
                prev_accel,
            };
            // The simulated ADC: unsigned 16-bit codes, clipped at its rails (in `sample_set`).
            sample_set(&chans, &cfg.effects, &set, &noise, &mut rng, cfg.quantize, |ch, u| {
                c.channels[ch].codes.push(u)
            });
            t += dt;
        }
        prev_accel = Some(accel);
        t += cfg.move_s;
    }
    let truth = Truth {
        seed: cfg.seed,
        g: cfg.g,
        noise: cfg.noise,
        channels: chans,
        effects: cfg.effects.iter().map(|e| e.describe()).collect(),
    };
    (c, truth)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn same_seed_same_campaign_and_clipping_holds() {
        let cfg = SimConfig { samples: 3, ..SimConfig::default() };
        let (a, ta) = simulate(&cfg);
        let (b, _) = simulate(&cfg);
        assert_eq!(a, b);
        assert_eq!(a.len(), 62 * 3);
        assert_eq!(a.dwells().len(), 62);
        assert!(a
            .channels
            .iter()
            .all(|c| c.codes.iter().all(|&v| (0.0..=65535.0).contains(&v) && v.fract() == 0.0)));
        let k = ta.channels[0].k;
        assert!((k[0] - 1670.0).abs() < 100.0 && k[1].abs() < 50.0, "{k:?}");
        let (c, _) = simulate(&SimConfig { seed: 2, samples: 3, ..SimConfig::default() });
        assert_ne!(a, c);
    }
}
