//! The ticks of the charts' axes and what they say: a value axis at a step of 1, 2 or 5 × 10ᵏ,
//! each label as short as lets the labels differ (`16600.25`, not `1.660e4` five times), in
//! fixed point unless scientific notation is shorter; an
//! axis of points in time order labelled by their dates (YYYY-MM-DD), one label per day at most.

use accelcal_core::output::utc_date_time;

/// An axis's ticks: where each is, and what it says.
#[derive(Clone, Debug, PartialEq)]
pub struct Ticks {
    /// Where, in the axis's coordinate, increasing.
    pub at: Vec<f64>,
    /// What each says.
    pub labels: Vec<String>,
}

impl Ticks {
    /// The label of the tick nearest `v` (the chart asks for the labels of [`Ticks::at`]).
    pub fn label(&self, v: f64) -> String {
        self.at
            .iter()
            .zip(&self.labels)
            .min_by(|a, b| (a.0 - v).abs().total_cmp(&(b.0 - v).abs()))
            .map(|(_, l)| l.clone())
            .unwrap_or_default()
    }
}

/// The power of ten of `x` (> 0): ⌊log₁₀ x⌋, robust to the rounding of a step like 1e-3.
fn decade(x: f64) -> i32 {
    (x.log10() + 1e-9).floor() as i32
}

/// The step of 1, 2 or 5 × 10ᵏ, not below `min_step`, that puts at most `max` ticks in `lo..=hi`.
fn step(lo: f64, hi: f64, max: usize, min_step: f64) -> f64 {
    let raw = ((hi - lo) / max.saturating_sub(1).max(1) as f64).max(min_step).max(f64::MIN_POSITIVE);
    let mag = 10f64.powi(decade(raw));
    [1.0, 2.0, 5.0, 10.0]
        .into_iter()
        .map(|m| m * mag)
        .find(|s| *s >= raw * (1.0 - 1e-9))
        .unwrap_or(10.0 * mag)
}

/// `v` written to the digits of `step` (the ticks' step) in fixed point.
fn fixed(v: f64, step: f64) -> String {
    let d = (-decade(step)).max(0) as usize;
    format!("{v:.d$}")
}

/// `v` written to the digits of `step` in scientific notation, `big` the largest magnitude on
/// the axis (a smaller value's mantissa has digits to spare).
fn scientific(v: f64, step: f64, big: f64) -> String {
    if v == 0.0 {
        return "0".into();
    }
    let p = (decade(big) - decade(step)).max(0) as usize;
    format!("{v:.p$e}")
}

/// Ticks of a value axis over `lo..hi`, at most `max` of them, at multiples of a step of 1, 2 or
/// 5 × 10ᵏ (at least `min_step`), each label distinct.
pub fn values(lo: f64, hi: f64, max: usize, min_step: f64) -> Ticks {
    let (lo, hi) = match (lo.is_finite() && hi.is_finite(), hi - lo) {
        (true, d) if d > 0.0 => (lo, hi),
        // One value: a tick at it, in the middle of a range of its own size.
        (true, _) if lo != 0.0 => (lo - lo.abs() / 2.0, lo + lo.abs() / 2.0),
        _ => (-1.0, 1.0),
    };
    let step = step(lo, hi, max, min_step);
    let (first, last) = ((lo / step - 1e-9).ceil() as i64, (hi / step + 1e-9).floor() as i64);
    // `0.0 * -x` is -0: written as 0.
    let at: Vec<f64> = (first..=last).map(|i| i as f64 * step + 0.0).collect();
    let big = at.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    // Fixed point unless scientific notation writes the longest label shorter.
    let longest = |l: &[String]| l.iter().map(String::len).max().unwrap_or(0);
    let fixed: Vec<String> = at.iter().map(|&v| fixed(v, step)).collect();
    let sci: Vec<String> = at.iter().map(|&v| scientific(v, step, big)).collect();
    let labels = if longest(&sci) < longest(&fixed) { sci } else { fixed };
    Ticks { at, labels }
}

/// Ticks of an axis of the points 1..=n (positions, recalibrations): whole numbers, at most `max`.
pub fn whole(n: usize, max: usize) -> Ticks {
    match n {
        0 | 1 => Ticks { at: vec![1.0], labels: vec!["1".into()] },
        _ => values(1.0, n as f64, max, 1.0),
    }
}

/// Ticks of an axis of points 1, 2, … in time order, started at `unix_s` (in order): the first
/// point of each day labelled with the day (YYYY-MM-DD), every k-th of those days kept so that at
/// most `max` remain.
pub fn dates(unix_s: &[i64], max: usize) -> Ticks {
    let mut firsts: Vec<(usize, String)> = Vec::new();
    for (i, &t) in unix_s.iter().enumerate() {
        let day = utc_date_time(t)[..10].to_string();
        if firsts.last().is_none_or(|(_, d)| *d != day) {
            firsts.push((i, day));
        }
    }
    let every = firsts.len().div_ceil(max.max(1)).max(1);
    let (at, labels) = firsts.into_iter().step_by(every).map(|(i, d)| (i as f64 + 1.0, d)).unzip();
    Ticks { at, labels }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every label differs from the others.
    fn distinct(t: &Ticks) -> bool {
        let mut l = t.labels.clone();
        l.sort();
        l.dedup();
        l.len() == t.labels.len()
    }

    #[test]
    fn a_narrow_range_of_large_values_has_distinct_short_labels() {
        let t = values(16_600.0, 16_600.4, 6, 0.0);
        assert_eq!(t.labels, ["16600.0", "16600.1", "16600.2", "16600.3", "16600.4"]);
        let t = values(16_598.7, 16_601.9, 6, 0.0);
        assert_eq!(t.labels, ["16599", "16600", "16601"], "{t:?}");
    }

    #[test]
    fn labels_differ_on_every_scale() {
        for (lo, hi) in [
            (16_600.0, 16_600.003),
            (-3.2, 5.1),
            (0.0, 1e-7),
            (1.2e-4, 1.3e-4),
            (9.99e4, 1.0001e5),
            (2.5e6, 2.500_01e6),
            (-1e-9, 1e-9),
            (0.0, 317.0),
        ] {
            let t = values(lo, hi, 6, 0.0);
            assert!((2..=6).contains(&t.at.len()), "{lo}..{hi}: {t:?}");
            assert!(distinct(&t), "{lo}..{hi}: {t:?}");
            let slack = (hi - lo) * 1e-9;
            assert!(t.at.iter().all(|v| (lo - slack..=hi + slack).contains(v)), "{lo}..{hi}: {t:?}");
            assert!(t.labels.iter().all(|l| l.len() <= 9), "{lo}..{hi}: {t:?}");
        }
        assert_eq!(values(0.0, 1e-7, 6, 0.0).labels, ["0", "2.0e-8", "4.0e-8", "6.0e-8", "8.0e-8", "1.0e-7"]);
        assert_eq!(values(-3.2, 5.1, 6, 0.0).labels, ["-2", "0", "2", "4"]);
    }

    #[test]
    fn positions_are_whole_numbers() {
        assert_eq!(whole(1, 12).labels, ["1"]);
        assert_eq!(whole(3, 12).labels, ["1", "2", "3"]);
        let t = whole(62, 12);
        assert!(distinct(&t) && t.labels.iter().all(|l| l.parse::<u32>().is_ok()), "{t:?}");
        assert_eq!(t.labels[..3], ["10", "20", "30"]);
    }

    #[test]
    fn a_time_axis_says_each_day_once() {
        const DAY: i64 = 86_400;
        let t0 = 1_767_225_600; // 2026-01-01T00:00:00Z
                                // Three points on the first day, two on the third, one on the fourth.
        let times = [t0, t0 + 60, t0 + 7200, t0 + 2 * DAY, t0 + 2 * DAY + 5, t0 + 3 * DAY];
        let t = dates(&times, 6);
        assert_eq!(t.labels, ["2026-01-01", "2026-01-03", "2026-01-04"]);
        assert_eq!(t.at, [1.0, 4.0, 6.0]);
        // 70 days, at most 5 labels: every 14th day.
        let many: Vec<i64> = (0..70).map(|d| t0 + d * DAY).collect();
        let t = dates(&many, 5);
        assert_eq!(t.labels, ["2026-01-01", "2026-01-15", "2026-01-29", "2026-02-12", "2026-02-26"]);
        assert!(distinct(&t));
        assert_eq!(t.label(15.0), "2026-01-15");
    }
}
