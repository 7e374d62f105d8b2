//! Weighted least squares on dwell means, with standard errors and the problem's condition.
//!
//! The fit is by SVD of the weighted design matrix; a model whose smallest singular value falls
//! below the threshold is not identifiable on the plan, and the error names the terms that cannot
//! be separated.

use accelcal_shared::Structure;
use nalgebra::{DMatrix, DVector};

use crate::error::{Classify, Kind};
use crate::positions::{ChannelStats, Positions};

/// Relative singular-value threshold below which a model counts as not identifiable: the
/// design matrix (columns scaled to unit RMS) must have `σ_min / σ_max > RANK_TOL`.
pub const RANK_TOL: f64 = 1e-9;

/// Why a least-squares fit was refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum LsqError {
    /// Fewer positions than terms.
    #[error("{terms} terms ({model}) need at least {terms} positions, the plan has {positions}: at most {positions} of them can be identified")]
    TooFewPositions {
        /// The model's terms, comma-separated.
        model: String,
        /// Terms in the model.
        terms: usize,
        /// Positions available.
        positions: usize,
    },
    /// The design matrix is rank deficient on this plan.
    #[error("model not identifiable on this plan: {} cannot be separated", .terms.join(", "))]
    Unidentifiable {
        /// Terms involved in the rank deficiency.
        terms: Vec<String>,
    },
}

impl Classify for LsqError {
    fn kind(&self) -> Kind {
        Kind::BadInput
    }
}

/// A fitted model of one channel.
#[derive(Clone, Debug)]
pub struct LsqFit {
    /// The model's terms.
    pub structure: Structure,
    /// Coefficients in term order: codes, codes per (m/s²)ⁿ.
    pub coefficients: Vec<f64>,
    /// Covariance matrix of the coefficients, row by row in term order (NaN where a coefficient's
    /// uncertainty is unknown: no residual degrees of freedom, an axis test turns cannot reach).
    pub covariance: Vec<Vec<f64>>,
    /// Condition number of the design matrix with its columns scaled to unit RMS.
    pub condition: f64,
    /// RMS residual over the rows used, codes.
    pub rms: f64,
    /// Residual degrees of freedom (rows − terms).
    pub dof: f64,
}

impl LsqFit {
    /// One-sigma standard errors of the coefficients, in term order: the square roots of the
    /// covariance matrix's diagonal.
    pub fn std_errors(&self) -> Vec<f64> {
        (0..self.covariance.len()).map(|c| self.covariance[c][c].sqrt()).collect()
    }

    /// Model output (codes) at `x = [ax, ay, az, t]` (see [`Positions::x`]).
    pub fn eval(&self, x: [f64; 4]) -> f64 {
        self.structure.terms().zip(&self.coefficients).map(|(t, c)| c * t.eval(x)).sum()
    }
}

/// Fits `structure` to one channel on the positions `subset` (all when `None`), weighting each
/// dwell mean by its row count.
pub fn fit(
    pos: &Positions,
    ch: &ChannelStats,
    structure: Structure,
    subset: Option<&[usize]>,
) -> Result<LsqFit, LsqError> {
    let all: Vec<usize>;
    let idx = match subset {
        Some(s) => s,
        None => {
            all = (0..pos.len()).collect();
            &all
        }
    };
    let terms: Vec<_> = structure.terms().collect();
    let (n, k) = (idx.len(), terms.len());
    if n < k {
        let model = terms.iter().map(|t| t.to_string()).collect::<Vec<_>>().join(",");
        return Err(LsqError::TooFewPositions { model, terms: k, positions: n });
    }
    // Rows scaled by sqrt(weight); columns scaled to unit RMS for the conditioning.
    let mut x = DMatrix::from_fn(n, k, |r, c| pos.weight[idx[r]].sqrt() * terms[c].eval(pos.x(idx[r])));
    let y = DVector::from_fn(n, |r, _| pos.weight[idx[r]].sqrt() * ch.mean[idx[r]]);
    let wsum: f64 = idx.iter().map(|&i| pos.weight[i]).sum();
    let mut scale = vec![1.0; k];
    for c in 0..k {
        let rms = (x.column(c).norm_squared() / wsum).sqrt();
        scale[c] = if rms > 0.0 { rms } else { 1.0 };
        x.column_mut(c).scale_mut(1.0 / scale[c]);
    }
    let svd = x.clone().svd(true, true);
    let smax = svd.singular_values.max();
    let smin = svd.singular_values.min();
    if !(smin > RANK_TOL * smax) {
        let v_t = svd.v_t.as_ref().expect("V requested");
        let mut involved = vec![false; k];
        for (s, row) in svd.singular_values.iter().zip(v_t.row_iter()) {
            if !(*s > RANK_TOL * smax) {
                for c in 0..k {
                    involved[c] |= row[c].abs() > 0.05;
                }
            }
        }
        let terms = terms.iter().zip(involved).filter(|(_, i)| *i).map(|(t, _)| t.to_string()).collect();
        return Err(LsqError::Unidentifiable { terms });
    }
    let beta_s = svd.solve(&y, 0.0).expect("U and V requested");
    let resid = &y - &x * &beta_s;
    let within: f64 = idx.iter().map(|&i| ch.within_ss[i]).sum();
    let sse = resid.norm_squared() + within;
    let dof = wsum - k as f64;
    let sigma2 = if dof > 0.0 { sse / dof } else { f64::NAN };
    // Cov(β_s) = σ² V Σ⁻² Vᵀ, and β = D⁻¹ β_s with D the column scales.
    let v_t = svd.v_t.as_ref().expect("V requested");
    let covariance: Vec<Vec<f64>> = (0..k)
        .map(|c| {
            (0..k)
                .map(|d| {
                    let s: f64 = (0..k)
                        .map(|s| {
                            v_t[(s, c)] * v_t[(s, d)] / (svd.singular_values[s] * svd.singular_values[s])
                        })
                        .sum();
                    sigma2 * s / (scale[c] * scale[d])
                })
                .collect()
        })
        .collect();
    let coefficients = (0..k).map(|c| beta_s[c] / scale[c]).collect();
    Ok(LsqFit { structure, coefficients, covariance, condition: smax / smin, rms: (sse / wsum).sqrt(), dof })
}

/// Parses a comma-separated term list (`ax,ay,az`); the intercept is always added.
pub fn parse_terms(list: &str) -> Result<Structure, String> {
    let mut mask = 1u32;
    for name in list.split(',').map(str::trim).filter(|s| !s.is_empty()) {
        let t = accelcal_shared::Term::parse(name).map_err(|e| format!("term `{name}`: {e}"))?;
        let i = t.index().ok_or_else(|| format!("term `{name}` is not in the cubic basis"))?;
        mask |= 1 << i;
    }
    Ok(Structure::from_mask(mask))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::{self, effects, SimConfig, ThermalPlan};

    /// The covariance equals σ²·(XᵀWX)⁻¹ computed from the normal equations, term by term, for a
    /// thermal model on a noisy thermal campaign; its diagonal is the squared standard errors.
    #[test]
    fn covariance_is_sigma2_times_the_inverse_normal_matrix() {
        let cfg = SimConfig {
            seed: 3,
            samples: 50,
            effects: vec![effects::parse("temperature=bias:3,scale:100").unwrap()],
            thermal: Some("-10,20,50:0:0".parse::<ThermalPlan>().unwrap()),
            ..SimConfig::default()
        };
        let (c, _) = sim::simulate(&cfg);
        let pos = Positions::new(&c, cfg.g);
        let structure = parse_terms("ax,ay,az,t,ax*t,ay*t,az*t").unwrap();
        for ch in pos.channel_stats(&c) {
            let f = fit(&pos, &ch, structure, None).unwrap();
            let terms: Vec<_> = structure.terms().collect();
            let k = terms.len();
            let n = pos.len();
            let x = DMatrix::from_fn(n, k, |r, j| terms[j].eval(pos.x(r)));
            let w = DMatrix::from_diagonal(&DVector::from_iterator(n, pos.weight.iter().copied()));
            let inv = (x.transpose() * w * &x).try_inverse().unwrap();
            let wsum: f64 = pos.weight.iter().sum();
            let sigma2 = f.rms * f.rms * wsum / f.dof;
            for a in 0..k {
                for b in 0..k {
                    let want = sigma2 * inv[(a, b)];
                    let scale = (sigma2 * inv[(a, a)] * inv[(b, b)] * sigma2).sqrt();
                    assert!(
                        (f.covariance[a][b] - want).abs() <= 1e-7 * scale,
                        "{}: cov({}, {}) = {} vs {want}",
                        ch.name,
                        terms[a],
                        terms[b],
                        f.covariance[a][b]
                    );
                }
                assert_eq!(f.std_errors()[a], f.covariance[a][a].sqrt());
            }
            // Off the diagonal it matters: the bias and its temperature coefficient covary.
            let se = f.std_errors();
            assert!(f.covariance[0][4].abs() > 0.1 * se[0] * se[4], "{}", ch.name);
        }
    }
}
