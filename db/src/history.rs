//! A unit's history from its stored runs: every run, the coefficient drift between consecutive
//! calibrations with its uncertainty, the as-found results, and the recommended recalibration
//! date ([`METHOD`] says how).
//!
//! A calibration is a run that ended `pass` with a stored fit of model 4 (terms `1`, `ax`, `ay`,
//! `az` on channels x, y, z). Each coefficient is expressed as the error it makes in the
//! channel's calibrated acceleration at 1 g, so that all twelve compare with one tolerance in
//! m/s²: for channel c with own-axis sensitivity k_c (of the latest calibration), the bias `u0`
//! as `u0 / k_c`, a sensitivity `k_cj` as `k_cj · g / k_c`. Their variances come from the fits'
//! covariance matrices (the diagonal; a fit JSON without `covariance` gives its standard errors).

use serde::Serialize;

use super::{Outcome, RunSummary};
use accelcal_core::document::verify::VerifyReport;
use accelcal_core::document::FitDoc;

/// The recommended recalibration date's method, as `history --help` and the guide (docs/src/line/database.md) state it.
pub const METHOD: &str = "Recalibration date: each of the 12 model-4 coefficients (bias and 3 \
sensitivities of channels x, y, z), expressed as the acceleration error it makes at 1 g (m/s²), is fitted \
against time over the unit's calibrations by weighted least squares (weights 1/σ² from the fits' covariances; \
the standard error scaled up by sqrt(χ²/(n−2)) when n > 2 calibrations scatter more than the covariances say): \
drift rate r ± s_r. From the last calibration the drift reaches the tolerance T (--tolerance-m-s2) after \
τ = T / (|r| + k·s_r) (k: --coverage); the recommended date is the last calibration plus the smallest τ of the \
12, at most --max-interval-days and at least --min-interval-days (the floor). With one calibration no drift is known yet: the date is the calibration plus \
--max-interval-days. Calibrations less than 1 day apart are repeats: the rate uses the latest of them. A \
calibration is a run that ended `pass` with a stored model-4 fit; unfinished, rejected and voided runs are \
listed but not used. An as-found result out of tolerance shortens the interval (ILAC-G24 method 1, the \
staircase): when the last calibration's as-found verification was out of tolerance (its decision rule's \
conditional fail or fail, against a specification; otherwise an error beyond T on a component at one of its \
positions), the recommended date is at most half the interval the unit had just served after it (the days \
since the latest calibration at least 1 day before it; half of --max-interval-days when the database holds \
none), and at least --min-interval-days. A certificate may state the laboratory's own interval instead \
(`report --interval-days`).";

/// Settings of the recalibration rule.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct RecalRule {
    /// The tolerance T, m/s² (the error at 1 g the drift may reach).
    pub tolerance_m_s2: f64,
    /// The coverage factor k on the rate's standard error.
    pub coverage: f64,
    /// The longest interval recommended, days.
    pub max_interval_days: f64,
    /// The shortest interval recommended, days: the floor under the drift's interval and under
    /// an interval halved after an as-found result out of tolerance.
    pub min_interval_days: f64,
    /// The interval the laboratory decided for this unit, days (`report --interval-days`):
    /// stated instead of the drift's, as the laboratory's decision.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub decided_interval_days: Option<f64>,
}

/// `history`'s default rule, also the certificate's: 0.05 m/s² at 1 g, k = 2, at least 30 days
/// and at most a year.
pub const DEFAULT_RULE: RecalRule = RecalRule {
    tolerance_m_s2: 0.05,
    coverage: 2.0,
    max_interval_days: 365.0,
    min_interval_days: 30.0,
    decided_interval_days: None,
};

/// A verification in a few numbers.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct VerifySummary {
    /// Every position passed.
    pub pass: bool,
    /// Positions checked.
    pub positions: usize,
    /// Positions outside their tolerance.
    pub failed: usize,
    /// The largest |error| of a component, m/s².
    pub max_abs_error_m_s2: f64,
}

impl VerifySummary {
    fn of(r: &VerifyReport) -> VerifySummary {
        VerifySummary {
            pass: r.pass,
            positions: r.positions.len(),
            failed: r.positions.iter().filter(|p| !p.pass).count(),
            max_abs_error_m_s2: r.max_abs_error_m_s2(),
        }
    }
}

/// One run of the unit.
#[derive(Clone, Debug, Serialize)]
pub struct RunLine {
    /// The run's id.
    pub run_id: String,
    /// When it started, Unix seconds.
    pub started_unix_s: i64,
    /// Station, head, operator.
    pub station: String,
    /// The dividing head.
    pub head: String,
    /// Who ran it.
    pub operator: String,
    /// accelcal's version.
    pub software_version: String,
    /// The node's firmware.
    pub firmware_version: String,
    /// g, m/s², and where it came from.
    pub g_m_s2: f64,
    /// Where g came from.
    pub g_source: String,
    /// `pass`, `rejected`, or `null` while the run is not finished (killed and not resumed).
    pub outcome: Option<Outcome>,
    /// Why it ended so (empty while not finished).
    pub reason: String,
    /// The stored record's CRC-32 (8 hex digits).
    pub record_crc32: Option<String>,
    /// When the record was flashed, Unix seconds.
    pub flashed_unix_s: Option<i64>,
    /// Whether the run counts as a calibration (its number among them, from 1).
    pub calibration: Option<usize>,
    /// Why a finished run with outcome pass is not a calibration.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub not_a_calibration: Option<String>,
    /// The as-found verification.
    pub as_found: Option<VerifySummary>,
    /// The as-left verification.
    pub as_left: Option<VerifySummary>,
    /// Why the run was voided (`accelcal void`): a voided run is listed, never used.
    pub voided: Option<String>,
    /// When it was voided, Unix seconds.
    pub voided_unix_s: Option<i64>,
    /// Why the run's rows are not the ones stored (they do not match their hash chain): such a
    /// run is listed, never used.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub tampered: Option<String>,
    /// Where its certificate in force stands (`awaiting_approval`, `approved`, `rejected`);
    /// absent when it has none.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub certificate_state: Option<super::signer::CertificateState>,
    /// The number of its certificate in force (its newest amendment's, else its first).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub certificate_number: Option<String>,
    /// The numbers of its certificates that amendments replaced, oldest first: superseded.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub superseded_certificates: Vec<String>,
}

/// One coefficient's change between two calibrations.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct TermDrift {
    /// The channel (`x`, `y`, `z`).
    pub channel: &'static str,
    /// The term (`1`, `ax`, `ay`, `az`).
    pub term: &'static str,
    /// The change, as an acceleration error at 1 g, m/s².
    pub delta_m_s2: f64,
    /// Its standard uncertainty, m/s² (both fits' variances).
    pub sigma_m_s2: f64,
}

/// The drift between two consecutive calibrations.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Drift {
    /// The earlier calibration's number.
    pub from: usize,
    /// The later one's.
    pub to: usize,
    /// Days between them.
    pub days: f64,
    /// Every coefficient (channels x, y, z; terms 1, ax, ay, az).
    pub terms: Vec<TermDrift>,
}

/// The coefficient that sets the recalibration date.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Limiting {
    /// The channel.
    pub channel: &'static str,
    /// The term.
    pub term: &'static str,
    /// Its drift rate, m/s² per year.
    pub rate_m_s2_per_year: f64,
    /// The rate's standard error, m/s² per year.
    pub rate_se_m_s2_per_year: f64,
    /// Days from the last calibration until |r|·τ + k·s_r·τ reaches the tolerance.
    pub days_to_tolerance: f64,
}

/// The recommended recalibration.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Recalibration {
    /// How it is found.
    pub method: &'static str,
    /// The rule's settings.
    pub rule: RecalRule,
    /// Calibrations it used.
    pub calibrations: usize,
    /// The recommended date, Unix seconds (`null` without a calibration).
    pub due_unix_s: Option<i64>,
    /// The coefficient whose drift sets it (`null`: the maximum interval does).
    pub limiting: Option<Limiting>,
    /// What set the date, in words.
    pub basis: String,
    /// The last calibration's as-found result was out of tolerance (`null`: it was not, or
    /// there was none): the interval it allows ([`METHOD`]).
    pub as_found_out_of_tolerance: Option<AsFoundShortening>,
}

/// An as-found result out of tolerance, and the interval it allows (ILAC-G24 method 1).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct AsFoundShortening {
    /// What was out of tolerance, in words.
    pub finding: String,
    /// The interval the unit had served: days from the calibration before to the last one
    /// (`null`: the database holds no calibration before it).
    pub served_days: Option<f64>,
    /// The longest interval it allows, days: half of the served one (at least 1 day), else half
    /// of the maximum interval.
    pub interval_days: f64,
}

/// Why an as-found verification was out of tolerance, or `None`: its decision against a
/// specification, else its largest error against the rule's tolerance `T`.
fn out_of_tolerance(v: &VerifyReport, rule: RecalRule) -> Option<String> {
    match (v.decision, &v.specification) {
        (Some(d), Some(spec)) => d.out_of_tolerance().then(|| {
            format!(
                "as found {} against the specification of {} (decision rule {})",
                d.name(),
                spec.unit_type,
                spec.rule.name()
            )
        }),
        (Some(d), None) => d.out_of_tolerance().then(|| format!("as found {}", d.name())),
        (None, _) => {
            let max = v.max_abs_error_m_s2();
            (max > rule.tolerance_m_s2).then(|| {
                format!("as found error {max:.4} m/s² beyond the tolerance {} m/s²", rule.tolerance_m_s2)
            })
        }
    }
}

/// A unit's history.
#[derive(Clone, Debug, Serialize)]
pub struct History {
    /// The unit's device id.
    pub device_id: String,
    /// Its serial numbers, as the runs give them (empty ones left out), in order of first use.
    pub serials: Vec<String>,
    /// Every run, oldest first.
    pub runs: Vec<RunLine>,
    /// The drift between consecutive calibrations.
    pub drifts: Vec<Drift>,
    /// The recommended recalibration.
    pub recalibration: Recalibration,
    /// The unit's runs that do not read (a cell that does not read as its column's type,
    /// [`crate::Db::listing_unreadable`]): named, never used.
    pub unreadable: Vec<super::cells::UnreadableRun>,
}

const CHANNELS: [&str; 3] = ["x", "y", "z"];
const TERMS: [&str; 4] = ["1", "ax", "ay", "az"];
const SECONDS_PER_DAY: f64 = 86_400.0;
const DAYS_PER_YEAR: f64 = 365.25;

/// One calibration's model-4 coefficients and their variances, `[channel][term]`.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Model4 {
    pub(crate) coef: [[f64; 4]; 3],
    var: [[f64; 4]; 3],
}

/// The model-4 part of a stored fit, or why there is none.
pub(crate) fn model4(fit_json: &str) -> Result<Model4, String> {
    let doc = FitDoc::parse(fit_json).map_err(|e| format!("its fit is not `fit --json` output: {e}"))?;
    model4_of(&doc)
}

/// The model-4 part of a fit document, or why there is none.
pub(crate) fn model4_of(doc: &FitDoc) -> Result<Model4, String> {
    let mut m = Model4 { coef: [[0.0; 4]; 3], var: [[0.0; 4]; 3] };
    for (c, name) in CHANNELS.iter().enumerate() {
        let ch = doc.channel(name).ok_or(format!("its fit has no channel {name}"))?;
        for (t, term) in TERMS.iter().enumerate() {
            let at = ch
                .terms
                .iter()
                .position(|x| x == term)
                .ok_or(format!("its fit's channel {name} has no term `{term}` (model 4 is needed)"))?;
            m.coef[c][t] =
                *ch.coefficients.get(at).ok_or(format!("its fit's channel {name} lacks coefficients"))?;
            let from_cov = ch.covariance.get(at).and_then(|row| row.get(at).copied().flatten());
            let from_se = ch.std_errors.get(at).copied().flatten().map(|s| s * s);
            m.var[c][t] = from_cov.or(from_se).filter(|v| v.is_finite() && *v >= 0.0).unwrap_or(0.0);
        }
        if m.coef[c][c + 1] == 0.0 {
            return Err(format!("its fit's channel {name} has a zero own-axis sensitivity"));
        }
    }
    Ok(m)
}

/// A calibration in the common scale: `q[channel][term]` m/s² at 1 g, and its σ.
#[derive(Clone)]
struct Scaled {
    t_days: f64,
    q: [[f64; 4]; 3],
    sigma: [[f64; 4]; 3],
}

fn scaled(m: &Model4, t_days: f64, k_ref: [f64; 3], g: f64) -> Scaled {
    let mut s = Scaled { t_days, q: [[0.0; 4]; 3], sigma: [[0.0; 4]; 3] };
    for c in 0..3 {
        for t in 0..4 {
            let scale = if t == 0 { 1.0 } else { g } / k_ref[c];
            s.q[c][t] = m.coef[c][t] * scale;
            s.sigma[c][t] = m.var[c][t].sqrt() * scale.abs();
        }
    }
    s
}

/// A straight line's slope fitted to `(t, y, σ)`: slope and its standard error (per unit of t).
/// Weighted by 1/σ² when every σ is positive, else unweighted with the residuals' scatter.
fn slope(points: &[(f64, f64, f64)]) -> (f64, f64) {
    let n = points.len();
    let weighted = points.iter().all(|p| p.2 > 0.0);
    let w = |p: &(f64, f64, f64)| if weighted { 1.0 / (p.2 * p.2) } else { 1.0 };
    let (mut s, mut sx, mut sy, mut sxx, mut sxy) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for p in points {
        let wi = w(p);
        s += wi;
        sx += wi * p.0;
        sy += wi * p.1;
        sxx += wi * p.0 * p.0;
        sxy += wi * p.0 * p.1;
    }
    let d = s * sxx - sx * sx;
    if d <= 0.0 {
        return (0.0, 0.0);
    }
    let r = (s * sxy - sx * sy) / d;
    let a = (sy - r * sx) / s;
    let chi2: f64 = points.iter().map(|p| w(p) * (p.1 - a - r * p.0).powi(2)).sum();
    let var = if weighted {
        let scale = if n > 2 { (chi2 / (n - 2) as f64).max(1.0) } else { 1.0 };
        s / d * scale
    } else if n > 2 {
        s / d * chi2 / (n - 2) as f64
    } else {
        0.0
    };
    (r, var.sqrt())
}

/// The unit's history from its runs (oldest first).
pub fn history(runs: &[RunSummary], rule: RecalRule) -> History {
    let mut lines = Vec::with_capacity(runs.len());
    let mut cals: Vec<(usize, i64, f64, Model4)> = Vec::new();
    for r in runs {
        let passed = matches!(r.end, Some((Outcome::Pass, _, _)));
        let model = match (&r.fit_json, passed, &r.voided) {
            _ if passed && r.tampered.is_some() => Some(Err(r.tampered.clone().unwrap_or_default())),
            (_, true, Some((why, _))) => Some(Err(format!("voided: {why}"))),
            (Some(f), true, None) => Some(model4(f)),
            (None, true, None) => Some(Err("no fit was stored".to_string())),
            _ => None,
        };
        let number = match &model {
            Some(Ok(m)) => {
                cals.push((lines.len(), r.start.started_unix_s, r.start.g_m_s2, m.clone()));
                Some(cals.len())
            }
            _ => None,
        };
        lines.push(RunLine {
            run_id: r.start.run_id.to_string(),
            started_unix_s: r.start.started_unix_s,
            station: r.start.station.clone(),
            head: r.start.head.clone(),
            operator: r.start.operator.clone(),
            software_version: r.start.software_version.clone(),
            firmware_version: r.start.firmware_version.clone(),
            g_m_s2: r.start.g_m_s2,
            g_source: r.start.g_source.clone(),
            outcome: r.end.as_ref().map(|e| e.0),
            reason: r.end.as_ref().map(|e| e.1.clone()).unwrap_or_default(),
            record_crc32: r.record_crc32.map(|c| format!("{c:08x}")),
            flashed_unix_s: r.flashed_unix_s,
            calibration: number,
            not_a_calibration: model.and_then(|m| m.err()),
            as_found: r.as_found.as_ref().map(VerifySummary::of),
            as_left: r.as_left.as_ref().map(VerifySummary::of),
            voided: r.voided.as_ref().map(|v| v.0.clone()),
            voided_unix_s: r.voided.as_ref().map(|v| v.1),
            tampered: r.tampered.clone(),
            certificate_state: r.certificate_state,
            certificate_number: r.certificate_number.clone(),
            superseded_certificates: r.superseded_certificates.clone(),
        });
    }
    let mut serials: Vec<String> = Vec::new();
    for r in runs.iter().filter(|r| r.voided.is_none()) {
        if !r.start.serial.is_empty() && !serials.contains(&r.start.serial) {
            serials.push(r.start.serial.clone());
        }
    }
    let (drifts, recalibration) = match cals.last() {
        None => (
            Vec::new(),
            Recalibration {
                method: METHOD,
                rule,
                calibrations: 0,
                due_unix_s: None,
                limiting: None,
                basis: "no complete calibration: nothing to recalibrate from".into(),
                as_found_out_of_tolerance: None,
            },
        ),
        Some(&(at, t_last, g_last, ref last)) => {
            let k_ref = [last.coef[0][1], last.coef[1][2], last.coef[2][3]];
            let scaled: Vec<Scaled> = cals
                .iter()
                .map(|(_, t, _, m)| scaled(m, (t - t_last) as f64 / SECONDS_PER_DAY, k_ref, g_last))
                .collect();
            let shortening =
                runs[at].as_found.as_ref().and_then(|v| out_of_tolerance(v, rule)).map(|finding| {
                    // The interval the unit served: since the calibration before the last that
                    // is not a repeat of it (a recalibration minutes later served nothing).
                    let served_days = cals
                        .iter()
                        .rev()
                        .map(|c| (t_last - c.1) as f64 / SECONDS_PER_DAY)
                        .find(|&d| d >= MIN_SPAN_DAYS);
                    let interval_days = match served_days {
                        Some(d) => d / 2.0,
                        None => rule.max_interval_days / 2.0,
                    }
                    .max(rule.min_interval_days);
                    AsFoundShortening { finding, served_days, interval_days }
                });
            (drifts_of(&scaled), recal(&scaled, t_last, rule, shortening))
        }
    };
    History {
        device_id: runs.first().map(|r| r.start.device_id.clone()).unwrap_or_default(),
        serials,
        runs: lines,
        drifts,
        recalibration,
        unreadable: Vec::new(),
    }
}

fn drifts_of(cals: &[Scaled]) -> Vec<Drift> {
    cals.windows(2)
        .enumerate()
        .map(|(i, w)| Drift {
            from: i + 1,
            to: i + 2,
            days: w[1].t_days - w[0].t_days,
            terms: (0..3)
                .flat_map(|c| (0..4).map(move |t| (c, t)))
                .map(|(c, t)| TermDrift {
                    channel: CHANNELS[c],
                    term: TERMS[t],
                    delta_m_s2: w[1].q[c][t] - w[0].q[c][t],
                    sigma_m_s2: w[0].sigma[c][t].hypot(w[1].sigma[c][t]),
                })
                .collect(),
        })
        .collect()
}

/// Calibrations closer than this, days, are repeats of one calibration for the drift rate (a
/// unit recalibrated the same day: their difference is noise, not drift over time).
pub const MIN_SPAN_DAYS: f64 = 1.0;

/// The calibrations the drift rate uses: the latest of each group of repeats
/// ([`MIN_SPAN_DAYS`]), oldest first.
fn epochs(cals: &[Scaled]) -> Vec<&Scaled> {
    let mut kept: Vec<&Scaled> = Vec::new();
    for s in cals.iter().rev() {
        if kept.last().is_none_or(|k| k.t_days - s.t_days >= MIN_SPAN_DAYS) {
            kept.push(s);
        }
    }
    kept.reverse();
    kept
}

/// The recommended recalibration: the drift's ([`by_drift`]), shortened by an as-found result
/// out of tolerance.
fn recal(
    cals: &[Scaled],
    t_last: i64,
    rule: RecalRule,
    shortening: Option<AsFoundShortening>,
) -> Recalibration {
    let (calibrations, mut days, mut limiting, mut basis) = by_drift(cals, rule);
    if let Some(s) = &shortening {
        let served = match s.served_days {
            Some(d) => format!("half the {d:.0} days it had served since the calibration before"),
            None => format!(
                "half of {} days (--max-interval-days), no calibration before it in the database",
                rule.max_interval_days
            ),
        };
        let served = if s.interval_days == rule.min_interval_days {
            format!("{served}, raised to the floor of {} days", rule.min_interval_days)
        } else {
            served
        };
        if s.interval_days < days {
            basis = format!("{}: {served}, ILAC-G24 method 1 (by the drift alone: {basis})", s.finding);
            days = s.interval_days;
            limiting = None;
        } else {
            basis = format!("{basis}; {} allows {:.0} days ({served})", s.finding, s.interval_days);
        }
    }
    if let Some(d) = rule.decided_interval_days {
        basis = format!("{d} days, the laboratory's decision; the rule gives {days:.0} days: {basis}");
        days = d;
        limiting = None;
    }
    Recalibration {
        method: METHOD,
        rule,
        calibrations,
        due_unix_s: Some(t_last + (days * SECONDS_PER_DAY).round() as i64),
        limiting,
        basis,
        as_found_out_of_tolerance: shortening,
    }
}

/// The interval the coefficients' drift allows: calibrations used, days, the limiting
/// coefficient (`None`: the maximum interval), and the basis in words.
fn by_drift(cals: &[Scaled], rule: RecalRule) -> (usize, f64, Option<Limiting>, String) {
    let max = rule.max_interval_days;
    let kept: Vec<Scaled> = epochs(cals).into_iter().cloned().collect();
    if kept.len() < 2 {
        let basis = if cals.len() < 2 {
            format!(
                "one calibration: no drift known yet, the calibration plus {max} days (--max-interval-days)"
            )
        } else {
            format!(
                "{} calibrations, all within {MIN_SPAN_DAYS} day of the last (repeats, not drift over time): no drift known yet, the last calibration plus {max} days (--max-interval-days)",
                cals.len()
            )
        };
        return (cals.len(), max, None, basis);
    }
    let cals = kept.as_slice();
    let mut best: Option<Limiting> = None;
    for c in 0..3 {
        for t in 0..4 {
            let pts: Vec<(f64, f64, f64)> =
                cals.iter().map(|s| (s.t_days, s.q[c][t], s.sigma[c][t])).collect();
            let (r, se) = slope(&pts);
            let speed = r.abs() + rule.coverage * se;
            let days = if speed > 0.0 { rule.tolerance_m_s2 / speed } else { f64::INFINITY };
            if best.as_ref().is_none_or(|b| days < b.days_to_tolerance) {
                best = Some(Limiting {
                    channel: CHANNELS[c],
                    term: TERMS[t],
                    rate_m_s2_per_year: r * DAYS_PER_YEAR,
                    rate_se_m_s2_per_year: se * DAYS_PER_YEAR,
                    days_to_tolerance: days,
                });
            }
        }
    }
    let best = best.expect("twelve coefficients");
    let (days, limiting, basis) = if best.days_to_tolerance < max {
        let basis = format!(
            "channel {} term {}: drift {:+.3e} ± {:.1e} m/s² per year reaches {} m/s² (k = {}) {:.0} days after the last calibration",
            best.channel,
            best.term,
            best.rate_m_s2_per_year,
            best.rate_se_m_s2_per_year,
            rule.tolerance_m_s2,
            rule.coverage,
            best.days_to_tolerance
        );
        if best.days_to_tolerance < rule.min_interval_days {
            let floor = rule.min_interval_days;
            (floor, Some(best), format!("{basis}, raised to the floor of {floor} days (--min-interval-days)"))
        } else {
            (best.days_to_tolerance, Some(best), basis)
        }
    } else {
        (
            max,
            None,
            format!("no coefficient's drift reaches the tolerance within {max} days (--max-interval-days)"),
        )
    };
    (cals.len(), days, limiting, basis)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_line_through_two_points_has_their_slope_and_the_propagated_error() {
        let (r, se) = slope(&[(0.0, 1.0, 0.3), (10.0, 3.0, 0.4)]);
        assert!((r - 0.2).abs() < 1e-12);
        assert!((se - 0.05).abs() < 1e-12, "{se}");
    }

    #[test]
    fn scatter_beyond_the_stated_errors_widens_the_slope_error() {
        let tight = slope(&[(0.0, 0.0, 1.0), (1.0, 1.0, 1.0), (2.0, 2.0, 1.0)]);
        assert!((tight.0 - 1.0).abs() < 1e-12);
        let stated_only = (1.0f64 / 2.0).sqrt();
        assert!((tight.1 - stated_only).abs() < 1e-12, "{tight:?}");
        let loose = slope(&[(0.0, 0.0, 0.01), (1.0, 3.0, 0.01), (2.0, 2.0, 0.01)]);
        assert!(loose.1 > 0.01 * stated_only * 10.0, "{loose:?}");
    }

    #[test]
    fn calibrations_within_a_day_are_repeats_for_the_drift_rate() {
        let at = |t_days: f64, bias: f64| {
            let mut q = [[0.0; 4]; 3];
            q[0][0] = bias;
            Scaled { t_days, q, sigma: [[0.001; 4]; 3] }
        };
        let rule = DEFAULT_RULE;
        // Minutes apart: no rate, the maximum interval.
        let r = recal(&[at(-0.002, 0.0), at(0.0, 0.001)], 1_000_000, rule, None);
        assert!(r.limiting.is_none() && r.basis.contains("repeats"), "{r:?}");
        assert_eq!(r.due_unix_s, Some(1_000_000 + 365 * 86_400));
        // A year apart, then a same-day repeat: the rate from the year (the repeat's earlier
        // calibration left out), 0.1 m/s² per year on x's bias.
        let r = recal(&[at(-365.0, 0.0), at(-0.001, 0.5), at(0.0, 0.1)], 0, rule, None);
        let l = r.limiting.expect("a rate");
        assert_eq!((l.channel, l.term), ("x", "1"));
        assert!((l.rate_m_s2_per_year - 0.1 * DAYS_PER_YEAR / 365.0).abs() < 1e-9, "{l:?}");
    }
}
