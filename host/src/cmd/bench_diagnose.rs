//! `accelcal bench-diagnose`: the blind benchmark of the diagnosis (confusion table, accuracy,
//! held-out shrink against an oracle that knows the effect).

use indicatif::{ProgressBar, ProgressStyle};

use crate::cli::BenchDiagnoseArgs;
use accelcal_core::diagnose::bench::{self, Summary};
use accelcal_core::error::bad;
use accelcal_core::output::write_json;

/// Runs `accelcal bench-diagnose`.
pub fn run(a: &BenchDiagnoseArgs) -> anyhow::Result<()> {
    if a.campaigns == 0 {
        return Err(bad("--campaigns must be >= 1"));
    }
    let pb = ProgressBar::new(a.campaigns as u64);
    pb.set_style(
        ProgressStyle::with_template("{bar:40} {pos}/{len} campaigns, {elapsed} elapsed, eta {eta}")
            .expect("valid template"),
    );
    let range = parse_range(&a.magnitude)?;
    let s = bench::run(a.campaigns, a.seed, range, &|| pb.inc(1));
    pb.finish_and_clear();
    print_summary(&s, a.seed, range);
    if let Some(j) = &a.json {
        write_json(j, &s)?;
    }
    Ok(())
}

fn parse_range(s: &str) -> anyhow::Result<(f64, f64)> {
    let v: Vec<Option<f64>> = s.split(':').map(|x| x.trim().parse::<f64>().ok()).collect();
    match v[..] {
        [Some(lo), Some(hi)] if lo.is_finite() && hi.is_finite() && lo > 0.0 && hi >= lo => Ok((lo, hi)),
        _ => Err(bad(format!("--magnitude `{s}`: expected LO:HI with 0 < LO <= HI"))),
    }
}

/// Prints the confusion table and the scores.
pub fn print_summary(s: &Summary, seed: u64, range: (f64, f64)) {
    println!(
        "blind benchmark: {} campaigns, master seed {seed}, magnitudes {}..{} x per-position noise",
        s.campaigns, range.0, range.1
    );
    let mut reported: Vec<String> = s.confusion.values().flat_map(|m| m.keys().cloned()).collect();
    reported.sort();
    reported.dedup();
    let mut rows: Vec<&str> = vec!["none"];
    rows.extend(accelcal_core::effects::names());
    print!("{:<18}", "true \\ reported");
    for r in &reported {
        print!(" {:>8}", abbrev(r));
    }
    println!(" {:>9} {:>9}", "correct", "shrink/or");
    for t in rows {
        let Some(m) = s.confusion.get(t) else { continue };
        print!("{t:<18}");
        for r in &reported {
            print!(" {:>8}", m.get(r).copied().unwrap_or(0));
        }
        let acc = s.accuracy.get(t).copied().unwrap_or(f64::NAN);
        let sh = s.shrink_vs_oracle.get(t).map_or("-".to_string(), |v| format!("{:.3}", v));
        println!(" {:>8.1}% {:>9}", 100.0 * acc, sh);
    }
    println!(
        "columns: {}",
        reported.iter().map(|r| format!("{}={r}", abbrev(r))).collect::<Vec<_>>().join(", ")
    );
    println!(
        "accuracy on campaigns with an effect: {:.1}%; clean campaigns with a false report: {}/{}; held-out shrink vs oracle: {:.3}",
        100.0 * s.accuracy_effects,
        s.clean_false_positives,
        s.clean,
        s.shrink_vs_oracle_all
    );
}

fn abbrev(name: &str) -> String {
    name.split('+').map(accelcal_core::effects::short_name).collect::<Vec<_>>().join("+")
}
