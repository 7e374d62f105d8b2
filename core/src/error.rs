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

/// A setting of the command that ran, as a library message refers to it: the library says which
/// setting (and what to do) in words of its own ([`Plain`]); the binary says how its user gives
/// it, a flag or a command line, through its own [`Wording`]. So no message of the library spells
/// a flag of one program.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Setting {
    /// The local gravity the fit used.
    G,
    /// The code range the user stated for the campaign.
    Codes,
    /// GMDH's split of the positions into parts A and B.
    Split,
    /// GMDH's split by temperature.
    SplitTemp,
    /// GMDH's leave-one-out criterion.
    CriterionLoo,
    /// The source of the temperature a thermal record reads on the node.
    TempInput,
    /// A second campaign to validate on.
    Validate,
    /// A fit written with its record.
    FitRecord,
    /// What writes a fit JSON again, with this version's identity fields.
    RefitJson,
    /// What writes a fit JSON together with its record.
    RefitWithRecord,
    /// A simulated unit written with signed codes.
    SimulateSigned,
    /// The MCU's unique id, as a fit is given it.
    DeviceId,
    /// What gives a fit the MCU's unique id.
    FitDeviceId,
    /// Model 4's terms, as a fit is given them.
    Model4Terms,
    /// The gravity-norm hold detector's minimum hold, seconds.
    MinHold,
    /// The gravity-norm hold detector's threshold.
    HoldThreshold,
}

/// How a message names each [`Setting`].
pub trait Wording {
    /// The words for `s`.
    fn name(&self, s: Setting) -> &'static str;
}

/// The library's own words for its settings (what [`std::fmt::Display`] of its errors says).
pub struct Plain;

impl Wording for Plain {
    fn name(&self, s: Setting) -> &'static str {
        match s {
            Setting::G => "the fit's gravity",
            Setting::Codes => "the stated code range",
            Setting::Split => "the split",
            Setting::SplitTemp => "a split by temperature",
            Setting::CriterionLoo => "the leave-one-out criterion",
            Setting::TempInput => "a temperature input",
            Setting::Validate => "a validation campaign",
            Setting::FitRecord => "with its record",
            Setting::RefitJson => "fit the campaign again with this version",
            Setting::RefitWithRecord => "fit the campaign again with a record",
            Setting::SimulateSigned => "a simulation in signed codes",
            Setting::DeviceId => "a device id",
            Setting::FitDeviceId => "fit with the device id",
            Setting::Model4Terms => "the terms ax,ay,az",
            Setting::MinHold => "a minimum hold of",
            Setting::HoldThreshold => "a higher detector threshold",
        }
    }
}

/// An error whose message names settings ([`Setting`]): its `Display` is
/// `worded(&Plain)`, and a binary words it with its flags.
pub trait Worded {
    /// The message, each setting named by `w`.
    fn worded(&self, w: &dyn Wording) -> Option<String>;
}
