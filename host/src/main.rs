//! The `accelcal` binary: parse the command line, run the command, map errors to exit codes
//! (2 for bad input, 1 for anything else).

use clap::Parser;

fn main() {
    let cli = accelcal::cli::Cli::parse();
    if let Err(e) = accelcal::cmd::run(cli) {
        eprintln!("error: {e:#}");
        std::process::exit(if accelcal::error::is_bad_input(&e) { 2 } else { 1 });
    }
}
