//! `accelcal compare`: the paper's Table 2.

use accelcal_core::compare::{compute_files, Comparison, Inversion};
use accelcal_core::output::write_json;

use crate::settings::campaign::Compare;

/// Prints Table 2.
pub fn print_table(r: &Comparison) -> anyhow::Result<()> {
    outln!(
        "acceleration error after calibration, m/s² ({} validation positions, {} rows, {} inversion)",
        r.validation_positions,
        r.validation_rows,
        match r.inversion {
            Inversion::Triad => "triad K^-1",
            Inversion::PerChannel => "per-channel",
        }
    )?;
    outln!("  {:<8} {:>11} {:>11} {:>11} {:>11}", "channel", "mean LSQ", "mean TT", "std LSQ", "std TT")?;
    for ch in &r.channels {
        outln!(
            "  {:<8} {:>11.5} {:>11.5} {:>11.5} {:>11.5}",
            ch.channel,
            ch.lsq.mean_error,
            ch.test_turns.mean_error,
            ch.lsq.std_error,
            ch.test_turns.std_error
        )?;
    }
    Ok(())
}

/// Writes the two error-per-position plots into `dir`.
pub fn plots(dir: &std::path::Path, r: &Comparison) -> anyhow::Result<Vec<std::path::PathBuf>> {
    std::fs::create_dir_all(dir).map_err(|e| anyhow::anyhow!("creating {}: {e}", dir.display()))?;
    let mut out = Vec::new();
    for (series, file, title) in [
        (&r.per_position.lsq, "errors-lsq.svg", "LSQ: mean acceleration error per validation position"),
        (
            &r.per_position.test_turns,
            "errors-test-turns.svg",
            "Test turns: mean acceleration error per validation position",
        ),
    ] {
        let path = dir.join(file);
        crate::report::plot::error_per_position(&path, title, series)?;
        out.push(path);
    }
    Ok(out)
}

/// Runs `accelcal compare`.
pub fn run(a: &Compare, g: &super::Gravity, warnings: &mut super::Warnings) -> anyhow::Result<()> {
    // Streamed: the fits need the dwell statistics, the errors one row at a time.
    let r = compute_files(&a.campaign.path, a.validate.as_deref(), a.campaign.codes, g.g, warnings)?;
    print_table(&r)?;
    if let Some(j) = &a.campaign.json {
        write_json(j, &r)?;
    }
    if let Some(dir) = &a.plot {
        for p in plots(dir, &r)? {
            outln!("plot: {}", p.display())?;
        }
    }
    Ok(())
}
