//! The dwell scatter: how much noise each dwell mean carries, evaluated from the samples within
//! the dwells, and what the dwell means scatter about the fit beyond that noise and the head's
//! stated errors.
//!
//! A dwell mean of `m` samples carries the samples' noise over `m`: per channel the samples'
//! variance pooled over the dwells, `s² = Σ within_ss / Σ(m − 1)` (JCGM 100 4.2.3, 4.2.4), a
//! Type A evaluation on `Σ(m − 1)` degrees of freedom, thousands on any plan. The dwell means'
//! scatter about the fit (`n − 4` degrees of freedom) is then a check of the rest: under that
//! noise and the head's stated angle errors the stacked residuals `r` of the three channels are
//! Gaussian with a known covariance `C`, so `rᵀr` has the mean `tr C` and the standard deviation
//! `√(2·tr C²)`. What `rᵀr` holds above the value noise alone stays below with the probability
//! [`super::lack_of_fit::LEVEL`] ([`super::lack_of_fit::noise_limit`], as for the quadratic
//! terms) (after what
//! the realised references explain: the head's rotation as this head has it, model 4's lack of
//! fit) is an error the stated values miss (samples correlated in time, a head worse than its
//! certificate, a drift) and is counted too, as before, from the dwell means on `n − 4`.
//!
//! The samples' variance includes their rounding to whole codes (1/12 code² when the noise spans
//! several codes); the budget's quantisation part counts it once more, which is conservative by
//! at most 1/12 code² per sample. The channels' noise is taken as independent: their
//! within-dwell covariance is not kept, and a common part shows in the residuals' check.
//!
//! Where the dwells hold a single sample each (a campaign of dwell means), there is nothing to
//! pool and the dwell means' scatter is the whole Type A evaluation, as it always was.

use nalgebra::{DMatrix, DVector};

use crate::positions::ChannelStats;

use super::lack_of_fit::noise_limit;

/// The samples' noise within the dwells, per axis row.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Within {
    /// Per axis (x, y, z rows), the pooled variance of one sample, codes².
    pub var_codes2: [f64; 3],
    /// Its degrees of freedom, `Σ(m − 1)` over the dwells.
    pub dof: f64,
}

impl Within {
    /// Pools each channel's scatter within its dwells; `order` are the channels of the x, y and z
    /// rows, `weight` the samples per dwell. `None` when no dwell has two samples.
    pub fn pooled(stats: &[ChannelStats], order: [usize; 3], weight: &[f64]) -> Option<Within> {
        let dof: f64 = weight.iter().map(|w| w - 1.0).filter(|&d| d > 0.0).sum();
        if !(dof >= 1.0) {
            return None;
        }
        let var_codes2 = order.map(|ci| stats[ci].within_ss.iter().sum::<f64>() / dof);
        var_codes2.iter().all(|v| v.is_finite()).then_some(Within { var_codes2, dof })
    }

    /// The covariance of the dwell means of axis rows `p` and `q` at one position, codes²: the
    /// samples' noise over the dwell's `samples` (rows independent), and the head's stated angle
    /// variance `angle_var` (rad²) through `response`, that position's output per radian of each
    /// head angle (α, β) on each row. Independent across positions.
    pub fn mean_cov(
        &self,
        p: usize,
        q: usize,
        samples: f64,
        response: &[[f64; 2]; 3],
        angle_var: f64,
    ) -> f64 {
        let noise = if p == q { self.var_codes2[p] / samples.max(1.0) } else { 0.0 };
        noise + angle_var * (response[p][0] * response[q][0] + response[p][1] * response[q][1])
    }
}

/// The residuals' check against what is stated.
pub struct Check<'a> {
    /// `I − X·A`, n × n.
    pub resid_maker: &'a DMatrix<f64>,
    /// Samples per dwell.
    pub weight: &'a [f64],
    /// The dwell means' residuals about the fit, per axis row.
    pub resid: &'a [DVector<f64>],
    /// Per position, per axis row, per head angle (α, β): the output one radian of that angle's
    /// setting error adds, codes.
    pub angle_response: &'a [[[f64; 2]; 3]],
    /// The stated head angle variance, rad².
    pub angle_var: f64,
    /// What realised references explain of the residuals' sum of squares, codes².
    pub realised: f64,
}

impl Check<'_> {
    /// The fraction of the residuals' sum of squares that the samples' noise `within` and the
    /// stated references do not account for beyond [`noise_limit`] of their mean and spread: 0
    /// when the residuals are what they should be.
    pub fn excess_fraction(&self, within: &Within) -> f64 {
        let n = self.weight.len();
        let observed: f64 = self.resid.iter().map(|v| v.norm_squared()).sum();
        if !(observed > 0.0) {
            return 0.0;
        }
        // The dwell means' errors are independent across positions: channels p and q covary by
        // the diagonal S_pq = δ_pq·s_p²·W⁻¹ + u_θ²·Σ_a diag(d_p,a ∘ d_q,a), and the residuals'
        // blocks are C_pq = R·S_pq·Rᵀ. With G = RᵀR: tr C = Σ_p Σ_i S_pp,i·G_ii and
        // tr C² = Σ_pq Σ_ij S_pq,i·S_pq,j·G_ij² (no 3n × 3n product needed).
        let g = self.resid_maker.transpose() * self.resid_maker;
        let s = |p: usize, q: usize, i: usize| {
            within.mean_cov(p, q, self.weight[i], &self.angle_response[i], self.angle_var)
        };
        let mean: f64 = (0..3).map(|p| (0..n).map(|i| s(p, p, i) * g[(i, i)]).sum::<f64>()).sum();
        let mut square = 0.0;
        for p in 0..3 {
            for q in 0..3 {
                let v: Vec<f64> = (0..n).map(|i| s(p, q, i)).collect();
                for i in 0..n {
                    for j in 0..n {
                        square += v[i] * v[j] * g[(i, j)] * g[(i, j)];
                    }
                }
            }
        }
        let excess = observed - self.realised - noise_limit(mean, square);
        (excess / observed).clamp(0.0, 1.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The residuals' covariance built whole, 3n × 3n: `(I₃ ⊗ R)·S·(I₃ ⊗ R)ᵀ`.
    fn dense(check: &Check, within: &Within) -> DMatrix<f64> {
        let n = check.weight.len();
        let r = check.resid_maker;
        let mut s = DMatrix::zeros(3 * n, 3 * n);
        for p in 0..3 {
            for q in 0..3 {
                for i in 0..n {
                    let d = &check.angle_response[i];
                    let noise = if p == q { within.var_codes2[p] / check.weight[i] } else { 0.0 };
                    s[(p * n + i, q * n + i)] =
                        noise + check.angle_var * (d[p][0] * d[q][0] + d[p][1] * d[q][1]);
                }
            }
        }
        let mut big_r = DMatrix::zeros(3 * n, 3 * n);
        for p in 0..3 {
            big_r.view_mut((p * n, p * n), (n, n)).copy_from(r);
        }
        &big_r * s * big_r.transpose()
    }

    #[test]
    fn the_residuals_check_is_the_dense_covariance_s_mean_and_spread() {
        let n = 9;
        // Rows [1, ax, ay, az] of a few orientations, unequal dwells.
        let x = DMatrix::from_fn(n, 4, |i, t| match t {
            0 => 1.0,
            _ => ((i * 7 + t * 3) as f64 * 0.71).sin(),
        });
        let weight: Vec<f64> = (0..n).map(|i| 50.0 + 10.0 * i as f64).collect();
        let w = DMatrix::from_diagonal(&DVector::from_column_slice(&weight));
        let xtw = x.transpose() * &w;
        let a = (&xtw * &x).try_inverse().unwrap() * &xtw;
        let resid_maker = DMatrix::identity(n, n) - &x * &a;
        let angle_response: Vec<[[f64; 2]; 3]> = (0..n)
            .map(|i| [0, 1, 2].map(|p| [((i + p) as f64).cos() * 3000.0, ((i * p) as f64).sin() * 3000.0]))
            .collect();
        let within = Within { var_codes2: [6400.0, 3600.0, 4900.0], dof: 500.0 };
        let angle_var = (20.0 * super::super::ARCSEC).powi(2);
        // Residuals whose sum of squares is the dense covariance's noise limit plus `extra`
        // spreads.
        let make = |extra: f64| {
            let check = Check {
                resid_maker: &resid_maker,
                weight: &weight,
                resid: &[],
                angle_response: &angle_response,
                angle_var,
                realised: 0.0,
            };
            let c = dense(&check, &within);
            let spread = (2.0 * c.norm_squared()).sqrt();
            let target = noise_limit(c.trace(), c.norm_squared()) + extra * spread;
            let unit = DVector::from_element(n, (target / (3 * n) as f64).sqrt());
            vec![unit.clone(), unit.clone(), unit]
        };
        let check_with = |resid: &[DVector<f64>]| {
            Check {
                resid_maker: &resid_maker,
                weight: &weight,
                resid,
                angle_response: &angle_response,
                angle_var,
                realised: 0.0,
            }
            .excess_fraction(&within)
        };
        // At the noise limit exactly nothing is left over; below it nothing; above it, the part
        // beyond the limit out of the whole.
        let at = make(0.0);
        assert!(check_with(&at).abs() < 1e-9, "{}", check_with(&at));
        assert_eq!(check_with(&make(-0.5)), 0.0);
        let over = make(2.0);
        let observed: f64 = over.iter().map(|v| v.norm_squared()).sum();
        let baseline: f64 = at.iter().map(|v| v.norm_squared()).sum();
        let want = (observed - baseline) / observed;
        assert!((check_with(&over) - want).abs() < 1e-9, "{} {want}", check_with(&over));
    }

    #[test]
    fn dwells_of_one_sample_pool_nothing() {
        let stats = vec![ChannelStats { name: "x".into(), mean: vec![0.0; 3], within_ss: vec![0.0; 3] }; 3];
        assert_eq!(Within::pooled(&stats, [0, 1, 2], &[1.0, 1.0, 1.0]), None);
        let stats: Vec<ChannelStats> = (0..3)
            .map(|c| ChannelStats {
                name: c.to_string(),
                mean: vec![0.0; 2],
                within_ss: vec![10.0 * (c + 1) as f64; 2],
            })
            .collect();
        let w = Within::pooled(&stats, [2, 0, 1], &[3.0, 3.0]).unwrap();
        assert_eq!(w.dof, 4.0);
        assert_eq!(w.var_codes2, [15.0, 5.0, 10.0]);
    }
}
