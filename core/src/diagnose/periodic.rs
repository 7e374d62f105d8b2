//! Where the gap lies beyond position and dwell: a periodogram of each channel's dwell residuals
//! against time (is there a disturbance periodic in time?) and the correlation of the residuals
//! across channels (is the residual common to all channels?).
//!
//! **Periodogram.** The positions' times are unevenly spaced in general, so the periodogram is a
//! weighted least-squares sine fit (a floating-mean Lomb–Scargle periodogram): at each frequency
//! `f` of a grid, `r(t) = c + a·cos 2πft + b·sin 2πft` is fitted to the dwell residuals with
//! weights `n/σ²`, and its χ² is compared with that of the constant alone. The grid runs from one
//! cycle over the campaign (`1/T`) to half the median rate of positions, in steps of
//! `1/(OVERSAMPLE·T)`; the best grid point is refined by a golden-section search between its
//! neighbours. **Significance**: at one frequency, the sine's two parameters are tested against
//! the rest of the residual by an F test, `F = (Δχ²/2) / (χ²_sine/(N − 3))`, whose chance of
//! exceeding its value under the null (no sine) is `(1 + 2F/(N − 3))^(−(N − 3)/2)`. Because the
//! largest over the grid was picked, the false-alarm probability is `1 − (1 − p)^M`, with `M` the
//! number of independent frequencies taken as `max(N, (f_max − f_min)·T)` (with uneven times the
//! peaks are more independent than the width `1/T` suggests; `M = N` brought 300 white series of
//! the unit test from 10 to 3 of 300 below a false alarm of 1%). The test is against the rest
//! of the residual, not against the white noise alone, so a large residual that is not periodic
//! does not make every period significant; but a position effect on a plan that repeats its
//! orientations at a steady rate is periodic in time, and is found as such. A period is *significant* when its false-alarm probability is below
//! [`FALSE_ALARM`].
//!
//! **Common mode.** For each pair of channels, the Pearson correlation `r` of their dwell
//! residuals over the positions, with `z = atanh(r)·√(N − 3)` (Fisher's transform; about N(0, 1)
//! when the residuals are independent). The residual is *common to all channels* when every pair
//! has `|z| >` [`super::NOISE_Z`] with the same sign of `r` as the first pair, i.e. one
//! disturbance moves every channel.

use serde::Serialize;

use super::{golden_min, NOISE_Z};

/// Grid steps per independent frequency.
pub const OVERSAMPLE: f64 = 10.0;

/// False-alarm probability below which a period is reported as significant.
pub const FALSE_ALARM: f64 = 0.01;

/// The strongest period of one channel's dwell residuals.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Period {
    /// Period of the best-fitting sine, s.
    pub period_s: f64,
    /// Its amplitude (half the peak-to-peak), codes.
    pub amplitude_codes: f64,
    /// Whether the data resolve that amplitude ([`amplitude_resolved`]): false when the sine
    /// reaches it only between the positions' times (uneven times let a long period fit with an
    /// amplitude far above anything measured, even above the ADC's range), so it is not reported.
    pub amplitude_resolved: bool,
    /// Probability that white residuals give a peak this high anywhere on the grid.
    pub false_alarm: f64,
    /// Whether `false_alarm` is below [`FALSE_ALARM`].
    pub significant: bool,
    /// Shortest and longest period searched, s.
    pub searched_s: (f64, f64),
}

/// Weighted fit of `c + a·cos + b·sin` at frequency `f`; returns (χ², a, b).
fn sine_fit(t: &[f64], y: &[f64], w: &[f64], f: f64) -> Option<(f64, f64, f64)> {
    let mut g = [[0.0; 3]; 3];
    let mut rhs = [0.0; 3];
    for ((&t, &y), &w) in t.iter().zip(y).zip(w) {
        let (s, c) = (2.0 * std::f64::consts::PI * f * t).sin_cos();
        let x = [1.0, c, s];
        for i in 0..3 {
            rhs[i] += w * x[i] * y;
            for j in 0..3 {
                g[i][j] += w * x[i] * x[j];
            }
        }
    }
    let m = nalgebra::Matrix3::from_fn(|i, j| g[i][j]);
    let beta = m.try_inverse()? * nalgebra::Vector3::from(rhs);
    let chi2 = t
        .iter()
        .zip(y)
        .zip(w)
        .map(|((&t, &y), &w)| {
            let (s, c) = (2.0 * std::f64::consts::PI * f * t).sin_cos();
            w * (y - beta[0] - beta[1] * c - beta[2] * s).powi(2)
        })
        .sum();
    Some((chi2, beta[1], beta[2]))
}

/// The strongest period of residuals `y` (codes) at times `t` (s) with variances `var` (codes²);
/// `None` with fewer than 6 points or no time span.
pub fn strongest_period(t: &[f64], y: &[f64], var: &[f64]) -> Option<Period> {
    let n = t.len();
    if n < 6 {
        return None;
    }
    let w: Vec<f64> = var.iter().map(|v| 1.0 / v).collect();
    let sw: f64 = w.iter().sum();
    let mean = y.iter().zip(&w).map(|(y, w)| y * w).sum::<f64>() / sw;
    let chi0: f64 = y.iter().zip(&w).map(|(y, w)| w * (y - mean).powi(2)).sum();
    let (t0, t1) = t.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| (a.min(x), b.max(x)));
    let span = t1 - t0;
    let mut dt: Vec<f64> = t.windows(2).map(|p| (p[1] - p[0]).abs()).filter(|d| *d > 0.0).collect();
    dt.sort_by(f64::total_cmp);
    if !(span > 0.0) || dt.is_empty() || !(chi0 > 0.0) {
        return None;
    }
    let (f_lo, f_hi) = (1.0 / span, 0.5 / dt[dt.len() / 2]);
    if !(f_hi > f_lo) {
        return None;
    }
    // Times from the first position keep the phases well conditioned.
    let tr: Vec<f64> = t.iter().map(|x| x - t0).collect();
    let chi = |f: f64| sine_fit(&tr, y, &w, f).map_or(f64::INFINITY, |r| r.0);
    let step = 1.0 / (OVERSAMPLE * span);
    let grid: Vec<f64> = (0..).map(|i| f_lo + i as f64 * step).take_while(|f| *f <= f_hi).collect();
    let best = grid.iter().copied().min_by(|a, b| chi(*a).total_cmp(&chi(*b)))?;
    let f = golden_min(&chi, (best - step).max(f_lo), (best + step).min(f_hi), 40);
    let (chi1, a, b) = sine_fit(&tr, y, &w, f)?;
    let nu = n as f64 - 3.0;
    let fstat = ((chi0 - chi1).max(0.0) / 2.0) / (chi1 / nu).max(f64::MIN_POSITIVE);
    let p = (1.0 + 2.0 * fstat / nu).powf(-nu / 2.0);
    let m = ((f_hi - f_lo) * span).max(n as f64);
    // 1 − (1 − p)^M, accurate for small p.
    let false_alarm = -(m * (-p).ln_1p()).exp_m1();
    Some(Period {
        period_s: 1.0 / f,
        amplitude_codes: a.hypot(b),
        amplitude_resolved: amplitude_resolved(&tr, f, a, b),
        false_alarm,
        significant: false_alarm < FALSE_ALARM,
        searched_s: (1.0 / f_hi, 1.0 / f_lo),
    })
}

/// The span of every code range the campaigns use (16 bits), codes: no residual of a dwell mean
/// reaches it.
pub const CODE_SPAN: f64 = 65_535.0;

/// Whether a sine `a·cos 2πft + b·sin 2πft` fitted at times `t` has an amplitude the data
/// resolve: its values at the times reach at least half of it (a sine seen over a quarter period
/// or more does), and its peak-to-peak is within the ADC's span ([`CODE_SPAN`]).
pub fn amplitude_resolved(t: &[f64], f: f64, a: f64, b: f64) -> bool {
    let amp = a.hypot(b);
    let seen = t.iter().map(|&t| {
        let (s, c) = (2.0 * std::f64::consts::PI * f * t).sin_cos();
        (a * c + b * s).abs()
    });
    let seen = seen.fold(0.0, f64::max);
    amp.is_finite() && 2.0 * amp <= CODE_SPAN && seen >= 0.5 * amp
}

/// The correlation of two channels' dwell residuals.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Correlation {
    /// The two channels.
    pub channels: (String, String),
    /// Pearson correlation over the positions.
    pub r: f64,
    /// Fisher's `atanh(r)·√(N − 3)`.
    pub z: f64,
}

/// Whether the residual is common to all channels.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct CommonMode {
    /// Every pair of channels.
    pub pairs: Vec<Correlation>,
    /// Every pair correlated beyond the noise, with one sign: one disturbance moves every channel.
    pub common: bool,
}

/// The common-mode test on dwell residuals `resid[channel][position]`; `None` with fewer than
/// two channels or four positions.
pub fn common_mode(names: &[String], resid: &[Vec<f64>]) -> Option<CommonMode> {
    let n = resid.first()?.len();
    if resid.len() < 2 || n < 4 {
        return None;
    }
    let centred: Vec<Vec<f64>> = resid
        .iter()
        .map(|r| {
            let m = r.iter().sum::<f64>() / n as f64;
            r.iter().map(|x| x - m).collect()
        })
        .collect();
    let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>();
    let mut pairs = Vec::new();
    for i in 0..resid.len() {
        for j in i + 1..resid.len() {
            let den = (dot(&centred[i], &centred[i]) * dot(&centred[j], &centred[j])).sqrt();
            let r = if den > 0.0 { (dot(&centred[i], &centred[j]) / den).clamp(-1.0, 1.0) } else { 0.0 };
            let z = r.clamp(-0.999_999_9, 0.999_999_9).atanh() * (n as f64 - 3.0).sqrt();
            pairs.push(Correlation { channels: (names[i].clone(), names[j].clone()), r, z });
        }
    }
    let sign = pairs[0].r.signum();
    let common = pairs.iter().all(|p| p.z.abs() > NOISE_Z && p.r.signum() == sign);
    Some(CommonMode { pairs, common })
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;
    use rand_distr::{Distribution, Normal};

    /// Uneven times: positions 3 to 6 s apart.
    fn times(n: usize) -> Vec<f64> {
        (0..n).scan(0.0, |t, i| Some(std::mem::replace(t, *t + 3.0 + (i * 7 % 4) as f64))).collect()
    }

    #[test]
    fn a_sine_in_noise_is_found_and_white_noise_is_not_significant() {
        let t = times(80);
        let noise = Normal::new(0.0, 4.0).unwrap();
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let white: Vec<f64> = t.iter().map(|_| noise.sample(&mut rng)).collect();
        let var = vec![16.0; t.len()];
        let p = strongest_period(&t, &white, &var).unwrap();
        assert!(!p.significant, "{p:?}");
        // The false-alarm probability is what it says: on 300 white series, about 1% fall below 1%.
        let false_alarms = (0..300)
            .filter(|_| {
                let w: Vec<f64> = t.iter().map(|_| noise.sample(&mut rng)).collect();
                strongest_period(&t, &w, &var).unwrap().significant
            })
            .count();
        assert!(false_alarms <= 8, "{false_alarms} of 300 white series significant at 1%");
        let sine: Vec<f64> = t
            .iter()
            .zip(&white)
            .map(|(t, e)| e + 10.0 * (2.0 * std::f64::consts::PI * t / 47.0 + 1.0).sin())
            .collect();
        let p = strongest_period(&t, &sine, &var).unwrap();
        assert!(p.significant && p.false_alarm < 1e-6, "{p:?}");
        assert!((p.period_s - 47.0).abs() < 0.02 * 47.0, "{p:?}");
        assert!((p.amplitude_codes - 10.0).abs() < 2.0, "{p:?}");
        assert!(p.amplitude_resolved, "{p:?}");
    }

    #[test]
    fn an_amplitude_the_times_never_see_or_beyond_the_adc_is_not_resolved() {
        // Period 10 s sampled every 5 s from t = 0: a sine of any amplitude is 0 at every time.
        let zeros: Vec<f64> = (0..20).map(|k| 5.0 * k as f64).collect();
        assert!(!amplitude_resolved(&zeros, 0.1, 0.0, 1000.0));
        // Sampled every 2.5 s, it reaches its peaks.
        let quarters: Vec<f64> = (0..20).map(|k| 2.5 * k as f64).collect();
        assert!(amplitude_resolved(&quarters, 0.1, 0.0, 1000.0));
        assert!(amplitude_resolved(&quarters, 0.1, 600.0, 800.0));
        // Peak-to-peak beyond the 16-bit range: not a period of any campaign's residuals.
        assert!(!amplitude_resolved(&quarters, 0.1, 0.0, 40_000.0));
        assert!(!amplitude_resolved(&quarters, 0.1, f64::NAN, 1.0));
    }

    #[test]
    fn a_shared_residual_is_common_and_one_channel_s_is_not() {
        let names: Vec<String> = ["x", "y", "z"].map(String::from).to_vec();
        let noise = Normal::new(0.0, 1.0).unwrap();
        let mut rng = ChaCha8Rng::seed_from_u64(4);
        let shared: Vec<f64> = (0..60).map(|_| 3.0 * noise.sample(&mut rng)).collect();
        let mut own =
            |k: f64| -> Vec<f64> { shared.iter().map(|s| k * s + noise.sample(&mut rng)).collect() };
        let all = [own(1.0), own(1.0), own(1.0)];
        assert!(common_mode(&names, &all).unwrap().common);
        let one = [own(1.0), own(0.0), own(0.0)];
        let c = common_mode(&names, &one).unwrap();
        assert!(!c.common, "{c:?}");
        assert!(c.pairs.iter().all(|p| p.z.abs() < NOISE_Z), "{c:?}");
    }
}
