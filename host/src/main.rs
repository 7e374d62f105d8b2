//! The `accelcal` binary: parse the command line, run the command, map errors to exit codes
//! (2 for bad input, 1 for anything else). A failure prints one line; the campaign readers'
//! warnings are printed after a success, or folded into that line.

use clap::Parser;

fn main() {
    reset_sigpipe();
    let cli = accelcal::cli::Cli::parse();
    let mut warnings = accelcal::cmd::Warnings::default();
    match accelcal::cmd::run(cli, &mut warnings) {
        Ok(()) => warnings.print(),
        Err(e) => {
            // One line: the error, with the campaign's warnings folded in.
            eprintln!("error: {}", warnings.error_line(&e));
            std::process::exit(if accelcal::error::is_bad_input(&e) { 2 } else { 1 });
        }
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
