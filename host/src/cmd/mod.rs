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

/// Runs a parsed command line; the campaign readers' warnings go to `warnings`.
pub fn run(cli: Cli, warnings: &mut Warnings) -> anyhow::Result<()> {
    match cli.command {
        Command::Simulate(a) => simulate::run(&a),
        Command::Select(a) => select::run(&a, warnings),
        Command::Fit(a) => fit::run(&a, warnings),
        Command::Compare(a) => compare::run(&a, warnings),
        Command::Demo(a) => demo::run(&a),
        Command::Flash(a) => crate::node::cli::run_flash(&a),
        Command::Monitor(a) => crate::node::cli::run_monitor(&a),
        Command::Hil(a) => crate::node::cli::run_hil(&a, warnings),
        Command::Diagnose(a) => diagnose::run(&a, warnings),
        Command::BenchDiagnose(a) => bench_diagnose::run(&a),
    }
}

/// The campaign readers' warnings (excluded samples, single-sample dwells), held until the
/// command ends: after a success each is printed on its own `warning:` line; a failure prints one
/// line, the error followed by the warnings (which may explain it: e.g. too few positions left
/// once saturated samples are excluded).
#[derive(Debug, Default)]
pub struct Warnings(Vec<String>);

impl Warnings {
    /// Adds a reader's warnings, one line each.
    pub fn extend(&mut self, lines: &[String]) {
        self.0.extend_from_slice(lines);
    }

    /// Prints the warnings on stderr, one `warning:` line each (after a success).
    pub fn print(&self) {
        for w in &self.0 {
            eprintln!("warning: {w}");
        }
    }

    /// The one line (without the `error: ` prefix) that reports the failure `e`.
    pub fn error_line(&self, e: &anyhow::Error) -> String {
        let line = format!("{e:#}");
        if self.0.is_empty() {
            line
        } else {
            format!("{line} (note: {})", self.0.join("; "))
        }
    }
}

/// Reads a campaign; its warnings go to `warnings`, its errors are bad input (exit code 2).
pub fn read_campaign(path: &Path, warnings: &mut Warnings) -> anyhow::Result<Campaign> {
    let c = Campaign::read(path).context("reading the campaign")?;
    warnings.extend(&c.warnings);
    Ok(c)
}

/// Reduces a campaign to its dwells in one streaming pass (bounded memory); its warnings go to
/// `warnings`, its errors are bad input (exit code 2).
pub fn reduce_campaign(path: &Path, warnings: &mut Warnings) -> anyhow::Result<Reduced> {
    let r = Campaign::reduce(path).context("reading the campaign")?;
    warnings.extend(&r.warnings);
    Ok(r)
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
