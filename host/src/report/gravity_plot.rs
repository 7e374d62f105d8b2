//! SVG plots of a gravity-norm calibration: residual per hold, and the variance detector trace.
//!
//! The plots are rendered into strings; the caller writes them (atomically, see `crate::output`).

use plotters::prelude::*;

use accelcal_core::gravity::holds::Detection;
use accelcal_core::gravity::Calibration;

/// A plot could not be drawn.
#[derive(Debug, thiserror::Error)]
#[error("cannot draw the {plot} plot: {message}")]
pub struct PlotError {
    /// Which plot.
    pub plot: &'static str,
    /// What went wrong.
    pub message: String,
}

fn err(plot: &'static str) -> impl Fn(String) -> PlotError {
    move |message| PlotError { plot, message }
}

/// Draws `|a| − g` per hold (m/s²) against the hold index, with ±RMS lines.
pub fn residuals_svg(cal: &Calibration) -> Result<String, PlotError> {
    let e = err("residual");
    let mut svg = String::new();
    let res = &cal.fit.residuals;
    let rms = cal.fit.rms;
    let ymax = res.iter().fold(rms, |m, r| m.max(r.abs())) * 1.25;
    let n = res.len().max(1) as f64;
    let root = SVGBackend::with_string(&mut svg, (900, 480)).into_drawing_area();
    root.fill(&WHITE).map_err(|x| e(x.to_string()))?;
    let caption =
        format!("|a| - g per hold, {} ({} holds, RMS {:.2e} m/s²)", cal.fit.structure.name(), res.len(), rms);
    let mut chart = ChartBuilder::on(&root)
        .caption(caption, ("sans-serif", 18))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(80)
        .build_cartesian_2d(-0.5..n - 0.5, -ymax..ymax)
        .map_err(|x| e(x.to_string()))?;
    chart
        .configure_mesh()
        .x_desc("hold (time order; 0 = initial rest)")
        .y_desc("|a| - g  [m/s²]")
        .y_label_formatter(&|y| format!("{y:.4}"))
        .draw()
        .map_err(|x| e(x.to_string()))?;
    for (level, style) in
        [(0.0, BLACK.stroke_width(1)), (rms, RED.stroke_width(1)), (-rms, RED.stroke_width(1))]
    {
        chart
            .draw_series(LineSeries::new([(-0.5, level), (n - 0.5, level)], style))
            .map_err(|x| e(x.to_string()))?;
    }
    chart
        .draw_series(res.iter().enumerate().map(|(k, &r)| Circle::new((k as f64, r), 4, BLUE.filled())))
        .map_err(|x| e(x.to_string()))?;
    root.present().map_err(|x| e(x.to_string()))?;
    drop(chart);
    drop(root);
    Ok(svg)
}

/// Draws the detector statistic (codes², log scale) against time, the threshold, and the kept holds.
pub fn detector_svg(t: &[f64], det: &Detection) -> Result<String, PlotError> {
    let e = err("detector");
    let mut svg = String::new();
    // Decimate to at most ~4000 points by taking the maximum of each block (keeps the movements).
    let block = (det.trace.len() / 4000).max(1);
    let pts: Vec<(f64, f64)> = det
        .trace
        .chunks(block)
        .zip(t.chunks(block))
        .filter_map(|(v, tt)| {
            let m = v.iter().copied().filter(|x| x.is_finite()).fold(f64::NAN, f64::max);
            m.is_finite().then(|| (tt[0], m.max(1e-3)))
        })
        .collect();
    let (t0, t1) = (t.first().copied().unwrap_or(0.0), t.last().copied().unwrap_or(1.0));
    let ylo = pts.iter().map(|p| p.1).fold(det.threshold, f64::min) * 0.5;
    let yhi = pts.iter().map(|p| p.1).fold(det.threshold, f64::max) * 2.0;
    let root = SVGBackend::with_string(&mut svg, (1100, 480)).into_drawing_area();
    root.fill(&WHITE).map_err(|x| e(x.to_string()))?;
    let caption = format!(
        "variance detector ({}-sample window): threshold {:.1} codes², {} holds kept, {} rejected",
        det.window,
        det.threshold,
        det.holds.len(),
        det.rejected.len()
    );
    let mut chart = ChartBuilder::on(&root)
        .caption(caption, ("sans-serif", 18))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(80)
        .build_cartesian_2d(t0..t1, (ylo..yhi).log_scale())
        .map_err(|x| e(x.to_string()))?;
    chart
        .configure_mesh()
        .x_desc("time [s]")
        .y_desc("sum of axis variances [codes²]")
        .y_label_formatter(&|y| format!("{y:.0e}"))
        .draw()
        .map_err(|x| e(x.to_string()))?;
    chart
        .draw_series(
            det.holds
                .iter()
                .map(|h| Rectangle::new([(h.t_start, ylo), (h.t_end, yhi)], GREEN.mix(0.15).filled())),
        )
        .map_err(|x| e(x.to_string()))?
        .label("kept hold")
        .legend(|(x, y)| Rectangle::new([(x, y - 5), (x + 16, y + 5)], GREEN.mix(0.3).filled()));
    chart
        .draw_series(LineSeries::new(pts, BLUE.stroke_width(1)))
        .map_err(|x| e(x.to_string()))?
        .label("detector statistic")
        .legend(|(x, y)| PathElement::new([(x, y), (x + 16, y)], BLUE));
    chart
        .draw_series(LineSeries::new([(t0, det.threshold), (t1, det.threshold)], RED.stroke_width(2)))
        .map_err(|x| e(x.to_string()))?
        .label("threshold")
        .legend(|(x, y)| PathElement::new([(x, y), (x + 16, y)], RED));
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .position(SeriesLabelPosition::UpperRight)
        .draw()
        .map_err(|x| e(x.to_string()))?;
    root.present().map_err(|x| e(x.to_string()))?;
    drop(chart);
    drop(root);
    Ok(svg)
}
