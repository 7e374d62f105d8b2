//! The settled command line ([`Settings`]) that `main` hands to the commands.

use super::reader;
use crate::cli::Command;

/// A command line, checked and settled before anything is opened: the commands converted so far
/// (issue 29: the database's readers) take their own settings, plain values with nothing of clap;
/// the others still take their parsed arguments, checked by
/// `settings::check`.
#[derive(Debug)]
pub enum Settings {
    /// `accelcal fleet`.
    Fleet(reader::Fleet),
    /// `accelcal certificate`.
    Certificate(reader::Certificate),
    /// Every other command, as parsed.
    Parsed(Command),
}

/// Settles a checked command line (`settings::check` first).
pub fn settle(command: Command) -> anyhow::Result<Settings> {
    Ok(match command {
        Command::Fleet(a) => Settings::Fleet(reader::fleet(&a, reader::today())?),
        Command::Certificate(a) => Settings::Certificate(reader::certificate(&a)?),
        command => Settings::Parsed(command),
    })
}
