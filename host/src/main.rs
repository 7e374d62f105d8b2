//! The `accelcal` binary: parse the command line, run the command, map errors to exit codes
//! (2 for bad input, 1 for anything else).

use clap::Parser;

fn main() {
    reset_sigpipe();
    let cli = accelcal::cli::Cli::parse();
    if let Err(e) = accelcal::cmd::run(cli) {
        eprintln!("error: {e:#}");
        std::process::exit(if accelcal::error::is_bad_input(&e) { 2 } else { 1 });
    }
}

/// Restores the default action of SIGPIPE (Rust ignores it), so that `accelcal ... | head` ends
/// quietly when the reader goes away instead of panicking on the failed write.
#[cfg(unix)]
fn reset_sigpipe() {
    // SAFETY: called first thing in main, before any other thread exists; it only sets the
    // signal's disposition back to the system default.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
}

#[cfg(not(unix))]
fn reset_sigpipe() {}
