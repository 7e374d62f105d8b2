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
    /// Mean temperature in each dwell, °C, when the campaign has a `temp_c` column.
    pub temp_c: Option<Vec<f64>>,
    /// Reference temperature of the thermal terms, °C: their `t` is `temp_c − t_ref_c`.
    pub t_ref_c: f64,
}

/// The reference temperature of the thermal terms unless `--t-ref` says otherwise, °C.
pub const T_REF_DEFAULT_C: f64 = 25.0;

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

/// Running statistics of one channel in one dwell: count, mean and sum of squared deviations,
/// accumulated sample by sample (shifted by the first sample, so whole-number codes give exact
/// sums). The in-memory and the streaming readers both use it, so they agree to the last bit.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct DwellAcc {
    n: usize,
    shift: f64,
    s1: f64,
    s2: f64,
}

impl DwellAcc {
    /// Adds one sample.
    pub fn push(&mut self, x: f64) {
        if self.n == 0 {
            self.shift = x;
        }
        let d = x - self.shift;
        self.s1 += d;
        self.s2 += d * d;
        self.n += 1;
    }

    /// Samples added.
    pub fn len(&self) -> usize {
        self.n
    }

    /// Whether no sample was added.
    pub fn is_empty(&self) -> bool {
        self.n == 0
    }

    /// Mean of the samples (NaN when there are none).
    pub fn mean(&self) -> f64 {
        self.shift + self.s1 / self.n as f64
    }

    /// Sum of squared deviations from the mean (zero for a single sample).
    pub fn within_ss(&self) -> f64 {
        if self.n < 2 {
            return 0.0;
        }
        (self.s2 - self.s1 * self.s1 / self.n as f64).max(0.0)
    }
}

impl ChannelStats {
    /// The statistics of one channel from its per-dwell accumulators.
    pub fn from_accs(name: &str, accs: &[DwellAcc]) -> ChannelStats {
        ChannelStats {
            name: name.to_string(),
            mean: accs.iter().map(DwellAcc::mean).collect(),
            within_ss: accs.iter().map(DwellAcc::within_ss).collect(),
        }
    }
}

impl Positions {
    /// Positions of a campaign for gravity `g`, with its dwells' mean temperatures.
    pub fn new(c: &Campaign, g: f64) -> Positions {
        let mut pos = Positions::from_dwells(c.dwells(), g);
        pos.temp_c = c.temp_c.as_ref().map(|t| {
            pos.dwells.iter().map(|d| t[d.start..d.end].iter().sum::<f64>() / d.len() as f64).collect()
        });
        pos
    }

    /// Positions of a list of dwells for gravity `g` (no temperature).
    pub fn from_dwells(dwells: Vec<Dwell>, g: f64) -> Positions {
        let accel = dwells.iter().map(|d| d.accel(g)).collect();
        let weight = dwells.iter().map(|d| d.len() as f64).collect();
        Positions { dwells, accel, weight, g, temp_c: None, t_ref_c: T_REF_DEFAULT_C }
    }

    /// The variables of the model terms at position `p`: `[ax, ay, az, t]` (m/s², and °C from
    /// the reference; NaN without a temperature, which only a term in `t` would read).
    pub fn x(&self, p: usize) -> [f64; 4] {
        let a = self.accel[p];
        let t = self.temp_c.as_ref().map_or(f64::NAN, |t| t[p] - self.t_ref_c);
        [a[0], a[1], a[2], t]
    }

    /// Refuses a structure with terms in `t` when the positions have no temperature: the message
    /// names the term.
    pub fn check_terms(&self, s: accelcal_shared::Structure) -> Result<(), String> {
        match s.terms().find(|t| t.is_thermal()) {
            Some(t) if self.temp_c.is_none() => {
                Err(format!("term `{t}` needs the temperature, and the campaign has no `temp_c` column"))
            }
            _ => Ok(()),
        }
    }

    /// Lowest and highest dwell temperature, °C, when there is a temperature.
    pub fn temp_range(&self) -> Option<(f64, f64)> {
        let t = self.temp_c.as_ref()?;
        let lo = t.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = t.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        (lo <= hi).then_some((lo, hi))
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
                let accs: Vec<DwellAcc> = self
                    .dwells
                    .iter()
                    .map(|d| {
                        let mut acc = DwellAcc::default();
                        ch.codes[d.start..d.end].iter().for_each(|&x| acc.push(x));
                        acc
                    })
                    .collect();
                ChannelStats::from_accs(&ch.name, &accs)
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
