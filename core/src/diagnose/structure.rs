//! Honesty checks on a set of named effects: what each should have removed and did not, where
//! the structure left lies, and effects the campaign cannot tell apart.
//!
//! **Leftover structure.** An effect of the library is a narrow model of a wider kind of
//! disturbance (a linear drift of slow changes in time, `hysteresis` of offsets set by how a
//! position was approached, `settling` of transients inside the dwells, ...). After the baseline and
//! the named effects are fitted on all data, two tests ask whether the residual still holds
//! structure of the effect's kind:
//! - **family**: the effect's wider family of columns (see [`family`]) is added to the fit; its
//!   χ² drop, scaled by the residual variance (an F test), as a z-score;
//! - **domain**: the χ² of the residual where the effect acts: the dwell means (every effect but
//!   `settling`), or the bins around their dwell mean (`settling`), as a z-score.
//!
//! An effect with either z at or beyond [`PARTIAL_Z`] is *partial*: it removes part of a
//! structure it does not fully describe, and the structure left is reported as unexplained.
//!
//! **Confounding.** A drift and a temperature effect are the same columns when the temperature
//! follows time; [`confounds`] reports the pair with the correlation and what would separate them.

use accelcal_shared::Structure;
use nalgebra::DMatrix;
use serde::Serialize;

use super::attribution::{angle_gains, derivatives, fit_backfit, residuals, Cand, Fitted};
use super::{wls, zscore, Data};

/// The z at or beyond which a named effect is reported as partial.
pub const PARTIAL_Z: f64 = 5.0;

/// What one named effect left.
#[derive(Clone, Debug, Serialize)]
pub struct Leftover {
    /// Effect name.
    pub name: &'static str,
    /// The wider family tested.
    pub family: &'static str,
    /// Columns of the family.
    pub columns: usize,
    /// z of the family's χ² drop (F test against the rest of the residual).
    pub z_family: f64,
    /// Where the effect acts: `positions` (dwell means) or `in dwell`.
    pub domain: &'static str,
    /// z of the residual's χ² there.
    pub z_domain: f64,
    /// Whether the effect is partial (either z at or beyond [`PARTIAL_Z`]).
    pub partial: bool,
}

/// Where the residual of the final model lies, per channel.
#[derive(Clone, Debug, Serialize)]
pub struct Where {
    /// Channel.
    pub channel: String,
    /// z of the χ² of the dwell-mean residuals.
    pub z_positions: f64,
    /// z of the χ² of the bins around their dwell mean.
    pub z_in_dwell: f64,
}

/// The wider family of an effect: what the family is called and its stacked columns
/// (`ch·bins + row`).
pub fn family(d: &Data, c: Cand, tau: f64) -> (&'static str, Vec<Vec<f64>>) {
    let nb = d.bins.len();
    let nch = d.nch();
    let per_channel =
        |f: &dyn Fn(usize, usize) -> f64| -> Vec<f64> { (0..nb * nch).map(|r| f(r / nb, r % nb)).collect() };
    let only = |ch: usize, f: &dyn Fn(usize, usize) -> f64| -> Vec<f64> {
        per_channel(&|c, row| if c == ch { f(c, row) } else { 0.0 })
    };
    let mut cols = Vec::new();
    let span = |v: &[f64]| {
        let (lo, hi) = v.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &x| (l.min(x), h.max(x)));
        ((lo + hi) / 2.0, ((hi - lo) / 2.0).max(1e-9))
    };
    let name = match c {
        Cand::BiasDrift | Cand::Temperature => {
            let v: Vec<f64> = if c == Cand::BiasDrift {
                d.bins.iter().map(|b| b.t).collect()
            } else {
                d.temp.clone().unwrap_or_else(|| vec![0.0; nb])
            };
            let (mid, half) = span(&v);
            for ch in 0..nch {
                for k in 2..=4 {
                    cols.push(only(ch, &|_, row| ((v[row] - mid) / half).powi(k)));
                }
            }
            if c == Cand::BiasDrift {
                "smooth changes in time (polynomials of degree 2 to 4 per channel)"
            } else {
                "smooth changes with temperature (polynomials of degree 2 to 4 per channel)"
            }
        }
        Cand::Nonlinearity => {
            for ch in 0..nch {
                let own = d.own[ch];
                // The squares of the other axes (the library has the own axis's only: with the
                // constant, they hold one more direction, since ax² + ay² + az² = g²), and cubes.
                let others = (0..3).filter(|&i| i != own).map(|i| {
                    let mut e = [0; 3];
                    e[i] = 2;
                    e
                });
                for e in others.chain([[3, 0, 0], [0, 3, 0], [0, 0, 3], [1, 1, 1]]) {
                    cols.push(only(ch, &|_, row| {
                        let a = d.accel[d.bins[row].pos];
                        (0..3).map(|i| (a[i] / d.g).powi(e[i])).product::<f64>()
                    }));
                }
            }
            "other terms of the input (the other axes' squares and the cubic terms, per channel)"
        }
        Cand::HeadMisalignment => {
            for axis in [0, 1] {
                for phase in [0.0, std::f64::consts::FRAC_PI_2] {
                    cols.push(per_channel(&|ch, row| {
                        let p = d.bins[row].pos;
                        let m = (d.angles[p].0.to_radians() + phase).sin();
                        let der = derivatives(d, p)[axis];
                        m * (0..3).map(|i| d.k[ch][i] * der[i]).sum::<f64>()
                    }));
                }
            }
            "a rotation of the head that changes with alpha (rx, rz times sin and cos alpha)"
        }
        Cand::Hysteresis => {
            let sign = |x: f64| if x.abs() < 1e-9 { 0.0 } else { x.signum() };
            let turn = |p: usize, i: usize| -> f64 {
                if p == 0 {
                    return 0.0;
                }
                let (a, b) = (d.angles[p], d.angles[p - 1]);
                let da = if i == 0 { a.0 - b.0 } else { a.1 - b.1 };
                sign((da + 180.0).rem_euclid(360.0) - 180.0)
            };
            for ch in 0..nch {
                for j in (0..3).filter(|&j| j != d.own[ch]) {
                    cols.push(only(ch, &|_, row| {
                        let p = d.bins[row].pos;
                        if p == 0 {
                            0.0
                        } else {
                            sign(d.accel[p][j] - d.accel[p - 1][j])
                        }
                    }));
                }
                for i in [0, 1] {
                    cols.push(only(ch, &|_, row| turn(d.bins[row].pos, i)));
                }
            }
            "offsets set by the approach (signs of the other axes' steps and of the head's turns)"
        }
        Cand::Settling => {
            let settle = d.settle(tau);
            let bins_per_dwell = d.bins.iter().map(|b| b.bin + 1).max().unwrap_or(1);
            for ch in 0..nch {
                let own = d.own[ch];
                for k in 0..bins_per_dwell.saturating_sub(1) {
                    cols.push(only(ch, &|c, row| {
                        if d.bins[row].bin == k {
                            d.step[c][d.bins[row].pos]
                        } else {
                            0.0
                        }
                    }));
                    cols.push(only(ch, &|_, row| if d.bins[row].bin == k { 1.0 } else { 0.0 }));
                }
                for j in (0..3).filter(|&j| j != own) {
                    cols.push(only(ch, &|_, row| {
                        let p = d.bins[row].pos;
                        let step = if p == 0 { 0.0 } else { d.accel[p][j] - d.accel[p - 1][j] };
                        step * settle[row]
                    }));
                }
                cols.push(only(ch, &|c, row| {
                    let s = d.step[c][d.bins[row].pos];
                    s * s / d.g * settle[row]
                }));
            }
            "transients inside the dwells (a free profile signed by the step, an unsigned one, other axes' steps, the squared step)"
        }
        Cand::AngleError => "angle errors that follow the head's angles (smooth functions of alpha and beta)",
    };
    (name, cols)
}

/// χ² z of the dwell-mean residuals and of the bins around their dwell mean, per channel, for a
/// stacked residual; `params` parameters per channel are taken from the dwell-mean dof.
fn localise(d: &Data, resid: &[f64], params: f64) -> Vec<Where> {
    let nb = d.bins.len();
    let npos = d.npos();
    (0..d.nch())
        .map(|ch| {
            let r = &resid[ch * nb..(ch + 1) * nb];
            let mean = d.dwell_means(r);
            let s2 = d.sigma[ch] * d.sigma[ch];
            let mut n = vec![0.0; npos];
            for b in &d.bins {
                n[b.pos] += b.n;
            }
            let chi_pos: f64 = (0..npos).map(|p| n[p] * mean[p] * mean[p] / s2).sum();
            let chi_in: f64 = d.bins.iter().zip(r).map(|(b, x)| b.n * (x - mean[b.pos]).powi(2) / s2).sum();
            Where {
                channel: d.channels[ch].clone(),
                z_positions: zscore(chi_pos, (npos as f64 - params).max(1.0)),
                z_in_dwell: zscore(chi_in, (nb - npos) as f64),
            }
        })
        .collect()
}

/// The full-data fit of `set` with its residual (angle errors removed), and where it lies.
fn final_fit(d: &Data, base: Structure, set: &[Cand]) -> Option<(Fitted, Vec<f64>, Vec<Where>)> {
    let all: Vec<usize> = (0..d.bins.len() * d.nch()).collect();
    let pos: Vec<usize> = (0..d.npos()).collect();
    let (f, _) = fit_backfit(d, base, set, &all, &pos)?;
    let resid = residuals(&f);
    let angles = if set.contains(&Cand::AngleError) { 2.0 * d.npos() as f64 / d.nch() as f64 } else { 0.0 };
    let params = f.beta.len() as f64 / d.nch() as f64 + angles;
    let at = localise(d, &resid, params);
    Some((f, resid, at))
}

/// The leftover structure of every effect of `set`, and where the final residual lies. When
/// `angle_error` is itself partial (the "random" angle errors follow the head's angles), it may
/// not hide the structure the other effects left: theirs is tested again without it, and the
/// worse of the two counts.
pub fn leftovers(d: &Data, base: Structure, set: &[Cand]) -> (Vec<Leftover>, Vec<Where>) {
    let Some((mut out, at)) = leftovers_of(d, base, set) else { return (Vec::new(), Vec::new()) };
    let angle_partial = out.iter().any(|l| l.name == Cand::AngleError.name() && l.partial);
    let rest: Vec<Cand> = set.iter().copied().filter(|&c| c != Cand::AngleError).collect();
    if angle_partial && !rest.is_empty() {
        if let Some((again, _)) = leftovers_of(d, base, &rest) {
            for l in out.iter_mut() {
                if let Some(a) = again.iter().find(|a| a.name == l.name) {
                    l.z_family = l.z_family.max(a.z_family);
                    l.z_domain = l.z_domain.max(a.z_domain);
                    l.partial |= a.partial;
                }
            }
        }
    }
    (out, at)
}

/// [`leftovers`] of one set as it is fitted.
fn leftovers_of(d: &Data, base: Structure, set: &[Cand]) -> Option<(Vec<Leftover>, Vec<Where>)> {
    let (f, _, at) = final_fit(d, base, set)?;
    let all: Vec<usize> = (0..d.bins.len() * d.nch()).collect();
    let combine = |zs: Vec<f64>| -> f64 {
        // The channels' z-scores of independent χ² pooled into one.
        zs.iter().sum::<f64>() / (zs.len().max(1) as f64).sqrt()
    };
    let z_positions = combine(at.iter().map(|w| w.z_positions).collect());
    let z_in_dwell = combine(at.iter().map(|w| w.z_in_dwell).collect());
    let out = set
        .iter()
        .map(|&c| {
            let (name, cols) = family(d, c, f.tau);
            let z_family =
                if c == Cand::AngleError { angle_structure_z(d, &f) } else { family_z(&f, &cols, &all) };
            let (domain, z_domain) =
                if c == Cand::Settling { ("in dwell", z_in_dwell) } else { ("positions", z_positions) };
            Leftover {
                name: c.name(),
                family: name,
                columns: cols.len(),
                z_family,
                domain,
                z_domain,
                partial: z_family >= PARTIAL_Z || z_domain >= PARTIAL_Z,
            }
        })
        .collect();
    Some((out, at))
}

/// z of the χ² drop the columns `extra` bring to the design of the fit `f` (scaled by the residual variance
/// per degree of freedom when above 1: an F test); 0 without columns.
fn family_z(f: &Fitted, extra: &[Vec<f64>], rows: &[usize]) -> f64 {
    if extra.is_empty() {
        return 0.0;
    }
    let x = &f.design.x;
    let k = x.ncols();
    let xe =
        DMatrix::from_fn(x.nrows(), k + extra.len(), |r, c| if c < k { x[(r, c)] } else { extra[c - k][r] });
    // Both fits by plain weighted least squares on the same data (with angle errors, the fitted
    // ones taken out), so that the drop is the family's alone.
    let (Some(b), Some(e)) =
        (wls(x, &f.design.y, &f.design.w, rows), wls(&xe, &f.design.y, &f.design.w, rows))
    else {
        return 0.0;
    };
    let p = extra.len() as f64;
    let dof = (rows.len() as f64 - xe.ncols() as f64).max(1.0);
    let s2 = (e.wsse / dof).max(1.0);
    zscore((b.wsse - e.wsse) / s2, p)
}

/// z of the structure of the fitted angle errors: random angle errors do not follow the head's
/// angles. The errors (δα, δβ) of each position are recovered from the angle part the mixed fit
/// took out of the data, where both are seen; each is regressed on a constant and sin α, cos α,
/// sin 2α, cos 2α, sin β, sin α·sin β, cos α·sin β, cos β (an F test of the sixteen non-constant
/// columns against the rest, as a z-score).
fn angle_structure_z(d: &Data, f: &Fitted) -> f64 {
    let nb = d.bins.len();
    let mut u: Vec<[f64; 2]> = Vec::new();
    let mut at: Vec<(f64, f64)> = Vec::new();
    for p in 0..d.npos() {
        let gr = angle_gains(d, p);
        let (mut a, mut b) = (nalgebra::Matrix2::<f64>::zeros(), nalgebra::Vector2::<f64>::zeros());
        for row in (0..nb).filter(|&r| d.bins[r].pos == p) {
            for (ch, g) in gr.iter().enumerate() {
                let adj = d.mean[ch][row] - f.design.y[ch * nb + row];
                let z = nalgebra::Vector2::new(g[0], g[1]);
                a += z * z.transpose();
                b += adj * z;
            }
        }
        // Only where both angles are seen (at β = ±90° a turn of α moves nothing).
        let e = a.symmetric_eigen();
        if !(e.eigenvalues.min() > 1e-3 * e.eigenvalues.max()) {
            continue;
        }
        if let Some(x) = a.try_inverse().map(|ai| ai * b) {
            u.push([x[0], x[1]]);
            at.push((d.angles[p].0.to_radians(), d.angles[p].1.to_radians()));
        }
    }
    let n = u.len();
    if n < 20 {
        return 0.0;
    }
    let cols = |(al, be): (f64, f64)| {
        let (sa, ca, sb) = (al.sin(), al.cos(), be.sin());
        [1.0, sa, ca, (2.0 * al).sin(), (2.0 * al).cos(), sb, sa * sb, ca * sb, be.cos()]
    };
    let k = cols((0.0, 0.0)).len();
    let x = DMatrix::from_fn(n, k, |r, c| cols(at[r])[c]);
    let x0 = DMatrix::from_fn(n, 1, |_, _| 1.0);
    let w = vec![1.0; n];
    let rows: Vec<usize> = (0..n).collect();
    let (mut drop, mut rest) = (0.0, 0.0);
    for k in 0..2 {
        let y: Vec<f64> = u.iter().map(|v| v[k]).collect();
        let (Some(full), Some(red)) = (wls(&x, &y, &w, &rows), wls(&x0, &y, &w, &rows)) else { return 0.0 };
        drop += red.wsse - full.wsse;
        rest += full.wsse;
    }
    let s2 = rest / (2 * (n - k)) as f64;
    if !(s2 > 0.0) {
        return 0.0;
    }
    zscore(drop / s2, 2.0 * (k - 1) as f64)
}

/// Two effects the campaign cannot tell apart.
#[derive(Clone, Debug, Serialize)]
pub struct Confound {
    /// The two effects.
    pub effects: [&'static str; 2],
    /// Correlation of their columns over the bins.
    pub r: f64,
    /// What would separate them.
    pub separate: &'static str,
}

/// The correlation beyond which a drift and a temperature effect count as confounded.
pub const CONFOUND_R: f64 = 0.9;

/// Confounded candidates of a campaign: `bias_drift` and `temperature` when the temperature
/// follows time (|r| ≥ [`CONFOUND_R`] between the bins' times and temperatures).
pub fn confounds(d: &Data) -> Vec<Confound> {
    let Some(temp) = &d.temp else { return Vec::new() };
    let t: Vec<f64> = d.bins.iter().map(|b| b.t).collect();
    let n = t.len() as f64;
    let (mt, mx) = (t.iter().sum::<f64>() / n, temp.iter().sum::<f64>() / n);
    let (mut sxy, mut sxx, mut syy) = (0.0, 0.0, 0.0);
    for (a, b) in t.iter().zip(temp) {
        sxy += (a - mt) * (b - mx);
        sxx += (a - mt) * (a - mt);
        syy += (b - mx) * (b - mx);
    }
    let r = if sxx > 0.0 && syy > 0.0 { sxy / (sxx * syy).sqrt() } else { 0.0 };
    if r.abs() < CONFOUND_R {
        return Vec::new();
    }
    vec![Confound {
        effects: [Cand::BiasDrift.name(), Cand::Temperature.name()],
        r,
        separate: "a campaign whose temperature does not follow time: a temperature cycle, a steady temperature, or the plan run again as the block cools",
    }]
}
