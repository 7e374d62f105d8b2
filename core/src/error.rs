//! What a failure is ([`Kind`]), stated by each error type where it is defined ([`Classify`]),
//! and the generic errors of each kind: [`BadInput`], input the user must fix, [`Environment`], a
//! failure of the file system, a process or a device, and [`Interrupted`]. The exit code rule
//! ([`crate::exit`]) reads the kind off the error.

/// What a failure is, for the user and for the exit code.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    /// Input the user must fix: a file, an option, a record, a campaign (exit code 2).
    BadInput,
    /// The environment failed: the file system, a process, a port, a device, a link (exit code 1).
    Environment,
    /// The unit under test failed a check it was put to (a verification): the tool worked
    /// (exit code 1).
    Rejected,
    /// The user stopped the command (exit code 130).
    Interrupted,
}

/// An error type that states what its failures are. Every error type of the core implements it
/// next to its definition, variant by variant where they differ, and is listed in
/// [`crate::exit`]'s registry (a test checks that none is missing).
pub trait Classify {
    /// What this failure is.
    fn kind(&self) -> Kind;
}

/// Bad input: a file or an argument the command cannot use. The message names the file (and the
/// line and column where there is one).
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct BadInput(pub String);

impl Classify for BadInput {
    fn kind(&self) -> Kind {
        Kind::BadInput
    }
}

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

impl Classify for Environment {
    fn kind(&self) -> Kind {
        Kind::Environment
    }
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

impl Classify for Interrupted {
    fn kind(&self) -> Kind {
        Kind::Interrupted
    }
}
