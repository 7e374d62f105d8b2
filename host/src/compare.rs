//! The paper's Table 2: error of the calibrated acceleration after calibration by LSQ and by test
//! turns, on validation positions that neither fit used.
//!
//! Calibrated acceleration: when the channels form a triad (three channels whose sensitive axes
//! are x, y and z), the joint inversion `a = K⁻¹(u − u0)` the node computes; otherwise each channel
//! alone, `a_own = (u − u0 − Σ_{j≠own} k_j·a_j)/k_own`, with the cross-axis components taken from
//! the rig. The error of a channel is its calibrated acceleration along its own axis minus the
//! rig's, over every row of the validation positions.

use accelcal_shared::linear::Model4;
use serde::Serialize;

use crate::campaign::Campaign;
use crate::lsq::LsqFit;

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

/// Per-row calibrated acceleration along each channel's own axis, and the rig's value, for the
/// validation `dwells` (row ranges) of `c`. Returns per channel `(errors)`.
pub fn errors(c: &Campaign, g: f64, fits: &[LsqFit], rows: &[(usize, usize)]) -> (Inversion, Vec<Vec<f64>>) {
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
    let mut out = vec![Vec::new(); fits.len()];
    for &(start, end) in rows {
        for r in start..end {
            let a = accelcal_shared::gravity(c.alpha_deg[r], c.beta_deg[r], g);
            if let Some(cal) = &inv {
                let mut u = [0.0; 3];
                for (ci, &ax) in axes.iter().enumerate() {
                    u[ax] = c.channels[ci].codes[r];
                }
                let ahat = cal.apply(u);
                for (ci, &ax) in axes.iter().enumerate() {
                    out[ci].push(ahat[ax] - a[ax]);
                }
            } else {
                for (ci, f) in fits.iter().enumerate() {
                    let k = &f.coefficients[1..4];
                    let own = axes[ci];
                    let cross: f64 = (0..3).filter(|&j| j != own).map(|j| k[j] * a[j]).sum();
                    let ahat = (c.channels[ci].codes[r] - f.coefficients[0] - cross) / k[own];
                    out[ci].push(ahat - a[own]);
                }
            }
        }
    }
    (if inv.is_some() { Inversion::Triad } else { Inversion::PerChannel }, out)
}

/// Mean and sample standard deviation.
pub fn stats(e: &[f64]) -> ErrorStats {
    let n = e.len() as f64;
    let mean = e.iter().sum::<f64>() / n;
    let var = e.iter().map(|x| (x - mean) * (x - mean)).sum::<f64>() / (n - 1.0).max(1.0);
    ErrorStats { mean_error: mean, std_error: var.sqrt() }
}
