//! The check that the head moved as the plan says (issue 24): each recorded position's mean codes
//! must have moved from the positions before it as much as the plan's commanded gravity moved.
//!
//! Without a calibration the unit's sensitivity is unknown, so the check compares sizes: for a
//! model-4 unit, `m = u0 + K·a`, the change of the mean codes between two positions is
//! `|Δm| = |K·Δa|`, between the smallest and largest singular value of `K` times `|Δa|`. For every
//! earlier position of the same pass (a chamber setpoint changes the offsets) whose commanded
//! gravity differs by at least [`MIN_CHANGE_G`] g, the ratio `|Δm| / |Δa|` (codes per m/s²) must
//! be
//! - at least the smallest plausible sensitivity ([`accelcal_core::calibrate::sensitivity_range`], the
//!   bound `fit --record` holds a record to): a head that was not turned moves the means by the
//!   noise only, tens of times less (issue 24: about 0.8 codes/(m/s²) against 3.3);
//! - within a factor [`RATIO_FACTOR`] of the median ratio of the pairs accepted before (once
//!   there is one): a unit's axes have similar sensitivities (the simulated unit's within 3 %, the
//!   real Xsens unit's within 1 %), so a head turned part of the way, or to another position of
//!   the plan, gives a ratio far from the others.
//!
//! And directions, per channel: where the plan's gravity changed by at least [`MIN_CHANGE_G`] g
//! along a channel's own axis, that channel's mean codes must have moved the same way. Its
//! sensitivity to its own axis is positive (a record with another is refused, `calibrate::gate`)
//! and the cross-axis sensitivities are small beside it, so a position turned to the mirror image
//! of the commanded one (every change of the same size, some of the other sign) is caught. The
//! first position of a pass is the reference.

/// Smallest commanded change of gravity, in g, between two positions that the check compares.
pub const MIN_CHANGE_G: f64 = 0.5;

/// How far a pair's ratio may be from the median of the pairs before it (a factor either way).
pub const RATIO_FACTOR: f64 = 2.0;

/// The positions of the current pass and what they read.
#[derive(Clone, Debug)]
pub struct MotionCheck {
    g: f64,
    /// (commanded acceleration m/s², mean codes, 1-based position number) of the accepted positions.
    seen: Vec<([f64; 3], [f64; 3], usize)>,
    /// Ratios of the accepted pairs, codes per m/s².
    ratios: Vec<f64>,
}

fn dist(a: [f64; 3], b: [f64; 3]) -> f64 {
    (0..3).map(|k| (a[k] - b[k]).powi(2)).sum::<f64>().sqrt()
}

impl MotionCheck {
    /// A check with no position yet, at gravity `g` (m/s²).
    pub fn new(g: f64) -> MotionCheck {
        MotionCheck { g, seen: Vec::new(), ratios: Vec::new() }
    }

    /// Forgets the positions (a new chamber setpoint begins a new pass).
    pub fn reset(&mut self) {
        self.seen.clear();
        self.ratios.clear();
    }

    fn median_ratio(&self) -> Option<f64> {
        let mut r = self.ratios.clone();
        r.sort_by(f64::total_cmp);
        (!r.is_empty()).then(|| r[r.len() / 2])
    }

    /// The ratios of position (`a`, `m`) with every earlier position far enough from it.
    fn pairs(&self, a: [f64; 3], m: [f64; 3]) -> impl Iterator<Item = (usize, f64, f64)> + '_ {
        let min = MIN_CHANGE_G * self.g;
        self.seen.iter().filter_map(move |&(ai, mi, i)| {
            let da = dist(a, ai);
            (da >= min).then(|| (i, da, dist(m, mi) / da))
        })
    }

    /// Whether the position commanded to read `a` (m/s²) that read mean codes `m` moved as the
    /// plan says from the accepted positions; why not, naming the earlier position.
    pub fn check(&self, a: [f64; 3], m: [f64; 3]) -> Result<(), String> {
        self.check_sizes(a, m)?;
        self.check_directions(a, m)
    }

    /// Each channel's mean moved the way its own axis's commanded gravity did (where that changed
    /// by at least [`MIN_CHANGE_G`] g).
    fn check_directions(&self, a: [f64; 3], m: [f64; 3]) -> Result<(), String> {
        let min = MIN_CHANGE_G * self.g;
        for &(ai, mi, i) in &self.seen {
            for (c, name) in ["x", "y", "z"].iter().enumerate() {
                let (da, dm) = (a[c] - ai[c], m[c] - mi[c]);
                if da.abs() >= min && dm * da <= 0.0 {
                    return Err(format!(
                        "channel {name}'s mean codes moved {dm:+.1} codes from position {i}'s, where the plan's gravity \
                         along {name} changed by {da:+.2} m/s²: the other way; is the head turned the other way (the \
                         mirror image of this position)?"
                    ));
                }
            }
        }
        Ok(())
    }

    /// The sizes of the changes (see the module's documentation).
    fn check_sizes(&self, a: [f64; 3], m: [f64; 3]) -> Result<(), String> {
        let floor = *accelcal_core::calibrate::sensitivity_range(self.g).start();
        let median = self.median_ratio();
        for (i, da, r) in self.pairs(a, m) {
            let moved = r * da;
            let too_small = r < floor || median.is_some_and(|s| r < s / RATIO_FACTOR);
            let too_large = median.is_some_and(|s| r > s * RATIO_FACTOR);
            if too_small || too_large {
                let expected = match median {
                    Some(s) => format!(
                        "about {:.0} codes (the positions so far read {s:.1} codes per m/s² of change)",
                        s * da
                    ),
                    None => {
                        format!("at least {:.0} codes for any unit ({floor:.2} codes per m/s²)", floor * da)
                    }
                };
                return Err(format!(
                    "its mean codes moved {moved:.1} codes from position {i}'s, where the plan's gravity changed by \
                     {da:.2} m/s²: expected {expected}; {}",
                    if too_small {
                        "was the head turned to this position?"
                    } else {
                        "is the head at this position of the plan?"
                    }
                ));
            }
        }
        Ok(())
    }

    /// Adds an accepted position (numbered `number`, 1-based, for messages).
    pub fn accept(&mut self, a: [f64; 3], m: [f64; 3], number: usize) {
        let new: Vec<f64> = self.pairs(a, m).map(|(_, _, r)| r).collect();
        self.ratios.extend(new);
        self.seen.push((a, m, number));
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use accelcal_core::sim::Plan;

    fn unit(a: [f64; 3]) -> [f64; 3] {
        let k = [[1671.2, 8.5, -3.25], [-4.0, 1650.75, 6.5], [2.5, -7.75, 1689.0]];
        let u0 = [32100.5, 33012.25, 31877.75];
        [0, 1, 2].map(|c| u0[c] + (0..3).map(|j| k[c][j] * a[j]).sum::<f64>())
    }

    #[test]
    fn an_unturned_head_is_refused_at_its_second_position() {
        let g = 9.81;
        let plan = Plan::six().positions;
        let a: Vec<[f64; 3]> = plan.iter().map(|&(al, be)| accelcal_shared::gravity(al, be, g)).collect();
        // Turned: every position accepted.
        let mut m = MotionCheck::new(g);
        for (k, &ak) in a.iter().enumerate() {
            m.check(ak, unit(ak)).unwrap_or_else(|e| panic!("position {}: {e}", k + 1));
            m.accept(ak, unit(ak), k + 1);
        }
        // Never turned (the first position's reading, plus a code of noise): the second is refused.
        let mut m = MotionCheck::new(g);
        m.accept(a[0], unit(a[0]), 1);
        let e = m.check(a[1], unit(a[0]).map(|v| v + 1.0)).unwrap_err();
        assert!(e.starts_with("its mean codes moved 1.7 codes from position 1's, where the plan's gravity changed by 19.62 m/s²: expected at least 66 codes"), "{e}");
        // Turned to the first position again instead of the third: refused against the first.
        m.accept(a[1], unit(a[1]), 2);
        let e = m.check(a[2], unit(a[0])).unwrap_err();
        assert!(e.contains("moved 0.0 codes from position 1's"), "{e}");
        // Turned 20° instead of 90°: the change is too small for the ratio seen so far.
        let part = accelcal_shared::gravity(20.0, 0.0, g);
        let e = m.check(a[2], unit(part)).unwrap_err();
        assert!(e.contains("the positions so far read"), "{e}");
        // Turned to the mirror image (270° instead of 90°): every change has the size the plan
        // says, but channel x moved the other way.
        let e = m.check(a[2], unit(a[3])).unwrap_err();
        assert!(e.starts_with("channel x's mean codes moved +16362.6 codes from position 1's, where the plan's gravity along x changed by -9.81 m/s²: the other way"), "{e}");
        // A new pass starts afresh.
        m.reset();
        assert!(m.check(a[2], unit(a[0])).is_ok());
    }
}
