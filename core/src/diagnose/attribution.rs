//! Attribution: the effects' models and how a set of them is scored on withheld positions (the
//! GMDH idea applied to effects: an external criterion decides; [`super::selection`] chooses).
//!
//! Every candidate is linear in its parameters on the bins (see the table in the README): the
//! baseline terms per channel plus the effect's columns (per channel, or shared by all channels
//! for `head_misalignment`, whose columns are `k_c·∂a/∂ω` with the fitted sensitivities), fitted
//! jointly by weighted least squares. `settling` adds a time constant found by a golden-section
//! search on the fitting part ([`Data::tau_range`]). `angle_error` is a random effect: fitted as a
//! mixed model with the deterministic part (per-position angle errors with an estimated variance,
//! eliminated per position), and on a withheld position its two angle errors are estimated from
//! the *other* channels' residuals and predict the channel left out.
//!
//! **Criterion.** Positions are split alternately into A and B; a model fitted on A is scored on
//! B and one fitted on B on A. The score is the held-out χ² = Σ n·r²/σ² over withheld bins, and
//! each effect of the set has a held-out [`Signature`]: how much of its predicted contribution
//! the withheld data carry.

use std::collections::BTreeMap;

use accelcal_shared::{Structure, Term};
use nalgebra::{DMatrix, DVector, Matrix2, Vector2};
use serde::Serialize;

use super::{golden_min, solve_normal, wls, Data};

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
    /// The head misalignment (rx, rz, mrad) fitted with `hysteresis`: where the commanded input
    /// of a channel does not change, the misaligned head still moves it a little, and the
    /// direction of that small step is the direction of approach.
    tilt: Option<(f64, f64)>,
}

impl Ctx<'_> {
    /// The direction of approach of channel `ch` at position `p`: the sign of the commanded
    /// step, or, where that is zero, of the step the misaligned head makes (0 without one).
    fn approach(&self, ch: usize, p: usize) -> f64 {
        let (d, own) = (self.d, self.d.own[ch]);
        let step = d.step[ch][p];
        if step.abs() >= 1e-6 {
            return step.signum();
        }
        match self.tilt {
            Some((rx, rz)) if p > 0 => {
                let (now, before) = (derivatives(d, p), derivatives(d, p - 1));
                let small = rx * (now[0][own] - before[0][own]) + rz * (now[1][own] - before[1][own]);
                if small.abs() < 1e-6 {
                    0.0
                } else {
                    small.signum()
                }
            }
            _ => 0.0,
        }
    }

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
            // A baseline term in `t` sees the bin's temperature from the default reference
            // (`Data::check` refuses one without a temperature).
            Kind::Base(i) => {
                let t = d.temp.as_ref().map_or(f64::NAN, |t| t[row] - crate::positions::T_REF_DEFAULT_C);
                self.terms[i].eval([a[0], a[1], a[2], t])
            }
            Kind::Drift => bin.t - self.t_mid,
            Kind::TempBias => d.temp.as_ref().map_or(0.0, |t| t[row] - self.temp_mid),
            Kind::TempScale => {
                d.temp.as_ref().map_or(0.0, |t| (t[row] - self.temp_mid) * 1e-6 * dot(&d.k[ch], &a))
            }
            Kind::Nl(0) => a[own] * a[own],
            Kind::Nl(1) => a[0] * a[1],
            Kind::Nl(2) => a[0] * a[2],
            Kind::Nl(_) => a[1] * a[2],
            Kind::Hyst => self.approach(ch, p),
            Kind::Settle => step * self.settle[row],
            Kind::HmX => dot(&d.k[ch], &derivatives(d, p)[0]),
            Kind::HmZ => dot(&d.k[ch], &derivatives(d, p)[1]),
        }
    }
}

/// The joint design over channels: stacked row `ch·bins + row`.
pub(super) struct Design {
    pub(super) x: DMatrix<f64>,
    pub(super) y: Vec<f64>,
    pub(super) w: Vec<f64>,
    cols: Vec<Col>,
}

fn design(d: &Data, base: Structure, set: &[Cand], tau: f64, tilt: Option<(f64, f64)>) -> Design {
    let nb = d.bins.len();
    let temp_mid = d.temp.as_ref().map_or(0.0, |t| t.iter().sum::<f64>() / t.len() as f64);
    let ctx = Ctx {
        d,
        terms: base.terms().collect(),
        settle: if set.contains(&Cand::Settling) { d.settle(tau) } else { Vec::new() },
        t_mid: d.bins.iter().map(|b| b.t).sum::<f64>() / nb as f64,
        temp_mid,
        tilt,
    };
    let cols = columns(d, base, set);
    let n = nb * d.nch();
    let x = DMatrix::from_fn(n, cols.len(), |r, c| ctx.value(&cols[c], r / nb, r % nb));
    let y = (0..n).map(|r| d.mean[r / nb][r % nb]).collect();
    let w = (0..n).map(|r| d.weight(r / nb, r % nb)).collect();
    Design { x, y, w, cols }
}

/// A deterministic fit: coefficients, covariance and the design it belongs to.
pub(super) struct Fitted {
    pub(super) design: Design,
    pub(super) beta: Vec<f64>,
    cov: DMatrix<f64>,
    pub(super) wsse: f64,
    pub(super) tau: f64,
    /// The head misalignment the hysteresis column used (see `Ctx::tilt`).
    tilt: Option<(f64, f64)>,
}

fn fit_at(d: &Data, base: Structure, set: &[Cand], tau: f64, rows: &[usize], adj: &[f64]) -> Option<Fitted> {
    let once = |tilt: Option<(f64, f64)>| -> Option<Fitted> {
        let mut design = design(d, base, set, tau, tilt);
        for (y, a) in design.y.iter_mut().zip(adj) {
            *y -= a;
        }
        let f = wls(&design.x, &design.y, &design.w, rows)?;
        Some(Fitted { design, beta: f.beta, cov: f.cov, wsse: f.wsse, tau, tilt })
    };
    let f = once(None)?;
    // With both, the hysteresis column takes the fitted misalignment's small steps (a second fit).
    if set.contains(&Cand::Hysteresis) && set.contains(&Cand::HeadMisalignment) {
        return once(tilt_of(&f));
    }
    Some(f)
}

/// The fitted head misalignment (rx, rz, mrad) of a fit that has it.
fn tilt_of(f: &Fitted) -> Option<(f64, f64)> {
    let at = |k: Kind| f.design.cols.iter().position(|c| c.kind == k).map(|i| f.beta[i]);
    Some((at(Kind::HmX)?, at(Kind::HmZ)?))
}

/// Fits the deterministic part of `set` on the stacked `rows`; with `settling`, the time constant
/// minimising the fitted χ² (golden-section search on log τ).
/// `adj` (stacked, may be empty) is subtracted from the data first.
fn fit(d: &Data, base: Structure, set: &[Cand], rows: &[usize], adj: &[f64]) -> Option<Fitted> {
    if !set.contains(&Cand::Settling) {
        return fit_at(d, base, set, 1.0, rows, adj);
    }
    let f = |lt: f64| fit_at(d, base, set, lt.exp(), rows, adj).map_or(f64::INFINITY, |f| f.wsse);
    let range = d.tau_range();
    let (mut lo, mut hi) = (range.0.ln(), range.1.ln());
    // A coarse scan first (the criterion need not be unimodal), then golden sections.
    let grid: Vec<f64> = (0..12).map(|i| lo + (hi - lo) * i as f64 / 11.0).collect();
    let best = grid.iter().copied().min_by(|a, b| f(*a).total_cmp(&f(*b)))?;
    let step = (hi - lo) / 11.0;
    (lo, hi) = ((best - step).max(lo), (best + step).min(hi));
    fit_at(d, base, set, golden_min(&f, lo, hi, 14).exp(), rows, adj)
}

/// Fits the deterministic part of `set` on `rows` (the bins of `positions`). With `angle_error`
/// in the set, a mixed model: the angle errors (δα, δβ) of each of `positions` are random effects
/// of variance `prior` (mrad², estimated from the data), fitted jointly with the deterministic
/// part ([`fit_mixed`]); the variance is re-estimated from the residual of each fit (three
/// passes), and with `settling` the time constant is searched with the angle errors taken out.
/// Returns the fit (its data have the fitted angle errors removed on `rows`, so its residuals
/// do) and the angle-error variance (mrad², 0 without `angle_error`).
pub(super) fn fit_backfit(
    d: &Data,
    base: Structure,
    set: &[Cand],
    rows: &[usize],
    positions: &[usize],
) -> Option<(Fitted, f64)> {
    let plain = fit(d, base, set, rows, &[])?;
    if !set.contains(&Cand::AngleError) {
        return Some((plain, 0.0));
    }
    let mut prior = angle_variance(d, &residuals(&plain), positions);
    let (mut tau, mut tilt) = (plain.tau, plain.tilt);
    let mut best = None;
    for pass in 0..3 {
        if !(prior > 0.0) {
            break;
        }
        let m = fit_mixed(d, base, set, tau, tilt, rows, positions, prior)?;
        let adj = m.1;
        let full: Vec<f64> = residuals(&m.0).iter().zip(&adj).map(|(r, a)| r + a).collect();
        prior = angle_variance(d, &full, positions);
        if pass < 2 && (set.contains(&Cand::Settling) || tilt.is_some()) {
            let again = fit(d, base, set, rows, &adj)?;
            (tau, tilt) = (again.tau, again.tilt);
        }
        best = Some(m.0);
    }
    match best {
        Some(f) => Some((f, prior)),
        None => Some((plain, 0.0)),
    }
}

/// The mixed-model fit at a time constant `tau` and an angle-error variance `prior` (mrad²): the
/// deterministic coefficients β with the angle errors u of `positions` as random effects,
/// `min Σ w·(y − X·β − Z·u)² + Σ |u|²/prior`, the per-position 2×2 blocks eliminated (Schur
/// complement) so that β is the generalised least-squares estimate under the covariance
/// `σ²/n + prior·Z·Zᵀ`. Returns the fit, with the fitted angle errors `Z·u` taken out of its data,
/// and `Z·u` (stacked).
#[allow(clippy::too_many_arguments)]
fn fit_mixed(
    d: &Data,
    base: Structure,
    set: &[Cand],
    tau: f64,
    tilt: Option<(f64, f64)>,
    rows: &[usize],
    positions: &[usize],
    prior: f64,
) -> Option<(Fitted, Vec<f64>)> {
    let mut design = design(d, base, set, tau, tilt);
    let nb = d.bins.len();
    let k = design.x.ncols();
    let (x, y, w) = (&design.x, &design.y, &design.w);
    let mut gram = DMatrix::<f64>::zeros(k, k);
    let mut rhs = DVector::<f64>::zeros(k);
    let mut by_pos: Vec<Vec<usize>> = vec![Vec::new(); d.npos()];
    for &r in rows {
        by_pos[d.bins[r % nb].pos].push(r);
        let xr = x.row(r);
        gram += w[r] * xr.transpose() * xr;
        rhs += w[r] * y[r] * xr.transpose();
    }
    // Per position: A = ZᵀWZ + I/prior, B = ZᵀWX, c = ZᵀWy.
    let mut blocks = Vec::new();
    for &p in positions {
        if by_pos[p].is_empty() {
            continue;
        }
        let gr = angle_gains(d, p);
        let mut a = Matrix2::<f64>::identity() / prior;
        let mut b = DMatrix::<f64>::zeros(2, k);
        let mut c = Vector2::<f64>::zeros();
        for &r in &by_pos[p] {
            let z = Vector2::new(gr[r / nb][0], gr[r / nb][1]);
            a += w[r] * z * z.transpose();
            for j in 0..k {
                b[(0, j)] += w[r] * z[0] * x[(r, j)];
                b[(1, j)] += w[r] * z[1] * x[(r, j)];
            }
            c += w[r] * y[r] * z;
        }
        let ai = a.try_inverse()?;
        let ai_d = DMatrix::from_fn(2, 2, |i, j| ai[(i, j)]);
        let c_d = DVector::from_fn(2, |i, _| c[i]);
        gram -= b.transpose() * &ai_d * &b;
        rhs -= b.transpose() * &ai_d * &c_d;
        blocks.push((p, gr, ai_d, b, c_d));
    }
    let (beta, cov) = solve_normal(&gram, &rhs)?;
    let mut adj = vec![0.0; y.len()];
    let mut penalty = 0.0;
    for (p, gr, ai, b, c) in &blocks {
        let u = ai * (c - b * &beta);
        penalty += (u[0] * u[0] + u[1] * u[1]) / prior;
        for &r in &by_pos[*p] {
            adj[r] = gr[r / nb][0] * u[0] + gr[r / nb][1] * u[1];
        }
    }
    for (yv, a) in design.y.iter_mut().zip(&adj) {
        *yv -= a;
    }
    let beta: Vec<f64> = beta.iter().copied().collect();
    let wsse = rows
        .iter()
        .map(|&r| {
            let e = design.y[r] - (0..k).map(|j| design.x[(r, j)] * beta[j]).sum::<f64>();
            design.w[r] * e * e
        })
        .sum::<f64>()
        + penalty;
    Some((Fitted { design, beta, cov, wsse, tau, tilt }, adj))
}

pub(super) fn residuals(f: &Fitted) -> Vec<f64> {
    let x = &f.design.x;
    (0..x.nrows())
        .map(|r| f.design.y[r] - (0..x.ncols()).map(|c| x[(r, c)] * f.beta[c]).sum::<f64>())
        .collect()
}

/// Sensitivities of each channel's dwell mean to δα and δβ (codes per mrad) at a position.
pub(super) fn angle_gains(d: &Data, p: usize) -> Vec<[f64; 2]> {
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
    heldout_signatures(d, base, set).0
}

/// Whether a kept effect's own signature is present in the withheld data: its contribution `p`,
/// predicted on the withheld positions by the fit on the others, against the withheld residual
/// of the model without it, `u = r + p`. The amplitude `Σw·u·p/Σw·p²` is 1 when the held-out data
/// carry the effect as fitted and 0 when they do not; its z is `Σw·u·p/√(Σw·p²)`. (The χ² drop the
/// effect brings on the same rows is `Σw·p²·(2·amplitude − 1)`: a drop can come from a small
/// part of a large prediction, the amplitude says how much of the prediction is there.)
#[derive(Clone, Copy, Debug, Serialize)]
pub struct Signature {
    /// Effect name.
    pub name: &'static str,
    /// Held-out amplitude of the predicted contribution (1: fully present).
    pub amplitude: f64,
    /// Its z-score against the noise.
    pub z: f64,
}

/// The least held-out amplitude and z of a kept effect's signature.
pub const SIGNATURE: (f64, f64) = (0.5, 5.0);

impl Signature {
    /// Whether the signature is present in the withheld data.
    pub fn present(&self) -> bool {
        self.amplitude >= SIGNATURE.0 && self.z >= SIGNATURE.1
    }
}

/// [`heldout`], with the held-out [`Signature`] of every effect of `set`.
pub fn heldout_signatures(d: &Data, base: Structure, set: &[Cand]) -> (Score, Vec<Signature>) {
    let nb = d.bins.len();
    let (mut chi2, mut ss, mut count, mut shape) = (0.0, 0.0, 0usize, 0.0);
    // Per effect: Σ w·u·p and Σ w·p².
    let mut sig = vec![(0.0, 0.0); set.len()];
    for parity in [0, 1] {
        let stacked = |keep: &dyn Fn(usize) -> bool| -> Vec<usize> {
            (0..nb * d.nch()).filter(|&r| keep(d.bins[r % nb].pos)).collect()
        };
        let fit_rows = stacked(&|p| p % 2 == parity);
        let test_rows = stacked(&|p| p % 2 != parity);
        let fit_pos: Vec<usize> = (0..d.npos()).filter(|p| p % 2 == parity).collect();
        let Some((f, prior)) = fit_backfit(d, base, set, &fit_rows, &fit_pos) else {
            let inf = f64::INFINITY;
            return (Score { chi2: inf, rms: inf, bins: 0, params: 0, chi2_shape: inf }, Vec::new());
        };
        let mut r = residuals(&f);
        let mut angle_pred = Vec::new();
        if set.contains(&Cand::AngleError) {
            let test_pos: Vec<usize> = (0..d.npos()).filter(|p| p % 2 != parity).collect();
            let mut all = r.clone();
            angle_correct(d, &mut all, &test_pos, false, prior);
            shape += test_rows.iter().map(|&i| f.design.w[i] * all[i] * all[i]).sum::<f64>();
            shape += 2.0 * test_pos.len() as f64;
            let before = r.clone();
            angle_correct(d, &mut r, &test_pos, true, prior);
            angle_pred = before.iter().zip(&r).map(|(b, a)| b - a).collect();
        }
        for (k, &c) in set.iter().enumerate() {
            let p = if c == Cand::AngleError { angle_pred.clone() } else { contribution(&f, c) };
            for &i in &test_rows {
                sig[k].0 += f.design.w[i] * (r[i] + p[i]) * p[i];
                sig[k].1 += f.design.w[i] * p[i] * p[i];
            }
        }
        for &i in &test_rows {
            chi2 += f.design.w[i] * r[i] * r[i];
            ss += r[i] * r[i];
            count += 1;
        }
    }
    let chi2_shape = if set.contains(&Cand::AngleError) { shape } else { chi2 };
    let score = Score {
        chi2,
        rms: (ss / count.max(1) as f64).sqrt(),
        bins: count,
        params: nparams(d, base, set),
        chi2_shape,
    };
    let sigs = set
        .iter()
        .zip(&sig)
        .map(|(c, &(up, pp))| Signature {
            name: c.name(),
            amplitude: if pp > 0.0 { up / pp } else { 0.0 },
            z: if pp > 0.0 { up / pp.sqrt() } else { 0.0 },
        })
        .collect();
    (score, sigs)
}

/// The contribution of effect `c` to every stacked row of a fit (its columns times their
/// coefficients).
fn contribution(f: &Fitted, c: Cand) -> Vec<f64> {
    let x = &f.design.x;
    let mine: Vec<usize> = (0..x.ncols()).filter(|&k| f.design.cols[k].cand == Some(c)).collect();
    (0..x.nrows()).map(|r| mine.iter().map(|&k| x[(r, k)] * f.beta[k]).sum()).collect()
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
