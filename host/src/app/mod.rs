//! The application layer: what commands, `serve` and the station share, above the crates and
//! below the commands (ARCHITECTURE.md, "The house"). A `cmd` module calls it; it calls no
//! `cmd` module.

pub mod attention;
pub mod certificate;
pub mod gravity;
pub mod recall;
