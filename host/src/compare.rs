//! The paper's Table 2: error of the calibrated acceleration after calibration by LSQ and by test
//! turns, on validation positions that neither fit used.
//!
//! Calibrated acceleration: when the channels form a triad (three channels whose sensitive axes
//! are x, y and z), the joint inversion `a = K⁻¹(u − u0)` the node computes; otherwise each channel
//! alone, `a_own = (u − u0 − Σ_{j≠own} k_j·a_j)/k_own`, with the cross-axis components taken from
//! the rig. The error of a channel is its calibrated acceleration along its own axis minus the
//! rig's, over every row of the validation positions. The rows are folded in one at a time
//! ([`ErrorAcc`]), so a campaign file can be streamed.

use accelcal_shared::linear::{LinearCal, Model4};
use serde::Serialize;

use crate::lsq::LsqFit;
use crate::positions::DwellAcc;

/// Mean and standard deviation of the acceleration error, m/s².
#[derive(Clone, Copy, Debug, Serialize, PartialEq)]
pub struct ErrorStats {
    /// Mean error, m/s².
    pub mean_error: f64,
    /// Standard deviation of the error, m/s².
    pub std_error: f64,
}

/// How calibrated acceleration is computed from the channels.
#[derive(Clone, Copy, Debug, Serialize, PartialEq, Eq)]
#[serde(rename_all = "kebab-case")]
pub enum Inversion {
    /// Joint `K⁻¹` of a triad.
    Triad,
    /// Each channel alone with the rig's cross-axis components.
    PerChannel,
}

/// Own axis of a fitted model-4 row: the largest |k|.
pub fn own_axis(fit: &LsqFit) -> usize {
    let k = &fit.coefficients[1..4];
    (0..3).max_by(|&a, &b| k[a].abs().total_cmp(&k[b].abs())).expect("three axes")
}

/// Calibrates rows with one model-4 fit per channel.
#[derive(Clone, Debug)]
pub struct Calibrator {
    /// Own axis of each channel.
    axes: Vec<usize>,
    /// Coefficients `[u0, kx, ky, kz]` of each channel.
    coefficients: Vec<[f64; 4]>,
    /// The joint inversion, when the channels form an invertible triad.
    inv: Option<LinearCal>,
}

impl Calibrator {
    /// The calibration of a set of model-4 fits (triad `K⁻¹` when the channels form one).
    pub fn new(fits: &[LsqFit]) -> Calibrator {
        let axes: Vec<usize> = fits.iter().map(own_axis).collect();
        let triad = fits.len() == 3 && {
            let mut s = axes.clone();
            s.sort_unstable();
            s == [0, 1, 2]
        };
        let inv = if triad {
            let mut m = Model4 { u0: [0.0; 3], k: [[0.0; 3]; 3] };
            // Row of K for axis j comes from the channel whose own axis is j.
            for (ci, f) in fits.iter().enumerate() {
                m.u0[axes[ci]] = f.coefficients[0];
                m.k[axes[ci]] = [f.coefficients[1], f.coefficients[2], f.coefficients[3]];
            }
            m.invert().ok()
        } else {
            None
        };
        let coefficients = fits.iter().map(|f| std::array::from_fn(|i| f.coefficients[i])).collect();
        Calibrator { axes, coefficients, inv }
    }

    /// How the calibrated acceleration is computed.
    pub fn inversion(&self) -> Inversion {
        if self.inv.is_some() {
            Inversion::Triad
        } else {
            Inversion::PerChannel
        }
    }

    /// The error of each channel's calibrated acceleration along its own axis, for one row with
    /// raw `codes` where the rig imposes `a`, into `out` (one per channel).
    pub fn errors(&self, a: [f64; 3], codes: &[f64], out: &mut [f64]) {
        if let Some(cal) = &self.inv {
            let mut u = [0.0; 3];
            for (ci, &ax) in self.axes.iter().enumerate() {
                u[ax] = codes[ci];
            }
            let ahat = cal.apply(u);
            for (ci, &ax) in self.axes.iter().enumerate() {
                out[ci] = ahat[ax] - a[ax];
            }
        } else {
            for (ci, c) in self.coefficients.iter().enumerate() {
                let own = self.axes[ci];
                let cross: f64 = (0..3).filter(|&j| j != own).map(|j| c[1 + j] * a[j]).sum();
                out[ci] = (codes[ci] - c[0] - cross) / c[1 + own] - a[own];
            }
        }
    }
}

/// The errors of one channel, folded in row by row: per validation position their sum (in row
/// order) and scatter, and their sum over all rows, so that the rows need not be kept.
#[derive(Clone, Debug, Default)]
pub struct ErrorAcc {
    total: f64,
    sums: Vec<f64>,
    accs: Vec<DwellAcc>,
}

impl ErrorAcc {
    /// Adds the error of one row of validation position `p` (positions numbered from 0 in the
    /// order their rows come).
    pub fn push(&mut self, p: usize, e: f64) {
        if p >= self.accs.len() {
            self.sums.resize(p + 1, 0.0);
            self.accs.resize(p + 1, DwellAcc::default());
        }
        self.total += e;
        self.sums[p] += e;
        self.accs[p].push(e);
    }

    /// Rows added.
    pub fn rows(&self) -> usize {
        self.accs.iter().map(DwellAcc::len).sum()
    }

    /// Mean error at each validation position.
    pub fn per_position(&self) -> Vec<f64> {
        self.sums.iter().zip(&self.accs).map(|(s, a)| s / a.len() as f64).collect()
    }

    /// Mean and sample standard deviation over all rows (the sum of squares pooled from the
    /// positions' scatter and their means' spread).
    pub fn stats(&self) -> ErrorStats {
        let n = self.rows() as f64;
        let mean = self.total / n;
        let ss: f64 = self
            .per_position()
            .iter()
            .zip(&self.accs)
            .map(|(m, a)| a.within_ss() + a.len() as f64 * (m - mean) * (m - mean))
            .sum();
        ErrorStats { mean_error: mean, std_error: (ss / (n - 1.0).max(1.0)).sqrt() }
    }
}
