//! The head tracking's charts: what standardises each statistic of a unit, and the CUSUM's
//! decision interval for a false-alarm rate.
//!
//! The angle statistics are standardised by a known variance (the unit's own fit states it)
//! about a reference learned from the head's earlier units with the head certificate's angle
//! uncertainty as its prior: the innovation of a static state (Kalman 1960), which is
//! Quesenberry's Q statistic for a normal mean with known variance (J. Qual. Technol. 23(3),
//! 1991, "SPC Q charts for start-up processes and short or long runs", case II) with a prior. The
//! mount terms vary from unit to unit by the units' own misalignments, a spread no unit states:
//! they are standardised by the mean and standard deviation of the earlier units (Quesenberry's
//! case IV, Hawkins' self-starting CUSUM: J. Qual. Technol. 19(2), 1987), the Student t taken to
//! the normal quantile exactly.

use statrs::distribution::{ContinuousCDF, Normal, StudentsT};

/// Siegmund's approximation of a one-sided CUSUM's average run length (Siegmund, *Sequential
/// Analysis*, 1985, eq. 2.57; Montgomery §9.1.5) for N(`mu`, 1) values, reference value `k`,
/// decision interval `h` (standard deviations).
pub fn average_run_length(k: f64, h: f64, mu: f64) -> f64 {
    let d = mu - k;
    let b = h + 1.166;
    if d.abs() < 1e-9 {
        b * b
    } else {
        ((-2.0 * d * b).exp() + 2.0 * d * b - 1.0) / (2.0 * d * d)
    }
}

/// The decision interval `h` that gives a one-sided CUSUM with reference value `k` an
/// in-control average run length of `arl0` ([`average_run_length`] solved by bisection).
pub fn decision_interval(k: f64, arl0: f64) -> f64 {
    let (mut lo, mut hi) = (0.0, 200.0);
    for _ in 0..100 {
        let mid = 0.5 * (lo + hi);
        if average_run_length(k, mid, 0.0) < arl0 {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

/// The normal quantile of a Student t value `t` with `nu` degrees of freedom, exact (the t's
/// tail probability, then the normal's quantile of it; held within ±40).
pub fn t_to_normal_exact(t: f64, nu: f64) -> f64 {
    let (Ok(td), Ok(n)) = (StudentsT::new(0.0, 1.0, nu), Normal::new(0.0, 1.0)) else {
        return 0.0;
    };
    let tail = td.sf(t.abs());
    let z = if tail <= 0.0 { 40.0 } else { (-n.inverse_cdf(tail)).min(40.0) };
    z.copysign(t)
}

/// For each position of a plan, `1 − h_pp`: the share of a change of the acceleration at that
/// position alone that model 4's least-squares fit leaves in its residual there (`h_pp` the
/// leverage of the regressors `[1, a_x, a_y, a_z]` of the commanded accelerations). The same for
/// every channel and unit on the plan.
pub fn kept_share(plan: &[(f64, f64)], g: f64) -> Vec<f64> {
    let rows: Vec<[f64; 4]> = plan
        .iter()
        .map(|&(a, b)| {
            let v = accelcal_shared::gravity(a, b, g);
            [1.0, v[0], v[1], v[2]]
        })
        .collect();
    let xtx = nalgebra::Matrix4::from_fn(|i, j| rows.iter().map(|r| r[i] * r[j]).sum::<f64>());
    let Some(inv) = xtx.try_inverse() else {
        return vec![1.0; plan.len()];
    };
    rows.iter()
        .map(|r| {
            let x = nalgebra::Vector4::from(*r);
            1.0 - (x.transpose() * inv * x)[(0, 0)]
        })
        .collect()
}

/// A reference learned from units: for an angle statistic the precision-weighted mean with a
/// prior (`w = 1/P0 + Σ 1/v`, `wx = Σ x/v`, the prior's mean 0); for a mount term the plain
/// running mean and standard deviation (Welford 1962).
#[derive(Clone, Copy, Debug, Default)]
pub struct Reference {
    /// Total precision (angle statistics).
    pub w: f64,
    /// Precision-weighted sum (angle statistics).
    pub wx: f64,
    /// Units taken in.
    pub n: f64,
    /// Their running mean.
    pub mean: f64,
    m2: f64,
    /// The sum of their stated variances.
    sum_var: f64,
}

impl Reference {
    /// An empty reference with a prior of variance `p0` about 0 (angle statistics; 0: none).
    pub fn with_prior(p0: f64) -> Reference {
        Reference { w: if p0 > 0.0 { 1.0 / p0 } else { 0.0 }, ..Reference::default() }
    }

    /// Takes in a unit's value `x` with stated variance `v` (0 for a mount term).
    pub fn add(&mut self, x: f64, v: f64) {
        if v > 0.0 {
            self.w += 1.0 / v;
            self.wx += x / v;
        }
        self.n += 1.0;
        self.sum_var += v;
        let d = x - self.mean;
        self.mean += d / self.n;
        self.m2 += d * (x - self.mean);
    }

    /// The sample standard deviation of the values taken in.
    pub fn sd(&self) -> f64 {
        if self.n > 1.0 {
            (self.m2 / (self.n - 1.0)).sqrt()
        } else {
            0.0
        }
    }

    /// The mean stated variance of the values taken in (0 before any).
    pub fn mean_var(&self) -> f64 {
        if self.n > 0.0 {
            self.sum_var / self.n
        } else {
            0.0
        }
    }

    /// The angle statistic's reference mean and its variance `(wx/w, 1/w)`.
    pub fn weighted(&self) -> (f64, f64) {
        if self.w > 0.0 {
            (self.wx / self.w, 1.0 / self.w)
        } else {
            (0.0, f64::INFINITY)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn siegmund_s_run_lengths_and_the_interval_for_one() {
        // Montgomery's table 9.3 (k = 0.5, h = 4, two-sided): ARL0 ≈ 168, twice it one-sided;
        // ARL at a 1σ shift ≈ 8.38.
        assert!((average_run_length(0.5, 4.0, 0.0) - 2.0 * 168.0).abs() < 3.0);
        assert!((average_run_length(0.5, 4.0, 1.0) - 8.38).abs() < 0.05);
        let h = decision_interval(0.5, 336.0);
        assert!((h - 4.0).abs() < 0.01, "{h}");
    }

    #[test]
    fn the_exact_t_to_normal_is_the_identity_in_the_limit_and_keeps_tails() {
        assert!((t_to_normal_exact(1.5, 1e6) - 1.5).abs() < 1e-3);
        // t = 3.182 is the 97.5 % point of t with 3 degrees of freedom.
        assert!((t_to_normal_exact(-3.182, 3.0) + 1.96).abs() < 0.01);
        assert!(t_to_normal_exact(1e9, 3.0) > 8.0);
    }

    #[test]
    fn the_kept_share_sums_to_the_residual_degrees_of_freedom() {
        let plan = crate::sim::Plan::head().positions;
        let keep = kept_share(&plan, 9.81);
        let sum: f64 = keep.iter().sum();
        assert!((sum - (plan.len() as f64 - 4.0)).abs() < 1e-9, "{sum}");
        assert!(keep.iter().all(|k| (0.0..1.0).contains(k)));
    }

    #[test]
    fn a_reference_weights_by_precision_and_shrinks_to_its_prior() {
        let mut r = Reference::with_prior(1.0);
        r.add(2.0, 1.0);
        assert_eq!(r.weighted(), (1.0, 0.5));
        r.add(5.0, 0.5);
        let (m, p) = r.weighted();
        assert!((m - 12.0 / 4.0).abs() < 1e-12 && (p - 0.25).abs() < 1e-12, "{m} {p}");
        assert_eq!((r.n, r.mean), (2.0, 3.5));
    }
}
