//! Verification of a calibrated node (`accelcal verify`): with the node streaming calibrated
//! acceleration, each position of a plan is set, the stream is let settle ([`StaticRule`]), and
//! the mean acceleration is compared with what the head imposes, `g` times the paper's
//! kinematics (`accelcal_shared::gravity`).
//!
//! A position passes when every component's error is within its tolerance. The tolerance is
//! either given (`--tolerance`, m/s², the same for every component) or derived per position and
//! component as `K · sqrt(σ_cal² + σ_mean²)` with the coverage factor `K` (`--coverage`, default
//! [`DEFAULT_COVERAGE`]): `σ_mean` is the standard error of the measured mean (the recorded sets'
//! scatter over √N), `σ_cal` the uncertainty of the calibration at that acceleration propagated
//! from the fit (`fit --json`): `sqrt(φᵀ C φ) / |k_ii|` for channel i, with `φ` its terms' values
//! (model 4: `1`, `ax`, `ay`, `az`; a thermal fit's terms in `t` too, at the position's mean
//! temperature), `C` the coefficients' covariance matrix and `k_ii` the own-axis sensitivity (at
//! that temperature). A fit JSON without `covariance` (written before it had one) gives the
//! standard errors only: `C` is then taken diagonal and the rule says so. Without a fit, `σ_cal`
//! is 0 and the rule says so.
//!
//! With `K` = 4 and Gaussian errors, one component of a correctly calibrated node falls outside
//! with probability 6.3·10⁻⁵, so a six-position verification (18 components) fails a good node
//! about once in 900 runs; `K` = 5 makes that once in 10⁵.

use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use accelcal_shared::terms::Term;
use accelcal_shared::wire::{Block, Output, RecordStatus};

use crate::acquire::{block_kind, capture, Captured, StaticRule};
use crate::head::{Positioner, Target};
use crate::node::session::{device_id_hex, record_json, Session};
use accelcal_core::campaign::identity::{self, Identity};
use accelcal_core::conformity::{measured_error_u, parameters, Measured, Specification, VerifyReferences};
pub use accelcal_core::document::verify::{Failed, PositionCheck, VerifyReport};
use accelcal_core::document::FitDoc;
use accelcal_core::error::bad;
use accelcal_core::sim::Plan;

/// Coverage factor of the derived tolerance when `--coverage` is not given.
pub const DEFAULT_COVERAGE: f64 = 4.0;

/// The static rule for calibrated streams: the default windows, with a per-set floor of half an
/// LSB of a ±2 g 16-bit ADC (3·10⁻⁴ m/s²).
pub fn calibrated_rule() -> StaticRule {
    StaticRule { min_sd: 3e-4, ..StaticRule::default() }
}

/// One channel's calibration uncertainty, from the fit's standard errors.
#[derive(Clone, Debug, PartialEq)]
pub struct ChannelUncertainty {
    /// The fit's terms with their standard errors (codes per unit of the term): model 4's `1`,
    /// `ax`, `ay`, `az`, and a thermal fit's terms in `t` too.
    pub terms: Vec<(Term, f64)>,
    /// The coefficients' covariance matrix in the order of `terms`, when the fit JSON has it.
    pub covariance: Option<Vec<Vec<f64>>>,
    /// The channel's own-axis sensitivity, codes per m/s², at the reference temperature.
    pub k_own: f64,
    /// Its temperature coefficient (the own axis's `·t` term), codes per m/s² per °C; 0 without.
    pub k_own_t: f64,
}

impl ChannelUncertainty {
    /// Standard uncertainty of the calibrated acceleration along the channel's axis at `a`
    /// (m/s²) and `t` (°C from the fit's reference temperature), m/s²: `sqrt(φᵀ C φ)` over the
    /// own-axis sensitivity at `t`, `φ` the terms' values and `C` the covariance matrix (diagonal
    /// from the standard errors when there is none).
    pub fn sigma(&self, a: [f64; 3], t: f64) -> f64 {
        let x = [a[0], a[1], a[2], t];
        let phi: Vec<f64> = self.terms.iter().map(|(term, _)| term.eval(x)).collect();
        let v: f64 = match &self.covariance {
            Some(c) => {
                (0..phi.len()).map(|i| (0..phi.len()).map(|j| phi[i] * c[i][j] * phi[j]).sum::<f64>()).sum()
            }
            None => self.terms.iter().zip(&phi).map(|((_, se), f)| (se * f).powi(2)).sum(),
        };
        // A covariance matrix is positive semi-definite; rounding may leave a tiny negative.
        v.max(0.0).sqrt() / (self.k_own + self.k_own_t * t).abs()
    }
}

/// The calibration's uncertainty on the three channels, from `fit --json`.
#[derive(Clone, Debug, PartialEq)]
pub struct CalUncertainty {
    /// Channels x, y, z.
    pub channels: [ChannelUncertainty; 3],
    /// The fit's reference temperature, °C (`t = temp_c − t_ref`); `None` for a fit without
    /// terms in `t`.
    pub t_ref_c: Option<f64>,
}

impl CalUncertainty {
    /// `t` at a position whose mean temperature is `temp_c`: 0 for a fit without thermal terms
    /// and where the node reported no temperature (the calibration at its reference).
    fn t(&self, temp_c: Option<f64>) -> f64 {
        match (self.t_ref_c, temp_c) {
            (Some(t_ref), Some(temp)) => temp - t_ref,
            _ => 0.0,
        }
    }
}

/// How the tolerance is set.
#[derive(Clone, Debug, PartialEq)]
pub enum Tolerance {
    /// The same bound for every component, m/s².
    Fixed(f64),
    /// Derived from the measurement's scatter and, when known, the fit's uncertainty, with
    /// coverage factor `k`.
    Derived {
        /// The calibration's uncertainty, from `fit --json`.
        cal: Option<Box<CalUncertainty>>,
        /// Coverage factor (> 0).
        k: f64,
    },
}

impl Tolerance {
    /// The rule in words.
    pub fn describe(&self) -> String {
        match self {
            Tolerance::Fixed(t) => format!("|error| <= {t} m/s² on every component (--tolerance)"),
            Tolerance::Derived { cal: Some(c), k } => format!(
                "|error| <= {k}·sqrt(σ_cal² + σ_mean²) per component: σ_cal from the fit's {} at the position's \
                 acceleration{}, σ_mean the standard error of the measured mean",
                if c.channels.iter().all(|ch| ch.covariance.is_some()) {
                    "covariance matrix"
                } else {
                    "standard errors (the fit JSON has no covariance: the terms' covariances are left out)"
                },
                if c.t_ref_c.is_some() { " and temperature" } else { "" }
            ),
            Tolerance::Derived { cal: None, k } => format!(
                "|error| <= {k}·σ_mean per component, σ_mean the standard error of the measured mean \
                 (no fit JSON given: the calibration's own uncertainty is not included)"
            ),
        }
    }

    /// Bounds for one position's components, at its mean temperature `temp_c` (°C) when known.
    fn bounds(&self, expected: [f64; 3], temp_c: Option<f64>, sd_mean: [f64; 3]) -> [f64; 3] {
        match self {
            Tolerance::Fixed(t) => [*t; 3],
            Tolerance::Derived { cal, k } => {
                let mut b = [0.0; 3];
                for i in 0..3 {
                    let s_cal = cal.as_ref().map_or(0.0, |c| c.channels[i].sigma(expected, c.t(temp_c)));
                    b[i] = k * (s_cal * s_cal + sd_mean[i] * sd_mean[i]).sqrt();
                }
                b
            }
        }
    }
}

/// A channel's `covariance` from a fit JSON: `n` rows of `n` finite numbers, symmetric, with a
/// non-negative diagonal.
fn covariance_of(rows: &[Vec<Option<f64>>], n: usize) -> Result<Vec<Vec<f64>>, String> {
    if rows.len() != n {
        return Err(format!("`covariance` is not {n} rows"));
    }
    let mut m = Vec::with_capacity(n);
    for (i, r) in rows.iter().enumerate() {
        if r.len() != n {
            return Err(format!("`covariance` row {i} is not {n} numbers"));
        }
        let row: Option<Vec<f64>> = r.iter().map(|v| v.filter(|v| v.is_finite())).collect();
        m.push(row.ok_or_else(|| format!("`covariance` row {i} has a value that is not a finite number"))?);
    }
    for i in 0..n {
        if m[i][i] < 0.0 {
            return Err(format!("`covariance` has a negative variance at {i}"));
        }
        for j in 0..i {
            if (m[i][j] - m[j][i]).abs() > 1e-9 * (m[i][i] * m[j][j]).sqrt() {
                return Err(format!("`covariance` is not symmetric at ({i}, {j})"));
            }
        }
    }
    Ok(m)
}

/// Reads the calibration's uncertainty from `fit --json` output: model 4 of channels x, y, z,
/// with or without terms in `t` (then the document's `t_ref_c` is needed).
pub fn uncertainty_from_fit_json(text: &str, what: &str) -> anyhow::Result<CalUncertainty> {
    let doc = FitDoc::parse(text).map_err(|e| bad(format!("{what}: not `fit --json` output: {e}")))?;
    let mut out = Vec::with_capacity(3);
    let mut thermal = false;
    for (i, name) in ["x", "y", "z"].iter().enumerate() {
        let ch = doc.channel(name).ok_or_else(|| bad(format!("{what}: no channel `{name}`")))?;
        let names: Vec<&str> = ch.terms.iter().map(String::as_str).collect();
        let num = |key: &str, at: usize, term: &str| -> anyhow::Result<f64> {
            let v = match key {
                "coefficients" => ch.coefficients.get(at).copied(),
                _ => ch.std_errors.get(at).copied().flatten(),
            };
            v.filter(|v| v.is_finite())
                .ok_or_else(|| bad(format!("{what}: channel {name}: no finite {key} for `{term}`")))
        };
        let mut terms = Vec::with_capacity(names.len());
        for (at, n) in names.iter().enumerate() {
            let term = Term::parse(n).map_err(|e| bad(format!("{what}: channel {name}: term `{n}`: {e}")))?;
            thermal |= term.is_thermal();
            terms.push((term, num("std_errors", at, n)?));
        }
        for needed in ["1", "ax", "ay", "az"] {
            if !names.contains(&needed) {
                return Err(bad(format!(
                    "{what}: channel {name} has no term `{needed}`: verification needs a model-4 fit"
                )));
            }
        }
        let coefficient = |term: &str| -> anyhow::Result<f64> {
            names.iter().position(|t| *t == term).map_or(Ok(0.0), |at| num("coefficients", at, term))
        };
        let own = ["ax", "ay", "az"][i];
        let k_own = coefficient(own)?;
        if k_own == 0.0 {
            return Err(bad(format!("{what}: channel {name} has a zero own-axis sensitivity")));
        }
        let covariance = match ch.covariance.as_slice() {
            [] => None,
            c => {
                Some(covariance_of(c, names.len()).map_err(|e| bad(format!("{what}: channel {name}: {e}")))?)
            }
        };
        out.push(ChannelUncertainty { terms, covariance, k_own, k_own_t: coefficient(&format!("{own}*t"))? });
    }
    let t_ref_c = if thermal {
        Some(doc.t_ref_c.filter(|t| t.is_finite()).ok_or_else(|| {
            bad(format!("{what}: the fit has terms in t but no `t_ref_c` (write it again with `fit --json`)"))
        })?)
    } else {
        None
    };
    let channels: [ChannelUncertainty; 3] =
        out.try_into().map_err(|_| bad(format!("{what}: three channels x, y, z expected")))?;
    Ok(CalUncertainty { channels, t_ref_c })
}

/// Settings of a verification.
#[derive(Clone, Debug)]
pub struct VerifyConfig {
    /// The positions.
    pub plan: Plan,
    /// Sets averaged per position.
    pub samples: usize,
    /// When the stream is static (m/s²).
    pub rule: StaticRule,
    /// How long a position may take to become static.
    pub settle_timeout: Duration,
    /// The head's part of the settled rule (read-back tolerance, wait after the move).
    pub settle: crate::head::Settle,
    /// Local gravity, m/s².
    pub g: f64,
    /// The pass bound.
    pub tolerance: Tolerance,
    /// Verify at this chamber setpoint (°C), after this soak.
    pub chamber: Option<(f64, Duration)>,
    /// The fit whose uncertainty sets the tolerance (`--fit`): its name and whose it is. The node
    /// must be its unit and run its record.
    pub fit: Option<(String, Identity)>,
    /// The product specification and its decision rule (`--spec`), with the references'
    /// uncertainties the measured errors' U takes: each position passes when the rule accepts
    /// every component (instead of the consistency bound `tolerance`).
    pub spec: Option<(Specification, VerifyReferences)>,
}

/// Refuses a fit that is not the node's: another device id, or a record other than the one the
/// node runs (the fit JSON names the record written with it; a fit JSON written without one
/// cannot be matched and is refused too).
fn check_fit(
    fit: &(String, Identity),
    node: &str,
    device_id: &str,
    record: RecordStatus,
) -> anyhow::Result<()> {
    let (what, id) = fit;
    if let Some(d) = &id.device_id {
        identity::same("device id", (what, d), (node, device_id), "not the same unit")?;
    }
    let crc = id.written_record(what, "the record the node runs")?;
    if let RecordStatus::InUse { crc: running, .. } = record {
        identity::same(
            "record CRC",
            (what, crc),
            (node, &format!("{running:08x}")),
            "the node does not run the record of this fit (flash it, or give its own fit JSON)",
        )?;
    }
    Ok(())
}

/// Calibrated blocks as values in m/s².
fn calibrated_values(b: &Block) -> Result<Vec<[f64; 3]>, String> {
    match b {
        Block::Calibrated(v) => Ok(v.iter().map(|a| a.map(f64::from)).collect()),
        Block::CalibratedFixed(v) => {
            Ok(v.iter().map(|a| a.map(|q| q as f64 / accelcal_shared::contract::FIXED_SCALE)).collect())
        }
        Block::Uncalibrated(_) => {
            Err("the node has no valid record: it streams uncalibrated codes (see `accelcal info`)".into())
        }
        other => Err(format!(
            "the node streams {} blocks after it was switched to calibrated output",
            block_kind(other)
        )),
    }
}

/// Refuses a plan (head angles α, β in degrees) without the ±axis positions that measure the
/// parameters `spec` limits (bad input: checked before the node is touched).
pub fn plan_measures_parameters(
    spec: &Specification,
    positions: &[(f64, f64)],
    g: f64,
) -> anyhow::Result<()> {
    let planned: Vec<Measured> = positions
        .iter()
        .map(|&(a, b)| Measured {
            expected_m_s2: accelcal_shared::gravity(a, b, g),
            error_m_s2: [0.0; 3],
            u_expanded_m_s2: [0.0; 3],
        })
        .collect();
    parameters(spec, g, &planned).map(|_| ()).map_err(|e| bad(e.to_string()))
}

/// Runs a verification; `on_position` sees each check as it is made.
pub fn verify(
    node: &mut Session,
    head: &mut dyn Positioner,
    cfg: &VerifyConfig,
    on_position: &mut dyn FnMut(&PositionCheck, usize),
    stop: &AtomicBool,
) -> anyhow::Result<VerifyReport> {
    if let Some((spec, _)) = &cfg.spec {
        plan_measures_parameters(spec, &cfg.plan.positions, cfg.g)?;
    }
    let info = node.info()?;
    if let RecordStatus::Missing(f) = info.record {
        return Err(bad(format!(
            "{}: the node has no record in force ({f}): nothing to verify",
            node.port()
        )));
    }
    if let Some(fit) = &cfg.fit {
        let who = format!("the node on {}", node.port());
        check_fit(fit, &who, &device_id_hex(&info.device_id), info.record)?;
    }
    let before = info.output;
    node.set_output(Output::Calibrated)?;
    let mut report = VerifyReport {
        version: accelcal_core::document::VERIFY_VERSION,
        device_id: device_id_hex(&info.device_id),
        record: record_json(info.record),
        g_m_s2: cfg.g,
        chamber_c: cfg.chamber.map(|c| c.0),
        tolerance_rule: cfg.tolerance.describe(),
        static_rule: cfg.rule.describe(),
        positions: Vec::new(),
        pass: false,
        interrupted: false,
        fit: cfg.fit.as_ref().map(|(_, id)| id.clone()),
        specification: cfg.spec.as_ref().map(|(s, _)| s.clone()),
        decision: None,
        parameters: None,
    };
    if let Some((spec, _)) = &cfg.spec {
        report.tolerance_rule = spec.describe();
        if spec.limits_parameters() {
            report.tolerance_rule.push_str(&format!("; {}", spec.describe_parameters()));
        }
    }
    let result = run(node, head, cfg, on_position, stop, &mut report);
    let restored = if before != Output::Calibrated { node.set_output(before).map(|_| ()) } else { Ok(()) };
    result?;
    restored?;
    if let Some((spec, _)) = cfg.spec.as_ref().filter(|(s, _)| s.limits_parameters() && !report.interrupted) {
        let measured: Vec<Measured> = report
            .positions
            .iter()
            .filter_map(|p| {
                Some(Measured {
                    expected_m_s2: p.expected_m_s2,
                    error_m_s2: p.error_m_s2,
                    u_expanded_m_s2: p.u_expanded_m_s2?,
                })
            })
            .collect();
        report.parameters = Some(parameters(spec, cfg.g, &measured).map_err(|e| bad(e.to_string()))?);
    }
    let params = report.parameters.as_deref().unwrap_or_default();
    report.pass = !report.interrupted
        && report.positions.iter().all(|p| p.pass)
        && params.iter().all(|c| c.decision.accepted());
    report.decision = report
        .positions
        .iter()
        .filter_map(|p| p.decisions)
        .flatten()
        .chain(params.iter().map(|c| c.decision))
        .max();
    Ok(report)
}

fn run(
    node: &mut Session,
    head: &mut dyn Positioner,
    cfg: &VerifyConfig,
    on_position: &mut dyn FnMut(&PositionCheck, usize),
    stop: &AtomicBool,
    report: &mut VerifyReport,
) -> anyhow::Result<()> {
    let n = cfg.plan.positions.len();
    head.home()?;
    if let Some((setpoint_c, soak)) = cfg.chamber {
        if !crate::acquire::soak(node, head, setpoint_c, soak, stop)? {
            report.interrupted = true;
            return Ok(());
        }
    }
    for (k, &(a, b)) in cfg.plan.positions.iter().enumerate() {
        let expected = accelcal_shared::gravity(a, b, cfg.g);
        let mut read_back;
        let cap = loop {
            let target = Target { k, n, angles: (a, b).into(), expected_m_s2: expected };
            read_back = head.set(&target)?;
            if stop.load(Ordering::Relaxed) {
                report.interrupted = true;
                return Ok(());
            }
            crate::head::settled(&head.describe(), &target, read_back, cfg.settle.tolerance_arcsec)?;
            if !crate::acquire::dwell(&mut [&mut *node], cfg.settle.wait, stop)? {
                report.interrupted = true;
                return Ok(());
            }
            match capture(node, cfg.rule, cfg.settle_timeout, cfg.samples, stop, calibrated_values)? {
                Captured::Done(c) => break c,
                Captured::Stopped => {
                    report.interrupted = true;
                    return Ok(());
                }
                Captured::Unsettled(why) => {
                    if !head.retry(k, &why)? {
                        return Err(bad(format!(
                            "position {} of {n} (alpha {a} deg, beta {b} deg): {why}",
                            k + 1
                        )));
                    }
                }
            }
        };
        let measured = cap.mean();
        let sd_mean = cap.sd().map(|s| s / (cap.sets.len() as f64).sqrt());
        let error = [0, 1, 2].map(|i| measured[i] - expected[i]);
        let temp_c = cap.mean_temp_c();
        let bound = cfg.tolerance.bounds(expected, temp_c, sd_mean);
        let judged = cfg.spec.as_ref().map(|(spec, refs)| {
            let u = measured_error_u(a, b, cfg.g, sd_mean, *refs);
            (u, [0, 1, 2].map(|i| spec.decide(error[i], u[i])))
        });
        let pass = match judged {
            Some((_, d)) => d.iter().all(|d| d.accepted()),
            None => (0..3).all(|i| error[i].abs() <= bound[i]),
        };
        let check = PositionCheck {
            position: k + 1,
            alpha_deg: a,
            beta_deg: b,
            read_back_alpha_deg: Some(read_back.alpha_deg),
            read_back_beta_deg: Some(read_back.beta_deg),
            expected_m_s2: expected,
            measured_m_s2: measured,
            error_m_s2: error,
            sd_mean_m_s2: sd_mean,
            tolerance_m_s2: bound,
            lost: cap.lost,
            temp_c,
            out_of_range: cap.out_of_range,
            pass,
            u_expanded_m_s2: judged.map(|j| j.0),
            decisions: judged.map(|j| j.1),
        };
        on_position(&check, n);
        report.positions.push(check);
    }
    Ok(())
}

#[cfg(test)]
mod tests;
