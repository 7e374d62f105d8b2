//! `accelcal compare`: the paper's Table 2.

use std::path::Path;

use anyhow::Context;
use serde::Serialize;

use crate::campaign::{Campaign, Row};
use crate::cli::{CompareArgs, Method};
use crate::compare::{Calibrator, ErrorAcc, ErrorStats, Inversion};
use crate::error::bad;
use crate::lsq::{self, LsqFit};
use crate::output::write_json;
use crate::positions::{ChannelStats, Positions};
use crate::reduce::Reread;
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

/// The two fits of a comparison and where they are validated.
struct Plan {
    /// The LSQ and the test-turn calibrations.
    cals: [Calibrator; 2],
    /// Without `--validate`: for each position of the campaign, its index among the validation
    /// positions, if it is one. With it: `None`, every position of the validation campaign is one.
    held: Option<Vec<Option<usize>>>,
}

impl Plan {
    /// Fits both methods on the dwell statistics. Without `validate`, the validation positions
    /// are every other position outside the test-turn positions, and the LSQ fit uses the rest.
    fn new(pos: &Positions, stats: &[ChannelStats], validate: bool) -> anyhow::Result<Plan> {
        let pairs = testturn::Pairs::find(pos)?;
        let used = pairs.used();
        let (fit_idx, held): (Vec<usize>, _) = if validate {
            ((0..pos.len()).collect(), None)
        } else {
            let others: Vec<usize> = (0..pos.len()).filter(|i| !used.contains(i)).collect();
            let held: Vec<usize> = others.iter().copied().skip(1).step_by(2).collect();
            if held.is_empty() {
                return Err(bad("the plan has no positions besides the test-turn ones to validate on; give --validate CAMPAIGN2"));
            }
            let fit_idx = (0..pos.len()).filter(|i| !held.contains(i)).collect();
            (fit_idx, Some((0..pos.len()).map(|i| held.iter().position(|&h| h == i)).collect()))
        };
        let lsq_fits: Vec<LsqFit> = stats
            .iter()
            .map(|s| {
                lsq::fit(pos, s, MODEL_4, Some(&fit_idx))
                    .map_err(|e| bad(format!("channel `{}`: {e}", s.name)))
            })
            .collect::<anyhow::Result<_>>()?;
        let tt_fits: Vec<LsqFit> = stats.iter().map(|s| testturn::fit(pos, s, &pairs)).collect();
        Ok(Plan { cals: [Calibrator::new(&lsq_fits), Calibrator::new(&tt_fits)], held })
    }

    /// Checks that the validation campaign has the campaign's channels.
    fn check_channels(names: &[String], vnames: &[String]) -> anyhow::Result<()> {
        if names != vnames {
            return Err(bad(format!(
                "the validation campaign's channels {vnames:?} differ from the campaign's {names:?}"
            )));
        }
        Ok(())
    }
}

/// The errors of both methods on the validation rows, folded in one row at a time.
struct Validation {
    plan: Plan,
    g: f64,
    /// Per method, per channel.
    errors: [Vec<ErrorAcc>; 2],
    buf: Vec<f64>,
}

impl Validation {
    fn new(plan: Plan, nch: usize, g: f64) -> Validation {
        let errors = [vec![ErrorAcc::default(); nch], vec![ErrorAcc::default(); nch]];
        Validation { plan, g, errors, buf: vec![0.0; nch] }
    }

    /// Adds one row of the validation campaign (dwell `k`).
    fn push(&mut self, k: usize, row: &Row) {
        let p = match &self.plan.held {
            Some(held) => match held[k] {
                Some(p) => p,
                None => return,
            },
            None => k,
        };
        let a = accelcal_shared::gravity(row.alpha, row.beta, self.g);
        for (cal, errs) in self.plan.cals.iter().zip(&mut self.errors) {
            cal.errors(a, &row.codes, &mut self.buf);
            errs.iter_mut().zip(&self.buf).for_each(|(acc, &e)| acc.push(p, e));
        }
    }

    fn finish(self, names: &[String]) -> CompareJson {
        let [lsq, tt] = &self.errors;
        let per_pos = |e: &[ErrorAcc]| -> Vec<(String, Vec<f64>)> {
            names.iter().zip(e).map(|(n, acc)| (n.clone(), acc.per_position())).collect()
        };
        CompareJson {
            inversion: self.plan.cals[0].inversion(),
            validation_positions: lsq[0].per_position().len(),
            validation_rows: lsq[0].rows(),
            channels: names
                .iter()
                .enumerate()
                .map(|(i, n)| CompareChannel {
                    channel: n.clone(),
                    lsq: lsq[i].stats(),
                    test_turns: tt[i].stats(),
                })
                .collect(),
            per_position: [per_pos(lsq), per_pos(tt)],
        }
    }
}

/// Fits both methods on an in-memory campaign and measures their errors on `validate`, or
/// without it on every other position outside the test-turn positions (left out of the LSQ fit).
pub fn compute(c: &Campaign, validate: Option<&Campaign>, g: f64) -> anyhow::Result<CompareJson> {
    let pos = Positions::new(c, g);
    let names: Vec<String> = c.channels.iter().map(|ch| ch.name.clone()).collect();
    let plan = Plan::new(&pos, &pos.channel_stats(c), validate.is_some())?;
    if let Some(v) = validate {
        Plan::check_channels(&names, &v.channels.iter().map(|ch| ch.name.clone()).collect::<Vec<_>>())?;
    }
    let mut val = Validation::new(plan, names.len(), g);
    validate.unwrap_or(c).for_each_row(|k, row| val.push(k, row));
    Ok(val.finish(&names))
}

/// [`compute`] on campaign files, streamed in bounded memory: the fits from the dwell statistics
/// of one pass over `campaign`, the errors from a second pass over the validation rows (of
/// `validate`, or of `campaign` again). A `validate` file is checked in a pass of its own first,
/// so that, as with the in-memory reader, every file is refused before anything is fitted.
/// The readers' warnings go to `warnings`.
pub fn compute_files(
    campaign: &Path,
    validate: Option<&Path>,
    g: f64,
    warnings: &mut super::Warnings,
) -> anyhow::Result<CompareJson> {
    let r = super::reduce_campaign(campaign, warnings)?;
    let vr = validate.map(|v| super::reduce_campaign(v, warnings)).transpose()?;
    let first_pass = vr.as_ref().unwrap_or(&r);
    let ctx = || campaign.display().to_string();
    Plan::check_channels(&r.channels, &first_pass.channels).with_context(ctx)?;
    let plan = Plan::new(&r.positions(g), &r.channel_stats(), validate.is_some()).with_context(ctx)?;
    let vpath = validate.unwrap_or(campaign);
    let mut rows =
        Reread::open(vpath, &first_pass.channels, &first_pass.dwells).context("reading the campaign")?;
    let mut val = Validation::new(plan, r.channels.len(), g);
    while let Some((k, row)) = rows.next_row().context("reading the campaign")? {
        val.push(k, row);
    }
    rows.finish().context("reading the campaign")?;
    Ok(val.finish(&r.channels))
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
    // Streamed: the fits need the dwell statistics, the errors one row at a time.
    let r = compute_files(&a.campaign, a.validate.as_deref(), a.common.g, warnings)?;
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::{simulate, SimConfig};

    /// A small campaign file with a few saturated rows (skipped by both readers).
    fn campaign_file(seed: u64) -> (Campaign, tempfile::NamedTempFile) {
        let (mut c, _) = simulate(&SimConfig { samples: 9, seed, ..SimConfig::default() });
        for i in [3, 100, 101, 250] {
            c.channels[i % 3].codes[i] = 65535.0;
        }
        let f = tempfile::NamedTempFile::new().unwrap();
        c.write(std::fs::File::create(f.path()).unwrap()).unwrap();
        (Campaign::read(f.path()).unwrap(), f)
    }

    #[test]
    fn streaming_compare_matches_the_in_memory_compare() {
        let (c, f) = campaign_file(3);
        let (v, vf) = campaign_file(4);
        let json = |r: &CompareJson| serde_json::to_value(r).unwrap();
        let cases = [(compute(&c, None, 9.81), None), (compute(&c, Some(&v), 9.81), Some(vf.path()))];
        for (mem, validate) in cases {
            let (mem, streamed) =
                (mem.unwrap(), compute_files(f.path(), validate, 9.81, &mut Default::default()).unwrap());
            assert_eq!(json(&mem), json(&streamed));
            assert_eq!(mem.per_position, streamed.per_position);
            assert!(mem.validation_rows > 0);
        }
    }
}
