//! A seeded simulator of the rig: a dividing head stepping through a position plan, a block of
//! analog accelerometers (bias, scale, misalignment, noise) read by a 16-bit ADC (quantisation and
//! clipping), and pluggable error effects.

pub mod effects;
pub mod plan;

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use serde::Serialize;

use crate::campaign::{Campaign, Channel, ADC_MAX};
pub use effects::{Effect, SampleCtx};
pub use plan::Plan;

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
        }
    }
}

/// The truth behind a simulated campaign, written beside it as JSON.
#[derive(Clone, Debug, Serialize, serde::Deserialize)]
pub struct Truth {
    /// Seed used.
    pub seed: u64,
    /// Gravity, m/s².
    pub g: f64,
    /// Noise per sample, codes.
    pub noise: f64,
    /// Each channel's linear model.
    pub channels: Vec<ChannelTruth>,
    /// The effects, with their parameters.
    pub effects: Vec<serde_json::Value>,
}

/// One channel's true linear model `u = bias + k·a` (before effects, noise and quantisation).
#[derive(Clone, Debug, Serialize, serde::Deserialize)]
pub struct ChannelTruth {
    /// Channel name.
    pub name: String,
    /// Nominal sensitive axis (0 = x, 1 = y, 2 = z).
    pub axis: usize,
    /// Zero offset, codes.
    pub bias: f64,
    /// Sensitivity to ax, ay, az, codes per m/s².
    pub k: [f64; 3],
}

fn normal(sd: f64) -> Normal<f64> {
    Normal::new(0.0, sd.abs()).expect("finite standard deviation")
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
        ..Campaign::default()
    };
    let noise = normal(cfg.noise);
    let dt = 1.0 / cfg.rate_hz;
    let mut t = 0.0f64;
    for (p, &(alpha, beta)) in cfg.plan.positions.iter().enumerate() {
        let accel = accelcal_shared::gravity(alpha, beta, cfg.g);
        for s in 0..cfg.samples {
            c.t_s.push((t * 1e6).round() / 1e6);
            c.alpha_deg.push(alpha);
            c.beta_deg.push(beta);
            for (ch, truth) in chans.iter().enumerate() {
                let ctx = SampleCtx { t_s: t, position: p, sample: s, accel, channel: ch, axis: truth.axis };
                let mut u = truth.bias + (0..3).map(|j| truth.k[j] * accel[j]).sum::<f64>();
                for e in &cfg.effects {
                    u += e.output(&ctx);
                }
                u += noise.sample(&mut rng);
                c.channels[ch].codes.push(if cfg.quantize { u.round().clamp(0.0, ADC_MAX) } else { u });
            }
            t += dt;
        }
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
            .all(|c| c.codes.iter().all(|&v| (0.0..=ADC_MAX).contains(&v) && v.fract() == 0.0)));
        let k = ta.channels[0].k;
        assert!((k[0] - 1670.0).abs() < 100.0 && k[1].abs() < 50.0, "{k:?}");
        let (c, _) = simulate(&SimConfig { seed: 2, samples: 3, ..SimConfig::default() });
        assert_ne!(a, c);
    }
}
