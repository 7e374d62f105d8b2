//! Static-hold detection: a sliding-window variance detector with a threshold derived from the data.
//!
//! The detector statistic at sample `i` is the sum over the three axes of the sample variance of the
//! raw codes in a centred window of `w` samples (`w` odd, about `window_s` seconds); its unit is codes².
//! Samples whose window is not complete (the first and last `w/2`) get `+∞` and are never static.
//!
//! **Threshold.** Unless the user gives one, the threshold is `threshold_factor × floor`, where the
//! noise floor is the `floor_quantile` quantile (default 0.25) of the detector trace. A multi-position
//! session is static most of the time (it starts with a rest and each hold lasts several seconds, while a
//! hand movement takes one or two), so the lower quartile lies inside the static population whenever at
//! least a quarter of the recording is static; it is then a robust estimate of the white-noise variance
//! sum that needs no knowledge of where the initial rest ends. For white noise the windowed estimate has
//! a relative standard deviation of about `sqrt(2 / (w − 1))` per axis (0.14 for `w` = 101, about 0.08
//! for the three-axis sum), so the default factor 4 puts the threshold some 30 standard deviations above
//! the static level: static windows are never flagged as moving, while a hand movement raises the
//! statistic by orders of magnitude.
//!
//! **Holds.** A hold is a maximal run of consecutive samples whose statistic is below the threshold. The
//! hold's mean is taken over exactly those samples (every one of them is the centre of a quiet window, so
//! half a window of quiet data separates the hold from any movement). A run is rejected if it is shorter
//! than `min_hold_s`, or if the variance of the whole run (summed over the axes) exceeds the threshold,
//! which catches a slow drift that no single window shows.

use crate::error::{Classify, Kind};

/// Settings of the static-hold detector.
#[derive(Debug, Clone, PartialEq)]
pub struct DetectorConfig {
    /// Length of the sliding variance window, in seconds (rounded to an odd number of samples ≥ 3).
    pub window_s: f64,
    /// Shortest accepted hold, in seconds (duration of the run of quiet window centres).
    pub min_hold_s: f64,
    /// Threshold given by the user, in codes²; `None` derives it from the data.
    pub threshold: Option<f64>,
    /// Quantile of the detector trace taken as the noise floor, in (0, 1).
    pub floor_quantile: f64,
    /// Multiple of the noise floor used as the threshold.
    pub threshold_factor: f64,
}

impl Default for DetectorConfig {
    fn default() -> Self {
        Self { window_s: 1.0, min_hold_s: 2.0, threshold: None, floor_quantile: 0.25, threshold_factor: 4.0 }
    }
}

/// An accepted static hold.
#[derive(Debug, Clone, PartialEq)]
pub struct Hold {
    /// Index of the first sample of the hold.
    pub start: usize,
    /// Index one past the last sample of the hold.
    pub end: usize,
    /// Time of the first sample, in seconds.
    pub t_start: f64,
    /// Time of the last sample, in seconds.
    pub t_end: f64,
    /// Mean raw output over the hold, in codes.
    pub mean: [f64; 3],
    /// Standard deviation of the raw output over the hold, in codes.
    pub std: [f64; 3],
}

impl Hold {
    /// Number of samples in the hold.
    pub fn len(&self) -> usize {
        self.end - self.start
    }

    /// Whether the hold has no sample (never the case for a detected hold).
    pub fn is_empty(&self) -> bool {
        self.end == self.start
    }
}

/// Why a quiet run was not accepted as a hold.
#[derive(Debug, Clone, PartialEq)]
pub enum Rejection {
    /// Shorter than the minimum hold duration.
    TooShort {
        /// Duration of the run, in seconds.
        duration_s: f64,
    },
    /// The variance over the whole run exceeds the threshold (slow drift).
    NotStatic {
        /// Variance of the run summed over the axes, in codes².
        variance: f64,
    },
}

impl std::fmt::Display for Rejection {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Rejection::TooShort { duration_s } => write!(f, "too short ({duration_s:.2} s)"),
            Rejection::NotStatic { variance } => {
                write!(f, "not static (run variance {variance:.1} codes²)")
            }
        }
    }
}

/// A quiet run that was rejected.
#[derive(Debug, Clone, PartialEq)]
pub struct RejectedRun {
    /// Index of the first sample of the run.
    pub start: usize,
    /// Index one past the last sample of the run.
    pub end: usize,
    /// Time of the first sample, in seconds.
    pub t_start: f64,
    /// Time of the last sample, in seconds.
    pub t_end: f64,
    /// Why it was rejected.
    pub reason: Rejection,
}

/// Where the threshold came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ThresholdSource {
    /// Derived from the data (`threshold_factor × floor`).
    Data,
    /// Given by the user.
    User,
}

/// Result of the detector: the trace, the threshold and the holds.
#[derive(Debug, Clone)]
pub struct Detection {
    /// Window length in samples (odd).
    pub window: usize,
    /// Median sampling interval of the recording, in seconds.
    pub dt: f64,
    /// Noise floor (quantile of the trace), in codes².
    pub floor: f64,
    /// Threshold used, in codes².
    pub threshold: f64,
    /// Whether the threshold was derived or given.
    pub source: ThresholdSource,
    /// Detector statistic per sample, in codes² (`+∞` where the window is incomplete).
    pub trace: Vec<f64>,
    /// Accepted holds, in time order.
    pub holds: Vec<Hold>,
    /// Rejected quiet runs, in time order.
    pub rejected: Vec<RejectedRun>,
}

/// Errors of the hold detector.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum HoldError {
    /// The recording is shorter than two windows.
    #[error("recording has {samples} samples, fewer than two detector windows ({window} samples each)")]
    TooShort {
        /// Number of samples.
        samples: usize,
        /// Window length in samples.
        window: usize,
    },
    /// The time stamps do not give a positive sampling interval.
    #[error("cannot determine a positive sampling interval from the time stamps")]
    BadSampling,
    /// A setting is out of range.
    #[error("invalid detector setting: {0}")]
    BadConfig(String),
}

impl Classify for HoldError {
    fn kind(&self) -> Kind {
        Kind::BadInput
    }
}

/// Runs the detector on raw codes `codes` sampled at times `t`.
pub fn detect(t: &[f64], codes: &[[f64; 3]], cfg: &DetectorConfig) -> Result<Detection, HoldError> {
    check_config(cfg)?;
    let n = t.len().min(codes.len());
    let dt = median_dt(&t[..n]).ok_or(HoldError::BadSampling)?;
    let window = ((cfg.window_s / dt).round() as usize).max(3) | 1;
    if n < 2 * window {
        return Err(HoldError::TooShort { samples: n, window });
    }
    let trace = variance_trace(&codes[..n], window);
    let floor = quantile(&trace, cfg.floor_quantile);
    let (threshold, source) = match cfg.threshold {
        Some(th) => (th, ThresholdSource::User),
        None => (cfg.threshold_factor * floor, ThresholdSource::Data),
    };
    let mut holds = Vec::new();
    let mut rejected = Vec::new();
    for (start, end) in quiet_runs(&trace, threshold) {
        let (mean, var) = mean_var(&codes[start..end]);
        let duration_s = t[end - 1] - t[start];
        let run_var: f64 = var.iter().sum();
        let reason = if duration_s < cfg.min_hold_s {
            Some(Rejection::TooShort { duration_s })
        } else if run_var > threshold {
            Some(Rejection::NotStatic { variance: run_var })
        } else {
            None
        };
        let (t_start, t_end) = (t[start], t[end - 1]);
        match reason {
            Some(reason) => rejected.push(RejectedRun { start, end, t_start, t_end, reason }),
            None => holds.push(Hold { start, end, t_start, t_end, mean, std: var.map(f64::sqrt) }),
        }
    }
    Ok(Detection { window, dt, floor, threshold, source, trace, holds, rejected })
}

/// What the detector kept and dropped ([`Detection::summary`]), for a message.
#[derive(Debug, Clone, PartialEq)]
pub struct Summary {
    /// Holds kept.
    pub kept: usize,
    /// The durations of the quiet runs dropped as too short, seconds.
    pub too_short_s: Vec<f64>,
    /// Quiet runs dropped as not static over their whole length.
    pub not_static: usize,
}

impl Summary {
    /// In one line, the settings that would keep the dropped holds named by `w`: `1 holds kept;
    /// 12 dropped: 12 too short (1.69 to 1.71 s): --min-hold-s 1.6 keeps them`.
    pub fn words(&self, w: &dyn crate::error::Wording) -> String {
        use crate::error::Setting;
        let dropped = self.too_short_s.len() + self.not_static;
        if dropped == 0 {
            return format!("{} holds kept, none dropped", self.kept);
        }
        let mut why = Vec::new();
        let lo = self.too_short_s.iter().copied().reduce(f64::min);
        let hi = self.too_short_s.iter().copied().reduce(f64::max);
        if let (Some(lo), Some(hi)) = (lo, hi) {
            // The longest minimum, to a tenth of a second, that keeps them all.
            let keep = (lo * 10.0).floor() / 10.0;
            why.push(format!(
                "{} too short ({lo:.2} to {hi:.2} s): {} {keep:.1} keeps them",
                self.too_short_s.len(),
                w.name(Setting::MinHold)
            ));
        }
        if self.not_static > 0 {
            why.push(format!(
                "{} not static over the whole run: {} keeps them",
                self.not_static,
                w.name(Setting::HoldThreshold)
            ));
        }
        format!("{} holds kept; {dropped} dropped: {}", self.kept, why.join("; "))
    }
}

impl Detection {
    /// What the detector kept and dropped.
    pub fn summary(&self) -> Summary {
        Summary {
            kept: self.holds.len(),
            too_short_s: self
                .rejected
                .iter()
                .filter_map(|r| match r.reason {
                    Rejection::TooShort { duration_s } => Some(duration_s),
                    Rejection::NotStatic { .. } => None,
                })
                .collect(),
            not_static: self
                .rejected
                .iter()
                .filter(|r| matches!(r.reason, Rejection::NotStatic { .. }))
                .count(),
        }
    }
}

fn check_config(cfg: &DetectorConfig) -> Result<(), HoldError> {
    let bad = |what: &str| Err(HoldError::BadConfig(what.to_string()));
    if !(cfg.window_s.is_finite() && cfg.window_s > 0.0) {
        return bad("window length must be positive");
    }
    if !(cfg.min_hold_s.is_finite() && cfg.min_hold_s >= 0.0) {
        return bad("minimum hold duration must be non-negative");
    }
    if !(cfg.floor_quantile > 0.0 && cfg.floor_quantile < 1.0) {
        return bad("floor quantile must be in (0, 1)");
    }
    if !(cfg.threshold_factor.is_finite() && cfg.threshold_factor > 0.0) {
        return bad("threshold factor must be positive");
    }
    if let Some(th) = cfg.threshold {
        if !(th.is_finite() && th > 0.0) {
            return bad("threshold must be positive");
        }
    }
    Ok(())
}

fn median_dt(t: &[f64]) -> Option<f64> {
    if t.len() < 2 {
        return None;
    }
    let mut dts: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).collect();
    dts.sort_by(f64::total_cmp);
    let m = dts[dts.len() / 2];
    (m.is_finite() && m > 0.0).then_some(m)
}

/// Sum over axes of the centred-window sample variance; `+∞` where the window is incomplete.
///
/// Uses prefix sums of the codes minus the first sample, so large offsets do not cost precision.
pub fn variance_trace(codes: &[[f64; 3]], window: usize) -> Vec<f64> {
    let n = codes.len();
    let h = window / 2;
    let mut trace = vec![f64::INFINITY; n];
    if n < window || window < 2 {
        return trace;
    }
    let origin = codes[0];
    let mut s1 = vec![[0.0f64; 3]; n + 1];
    let mut s2 = vec![[0.0f64; 3]; n + 1];
    for (i, c) in codes.iter().enumerate() {
        for a in 0..3 {
            let x = c[a] - origin[a];
            s1[i + 1][a] = s1[i][a] + x;
            s2[i + 1][a] = s2[i][a] + x * x;
        }
    }
    let w = window as f64;
    for (i, out) in trace.iter_mut().enumerate().take(n - h).skip(h) {
        let (lo, hi) = (i - h, i + h + 1);
        let mut v = 0.0;
        for a in 0..3 {
            let sum = s1[hi][a] - s1[lo][a];
            let sum2 = s2[hi][a] - s2[lo][a];
            v += ((sum2 - sum * sum / w) / (w - 1.0)).max(0.0);
        }
        *out = v;
    }
    trace
}

/// The `q` quantile (nearest rank) of the finite values of `xs`; `+∞` if there is none.
fn quantile(xs: &[f64], q: f64) -> f64 {
    let mut v: Vec<f64> = xs.iter().copied().filter(|x| x.is_finite()).collect();
    if v.is_empty() {
        return f64::INFINITY;
    }
    v.sort_by(f64::total_cmp);
    let k = ((q * v.len() as f64) as usize).min(v.len() - 1);
    v[k]
}

/// Maximal runs `[start, end)` where `trace < threshold`.
fn quiet_runs(trace: &[f64], threshold: f64) -> Vec<(usize, usize)> {
    let mut runs = Vec::new();
    let mut start = None;
    for (i, &v) in trace.iter().enumerate() {
        match (v < threshold, start) {
            (true, None) => start = Some(i),
            (false, Some(s)) => {
                runs.push((s, i));
                start = None;
            }
            _ => {}
        }
    }
    if let Some(s) = start {
        runs.push((s, trace.len()));
    }
    runs
}

/// Per-axis mean and sample variance (two-pass).
fn mean_var(codes: &[[f64; 3]]) -> ([f64; 3], [f64; 3]) {
    let n = codes.len() as f64;
    let mut mean = [0.0; 3];
    for c in codes {
        for a in 0..3 {
            mean[a] += c[a];
        }
    }
    mean = mean.map(|m| m / n);
    let mut var = [0.0; 3];
    for c in codes {
        for a in 0..3 {
            var[a] += (c[a] - mean[a]).powi(2);
        }
    }
    let denom = (n - 1.0).max(1.0);
    (mean, var.map(|v| v / denom))
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;
    use rand_distr::{Distribution, Normal};

    /// Static segments at the given levels, joined by large ramps, with Gaussian noise.
    fn synthetic(levels: &[(f64, usize)], ramp: usize, seed: u64) -> (Vec<f64>, Vec<[f64; 3]>) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let noise = Normal::new(0.0, 3.0).unwrap();
        let mut codes = Vec::new();
        for (k, &(level, len)) in levels.iter().enumerate() {
            if k > 0 {
                for j in 0..ramp {
                    let x = 5000.0 * (std::f64::consts::PI * j as f64 / ramp as f64).sin();
                    codes.push([level + x, level - x, level + 0.5 * x]);
                }
            }
            for _ in 0..len {
                codes.push([
                    level + noise.sample(&mut rng),
                    level + noise.sample(&mut rng),
                    level + noise.sample(&mut rng),
                ]);
            }
        }
        let t = (0..codes.len()).map(|i| i as f64 * 0.01).collect();
        (t, codes)
    }

    #[test]
    fn finds_holds_and_their_means() {
        let (t, codes) = synthetic(&[(30000.0, 1500), (31000.0, 600), (29000.0, 700)], 150, 1);
        let d = detect(&t, &codes, &DetectorConfig::default()).unwrap();
        assert_eq!(d.window, 101);
        assert_eq!(d.holds.len(), 3, "{:?}", d.rejected);
        for (h, level) in d.holds.iter().zip([30000.0, 31000.0, 29000.0]) {
            for a in 0..3 {
                assert!((h.mean[a] - level).abs() < 0.5, "{:?}", h.mean);
                assert!((h.std[a] - 3.0).abs() < 0.4, "{:?}", h.std);
            }
        }
        // Noise floor: 3 axes × 9 codes² = 27 codes², estimated from below by the lower quartile.
        assert!(d.floor > 20.0 && d.floor < 27.0, "floor {}", d.floor);
        assert_eq!(d.source, ThresholdSource::Data);
    }

    #[test]
    fn rejects_short_runs_and_drifting_runs() {
        let (t, mut codes) = synthetic(&[(30000.0, 1500), (31000.0, 250), (29000.0, 1500)], 150, 2);
        // A slow drift of 40 codes over the last hold: each window stays quiet, the run does not.
        let n = codes.len();
        for (k, c) in codes[n - 1500..].iter_mut().enumerate() {
            c[0] += 40.0 * k as f64 / 1500.0;
        }
        let d = detect(&t, &codes, &DetectorConfig::default()).unwrap();
        assert_eq!(d.holds.len(), 1);
        assert_eq!(d.rejected.len(), 2);
        assert!(matches!(d.rejected[0].reason, Rejection::TooShort { .. }));
        assert!(matches!(d.rejected[1].reason, Rejection::NotStatic { .. }));
    }

    #[test]
    fn user_threshold_and_bad_settings() {
        let (t, codes) = synthetic(&[(30000.0, 800), (31000.0, 800)], 150, 3);
        let cfg = DetectorConfig { threshold: Some(1e12), ..Default::default() };
        let d = detect(&t, &codes, &cfg).unwrap();
        assert_eq!(d.source, ThresholdSource::User);
        assert_eq!(d.holds.len() + d.rejected.len(), 1, "a huge threshold merges everything");
        let cfg = DetectorConfig { window_s: -1.0, ..Default::default() };
        assert!(matches!(detect(&t, &codes, &cfg), Err(HoldError::BadConfig(_))));
        assert!(matches!(
            detect(&t[..50], &codes[..50], &DetectorConfig::default()),
            Err(HoldError::TooShort { .. })
        ));
        assert!(matches!(
            detect(&[0.0, 0.0, 0.0], &codes[..3], &DetectorConfig::default()),
            Err(HoldError::BadSampling)
        ));
    }

    #[test]
    fn trace_matches_direct_variance() {
        let codes: Vec<[f64; 3]> = (0..20).map(|i| [(i * i) as f64, 40000.0 + i as f64, 7.0]).collect();
        let tr = variance_trace(&codes, 5);
        assert!(tr[0].is_infinite() && tr[1].is_infinite() && tr[19].is_infinite());
        let xs: Vec<f64> = (8..13).map(|i| (i * i) as f64).collect();
        let m = xs.iter().sum::<f64>() / 5.0;
        let v0 = xs.iter().map(|x| (x - m).powi(2)).sum::<f64>() / 4.0;
        let v1 = 2.5; // variance of 5 consecutive integers
        assert!((tr[10] - (v0 + v1)).abs() < 1e-6, "{} vs {}", tr[10], v0 + v1);
    }
}
