//! The gap: the baseline's residual localised per channel, per position, over time, inside the
//! dwells, against temperature and against the direction of approach, periodic in time and common
//! to the channels ([`super::periodic`]), with the test of whether
//! it is consistent with white noise, and a simulated twin of the campaign for comparison.
//!
//! **Noise test.** With σ estimated from the within-bin scatter, the bin residuals of a correct
//! baseline give χ² = Σ n·r²/σ² with `dof = bins·channels − parameters`; the residual counts as
//! consistent with the noise when `z = (χ² − dof)/√(2·dof) < 4`.

use accelcal_shared::Structure;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use serde::Serialize;

use super::attribution::full_fit;
use super::periodic::{common_mode, strongest_period, CommonMode, Period};
use super::{zscore, Data, NOISE_Z};
use crate::positions::DwellAcc;

/// Where one channel's residual lies.
#[derive(Clone, Debug, Serialize)]
pub struct ChannelGap {
    /// Channel name.
    pub name: String,
    /// White noise per sample, codes.
    pub sigma: f64,
    /// RMS of the dwell-mean residuals, codes.
    pub rms_position: f64,
    /// The same on the simulated twin (baseline + white noise), codes.
    pub rms_position_sim: f64,
    /// z of the position-level χ² (residual per position/orientation).
    pub z_position: f64,
    /// z of the within-dwell χ² (residual over the time inside each dwell).
    pub z_in_dwell: f64,
    /// Slope of the dwell residual against time, codes/s, and its z.
    pub time_slope: f64,
    /// z of the time slope.
    pub z_time: f64,
    /// Slope against temperature, codes/°C (None without `temp_c`).
    pub temp_slope: Option<f64>,
    /// z of the temperature slope.
    pub z_temp: Option<f64>,
    /// Mean residual approached from below minus from above (sign of the input change), codes.
    pub approach_diff: f64,
    /// z of the approach difference.
    pub z_approach: f64,
    /// Mean of (bin − dwell) residual times the sign of the step, per bin index, codes.
    pub in_dwell_profile: Vec<f64>,
    /// The strongest period of the dwell residuals over time (None with fewer than 6 positions).
    pub period: Option<Period>,
    /// mg (1 mg = 9.80665e-3 m/s²) per code of this channel: one over its model-4 sensitivity
    /// to its sensitive axis (`Data::k`), for giving effect sizes in acceleration; NaN for a
    /// channel with no sensitivity.
    pub mg_per_code: f64,
}

/// One position with a large residual.
#[derive(Clone, Debug, Serialize)]
pub struct PositionGap {
    /// Position index (0-based, file order).
    pub position: usize,
    /// Commanded α, degrees.
    pub alpha_deg: f64,
    /// Commanded β, degrees.
    pub beta_deg: f64,
    /// Dwell residual of each channel, in units of its per-position noise.
    pub z: Vec<f64>,
}

/// The localised gap.
#[derive(Clone, Debug, Serialize)]
pub struct Gap {
    /// Whether the baseline's residual is consistent with white noise.
    pub consistent_with_noise: bool,
    /// χ² of the bin residuals.
    pub chi2: f64,
    /// Its degrees of freedom.
    pub dof: f64,
    /// Its z-score.
    pub z: f64,
    /// z of the same χ² on the simulated twin.
    pub z_sim: f64,
    /// Per channel.
    pub channels: Vec<ChannelGap>,
    /// The five positions with the largest residual.
    pub worst_positions: Vec<PositionGap>,
    /// Dwell residual of every position and channel (codes): `position_residual[ch][pos]`.
    pub position_residual: Vec<Vec<f64>>,
    /// Whether the dwell residual is common to all channels (None with a single channel).
    pub common_mode: Option<CommonMode>,
}

/// Weighted slope of `y` on `x` and its z (σ from the weights).
fn slope(x: &[f64], y: &[f64], var: &[f64]) -> (f64, f64) {
    let w: Vec<f64> = var.iter().map(|v| 1.0 / v).collect();
    let sw: f64 = w.iter().sum();
    let xm = x.iter().zip(&w).map(|(x, w)| x * w).sum::<f64>() / sw;
    let ym = y.iter().zip(&w).map(|(y, w)| y * w).sum::<f64>() / sw;
    let sxx: f64 = x.iter().zip(&w).map(|(x, w)| w * (x - xm) * (x - xm)).sum();
    if !(sxx > 0.0) {
        return (0.0, 0.0);
    }
    let sxy: f64 = x.iter().zip(y).zip(&w).map(|((x, y), w)| w * (x - xm) * (y - ym)).sum();
    let b = sxy / sxx;
    (b, b * sxx.sqrt())
}

/// Localises the residual of `base` on the data.
pub fn localise(d: &Data, base: Structure) -> Option<Gap> {
    let ff = full_fit(d, base, &[])?;
    let nb = d.bins.len();
    let npos = d.npos();
    let nterms = base.terms().count() as f64;
    let n_pos: Vec<f64> = d.dwell_means(&vec![1.0; nb]).iter().map(|_| 0.0).collect();
    let mut n_pos = n_pos;
    for b in &d.bins {
        n_pos[b.pos] += b.n;
    }
    let temp_pos = d.temp.as_ref().map(|t| d.dwell_means(t));
    let twin = twin_rms(d, base, &ff.resid);
    let mut channels = Vec::new();
    let mut position_residual = Vec::new();
    for ch in 0..d.nch() {
        let r = &ff.resid[ch * nb..(ch + 1) * nb];
        let rp = d.dwell_means(r);
        let var: Vec<f64> = n_pos.iter().map(|n| d.sigma[ch] * d.sigma[ch] / n).collect();
        let chi_pos: f64 = rp.iter().zip(&var).map(|(r, v)| r * r / v).sum();
        let chi_in: f64 = (0..nb).map(|i| d.weight(ch, i) * (r[i] - rp[d.bins[i].pos]).powi(2)).sum();
        let (time_slope, z_time) = slope(&d.t_pos, &rp, &var);
        let (temp_slope, z_temp) = match &temp_pos {
            Some(t) => {
                let (s, z) = slope(t, &rp, &var);
                (Some(s), Some(z))
            }
            None => (None, None),
        };
        let (mut up, mut dn) = ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0));
        for p in 0..npos {
            let s = d.step[ch][p];
            let acc = if s > 1e-6 {
                &mut up
            } else if s < -1e-6 {
                &mut dn
            } else {
                continue;
            };
            acc.0 += rp[p];
            acc.1 += 1.0;
            acc.2 += var[p];
        }
        let mean = |a: (f64, f64, f64)| if a.1 > 0.0 { a.0 / a.1 } else { 0.0 };
        let approach_diff = mean(up) - mean(dn);
        let sd = (up.2 / (up.1 * up.1).max(1.0) + dn.2 / (dn.1 * dn.1).max(1.0)).sqrt();
        let nbins = d.bins.iter().map(|b| b.bin + 1).max().unwrap_or(1);
        let mut prof = vec![(0.0, 0.0); nbins];
        for (i, b) in d.bins.iter().enumerate() {
            let s = d.step[ch][b.pos];
            if s.abs() > 1e-6 {
                prof[b.bin].0 += (r[i] - rp[b.pos]) * s.signum();
                prof[b.bin].1 += 1.0;
            }
        }
        channels.push(ChannelGap {
            name: d.channels[ch].clone(),
            sigma: d.sigma[ch],
            rms_position: (rp.iter().map(|r| r * r).sum::<f64>() / npos as f64).sqrt(),
            rms_position_sim: twin.as_ref().map_or(f64::NAN, |t| t.0[ch]),
            z_position: zscore(chi_pos, npos as f64 - nterms),
            z_in_dwell: zscore(chi_in, (nb - npos) as f64),
            time_slope,
            z_time,
            temp_slope,
            z_temp,
            approach_diff,
            z_approach: if sd > 0.0 { approach_diff / sd } else { 0.0 },
            in_dwell_profile: prof.iter().map(|(s, n)| if *n > 0.0 { s / n } else { 0.0 }).collect(),
            period: strongest_period(&d.t_pos, &rp, &var),
            mg_per_code: d.mg_per_code(ch),
        });
        position_residual.push(rp);
    }
    let mut worst: Vec<PositionGap> = (0..npos)
        .map(|p| PositionGap {
            position: p,
            alpha_deg: d.angles[p].0,
            beta_deg: d.angles[p].1,
            z: (0..d.nch()).map(|c| position_residual[c][p] / d.sigma_pos(c, p)).collect(),
        })
        .collect();
    let norm = |g: &PositionGap| g.z.iter().map(|z| z * z).sum::<f64>();
    worst.sort_by(|a, b| norm(b).total_cmp(&norm(a)));
    worst.truncate(5);
    let z = zscore(ff.chi2, ff.dof);
    Some(Gap {
        consistent_with_noise: z < NOISE_Z,
        chi2: ff.chi2,
        dof: ff.dof,
        z,
        z_sim: twin.map_or(f64::NAN, |t| t.1),
        channels,
        worst_positions: worst,
        common_mode: common_mode(&d.channels, &position_residual),
        position_residual,
    })
}

/// Simulates the campaign from the fitted baseline (its prediction per dwell plus white noise of
/// the estimated σ, rounded to codes, for every sample of every bin) and returns the twin's
/// per-channel position RMS and χ² z. The samples are drawn in file order and folded into their
/// bin at once, so the twin needs no rows.
fn twin_rms(d: &Data, base: Structure, resid: &[f64]) -> Option<(Vec<f64>, f64)> {
    let nb = d.bins.len();
    let mut rng = ChaCha8Rng::seed_from_u64(0x7477_696e);
    let mut mean = vec![Vec::with_capacity(nb); d.nch()];
    let mut within = vec![0.0; d.nch()];
    for ch in 0..d.nch() {
        let pred: Vec<f64> =
            d.dwell_means(&(0..nb).map(|i| d.mean[ch][i] - resid[ch * nb + i]).collect::<Vec<_>>());
        let noise = Normal::new(0.0, d.sigma[ch]).ok()?;
        for b in &d.bins {
            let mut acc = DwellAcc::default();
            for _ in 0..b.n as usize {
                acc.push((pred[b.pos] + noise.sample(&mut rng)).round());
            }
            mean[ch].push(acc.mean());
            within[ch] += acc.within_ss();
        }
    }
    let td = d.with_codes(mean, within).ok()?;
    let ff = full_fit(&td, base, &[])?;
    let rms = (0..td.nch())
        .map(|ch| {
            let rp = td.dwell_means(&ff.resid[ch * nb..(ch + 1) * nb]);
            (rp.iter().map(|r| r * r).sum::<f64>() / rp.len() as f64).sqrt()
        })
        .collect();
    Some((rms, zscore(ff.chi2, ff.dof)))
}
