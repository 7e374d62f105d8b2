//! `accelcal compare`: the paper's Table 2.

use anyhow::Context;
use serde::Serialize;

use crate::campaign::Campaign;
use crate::cli::{CompareArgs, Method};
use crate::compare::{self, ErrorStats, Inversion};
use crate::error::bad;
use crate::lsq::{self, LsqFit};
use crate::output::write_json;
use crate::positions::Positions;
use crate::testturn;
use accelcal_shared::terms::MODEL_4;

/// One channel's row of Table 2.
#[derive(Serialize, Clone)]
pub struct CompareChannel {
    channel: String,
    lsq: ErrorStats,
    test_turns: ErrorStats,
}

/// The outcome of a comparison.
#[derive(Serialize, Clone)]
pub struct CompareJson {
    inversion: Inversion,
    validation_positions: usize,
    validation_rows: usize,
    channels: Vec<CompareChannel>,
    /// Mean error at each validation position, per method and channel (for the plots).
    #[serde(skip)]
    per_position: [Vec<(String, Vec<f64>)>; 2],
}

/// Fits both methods and measures their errors. Without `validate`, the validation positions are
/// every other position outside the test-turn positions, and the LSQ fit uses the rest.
pub fn compute(c: &Campaign, validate: Option<&Campaign>, g: f64) -> anyhow::Result<CompareJson> {
    let pos = Positions::new(c, g);
    let stats = pos.channel_stats(c);
    let pairs = testturn::Pairs::find(&pos)?;
    let used = pairs.used();
    let (fit_idx, val_rows): (Vec<usize>, Vec<(usize, usize)>) = match validate {
        Some(v) => {
            let names: Vec<_> = c.channels.iter().map(|c| &c.name).collect();
            let vnames: Vec<_> = v.channels.iter().map(|c| &c.name).collect();
            if names != vnames {
                return Err(bad(format!(
                    "the validation campaign's channels {vnames:?} differ from the campaign's {names:?}"
                )));
            }
            ((0..pos.len()).collect(), v.dwells().iter().map(|d| (d.start, d.end)).collect())
        }
        None => {
            let others: Vec<usize> = (0..pos.len()).filter(|i| !used.contains(i)).collect();
            let held: Vec<usize> = others.iter().copied().skip(1).step_by(2).collect();
            if held.is_empty() {
                return Err(bad("the plan has no positions besides the test-turn ones to validate on; give --validate CAMPAIGN2"));
            }
            let fit_idx = (0..pos.len()).filter(|i| !held.contains(i)).collect();
            (fit_idx, held.iter().map(|&i| (pos.dwells[i].start, pos.dwells[i].end)).collect())
        }
    };
    let lsq_fits: Vec<LsqFit> = stats
        .iter()
        .map(|s| {
            lsq::fit(&pos, s, MODEL_4, Some(&fit_idx)).map_err(|e| bad(format!("channel `{}`: {e}", s.name)))
        })
        .collect::<anyhow::Result<_>>()?;
    let tt_fits: Vec<LsqFit> = stats.iter().map(|s| testturn::fit(&pos, s, &pairs)).collect();
    let vc = validate.unwrap_or(c);
    let (inv, e_lsq) = compare::errors(vc, g, &lsq_fits, &val_rows);
    let (_, e_tt) = compare::errors(vc, g, &tt_fits, &val_rows);
    let per_pos = |e: &Vec<Vec<f64>>| -> Vec<(String, Vec<f64>)> {
        c.channels
            .iter()
            .zip(e)
            .map(|(ch, errs)| {
                let mut out = Vec::new();
                let mut at = 0;
                for &(s, t) in &val_rows {
                    let n = t - s;
                    out.push(errs[at..at + n].iter().sum::<f64>() / n as f64);
                    at += n;
                }
                (ch.name.clone(), out)
            })
            .collect()
    };
    Ok(CompareJson {
        inversion: inv,
        validation_positions: val_rows.len(),
        validation_rows: val_rows.iter().map(|(s, t)| t - s).sum(),
        channels: c
            .channels
            .iter()
            .enumerate()
            .map(|(i, ch)| CompareChannel {
                channel: ch.name.clone(),
                lsq: compare::stats(&e_lsq[i]),
                test_turns: compare::stats(&e_tt[i]),
            })
            .collect(),
        per_position: [per_pos(&e_lsq), per_pos(&e_tt)],
    })
}

/// Prints Table 2.
pub fn print_table(r: &CompareJson) {
    println!(
        "acceleration error after calibration, m/s² ({} validation positions, {} rows, {} inversion)",
        r.validation_positions,
        r.validation_rows,
        match r.inversion {
            Inversion::Triad => "triad K^-1",
            Inversion::PerChannel => "per-channel",
        }
    );
    println!("  {:<8} {:>11} {:>11} {:>11} {:>11}", "channel", "mean LSQ", "mean TT", "std LSQ", "std TT");
    for ch in &r.channels {
        println!(
            "  {:<8} {:>11.5} {:>11.5} {:>11.5} {:>11.5}",
            ch.channel,
            ch.lsq.mean_error,
            ch.test_turns.mean_error,
            ch.lsq.std_error,
            ch.test_turns.std_error
        );
    }
}

/// Writes the two error-per-position plots into `dir`.
pub fn plots(dir: &std::path::Path, r: &CompareJson) -> anyhow::Result<Vec<std::path::PathBuf>> {
    std::fs::create_dir_all(dir).map_err(|e| anyhow::anyhow!("creating {}: {e}", dir.display()))?;
    let mut out = Vec::new();
    for (m, (file, title)) in [
        (Method::Lsq, ("errors-lsq.svg", "LSQ: mean acceleration error per validation position")),
        (
            Method::TestTurns,
            ("errors-test-turns.svg", "Test turns: mean acceleration error per validation position"),
        ),
    ] {
        let path = dir.join(file);
        crate::plot::error_per_position(&path, title, &r.per_position[m as usize])?;
        out.push(path);
    }
    Ok(out)
}

/// Runs `accelcal compare`.
pub fn run(a: &CompareArgs, warnings: &mut super::Warnings) -> anyhow::Result<()> {
    super::check_g(a.common.g)?;
    let c = super::read_campaign(&a.campaign, warnings)?;
    let v = a.validate.as_deref().map(|p| super::read_campaign(p, warnings)).transpose()?;
    let r = compute(&c, v.as_ref(), a.common.g).with_context(|| a.campaign.display().to_string())?;
    print_table(&r);
    if let Some(j) = &a.common.json {
        write_json(j, &r)?;
    }
    if let Some(dir) = &a.plot {
        for p in plots(dir, &r)? {
            println!("plot: {}", p.display());
        }
    }
    Ok(())
}
