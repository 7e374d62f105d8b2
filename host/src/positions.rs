//! Position-level view of a campaign: the dwells, the acceleration the head imposes in each, and
//! per channel the dwell means and within-dwell sums of squares.
//!
//! The regressors of every model depend on the position only, so for least squares over the rows
//! these are sufficient: the weighted fit on dwell means (weights = rows per dwell) gives the
//! same coefficients as the fit on the rows, and the row residual sum of squares is the weighted
//! sum over means plus the within-dwell sum, which no model can change.

use crate::campaign::{Campaign, Dwell};

/// The dwells of a campaign with their imposed accelerations.
#[derive(Clone, Debug)]
pub struct Positions {
    /// The dwells, in file order.
    pub dwells: Vec<Dwell>,
    /// Apparent acceleration in each dwell, m/s².
    pub accel: Vec<[f64; 3]>,
    /// Rows in each dwell (the least-squares weight).
    pub weight: Vec<f64>,
    /// Gravity used for the kinematics, m/s².
    pub g: f64,
}

/// One channel's dwell statistics.
#[derive(Clone, Debug)]
pub struct ChannelStats {
    /// Channel name.
    pub name: String,
    /// Mean code in each dwell.
    pub mean: Vec<f64>,
    /// Sum of squared deviations from the mean within each dwell, codes².
    pub within_ss: Vec<f64>,
}

impl Positions {
    /// Positions of a campaign for gravity `g`.
    pub fn new(c: &Campaign, g: f64) -> Positions {
        let dwells = c.dwells();
        let accel = dwells.iter().map(|d| d.accel(g)).collect();
        let weight = dwells.iter().map(|d| d.len() as f64).collect();
        Positions { dwells, accel, weight, g }
    }

    /// Number of positions.
    pub fn len(&self) -> usize {
        self.dwells.len()
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.dwells.is_empty()
    }

    /// Dwell statistics of every channel.
    pub fn channel_stats(&self, c: &Campaign) -> Vec<ChannelStats> {
        c.channels
            .iter()
            .map(|ch| {
                let mut mean = Vec::with_capacity(self.len());
                let mut within = Vec::with_capacity(self.len());
                for d in &self.dwells {
                    let xs = &ch.codes[d.start..d.end];
                    let m = xs.iter().sum::<f64>() / xs.len() as f64;
                    mean.push(m);
                    within.push(xs.iter().map(|x| (x - m) * (x - m)).sum());
                }
                ChannelStats { name: ch.name.clone(), mean, within_ss: within }
            })
            .collect()
    }

    /// Index of the first position whose acceleration is `sign·g` along `axis` (and zero on the
    /// other axes, to 1e-9·g), if any.
    pub fn find_axis_position(&self, axis: usize, sign: f64) -> Option<usize> {
        let tol = 1e-9 * self.g;
        self.accel.iter().position(|a| {
            (0..3).all(|j| {
                let want = if j == axis { sign * self.g } else { 0.0 };
                (a[j] - want).abs() <= tol
            })
        })
    }
}
