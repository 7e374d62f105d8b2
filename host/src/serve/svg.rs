//! The web view's charts as SVG (plotters, which escapes every text it draws): a control chart,
//! a unit's drift between calibrations, a head's signature. Their ticks and labels are
//! [`super::ticks`]'s: distinct numbers, and dates on the axes in time order.

use anyhow::anyhow;
use plotters::coord::ranged1d::{KeyPointHint, NoDefaultFormatting, ValueFormatter};
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;

use super::ticks::{self, Ticks};
use crate::report::plot::{span, svg_string, COLORS};

/// An axis of a chart: its range, with its ticks where [`Ticks`] puts them, saying what they say.
struct Axis {
    range: RangedCoordf64,
    ticks: Ticks,
}

impl Axis {
    fn new(range: std::ops::Range<f64>, ticks: &Ticks) -> Axis {
        Axis { range: range.into(), ticks: ticks.clone() }
    }
}

impl Ranged for Axis {
    type FormatOption = NoDefaultFormatting;
    type ValueType = f64;

    fn map(&self, value: &f64, limit: (i32, i32)) -> i32 {
        self.range.map(value, limit)
    }

    fn key_points<H: KeyPointHint>(&self, _: H) -> Vec<f64> {
        self.ticks.at.clone()
    }

    fn range(&self) -> std::ops::Range<f64> {
        self.range.range()
    }
}

impl ValueFormatter<f64> for Axis {
    fn format_ext(&self, value: &f64) -> String {
        self.ticks.label(*value)
    }
}

type Chart<'a, 'b> = ChartContext<'a, SVGBackend<'b>, Cartesian2d<Axis, Axis>>;

/// Value ticks on a chart's y axis at most.
const Y_TICKS: usize = 7;

/// Date labels on a time axis at most (each is 10 characters wide).
const DATE_TICKS: usize = 5;

/// The axes of a chart over `x` and `y`, ticked and labelled by `xt` and `yt`, with their
/// descriptions.
fn frame<'a, 'b>(
    root: &'a DrawingArea<SVGBackend<'b>, plotters::coord::Shift>,
    (x, y): (std::ops::Range<f64>, std::ops::Range<f64>),
    (xt, yt): (&Ticks, &Ticks),
    (xdesc, ydesc): (&str, &str),
) -> anyhow::Result<Chart<'a, 'b>> {
    let mut chart = ChartBuilder::on(root)
        .margin(8)
        .x_label_area_size(30)
        .y_label_area_size(70)
        .build_cartesian_2d(Axis::new(x, xt), Axis::new(y, yt))
        .map_err(|e| anyhow!("{e}"))?;
    chart.configure_mesh().x_desc(xdesc).y_desc(ydesc).draw().map_err(|e| anyhow!("{e}"))?;
    Ok(chart)
}

/// What a chart's points are drawn against.
pub struct Lines {
    pub center: f64,
    pub lcl: f64,
    pub ucl: f64,
}

/// An individuals chart: the points in time order (`started_unix_s`: when each was measured,
/// the x axis's dates; `None`: numbered 1, 2, …), the centre line and the control limits, the
/// points that break a rule in red.
pub fn control_chart(
    ylabel: &str,
    values: &[f64],
    started_unix_s: Option<&[i64]>,
    lines: Option<&Lines>,
    broken: &[usize],
) -> anyhow::Result<String> {
    let n = values.len().max(2) as f64;
    let ys = values.iter().copied().chain(lines.iter().flat_map(|l| [l.lcl, l.ucl, l.center]));
    let (lo, hi) = span(ys);
    let (xt, xdesc) = match started_unix_s {
        Some(t) => (ticks::dates(t, DATE_TICKS), "point, in time order (UTC date)"),
        None => (ticks::whole(values.len(), 12), "point, in time order"),
    };
    let yt = ticks::values(lo, hi, Y_TICKS, 0.0);
    svg_string((600, 230), |root| {
        let mut chart = frame(root, (0.5..n + 0.5, lo..hi), (&xt, &yt), (xdesc, ylabel))?;
        if let Some(l) = lines {
            for (y, color) in [(l.center, RGBColor(44, 160, 44)), (l.lcl, RED), (l.ucl, RED)] {
                chart
                    .draw_series(LineSeries::new([(0.5, y), (n + 0.5, y)], color.stroke_width(1)))
                    .map_err(|e| anyhow!("{e}"))?;
            }
        }
        let pts: Vec<(f64, f64)> = values.iter().enumerate().map(|(i, &v)| (i as f64 + 1.0, v)).collect();
        chart
            .draw_series(LineSeries::new(pts.clone(), COLORS[0].stroke_width(1)))
            .map_err(|e| anyhow!("{e}"))?;
        chart
            .draw_series(pts.iter().enumerate().map(|(i, &p)| {
                let color = if broken.contains(&i) { RED.filled() } else { COLORS[0].filled() };
                Circle::new(p, if broken.contains(&i) { 5 } else { 3 }, color)
            }))
            .map_err(|e| anyhow!("{e}"))?;
        Ok(())
    })
}

/// A unit's drift: per pair of consecutive calibrations (x: the later one, 1, 2, …, labelled by
/// the date it started, `started_unix_s`), the change of each channel's bias term at 1 g with ±2
/// standard uncertainties, m/s².
pub fn drift_chart(pairs: &[[(f64, f64); 3]], started_unix_s: &[i64]) -> anyhow::Result<String> {
    let n = pairs.len().max(1) as f64;
    let (lo, hi) = span(pairs.iter().flatten().flat_map(|&(d, s)| [d - 2.0 * s, d + 2.0 * s, 0.0]));
    let (xt, yt) = (ticks::dates(started_unix_s, DATE_TICKS), ticks::values(lo, hi, Y_TICKS, 0.0));
    svg_string((600, 250), |root| {
        let mut chart = frame(
            root,
            (0.5..n + 0.5, lo..hi),
            (&xt, &yt),
            ("recalibration (UTC date)", "bias change at 1 g, m/s²"),
        )?;
        chart
            .draw_series(LineSeries::new([(0.5, 0.0), (n + 0.5, 0.0)], BLACK))
            .map_err(|e| anyhow!("{e}"))?;
        for (ch, name) in ["x", "y", "z"].iter().enumerate() {
            let dx = (ch as f64 - 1.0) * 0.12;
            let color = COLORS[ch];
            chart
                .draw_series(pairs.iter().enumerate().map(|(i, p)| {
                    let (d, s) = p[ch];
                    let x = i as f64 + 1.0 + dx;
                    PathElement::new(vec![(x, d - 2.0 * s), (x, d + 2.0 * s)], color.stroke_width(1))
                }))
                .map_err(|e| anyhow!("{e}"))?;
            chart
                .draw_series(
                    pairs
                        .iter()
                        .enumerate()
                        .map(|(i, p)| Circle::new((i as f64 + 1.0 + dx, p[ch].0), 4, color.filled())),
                )
                .map_err(|e| anyhow!("{e}"))?
                .label(*name)
                .legend(move |(x, y)| Circle::new((x + 6, y), 4, color.filled()));
        }
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()
            .map_err(|e| anyhow!("{e}"))?;
        Ok(())
    })
}

/// A head's signature: per position (in the plan's order), the units' common residual as a head
/// angle, arcsec, with a bar of ±2 standard errors (`se_arcsec`, the residual's standard error
/// as an angle) on each.
pub fn signature_chart(arcsec: &[f64], se_arcsec: &[f64]) -> anyhow::Result<String> {
    let n = arcsec.len().max(1) as f64;
    let top = arcsec.iter().zip(se_arcsec).map(|(a, s)| a + 2.0 * s);
    let (_, hi) = span(arcsec.iter().copied().chain(top).chain([0.0]));
    let hi = hi.max(1e-9);
    let (xt, yt) = (ticks::whole(arcsec.len(), 12), ticks::values(0.0, hi, Y_TICKS, 0.0));
    svg_string((600, 230), |root| {
        let mut chart = frame(
            root,
            (0.5..n + 0.5, 0.0..hi),
            (&xt, &yt),
            ("position of the plan", "common residual, arcsec (bars: ±2 standard errors)"),
        )?;
        chart
            .draw_series(arcsec.iter().enumerate().map(|(i, &a)| {
                let x = i as f64 + 1.0;
                Rectangle::new([(x - 0.35, 0.0), (x + 0.35, a)], COLORS[0].filled())
            }))
            .map_err(|e| anyhow!("{e}"))?;
        chart
            .draw_series(arcsec.iter().zip(se_arcsec).enumerate().map(|(i, (&a, &s))| {
                let x = i as f64 + 1.0;
                PathElement::new(vec![(x, (a - 2.0 * s).max(0.0)), (x, a + 2.0 * s)], BLACK.stroke_width(1))
            }))
            .map_err(|e| anyhow!("{e}"))?;
        Ok(())
    })
}
