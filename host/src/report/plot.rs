//! SVG plots: acceleration error per position for each method (the paper's Figures 3 and 4), the
//! GMDH criterion against model complexity, and the diagnosis's gap map. Every plot is rendered
//! into memory and written atomically (a failure leaves no partial file).

use std::path::Path;

use accelcal_core::output::write_atomic;
use anyhow::anyhow;
use plotters::prelude::*;

pub(crate) const COLORS: [RGBColor; 8] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
];

/// Renders an SVG of `size` pixels on a white background with `draw`, in memory, then writes it
/// to `path` atomically (a failure leaves no partial file).
fn svg_file(
    path: &Path,
    size: (u32, u32),
    draw: impl FnOnce(&DrawingArea<SVGBackend, plotters::coord::Shift>) -> anyhow::Result<()>,
) -> anyhow::Result<()> {
    write_atomic(path, svg_string(size, draw)?.as_bytes())
}

/// Renders an SVG of `size` pixels on a white background with `draw`, into a string.
pub(crate) fn svg_string(
    size: (u32, u32),
    draw: impl FnOnce(&DrawingArea<SVGBackend, plotters::coord::Shift>) -> anyhow::Result<()>,
) -> anyhow::Result<String> {
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, size).into_drawing_area();
        root.fill(&WHITE).map_err(|e| anyhow!("{e}"))?;
        draw(&root)?;
        root.present().map_err(|e| anyhow!("{e}"))?;
    }
    Ok(svg)
}

pub(crate) fn span(vals: impl Iterator<Item = f64>) -> (f64, f64) {
    let (lo, hi) = vals
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| (a.min(v), b.max(v)));
    if !lo.is_finite() {
        return (-1.0, 1.0);
    }
    let pad = ((hi - lo) * 0.08).max(1e-9);
    (lo - pad, hi + pad)
}

/// One series per channel: the mean error (m/s²) at each validation position.
pub fn error_per_position(path: &Path, title: &str, series: &[(String, Vec<f64>)]) -> anyhow::Result<()> {
    let xy: Vec<(String, Vec<(f64, f64)>)> = series
        .iter()
        .map(|(name, ys)| (name.clone(), ys.iter().enumerate().map(|(k, &y)| (k as f64 + 1.0, y)).collect()))
        .collect();
    lines(path, title, "validation position", "error of calibrated acceleration, m/s²", &xy)
}

/// Line plot of named series of `(x, y)` points, with point markers, a zero line, integer x labels
/// and a legend: the residual and error plots of every command.
pub fn lines(
    path: &Path,
    title: &str,
    xdesc: &str,
    ydesc: &str,
    series: &[(String, Vec<(f64, f64)>)],
) -> anyhow::Result<()> {
    xy(path, title, xdesc, ydesc, series, true)
}

/// Scatter plot of named series of `(x, y)` points (markers only, continuous x labels), with a
/// zero line and a legend: a residual against a measured quantity such as the temperature.
pub fn scatter(
    path: &Path,
    title: &str,
    xdesc: &str,
    ydesc: &str,
    series: &[(String, Vec<(f64, f64)>)],
) -> anyhow::Result<()> {
    xy(path, title, xdesc, ydesc, series, false)
}

/// [`lines`] (`joined`: points joined in order, integer x labels) or [`scatter`].
fn xy(
    path: &Path,
    title: &str,
    xdesc: &str,
    ydesc: &str,
    series: &[(String, Vec<(f64, f64)>)],
    joined: bool,
) -> anyhow::Result<()> {
    write_atomic(path, xy_svg(title, xdesc, ydesc, series, joined, (900, 500))?.as_bytes())
}

/// [`lines`] rendered into a string of `size` pixels, for pages that inline their plots.
pub fn lines_svg(
    title: &str,
    xdesc: &str,
    ydesc: &str,
    series: &[(String, Vec<(f64, f64)>)],
    size: (u32, u32),
) -> anyhow::Result<String> {
    xy_svg(title, xdesc, ydesc, series, true, size)
}

fn xy_svg(
    title: &str,
    xdesc: &str,
    ydesc: &str,
    series: &[(String, Vec<(f64, f64)>)],
    joined: bool,
    size: (u32, u32),
) -> anyhow::Result<String> {
    let (x0, x1) = span(series.iter().flat_map(|s| s.1.iter().map(|p| p.0)));
    let (y0, y1) = span(series.iter().flat_map(|s| s.1.iter().map(|p| p.1)));
    let (x0, x1) = if joined { (x0.floor() - 0.5, x1.ceil() + 0.5) } else { (x0, x1) };
    let xfmt = |x: &f64| if joined { format!("{x:.0}") } else { format!("{x:.2}") };
    svg_string(size, |root| {
        let mut chart = ChartBuilder::on(root)
            .caption(title, ("sans-serif", 22))
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(70)
            .build_cartesian_2d(x0..x1, y0..y1)
            .map_err(|e| anyhow!("{e}"))?;
        chart
            .configure_mesh()
            .x_desc(xdesc)
            .x_label_formatter(&xfmt)
            .y_desc(ydesc)
            .draw()
            .map_err(|e| anyhow!("{e}"))?;
        chart
            .draw_series(LineSeries::new([(x0, 0.0), (x1, 0.0)], BLACK.mix(0.4)))
            .map_err(|e| anyhow!("{e}"))?;
        for (i, (name, pts)) in series.iter().enumerate() {
            let color = COLORS[i % COLORS.len()];
            let markers = chart
                .draw_series(pts.iter().map(|&p| Circle::new(p, 3, color.filled())))
                .map_err(|e| anyhow!("{e}"))?;
            if joined {
                chart
                    .draw_series(LineSeries::new(pts.clone(), color.stroke_width(2)))
                    .map_err(|e| anyhow!("{e}"))?
                    .label(name.as_str())
                    .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], color.stroke_width(2)));
            } else {
                markers.label(name.as_str()).legend(move |(x, y)| Circle::new((x + 8, y), 3, color.filled()));
            }
        }
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperRight)
            .border_style(BLACK)
            .background_style(WHITE.mix(0.8))
            .draw()
            .map_err(|e| anyhow!("{e}"))?;
        Ok(())
    })
}

/// Criterion (RMS codes, log scale) of every identifiable candidate against its number of terms,
/// the selected model marked, and the tolerance line.
pub fn criterion_vs_complexity(
    path: &Path,
    title: &str,
    points: &[(usize, f64)],
    selected: (usize, f64),
    limit: f64,
) -> anyhow::Result<()> {
    let points = &thin_per_size(points, CANDIDATES_PER_SIZE);
    let kmax = points.iter().map(|p| p.0).max().unwrap_or(1).max(selected.0);
    let (lo, hi) = points
        .iter()
        .map(|p| p.1)
        .filter(|v| *v > 0.0)
        .fold((f64::INFINITY, 0.0f64), |(a, b), v| (a.min(v), b.max(v)));
    let (lo, hi) = if lo.is_finite() { (lo * 0.9, hi * 1.1) } else { (0.1, 10.0) };
    svg_file(path, (800, 500), |root| {
        let mut chart = ChartBuilder::on(root)
            .caption(title, ("sans-serif", 22))
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(70)
            .build_cartesian_2d(0.5f64..kmax as f64 + 0.5, (lo..hi).log_scale())
            .map_err(|e| anyhow!("{e}"))?;
        chart
            .configure_mesh()
            .x_desc("terms in the model (intercept included)")
            .x_label_formatter(&|x| format!("{x:.0}"))
            .y_desc("criterion, RMS ADC codes")
            .draw()
            .map_err(|e| anyhow!("{e}"))?;
        chart
            .draw_series(
                points.iter().map(|&(k, v)| Circle::new((k as f64, v), 3, COLORS[0].mix(0.6).filled())),
            )
            .map_err(|e| anyhow!("{e}"))?
            .label("candidate")
            .legend(|(x, y)| Circle::new((x + 8, y), 3, COLORS[0].filled()));
        chart
            .draw_series(LineSeries::new(
                [(0.5, limit), (kmax as f64 + 0.5, limit)],
                COLORS[3].stroke_width(1),
            ))
            .map_err(|e| anyhow!("{e}"))?
            .label("best + tolerance")
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], COLORS[3]));
        chart
            .draw_series(std::iter::once(TriangleMarker::new(
                (selected.0 as f64, selected.1),
                8,
                COLORS[1].filled(),
            )))
            .map_err(|e| anyhow!("{e}"))?
            .label("selected")
            .legend(|(x, y)| TriangleMarker::new((x + 8, y), 6, COLORS[1].filled()));
        chart
            .configure_series_labels()
            .border_style(BLACK)
            .background_style(WHITE.mix(0.8))
            .draw()
            .map_err(|e| anyhow!("{e}"))?;
        Ok(())
    })
}

/// Candidates drawn per model size in the criterion plot: the best ones, which are all the
/// selection rule looks at (a cubic basis has 524,288 candidates; drawing them all made 24 MB SVGs).
pub const CANDIDATES_PER_SIZE: usize = 200;

/// The `per_size` lowest criteria of each model size.
fn thin_per_size(points: &[(usize, f64)], per_size: usize) -> Vec<(usize, f64)> {
    let mut sorted = points.to_vec();
    sorted.sort_by(|a, b| a.0.cmp(&b.0).then(a.1.total_cmp(&b.1)));
    let mut out = Vec::new();
    for (i, p) in sorted.iter().enumerate() {
        if i < per_size || sorted[i - per_size].0 != p.0 {
            out.push(*p);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    #[test]
    fn the_criterion_plot_keeps_the_best_candidates_of_each_size() {
        let pts: Vec<(usize, f64)> = (0..1000).map(|i| (1 + i % 3, (i as f64 * 7.0) % 101.0)).collect();
        let kept = super::thin_per_size(&pts, 5);
        assert_eq!(kept.len(), 15);
        for k in 1..=3 {
            let mut all: Vec<f64> = pts.iter().filter(|p| p.0 == k).map(|p| p.1).collect();
            all.sort_by(f64::total_cmp);
            let got: Vec<f64> = kept.iter().filter(|p| p.0 == k).map(|p| p.1).collect();
            assert_eq!(got, all[..5]);
        }
    }
}
