//! `verify --json` ([`VerifyReport`]): a verification's result, what `report --verify`, the
//! station and the database read; and [`Failed`], the error of a verification that did not pass.

use serde::{Deserialize, Serialize};

use crate::campaign::identity::Identity;
use crate::conformity::{Decision, ParameterCheck, Specification};
use crate::error::{bad, Classify, Kind};

/// A verification in which a position failed, or a parameter the specification limits was not
/// accepted (exit code 1: the node, not the input, is wrong).
#[derive(Debug, thiserror::Error)]
#[error("verification failed: {}", failed_words(.failed, .conditional, .total, .parameters))]
pub struct Failed {
    /// Positions not accepted with a component outside the tolerance (or, under a guard-band
    /// rule, conditionally failed).
    pub failed: usize,
    /// Positions not accepted although every component is inside the tolerance T: within the
    /// guard band (a conditional pass, which the rule does not accept).
    pub conditional: usize,
    /// Positions checked.
    pub total: usize,
    /// The parameters the decision rule did not accept, in words (`bias x +2.04 mg (fail)`).
    pub parameters: Vec<String>,
}

fn failed_words(failed: &usize, conditional: &usize, total: &usize, parameters: &[String]) -> String {
    let mut words = Vec::new();
    if *failed > 0 || (*conditional == 0 && parameters.is_empty()) {
        words.push(format!("{failed} of {total} positions outside the tolerance"));
    }
    if *conditional > 0 {
        words.push(format!(
            "{conditional} of {total} positions inside T, within the guard band (conditional pass, not accepted)"
        ));
    }
    if !parameters.is_empty() {
        words.push(format!("the decision rule does not accept {}", parameters.join(", ")));
    }
    words.join("; ")
}

impl Failed {
    /// What failed, in words (the error's message without "verification failed: ").
    pub fn words(&self) -> String {
        failed_words(&self.failed, &self.conditional, &self.total, &self.parameters)
    }
}

impl Classify for Failed {
    fn kind(&self) -> Kind {
        Kind::Rejected
    }
}

/// One position's check.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct PositionCheck {
    /// Index in the plan (1-based, as printed).
    pub position: usize,
    /// α, degrees.
    pub alpha_deg: f64,
    /// β, degrees.
    pub beta_deg: f64,
    /// α the head read back once the move was done, degrees (the commanded α for a manual head;
    /// `null` in a report written before heads read back, tool 0.x before issue 56).
    #[serde(default)]
    pub read_back_alpha_deg: Option<f64>,
    /// β the head read back, degrees (`null` likewise).
    #[serde(default)]
    pub read_back_beta_deg: Option<f64>,
    /// What the head imposes, m/s².
    pub expected_m_s2: [f64; 3],
    /// The node's mean calibrated acceleration, m/s².
    pub measured_m_s2: [f64; 3],
    /// measured − expected, m/s².
    pub error_m_s2: [f64; 3],
    /// Standard error of the measured mean, m/s².
    pub sd_mean_m_s2: [f64; 3],
    /// The bound each component's error is held to, m/s².
    pub tolerance_m_s2: [f64; 3],
    /// Sets the node lost while this position was recorded.
    pub lost: u64,
    /// The node's mean temperature over the recorded sets, °C (`null` when it reports none).
    pub temp_c: Option<f64>,
    /// A thermal record was applied outside its calibrated temperature range in a recorded set.
    pub out_of_range: bool,
    /// Every component within its bound (with a specification: every component accepted by its
    /// decision rule).
    pub pass: bool,
    /// With a specification: the expanded uncertainty (k = 2) of each component's measured error,
    /// m/s².
    #[serde(default, rename = "U_m_s2", skip_serializing_if = "Option::is_none")]
    pub u_expanded_m_s2: Option<[f64; 3]>,
    /// With a specification: the decision on each component.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub decisions: Option<[Decision; 3]>,
}

/// A verification's result.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct VerifyReport {
    /// `accelcal_core::document::VERIFY_VERSION` (0: written before documents carried a
    /// version).
    #[serde(default)]
    pub version: u32,
    /// The node's device id (hex).
    pub device_id: String,
    /// The record in force: slot, sequence, created, CRC (hex).
    pub record: serde_json::Value,
    /// Gravity used, m/s².
    pub g_m_s2: f64,
    /// The chamber setpoint of the verification, °C (`null`: none set).
    pub chamber_c: Option<f64>,
    /// The tolerance rule in words.
    pub tolerance_rule: String,
    /// The static rule in words.
    pub static_rule: String,
    /// Every position checked.
    pub positions: Vec<PositionCheck>,
    /// Every position passed (false also when interrupted).
    pub pass: bool,
    /// Stopped on request before the end.
    pub interrupted: bool,
    /// Whose fit the tolerance came from (`--fit`), as its JSON states it (`null`: no fit given).
    #[serde(default)]
    pub fit: Option<Identity>,
    /// The specification and decision rule applied (`--spec`), when one was.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub specification: Option<Specification>,
    /// The worst decision over every position and component (and parameter), when a
    /// specification was applied.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub decision: Option<Decision>,
    /// With a specification that limits them: the bias, scale-factor and misalignment errors the
    /// ±axis positions measure, each decided ([`crate::conformity::parameters`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub parameters: Option<Vec<ParameterCheck>>,
}

impl VerifyReport {
    /// The largest |error| of a component over the positions, m/s² (0 without a position).
    pub fn max_abs_error_m_s2(&self) -> f64 {
        self.positions.iter().flat_map(|p| p.error_m_s2).fold(0.0, |m, e| m.max(e.abs()))
    }

    /// Why the verification did not pass, or `None` when it passed: the positions outside
    /// their tolerance and the parameters not accepted.
    pub fn failure(&self) -> Option<Failed> {
        // A position not accepted whose every component is inside T lies in the guard band.
        let in_band =
            |p: &PositionCheck| p.decisions.is_some_and(|d| d.iter().all(|d| !d.out_of_tolerance()));
        let conditional = self.positions.iter().filter(|p| !p.pass && in_band(p)).count();
        let failed = self.positions.iter().filter(|p| !p.pass && !in_band(p)).count();
        let parameters: Vec<String> = self
            .parameters
            .iter()
            .flatten()
            .filter(|c| !c.decision.accepted())
            .map(|c| {
                format!(
                    "{} {} {:+.4} {} ({})",
                    c.parameter.replace('_', " "),
                    c.axis,
                    c.value,
                    c.unit,
                    c.decision.name()
                )
            })
            .collect();
        let total = self.positions.len();
        (failed + conditional > 0 || !parameters.is_empty() || total == 0).then_some(Failed {
            failed,
            conditional,
            total,
            parameters,
        })
    }

    /// Parses a report that `verify --json` wrote; a later version than this build writes is
    /// refused (`accelcal_core::document::check_version`).
    pub fn parse(text: &str) -> Result<VerifyReport, serde_json::Error> {
        use super::{check_version, VERIFY_VERSION};
        let report: VerifyReport = serde_json::from_str(text)?;
        check_version("verify", report.version, VERIFY_VERSION)?;
        Ok(report)
    }

    /// Reads a report that `verify --json` wrote.
    pub fn read(path: &std::path::Path) -> anyhow::Result<VerifyReport> {
        let name = path.display();
        let text = std::fs::read_to_string(path).map_err(|e| bad(format!("{name}: cannot read: {e}")))?;
        VerifyReport::parse(&text)
            .map_err(|e| bad(format!("{name}: not the JSON report `accelcal verify` writes: {e}")))
    }
}
