//! Attribution: which effects explain the gap, decided on withheld positions (the GMDH idea
//! applied to effects: an external criterion decides).
//!
//! Every candidate is linear in its parameters on the bins (see the table in the README): the
//! baseline terms per channel plus the effect's columns (per channel, or shared by all channels
//! for `head_misalignment`, whose columns are `k_c·∂a/∂ω` with the fitted sensitivities), fitted
//! jointly by weighted least squares. `settling` adds a time constant found by a golden-section
//! search on the fitting part. `angle_error` is a random effect: on a withheld position its two
//! angle errors are estimated from the *other* channels' residuals and predict the channel left
//! out.
//!
//! **Criterion.** Positions are split alternately into A and B; a model fitted on A is scored on
//! B and one fitted on B on A. The score is the held-out χ² = Σ n·r²/σ² over withheld bins.
//! **Greedy selection.** Starting from the baseline, every remaining candidate is added in turn;
//! the one with the largest held-out χ² drop `D` among those passing both rules is kept:
//! (1) `D > max(25 + 5·√(2p), 0.05·χ²_before)`, p the parameters it adds (under the null
//! hypothesis, that the effect is absent, an added column raises the held-out χ² on average and
//! `D` has a spread of about `2√(2p)`, so the first term is more than five spreads; the second
//! asks for a practically relevant drop, as collinear columns widen the null spread); (2) `D` is
//! at least [`MIN_EXPLAINED`] (50%) of the remaining excess held-out χ² (held-out χ² minus its
//! noise expectation, the number of withheld bins), for `angle_error` the shape rule
//! [`MIN_ANGLE_SHAPE`] instead. Rounds go on until no candidate passes. An effect that removes
//! only a slice of a residual it does not describe is not named: the residual stays unexplained.
//! **Pairs.** When the greedy path stalls (the first round keeps nothing, or it keeps one effect
//! and the full-data residual is still beyond the noise), every pair of candidates is scored
//! (greedy's blind spot: two effects present whose sum a third one mimics better than either
//! alone, or a second effect hidden behind angle errors); the best pair is named when each
//! member's marginal drop passes rule (1), together they remove at least half the excess, and it
//! beats the greedy set on the held-out χ².

use std::collections::BTreeMap;

use accelcal_shared::{Structure, Term};
use nalgebra::DMatrix;
use serde::Serialize;

use super::{golden_min, wls, zscore, Data, NOISE_Z, TAU_RANGE};

/// The candidates are the effects of the registry.
pub use crate::effects::EffectKind as Cand;

impl Cand {
    /// Whether the data allow this candidate (temperature needs `temp_c`, angle errors three
    /// channels).
    pub fn available(self, d: &Data) -> bool {
        match self {
            Cand::Temperature => d.temp.is_some(),
            Cand::AngleError => d.nch() >= 3,
            _ => true,
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Kind {
    Base(usize),
    Drift,
    TempBias,
    TempScale,
    Nl(usize),
    Hyst,
    Settle,
    HmX,
    HmZ,
}

/// One column of the joint design.
#[derive(Clone, Copy, Debug)]
struct Col {
    ch: Option<usize>,
    kind: Kind,
    cand: Option<Cand>,
    param: &'static str,
}

fn per_channel(cand: Cand) -> &'static [(Kind, &'static str)] {
    match cand {
        Cand::BiasDrift => &[(Kind::Drift, "rate")],
        Cand::Temperature => &[(Kind::TempBias, "bias"), (Kind::TempScale, "scale")],
        Cand::Nonlinearity => {
            &[(Kind::Nl(0), "k2"), (Kind::Nl(1), "ax*ay"), (Kind::Nl(2), "ax*az"), (Kind::Nl(3), "ay*az")]
        }
        Cand::Hysteresis => &[(Kind::Hyst, "h")],
        Cand::Settling => &[(Kind::Settle, "gain")],
        Cand::HeadMisalignment | Cand::AngleError => &[],
    }
}

fn columns(d: &Data, base: Structure, set: &[Cand]) -> Vec<Col> {
    let nb = base.terms().count();
    let mut cols = Vec::new();
    for ch in 0..d.nch() {
        for i in 0..nb {
            cols.push(Col { ch: Some(ch), kind: Kind::Base(i), cand: None, param: "" });
        }
        for &c in set {
            for &(kind, param) in per_channel(c) {
                cols.push(Col { ch: Some(ch), kind, cand: Some(c), param });
            }
        }
    }
    if set.contains(&Cand::HeadMisalignment) {
        let c = Some(Cand::HeadMisalignment);
        cols.push(Col { ch: None, kind: Kind::HmX, cand: c, param: "rx_mrad" });
        cols.push(Col { ch: None, kind: Kind::HmZ, cand: c, param: "rz_mrad" });
    }
    cols
}

/// Derivatives of the imposed acceleration at a position: with respect to a rotation about x and
/// about z between the stages, and to α and β, each per mrad.
pub fn derivatives(d: &Data, p: usize) -> [[f64; 3]; 4] {
    let (a, b) = d.angles[p];
    let (sa, ca) = a.to_radians().sin_cos();
    let (sb, cb) = b.to_radians().sin_cos();
    let m = -d.g * 1e-3;
    [
        [m * sa * sb, -m * cb, m * ca * sb],
        [-m * ca * sb, 0.0, m * sa * sb],
        [m * cb * ca, 0.0, -m * cb * sa],
        [-m * sb * sa, m * cb, -m * sb * ca],
    ]
}

fn dot(k: &[f64; 3], v: &[f64; 3]) -> f64 {
    k[0] * v[0] + k[1] * v[1] + k[2] * v[2]
}

struct Ctx<'a> {
    d: &'a Data,
    terms: Vec<Term>,
    settle: Vec<f64>,
    t_mid: f64,
    temp_mid: f64,
}

impl Ctx<'_> {
    fn value(&self, col: &Col, ch: usize, row: usize) -> f64 {
        if col.ch.is_some_and(|c| c != ch) {
            return 0.0;
        }
        let d = self.d;
        let bin = &d.bins[row];
        let p = bin.pos;
        let a = d.accel[p];
        let own = d.own[ch];
        let step = d.step[ch][p];
        match col.kind {
            Kind::Base(i) => self.terms[i].eval([a[0], a[1], a[2], f64::NAN]),
            Kind::Drift => bin.t - self.t_mid,
            Kind::TempBias => d.temp.as_ref().map_or(0.0, |t| t[row] - self.temp_mid),
            Kind::TempScale => {
                d.temp.as_ref().map_or(0.0, |t| (t[row] - self.temp_mid) * 1e-6 * dot(&d.k[ch], &a))
            }
            Kind::Nl(0) => a[own] * a[own],
            Kind::Nl(1) => a[0] * a[1],
            Kind::Nl(2) => a[0] * a[2],
            Kind::Nl(_) => a[1] * a[2],
            Kind::Hyst => {
                if step.abs() < 1e-6 {
                    0.0
                } else {
                    step.signum()
                }
            }
            Kind::Settle => step * self.settle[row],
            Kind::HmX => dot(&d.k[ch], &derivatives(d, p)[0]),
            Kind::HmZ => dot(&d.k[ch], &derivatives(d, p)[1]),
        }
    }
}

/// The joint design over channels: stacked row `ch·bins + row`.
struct Design {
    x: DMatrix<f64>,
    y: Vec<f64>,
    w: Vec<f64>,
    cols: Vec<Col>,
}

fn design(d: &Data, base: Structure, set: &[Cand], tau: f64) -> Design {
    let nb = d.bins.len();
    let temp_mid = d.temp.as_ref().map_or(0.0, |t| t.iter().sum::<f64>() / t.len() as f64);
    let ctx = Ctx {
        d,
        terms: base.terms().collect(),
        settle: if set.contains(&Cand::Settling) { d.settle(tau) } else { Vec::new() },
        t_mid: d.bins.iter().map(|b| b.t).sum::<f64>() / nb as f64,
        temp_mid,
    };
    let cols = columns(d, base, set);
    let n = nb * d.nch();
    let x = DMatrix::from_fn(n, cols.len(), |r, c| ctx.value(&cols[c], r / nb, r % nb));
    let y = (0..n).map(|r| d.mean[r / nb][r % nb]).collect();
    let w = (0..n).map(|r| d.weight(r / nb, r % nb)).collect();
    Design { x, y, w, cols }
}

/// A deterministic fit: coefficients, covariance and the design it belongs to.
struct Fitted {
    design: Design,
    beta: Vec<f64>,
    cov: DMatrix<f64>,
    wsse: f64,
    tau: f64,
}

fn fit_at(d: &Data, base: Structure, set: &[Cand], tau: f64, rows: &[usize], adj: &[f64]) -> Option<Fitted> {
    let mut design = design(d, base, set, tau);
    for (y, a) in design.y.iter_mut().zip(adj) {
        *y -= a;
    }
    let f = wls(&design.x, &design.y, &design.w, rows)?;
    Some(Fitted { design, beta: f.beta, cov: f.cov, wsse: f.wsse, tau })
}

/// Fits the deterministic part of `set` on the stacked `rows`; with `settling`, the time constant
/// minimising the fitted χ² (golden-section search on log τ).
/// `adj` (stacked, may be empty) is subtracted from the data first.
fn fit(d: &Data, base: Structure, set: &[Cand], rows: &[usize], adj: &[f64]) -> Option<Fitted> {
    if !set.contains(&Cand::Settling) {
        return fit_at(d, base, set, 1.0, rows, adj);
    }
    let f = |lt: f64| fit_at(d, base, set, lt.exp(), rows, adj).map_or(f64::INFINITY, |f| f.wsse);
    let (mut lo, mut hi) = (TAU_RANGE.0.ln(), TAU_RANGE.1.ln());
    // A coarse scan first (the criterion need not be unimodal), then golden sections.
    let grid: Vec<f64> = (0..12).map(|i| lo + (hi - lo) * i as f64 / 11.0).collect();
    let best = grid.iter().copied().min_by(|a, b| f(*a).total_cmp(&f(*b)))?;
    let step = (hi - lo) / 11.0;
    (lo, hi) = ((best - step).max(lo), (best + step).min(hi));
    fit_at(d, base, set, golden_min(&f, lo, hi, 14).exp(), rows, adj)
}

/// Fits the deterministic part of `set` on `rows` (the bins of `positions`). With `angle_error`
/// in the set, backfitting: the angle errors of `positions` are estimated from all channels and
/// taken out of the data, and the deterministic part refitted (three passes), so that angle
/// errors do not bias the other parameters. Returns the fit (its residuals have the fitted angle
/// errors removed on `rows`) and the angle-error variance (mrad², 0 without `angle_error`).
fn fit_backfit(
    d: &Data,
    base: Structure,
    set: &[Cand],
    rows: &[usize],
    positions: &[usize],
) -> Option<(Fitted, f64)> {
    if !set.contains(&Cand::AngleError) {
        return Some((fit(d, base, set, rows, &[])?, 0.0));
    }
    let mut adj = vec![0.0; d.bins.len() * d.nch()];
    let mut prior = 0.0;
    for _ in 0..3 {
        let f = fit(d, base, set, rows, &adj)?;
        let full: Vec<f64> = residuals(&f).iter().zip(&adj).map(|(r, a)| r + a).collect();
        prior = angle_variance(d, &full, positions);
        let mut left = full.clone();
        angle_correct(d, &mut left, positions, false, prior);
        adj = full.iter().zip(&left).map(|(f, l)| f - l).collect();
    }
    Some((fit(d, base, set, rows, &adj)?, prior))
}

fn residuals(f: &Fitted) -> Vec<f64> {
    let x = &f.design.x;
    (0..x.nrows())
        .map(|r| f.design.y[r] - (0..x.ncols()).map(|c| x[(r, c)] * f.beta[c]).sum::<f64>())
        .collect()
}

/// Sensitivities of each channel's dwell mean to δα and δβ (codes per mrad) at a position.
fn angle_gains(d: &Data, p: usize) -> Vec<[f64; 2]> {
    let der = derivatives(d, p);
    (0..d.nch()).map(|c| [dot(&d.k[c], &der[2]), dot(&d.k[c], &der[3])]).collect()
}

/// Dwell-mean residual of each channel at a position, and the bins of the position.
fn dwell_resid(d: &Data, resid: &[f64], p: usize) -> (Vec<f64>, Vec<usize>, f64) {
    let nb = d.bins.len();
    let rows: Vec<usize> = (0..nb).filter(|&r| d.bins[r].pos == p).collect();
    let n: f64 = rows.iter().map(|&r| d.bins[r].n).sum();
    let r = (0..d.nch())
        .map(|c| rows.iter().map(|&i| d.bins[i].n * resid[c * nb + i]).sum::<f64>() / n)
        .collect();
    (r, rows, n)
}

/// Solves for (δα, δβ) from the channels other than `skip`, with a Gaussian prior of variance
/// `prior` (mrad²; infinite: none). Returns the estimate, the sum of the noise variances of the
/// observable directions, and their number.
fn solve_angles(
    gr: &[[f64; 2]],
    r: &[f64],
    var: &[f64],
    skip: Option<usize>,
    prior: f64,
) -> ([f64; 2], f64, usize) {
    let mut a = nalgebra::Matrix2::<f64>::zeros();
    let mut b = nalgebra::Vector2::<f64>::zeros();
    for o in (0..gr.len()).filter(|&o| Some(o) != skip) {
        for i in 0..2 {
            b[i] += gr[o][i] * r[o] / var[o];
            for j in 0..2 {
                a[(i, j)] += gr[o][i] * gr[o][j] / var[o];
            }
        }
    }
    let e = a.symmetric_eigen();
    let lmax = e.eigenvalues.max();
    let mut inv = nalgebra::Matrix2::zeros();
    let (mut tr, mut rank) = (0.0, 0);
    for i in 0..2 {
        let l = e.eigenvalues[i];
        if lmax > 0.0 && l > 1e-3 * lmax {
            let v = e.eigenvectors.column(i);
            inv += v * v.transpose() / (l + 1.0 / prior);
            tr += 1.0 / l;
            rank += 1;
        }
    }
    let x = inv * b;
    ([x[0], x[1]], tr, rank)
}

/// Estimates the angle-error variance (mrad², per angle) from all channels' residuals at
/// `positions`, net of the noise.
fn angle_variance(d: &Data, resid: &[f64], positions: &[usize]) -> f64 {
    let (mut num, mut den) = (0.0, 0usize);
    for &p in positions {
        let (r, _, n) = dwell_resid(d, resid, p);
        let var: Vec<f64> = d.sigma.iter().map(|s| s * s / n).collect();
        let (x, tr, rank) = solve_angles(&angle_gains(d, p), &r, &var, None, f64::INFINITY);
        num += x[0] * x[0] + x[1] * x[1] - tr;
        den += rank;
    }
    if den == 0 {
        0.0
    } else {
        (num / den as f64).max(0.0)
    }
}

/// Removes from the residuals at `positions` what angle errors of variance `prior` (mrad²)
/// explain. With `leave_out`, each channel's correction comes from the other channels only (a
/// held-out prediction).
fn angle_correct(d: &Data, resid: &mut [f64], positions: &[usize], leave_out: bool, prior: f64) {
    if !(prior > 0.0) {
        return;
    }
    let nb = d.bins.len();
    for &p in positions {
        let (r, rows, n) = dwell_resid(d, resid, p);
        let var: Vec<f64> = d.sigma.iter().map(|s| s * s / n).collect();
        let gr = angle_gains(d, p);
        let preds: Vec<f64> = (0..d.nch())
            .map(|c| {
                let (x, _, _) = solve_angles(&gr, &r, &var, leave_out.then_some(c), prior);
                gr[c][0] * x[0] + gr[c][1] * x[1]
            })
            .collect();
        for (c, pred) in preds.iter().enumerate() {
            for &i in &rows {
                resid[c * nb + i] -= pred;
            }
        }
    }
}

/// A held-out score.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct Score {
    /// Held-out χ²: Σ n·r²/σ² over the withheld bins of both folds.
    pub chi2: f64,
    /// RMS of the withheld bin-mean residuals, codes.
    pub rms: f64,
    /// Withheld bins (all channels).
    pub bins: usize,
    /// Parameters of the model (per fold).
    pub params: usize,
    /// With `angle_error`: the held-out χ² after removing the angle errors estimated from all
    /// channels (not left out) plus two per position (their degrees of freedom); else `chi2`.
    pub chi2_shape: f64,
}

fn nparams(d: &Data, base: Structure, set: &[Cand]) -> usize {
    columns(d, base, set).len() + if set.contains(&Cand::AngleError) { 2 } else { 0 }
}

/// Scores `set` on withheld positions: fitted on the even positions and scored on the odd ones,
/// then the other way round.
pub fn heldout(d: &Data, base: Structure, set: &[Cand]) -> Score {
    let nb = d.bins.len();
    let (mut chi2, mut ss, mut count, mut shape) = (0.0, 0.0, 0usize, 0.0);
    for parity in [0, 1] {
        let stacked = |keep: &dyn Fn(usize) -> bool| -> Vec<usize> {
            (0..nb * d.nch()).filter(|&r| keep(d.bins[r % nb].pos)).collect()
        };
        let fit_rows = stacked(&|p| p % 2 == parity);
        let test_rows = stacked(&|p| p % 2 != parity);
        let fit_pos: Vec<usize> = (0..d.npos()).filter(|p| p % 2 == parity).collect();
        let Some((f, prior)) = fit_backfit(d, base, set, &fit_rows, &fit_pos) else {
            return Score {
                chi2: f64::INFINITY,
                rms: f64::INFINITY,
                bins: 0,
                params: 0,
                chi2_shape: f64::INFINITY,
            };
        };
        let mut r = residuals(&f);
        if set.contains(&Cand::AngleError) {
            let test_pos: Vec<usize> = (0..d.npos()).filter(|p| p % 2 != parity).collect();
            let mut all = r.clone();
            angle_correct(d, &mut all, &test_pos, false, prior);
            shape += test_rows.iter().map(|&i| f.design.w[i] * all[i] * all[i]).sum::<f64>();
            shape += 2.0 * test_pos.len() as f64;
            angle_correct(d, &mut r, &test_pos, true, prior);
        }
        for &i in &test_rows {
            chi2 += f.design.w[i] * r[i] * r[i];
            ss += r[i] * r[i];
            count += 1;
        }
    }
    let chi2_shape = if set.contains(&Cand::AngleError) { shape } else { chi2 };
    Score {
        chi2,
        rms: (ss / count.max(1) as f64).sqrt(),
        bins: count,
        params: nparams(d, base, set),
        chi2_shape,
    }
}

/// One candidate's trial in one round of the greedy selection.
#[derive(Clone, Debug, Serialize)]
pub struct Trial {
    /// Effect name.
    pub name: &'static str,
    /// Held-out score with the effect added.
    pub score: Score,
    /// Drop of the held-out χ² it brings.
    pub chi2_drop: f64,
    /// Threshold of the drop: the larger of 25 + 5·√(2p) and 5% of the held-out χ² before.
    pub threshold: f64,
    /// Fraction of the remaining excess χ² it removes.
    pub explained: f64,
    /// The fraction its shape rule uses: `explained`, except for `angle_error` (see
    /// [`significant`]).
    pub shape_explained: f64,
}

/// One round of the greedy selection.
#[derive(Clone, Debug, Serialize)]
pub struct Round {
    /// Held-out score of the model so far.
    pub before: Score,
    /// Every candidate tried, best first.
    pub trials: Vec<Trial>,
    /// The effect kept, if any.
    pub kept: Option<&'static str>,
}

/// The least fraction of the remaining excess χ² an effect must remove on withheld positions to
/// be kept in a round, and that the kept effects together must remove to be named.
pub const MIN_EXPLAINED: f64 = 0.5;

/// The least fraction of the excess χ² that the per-position angle subspace must hold for
/// `angle_error` to be named. Its held-out prediction (each channel from the others) is limited
/// by geometry (on a triad at α = 0 a change of α moves ax only), so its shape is checked by
/// estimating the angles from all channels: two parameters per position in a space of three
/// channels hold about 2/3 of a residual without angle structure, all of one with it.
pub const MIN_ANGLE_SHAPE: f64 = 0.8;

/// Whether a trial may be kept in its round: a drop above the threshold that removes at least
/// [`MIN_EXPLAINED`] of the remaining excess (for `angle_error`: the shape rule).
pub fn significant(t: &Trial) -> bool {
    let min = if t.name == Cand::AngleError.name() { MIN_ANGLE_SHAPE } else { MIN_EXPLAINED };
    t.chi2_drop > t.threshold && t.shape_explained >= min
}

/// The outcome of the greedy selection.
#[derive(Clone, Debug, Serialize)]
pub struct EffectSelection {
    /// The effects named, in the order kept (empty when they explain too little together).
    pub set: Vec<Cand>,
    /// Every round.
    pub rounds: Vec<Round>,
    /// Fraction of the baseline's held-out excess χ² the kept effects remove together.
    pub joint_explained: f64,
    /// Effects kept but not named because together they explain less than [`MIN_EXPLAINED`] of
    /// the excess (the residual is reported as unexplained instead).
    pub not_named: Vec<&'static str>,
    /// For each named effect: the held-out score before and after adding it.
    pub steps: Vec<(Score, Score)>,
    /// Whether the set came from the pair search (the greedy path stalled).
    pub from_pairs: bool,
}

/// Greedy selection of effects by held-out χ² drop: each round keeps the candidate with the
/// largest drop among those that pass [`significant`]; the kept effects are named when together
/// they remove at least [`MIN_EXPLAINED`] of the baseline's held-out excess χ².
pub fn select(d: &Data, base: Structure) -> EffectSelection {
    let mut set: Vec<Cand> = Vec::new();
    let mut rounds = Vec::new();
    let mut before = heldout(d, base, &set);
    loop {
        let remaining: Vec<Cand> =
            Cand::ALL.into_iter().filter(|c| !set.contains(c) && c.available(d)).collect();
        if remaining.is_empty() {
            break;
        }
        let excess = (before.chi2 - before.bins as f64).max(1e-9);
        let mut trials: Vec<(Cand, Trial)> = remaining
            .iter()
            .map(|&c| {
                let mut s = set.clone();
                s.push(c);
                let score = heldout(d, base, &s);
                let drop = before.chi2 - score.chi2;
                let p = score.params.saturating_sub(before.params).max(1) as f64;
                let shape_explained = if c == Cand::AngleError {
                    (before.chi2 - score.chi2_shape) / excess
                } else {
                    drop / excess
                };
                let t = Trial {
                    name: c.name(),
                    score,
                    chi2_drop: drop,
                    threshold: (25.0 + 5.0 * (2.0 * p).sqrt()).max(0.05 * before.chi2),
                    explained: drop / excess,
                    shape_explained,
                };
                (c, t)
            })
            .collect();
        trials.sort_by(|a, b| b.1.chi2_drop.total_cmp(&a.1.chi2_drop));
        let best = trials.iter().find(|(_, t)| significant(t)).map(|(c, t)| (*c, t.score));
        rounds.push(Round {
            before,
            trials: trials.iter().map(|(_, t)| t.clone()).collect(),
            kept: best.map(|b| b.0.name()),
        });
        match best {
            Some((c, score)) => {
                set.push(c);
                before = score;
            }
            None => break,
        }
    }
    let first = rounds.first().map_or(before, |r| r.before);
    let excess = (first.chi2 - first.bins as f64).max(1e-9);
    let mut steps: Vec<(Score, Score)> = Vec::new();
    for (i, r) in rounds.iter().enumerate().take(set.len()) {
        let after = rounds.get(i + 1).map_or(before, |n| n.before);
        steps.push((r.before, after));
    }
    let mut joint_explained = if set.is_empty() { 0.0 } else { (first.chi2 - before.chi2_shape) / excess };
    let mut from_pairs = false;
    let stalled = set.is_empty() || set.len() == 1 && residual_z(d, base, &set) >= NOISE_Z;
    if stalled && !rounds.is_empty() {
        if let Some((pair, pair_steps, joint)) = best_pair(d, base, &rounds[0]) {
            if set.is_empty() || pair_steps[1].1.chi2 < before.chi2 {
                (set, steps, joint_explained, from_pairs) = (pair, pair_steps, joint, true);
            }
        }
    }
    let mut not_named = Vec::new();
    if joint_explained < MIN_EXPLAINED {
        not_named = set.iter().map(|c| c.name()).collect();
        set.clear();
        steps.clear();
    }
    EffectSelection { set, rounds, joint_explained, not_named, steps, from_pairs }
}

/// A pair found by [`best_pair`]: the effects, their steps, and the fraction of the excess removed.
type PairPick = (Vec<Cand>, Vec<(Score, Score)>, f64);

/// z of the χ² of the full-data fit of the baseline and `set`.
fn residual_z(d: &Data, base: Structure, set: &[Cand]) -> f64 {
    full_fit(d, base, set).map_or(f64::INFINITY, |f| zscore(f.chi2, f.dof))
}

/// The pair search, for when the greedy path stalls: the first round keeps nothing (two effects
/// present whose sum a third one mimics better than either alone), or it keeps one effect and a
/// residual beyond the noise remains (with angle errors present, the leave-one-channel-out
/// residual hides a second effect from rule (2)). Every pair of deterministic candidates (not
/// `angle_error`: paired, it named a drift `settling` on spot checks) is scored; a pair qualifies when each member's marginal drop (the
/// pair against the other member alone) passes the round-1 threshold; the qualifying pair with
/// the lowest held-out χ² is returned, ordered by single-effect drop, with its steps and the
/// fraction of the excess it removes.
fn best_pair(d: &Data, base: Structure, r1: &Round) -> Option<PairPick> {
    let single = |c: Cand| r1.trials.iter().find(|t| t.name == c.name());
    let cands: Vec<Cand> = Cand::ALL
        .into_iter()
        .filter(|&c| c != Cand::AngleError && c.available(d) && single(c).is_some())
        .collect();
    let excess = (r1.before.chi2 - r1.before.bins as f64).max(1e-9);
    let mut best: Option<PairPick> = None;
    for (i, &a) in cands.iter().enumerate() {
        for &b in &cands[i + 1..] {
            let (ta, tb) = (single(a)?, single(b)?);
            let score = heldout(d, base, &[a, b]);
            let ok = |alone: &Trial, other: &Trial| {
                let p = score.params.saturating_sub(other.score.params).max(1) as f64;
                let thr = (25.0 + 5.0 * (2.0 * p).sqrt()).max(0.05 * other.score.chi2);
                other.score.chi2 - score.chi2 > thr && alone.chi2_drop > 0.0
            };
            if !(ok(ta, tb) && ok(tb, ta)) {
                continue;
            }
            if best.as_ref().is_some_and(|(_, s, _)| s[1].1.chi2 <= score.chi2) {
                continue;
            }
            let (first, second, t1) = if ta.chi2_drop >= tb.chi2_drop { (a, b, ta) } else { (b, a, tb) };
            let steps = vec![(r1.before, t1.score), (t1.score, score)];
            best = Some((vec![first, second], steps, (r1.before.chi2 - score.chi2_shape) / excess));
        }
    }
    best
}

/// A parameter estimate with its one-sigma uncertainty (None when not available).
#[derive(Clone, Copy, Debug, Serialize)]
pub struct Estimate {
    /// Value.
    pub value: f64,
    /// One-sigma uncertainty.
    pub sd: Option<f64>,
}

/// The full-data fit of the baseline with a set of effects.
pub struct FullFit {
    /// Parameters per effect: effect → channel (or `all`) → parameter → estimate.
    pub params: BTreeMap<Cand, BTreeMap<String, BTreeMap<String, Estimate>>>,
    /// Residual of every stacked bin (`ch·bins + row`), codes.
    pub resid: Vec<f64>,
    /// χ² of the residuals.
    pub chi2: f64,
    /// Degrees of freedom of the χ².
    pub dof: f64,
}

/// Fits the baseline and `set` on all the data.
pub fn full_fit(d: &Data, base: Structure, set: &[Cand]) -> Option<FullFit> {
    let nb = d.bins.len();
    let all: Vec<usize> = (0..nb * d.nch()).collect();
    let pos: Vec<usize> = (0..d.npos()).collect();
    let (f, prior) = fit_backfit(d, base, set, &all, &pos)?;
    let resid = residuals(&f);
    let mut dof = all.len() as f64 - f.beta.len() as f64;
    let mut params: BTreeMap<Cand, BTreeMap<String, BTreeMap<String, Estimate>>> = BTreeMap::new();
    let chi2_det: f64 = all.iter().map(|&i| f.design.w[i] * resid[i] * resid[i]).sum();
    let inflate = (chi2_det / dof.max(1.0)).max(1.0);
    for (i, col) in f.design.cols.iter().enumerate() {
        let Some(c) = col.cand else { continue };
        let who = col.ch.map_or("all".to_string(), |ch| d.channels[ch].clone());
        let sd = (f.cov[(i, i)] * inflate).sqrt();
        params
            .entry(c)
            .or_default()
            .entry(who)
            .or_default()
            .insert(col.param.to_string(), Estimate { value: f.beta[i], sd: sd.is_finite().then_some(sd) });
    }
    if set.contains(&Cand::Settling) {
        for ch in &d.channels {
            params
                .entry(Cand::Settling)
                .or_default()
                .entry(ch.clone())
                .or_default()
                .insert("tau_s".into(), Estimate { value: f.tau, sd: None });
        }
    }
    if set.contains(&Cand::AngleError) {
        let n = pos.len() as f64;
        let sd = prior.sqrt();
        let mut m = BTreeMap::new();
        m.insert("sd_mrad".to_string(), Estimate { value: sd, sd: Some(sd / (2.0 * n).sqrt()) });
        params.entry(Cand::AngleError).or_default().insert("all".into(), m);
        dof -= 2.0 * n;
    }
    let chi2 = all.iter().map(|&i| f.design.w[i] * resid[i] * resid[i]).sum();
    Some(FullFit { params, resid, chi2, dof })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::effects::unit_of;

    /// Every parameter the diagnosis reports is a parameter of the registry (same key, so the same
    /// unit as the simulator's): the diagnosis columns and the registry cannot drift apart.
    #[test]
    fn every_reported_parameter_is_in_the_registry() {
        for c in Cand::ALL {
            for &(_, key) in per_channel(c) {
                assert!(unit_of(c, key).is_some(), "{}: `{key}` has no unit in the registry", c.name());
            }
        }
        for (c, key) in [
            (Cand::HeadMisalignment, "rx_mrad"),
            (Cand::HeadMisalignment, "rz_mrad"),
            (Cand::Settling, "tau_s"),
            (Cand::AngleError, "sd_mrad"),
        ] {
            assert!(unit_of(c, key).is_some(), "{}: `{key}`", c.name());
        }
    }
}
