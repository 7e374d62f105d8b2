//! Gravity-norm calibration: the imu_tk 9-parameter triad model fitted on |a| = g over static holds.
//!
//! # Model and conventions
//!
//! For a raw output `u` (codes, one value per axis) the calibrated specific force is
//!
//! ```text
//! v_i = (u_i − b_i) / s_i            per-axis, m/s²          (b: bias in codes, s: scale in codes per m/s²)
//! w_i = v_i + q_i · v_i²             per-axis nonlinearity   (q in 1/(m/s²); zero unless GravityStructure::ImuTkQuadratic)
//! a   = T · w                        T = | 1  −α_yz   α_zy |
//!                                        | 0    1    −α_zx |
//!                                        | 0    0      1   |
//! ```
//!
//! This is the accelerometer model of imu_tk (Tedaldi, Pretto, Menegatti, ICRA 2014) with the scale
//! expressed as a sensitivity (codes per m/s², the inverse of imu_tk's `K`). `T` is upper unit
//! triangular: the calibrated frame has its z axis along the sensitive z axis, its y axis in the plane
//! of the sensitive y and z axes, and x completing a right-handed orthonormal frame. To first order in
//! the angles (radians) the sensitive axes, expressed in that frame, are
//! `e_z = (0, 0, 1)`, `e_y = (0, 1, α_zx)`, `e_x = (1, α_yz, −α_zy)`. Only `|a|` is observed, so the
//! rotation of the calibrated frame is not identifiable; the triangular `T` removes those 3 degrees of
//! freedom, which leaves 9 parameters. The JSON `misalignment` is `T`, row by row.
//!
//! # Fit
//!
//! Each hold contributes one residual `r_k = |a(ū_k)| − g` (m/s²), where `ū_k` is the hold's mean output.
//! The sum of squares is minimised with Levenberg–Marquardt (see [`super::solver`]) on internally scaled
//! parameters (bias steps and scale changes in units of the initial scale), from an initial guess taken
//! from the data: per axis `b = (max + min)/2` and `s = (max − min)/(2g)` of the hold means, refined by
//! an axis-aligned ellipsoid fitted by linear least squares when that is well posed. Standard errors are
//! `sqrt(diag(σ² (JᵀJ)⁻¹))` with `J` the Jacobian in natural units at the solution and
//! `σ² = Σ r² / (holds − parameters)`.

use nalgebra::{DMatrix, DVector};

use super::solver;
use crate::error::{Classify, Kind};

/// Candidate model structures, from the simplest to the richest.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum GravityStructure {
    /// Bias and scale only (6 parameters, `T = I`).
    BiasScale,
    /// The imu_tk model: bias, scale and three misalignment angles (9 parameters).
    ImuTk,
    /// The imu_tk model plus a per-axis quadratic term (12 parameters).
    ImuTkQuadratic,
}

impl GravityStructure {
    /// All structures, simplest first.
    pub const ALL: [GravityStructure; 3] =
        [GravityStructure::BiasScale, GravityStructure::ImuTk, GravityStructure::ImuTkQuadratic];

    /// Indices of the free parameters in the full parameter vector (see [`PARAM_NAMES`]).
    pub fn active(self) -> &'static [usize] {
        match self {
            GravityStructure::BiasScale => &[3, 4, 5, 6, 7, 8],
            GravityStructure::ImuTk => &[0, 1, 2, 3, 4, 5, 6, 7, 8],
            GravityStructure::ImuTkQuadratic => &[0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11],
        }
    }

    /// Number of free parameters.
    pub fn n_params(self) -> usize {
        self.active().len()
    }

    /// Short name used in tables and JSON.
    pub fn name(self) -> &'static str {
        match self {
            GravityStructure::BiasScale => "bias+scale",
            GravityStructure::ImuTk => "imu_tk (bias+scale+misalignment)",
            GravityStructure::ImuTkQuadratic => "imu_tk + per-axis quadratic",
        }
    }
}

/// Names of the entries of the full 12-parameter vector, in order.
pub const PARAM_NAMES: [&str; 12] = [
    "alpha_yz", "alpha_zy", "alpha_zx", "scale_x", "scale_y", "scale_z", "bias_x", "bias_y", "bias_z",
    "quad_x", "quad_y", "quad_z",
];

/// Parameters of the triad model (see the module documentation for the equations).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct TriadModel {
    /// Bias `b`, in codes.
    pub bias: [f64; 3],
    /// Scale `s` (sensitivity), in codes per m/s².
    pub scale: [f64; 3],
    /// Misalignment angles `[α_yz, α_zy, α_zx]`, in radians.
    pub alpha: [f64; 3],
    /// Per-axis quadratic coefficients `q`, in 1/(m/s²).
    pub quad: [f64; 3],
}

impl TriadModel {
    /// The misalignment matrix `T`, row-major.
    pub fn misalignment(&self) -> [[f64; 3]; 3] {
        let [yz, zy, zx] = self.alpha;
        [[1.0, -yz, zy], [0.0, 1.0, -zx], [0.0, 0.0, 1.0]]
    }

    /// Calibrated specific force `a` (m/s²) for a raw output `u` (codes).
    pub fn apply(&self, u: [f64; 3]) -> [f64; 3] {
        let w: [f64; 3] = std::array::from_fn(|i| {
            let v = (u[i] - self.bias[i]) / self.scale[i];
            v + self.quad[i] * v * v
        });
        mat_vec(&self.misalignment(), w)
    }

    /// Raw output `u` (codes, unquantised) that the model maps to the specific force `a`, or `None`
    /// where the quadratic term has no real inverse.
    pub fn raw_from_specific_force(&self, a: [f64; 3]) -> Option<[f64; 3]> {
        let [yz, zy, zx] = self.alpha;
        // Back-substitution of the upper unit-triangular T.
        let wz = a[2];
        let wy = a[1] + zx * wz;
        let wx = a[0] + yz * wy - zy * wz;
        let w = [wx, wy, wz];
        let mut u = [0.0; 3];
        for i in 0..3 {
            let q = self.quad[i];
            let v = if q == 0.0 {
                w[i]
            } else {
                let disc = 1.0 + 4.0 * q * w[i];
                if disc < 0.0 {
                    return None;
                }
                (disc.sqrt() - 1.0) / (2.0 * q)
            };
            u[i] = self.bias[i] + self.scale[i] * v;
        }
        Some(u)
    }

    /// The same calibration as model 4 (`u = u0 + K·a`, the node's model), exactly: with the
    /// quadratic terms zero, `a = T·S⁻¹·(u − b)` inverts to `u = b + S·T⁻¹·a`, so `u0 = b` and
    /// `K = S·T⁻¹` (row i of the upper unit-triangular `T⁻¹` scaled by `s_i`). `None` when a
    /// quadratic term is not zero: that model is not linear in `u`.
    pub fn model4(&self) -> Option<accelcal_shared::linear::Model4> {
        if self.quad.iter().any(|&q| q != 0.0) {
            return None;
        }
        let [yz, zy, zx] = self.alpha;
        let t_inv = [[1.0, yz, yz * zx - zy], [0.0, 1.0, zx], [0.0, 0.0, 1.0]];
        let k = std::array::from_fn(|i| t_inv[i].map(|v| self.scale[i] * v));
        Some(accelcal_shared::linear::Model4 { u0: self.bias, k })
    }

    /// The full 12-parameter vector in the order of [`PARAM_NAMES`].
    pub fn to_vec(&self) -> [f64; 12] {
        let mut p = [0.0; 12];
        p[0..3].copy_from_slice(&self.alpha);
        p[3..6].copy_from_slice(&self.scale);
        p[6..9].copy_from_slice(&self.bias);
        p[9..12].copy_from_slice(&self.quad);
        p
    }

    /// The model from a full 12-parameter vector in the order of [`PARAM_NAMES`].
    pub fn from_vec(p: &[f64; 12]) -> Self {
        Self {
            alpha: [p[0], p[1], p[2]],
            scale: [p[3], p[4], p[5]],
            bias: [p[6], p[7], p[8]],
            quad: [p[9], p[10], p[11]],
        }
    }
}

fn mat_vec(m: &[[f64; 3]; 3], v: [f64; 3]) -> [f64; 3] {
    std::array::from_fn(|i| m[i][0] * v[0] + m[i][1] * v[1] + m[i][2] * v[2])
}

/// Errors of the gravity-norm fit.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FitError {
    /// Fewer holds than parameters plus one.
    #[error("{holds} holds are too few for {params} parameters (need at least {})", params + 1)]
    TooFewHolds {
        /// Holds given.
        holds: usize,
        /// Parameters of the structure.
        params: usize,
    },
    /// The gravity magnitude is not a positive finite number.
    #[error("gravity magnitude {0} is not positive")]
    BadGravity(f64),
    /// A hold mean is not finite.
    #[error("hold {0} has a non-finite mean")]
    NonFinite(usize),
    /// The hold means do not spread along an axis, so its scale cannot be estimated.
    #[error("hold means do not vary along axis {axis}: place the block in more orientations")]
    NoSpread {
        /// Axis name.
        axis: char,
    },
    /// The solver did not converge.
    #[error("the least-squares solver did not converge ({0})")]
    NotConverged(String),
    /// `JᵀJ` is singular at the solution: the holds do not determine all parameters.
    #[error("the holds do not determine all parameters (singular normal matrix)")]
    Singular,
}

impl Classify for FitError {
    fn kind(&self) -> Kind {
        Kind::BadInput
    }
}

/// Result of a gravity-norm fit.
#[derive(Debug, Clone)]
pub struct GravityFit {
    /// Structure fitted.
    pub structure: GravityStructure,
    /// Gravity magnitude used, in m/s².
    pub g: f64,
    /// Fitted parameters (inactive ones are zero, or identity for `T`).
    pub model: TriadModel,
    /// Standard errors of the parameters, same layout (zero for inactive ones).
    pub std_err: TriadModel,
    /// Covariance of the active parameters in natural units, in the order of [`GravityStructure::active`].
    pub covariance: DMatrix<f64>,
    /// Residual `|a| − g` per hold, in m/s².
    pub residuals: Vec<f64>,
    /// Root mean square of the residuals, in m/s².
    pub rms: f64,
    /// Residual standard deviation `sqrt(Σr² / (holds − parameters))`, in m/s².
    pub sigma: f64,
    /// Solver termination reason.
    pub termination: String,
    /// Number of residual evaluations by the solver.
    pub evaluations: usize,
}

/// Residual `|a| − g` for every hold mean under `model`.
pub fn residuals(model: &TriadModel, means: &[[f64; 3]], g: f64) -> Vec<f64> {
    means.iter().map(|&u| norm(model.apply(u)) - g).collect()
}

fn norm(a: [f64; 3]) -> f64 {
    (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt()
}

/// Residual and its gradient with respect to the full 12-parameter vector, for one hold.
fn residual_and_gradient(p: &[f64; 12], u: [f64; 3], g: f64) -> (f64, [f64; 12]) {
    let m = TriadModel::from_vec(p);
    let t = m.misalignment();
    let v: [f64; 3] = std::array::from_fn(|i| (u[i] - m.bias[i]) / m.scale[i]);
    let w: [f64; 3] = std::array::from_fn(|i| v[i] + m.quad[i] * v[i] * v[i]);
    let a = mat_vec(&t, w);
    let na = norm(a);
    let n: [f64; 3] = a.map(|x| x / na);
    let mut grad = [0.0; 12];
    grad[0] = -n[0] * w[1];
    grad[1] = n[0] * w[2];
    grad[2] = -n[1] * w[2];
    for i in 0..3 {
        // n · T[:, i]
        let nt = n[0] * t[0][i] + n[1] * t[1][i] + n[2] * t[2][i];
        let dw_dv = 1.0 + 2.0 * m.quad[i] * v[i];
        grad[3 + i] = nt * dw_dv * (-v[i] / m.scale[i]);
        grad[6 + i] = nt * dw_dv * (-1.0 / m.scale[i]);
        grad[9 + i] = nt * v[i] * v[i];
    }
    (na - g, grad)
}

/// Initial guess from the hold means: min/max per axis, refined by an axis-aligned ellipsoid.
pub fn initial_guess(means: &[[f64; 3]], g: f64) -> Result<TriadModel, FitError> {
    let mut bias = [0.0; 3];
    let mut scale = [0.0; 3];
    for (i, axis) in ['x', 'y', 'z'].into_iter().enumerate() {
        let lo = means.iter().map(|u| u[i]).fold(f64::INFINITY, f64::min);
        let hi = means.iter().map(|u| u[i]).fold(f64::NEG_INFINITY, f64::max);
        if !(hi - lo > 0.0) {
            return Err(FitError::NoSpread { axis });
        }
        bias[i] = 0.5 * (hi + lo);
        scale[i] = (hi - lo) / (2.0 * g);
    }
    let coarse = TriadModel { bias, scale, alpha: [0.0; 3], quad: [0.0; 3] };
    Ok(ellipsoid_refine(&coarse, means, g).unwrap_or(coarse))
}

/// Fits the axis-aligned quadric `Σ p_i z_i² + Σ c_i z_i = 1` (z in m/s² under the coarse model, so
/// the origin lies inside the ellipsoid and the constant term can be normalised to −1) and converts
/// it to bias and scale. Returns `None` if the system is ill-posed, the quadric is not an ellipsoid,
/// or the result fits the holds worse than the coarse guess.
fn ellipsoid_refine(coarse: &TriadModel, means: &[[f64; 3]], g: f64) -> Option<TriadModel> {
    if means.len() < 7 {
        return None;
    }
    let z: Vec<[f64; 3]> =
        means.iter().map(|u| std::array::from_fn(|i| (u[i] - coarse.bias[i]) / coarse.scale[i])).collect();
    let a = DMatrix::from_fn(z.len(), 6, |k, j| if j < 3 { z[k][j] * z[k][j] } else { z[k][j - 3] });
    let rhs = DVector::from_element(z.len(), 1.0);
    let svd = a.svd(true, true);
    let sv = &svd.singular_values;
    if !(sv.min() > 1e-9 * sv.max()) {
        return None;
    }
    let sol = svd.solve(&rhs, 0.0).ok()?;
    let p = [sol[0], sol[1], sol[2]];
    if p.iter().any(|&x| !(x > 0.0)) {
        return None;
    }
    let center: [f64; 3] = std::array::from_fn(|i| -sol[3 + i] / (2.0 * p[i]));
    // Σ p (z − c)² = 1 + Σ p c² =: k
    let k = 1.0 + (0..3).map(|i| p[i] * center[i] * center[i]).sum::<f64>();
    let mut m = *coarse;
    for i in 0..3 {
        m.bias[i] = coarse.bias[i] + coarse.scale[i] * center[i];
        // ((z − c)/σ)² with 1/σ² = p g² / k, z in units of the coarse scale.
        m.scale[i] = coarse.scale[i] * (k / (p[i] * g * g)).sqrt();
    }
    let ss = |model: &TriadModel| residuals(model, means, g).iter().map(|r| r * r).sum::<f64>();
    let finite = m.bias.iter().chain(&m.scale).all(|x| x.is_finite());
    (finite && ss(&m) < ss(coarse)).then_some(m)
}

/// Fits `structure` to the hold means `means` (codes) under gravity magnitude `g` (m/s²).
pub fn fit(means: &[[f64; 3]], g: f64, structure: GravityStructure) -> Result<GravityFit, FitError> {
    if !(g.is_finite() && g > 0.0) {
        return Err(FitError::BadGravity(g));
    }
    if let Some(k) = means.iter().position(|u| u.iter().any(|x| !x.is_finite())) {
        return Err(FitError::NonFinite(k));
    }
    let active = structure.active();
    let n = active.len();
    if means.len() <= n {
        return Err(FitError::TooFewHolds { holds: means.len(), params: n });
    }
    let start = initial_guess(means, g)?;
    let theta0 = start.to_vec();
    // Natural parameter k = theta0[k] + step[k] · x.
    let step: [f64; 12] = std::array::from_fn(|k| match k {
        3..=5 => start.scale[k - 3],
        6..=8 => start.scale[k - 6],
        9..=11 => 1.0 / g,
        _ => 1.0,
    });
    let to_theta = |x: &[f64]| {
        let mut th = theta0;
        for (j, &k) in active.iter().enumerate() {
            th[k] = theta0[k] + step[k] * x[j];
        }
        th
    };
    let eval = |x: &[f64]| {
        let th = to_theta(x);
        if th[3..6].iter().any(|&s| !(s.abs() > 0.0)) {
            return None;
        }
        let mut r = Vec::with_capacity(means.len());
        let mut j = Vec::with_capacity(means.len() * n);
        for &u in means {
            let (res, grad) = residual_and_gradient(&th, u, g);
            r.push(res);
            j.extend(active.iter().map(|&k| grad[k] * step[k]));
        }
        Some((r, j))
    };
    let sol = solver::minimize(&vec![0.0; n], means.len(), &eval);
    if !sol.converged {
        return Err(FitError::NotConverged(sol.termination));
    }
    let theta = to_theta(&sol.x);
    let model = TriadModel::from_vec(&theta);
    let res = residuals(&model, means, g);
    let rss: f64 = res.iter().map(|r| r * r).sum();
    let dof = (means.len() - n) as f64;
    let sigma = (rss / dof).sqrt();
    let jac = DMatrix::from_fn(means.len(), n, |row, col| {
        residual_and_gradient(&theta, means[row], g).1[active[col]]
    });
    let covariance = covariance(&jac, sigma * sigma).ok_or(FitError::Singular)?;
    let mut se = [0.0; 12];
    for (j, &k) in active.iter().enumerate() {
        se[k] = covariance[(j, j)].max(0.0).sqrt();
    }
    Ok(GravityFit {
        structure,
        g,
        model,
        std_err: TriadModel::from_vec(&se),
        covariance,
        rms: (rss / means.len() as f64).sqrt(),
        residuals: res,
        sigma,
        termination: sol.termination,
        evaluations: sol.evaluations,
    })
}

/// `σ² (JᵀJ)⁻¹`, computed with column equilibration so that parameters of very different magnitude
/// (codes and radians) do not spoil the conditioning; `None` if `JᵀJ` is numerically singular.
fn covariance(jac: &DMatrix<f64>, sigma2: f64) -> Option<DMatrix<f64>> {
    let n = jac.ncols();
    let norms: Vec<f64> = (0..n).map(|c| jac.column(c).norm()).collect();
    if norms.iter().any(|&x| !(x > 0.0)) {
        return None;
    }
    let scaled = DMatrix::from_fn(jac.nrows(), n, |r, c| jac[(r, c)] / norms[c]);
    let jtj = scaled.transpose() * &scaled;
    let svd = jtj.clone().svd(false, false);
    let smax = svd.singular_values.max();
    let smin = svd.singular_values.min();
    if !(smin > smax * 1e-13) {
        return None;
    }
    let inv = jtj.cholesky()?.inverse();
    Some(DMatrix::from_fn(n, n, |i, j| sigma2 * inv[(i, j)] / (norms[i] * norms[j])))
}

/// Score of one structure in the GMDH-style selection.
#[derive(Debug, Clone, PartialEq)]
pub struct StructureScore {
    /// The structure.
    pub structure: GravityStructure,
    /// RMS of `|a| − g` when fitted on all holds, in m/s².
    pub fit_rms: f64,
    /// RMS of `|a| − g` on withheld holds (fit on even holds, test on odd, and the reverse), in m/s²;
    /// `None` if a half has too few holds for this structure or its fit fails.
    pub cv_rms: Option<f64>,
}

/// Scores every structure: fit on all holds, and the external criterion of GMDH, the residual on
/// holds withheld from the fit (alternate holds: even-indexed ones predict odd-indexed ones and the
/// reverse). See [`select`] for the choice.
pub fn score_structures(means: &[[f64; 3]], g: f64) -> Vec<StructureScore> {
    let even: Vec<[f64; 3]> = means.iter().step_by(2).copied().collect();
    let odd: Vec<[f64; 3]> = means.iter().skip(1).step_by(2).copied().collect();
    GravityStructure::ALL
        .iter()
        .filter_map(|&s| {
            let full = fit(means, g, s).ok()?;
            let cv = (|| {
                let a = fit(&even, g, s).ok()?;
                let b = fit(&odd, g, s).ok()?;
                let ss: f64 = residuals(&a.model, &odd, g)
                    .iter()
                    .chain(&residuals(&b.model, &even, g))
                    .map(|r| r * r)
                    .sum();
                Some((ss / means.len() as f64).sqrt())
            })();
            Some(StructureScore { structure: s, fit_rms: full.rms, cv_rms: cv })
        })
        .collect()
}

/// Relative margin by which a richer structure must beat a simpler one on withheld holds.
pub const PARSIMONY: f64 = 0.05;

/// The selected structure: the simplest one whose withheld-hold RMS is within [`PARSIMONY`] (5 %) of
/// the smallest, so that an extra term must earn its place by a clear reduction of the external
/// criterion, not by a tie; `None` if no structure could be scored.
pub fn select(scores: &[StructureScore]) -> Option<GravityStructure> {
    let best = scores.iter().filter_map(|s| s.cv_rms).min_by(f64::total_cmp)?;
    GravityStructure::ALL.into_iter().find(|st| {
        scores.iter().any(|s| s.structure == *st && s.cv_rms.is_some_and(|cv| cv <= best * (1.0 + PARSIMONY)))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    const G: f64 = 9.81;

    fn truth() -> TriadModel {
        TriadModel {
            bias: [33100.0, 33300.0, 32900.0],
            scale: [1680.0, 1650.0, 1700.0],
            alpha: [2e-3, -4e-3, 1.5e-3],
            quad: [0.0; 3],
        }
    }

    /// Exact hold means for well-spread directions (a Fibonacci sphere), no noise.
    fn exact_means(m: &TriadModel, n: usize) -> Vec<[f64; 3]> {
        (0..n)
            .map(|k| {
                let z = 1.0 - 2.0 * (k as f64 + 0.5) / n as f64;
                let r = (1.0 - z * z).sqrt();
                let phi = k as f64 * 2.399_963_229_728_653;
                m.raw_from_specific_force([G * r * phi.cos(), G * r * phi.sin(), G * z]).unwrap()
            })
            .collect()
    }

    #[test]
    fn model4_is_the_same_calibration_and_quadratic_has_none() {
        let m = truth();
        let cal = m.model4().unwrap().invert().unwrap();
        for u in exact_means(&m, 12) {
            let (want, got) = (m.apply(u), cal.apply(u));
            for i in 0..3 {
                assert!((got[i] - want[i]).abs() < 1e-12 * G, "{got:?} {want:?}");
            }
        }
        // u = u0 + K·a is the forward model itself.
        let a = [3.0, -7.0, 5.5];
        let (u, k) = (m.raw_from_specific_force(a).unwrap(), m.model4().unwrap());
        for i in 0..3 {
            let fwd = k.u0[i] + (0..3).map(|j| k.k[i][j] * a[j]).sum::<f64>();
            assert!((fwd - u[i]).abs() < 1e-9, "{fwd} {}", u[i]);
        }
        let mut q = m;
        q.quad[1] = 1e-4;
        assert!(q.model4().is_none());
    }

    #[test]
    fn apply_inverts_raw_from_specific_force() {
        let mut m = truth();
        m.quad = [1e-3, -2e-3, 5e-4];
        let a = [3.0, -7.0, 5.5];
        let u = m.raw_from_specific_force(a).unwrap();
        let back = m.apply(u);
        for i in 0..3 {
            assert!((back[i] - a[i]).abs() < 1e-9, "{back:?}");
        }
    }

    #[test]
    fn analytic_gradient_matches_finite_differences() {
        let mut m = truth();
        m.quad = [1e-3, -2e-3, 5e-4];
        let p = m.to_vec();
        let u = [34000.0, 31000.0, 36000.0];
        let (_, grad) = residual_and_gradient(&p, u, G);
        for k in 0..12 {
            let h = 1e-6 * p[k].abs().max(1e-3);
            let (mut pp, mut pm) = (p, p);
            pp[k] += h;
            pm[k] -= h;
            let fd = (residual_and_gradient(&pp, u, G).0 - residual_and_gradient(&pm, u, G).0) / (2.0 * h);
            assert!(
                (fd - grad[k]).abs() <= 1e-6 * grad[k].abs().max(1e-6),
                "{}: {fd} vs {}",
                PARAM_NAMES[k],
                grad[k]
            );
        }
    }

    #[test]
    fn recovers_exact_parameters_from_noise_free_holds() {
        let t = truth();
        let fit = fit(&exact_means(&t, 24), G, GravityStructure::ImuTk).unwrap();
        for i in 0..3 {
            assert!((fit.model.bias[i] - t.bias[i]).abs() < 1e-6);
            assert!((fit.model.scale[i] / t.scale[i] - 1.0).abs() < 1e-10);
            assert!((fit.model.alpha[i] - t.alpha[i]).abs() < 1e-10);
        }
        assert!(fit.rms < 1e-9, "rms {}", fit.rms);
    }

    #[test]
    fn selection_prefers_the_simpler_structure_on_a_tie() {
        let sc = |structure, cv| StructureScore { structure, fit_rms: 0.0, cv_rms: Some(cv) };
        let scores = [
            sc(GravityStructure::BiasScale, 0.07),
            sc(GravityStructure::ImuTk, 0.00058),
            sc(GravityStructure::ImuTkQuadratic, 0.00057),
        ];
        assert_eq!(select(&scores), Some(GravityStructure::ImuTk));
        let scores = [
            sc(GravityStructure::BiasScale, 0.07),
            sc(GravityStructure::ImuTk, 0.0006),
            sc(GravityStructure::ImuTkQuadratic, 0.0005),
        ];
        assert_eq!(select(&scores), Some(GravityStructure::ImuTkQuadratic));
        assert_eq!(select(&[]), None);
    }

    #[test]
    fn ellipsoid_refinement_lands_near_the_truth() {
        // Axis-aligned truth: the quadric fit is exact, so the refined guess is the truth.
        let t = TriadModel { alpha: [0.0; 3], ..truth() };
        let means = exact_means(&t, 20);
        let m = initial_guess(&means, G).unwrap();
        for i in 0..3 {
            assert!((m.bias[i] - t.bias[i]).abs() < 1e-6, "{m:?}");
            assert!((m.scale[i] / t.scale[i] - 1.0).abs() < 1e-9, "{m:?}");
        }
    }

    #[test]
    fn too_few_holds_and_no_spread_are_errors() {
        let means = exact_means(&truth(), 9);
        assert_eq!(
            fit(&means, G, GravityStructure::ImuTk).unwrap_err(),
            FitError::TooFewHolds { holds: 9, params: 9 }
        );
        let flat = vec![[1.0, 2.0, 3.0]; 12];
        assert_eq!(fit(&flat, G, GravityStructure::ImuTk).unwrap_err(), FitError::NoSpread { axis: 'x' });
        assert_eq!(fit(&means, -1.0, GravityStructure::BiasScale).unwrap_err(), FitError::BadGravity(-1.0));
    }

    #[test]
    fn gmdh_prefers_the_quadratic_structure_only_when_the_truth_has_it() {
        let mut t = truth();
        t.quad = [3e-3, -2e-3, 2.5e-3];
        let scores = score_structures(&exact_means(&t, 30), G);
        assert_eq!(select(&scores), Some(GravityStructure::ImuTkQuadratic), "{scores:?}");
        // Without a quadratic term, misalignment must still beat the bias+scale structure.
        let scores = score_structures(&exact_means(&truth(), 30), G);
        let cv = |s| scores.iter().find(|x| x.structure == s).unwrap().cv_rms.unwrap();
        assert!(cv(GravityStructure::ImuTk) < 0.1 * cv(GravityStructure::BiasScale), "{scores:?}");
    }
}
