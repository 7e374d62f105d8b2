//! The check standard (issue 31 item 2): a known unit whose record is in force, measured on a
//! station at the start of a shift (`station --check-standard SERIAL`: its as-found verification
//! only, nothing recalibrated). Each check is a run of that unit, ended with a reason that begins
//! with [`CHECK_REASON`] (the `run_end` row, in the hash chain): `pass` when the check is in
//! control, `rejected` (with the rule and the point) when not.
//!
//! The chart: per axis x, y, z, the mean over the verification's positions of the error of that
//! component, m/s² (on a plan of ±axis positions this is the unit's bias on the station; the
//! scale-factor errors cancel between + and −). Phase II of an individuals chart (Montgomery
//! §6.4): the limits ([`ImrLimits`]) are those of the first [`BASELINE`] checks (or of every
//! check before the latest, when there are fewer), at least [`MIN_BASELINE`] of them; the
//! Western Electric rules run over every check with those limits. A check is out of control when
//! a rule is broken at its own point. A station refuses production while its latest check is out
//! of control, until a check is in control again.

use accelcal_core::document::verify::VerifyReport;
use accelcal_core::spc::{ImrLimits, Violation};
use serde::Serialize;

use super::{Db, DbError};

/// How the reason of a check run's end begins (`fleet`'s SQL leaves these runs out by it:
/// `super::fleet`'s `WHERE`, whose 14 is this text's length).
pub const CHECK_REASON: &str = "check standard";

/// The SQL condition on `run_end e` that its run is a check: the expression of the partial index
/// `run_end_check_standard` (schema 6), so that the database reads only the checks' rows.
pub(crate) const IS_CHECK: &str = "substr(e.reason, 1, 14) = 'check standard'";

const _: () = assert!(CHECK_REASON.len() == 14, "IS_CHECK and the index spell its 14 bytes");

/// The checks whose limits the chart uses.
pub const BASELINE: usize = 20;

/// The fewest earlier checks that set limits; before that, a check is recorded and not judged.
pub const MIN_BASELINE: usize = 5;

/// One check of a station's check standard.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct CheckRun {
    /// The run.
    pub run_id: String,
    /// The check standard's serial.
    pub serial: String,
    /// Start, Unix seconds.
    pub started_unix_s: i64,
    /// `pass` (in control), `rejected` (out of control) or `null` (not ended).
    pub outcome: Option<String>,
    /// Why it ended so (begins with [`CHECK_REASON`]).
    pub reason: String,
    /// Per axis x, y, z, the mean error of that component over the positions, m/s² (`null`: no
    /// as-found verification stored, or one without positions).
    pub mean_error_m_s2: Option<[f64; 3]>,
}

/// The mean over `report`'s positions of each error component, m/s².
pub fn mean_errors(report: &VerifyReport) -> Option<[f64; 3]> {
    let n = report.positions.len();
    (n > 0).then(|| {
        std::array::from_fn(|c| report.positions.iter().map(|p| p.error_m_s2[c]).sum::<f64>() / n as f64)
    })
}

/// A check standard's chart of one axis.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct CheckChart {
    /// `mean error x` (y, z).
    pub quantity: String,
    /// m/s².
    pub unit: &'static str,
    /// The checks' values in time order, with their runs.
    pub points: Vec<(String, f64)>,
    /// The limits of the baseline (`null`: fewer than [`MIN_BASELINE`] checks before the latest).
    pub limits: Option<ImrLimits>,
    /// The points that break a rule.
    pub violations: Vec<Violation>,
}

/// The three charts of `checks` (in time order; checks without values are left out).
pub fn check_charts(checks: &[CheckRun]) -> Vec<CheckChart> {
    let with: Vec<(&CheckRun, [f64; 3])> =
        checks.iter().filter_map(|c| c.mean_error_m_s2.map(|m| (c, m))).collect();
    ["x", "y", "z"]
        .iter()
        .enumerate()
        .map(|(axis, name)| {
            let x: Vec<f64> = with.iter().map(|(_, m)| m[axis]).collect();
            let base = BASELINE.min(x.len().saturating_sub(1));
            let limits = (base >= MIN_BASELINE).then(|| ImrLimits::of(&x[..base])).flatten();
            let violations = limits.map(|l| l.violations(&x)).unwrap_or_default();
            CheckChart {
                quantity: format!("mean error {name}"),
                unit: "m/s²",
                points: with.iter().map(|(c, m)| (c.run_id.clone(), m[axis])).collect(),
                limits,
                violations,
            }
        })
        .collect()
}

/// Why the latest check of `charts` is out of control: the first of rules 1 to 4 broken at its point, in
/// words (the quantity, the rule, the check's place and value, the limits); `None` when it is in
/// control or the charts have no limits yet.
pub fn out_of_control(charts: &[CheckChart]) -> Option<String> {
    charts.iter().find_map(|c| {
        let last = c.points.len().checked_sub(1)?;
        let l = c.limits?;
        // Rules 1 to 4 of the individuals decide; a moving range beyond its limit (rule 5) is
        // charted, not decisive: the check that returns from a bad one breaks it too.
        let v = c.violations.iter().find(|v| v.index == last && v.rule <= 4)?;
        let (run, value) = &c.points[last];
        Some(format!(
            "{}: rule {} ({}) at check {} of {} (run {run}): {value:+.5} {} against centre {:+.5}, limits {:+.5} to {:+.5}",
            c.quantity,
            v.rule,
            v.what,
            last + 1,
            c.points.len(),
            c.unit,
            l.center,
            l.lcl,
            l.ucl
        ))
    })
}

/// The latest check of a chart, judged.
#[derive(Clone, Debug, PartialEq)]
pub enum Judgement {
    /// A rule of 1 to 4 broke at its point ([`out_of_control`]'s words).
    OutOfControl(String),
    /// The chart has limits and no rule broke at its point.
    InControl,
    /// Too few earlier checks for limits.
    NotJudged,
}

/// The latest check of `charts`, judged.
pub fn judge(charts: &[CheckChart]) -> Judgement {
    match out_of_control(charts) {
        Some(why) => Judgement::OutOfControl(why),
        None if charts.iter().any(|c| c.limits.is_some()) => Judgement::InControl,
        None => Judgement::NotJudged,
    }
}

/// How the reason of a check that ended out of control begins, after [`CHECK_REASON`].
const OUT_OF_CONTROL: &str = "out of control: ";

impl Judgement {
    /// `in control`, `out of control` or `not judged`.
    pub fn state(&self) -> &'static str {
        match self {
            Judgement::OutOfControl(_) => "out of control",
            Judgement::InControl => "in control",
            Judgement::NotJudged => "not judged",
        }
    }

    /// What the check of `checks` checks in all (this one included) found, in words.
    pub fn words(&self, checks: usize) -> String {
        match self {
            Judgement::OutOfControl(why) => format!("{OUT_OF_CONTROL}{why}"),
            Judgement::InControl => format!("in control ({checks} checks)"),
            Judgement::NotJudged => format!(
                "recorded, not judged: {} of the {MIN_BASELINE} earlier checks the limits need",
                checks.saturating_sub(1)
            ),
        }
    }

    /// The reason its run ends with: [`CHECK_REASON`], then [`Judgement::words`]
    /// ([`why_out_of_control`] reads it back).
    pub fn reason(&self, checks: usize) -> String {
        format!("{CHECK_REASON}: {}", self.words(checks))
    }
}

/// Why a check ended out of control, read from the reason [`Judgement::reason`] wrote (the whole
/// reason, for one written otherwise).
pub fn why_out_of_control(reason: &str) -> &str {
    reason
        .strip_prefix(CHECK_REASON)
        .and_then(|r| r.strip_prefix(": "))
        .and_then(|r| r.strip_prefix(OUT_OF_CONTROL))
        .unwrap_or(reason)
}

/// A station's check standard as `fleet` reports it.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct CheckStandard {
    /// The station.
    pub station: String,
    /// The serial of its latest check.
    pub serial: String,
    /// Its checks, every one (the limits need the first 20).
    pub checks: usize,
    /// `in control`, `out of control` or `not judged` (too few checks for limits).
    pub state: &'static str,
    /// Why the latest check is out of control (`null` otherwise).
    pub why: Option<String>,
    /// The three charts.
    pub charts: Vec<CheckChart>,
}

impl Db {
    /// The check standard of every station that has checks (`station`: only that one), by
    /// station name.
    pub fn check_standards(&mut self, station: Option<&str>) -> Result<Vec<CheckStandard>, DbError> {
        let rows = self.conn.transaction(|tx| {
            tx.query(
                &format!(
                    "SELECT DISTINCT r.station FROM run_end e JOIN run r ON r.run_id = e.run_id \
                     WHERE {IS_CHECK} AND ($1 = '' OR r.station = $1) ORDER BY r.station"
                ),
                &[station.unwrap_or("").into()],
            )
        })?;
        let mut out = Vec::new();
        for r in rows {
            let station = r[0].text()?;
            let checks = self.check_runs(&station)?;
            let Some(last) = checks.last() else { continue };
            let charts = check_charts(&checks);
            let judgement = judge(&charts);
            let state = judgement.state();
            let why = match judgement {
                Judgement::OutOfControl(why) => Some(why),
                _ => None,
            };
            out.push(CheckStandard {
                serial: last.serial.clone(),
                checks: checks.len(),
                station,
                state,
                why,
                charts,
            });
        }
        Ok(out)
    }

    /// The checks of `station` (every serial), oldest first, not voided.
    pub fn check_runs(&mut self, station: &str) -> Result<Vec<CheckRun>, DbError> {
        let rows = self.conn.transaction(|tx| {
            tx.query(
                &format!(
                    "SELECT r.run_id, r.serial, r.started_unix_s, e.outcome, v.report_json, e.reason \
                     FROM run_end e JOIN run r ON r.run_id = e.run_id \
                     LEFT JOIN verification v ON v.run_id = r.run_id AND v.phase = 'as_found' \
                     WHERE r.station = $1 AND {IS_CHECK} \
                     AND NOT EXISTS (SELECT 1 FROM void x WHERE x.run_id = r.run_id) \
                     ORDER BY r.started_unix_s, r.run_id"
                ),
                &[station.into()],
            )
        })?;
        rows.iter()
            .map(|r| {
                let report = r[4].opt_text()?;
                Ok(CheckRun {
                    run_id: r[0].text()?,
                    serial: r[1].text()?,
                    started_unix_s: r[2].int()?,
                    outcome: r[3].opt_text()?,
                    reason: r[5].text()?,
                    mean_error_m_s2: report
                        .and_then(|t| VerifyReport::parse(&t).ok())
                        .and_then(|v| mean_errors(&v)),
                })
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn check(i: usize, m: [f64; 3]) -> CheckRun {
        CheckRun {
            run_id: format!("r{i}"),
            serial: "GOLD-1".into(),
            started_unix_s: i as i64,
            outcome: Some("pass".into()),
            reason: CHECK_REASON.into(),
            mean_error_m_s2: Some(m),
        }
    }

    #[test]
    fn a_check_beyond_the_baseline_s_limits_is_out_of_control_and_one_within_is_not() {
        // Ten checks scattering by ±0.001 m/s² about 0.002 on x.
        let mut checks: Vec<CheckRun> =
            (0..10).map(|i| check(i, [0.002 + if i % 2 == 0 { 0.001 } else { -0.001 }, 0.0, 0.0])).collect();
        assert_eq!(out_of_control(&check_charts(&checks)), None);
        // The head knocked: x reads 0.02 m/s² more.
        checks.push(check(10, [0.022, 0.0, 0.0]));
        let why = out_of_control(&check_charts(&checks)).expect("out of control");
        assert!(
            why.starts_with(
                "mean error x: rule 1 (a point beyond 3σ) at check 11 of 11 (run r10): +0.02200 m/s²"
            ),
            "{why}"
        );
        // The reason its run ends with, read back.
        let j = judge(&check_charts(&checks));
        assert_eq!(j, Judgement::OutOfControl(why.clone()));
        assert_eq!(why_out_of_control(&j.reason(11)), why);
        // The next check back where it was: in control again.
        checks.push(check(11, [0.002, 0.0, 0.0]));
        assert_eq!(out_of_control(&check_charts(&checks)), None);
        assert_eq!(judge(&check_charts(&checks)).reason(12), "check standard: in control (12 checks)");
    }

    #[test]
    fn fleet_leaves_out_the_runs_that_end_so() {
        assert_eq!(CHECK_REASON.len(), 14);
        assert!(super::super::fleet::WHERE.contains(&format!("substr(ce.reason, 1, 14) = '{CHECK_REASON}'")));
    }

    #[test]
    fn too_few_checks_set_no_limits() {
        let checks: Vec<CheckRun> = (0..MIN_BASELINE).map(|i| check(i, [i as f64, 0.0, 0.0])).collect();
        let charts = check_charts(&checks);
        assert!(charts.iter().all(|c| c.limits.is_none()));
        assert_eq!(out_of_control(&charts), None);
        assert_eq!(judge(&charts).state(), "not judged");
        // One more: the first five are the baseline.
        let mut more = checks;
        more.push(check(MIN_BASELINE, [100.0, 0.0, 0.0]));
        assert!(out_of_control(&check_charts(&more)).is_some());
    }
}
