//! One module per subcommand; [`run`] dispatches.

pub mod bench_diagnose;
pub mod compare;
pub mod demo;
pub mod diagnose;
pub mod fit;
pub mod select;
pub mod simulate;

use std::path::Path;

use anyhow::Context;

use crate::campaign::Campaign;
use crate::cli::{Cli, Command};
use crate::reduce::Reduced;

/// Runs a parsed command line.
pub fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Simulate(a) => simulate::run(&a),
        Command::Select(a) => select::run(&a),
        Command::Fit(a) => fit::run(&a),
        Command::Compare(a) => compare::run(&a),
        Command::Demo(a) => demo::run(&a),
        Command::Flash(a) => crate::node::cli::run_flash(&a),
        Command::Monitor(a) => crate::node::cli::run_monitor(&a),
        Command::Hil(a) => crate::node::cli::run_hil(&a),
        Command::Diagnose(a) => diagnose::run(&a),
        Command::BenchDiagnose(a) => bench_diagnose::run(&a),
    }
}

/// Reads a campaign and prints its warnings on stderr; its errors are bad input (exit code 2).
pub fn read_campaign(path: &Path) -> anyhow::Result<Campaign> {
    let c = Campaign::read(path).context("reading the campaign")?;
    warn(&c.warnings);
    Ok(c)
}

/// Reduces a campaign to its dwells in one streaming pass (bounded memory) and prints its
/// warnings on stderr; its errors are bad input (exit code 2).
pub fn reduce_campaign(path: &Path) -> anyhow::Result<Reduced> {
    let r = Campaign::reduce(path).context("reading the campaign")?;
    warn(&r.warnings);
    Ok(r)
}

/// Prints the reader's warnings, one line each.
pub fn warn(warnings: &[String]) {
    for w in warnings {
        eprintln!("warning: {w}");
    }
}

/// Checks that g is usable.
pub fn check_g(g: f64) -> anyhow::Result<()> {
    if !(g.is_finite() && g > 0.0) {
        return Err(crate::error::bad(format!("--g must be a positive number of m/s², got {g}")));
    }
    Ok(())
}

/// Formats a number with a fixed number of significant digits for tables.
pub fn sig(v: f64, digits: usize) -> String {
    if !v.is_finite() {
        return "-".into();
    }
    if v == 0.0 {
        return "0".into();
    }
    let mag = v.abs().log10().floor() as i32;
    let decimals = (digits as i32 - 1 - mag).clamp(0, 12) as usize;
    format!("{v:.decimals$}")
}
