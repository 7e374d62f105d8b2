//! The dividing head: the one place for heads.
//!
//! - [`Positioner`]: what the acquisition and the verification ask of a head (home, set a
//!   position and read its angles back, stop, the chamber where the rig has one, and what to do
//!   when a position is refused);
//! - [`spec`]: the `--head` spec, parsed once into a typed value that settings carry, and the
//!   head's settings ([`HeadSettings`]);
//! - [`open`]: the factory from settings to a driver;
//! - [`settled`]: the rule a position must meet before anything of it is recorded;
//! - the drivers, one file each: [`manual`] (an operator), [`line_head`] (a head on the line
//!   protocol of [`protocol`] over a [`link`]: the emulated head, `sim:`), [`exec`] (an adapter
//!   program speaking that protocol, `exec:`), [`zaber`] (a Zaber head over Zaber's ASCII
//!   protocol, `zaber:`).
//!
//! A new driver is one new file plus its arm in [`spec::HeadSpec`] and in [`open`].

pub mod error;
pub mod exec;
pub mod line_head;
pub mod link;
pub mod manual;
pub mod protocol;
pub mod spec;
pub mod zaber;

use std::sync::atomic::AtomicBool;
use std::sync::Arc;

pub use error::HeadError;
pub use line_head::LineHead;
pub use protocol::CHAMBER_RANGE_C;
pub use spec::{HeadSettings, HeadSpec};
pub use zaber::{ZaberAxes, ZaberHead, ZaberPort};

/// A head's two angles, degrees, in the paper's convention (α about the spindle, β the tilt;
/// `accelcal_shared::kinematics`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Angles {
    /// α, degrees.
    pub alpha_deg: f64,
    /// β, degrees.
    pub beta_deg: f64,
}

impl From<(f64, f64)> for Angles {
    fn from((alpha_deg, beta_deg): (f64, f64)) -> Angles {
        Angles { alpha_deg, beta_deg }
    }
}

/// A position the head is set to.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Target {
    /// The position's index, 0-based, among `n`.
    pub k: usize,
    /// How many positions the plan has.
    pub n: usize,
    /// The angles commanded.
    pub angles: Angles,
    /// What the unit should read there, m/s² (g times the paper's kinematics): shown to an
    /// operator.
    pub expected_m_s2: [f64; 3],
}

/// What sets the head to a position.
pub trait Positioner {
    /// The head in words for the campaign and the journal (its spec, and its identification
    /// where the head gives one).
    fn describe(&self) -> String;

    /// Brings the axes that need it to their home position; called once before the first move of
    /// an acquisition or a verification.
    fn home(&mut self) -> anyhow::Result<()> {
        Ok(())
    }

    /// Sets the head to `target` and returns once the controller reports the move done (or an
    /// operator confirmed it), with the angles the head reads back. When a stop was requested
    /// meanwhile (Ctrl-C), the head is stopped and whatever angles it stopped at are returned:
    /// the caller checks its stop flag before it uses them.
    fn set(&mut self, target: &Target) -> anyhow::Result<Angles>;

    /// The angles the head reads back now.
    fn read_back(&mut self) -> anyhow::Result<Angles>;

    /// Stops every axis at once (Ctrl-C during a move).
    fn stop(&mut self) -> anyhow::Result<()> {
        Ok(())
    }

    /// Position `k` was refused: it did not become static in time, or its reading did not move as
    /// the plan says (`why` says which, and by how much); true to try it again (the head is set
    /// again), false to stop with an error naming the position. A positioner that waits for an
    /// operator returns at once when a stop was requested (the caller checks its stop flag).
    fn retry(&mut self, _k: usize, _why: &str) -> anyhow::Result<bool> {
        Ok(false)
    }

    /// Sets the rig's thermal chamber to `setpoint_c` (°C); the caller then waits its soak time.
    fn chamber(&mut self, setpoint_c: f64) -> anyhow::Result<()> {
        Err(accelcal_core::error::bad(format!(
            "{} has no thermal chamber to set to {setpoint_c} °C (--chamber needs a rig with one)",
            self.describe()
        )))
    }
}

/// The head `settings` name, connected. An operator's prompts go to `operator` (the terminal's
/// stderr), their answers come from standard input; `stop` is the command's Ctrl-C flag.
pub fn open(
    settings: &HeadSettings,
    stop: Arc<AtomicBool>,
    operator: Box<dyn std::io::Write + Send>,
) -> anyhow::Result<Box<dyn Positioner>> {
    Ok(match &settings.spec {
        HeadSpec::Manual => Box::new(manual::ManualHead::new(stop, operator)),
        HeadSpec::Sim(addr) => Box::new(LineHead::connect(addr, settings.timeout)?.stop_on(stop)),
        HeadSpec::Exec(command) => Box::new(exec::start(command, settings.timeout, operator)?.stop_on(stop)),
        HeadSpec::Zaber(port) => Box::new(ZaberHead::connect(port, settings.zaber, settings.timeout, stop)?),
    })
}

/// The head's part of the settled rule: a position is recorded only when the controller reported
/// the move done, the read-back lies within `tolerance_arcsec` of the commanded angles, `wait` has
/// elapsed since, and the node's stream is still (the acquisition's static test).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Settle {
    /// Largest accepted deviation of either read-back angle from the commanded one, arcsec
    /// (`--head-tolerance-arcsec`).
    pub tolerance_arcsec: f64,
    /// Wait after the move is reported done, before the static test (`--settle-s`).
    pub wait: std::time::Duration,
}

impl Settle {
    /// `--head-tolerance-arcsec`'s default: ten times a Zaber rotary stage's microstep (0.84″),
    /// far below any fault a head can have and any angle error the budget allows for.
    pub const TOLERANCE_ARCSEC: f64 = 10.0;
}

impl Default for Settle {
    fn default() -> Settle {
        Settle { tolerance_arcsec: Settle::TOLERANCE_ARCSEC, wait: std::time::Duration::ZERO }
    }
}

/// How far `read_back` lies from `commanded`, arcsec: the larger of the two angles' deviations,
/// α taken modulo 360° (a spindle at 359.9° stands 0.1° from 0°).
pub fn off_arcsec(commanded: Angles, read_back: Angles) -> f64 {
    let da = (read_back.alpha_deg - commanded.alpha_deg).rem_euclid(360.0);
    let da = da.min(360.0 - da);
    let db = (read_back.beta_deg - commanded.beta_deg).abs();
    da.max(db) * 3600.0
}

/// The settled rule's check of the angles: the read-back lies within `tolerance_arcsec` of the
/// commanded angles, or the position is refused before anything of it is recorded.
pub fn settled(
    head: &str,
    target: &Target,
    read_back: Angles,
    tolerance_arcsec: f64,
) -> Result<(), HeadError> {
    let off = off_arcsec(target.angles, read_back);
    if off <= tolerance_arcsec {
        return Ok(());
    }
    Err(HeadError::OffTarget {
        addr: head.to_string(),
        position: target.k + 1,
        commanded: target.angles,
        read_back,
        off_arcsec: off,
        tolerance_arcsec,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn off_target_wraps_the_spindle_and_names_both_angles() {
        let at = |a, b| Angles { alpha_deg: a, beta_deg: b };
        assert!((off_arcsec(at(0.0, 0.0), at(359.99, 0.0)) - 36.0).abs() < 1e-6);
        assert!((off_arcsec(at(90.0, -60.0), at(90.0, -60.01)) - 36.0).abs() < 1e-6);
        let t = Target { k: 4, n: 62, angles: at(90.0, -60.0), expected_m_s2: [0.0; 3] };
        assert!(settled("sim:h:1", &t, at(90.0, -60.001), 10.0).is_ok());
        let e = settled("sim:h:1", &t, at(90.0, -60.02), 10.0).unwrap_err().to_string();
        assert_eq!(
            e,
            "head sim:h:1: position 5: read back alpha 90 deg, beta -60.02 deg, commanded alpha 90 deg, \
             beta -60 deg: 72.0 arcsec off, beyond --head-tolerance-arcsec 10"
        );
    }
}
