//! The diagnosis's gap map.

use std::path::Path;

use accelcal_core::diagnose::gap::Gap;
use accelcal_core::diagnose::Data;
use anyhow::Context;

/// Writes the gap map into `dir`: `gap-positions.svg` (dwell residual per position in units of
/// the per-position noise), `gap-in-dwell.svg` (the in-dwell profile per channel) and, when the
/// campaign has `temp_c`, `gap-temperature.svg` (dwell residual against temperature). Returns the
/// files written.
pub fn gap_map(dir: &Path, d: &Data, gap: &Gap) -> anyhow::Result<Vec<std::path::PathBuf>> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let pos: Vec<(String, Vec<(f64, f64)>)> = (0..d.nch())
        .map(|c| {
            let pts =
                (0..d.npos()).map(|p| (p as f64, gap.position_residual[c][p] / d.sigma_pos(c, p))).collect();
            (d.channels[c].clone(), pts)
        })
        .collect();
    let a = dir.join("gap-positions.svg");
    super::plot::lines(
        &a,
        "baseline residual per position (real - simulated)",
        "position",
        "dwell residual / per-position noise",
        &pos,
    )?;
    let prof: Vec<(String, Vec<(f64, f64)>)> = gap
        .channels
        .iter()
        .map(|g| {
            (g.name.clone(), g.in_dwell_profile.iter().enumerate().map(|(i, v)| (i as f64, *v)).collect())
        })
        .collect();
    let b = dir.join("gap-in-dwell.svg");
    super::plot::lines(
        &b,
        "residual inside the dwell, signed by the step",
        "bin within dwell",
        "codes",
        &prof,
    )?;
    let mut written = vec![a, b];
    if let Some(t) = &d.temp {
        written.push(temperature(dir, d, gap, &d.dwell_means(t))?);
    }
    Ok(written)
}

/// Writes `gap-temperature.svg`: each channel's dwell residual (codes) against the dwell's mean
/// temperature. Returns the file written.
fn temperature(dir: &Path, d: &Data, gap: &Gap, temp_pos: &[f64]) -> anyhow::Result<std::path::PathBuf> {
    let series: Vec<(String, Vec<(f64, f64)>)> = (0..d.nch())
        .map(|c| {
            let pts = temp_pos.iter().zip(&gap.position_residual[c]).map(|(&t, &r)| (t, r)).collect();
            (d.channels[c].clone(), pts)
        })
        .collect();
    let path = dir.join("gap-temperature.svg");
    super::plot::scatter(
        &path,
        "baseline residual against temperature",
        "dwell mean temperature, °C",
        "dwell residual, codes",
        &series,
    )?;
    Ok(path)
}
