//! The uncertainty budget on the command line: `accelcal uncertainty-check` (the Monte Carlo
//! check of the budget) and the budget table `fit` prints.

use accelcal_core::output::write_json;
use accelcal_core::uncertainty::montecarlo::{self, Outcome, Scenario, Settings};
use accelcal_core::uncertainty::UncertaintyJson;
use indicatif::{ProgressBar, ProgressStyle};
use serde::Serialize;

use crate::settings::campaign::UncertaintyCheck;

/// The JSON of `uncertainty-check`.
#[derive(Serialize)]
struct CheckJson<'a> {
    units: u32,
    samples: u32,
    orientations: u32,
    seed: u64,
    scenarios: Vec<ScenarioJson<'a>>,
    /// The decision rules at the limit and half a U either side of it.
    decision_rules: Vec<RuleRow>,
    /// The guard-band rule on the parameters the six ±axis positions measure, at their limits.
    parameter_rules: Vec<ParameterRow>,
    passed: bool,
}

/// One parameter at its limit under the guard-band rule: the share of each decision.
#[derive(Serialize)]
struct ParameterRow {
    parameter: &'static str,
    axis: &'static str,
    /// The true value, at the limit, in `unit`.
    true_value: f64,
    unit: &'static str,
    /// Each component's U at each position, m/s².
    #[serde(rename = "U_m_s2")]
    u_expanded_m_s2: f64,
    /// pass, conditional pass, conditional fail, fail.
    shares: [f64; 4],
}

/// The parameters' limits of the check: (parameter, axis, limit, unit).
const PARAMETER_LIMITS: [(&str, &str, f64, &str); 3] =
    [("bias", "x", 2.0, "mg"), ("scale_factor", "x", 2000.0, "ppm"), ("misalignment", "x→y", 2000.0, "µrad")];

/// The guard-band rule on each parameter the six ±axis positions measure (bias, scale factor,
/// misalignment), each at its limit, every component measured with the budget's U: its
/// false-accept rate must be at most 2.5 % too (it checks the quadrature that gives each
/// parameter's U).
fn parameter_rules(u_expanded: f64, seed: u64) -> anyhow::Result<(Vec<ParameterRow>, Vec<String>)> {
    use accelcal_core::conformity::{parameter_outcome_rates, RuleKind, Specification, K};
    let spec = Specification {
        unit_type: "check".into(),
        acceleration_error_m_s2: CHECK_LIMIT_M_S2,
        rule: RuleKind::GuardBand,
        guard_band_m_s2: None,
        bias_mg: Some(PARAMETER_LIMITS[0].2),
        scale_factor_ppm: Some(PARAMETER_LIMITS[1].2),
        misalignment_urad: Some(PARAMETER_LIMITS[2].2),
    };
    let draws = RULE_DRAWS;
    outln!(
        "parameters at their limits, guard-band rule (the six ±axis positions, each component with U = {u_expanded:.3e} m/s²); {draws} verifications per row"
    )?;
    outln!(
        "{:<14} {:>6} {:>12} {:>9} {:>11} {:>11} {:>9}",
        "parameter",
        "axis",
        "true value",
        "pass",
        "cond. pass",
        "cond. fail",
        "fail"
    )?;
    let (mut rows, mut missed) = (Vec::new(), Vec::new());
    for (i, (parameter, axis, limit, unit)) in PARAMETER_LIMITS.into_iter().enumerate() {
        let shares = parameter_outcome_rates(
            &spec,
            accelcal_shared::G_STANDARD,
            parameter,
            limit,
            u_expanded / K,
            draws,
            seed + 10 + i as u64,
        )?;
        let pct = |x: f64| format!("{:.2}%", 100.0 * x);
        outln!(
            "{:<14} {:>6} {:>12} {:>9} {:>11} {:>11} {:>9}",
            parameter,
            axis,
            format!("{limit} {unit}"),
            pct(shares[0]),
            pct(shares[1]),
            pct(shares[2]),
            pct(shares[3])
        )?;
        if shares[0] > 0.025 {
            missed.push(format!("{parameter} false-accept rate {:.2} % > 2.5 %", 100.0 * shares[0]));
        }
        rows.push(ParameterRow {
            parameter,
            axis,
            true_value: limit,
            unit,
            u_expanded_m_s2: u_expanded,
            shares,
        });
    }
    Ok((rows, missed))
}

/// One row of the decision-rule check: a rule, a unit's true error, and the share of each
/// decision over the draws of the measured error.
#[derive(Serialize)]
struct RuleRow {
    rule: &'static str,
    true_error_m_s2: f64,
    #[serde(rename = "U_m_s2")]
    u_expanded_m_s2: f64,
    /// pass, conditional pass, conditional fail, fail.
    shares: [f64; 4],
}

/// The limit of the decision-rule check, m/s² (the tolerance `history` uses).
const CHECK_LIMIT_M_S2: f64 = 0.05;
/// Measured errors drawn per row of the decision-rule check.
const RULE_DRAWS: usize = 200_000;

/// The decision rules against a limit T with the U of the budget's first scenario (every
/// contributor on): the shares of each decision for units whose true error is T − U/2, T and
/// T + U/2, and the guard-band rule's false-accept rate at T (it must be at most 2.5 %).
fn decision_rules(u_expanded: f64, seed: u64) -> anyhow::Result<(Vec<RuleRow>, Option<String>)> {
    use accelcal_core::conformity::{outcome_rates, RuleKind, Specification, K};
    let t = CHECK_LIMIT_M_S2;
    outln!(
        "decision rules (ILAC-G8) against T = {t} m/s², U = {u_expanded:.3e} m/s² (the budget's, every contributor on); {RULE_DRAWS} measurements per row"
    )?;
    outln!(
        "{:<11} {:>14} {:>9} {:>11} {:>11} {:>9}",
        "rule",
        "true error",
        "pass",
        "cond. pass",
        "cond. fail",
        "fail"
    )?;
    let mut rows = Vec::new();
    let mut far = None;
    for rule in [RuleKind::GuardBand, RuleKind::Simple] {
        let spec = Specification {
            unit_type: "check".into(),
            acceleration_error_m_s2: t,
            rule,
            guard_band_m_s2: None,
            bias_mg: None,
            scale_factor_ppm: None,
            misalignment_urad: None,
        };
        for (i, (label, e)) in
            [("T - U/2", t - u_expanded / 2.0), ("T", t), ("T + U/2", t + u_expanded / 2.0)]
                .into_iter()
                .enumerate()
        {
            let shares = outcome_rates(&spec, e, u_expanded / K, RULE_DRAWS, seed + i as u64);
            let pct = |x: f64| format!("{:.2}%", 100.0 * x);
            outln!(
                "{:<11} {:>14} {:>9} {:>11} {:>11} {:>9}",
                rule.name(),
                label,
                pct(shares[0]),
                pct(shares[1]),
                pct(shares[2]),
                pct(shares[3])
            )?;
            if rule == RuleKind::GuardBand && label == "T" {
                far = Some(shares[0]);
            }
            rows.push(RuleRow { rule: rule.name(), true_error_m_s2: e, u_expanded_m_s2: u_expanded, shares });
        }
    }
    let far = far.expect("the guard-band row at T");
    outln!("guard-band false-accept rate at the limit: {:.2} % (at most 2.5 %)", 100.0 * far)?;
    let missed = (far > 0.025).then(|| format!("guard-band false-accept rate {:.2} % > 2.5 %", 100.0 * far));
    Ok((rows, missed))
}

#[derive(Serialize)]
struct ScenarioJson<'a> {
    #[serde(flatten)]
    outcome: &'a Outcome,
    range: (f64, f64),
    passed: bool,
}

/// Runs `accelcal uncertainty-check`.
pub fn run_check(a: &UncertaintyCheck) -> anyhow::Result<()> {
    let set = Settings {
        units: a.units as usize,
        plan: accelcal_core::sim::Plan::head(),
        samples: a.samples as usize,
        orientations: a.orientations as usize,
        seed: a.seed,
    };
    let scenarios = Scenario::standard();
    let pb = ProgressBar::new((set.units * scenarios.len()) as u64);
    pb.set_style(
        ProgressStyle::with_template("{bar:40} {pos}/{len} units, {elapsed} elapsed, eta {eta}")
            .expect("valid template"),
    );
    let mut outcomes = Vec::new();
    for s in &scenarios {
        let out = montecarlo::run(s, &set, &|_| pb.inc(1)).map_err(anyhow::Error::msg)?;
        outcomes.push(out);
    }
    pb.finish_and_clear();
    outln!(
        "Monte Carlo check of the uncertainty budget (JCGM 101): {} units per scenario, {} sample sets per position, {} orientations per unit, seed {}",
        set.units, set.samples, set.orientations, set.seed
    )?;
    outln!(
        "{:<20} {:>7} {:>7} {:>9} {:>8} {:>15} {:>10} {:>10} {:>13}  mean max U",
        "scenario",
        "noise",
        "angle",
        "orthog.",
        "u(g)",
        "temperature",
        "quadratic",
        "coverage",
        "range"
    )?;
    outln!(
        "{:<20} {:>7} {:>7} {:>9} {:>8} {:>15} {:>10}",
        "",
        "codes",
        "arcsec",
        "arcsec",
        "m/s²",
        "mg/ppm/°C, °C",
        "codes"
    )?;
    let mut rows = Vec::new();
    let mut failed = Vec::new();
    for o in &outcomes {
        let s = &o.scenario;
        let (lo, hi) = s.range;
        let passed = (lo..=hi).contains(&o.coverage);
        if !passed {
            failed.push(format!("{} {:.1} %", s.name, 100.0 * o.coverage));
        }
        let temp = s.temperature.map_or("-".to_string(), |t| {
            format!("{}/{}/{}", t.bias_mg_per_c, t.scale_ppm_per_c, t.thermometer_c)
        });
        outln!(
            "{:<20} {:>7} {:>7} {:>9} {:>8} {:>15} {:>10} {:>9.2}% {:>5.1}–{:.1} %  {:.3e} m/s²  {}",
            s.name,
            s.noise_codes,
            s.head_angle_arcsec,
            s.head_orthogonality_arcsec,
            s.g_u_m_s2,
            temp,
            s.quadratic_codes,
            100.0 * o.coverage,
            100.0 * lo,
            100.0 * hi,
            o.mean_u_m_s2,
            if passed { "ok" } else { "MISSED" }
        )?;
        rows.push(ScenarioJson { outcome: o, range: (lo, hi), passed });
    }
    let u_all = outcomes.first().map_or(0.0, |o| o.mean_u_m_s2);
    let (decision_rules, missed) = decision_rules(u_all, a.seed)?;
    failed.extend(missed);
    let (parameter_rules, missed) = parameter_rules(u_all, a.seed)?;
    failed.extend(missed);
    if let Some(j) = &a.json {
        write_json(
            j,
            &CheckJson {
                units: a.units,
                samples: a.samples,
                orientations: a.orientations,
                seed: a.seed,
                passed: failed.is_empty(),
                scenarios: rows,
                decision_rules,
                parameter_rules,
            },
        )?;
    }
    if failed.is_empty() {
        outln!(
            "the budget holds: every scenario's coverage is in its range, and the guard band keeps its risk"
        )?;
        Ok(())
    } else {
        Err(anyhow::anyhow!("the budget's coverage is out of its range: {}", failed.join(", ")))
    }
}

/// Prints a budget (`fit`'s, or the one a fit JSON states): the expanded uncertainty per axis and
/// each contributor.
pub fn print_budget(b: &UncertaintyJson) -> anyhow::Result<()> {
    let u = b.u_m_s2;
    outln!(
        "expanded uncertainty of the calibrated acceleration (k = {}, the largest over the orientations at 1 g): x {:.2e}, y {:.2e}, z {:.2e} m/s²",
        b.k, u[0], u[1], u[2]
    )?;
    match &b.stated_at {
        Some(s) => outln!(
            "  the contributors along {} at ({}) m/s², the orientation where U is largest (√Σu² × k = U there):",
            s.axis,
            s.acceleration_m_s2.iter().map(|v| format!("{v:+.2}")).collect::<Vec<_>>().join(", ")
        )?,
        None => outln!(
            "  the contributors at their own worst axis and orientation, shares averaged over the orientations \
             (a fit JSON written before budgets stated where U is):"
        )?,
    }
    outln!("  {:<20} {:>4} {:>12} {:>7}  source", "contributor", "type", "u, m/s²", "share")?;
    for c in &b.contributors {
        outln!("  {:<20} {:>4} {:>12.3e} {:>6.1}%  {}", c.name, c.kind, c.u_m_s2, 100.0 * c.share, c.source)?;
    }
    if let Some(i) = b.stated_at.as_ref().and_then(|s| ["x", "y", "z"].iter().position(|a| *a == s.axis)) {
        let uc = b.contributors.iter().map(|c| c.u_m_s2 * c.u_m_s2).sum::<f64>().sqrt();
        let p = b
            .coverage_probability
            .map_or(String::new(), |p| format!(", coverage probability {:.1} %", 100.0 * p));
        outln!("  {:<20} {:>4} {:>12.3e} {:>6.1}%  √Σu²", "combined u_c", "", uc, 100.0)?;
        outln!("  {:<20} {:>4} {:>12.3e} {:>7}  k = {}{p}", "expanded U = k·u_c", "", b.u_m_s2[i], "", b.k)?;
    }
    for n in &b.not_included {
        outln!("  not included: {n}")?;
    }
    Ok(())
}
