//! Conformity to a product specification (ILAC-G8:09/2019): the specification of a unit type,
//! the decision rule, and the uncertainty of a verification's measured error that the rule
//! weighs.
//!
//! A verification measures, at each position, the error `e` of each component of the unit's
//! calibrated acceleration (what the node reads less what the head imposes). Its expanded
//! uncertainty `U` (k = 2) is that of the measurement of `e`: the scatter of the position's mean
//! (Type A), the head's stated angle setting error and axis non-orthogonality (they move what the
//! head imposes), and the bound on g (it scales what the head imposes). The specification is a
//! limit `T` on `|e|` of each component at every orientation.
//!
//! - `simple` (shared risk): `|e| ≤ T` passes, else fails.
//! - `guard-band` with guard band `w` (`U` of each result unless stated): `|e| ≤ T − w` passes,
//!   `T − w < |e| ≤ T` is a conditional pass, `T < |e| ≤ T + w` a conditional fail, beyond a
//!   fail. Only a pass is accepted: with `w = U` the probability of accepting a unit whose true
//!   error is at the limit is that of a normal deviate below −2, 2.3 %.

use serde::{Deserialize, Serialize};

/// The coverage factor of the expanded uncertainties the rule weighs.
pub const K: f64 = 2.0;

/// The decision rule.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum RuleKind {
    /// Accept when the result is within the limit.
    Simple,
    /// Accept when the result is within the limit less the guard band.
    GuardBand,
}

impl RuleKind {
    /// Its name, as the specification file and the reports spell it.
    pub fn name(self) -> &'static str {
        match self {
            RuleKind::Simple => "simple",
            RuleKind::GuardBand => "guard-band",
        }
    }
}

/// A unit type's specification and the decision rule applied to it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Specification {
    /// The unit type it specifies.
    pub unit_type: String,
    /// `T`: the limit on the error of each component of the calibrated acceleration at any
    /// orientation, m/s².
    pub acceleration_error_m_s2: f64,
    /// The decision rule.
    pub rule: RuleKind,
    /// The guard band `w`, m/s² (`guard-band` only) [default: the expanded uncertainty `U` of
    /// each result].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub guard_band_m_s2: Option<f64>,
    /// The limit on each axis's bias error, mg (IEEE Std 1293's K0, as the verification's
    /// ±axis positions measure it: [`parameters`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bias_mg: Option<f64>,
    /// The limit on each axis's scale-factor error, ppm (K1).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub scale_factor_ppm: Option<f64>,
    /// The limit on each input-axis misalignment, µrad (δ).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub misalignment_urad: Option<f64>,
}

/// A specification that cannot be applied.
#[derive(Debug, thiserror::Error)]
#[error("the specification {0}")]
pub struct SpecError(pub String);

impl crate::error::Classify for SpecError {
    fn kind(&self) -> crate::error::Kind {
        crate::error::Kind::BadInput
    }
}

impl Specification {
    /// Checks the limits: `T` positive, `w` non-negative and below `T`, given only for a
    /// guard-band rule.
    pub fn check(&self) -> Result<(), SpecError> {
        let t = self.acceleration_error_m_s2;
        if !(t.is_finite() && t > 0.0) {
            return Err(SpecError(format!(
                "`acceleration_error_m_s2` must be a positive number of m/s², got {t}"
            )));
        }
        if let Some(w) = self.guard_band_m_s2 {
            if self.rule == RuleKind::Simple {
                return Err(SpecError(
                    "`guard_band_m_s2` does not apply to the rule `simple` (it accepts within the limit)"
                        .into(),
                ));
            }
            if !(w.is_finite() && (0.0..t).contains(&w)) {
                return Err(SpecError(format!(
                    "`guard_band_m_s2` must be at least 0 and below the limit {t} m/s², got {w}"
                )));
            }
        }
        for (key, v) in [
            ("bias_mg", self.bias_mg),
            ("scale_factor_ppm", self.scale_factor_ppm),
            ("misalignment_urad", self.misalignment_urad),
        ] {
            if let Some(v) = v.filter(|v| !(v.is_finite() && *v > 0.0)) {
                return Err(SpecError(format!("`{key}` must be a positive limit, got {v}")));
            }
        }
        crate::text::single_line("`unit_type`", &self.unit_type).map_err(|e| SpecError(e.to_string()))?;
        if self.unit_type.trim().is_empty() {
            return Err(SpecError("`unit_type` must be one line of text".into()));
        }
        Ok(())
    }

    /// The rule in words, for reports and certificates.
    pub fn describe(&self) -> String {
        let t = self.acceleration_error_m_s2;
        match (self.rule, self.guard_band_m_s2) {
            (RuleKind::Simple, _) => format!(
                "{}: |error| of each component at most T = {t} m/s²; decision rule simple (accepted within T, the \
                 measurement uncertainty shared)",
                self.unit_type
            ),
            (RuleKind::GuardBand, w) => format!(
                "{}: |error| of each component at most T = {t} m/s²; decision rule guard-band, w = {} (accepted \
                 within T − w; conditional pass within T, conditional fail within T + w)",
                self.unit_type,
                w.map_or("U of each result (k = 2)".to_string(), |w| format!("{w} m/s²"))
            ),
        }
    }

    /// Whether it limits a parameter of the triad (bias, scale factor, misalignment), which a
    /// verification must then measure at the six ±axis positions.
    pub fn limits_parameters(&self) -> bool {
        self.bias_mg.is_some() || self.scale_factor_ppm.is_some() || self.misalignment_urad.is_some()
    }

    /// The parameters' limits in words (empty without any).
    pub fn describe_parameters(&self) -> String {
        let mut parts = Vec::new();
        if let Some(b) = self.bias_mg {
            parts.push(format!("|bias error| ≤ {b} mg"));
        }
        if let Some(s) = self.scale_factor_ppm {
            parts.push(format!("|scale-factor error| ≤ {s} ppm"));
        }
        if let Some(m) = self.misalignment_urad {
            parts.push(format!("|misalignment| ≤ {m} µrad"));
        }
        parts.join(", ")
    }

    /// The decision on a measured error `e` (m/s²) with expanded uncertainty `u_expanded`.
    pub fn decide(&self, e: f64, u_expanded: f64) -> Decision {
        self.decide_against(self.acceleration_error_m_s2, self.guard_band_m_s2, e, u_expanded)
    }

    /// The decision on a result `e` with expanded uncertainty `u_expanded` against the limit
    /// `t`, by the rule, with the guard band `w` (`None`: `U`).
    fn decide_against(&self, t: f64, w: Option<f64>, e: f64, u_expanded: f64) -> Decision {
        let a = e.abs();
        match self.rule {
            RuleKind::Simple if a <= t => Decision::Pass,
            RuleKind::Simple => Decision::Fail,
            RuleKind::GuardBand => {
                let w = w.unwrap_or(u_expanded);
                if a <= t - w {
                    Decision::Pass
                } else if a <= t {
                    Decision::ConditionalPass
                } else if a <= t + w {
                    Decision::ConditionalFail
                } else {
                    Decision::Fail
                }
            }
        }
    }
}

/// A decision on a result, from best to worst.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Serialize, Deserialize)]
pub enum Decision {
    /// Within the acceptance limit: conforms.
    #[serde(rename = "pass")]
    Pass,
    /// Within the limit, but not by the guard band: not shown to conform.
    #[serde(rename = "conditional pass")]
    ConditionalPass,
    /// Beyond the limit by less than the guard band: not shown not to conform.
    #[serde(rename = "conditional fail")]
    ConditionalFail,
    /// Beyond the limit by more than the guard band: does not conform.
    #[serde(rename = "fail")]
    Fail,
}

impl Decision {
    /// Its name, as the reports spell it.
    pub fn name(self) -> &'static str {
        match self {
            Decision::Pass => "pass",
            Decision::ConditionalPass => "conditional pass",
            Decision::ConditionalFail => "conditional fail",
            Decision::Fail => "fail",
        }
    }

    /// Whether the rule accepts it (a pass only).
    pub fn accepted(self) -> bool {
        self == Decision::Pass
    }

    /// Whether the result lies beyond the limit itself (out of tolerance).
    pub fn out_of_tolerance(self) -> bool {
        self >= Decision::ConditionalFail
    }
}

/// The standard uncertainties of the references a verification's error is measured against.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct VerifyReferences {
    /// One sigma of each head angle's setting error, rad.
    pub head_angle_rad: f64,
    /// One sigma of each of the three rotations between the head's stages, rad.
    pub head_orthogonality_rad: f64,
    /// The standard uncertainty of g, m/s².
    pub g_m_s2: f64,
}

/// The expanded uncertainty (k = [`K`]) of the measured error of each component at the head
/// position (α, β) degrees, g m/s², whose mean has standard errors `sd_mean` (m/s²).
pub fn measured_error_u(
    alpha_deg: f64,
    beta_deg: f64,
    g: f64,
    sd_mean: [f64; 3],
    r: VerifyReferences,
) -> [f64; 3] {
    let e = accelcal_shared::gravity(alpha_deg, beta_deg, g);
    // What the head imposes moves with each angle: central differences over ±1 mdeg.
    let h: f64 = 1e-3;
    let d = |da: f64, db: f64| {
        let p = accelcal_shared::gravity(alpha_deg + da, beta_deg + db, g);
        let m = accelcal_shared::gravity(alpha_deg - da, beta_deg - db, g);
        [0, 1, 2].map(|i| (p[i] - m[i]) / (2.0 * h.to_radians()))
    };
    let (da, db) = (d(h, 0.0), d(0.0, h));
    [0, 1, 2].map(|i| {
        let (j, k) = ((i + 1) % 3, (i + 2) % 3);
        let var = sd_mean[i].powi(2)
            + (da[i].powi(2) + db[i].powi(2)) * r.head_angle_rad.powi(2)
            // A small rotation ω of what the head imposes: (ω × e)_i, ω's components independent.
            + (e[j].powi(2) + e[k].powi(2)) * r.head_orthogonality_rad.powi(2)
            + (e[i] / g * r.g_m_s2).powi(2);
        K * var.sqrt()
    })
}

/// A parameter of the triad measured by a verification and decided against its limit.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ParameterCheck {
    /// `bias`, `scale_factor` or `misalignment`.
    pub parameter: String,
    /// The channel (`x`), or the channel and the axis it leans toward (`x→y`).
    pub axis: String,
    /// The measured error, in `unit`.
    pub value: f64,
    /// Its expanded uncertainty (k = 2), in `unit`.
    #[serde(rename = "U")]
    pub u_expanded: f64,
    /// The limit, in `unit`.
    pub limit: f64,
    /// `mg`, `ppm` or `µrad`.
    pub unit: String,
    /// The decision (the guard band, for a guard-band rule, is `U`).
    pub decision: Decision,
}

/// One position of a verification as [`parameters`] reads it: what the head imposed, m/s², the
/// error of each component and its expanded uncertainty, m/s².
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Measured {
    /// What the head imposes.
    pub expected_m_s2: [f64; 3],
    /// The error of each component.
    pub error_m_s2: [f64; 3],
    /// Its expanded uncertainty.
    pub u_expanded_m_s2: [f64; 3],
}

/// Standard gravity g_n, m/s²: the unit of "mg".
const G_N: f64 = 9.80665;

/// The triad's parameter errors that a verification's ±axis positions measure, decided against
/// the specification's limits. At the position imposing +g along axis j and the one imposing
/// −g (each within 2 % of g, the other axes within 2 % of g of 0), channel c's errors are e⁺ and
/// e⁻: its bias error is (e⁺ + e⁻)/2 at j = c, its scale-factor error (e⁺ − e⁻)/(2g) at j = c,
/// its misalignment toward j (e⁺ − e⁻)/(2g) at j ≠ c; U combines the two positions' U in
/// quadrature (their measurements are independent: a position's scatter and its head setting).
/// Empty without parameter limits; an error naming the axis when the positions lack a ±axis
/// pair a limit needs.
pub fn parameters(
    spec: &Specification,
    g: f64,
    positions: &[Measured],
) -> Result<Vec<ParameterCheck>, SpecError> {
    if !spec.limits_parameters() {
        return Ok(Vec::new());
    }
    const AXES: [&str; 3] = ["x", "y", "z"];
    let along = |j: usize, sign: f64| {
        positions.iter().find(|p| {
            (0..3).all(|i| {
                let want = if i == j { sign * g } else { 0.0 };
                (p.expected_m_s2[i] - want).abs() <= 0.02 * g
            })
        })
    };
    let mut pairs = Vec::with_capacity(3);
    for j in 0..3 {
        match (along(j, 1.0), along(j, -1.0)) {
            (Some(p), Some(m)) => pairs.push((p, m)),
            _ => {
                return Err(SpecError(format!(
                    "limits bias, scale factor or misalignment, which need a position imposing +g and one imposing −g along each axis: the plan has none along {} (verify with the six-position plan `six`)",
                    AXES[j]
                )))
            }
        }
    }
    let mut out = Vec::new();
    let mut check = |parameter: &str, axis: String, value: f64, u: f64, limit: f64, unit: &str| {
        out.push(ParameterCheck {
            parameter: parameter.into(),
            axis,
            value,
            u_expanded: u,
            limit,
            unit: unit.into(),
            decision: spec.decide_against(limit, None, value, u),
        });
    };
    for c in 0..3 {
        let (p, m) = pairs[c];
        let (ep, em) = (p.error_m_s2[c], m.error_m_s2[c]);
        let u = p.u_expanded_m_s2[c].hypot(m.u_expanded_m_s2[c]);
        if let Some(t) = spec.bias_mg {
            check("bias", AXES[c].into(), (ep + em) / 2.0 / G_N * 1e3, u / 2.0 / G_N * 1e3, t, "mg");
        }
        if let Some(t) = spec.scale_factor_ppm {
            check("scale_factor", AXES[c].into(), (ep - em) / (2.0 * g) * 1e6, u / (2.0 * g) * 1e6, t, "ppm");
        }
        if let Some(t) = spec.misalignment_urad {
            for j in (0..3).filter(|&j| j != c) {
                let (p, m) = pairs[j];
                let (ep, em) = (p.error_m_s2[c], m.error_m_s2[c]);
                let u = p.u_expanded_m_s2[c].hypot(m.u_expanded_m_s2[c]);
                check(
                    "misalignment",
                    format!("{}→{}", AXES[c], AXES[j]),
                    (ep - em) / (2.0 * g) * 1e6,
                    u / (2.0 * g) * 1e6,
                    t,
                    "µrad",
                );
            }
        }
    }
    Ok(out)
}

/// The share of each decision (pass, conditional pass, conditional fail, fail) when the true
/// error is `true_error` and each measurement of it errs by a normal deviate of standard
/// deviation `u` (m/s², so U = [`K`]·u): `n` draws from `seed`.
pub fn outcome_rates(spec: &Specification, true_error: f64, u: f64, n: usize, seed: u64) -> [f64; 4] {
    use rand::SeedableRng;
    use rand_distr::Distribution;
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let mut counts = [0usize; 4];
    for _ in 0..n {
        let z: f64 = rand_distr::StandardNormal.sample(&mut rng);
        counts[spec.decide(true_error + u * z, K * u) as usize] += 1;
    }
    counts.map(|c| c as f64 / n.max(1) as f64)
}

/// The share of each decision (as [`outcome_rates`]) of one parameter that [`parameters`]
/// measures from the six ±axis positions, when its true value is `true_value` (in its unit:
/// `bias` of x in mg, `scale_factor` of x in ppm, `misalignment` x→y in µrad) and every
/// component of every position errs by a normal deviate of standard deviation `u` (m/s²,
/// stated as U = [`K`]·u): the check of the quadrature that gives the parameter's U.
pub fn parameter_outcome_rates(
    spec: &Specification,
    g: f64,
    parameter: &str,
    true_value: f64,
    u: f64,
    n: usize,
    seed: u64,
) -> Result<[f64; 4], SpecError> {
    use rand::SeedableRng;
    use rand_distr::Distribution;
    // The axis its check names, and the error it leaves on channel x at an acceleration a.
    let axis = match parameter {
        "bias" | "scale_factor" => "x",
        "misalignment" => "x→y",
        other => return Err(SpecError(format!("has no parameter `{other}`"))),
    };
    let effect = |a: [f64; 3]| match parameter {
        "bias" => true_value * 1e-3 * G_N,
        "scale_factor" => true_value * 1e-6 * a[0],
        _ => true_value * 1e-6 * a[1],
    };
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let mut counts = [0usize; 4];
    let imposed: Vec<[f64; 3]> = (0..6)
        .map(|k| {
            let mut a = [0.0; 3];
            a[k / 2] = if k % 2 == 0 { g } else { -g };
            a
        })
        .collect();
    for _ in 0..n {
        let positions: Vec<Measured> = imposed
            .iter()
            .map(|&a| {
                let mut e = [0.0; 3];
                for (i, v) in e.iter_mut().enumerate() {
                    let z: f64 = rand_distr::StandardNormal.sample(&mut rng);
                    *v = u * z + if i == 0 { effect(a) } else { 0.0 };
                }
                Measured { expected_m_s2: a, error_m_s2: e, u_expanded_m_s2: [K * u; 3] }
            })
            .collect();
        let checks = parameters(spec, g, &positions)?;
        let c = checks
            .iter()
            .find(|c| c.parameter == parameter && c.axis == axis)
            .ok_or_else(|| SpecError(format!("limits no {parameter}")))?;
        counts[c.decision as usize] += 1;
    }
    Ok(counts.map(|c| c as f64 / n.max(1) as f64))
}

/// The share of results accepted (see [`outcome_rates`]): at the limit, the false-accept rate
/// (ILAC-G8's specific risk).
pub fn accept_rate(spec: &Specification, true_error: f64, u: f64, n: usize, seed: u64) -> f64 {
    outcome_rates(spec, true_error, u, n, seed)[Decision::Pass as usize]
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spec(rule: RuleKind, w: Option<f64>) -> Specification {
        Specification {
            unit_type: "MS9002.D triad".into(),
            acceleration_error_m_s2: 0.05,
            rule,
            guard_band_m_s2: w,
            bias_mg: None,
            scale_factor_ppm: None,
            misalignment_urad: None,
        }
    }

    /// Errors made by a bias b and a scale/misalignment matrix S (e = b + S·a) at the six ±axis
    /// positions (and one tilted position, which is not read) come back as b, the diagonal and
    /// the off-diagonal of S, decided against their limits; a plan without a ±axis pair is
    /// refused when a parameter is limited.
    #[test]
    fn the_six_axis_positions_give_bias_scale_factor_and_misalignment() {
        let g = 9.81;
        let b = [0.01, 0.0, -0.02];
        let mut sm = [[0.0; 3]; 3];
        sm[0][0] = 100e-6;
        sm[0][1] = 50e-6;
        sm[2][1] = -400e-6;
        let at = |a: [f64; 3]| Measured {
            expected_m_s2: a,
            error_m_s2: [0, 1, 2].map(|c| b[c] + (0..3).map(|j| sm[c][j] * a[j]).sum::<f64>()),
            u_expanded_m_s2: [0.0002; 3],
        };
        let mut six: Vec<Measured> = (0..3)
            .flat_map(|j| {
                [1.0, -1.0].map(|s| {
                    let mut a = [0.0; 3];
                    a[j] = s * g;
                    at(a)
                })
            })
            .collect();
        six.insert(2, at([g / 2f64.sqrt(), g / 2f64.sqrt(), 0.0]));
        let limited = Specification {
            bias_mg: Some(1.03),
            scale_factor_ppm: Some(200.0),
            misalignment_urad: Some(390.0),
            ..spec(RuleKind::GuardBand, None)
        };
        assert!(limited.check().is_ok());
        let r = parameters(&limited, g, &six).unwrap();
        let find =
            |p: &str, axis: &str| r.iter().find(|c| c.parameter == p && c.axis == axis).unwrap().clone();
        let bx = find("bias", "x");
        assert!((bx.value - 0.01 / G_N * 1e3).abs() < 1e-9, "{bx:?}");
        assert!((bx.u_expanded - 0.0002 * 2f64.sqrt() / 2.0 / G_N * 1e3).abs() < 1e-9);
        assert_eq!(bx.decision, Decision::ConditionalPass, "1.020 mg, U 0.014 mg, T 1.03 mg: {bx:?}");
        assert_eq!(find("bias", "z").decision, Decision::Fail, "2.04 mg");
        let sx = find("scale_factor", "x");
        assert!((sx.value - 100.0).abs() < 1e-6 && sx.unit == "ppm", "{sx:?}");
        assert_eq!(sx.decision, Decision::Pass, "100 ppm, U 14 ppm, T 200 ppm: {sx:?}");
        let mxy = find("misalignment", "x→y");
        assert!((mxy.value - 50.0).abs() < 1e-6, "{mxy:?}");
        assert!((find("misalignment", "z→y").value + 400.0).abs() < 1e-6);
        assert_eq!(find("misalignment", "z→y").decision, Decision::ConditionalFail, "400 µrad, U 14, T 390");
        assert_eq!(r.len(), 3 + 3 + 6);
        // No parameter limited: nothing to measure, whatever the plan.
        assert!(parameters(&spec(RuleKind::Simple, None), g, &six[..2]).unwrap().is_empty());
        let e = parameters(&limited, g, &six[..4]).unwrap_err().to_string();
        assert!(e.contains("the plan has none along y"), "{e}");
        let bad = Specification { bias_mg: Some(-1.0), ..limited };
        assert!(bad.check().unwrap_err().to_string().contains("`bias_mg` must be a positive limit, got -1"));
    }

    #[test]
    fn results_at_the_limit_and_half_a_u_either_side_get_the_rule_s_outcomes() {
        let (t, u) = (0.05, 0.01);
        let g = spec(RuleKind::GuardBand, None);
        let s = spec(RuleKind::Simple, None);
        let at = |x: f64| [g.decide(x, u), g.decide(-x, u), s.decide(x, u)];
        use Decision::*;
        assert_eq!(at(t - 1.5 * u), [Pass, Pass, Pass]);
        assert_eq!(at(t - 0.5 * u), [ConditionalPass, ConditionalPass, Pass]);
        assert_eq!(at(t), [ConditionalPass, ConditionalPass, Pass]);
        assert_eq!(at(t + 0.5 * u), [ConditionalFail, ConditionalFail, Fail]);
        assert_eq!(at(t + 1.5 * u), [Fail, Fail, Fail]);
        // A stated guard band replaces U.
        assert_eq!(spec(RuleKind::GuardBand, Some(0.002)).decide(t - 0.005, u), Pass);
        assert!(Pass.accepted() && !ConditionalPass.accepted());
        assert!(ConditionalFail.out_of_tolerance() && !ConditionalPass.out_of_tolerance());
        assert_eq!(serde_json::to_string(&ConditionalPass).unwrap(), "\"conditional pass\"");
    }

    #[test]
    fn each_parameters_u_is_its_scatter_so_the_guard_band_keeps_its_false_accepts_at_the_limit() {
        let s = Specification {
            bias_mg: Some(2.0),
            scale_factor_ppm: Some(2000.0),
            misalignment_urad: Some(2000.0),
            ..spec(RuleKind::GuardBand, None)
        };
        let u = 0.004;
        for (p, t) in [("bias", 2.0), ("scale_factor", 2000.0), ("misalignment", 2000.0)] {
            let r = parameter_outcome_rates(&s, 9.80665, p, t, u, 100_000, 11).unwrap();
            // A U from the quadrature that matched the scatter gives 2.3 % at the limit; a U
            // √2 too wide would give 0.3 %, one √2 too narrow 7.9 %.
            assert!((0.018..=0.025).contains(&r[0]), "{p}: {r:?}");
            let inside = parameter_outcome_rates(&s, 9.80665, p, 0.0, u, 20_000, 12).unwrap();
            assert!(inside[0] > 0.99, "{p}: {inside:?}");
        }
        assert!(parameter_outcome_rates(&s, 9.80665, "offset", 0.0, u, 10, 1).is_err());
    }

    #[test]
    fn the_guard_band_keeps_false_accepts_at_the_limit_below_2_5_percent() {
        let (t, u) = (0.05, 0.004);
        let g = spec(RuleKind::GuardBand, None);
        let far = accept_rate(&g, t, u, 200_000, 7);
        assert!((0.018..0.025).contains(&far), "guard-band false-accept rate {far}");
        // The simple rule shares the risk: half the units at the limit are accepted.
        let simple = accept_rate(&spec(RuleKind::Simple, None), t, u, 200_000, 7);
        assert!((simple - 0.5).abs() < 0.01, "{simple}");
        // Well inside, the guard band costs little; outside by 2u, a unit is accepted only when the
        // measurement errs by -4u.
        assert!(accept_rate(&g, t - 4.0 * u, u, 50_000, 8) > 0.97);
        assert!(accept_rate(&g, t + 2.0 * u, u, 50_000, 9) < 1e-3);
    }

    #[test]
    fn the_measured_error_s_uncertainty_has_each_reference_s_share() {
        let g = 9.81;
        let sd = [1e-4, 2e-4, 3e-4];
        // Type A alone: 2 sd.
        let u = measured_error_u(0.0, 0.0, g, sd, VerifyReferences::default());
        for i in 0..3 {
            assert!((u[i] - 2.0 * sd[i]).abs() < 1e-15);
        }
        // Along an axis, a head angle error moves the two perpendicular components by g·δ to
        // first order and the axial one not at all; a rotation likewise; g only the axial one.
        let up = accelcal_shared::gravity(0.0, 0.0, g);
        let axis = up.iter().position(|v| v.abs() > 1.0).unwrap();
        let r = VerifyReferences { head_angle_rad: 1e-4, head_orthogonality_rad: 0.0, g_m_s2: 0.0 };
        let u = measured_error_u(0.0, 0.0, g, [0.0; 3], r);
        assert!(u[axis] < 1e-9, "{u:?}");
        assert!(u.iter().any(|&v| (v - 2.0 * g * 1e-4).abs() < 1e-6 * g), "{u:?}");
        let r = VerifyReferences { head_angle_rad: 0.0, head_orthogonality_rad: 1e-4, g_m_s2: 0.0 };
        let u = measured_error_u(0.0, 0.0, g, [0.0; 3], r);
        assert!(
            u[axis] < 1e-12 && (0..3).filter(|&i| i != axis).all(|i| (u[i] - 2.0 * g * 1e-4).abs() < 1e-9)
        );
        let r = VerifyReferences { g_m_s2: 1e-3, ..Default::default() };
        let u = measured_error_u(0.0, 0.0, g, [0.0; 3], r);
        assert!((u[axis] - 2e-3).abs() < 1e-12);
    }

    #[test]
    fn a_specification_that_cannot_be_applied_is_refused() {
        let mut s = spec(RuleKind::Simple, Some(0.01));
        assert!(s.check().unwrap_err().to_string().contains("does not apply to the rule `simple`"));
        s = spec(RuleKind::GuardBand, Some(0.06));
        assert!(s.check().unwrap_err().to_string().contains("below the limit"));
        s.guard_band_m_s2 = None;
        s.acceleration_error_m_s2 = -1.0;
        assert!(s.check().is_err());
        s.acceleration_error_m_s2 = 0.05;
        s.check().unwrap();
    }
}
