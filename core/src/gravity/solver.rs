//! Thin adapter around the `levenberg-marquardt` crate (MINPACK-style Levenberg–Marquardt).
//!
//! The crate's latest release (0.15) is built on nalgebra 0.34 while the rest of accelcal uses nalgebra
//! 0.35, so this file is the only place that touches the 0.34 copy (`nalgebra_lm`): the problem is
//! handed over as plain slices, and nothing of nalgebra 0.34 leaks out. When a release of
//! `levenberg-marquardt` on nalgebra 0.35 appears, only this file and one line of `Cargo.toml` change.

use levenberg_marquardt::{LeastSquaresProblem, LevenbergMarquardt};
use nalgebra_lm::{DMatrix, DVector, Dyn, Owned};

/// Residuals and Jacobian at a parameter vector: `(r, J)` with `J` row-major, `r.len()` rows and
/// `x.len()` columns. Returning `None` marks the point as invalid (the solver then stops).
pub(crate) type Evaluate<'a> = dyn Fn(&[f64]) -> Option<(Vec<f64>, Vec<f64>)> + 'a;

/// Outcome of a minimisation.
#[derive(Debug, Clone)]
pub(crate) struct Solution {
    /// Parameters at the end.
    pub x: Vec<f64>,
    /// Whether the solver reports convergence (as opposed to a usage error or evaluation failure).
    pub converged: bool,
    /// The solver's termination reason, as text.
    pub termination: String,
    /// Number of residual evaluations.
    pub evaluations: usize,
}

struct Problem<'a> {
    x: DVector<f64>,
    m: usize,
    eval: &'a Evaluate<'a>,
}

impl LeastSquaresProblem<f64, Dyn, Dyn> for Problem<'_> {
    type ResidualStorage = Owned<f64, Dyn>;
    type JacobianStorage = Owned<f64, Dyn, Dyn>;
    type ParameterStorage = Owned<f64, Dyn>;

    fn set_params(&mut self, x: &DVector<f64>) {
        self.x.copy_from(x);
    }

    fn params(&self) -> DVector<f64> {
        self.x.clone()
    }

    fn residuals(&self) -> Option<DVector<f64>> {
        let (r, _) = (self.eval)(self.x.as_slice())?;
        (r.len() == self.m && r.iter().all(|v| v.is_finite())).then(|| DVector::from_vec(r))
    }

    fn jacobian(&self) -> Option<DMatrix<f64>> {
        let n = self.x.len();
        let (_, j) = (self.eval)(self.x.as_slice())?;
        (j.len() == self.m * n && j.iter().all(|v| v.is_finite()))
            .then(|| DMatrix::from_row_slice(self.m, n, &j))
    }
}

/// Minimises `½‖r(x)‖²` from `x0`, for `m` residuals.
pub(crate) fn minimize(x0: &[f64], m: usize, eval: &Evaluate<'_>) -> Solution {
    let problem = Problem { x: DVector::from_column_slice(x0), m, eval };
    let (problem, report) = LevenbergMarquardt::new()
        .with_ftol(1e-14)
        .with_xtol(1e-14)
        .with_gtol(1e-14)
        .with_patience(200)
        .minimize(problem);
    Solution {
        x: problem.x.as_slice().to_vec(),
        converged: report.termination.was_successful(),
        termination: format!("{:?}", report.termination),
        evaluations: report.number_of_evaluations,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fits_an_exponential_decay() {
        // y = 3 exp(-0.7 t), sampled exactly: the solver must recover (3, 0.7).
        let ts: Vec<f64> = (0..20).map(|k| k as f64 * 0.25).collect();
        let ys: Vec<f64> = ts.iter().map(|t| 3.0 * (-0.7 * t).exp()).collect();
        let eval = |x: &[f64]| {
            let mut r = Vec::new();
            let mut j = Vec::new();
            for (t, y) in ts.iter().zip(&ys) {
                let e = (-x[1] * t).exp();
                r.push(x[0] * e - y);
                j.extend([e, -x[0] * t * e]);
            }
            Some((r, j))
        };
        let sol = minimize(&[1.0, 0.1], ts.len(), &eval);
        assert!(sol.converged, "{}", sol.termination);
        assert!((sol.x[0] - 3.0).abs() < 1e-9 && (sol.x[1] - 0.7).abs() < 1e-9, "{:?}", sol.x);
    }

    #[test]
    fn invalid_evaluation_stops_without_panic() {
        let eval = |_: &[f64]| None;
        let sol = minimize(&[1.0], 3, &eval);
        assert!(!sol.converged);
    }
}
