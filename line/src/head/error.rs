//! Why a head could not be driven: one error type for every driver, all of them failures of the
//! environment (exit code 3).

use accelcal_core::error::{Classify, Kind};

/// Why a head could not be driven.
#[derive(Debug, thiserror::Error)]
pub enum HeadError {
    /// The connection failed or timed out.
    #[error("head {addr}: {cause}")]
    Io {
        /// The head's address.
        addr: String,
        /// The cause.
        cause: std::io::Error,
    },
    /// No reply within the head's timeout (a move is answered once the head stands still).
    #[error(
        "head {addr}: no reply to `{request}` within {secs} s (is the head stuck, or does a move take longer? \
         --head-timeout-s sets the wait)"
    )]
    Timeout {
        /// The head's address.
        addr: String,
        /// The request's line.
        request: String,
        /// The timeout, s.
        secs: f64,
    },
    /// The head answered something else than the protocol allows, or refused.
    #[error("head {addr}: {message}")]
    Protocol {
        /// The head's address.
        addr: String,
        /// What went wrong.
        message: String,
    },
    /// An axis refused a command (Zaber's `RJ`, an adapter's `ERR`).
    #[error("head {addr}: {axis} refused `{command}`: {said}")]
    Rejected {
        /// The head's address.
        addr: String,
        /// Which axis, in words (`alpha (device 1 axis 1)`).
        axis: String,
        /// The command refused.
        command: String,
        /// What the axis said, escaped.
        said: String,
    },
    /// An axis reports a fault (stall, limit, encoder error, driver disabled and the like).
    #[error("head {addr}: {axis} reports a fault: {fault}")]
    Fault {
        /// The head's address.
        addr: String,
        /// Which axis, in words.
        axis: String,
        /// The fault in words, with the flag the axis sent.
        fault: String,
    },
    /// The read-back angles lie beyond the tolerance of the commanded ones: nothing of this
    /// position is recorded.
    #[error(
        "head {addr}: position {position}: read back alpha {} deg, beta {} deg, commanded alpha {} deg, \
         beta {} deg: {off_arcsec:.1} arcsec off, beyond --head-tolerance-arcsec {tolerance_arcsec}",
        read_back.alpha_deg, read_back.beta_deg, commanded.alpha_deg, commanded.beta_deg
    )]
    OffTarget {
        /// The head's address.
        addr: String,
        /// The position, 1-based.
        position: usize,
        /// The angles commanded.
        commanded: super::Angles,
        /// The angles the head reports.
        read_back: super::Angles,
        /// The larger of the two angles' deviations, arcsec.
        off_arcsec: f64,
        /// The tolerance, arcsec.
        tolerance_arcsec: f64,
    },
}

impl Classify for HeadError {
    fn kind(&self) -> Kind {
        Kind::Environment
    }
}
