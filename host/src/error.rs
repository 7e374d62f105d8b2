//! The one error type the binary maps to exit code 2: input the user must fix.

/// Bad input: a file or an argument the command cannot use. The message names the file (and the
/// line and column where there is one).
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct BadInput(pub String);

/// Shorthand for an `anyhow` error carrying [`BadInput`].
pub fn bad(msg: impl Into<String>) -> anyhow::Error {
    anyhow::Error::new(BadInput(msg.into()))
}

/// Whether an error (anywhere in its chain) is the user's input to fix.
pub fn is_bad_input(e: &anyhow::Error) -> bool {
    e.chain().any(|c| {
        c.is::<BadInput>()
            || c.is::<crate::campaign::CampaignError>()
            || c.is::<crate::lsq::LsqError>()
            || c.is::<crate::gmdh::GmdhError>()
            || c.is::<crate::testturn::TestTurnError>()
            || c.is::<crate::gravity::imutk::ImuTkError>()
            || c.is::<crate::gravity::GravityError>()
    })
}
