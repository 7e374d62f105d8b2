//! Statistical process control of the line: the individuals and moving-range (I-MR) chart and
//! the Western Electric rules (Montgomery, *Introduction to Statistical Quality Control*, §6.4
//! and §5.3.6; Western Electric, *Statistical Quality Control Handbook*, 1956).
//!
//! For individuals `x_1 … x_n` in time order: the moving ranges `MR_i = |x_i − x_{i−1}|`, the
//! centre line `x̄`, the process standard deviation estimated as `σ̂ = MR̄ / d2` (`d2 = 1.128`, two
//! observations per range), the individuals' limits `x̄ ± 3σ̂`, and the moving range's upper
//! limit `D4·MR̄` (`D4 = 3.267`). The limits are those of the points charted (phase I). The
//! rules, in zones of `σ̂` about `x̄`: 1, a point beyond 3σ̂; 2, two of three consecutive points
//! beyond 2σ̂ on the same side; 3, four of five consecutive beyond 1σ̂ on the same side; 4, eight
//! consecutive on the same side of the centre line.

use serde::Serialize;

/// `d2` for ranges of two observations.
pub const D2: f64 = 1.128;
/// `D4` for ranges of two observations.
pub const D4: f64 = 3.267;

/// The I-MR chart's lines.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct ImrLimits {
    /// Centre line, `x̄`.
    pub center: f64,
    /// `σ̂ = MR̄ / d2`.
    pub sigma: f64,
    /// Upper control limit, `x̄ + 3σ̂`.
    pub ucl: f64,
    /// Lower control limit, `x̄ − 3σ̂`.
    pub lcl: f64,
    /// Mean moving range.
    pub mr_bar: f64,
    /// The moving range's upper limit, `D4·MR̄`.
    pub mr_ucl: f64,
}

/// A point that breaks a rule.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Violation {
    /// The Western Electric rule, 1 to 4 (5: a moving range beyond `D4·MR̄`).
    pub rule: u8,
    /// The point (from 0) at which the rule is broken.
    pub index: usize,
    /// The rule in words.
    pub what: &'static str,
}

/// Violations per point (rules 1 to 5 together, [`ImrLimits::violations`]) on a chart of
/// independent normal values whose limits come from its own points, by the chart's size:
/// measured by the unit test `the_chance_rate_is_what_in_control_charts_show` on 2 million
/// simulated points per size. Each rule counts every point that completes it, so a run of nine
/// on one side is two violations of rule 4.
pub const CHANCE_RATE: [(usize, f64); 4] = [(30, 0.0172), (70, 0.0218), (300, 0.0245), (2700, 0.0254)];

/// The violations an in-control chart of `n` points shows by chance ([`CHANCE_RATE`], linear
/// in log n between its sizes, held at its ends): at a line's volume a chart with about this
/// many violations is not out of control for having them.
pub fn violations_by_chance(n: usize) -> f64 {
    let ln = (n.max(1) as f64).ln();
    let rate = match CHANCE_RATE.iter().position(|&(m, _)| m >= n) {
        Some(0) => CHANCE_RATE[0].1,
        None => CHANCE_RATE[CHANCE_RATE.len() - 1].1,
        Some(i) => {
            let ((a, ra), (b, rb)) = (CHANCE_RATE[i - 1], CHANCE_RATE[i]);
            let t = (ln - (a as f64).ln()) / ((b as f64).ln() - (a as f64).ln());
            ra + t * (rb - ra)
        }
    };
    rate * n as f64
}

impl ImrLimits {
    /// The limits of `x` (at least two points; `None` otherwise or when a value is not finite).
    pub fn of(x: &[f64]) -> Option<ImrLimits> {
        if x.len() < 2 || x.iter().any(|v| !v.is_finite()) {
            return None;
        }
        let center = x.iter().sum::<f64>() / x.len() as f64;
        let mr_bar = x.windows(2).map(|w| (w[1] - w[0]).abs()).sum::<f64>() / (x.len() - 1) as f64;
        let sigma = mr_bar / D2;
        Some(ImrLimits {
            center,
            sigma,
            ucl: center + 3.0 * sigma,
            lcl: center - 3.0 * sigma,
            mr_bar,
            mr_ucl: D4 * mr_bar,
        })
    }

    /// The points of `x` that break a rule, in time order (each rule named at the point that
    /// completes it). No rule applies when `σ̂` is 0.
    pub fn violations(&self, x: &[f64]) -> Vec<Violation> {
        let mut out = Vec::new();
        if self.sigma <= 0.0 {
            return out;
        }
        let z: Vec<f64> = x.iter().map(|v| (v - self.center) / self.sigma).collect();
        // `count` of the last `window` points (ending at i) beyond `zone` σ̂ on one side.
        let beyond = |i: usize, window: usize, count: usize, zone: f64| -> bool {
            if i + 1 < window {
                return false;
            }
            let w = &z[i + 1 - window..=i];
            let up = w.iter().filter(|&&v| v > zone).count();
            let down = w.iter().filter(|&&v| v < -zone).count();
            // The point itself must be one of them, on that side.
            (up >= count && z[i] > zone) || (down >= count && z[i] < -zone)
        };
        for i in 0..z.len() {
            if z[i].abs() > 3.0 {
                out.push(Violation { rule: 1, index: i, what: "a point beyond 3σ" });
            } else if beyond(i, 3, 2, 2.0) {
                out.push(Violation { rule: 2, index: i, what: "two of three beyond 2σ on one side" });
            } else if beyond(i, 5, 4, 1.0) {
                out.push(Violation { rule: 3, index: i, what: "four of five beyond 1σ on one side" });
            } else if beyond(i, 8, 8, 0.0) {
                out.push(Violation {
                    rule: 4,
                    index: i,
                    what: "eight in a row on one side of the centre line",
                });
            }
            if i > 0 && (x[i] - x[i - 1]).abs() > self.mr_ucl {
                out.push(Violation { rule: 5, index: i, what: "a moving range beyond D4·MR̄" });
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_limits_follow_the_moving_range() {
        // Moving ranges 2, 2, 2, 2: MR̄ = 2, σ̂ = 2/1.128.
        let x = [10.0, 12.0, 10.0, 12.0, 10.0];
        let l = ImrLimits::of(&x).unwrap();
        assert_eq!((l.center, l.mr_bar), (10.8, 2.0));
        assert!((l.sigma - 2.0 / 1.128).abs() < 1e-12);
        assert!((l.ucl - (10.8 + 6.0 / 1.128)).abs() < 1e-12 && (l.mr_ucl - 6.534).abs() < 1e-12);
        assert!(l.violations(&x).is_empty());
        assert_eq!(ImrLimits::of(&[1.0]), None);
        assert_eq!(ImrLimits::of(&[1.0, f64::NAN]), None);
    }

    #[test]
    fn the_chance_rate_is_what_in_control_charts_show() {
        use rand::SeedableRng;
        use rand_distr::{Distribution, Normal};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
        let nd = Normal::new(0.0, 1.0).unwrap();
        for (n, rate) in CHANCE_RATE {
            let (mut count, mut points) = (0, 0);
            for _ in 0..(2_000_000 / n) {
                let x: Vec<f64> = (0..n).map(|_| nd.sample(&mut rng)).collect();
                count += ImrLimits::of(&x).unwrap().violations(&x).len();
                points += n;
            }
            let seen = count as f64 / points as f64;
            assert!((seen / rate - 1.0).abs() < 0.02, "{n} points: {seen} per point, stated {rate}");
        }
        assert_eq!(violations_by_chance(10), 0.172);
        assert!((violations_by_chance(2700) - 68.58).abs() < 1e-9);
        assert!((violations_by_chance(100_000) - 2540.0).abs() < 1e-9);
        let mid = violations_by_chance(140) / 140.0;
        assert!(mid > 0.0218 && mid < 0.0245, "{mid}");
    }

    #[test]
    fn each_rule_is_named_where_it_is_broken() {
        let l = ImrLimits { center: 0.0, sigma: 1.0, ucl: 3.0, lcl: -3.0, mr_bar: 1.128, mr_ucl: 100.0 };
        let rules = |x: &[f64]| l.violations(x).into_iter().map(|v| (v.rule, v.index)).collect::<Vec<_>>();
        assert_eq!(rules(&[0.0, 3.5, 0.0]), [(1, 1)]);
        assert_eq!(rules(&[0.0, 2.5, 0.0, 2.5]), [(2, 3)]);
        assert_eq!(rules(&[0.0, -2.5, -2.2]), [(2, 2)]);
        // Two beyond 2σ on opposite sides break nothing.
        assert!(rules(&[2.5, -2.5, 0.0]).is_empty());
        assert_eq!(rules(&[1.5, 1.5, 0.0, 1.5, 1.5]), [(3, 4)]);
        let eight = [0.5; 8];
        assert_eq!(rules(&eight), [(4, 7)]);
        assert_eq!(rules(&[0.5; 7]), []);
        let tight = ImrLimits { mr_ucl: 1.0, ..l };
        assert_eq!(tight.violations(&[0.0, 1.5]).iter().map(|v| v.rule).collect::<Vec<_>>(), [5]);
    }
}
