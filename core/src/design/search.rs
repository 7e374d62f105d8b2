//! The choice of positions: an exchange algorithm (Fedorov's, first improvement) on the predicted
//! worst-case uncertainty, over the positions the head reaches, from several seeded random starts;
//! and the choice of the number of positions and the dwell for the least head time that reaches a
//! target ([`design_auto`]).

use rand::seq::index::sample;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use serde::Serialize;

use super::order::{arrange, Selection};
use super::{head_time_s, DesignError, Evaluator, Point, Prediction, Prior, Stated, Sums, SEARCH_POINTS};

/// The positions a dividing head reaches: α all round in steps, β within ±`beta_max_deg` in
/// steps from 0. At β = ±90° every α is the same orientation, so it counts once.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Head {
    /// The α stage's step, degrees.
    pub alpha_step_deg: f64,
    /// The β stage's step, degrees.
    pub beta_step_deg: f64,
    /// The β stage's limit either side of 0, degrees (at most 90).
    pub beta_max_deg: f64,
}

impl Head {
    /// Its distinct positions `(alpha_deg, beta_deg)`.
    pub fn reachable(&self) -> Result<Vec<(f64, f64)>, DesignError> {
        let Head { alpha_step_deg: da, beta_step_deg: db, beta_max_deg: bmax } = *self;
        if !(da.is_finite() && da > 0.0 && da <= 180.0) {
            return Err(DesignError::Head(format!("the α step must be in (0, 180] degrees, got {da}")));
        }
        if !(db.is_finite() && db > 0.0 && db <= 90.0) {
            return Err(DesignError::Head(format!("the β step must be in (0, 90] degrees, got {db}")));
        }
        if !(bmax.is_finite() && (0.0..=90.0).contains(&bmax)) {
            return Err(DesignError::Head(format!("the β limit must be in [0, 90] degrees, got {bmax}")));
        }
        let alphas: Vec<f64> = (0..).map(|i| i as f64 * da).take_while(|&a| a < 360.0 - 1e-9).collect();
        let steps = (bmax / db + 1e-9).floor() as i64;
        let mut out = Vec::new();
        for j in -steps..=steps {
            let b = j as f64 * db;
            if (b.abs() - 90.0).abs() < 1e-9 {
                out.push((0.0, b));
            } else {
                out.extend(alphas.iter().map(|&a| (a, b)));
            }
        }
        Ok(out)
    }
}

/// The fewest positions a design may have: GMDH's largest identifiable paper model (model 10, 7
/// terms) by leave-one-out.
pub const MIN_POSITIONS: usize = 8;

/// Random starts of a design.
const STARTS: usize = 4;

/// A designed plan.
#[derive(Clone, Debug, Serialize)]
pub struct Designed {
    /// The positions `(alpha_deg, beta_deg)` in the order the head visits them.
    pub positions: Vec<(f64, f64)>,
    /// Samples per position.
    pub samples: usize,
    /// Its prediction.
    pub prediction: Prediction,
    /// How GMDH's selection ranks the paper's models on it.
    pub selection: Selection,
    /// The head's travel over the plan from α = β = 0, the larger of the two stages' angles per
    /// move, degrees.
    pub travel_deg: f64,
}

/// One exchange run from a random start: the chosen candidate indices and their objective.
fn exchange(ev: &Evaluator, cands: &[Point], points: &[[f64; 3]], n: usize, seed: u64) -> (Vec<usize>, f64) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut chosen: Vec<usize> = sample(&mut rng, cands.len(), n).into_vec();
    let mut inside = vec![false; cands.len()];
    let mut sums = Sums::zero();
    for &c in &chosen {
        inside[c] = true;
        sums.add(&cands[c], 1.0);
    }
    let mut best = ev.objective(&sums, points);
    for _sweep in 0..60 {
        let mut changed = false;
        for slot in 0..n {
            let out = chosen[slot];
            let mut base = sums;
            base.add(&cands[out], -1.0);
            let mut pick: Option<(usize, f64, Sums)> = None;
            for (c, p) in cands.iter().enumerate() {
                if inside[c] {
                    continue;
                }
                let mut s = base;
                s.add(p, 1.0);
                let v = ev.objective(&s, points);
                if v < pick.as_ref().map_or(best, |x| x.1) {
                    pick = Some((c, v, s));
                }
            }
            if let Some((c, v, s)) = pick {
                if v < best * (1.0 - 1e-9) {
                    inside[out] = false;
                    inside[c] = true;
                    chosen[slot] = c;
                    sums = s;
                    best = v;
                    changed = true;
                }
            }
        }
        if !changed {
            break;
        }
    }
    (chosen, best)
}

/// The best of `starts` exchange runs: candidate indices.
fn best_of(ev: &Evaluator, cands: &[Point], n: usize, seed: u64, starts: usize) -> Vec<usize> {
    let points = ev.sphere(SEARCH_POINTS);
    let runs: Vec<(Vec<usize>, f64)> = (0..starts as u64)
        .into_par_iter()
        .map(|s| exchange(ev, cands, &points, n, seed.wrapping_mul(0x9E37_79B9).wrapping_add(s)))
        .collect();
    runs.into_iter().min_by(|a, b| a.1.total_cmp(&b.1)).map(|r| r.0).unwrap_or_default()
}

/// Designs a plan of `n` positions with `samples` samples per position among those `head`
/// reaches, minimising the worst-case expanded uncertainty; `seed` makes it repeatable.
pub fn design(
    n: usize,
    samples: usize,
    prior: &Prior,
    stated: &Stated,
    g: f64,
    head: &Head,
    seed: u64,
) -> Result<Designed, DesignError> {
    design_with(n, samples, prior, stated, g, head, seed, STARTS)
}

#[allow(clippy::too_many_arguments)]
fn design_with(
    n: usize,
    samples: usize,
    prior: &Prior,
    stated: &Stated,
    g: f64,
    head: &Head,
    seed: u64,
    starts: usize,
) -> Result<Designed, DesignError> {
    let reach = head.reachable()?;
    if n < MIN_POSITIONS {
        return Err(DesignError::TooFew { n, min: MIN_POSITIONS });
    }
    if n > reach.len() {
        return Err(DesignError::TooMany { n, reachable: reach.len() });
    }
    let ev = Evaluator::new(prior, stated, g, samples)?;
    let cands: Vec<Point> = reach.iter().map(|&p| ev.point(p)).collect();
    let chosen = best_of(&ev, &cands, n, seed, starts);
    let (positions, selection, travel_deg) = arrange(chosen.iter().map(|&c| reach[c]).collect(), g)?;
    let prediction = super::predict(&positions, samples, prior, stated, g)?;
    Ok(Designed { positions, samples, prediction, selection, travel_deg })
}

/// What `auto` is asked for.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AutoTarget {
    /// The expanded uncertainty to reach (worst axis, worst orientation at 1 g), m/s².
    pub u_m_s2: f64,
    /// The sample rate, Hz.
    pub rate_hz: f64,
    /// The move and settling time per position, s.
    pub move_s: f64,
}

/// The dwells `auto` tries, s: every second to 20 s, then coarser to a minute.
pub const AUTO_DWELLS_S: [f64; 25] = [
    1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0, 10.0, 11.0, 12.0, 13.0, 14.0, 15.0, 16.0, 17.0, 18.0, 19.0,
    20.0, 25.0, 30.0, 40.0, 50.0, 60.0,
];

/// The most positions `auto` considers.
const AUTO_MAX_POSITIONS: usize = 400;

/// Designs the plan of least head time whose predicted worst-case U is at most the target: for
/// each dwell of [`AUTO_DWELLS_S`], the fewest positions that reach it (from the plan-dependent
/// part of the variance, which falls as 1/N, then checked on designed plans); `progress` is told
/// each dwell as it is done.
pub fn design_auto(
    target: &AutoTarget,
    prior: &Prior,
    stated: &Stated,
    g: f64,
    head: &Head,
    seed: u64,
    progress: &(dyn Fn(usize) + Sync),
) -> Result<Designed, DesignError> {
    for (what, value) in [("the target U", target.u_m_s2), ("the sample rate", target.rate_hz)] {
        if !(value.is_finite() && value > 0.0) {
            return Err(DesignError::NotPositive { what, value });
        }
    }
    if !(target.move_s.is_finite() && target.move_s >= 0.0) {
        return Err(DesignError::NotPositive { what: "the move time", value: target.move_s });
    }
    let reach = head.reachable()?.len();
    let max_n = reach.min(AUTO_MAX_POSITIONS);
    let done = std::sync::atomic::AtomicUsize::new(0);
    let options: Vec<Result<(usize, usize), DesignError>> = AUTO_DWELLS_S
        .par_iter()
        .map(|&dwell| {
            let samples = ((dwell * target.rate_hz).round() as usize).max(1);
            let r = fewest(target.u_m_s2, samples, prior, stated, g, head, seed, max_n);
            progress(done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1);
            r.map(|n| (n, samples))
        })
        .collect();
    let mut reachable = Vec::new();
    for o in options {
        match o {
            Ok(x) => reachable.push(x),
            Err(DesignError::Unreachable { .. }) => {}
            Err(e) => return Err(e),
        }
    }
    let time = |&(n, s): &(usize, usize)| head_time_s(n, s, target.rate_hz, target.move_s);
    let Some(&(mut n, samples)) =
        reachable.iter().min_by(|a, b| time(a).total_cmp(&time(b)).then(a.0.cmp(&b.0)))
    else {
        return Err(DesignError::Unreachable {
            target: target.u_m_s2,
            why: format!(
                "not with up to {max_n} positions at any dwell up to {} s (the gravity's share and the head's angle errors set a floor)",
                AUTO_DWELLS_S[AUTO_DWELLS_S.len() - 1]
            ),
        });
    };
    loop {
        let d = design(n, samples, prior, stated, g, head, seed)?;
        if d.prediction.worst_m_s2 <= target.u_m_s2 || n >= max_n {
            return Ok(d);
        }
        n += 1;
    }
}

/// The fewest positions (at least [`MIN_POSITIONS`]) whose designed plan reaches `target` with
/// `samples` per position, or `Unreachable`.
#[allow(clippy::too_many_arguments)]
fn fewest(
    target: f64,
    samples: usize,
    prior: &Prior,
    stated: &Stated,
    g: f64,
    head: &Head,
    seed: u64,
    max_n: usize,
) -> Result<usize, DesignError> {
    let u_of = |n: usize, starts: usize| {
        design_with(n, samples, prior, stated, g, head, seed, starts).map(|d| d.prediction)
    };
    let gravity = |p: &Prediction| p.parts.iter().find(|x| x.name == "gravity").map_or(0.0, |x| x.u_m_s2);
    let probe_n = 24.min(max_n).max(MIN_POSITIONS);
    let probe = u_of(probe_n, 1)?;
    // U² = k²(V_g + V_plan/N): the gravity's share does not fall with N.
    let vg = (super::K_COVERAGE * gravity(&probe)).powi(2);
    let t2 = target * target;
    if t2 <= vg {
        return Err(DesignError::Unreachable { target, why: "the uncertainty of g alone is larger".into() });
    }
    let estimate = (probe_n as f64 * (probe.worst_m_s2.powi(2) - vg) / (t2 - vg)).ceil().max(1.0) as usize;
    let mut n = estimate.clamp(MIN_POSITIONS, max_n);
    // Whether `n` positions reach the target, decided on the design `design` itself would give.
    let meets = |n: usize| u_of(n, STARTS).map(|p| p.worst_m_s2 <= target);
    if meets(n)? {
        for _ in 0..6 {
            if n == MIN_POSITIONS || !meets(n - 1)? {
                break;
            }
            n -= 1;
        }
        return Ok(n);
    }
    for _ in 0..8 {
        if n >= max_n {
            break;
        }
        n = (n + 1 + n / 20).min(max_n);
        if meets(n)? {
            return Ok(n);
        }
    }
    Err(DesignError::Unreachable { target, why: format!("not with {n} positions") })
}
