//! The blind benchmark: simulated campaigns, each clean or with one effect whose seed, direction
//! and magnitude the diagnosis is never told; the confusion table of true against reported
//! effects, and the held-out shrink reached against that of an oracle which knows the effect.
//!
//! Magnitude: the RMS, over positions and channels, of the effect's contribution to the dwell
//! means (each channel's mean removed), in units of the per-position noise σ/√samples. Every
//! campaign has a temperature profile, so `temperature` is always a candidate.

use std::collections::BTreeMap;

use accelcal_shared::terms::MODEL_4;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use serde::Serialize;

use super::attribution::{heldout, select, Cand};
use super::Data;
use crate::sim::{self, effects, SimConfig, TempProfile};

/// Default range of the magnitudes drawn, in units of the per-position noise.
pub const MAGNITUDE: (f64, f64) = (5.0, 15.0);

/// One benchmark campaign as generated (what the diagnosis is not told).
#[derive(Clone, Debug, Serialize)]
pub struct Case {
    /// Index in the benchmark.
    pub index: usize,
    /// Simulation seed.
    pub seed: u64,
    /// The true effect (None: clean).
    pub truth: Option<&'static str>,
    /// The effect as given to the simulator.
    pub spec: Option<String>,
    /// Magnitude, per-position noise units.
    pub magnitude: f64,
}

/// The outcome on one campaign.
#[derive(Clone, Debug, Serialize)]
pub struct Outcome {
    /// The campaign.
    pub case: Case,
    /// Effects reported, in order.
    pub reported: Vec<&'static str>,
    /// Whether the report is exactly the truth (empty for a clean campaign).
    pub correct: bool,
    /// Held-out RMS of the baseline, codes.
    pub rms_before: f64,
    /// Held-out RMS with the reported effects, codes.
    pub rms_after: f64,
    /// Held-out RMS with the true effect (the oracle), codes.
    pub rms_oracle: f64,
}

/// The benchmark's summary.
#[derive(Clone, Debug, Serialize)]
pub struct Summary {
    /// Campaigns run.
    pub campaigns: usize,
    /// `confusion[truth][reported]` counts (`none` for clean / nothing reported; several
    /// reported effects are joined with `+`).
    pub confusion: BTreeMap<String, BTreeMap<String, usize>>,
    /// Fraction correct per true effect (`none`: clean campaigns with nothing reported).
    pub accuracy: BTreeMap<String, f64>,
    /// Fraction correct over the campaigns with an effect.
    pub accuracy_effects: f64,
    /// Clean campaigns on which something was reported.
    pub clean_false_positives: usize,
    /// Clean campaigns.
    pub clean: usize,
    /// Per true effect: Σ(before − after) / Σ(before − oracle) of the held-out RMS.
    pub shrink_vs_oracle: BTreeMap<String, f64>,
    /// The same over all campaigns with an effect.
    pub shrink_vs_oracle_all: f64,
    /// Every campaign.
    pub outcomes: Vec<Outcome>,
}

fn sign(rng: &mut ChaCha8Rng) -> f64 {
    if rng.random::<bool>() {
        1.0
    } else {
        -1.0
    }
}

/// An effect spec with unit-ish parameters in a random direction, scaled by `s`.
fn spec(c: Cand, s: f64, rng: &mut ChaCha8Rng) -> String {
    match c {
        Cand::BiasDrift => format!("bias_drift=rate:{}", 0.1 * s * sign(rng)),
        Cand::Temperature => {
            let (b, k) = match rng.random_range(0..3) {
                0 => (1.0, 0.0),
                1 => (0.0, 100.0),
                _ => (0.7, 70.0),
            };
            format!("temperature=bias:{},scale:{}", b * s * sign(rng), k * s * sign(rng))
        }
        Cand::Nonlinearity => {
            let (k2, xy) = match rng.random_range(0..3) {
                0 => (0.1, 0.0),
                1 => (0.0, 0.1),
                _ => (0.07, 0.07),
            };
            format!("nonlinearity=k2:{},ax*ay:{}", k2 * s * sign(rng), xy * s * sign(rng))
        }
        Cand::HeadMisalignment => {
            let th: f64 = rng.random_range(0.0..std::f64::consts::TAU);
            format!("head_misalignment=rx_mrad:{},rz_mrad:{}", s * th.cos(), s * th.sin())
        }
        Cand::Hysteresis => format!("hysteresis=h:{}", 10.0 * s * sign(rng)),
        Cand::Settling => {
            let tau: f64 = rng.random_range(0.2..1.5);
            format!("settling=gain:{},tau:{tau:.3}", 10.0 * s * sign(rng))
        }
        Cand::AngleError => format!("angle_error=sd_mrad:{}", s),
    }
}

/// RMS of an effect's contribution to the dwell means (channel means removed), codes.
fn effect_rms(cfg: &SimConfig, spec: &str) -> f64 {
    let exact = |effects: Vec<Box<dyn effects::Effect>>| {
        let c = SimConfig { noise: 0.0, quantize: false, effects, temp: cfg.temp, ..base_config(cfg.seed) };
        sim::simulate(&c).0
    };
    let a = exact(Vec::new());
    let b = exact(vec![effects::parse(spec).expect("benchmark specs parse")]);
    let dw = a.dwells();
    let mut ss = 0.0;
    for (ca, cb) in a.channels.iter().zip(&b.channels) {
        let diff: Vec<f64> = dw
            .iter()
            .map(|w| (w.start..w.end).map(|i| cb.codes[i] - ca.codes[i]).sum::<f64>() / w.len() as f64)
            .collect();
        let m = diff.iter().sum::<f64>() / diff.len() as f64;
        ss += diff.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / diff.len() as f64;
    }
    (ss / a.channels.len() as f64).sqrt()
}

fn base_config(seed: u64) -> SimConfig {
    SimConfig { seed, ..SimConfig::default() }
}

/// Generates campaign `index` of the benchmark with master seed `master`: clean for index ≡ 0
/// (mod 8), else the effect `Cand::ALL[index % 8 − 1]` with a magnitude drawn uniformly in
/// `range` (per-position noise units).
pub fn generate(master: u64, index: usize, range: (f64, f64)) -> (Case, SimConfig) {
    let mut rng = ChaCha8Rng::seed_from_u64(master ^ (index as u64 + 1).wrapping_mul(0x9E37_79B9_7F4A_7C15));
    let seed: u64 = rng.random();
    let temp = TempProfile {
        base_c: rng.random_range(20.0..30.0),
        amp_c: rng.random_range(2.0..8.0),
        cycles: rng.random_range(1.0..2.5),
        phase: rng.random_range(0.0..std::f64::consts::TAU),
    };
    let mut cfg = SimConfig { temp: Some(temp), ..base_config(seed) };
    let truth = match index % 8 {
        0 => None,
        k => Some(Cand::ALL[k - 1]),
    };
    let magnitude = if range.1 > range.0 { rng.random_range(range.0..range.1) } else { range.0 };
    let mut case = Case { index, seed, truth: truth.map(Cand::name), spec: None, magnitude: 0.0 };
    if let Some(c) = truth {
        let mut dir = rng.clone();
        let unit = spec(c, 1.0, &mut dir);
        let sigma_pos = cfg.noise / (cfg.samples as f64).sqrt();
        let s = magnitude * sigma_pos / effect_rms(&cfg, &unit);
        let mut dir = rng.clone();
        let scaled = spec(c, s, &mut dir);
        case.magnitude = effect_rms(&cfg, &scaled) / sigma_pos;
        cfg.effects = vec![effects::parse(&scaled).expect("benchmark specs parse")];
        case.spec = Some(scaled);
    }
    (case, cfg)
}

/// Runs one campaign: simulate, diagnose blind, score against the oracle.
pub fn run_case(master: u64, index: usize, range: (f64, f64)) -> Outcome {
    let (case, cfg) = generate(master, index, range);
    let (c, _) = sim::simulate(&cfg);
    let d = Data::new(&c, cfg.g).expect("simulated campaigns have noise and positions");
    let sel = select(&d, MODEL_4);
    let set = sel.set;
    let reported: Vec<&'static str> = set.iter().map(|c| c.name()).collect();
    let truth: Vec<&'static str> = case.truth.into_iter().collect();
    let rms_before = sel.rounds.first().map_or(f64::NAN, |r| r.before.rms);
    let rms_after = heldout(&d, MODEL_4, &set).rms;
    let oracle: Vec<Cand> = case.truth.and_then(Cand::from_name).into_iter().collect();
    let rms_oracle = heldout(&d, MODEL_4, &oracle).rms;
    Outcome { correct: reported == truth, case, reported, rms_before, rms_after, rms_oracle }
}

/// Runs `n` campaigns (in parallel) with magnitudes in `range`; `tick` is called after each.
pub fn run(n: usize, master: u64, range: (f64, f64), tick: &(dyn Fn() + Sync)) -> Summary {
    let outcomes: Vec<Outcome> = (0..n)
        .into_par_iter()
        .map(|i| {
            let o = run_case(master, i, range);
            tick();
            o
        })
        .collect();
    summarise(outcomes)
}

fn label(v: &[&str]) -> String {
    if v.is_empty() {
        "none".into()
    } else {
        v.join("+")
    }
}

/// Tabulates outcomes.
pub fn summarise(outcomes: Vec<Outcome>) -> Summary {
    let mut confusion: BTreeMap<String, BTreeMap<String, usize>> = BTreeMap::new();
    let mut tally: BTreeMap<String, (usize, usize, f64, f64)> = BTreeMap::new();
    for o in &outcomes {
        let t = label(&o.case.truth.into_iter().collect::<Vec<_>>());
        *confusion.entry(t.clone()).or_default().entry(label(&o.reported)).or_default() += 1;
        let e = tally.entry(t).or_default();
        e.0 += 1;
        e.1 += o.correct as usize;
        e.2 += o.rms_before - o.rms_after;
        e.3 += o.rms_before - o.rms_oracle;
    }
    let accuracy = tally.iter().map(|(k, v)| (k.clone(), v.1 as f64 / v.0 as f64)).collect();
    let shrink_vs_oracle =
        tally.iter().filter(|(k, _)| *k != "none").map(|(k, v)| (k.clone(), v.2 / v.3)).collect();
    let eff: Vec<&Outcome> = outcomes.iter().filter(|o| o.case.truth.is_some()).collect();
    let clean: Vec<&Outcome> = outcomes.iter().filter(|o| o.case.truth.is_none()).collect();
    let num: f64 = eff.iter().map(|o| o.rms_before - o.rms_after).sum();
    let den: f64 = eff.iter().map(|o| o.rms_before - o.rms_oracle).sum();
    Summary {
        campaigns: outcomes.len(),
        confusion,
        accuracy,
        accuracy_effects: eff.iter().filter(|o| o.correct).count() as f64 / eff.len().max(1) as f64,
        clean_false_positives: clean.iter().filter(|o| !o.reported.is_empty()).count(),
        clean: clean.len(),
        shrink_vs_oracle,
        shrink_vs_oracle_all: num / den,
        outcomes,
    }
}
