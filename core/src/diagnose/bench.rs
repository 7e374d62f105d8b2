//! The blind benchmark: simulated campaigns, clean, with one, two or three effects of the
//! library, or with an effect outside it ([`Outside`], generated here and nowhere else); seeds,
//! directions and magnitudes the diagnosis is never told. Scored per case kind as right / wrong /
//! missed, with the held-out shrink reached against that of an oracle that refits with the true
//! effect set.
//!
//! Magnitude: the RMS, over positions and channels, of one effect's contribution to the dwell
//! means (each channel's mean removed), in units of the per-position noise σ/√samples; every
//! effect of a campaign gets its own magnitude. Every campaign has a temperature profile, so
//! `temperature` is always a candidate.

use std::collections::BTreeMap;

use accelcal_shared::terms::MODEL_4;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use serde::Serialize;
use serde_json::json;

use super::attribution::{heldout, Cand};
use super::Data;
use crate::sim::effects::{rotation, Effect, Kinematics, SampleCtx};
use crate::sim::{self, effects, Plan, SimConfig, TempProfile};

/// Default range of the magnitudes drawn, in units of the per-position noise.
pub const MAGNITUDE: (f64, f64) = (3.0, 8.0);

/// Effects outside the library: things a real rig or sensor does that no library effect models.
/// The benchmark generates them; the diagnosis knows nothing of them.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Outside {
    /// Mains pickup beating with the sample clock: a sine in time of period 8–60 s, with its own
    /// amplitude on each channel.
    Hum,
    /// Crosstalk of transients: each channel picks up the settling transient of the next axis's
    /// step (`gain·Δa_next·exp(−t_d/τ)`), which the library's `settling` (own axis) does not.
    Crosstalk,
    /// Square-law supply droop: the motor's current after a move sags the reference by the
    /// square of the step, recovering with τ (`c·Δa_own²/g·exp(−t_d/τ)`, even in the step).
    SupplyDroop,
    /// A wobbling α bearing: the head tilts about x by `θ·sin(α + φ)` (a rotation that changes
    /// with the head's angle, unlike `head_misalignment`).
    AxisWobble,
    /// Cable wind-up: the cable twists as α turns and is rewound at each row, pulling on the
    /// board; a bias proportional to α on each channel.
    CableWindup,
}

impl Outside {
    /// Every kind.
    pub const ALL: [Outside; 5] =
        [Outside::Hum, Outside::Crosstalk, Outside::SupplyDroop, Outside::AxisWobble, Outside::CableWindup];

    /// Name in the tables (in the order of [`Outside::ALL`]).
    pub fn name(self) -> &'static str {
        ["hum", "crosstalk", "supply_droop", "axis_wobble", "cable_windup"][self as usize]
    }
}

/// An out-of-library effect with its drawn parameters, scaled by `s`.
struct Foreign {
    kind: Outside,
    s: f64,
    /// Per channel amplitude direction (hum, cable wind-up).
    amp: [f64; 3],
    /// Period (hum), s; τ (crosstalk, droop), s.
    time: f64,
    /// Phase, rad.
    phase: f64,
    /// Commanded α of each position, degrees.
    alpha: Vec<f64>,
}

impl Effect for Foreign {
    fn name(&self) -> &'static str {
        self.kind.name()
    }
    fn describe(&self) -> serde_json::Value {
        json!({"name": self.kind.name(), "scale": self.s, "amp": self.amp, "time_s": self.time, "phase": self.phase})
    }
    fn output(&self, ctx: &SampleCtx) -> f64 {
        let prev = ctx.prev_accel;
        let step = |axis: usize| prev.map_or(0.0, |p| ctx.accel[axis] - p[axis]);
        let amp = self.amp[ctx.channel % 3];
        match self.kind {
            Outside::Hum => self.s * amp * (std::f64::consts::TAU * ctx.t_s / self.time + self.phase).sin(),
            Outside::Crosstalk => self.s * step((ctx.axis + 1) % 3) * (-ctx.t_in_dwell_s / self.time).exp(),
            Outside::SupplyDroop => {
                let st = step(ctx.axis);
                -self.s * st * st / 9.81 * (-ctx.t_in_dwell_s / self.time).exp()
            }
            Outside::AxisWobble => 0.0,
            Outside::CableWindup => {
                self.s * amp * self.alpha.get(ctx.position).copied().unwrap_or(0.0) / 360.0
            }
        }
    }
    fn kinematics(&self, k: &mut Kinematics) {
        if self.kind != Outside::AxisWobble {
            return;
        }
        // The block sees −g·Ry(α)·r·Rx(−β)·e_z; r = Ry(−α)·T·Ry(α) puts the tilt T outermost.
        let alpha = k.alpha_rad;
        let tilt = rotation([self.s * 1e-3 * (alpha + self.phase).sin(), 0.0, 0.0]);
        let m = mat_mul(&mat_mul(&rotation([0.0, -alpha, 0.0]), &tilt), &rotation([0.0, alpha, 0.0]));
        k.r = mat_mul(&k.r, &m);
        k.changed = true;
    }
}

fn mat_mul(a: &[[f64; 3]; 3], b: &[[f64; 3]; 3]) -> [[f64; 3]; 3] {
    let mut out = [[0.0; 3]; 3];
    for (i, row) in out.iter_mut().enumerate() {
        for (j, v) in row.iter_mut().enumerate() {
            *v = (0..3).map(|m| a[i][m] * b[m][j]).sum();
        }
    }
    out
}

/// One effect of a benchmark campaign.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Ingredient {
    /// An effect of the library.
    Library(Cand),
    /// An effect outside it.
    Outside(Outside),
}

impl Ingredient {
    fn name(self) -> &'static str {
        match self {
            Ingredient::Library(c) => c.name(),
            Ingredient::Outside(o) => o.name(),
        }
    }
}

/// The kinds of benchmark campaigns.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum CaseKind {
    /// No effect.
    Clean,
    /// One library effect.
    Single,
    /// Two library effects.
    Pair,
    /// Three library effects.
    Triple,
    /// One effect outside the library.
    Outside,
}

impl CaseKind {
    /// Name in the tables (in the order of declaration, which is the tables' order).
    pub fn name(self) -> &'static str {
        ["clean", "one effect", "two effects", "three effects", "outside library"][self as usize]
    }

    /// The kind of campaign `index`: of every 8, one clean, two single, two pairs, one triple,
    /// two outside the library.
    pub fn of(index: usize) -> CaseKind {
        match index % 8 {
            0 => CaseKind::Clean,
            1 | 2 => CaseKind::Single,
            3 | 4 => CaseKind::Pair,
            5 => CaseKind::Triple,
            _ => CaseKind::Outside,
        }
    }
}

/// One benchmark campaign as generated (what the diagnosis is not told).
#[derive(Clone, Debug, Serialize)]
pub struct Case {
    /// Index in the benchmark.
    pub index: usize,
    /// Its kind.
    pub kind: CaseKind,
    /// Simulation seed.
    pub seed: u64,
    /// The true effects (empty: clean).
    pub truth: Vec<&'static str>,
    /// The effects as generated (library specs, or the outside effect's description).
    pub specs: Vec<String>,
    /// Magnitude of each effect, per-position noise units.
    pub magnitudes: Vec<f64>,
}

/// How a campaign's report compares with the truth.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Verdict {
    /// Library cases: exactly the true set named, none partial; clean: nothing named; outside:
    /// the gap reported as unexplained (nothing named, or only partial effects / effects that
    /// claim at most half of it).
    Right,
    /// A name not in the truth (library cases); outside: a library name claiming more than half
    /// of the held-out gap.
    Wrong,
    /// Library cases: a true effect not named (or named as partial), nothing wrong; outside:
    /// nothing reported at all (the gap called noise).
    Missed,
}

/// The outcome on one campaign.
#[derive(Clone, Debug, Serialize)]
pub struct Outcome {
    /// The campaign.
    pub case: Case,
    /// Effects named, in order.
    pub reported: Vec<&'static str>,
    /// The named effects reported as partial.
    pub partial: Vec<&'static str>,
    /// Share of the held-out excess χ² the named effects remove together.
    pub claimed: f64,
    /// Residual left unexplained, codes.
    pub unexplained_rms: f64,
    /// The verdict.
    pub verdict: Verdict,
    /// Held-out RMS of the baseline, codes.
    pub rms_before: f64,
    /// Held-out RMS with the reported effects, codes.
    pub rms_after: f64,
    /// Held-out RMS with the true effect set (library cases; the oracle), codes.
    pub rms_oracle: Option<f64>,
}

/// Counts of one row of the table.
#[derive(Clone, Debug, Default, Serialize)]
pub struct Tally {
    /// Campaigns.
    pub campaigns: usize,
    /// Right.
    pub right: usize,
    /// Wrong.
    pub wrong: usize,
    /// Missed.
    pub missed: usize,
    /// Σ(before − after) of the held-out RMS over the library cases, codes.
    pub shrink: f64,
    /// Σ(before − oracle), codes.
    pub shrink_oracle: f64,
}

impl Tally {
    fn add(&mut self, o: &Outcome) {
        self.campaigns += 1;
        match o.verdict {
            Verdict::Right => self.right += 1,
            Verdict::Wrong => self.wrong += 1,
            Verdict::Missed => self.missed += 1,
        }
        if let Some(or) = o.rms_oracle {
            self.shrink += o.rms_before - o.rms_after;
            self.shrink_oracle += o.rms_before - or;
        }
    }

    /// Fraction right.
    pub fn right_share(&self) -> f64 {
        self.right as f64 / self.campaigns.max(1) as f64
    }

    /// Held-out shrink against the oracle's (None without library cases).
    pub fn vs_oracle(&self) -> Option<f64> {
        (self.shrink_oracle > 0.0).then(|| self.shrink / self.shrink_oracle)
    }
}

/// The benchmark's summary.
#[derive(Clone, Debug, Serialize)]
pub struct Summary {
    /// Campaigns run.
    pub campaigns: usize,
    /// Per case kind.
    pub kinds: BTreeMap<CaseKind, Tally>,
    /// Per true effect set (`none` for clean; names joined with `+`), for the detail rows.
    pub truths: BTreeMap<String, (CaseKind, Tally)>,
    /// `confusion[truth][reported]` counts (names joined with `+`, partial ones marked `~`).
    pub confusion: BTreeMap<String, BTreeMap<String, usize>>,
    /// Outside cases where a library name claims more than half of the held-out gap.
    pub outside_overclaimed: usize,
    /// Held-out shrink against the oracle over all library cases.
    pub shrink_vs_oracle: f64,
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

/// A library effect spec with unit-ish parameters in a random direction, scaled by `s`.
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

/// An effect scaled by `s`, its direction drawn from `rng`.
fn build(ing: Ingredient, s: f64, rng: &mut ChaCha8Rng, alpha: &[f64]) -> Box<dyn Effect> {
    match ing {
        Ingredient::Library(c) => effects::parse(&spec(c, s, rng)).expect("benchmark specs parse"),
        Ingredient::Outside(kind) => {
            let amp = [0; 3].map(|_| sign(rng) * rng.random_range(0.5..1.0));
            let time = match kind {
                Outside::Hum => rng.random_range(8.0..60.0),
                _ => rng.random_range(0.2..1.5),
            };
            let phase = rng.random_range(0.0..std::f64::consts::TAU);
            Box::new(Foreign { kind, s: s * sign(rng), amp, time, phase, alpha: alpha.to_vec() })
        }
    }
}

/// RMS of an effect's contribution to the dwell means (channel means removed), codes.
fn effect_rms(cfg: &SimConfig, e: Box<dyn Effect>) -> f64 {
    let exact = |effects: Vec<Box<dyn Effect>>| {
        let c = SimConfig { noise: 0.0, quantize: false, effects, temp: cfg.temp, ..base_config(cfg.seed) };
        sim::simulate(&c).0
    };
    let a = exact(Vec::new());
    let b = exact(vec![e]);
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
    SimConfig { seed, plan: Plan::head(), ..SimConfig::default() }
}

/// The `k`-th combination of `r` of the library's effects, in lexicographic order (cycling).
fn combination(k: usize, r: usize) -> Vec<Cand> {
    let n = Cand::ALL.len();
    let mut all: Vec<Vec<usize>> = Vec::new();
    let mut cur: Vec<usize> = (0..r).collect();
    loop {
        all.push(cur.clone());
        let Some(i) = (0..r).rev().find(|&i| cur[i] < n - r + i) else { break };
        cur[i] += 1;
        for j in i + 1..r {
            cur[j] = cur[j - 1] + 1;
        }
    }
    all[k % all.len()].iter().map(|&i| Cand::ALL[i]).collect()
}

/// The effects of campaign `index`: its kind's combinations in turn.
fn ingredients(index: usize) -> Vec<Ingredient> {
    let (round, slot) = (index / 8, index % 8);
    let lib = |v: Vec<Cand>| v.into_iter().map(Ingredient::Library).collect();
    match CaseKind::of(index) {
        CaseKind::Clean => Vec::new(),
        CaseKind::Single => lib(combination(2 * round + slot - 1, 1)),
        CaseKind::Pair => lib(combination(2 * round + slot - 3, 2)),
        CaseKind::Triple => lib(combination(round, 3)),
        CaseKind::Outside => {
            vec![Ingredient::Outside(Outside::ALL[(2 * round + slot - 6) % Outside::ALL.len()])]
        }
    }
}

/// Generates campaign `index` of the benchmark with master seed `master`: its kind from the
/// index ([`CaseKind::of`]), each effect's magnitude drawn uniformly in `range` (per-position noise
/// units) and its direction at random.
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
    let alpha: Vec<f64> = cfg.plan.positions.iter().map(|p| p.0).collect();
    let ings = ingredients(index);
    let kind = CaseKind::of(index);
    let mut case = Case {
        index,
        kind,
        seed,
        truth: ings.iter().map(|i| i.name()).collect(),
        specs: Vec::new(),
        magnitudes: Vec::new(),
    };
    let sigma_pos = cfg.noise / (cfg.samples as f64).sqrt();
    for ing in ings {
        let magnitude = if range.1 > range.0 { rng.random_range(range.0..range.1) } else { range.0 };
        let dir = rng.clone();
        let unit = effect_rms(&cfg, build(ing, 1.0, &mut dir.clone(), &alpha));
        let s = magnitude * sigma_pos / unit;
        let scaled = build(ing, s, &mut dir.clone(), &alpha);
        case.specs.push(match ing {
            Ingredient::Library(c) => spec(c, s, &mut dir.clone()),
            Ingredient::Outside(_) => scaled.describe().to_string(),
        });
        case.magnitudes.push(effect_rms(&cfg, build(ing, s, &mut dir.clone(), &alpha)) / sigma_pos);
        cfg.effects.push(scaled);
        // The next effect's direction from a fresh draw.
        let _: u64 = rng.random();
    }
    (case, cfg)
}

/// The verdict on a report: `named` (all named effects), `partial` (those of them reported as
/// partial), `claimed` (their joint share of the held-out excess), `unexplained` (codes).
fn verdict(
    case: &Case,
    named: &[&'static str],
    partial: &[&'static str],
    claimed: f64,
    unexplained: f64,
) -> Verdict {
    match case.kind {
        CaseKind::Outside => {
            let full = named.iter().any(|n| !partial.contains(n));
            if full && claimed > 0.5 {
                Verdict::Wrong
            } else if named.is_empty() && unexplained == 0.0 {
                Verdict::Missed
            } else {
                Verdict::Right
            }
        }
        _ => {
            if named.iter().any(|n| !case.truth.contains(n)) {
                Verdict::Wrong
            } else if named.len() == case.truth.len() && partial.is_empty() {
                Verdict::Right
            } else {
                Verdict::Missed
            }
        }
    }
}

/// Runs one campaign: simulate, diagnose blind, score against the oracle.
pub fn run_case(master: u64, index: usize, range: (f64, f64)) -> Outcome {
    let (case, cfg) = generate(master, index, range);
    let (c, _) = sim::simulate(&cfg);
    let d = Data::new(&c, cfg.g).expect("simulated campaigns have noise and positions");
    let a = super::attribute(&d, MODEL_4);
    let set: Vec<Cand> = a.effects.iter().filter_map(|e| Cand::from_name(&e.name)).collect();
    let reported: Vec<&'static str> = set.iter().map(|c| c.name()).collect();
    let partial: Vec<&'static str> = a
        .effects
        .iter()
        .filter(|e| e.partial)
        .filter_map(|e| Cand::from_name(&e.name))
        .map(Cand::name)
        .collect();
    let claimed = if set.is_empty() { 0.0 } else { a.joint_explained };
    let rms_before = a.rounds.first().map_or(f64::NAN, |r| r.before.rms);
    let rms_after = heldout(&d, MODEL_4, &set).rms;
    let rms_oracle = match case.kind {
        CaseKind::Single | CaseKind::Pair | CaseKind::Triple => {
            let truth: Vec<Cand> = case.truth.iter().filter_map(|n| Cand::from_name(n)).collect();
            Some(heldout(&d, MODEL_4, &truth).rms)
        }
        _ => None,
    };
    let verdict = verdict(&case, &reported, &partial, claimed, a.unexplained_rms);
    Outcome {
        case,
        reported,
        partial,
        claimed,
        unexplained_rms: a.unexplained_rms,
        verdict,
        rms_before,
        rms_after,
        rms_oracle,
    }
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
    let mut kinds: BTreeMap<CaseKind, Tally> = BTreeMap::new();
    let mut truths: BTreeMap<String, (CaseKind, Tally)> = BTreeMap::new();
    let mut confusion: BTreeMap<String, BTreeMap<String, usize>> = BTreeMap::new();
    let mut all = Tally::default();
    for o in &outcomes {
        kinds.entry(o.case.kind).or_default().add(o);
        let t = label(&o.case.truth);
        truths.entry(t.clone()).or_insert_with(|| (o.case.kind, Tally::default())).1.add(o);
        // In the registry's order, as the truth is written.
        let mut reported = o.reported.clone();
        reported.sort_by_key(|n| Cand::from_name(n));
        let shown: Vec<String> = reported
            .iter()
            .map(|n| if o.partial.contains(n) { format!("~{n}") } else { n.to_string() })
            .collect();
        let shown: Vec<&str> = shown.iter().map(String::as_str).collect();
        *confusion.entry(t).or_default().entry(label(&shown)).or_default() += 1;
        all.add(o);
    }
    let outside_overclaimed =
        outcomes.iter().filter(|o| o.case.kind == CaseKind::Outside && o.verdict == Verdict::Wrong).count();
    Summary {
        campaigns: outcomes.len(),
        kinds,
        truths,
        confusion,
        outside_overclaimed,
        shrink_vs_oracle: all.vs_oracle().unwrap_or(f64::NAN),
        outcomes,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_combination_comes_in_turn() {
        assert_eq!(combination(0, 2), [Cand::ALL[0], Cand::ALL[1]]);
        let pairs: std::collections::BTreeSet<Vec<Cand>> = (0..21).map(|k| combination(k, 2)).collect();
        assert_eq!(pairs.len(), 21);
        let triples: std::collections::BTreeSet<Vec<Cand>> = (0..35).map(|k| combination(k, 3)).collect();
        assert_eq!(triples.len(), 35);
        assert_eq!(combination(35, 3), combination(0, 3));
    }

    #[test]
    fn names_follow_the_order_of_all() {
        assert!(Outside::ALL.iter().enumerate().all(|(i, o)| *o as usize == i));
        assert_eq!((CaseKind::Clean.name(), CaseKind::Outside.name()), ("clean", "outside library"));
        assert_eq!(Outside::CableWindup.name(), "cable_windup");
        assert_eq!((CaseKind::of(13), CaseKind::of(14)), (CaseKind::Triple, CaseKind::Outside));
    }

    #[test]
    fn each_outside_effect_is_scaled_to_its_magnitude() {
        for i in [6, 7, 14, 15, 22] {
            let (case, cfg) = generate(5, i, (4.0, 4.0));
            assert_eq!(case.kind, CaseKind::Outside);
            assert_eq!(cfg.effects.len(), 1);
            assert!((case.magnitudes[0] - 4.0).abs() < 0.05, "{case:?}");
        }
    }
}
