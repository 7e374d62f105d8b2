//! The two error kinds the exit code rule ([`crate::exit`]) knows by name: [`BadInput`], input
//! the user must fix, and [`Environment`], a failure of the file system, a process or a device.

/// Bad input: a file or an argument the command cannot use. The message names the file (and the
/// line and column where there is one).
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct BadInput(pub String);

/// Shorthand for an `anyhow` error carrying [`BadInput`].
pub fn bad(msg: impl Into<String>) -> anyhow::Error {
    anyhow::Error::new(BadInput(msg.into()))
}

/// A failure of the environment (the file system, a process, a device), not of the input.
#[derive(Debug, thiserror::Error)]
#[error("{what}")]
pub struct Environment {
    /// What was being done.
    pub what: String,
    /// What failed.
    #[source]
    pub source: Box<dyn std::error::Error + Send + Sync>,
}

/// Marks `e` as a failure of the environment, with what was being done.
pub fn environment(what: impl Into<String>, e: impl Into<anyhow::Error>) -> anyhow::Error {
    anyhow::Error::new(Environment { what: what.into(), source: e.into().into() })
}

/// The user stopped the command (Ctrl-C, SIGTERM) before it finished; what it had completed is
/// kept and the message says how to continue. Exit code 130, as a shell reports SIGINT.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct Interrupted(pub String);
