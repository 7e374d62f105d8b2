//! The uncertainty budget on the command line: `accelcal uncertainty-check` (the Monte Carlo
//! check of the budget) and the budget table `fit` prints.

use accelcal_core::output::write_json;
use accelcal_core::uncertainty::montecarlo::{self, Outcome, Scenario, Settings};
use accelcal_core::uncertainty::Budget;
use indicatif::{ProgressBar, ProgressStyle};
use serde::Serialize;

use crate::cli::UncertaintyCheckArgs;

/// The JSON of `uncertainty-check`.
#[derive(Serialize)]
struct CheckJson<'a> {
    units: u32,
    samples: u32,
    orientations: u32,
    seed: u64,
    scenarios: Vec<ScenarioJson<'a>>,
    passed: bool,
}

#[derive(Serialize)]
struct ScenarioJson<'a> {
    #[serde(flatten)]
    outcome: &'a Outcome,
    range: (f64, f64),
    passed: bool,
}

/// Runs `accelcal uncertainty-check`.
pub fn run_check(a: &UncertaintyCheckArgs) -> anyhow::Result<()> {
    let set = Settings {
        units: a.units as usize,
        samples: a.samples as usize,
        orientations: a.orientations as usize,
        seed: a.seed,
    };
    let scenarios = Scenario::standard();
    let pb = ProgressBar::new((set.units * scenarios.len()) as u64);
    pb.set_style(
        ProgressStyle::with_template("{bar:40} {pos}/{len} units, {elapsed} elapsed, eta {eta}")
            .expect("valid template"),
    );
    let mut outcomes = Vec::new();
    for s in &scenarios {
        let out = montecarlo::run(s, &set, &|_| pb.inc(1)).map_err(anyhow::Error::msg)?;
        outcomes.push(out);
    }
    pb.finish_and_clear();
    println!(
        "Monte Carlo check of the uncertainty budget (JCGM 101): {} units per scenario, {} sample sets per position, {} orientations per unit, seed {}",
        set.units, set.samples, set.orientations, set.seed
    );
    println!(
        "{:<20} {:>7} {:>7} {:>9} {:>8} {:>10} {:>13}  mean max U",
        "scenario", "noise", "angle", "orthog.", "u(g)", "coverage", "range"
    );
    println!("{:<20} {:>7} {:>7} {:>9} {:>8}", "", "codes", "arcsec", "arcsec", "m/s²");
    let mut rows = Vec::new();
    let mut failed = Vec::new();
    for o in &outcomes {
        let s = &o.scenario;
        let (lo, hi) = s.range;
        let passed = (lo..=hi).contains(&o.coverage);
        if !passed {
            failed.push(format!("{} {:.1} %", s.name, 100.0 * o.coverage));
        }
        println!(
            "{:<20} {:>7} {:>7} {:>9} {:>8} {:>9.2}% {:>5.1}–{:.1} %  {:.3e} m/s²  {}",
            s.name,
            s.noise_codes,
            s.head_angle_arcsec,
            s.head_orthogonality_arcsec,
            s.g_u_m_s2,
            100.0 * o.coverage,
            100.0 * lo,
            100.0 * hi,
            o.mean_u_m_s2,
            if passed { "ok" } else { "MISSED" }
        );
        rows.push(ScenarioJson { outcome: o, range: (lo, hi), passed });
    }
    if let Some(j) = &a.json {
        write_json(
            j,
            &CheckJson {
                units: a.units,
                samples: a.samples,
                orientations: a.orientations,
                seed: a.seed,
                passed: failed.is_empty(),
                scenarios: rows,
            },
        )?;
    }
    if failed.is_empty() {
        println!("the budget holds: every scenario's coverage is in its range");
        Ok(())
    } else {
        Err(anyhow::anyhow!("the budget's coverage is out of its range: {}", failed.join(", ")))
    }
}

/// Prints a budget: the expanded uncertainty per axis and each contributor.
pub fn print_budget(b: &Budget) {
    let u = b.expanded_max;
    println!(
        "expanded uncertainty of the calibrated acceleration (k = 2, the largest over the orientations at 1 g): x {:.2e}, y {:.2e}, z {:.2e} m/s²",
        u[0], u[1], u[2]
    );
    println!("  {:<20} {:>4} {:>12} {:>7}  source", "contributor", "type", "u, m/s²", "share");
    for c in &b.contributors {
        println!(
            "  {:<20} {:>4} {:>12.3e} {:>6.1}%  {}",
            c.name,
            c.kind,
            c.u_m_s2,
            100.0 * c.share,
            c.source
        );
    }
    for n in &b.not_included {
        println!("  not included: {n}");
    }
}
