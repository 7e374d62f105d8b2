//! The budget's contributors, one function each: every one takes what the fit's positions give
//! ([`Setup`]) and the stated references, and returns its covariance of the 12 coefficients and
//! what it explains of the residuals, which the dwell scatter then leaves out. [`super::budget`]
//! calls them in order and sums them.

use nalgebra::{DMatrix, DVector};

use super::{add_block, dot3, head_partials, lack_of_fit, row, scatter, Cov12, References, UncertaintyError};
use crate::lsq::LsqFit;
use crate::positions::{ChannelStats, Positions};
use accelcal_shared::linear::Model4;

/// What every contributor is computed from: the positions, the least-squares operator and the
/// residuals of the fit.
pub(super) struct Setup<'a> {
    pub pos: &'a Positions,
    pub stats: &'a [ChannelStats],
    /// Which channel (index into `stats`) is the x, y and z row.
    pub order: [usize; 3],
    pub model: Model4,
    /// Positions.
    pub n: usize,
    /// The residuals' degrees of freedom, n − 4.
    pub dof: f64,
    /// A = (XᵀWX)⁻¹XᵀW, 4 × n.
    pub a: DMatrix<f64>,
    /// (XᵀWX)⁻¹.
    pub xtwx_inv: DMatrix<f64>,
    /// R = I − X·A, the residual maker.
    pub resid_maker: DMatrix<f64>,
    /// Each column of R's sum of squares.
    pub rcol_ss: Vec<f64>,
    /// The dwell means' residuals, per axis row.
    pub resid: Vec<DVector<f64>>,
    /// ∂a/∂θ of each position for the head's five parameters.
    pub partials: Vec<[[f64; 3]; 5]>,
    /// Each axis row's response to the two angle errors at each position, codes/rad.
    pub angle_response: Vec<[[f64; 2]; 3]>,
}

impl<'a> Setup<'a> {
    /// The operator and residuals of the fits `fits` (rows `order`) on `pos`.
    pub fn new(
        pos: &'a Positions,
        stats: &'a [ChannelStats],
        fits: &[&LsqFit],
        order: [usize; 3],
        model: Model4,
    ) -> Result<Setup<'a>, UncertaintyError> {
        let n = pos.len();
        let x = DMatrix::from_fn(n, 4, |i, t| row(pos.accel[i])[t]);
        let w = DVector::from_fn(n, |i, _| pos.weight[i]);
        let xtw = DMatrix::from_fn(4, n, |t, i| x[(i, t)] * w[i]);
        let xtwx_inv = (&xtw * &x).try_inverse().ok_or(UncertaintyError::Singular)?;
        let a = &xtwx_inv * &xtw;
        let resid_maker = DMatrix::identity(n, n) - &x * &a;
        let rcol_ss: Vec<f64> = (0..n).map(|i| resid_maker.column(i).norm_squared()).collect();
        let resid: Vec<DVector<f64>> = order
            .iter()
            .map(|&ci| {
                let c = &fits[ci].coefficients;
                DVector::from_fn(n, |i, _| {
                    let r = row(pos.accel[i]);
                    stats[ci].mean[i] - (0..4).map(|t| c[t] * r[t]).sum::<f64>()
                })
            })
            .collect();
        let partials: Vec<[[f64; 3]; 5]> =
            pos.dwells.iter().map(|d| head_partials(d.alpha_deg, d.beta_deg, pos.g)).collect();
        let angle_response = partials
            .iter()
            .map(|pd| [0, 1, 2].map(|ax| [dot3(&model.k[ax], &pd[0]), dot3(&model.k[ax], &pd[1])]))
            .collect();
        Ok(Setup {
            pos,
            stats,
            order,
            model,
            n,
            dof: (n - 4) as f64,
            a,
            xtwx_inv,
            resid_maker,
            rcol_ss,
            resid,
            partials,
            angle_response,
        })
    }

    /// A's column `i`: the coefficients' response to position `i`'s dwell mean.
    fn col(&self, i: usize) -> [f64; 4] {
        std::array::from_fn(|t| self.a[(t, i)])
    }

    /// A·d.
    fn apply_a(&self, d: &DVector<f64>) -> [f64; 4] {
        let v = &self.a * d;
        std::array::from_fn(|t| v[t])
    }
}

/// A covariance and what it explains of the residuals' sum of squares.
pub(super) struct Part {
    pub cov: Cov12,
    /// The residual sum of squares it explains, all channels, codes².
    pub explains: f64,
}

/// The head's angle setting errors (variance `ua2`, rad²): independent per position and angle,
/// common to the channels. What they explain of the residuals is in expectation.
pub(super) fn head_angle(s: &Setup<'_>, ua2: f64) -> Part {
    let mut cov = Cov12::zeros();
    let mut explains = 0.0;
    if ua2 > 0.0 {
        for i in 0..s.n {
            let ai = s.col(i);
            let d = s.angle_response[i];
            for p in 0..3 {
                for q in 0..3 {
                    let v = d[p][0] * d[q][0] + d[p][1] * d[q][1];
                    add_block(&mut cov, p, q, &ai, &ai, ua2 * v);
                }
                explains += ua2 * s.rcol_ss[i] * (d[p][0] * d[p][0] + d[p][1] * d[p][1]);
            }
        }
    }
    Part { cov, explains }
}

/// The head's orthogonality (variance `uo2`, rad², of each of the three rotations between its
/// stages): common to every position and channel. What the fit does not absorb of a rotation
/// stays in the residuals with a shape of its own (the three channels' residuals stacked): the
/// part of the residuals of those shapes is this head's rotation as realised, not scatter. The
/// stated value is not subtracted: a stated error that is not there must not shrink the budget.
pub(super) fn head_orthogonality(s: &Setup<'_>, uo2: f64) -> Part {
    let mut cov = Cov12::zeros();
    if uo2 <= 0.0 {
        return Part { cov, explains: 0.0 };
    }
    let n = s.n;
    let mut shapes = vec![DVector::zeros(3 * n); 3];
    for (j, shape) in shapes.iter_mut().enumerate() {
        let dc: Vec<[f64; 4]> = (0..3)
            .map(|ax| {
                let d = DVector::from_fn(n, |i, _| dot3(&s.model.k[ax], &s.partials[i][2 + j]));
                shape.rows_mut(ax * n, n).copy_from(&(&s.resid_maker * &d));
                s.apply_a(&d)
            })
            .collect();
        for p in 0..3 {
            for q in 0..3 {
                add_block(&mut cov, p, q, &dc[p], &dc[q], uo2);
            }
        }
    }
    let r = DVector::from_fn(3 * n, |k, _| s.resid[k / n][k % n]);
    let v = DMatrix::from_fn(3 * n, 3, |k, j| shapes[j][k]);
    let explains = match (v.transpose() * &v).try_inverse() {
        Some(inv) => {
            let vtr = v.transpose() * &r;
            vtr.dot(&(inv * &vtr))
        }
        None => 0.0,
    };
    Part { cov, explains }
}

/// Gravity: a relative error `rel` of g scales every sensitivity.
pub(super) fn gravity(s: &Setup<'_>, rel: f64) -> Cov12 {
    let mut cov = Cov12::zeros();
    let dk: [[f64; 4]; 3] = [0, 1, 2].map(|ax| [0.0, s.model.k[ax][0], s.model.k[ax][1], s.model.k[ax][2]]);
    for p in 0..3 {
        for q in 0..3 {
            add_block(&mut cov, p, q, &dk[p], &dk[q], rel * rel);
        }
    }
    cov
}

/// Quantisation: 1/12 code² per sample, independent per channel; what it explains of the
/// residuals is in expectation.
pub(super) fn quantisation(s: &Setup<'_>) -> Part {
    let mut cov = Cov12::zeros();
    let mut explains = 0.0;
    for i in 0..s.n {
        let ai = s.col(i);
        let v = 1.0 / (12.0 * s.pos.weight[i].max(1.0));
        for p in 0..3 {
            add_block(&mut cov, p, p, &ai, &ai, v);
        }
        explains += 3.0 * v * s.rcol_ss[i];
    }
    Part { cov, explains }
}

/// Temperature: each channel's bias and scale factor at T_ref, not at the campaign's mean T̄;
/// with where it comes from, in words.
pub(super) fn temperature(s: &Setup<'_>, refs: &References) -> Result<(Cov12, String), UncertaintyError> {
    let mut cov = Cov12::zeros();
    let Some(t) = refs.temperature else { return Ok((cov, "not stated".into())) };
    let pos = s.pos;
    let temps = pos.temp_c.as_ref().ok_or(UncertaintyError::NoTemperature)?;
    let wsum: f64 = pos.weight.iter().sum();
    let mean = temps.iter().zip(&pos.weight).map(|(t, w)| t * w).sum::<f64>() / wsum.max(f64::MIN_POSITIVE);
    let dt = mean - pos.t_ref_c;
    let spread = dt * dt + t.thermometer_c * t.thermometer_c;
    for p in 0..3 {
        let k = s.model.k[p];
        let own = k[p].abs();
        // mg are of standard gravity.
        let bias_codes = t.bias_mg_per_c * 1e-3 * accelcal_shared::G_STANDARD * own;
        cov[(4 * p, 4 * p)] += bias_codes * bias_codes * spread;
        let rel = t.scale_ppm_per_c * 1e-6;
        let dk = [0.0, k[0], k[1], k[2]];
        add_block(&mut cov, p, p, &dk, &dk, rel * rel * spread);
    }
    let source = format!(
        "{} mg/°C bias and {} ppm/°C scale factor per channel (stated, one sigma), calibrated at {mean:.1} °C \
         (mean of the campaign's readings) for the reference {:.1} °C, thermometer u(T) = {} °C",
        t.bias_mg_per_c, t.scale_ppm_per_c, pos.t_ref_c, t.thermometer_c
    );
    Ok((cov, source))
}

/// Model 4's lack of fit ([`lack_of_fit::measure`]): each channel's RMS error over the sphere
/// `points`, on its bias term; what it explains of the residuals as realised; its source in
/// words; and why it was not measured, when it was not.
pub(super) fn lack_of_fit(
    s: &Setup<'_>,
    refs: &References,
    within: Option<scatter::Within>,
    points: &[[f64; 3]],
) -> (Part, String, Option<String>) {
    let (n, order) = (s.n, s.order);
    let ua2 = refs.head_angle_rad * refs.head_angle_rad;
    let uo = refs.head_orthogonality_rad;
    let mut cov = Cov12::zeros();
    let mut explains = 0.0;
    // The head's stated rotation leaves outputs of its own, which a linear unit shows too.
    let head_outputs: Vec<DMatrix<f64>> = (0..s.stats.len())
        .map(|ci| match order.iter().position(|&o| o == ci) {
            Some(p) if uo > 0.0 => {
                DMatrix::from_fn(n, 3, |i, j| uo * dot3(&s.model.k[p], &s.partials[i][2 + j]))
            }
            _ => DMatrix::zeros(n, 0),
        })
        .collect();
    // What the samples' noise and the head's stated angle errors predict of the dwell means'
    // scatter, per channel in the order of the stats.
    let axis_of = |ci: usize| order.iter().position(|&o| o == ci);
    let mean_var: Vec<Vec<f64>> = (0..s.stats.len())
        .map(|ci| match (axis_of(ci), within) {
            (Some(p), Some(w)) => {
                (0..n).map(|i| w.mean_cov(p, p, s.pos.weight[i], &s.angle_response[i], ua2)).collect()
            }
            _ => Vec::new(),
        })
        .collect();
    let known = within.map(|_| lack_of_fit::Known { mean_var: &mean_var });
    let measured = lack_of_fit::measure(s.pos, s.stats, &s.a, &s.resid_maker, points, &head_outputs, known);
    match measured {
        Ok(m) => {
            for (p, &ci) in order.iter().enumerate() {
                cov[(4 * p, 4 * p)] = m.u_codes[ci] * m.u_codes[ci];
                explains += m.explained_ss[ci];
            }
            let [x, y, z] = order.map(|ci| m.rms_codes[ci]);
            let [fx, fy, fz] = order.map(|ci| m.floor_codes[ci]);
            let gap = match refs.lack_of_fit_codes {
                Some(lof) => {
                    let [gx, gy, gz] = order.map(|ci| lof[ci]);
                    format!(
                        "; GMDH's criterion gap to the best of the paper's 11 models x {gx:.2}, y {gy:.2}, z {gz:.2} codes"
                    )
                }
                None => String::new(),
            };
            let source = format!(
                "model 4's error against the quadratic model, RMS over the sphere less the dwell scatter's share: \
                 x {x:.2}, y {y:.2}, z {z:.2} codes (this plan resolves x {fx:.2}, y {fy:.2}, z {fz:.2}); u is half its \
                 95th percentile{gap}"
            );
            (Part { cov, explains }, source, None)
        }
        Err(why) => (Part { cov, explains }, "not measured".to_string(), Some(why.to_string())),
    }
}

/// The dwell scatter ([`scatter`]): the samples' noise within the dwells, and what the dwell
/// means scatter about the fit beyond it and the stated references (`expected` of the residual
/// sum of squares in expectation, `realised` as realised; all of their scatter, less what the
/// references explain, when the dwells hold one sample each). Gives the noise's and the
/// excess's covariances and the source in words.
pub(super) fn dwell_scatter(
    s: &Setup<'_>,
    refs: &References,
    within: Option<scatter::Within>,
    expected: f64,
    realised: f64,
) -> (Cov12, Cov12, String) {
    let (n, dof) = (s.n, s.dof);
    let kept = match &within {
        Some(w) => scatter::Check {
            resid_maker: &s.resid_maker,
            weight: &s.pos.weight,
            resid: &s.resid,
            angle_response: &s.angle_response,
            angle_var: refs.head_angle_rad * refs.head_angle_rad,
            realised,
        }
        .excess_fraction(w),
        None => {
            let observed: f64 = s.resid.iter().map(|r| r.norm_squared()).sum();
            if observed > 0.0 {
                (1.0 - (expected + realised) / observed).max(0.0)
            } else {
                0.0
            }
        }
    };
    let mut noise = Cov12::zeros();
    if let Some(w) = &within {
        for p in 0..3 {
            for i in 0..4 {
                for j in 0..4 {
                    noise[(4 * p + i, 4 * p + j)] = w.var_codes2[p] * s.xtwx_inv[(i, j)];
                }
            }
        }
    }
    let aat = &s.a * s.a.transpose();
    let mut excess = Cov12::zeros();
    for p in 0..3 {
        for q in 0..3 {
            let v = s.resid[p].dot(&s.resid[q]) / dof * kept;
            for i in 0..4 {
                for j in 0..4 {
                    excess[(4 * p + i, 4 * q + j)] = v * aat[(i, j)];
                }
            }
        }
    }
    let source = match &within {
        Some(w) => format!(
            "the samples' scatter within the dwells ({:.0} degrees of freedom) over each dwell's samples; beyond it and the \
             stated references, the dwell means' scatter about the fit ({n} positions, {dof} degrees of freedom) holds {}",
            w.dof,
            if kept > 0.0 { format!("{:.0} % of its sum of squares more", kept * 100.0) } else { "nothing more".into() }
        ),
        None => format!(
            "the dwell means' scatter about the fit ({n} positions, {dof} degrees of freedom), {:.0} % of it left once the \
             stated references are taken out",
            kept * 100.0
        ),
    };
    (noise, excess, source)
}
