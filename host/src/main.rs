//! The `accelcal` binary: parse the command line, run the command, map errors to exit codes
//! (2 for bad input, 1 for anything else; `station` says 1 for a rejected unit, 3 for the
//! environment). A failure prints one line; the campaign readers'
//! warnings are printed after a success, or folded into that line.

#[macro_use]
mod out;

mod app;
mod cli;
mod cmd;
mod exit;
mod report;
mod resolved;
mod serve;
mod settings;
#[cfg(test)]
mod sources;
mod words;

use clap::{CommandFactory, FromArgMatches};

fn main() {
    reset_sigpipe();
    let matches = cli::Cli::command().try_get_matches().unwrap_or_else(|e| refused(e));
    let mut cli = cli::Cli::from_arg_matches(&matches).unwrap_or_else(|e| e.exit());
    // The whole command line is checked before any file is opened.
    let mut given = settings::Given::of(&matches).expect("clap requires a subcommand");
    let checked = settings::check_text(&matches, &cli.command).and_then(|()| {
        let config = settings::apply_config(&mut cli.command, &mut given)?;
        settings::check(&cli.command, &given)?;
        let gravity = settings::gravity::stated(&cli.command, &given)?;
        let plan = settings::station::plan_dwell(&cli.command, &given)?;
        Ok(resolved::Resolved { gravity, config, plan })
    });
    let settled = checked.and_then(|resolved| {
        let settings = settings::settled::settle(cli.command, &resolved)?;
        Ok((resolved, settings))
    });
    let (resolved, settings) = match settled {
        Ok(r) => r,
        Err(e) => {
            failed(&words::line(&e), 2);
        }
    };
    let mut warnings = cmd::Warnings::default();
    // The station tells a rejected unit (1) from a failed environment (3).
    let code = match settings {
        settings::settled::Settings::Station(_) => crate::exit::station_code,
        _ => crate::exit::code,
    };
    match cmd::run(settings, &resolved, &mut warnings) {
        Ok(()) => {
            cmd::print_warnings(&warnings);
            // The command's work is done; a diagnostic it could not write still fails it.
            if let Some(e) = out::stderr_failed() {
                let e = anyhow::anyhow!("writing to standard error: {e}");
                failed(&words::line(&e), code(&e));
            }
        }
        Err(e) => {
            // One line: the error, with the campaign's warnings folded in.
            failed(&cmd::error_line(&warnings, &e), code(&e));
        }
    }
}

/// Prints `error: {line}` and exits with `code`. A standard error that cannot take the line
/// changes nothing: the exit code still says what happened.
fn failed(line: &str, code: i32) -> ! {
    use std::io::Write;
    let _ = writeln!(std::io::stderr().lock(), "error: {line}");
    std::process::exit(code)
}

/// clap's refusal of the command line. A value that clap's value parser refuses (a number out of
/// its range, `cli::range`) is bad input like any other: one line, exit code 2. Help, version
/// and the usage errors clap explains with a usage and a tip keep clap's words.
fn refused(e: clap::Error) -> ! {
    use std::io::Write;
    if e.kind() == clap::error::ErrorKind::ValueValidation {
        let text = e.render().to_string();
        let line = text.lines().next().unwrap_or("error: a value is out of its range").trim_end();
        let _ = writeln!(std::io::stderr().lock(), "{line}");
        std::process::exit(2);
    }
    e.exit()
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
