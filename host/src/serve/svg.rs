//! The web view's charts as SVG (plotters, which escapes every text it draws): a control chart,
//! a unit's drift between calibrations, a head's signature.

use anyhow::anyhow;
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;

use crate::report::plot::{span, svg_string, COLORS};

type Chart<'a, 'b> = ChartContext<'a, SVGBackend<'b>, Cartesian2d<RangedCoordf64, RangedCoordf64>>;

/// The axes of a chart over `x` and `y`, with their descriptions and the y labels' format.
fn frame<'a, 'b>(
    root: &'a DrawingArea<SVGBackend<'b>, plotters::coord::Shift>,
    (x, y): (std::ops::Range<f64>, std::ops::Range<f64>),
    (xdesc, ydesc): (&str, &str),
    yfmt: &dyn Fn(&f64) -> String,
) -> anyhow::Result<Chart<'a, 'b>> {
    let mut chart = ChartBuilder::on(root)
        .margin(8)
        .x_label_area_size(30)
        .y_label_area_size(70)
        .build_cartesian_2d(x, y)
        .map_err(|e| anyhow!("{e}"))?;
    chart
        .configure_mesh()
        .x_desc(xdesc)
        .y_desc(ydesc)
        .x_label_formatter(&|v| format!("{v:.0}"))
        .y_label_formatter(yfmt)
        .draw()
        .map_err(|e| anyhow!("{e}"))?;
    Ok(chart)
}

/// What a chart's points are drawn against.
pub struct Lines {
    pub center: f64,
    pub lcl: f64,
    pub ucl: f64,
}

/// An individuals chart: the points in time order, the centre line and the control limits, the
/// points that break a rule in red.
pub fn control_chart(
    ylabel: &str,
    values: &[f64],
    lines: Option<&Lines>,
    broken: &[usize],
) -> anyhow::Result<String> {
    let n = values.len().max(2) as f64;
    let ys = values.iter().copied().chain(lines.iter().flat_map(|l| [l.lcl, l.ucl, l.center]));
    let (lo, hi) = span(ys);
    svg_string((600, 230), |root| {
        let mut chart =
            frame(root, (0.5..n + 0.5, lo..hi), ("point, in time order", ylabel), &|v| format!("{v:.3e}"))?;
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

/// A unit's drift: per pair of consecutive calibrations (x: the later one, 1, 2, …), the change
/// of each channel's bias term at 1 g with ±2 standard uncertainties, m/s².
pub fn drift_chart(pairs: &[[(f64, f64); 3]]) -> anyhow::Result<String> {
    let n = pairs.len().max(1) as f64;
    let (lo, hi) = span(pairs.iter().flatten().flat_map(|&(d, s)| [d - 2.0 * s, d + 2.0 * s, 0.0]));
    svg_string((600, 250), |root| {
        let mut chart =
            frame(root, (0.5..n + 0.5, lo..hi), ("recalibration", "bias change at 1 g, m/s²"), &|v| {
                format!("{v:.2e}")
            })?;
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
    svg_string((600, 230), |root| {
        let mut chart = frame(
            root,
            (0.5..n + 0.5, 0.0..hi.max(1e-9)),
            ("position of the plan", "common residual, arcsec (bars: ±2 standard errors)"),
            &|v| format!("{v:.0}"),
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
