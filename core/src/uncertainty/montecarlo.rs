//! The budget checked by simulation (JCGM 101:2008, Supplement 1 of the GUM): units calibrated on
//! a simulated head whose errors are drawn from its stated uncertainties, and the true error of
//! each unit's calibrated acceleration compared with the expanded uncertainty its own budget
//! gives at that orientation.
//!
//! Each simulated unit: a triad with the simulator's spread of biases, sensitivities and
//! misalignments; the head's three stage rotations drawn from the stated orthogonality (the
//! simulator's `head_misalignment`), its angle setting errors from the stated angle uncertainty
//! (`angle_error`), the true g drawn from the stated u(g) while the fit uses the stated g,
//! and the temperature: the block calibrated 5 °C above the reference temperature, the unit's bias and
//! scale-factor coefficients drawn from the stated ones (`temperature`, common to the channels)
//! and the thermometer's reading off the true temperature by a draw of its stated u(T), and a
//! quadratic output that model 4 cannot follow: each of the six second-degree terms and the
//! sensitive axis' square drawn per unit (the simulator's `nonlinearity`). The
//! unit is fitted with model 4 by least squares, its budget made from the same stated values, and
//! at random orientations the calibrated acceleration of the noise-free codes is compared with the
//! truth: the fraction of axis values within `U` is the coverage, 95 % for a budget that is right.
//! A budget that is too wide fails as surely as one that is too narrow.

use accelcal_shared::terms::{BASIS, MODEL_4};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal, StandardNormal};
use rayon::prelude::*;
use serde::Serialize;

use super::{budget, References, TempCoefficients, ARCSEC};
use crate::calibrate::{fit_positions, Method};
use crate::positions::{Positions, T_REF_DEFAULT_C};
use crate::sim::effects::{AngleError, Effect, HeadMisalignment, Nonlinearity, SampleCtx, Temperature};
use crate::sim::{simulate, Plan, SimConfig, TempProfile, NOMINAL_CODES_PER_G};

/// How far above the reference temperature a scenario with temperature coefficients is run, °C.
const CALIBRATED_ABOVE_REF_C: f64 = 5.0;

/// One setting of the check: which contributors are on, and how large.
#[derive(Clone, Debug, Serialize)]
pub struct Scenario {
    /// Its name.
    pub name: String,
    /// White noise per sample, codes (one sigma).
    pub noise_codes: f64,
    /// Stated (and simulated) head angle setting uncertainty, arcsec.
    pub head_angle_arcsec: f64,
    /// Stated (and simulated) head orthogonality uncertainty, arcsec.
    pub head_orthogonality_arcsec: f64,
    /// Stated (and simulated) standard uncertainty of g, m/s².
    pub g_u_m_s2: f64,
    /// Stated (and simulated) temperature coefficients, one sigma; the campaign is run 5 °C above
    /// the reference temperature. `None`: at the reference temperature, none stated.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub temperature: Option<TempCoefficients>,
    /// One sigma of each second-degree term of the output (the simulator's `nonlinearity`: the
    /// sensitive axis' square and the six quadratic terms, drawn per unit), codes at 1 g; 0 for
    /// a linear unit.
    pub quadratic_codes: f64,
    /// The coverage a budget that is right reaches, (lowest, highest).
    #[serde(skip)]
    pub range: (f64, f64),
}

impl Scenario {
    /// The scenarios the check runs: every contributor on (coverage 95 ± 1.5 %), then each one
    /// alone (93–97 %; the sample noise cannot be switched off: alone, the others run with a
    /// small noise of 2 codes). In `all` the quadratic terms are of 1 code, the paper's finding
    /// (model 4 within one code of the best model); alone, 4 codes, well above the floor the
    /// plan's scatter sets for seeing them. Below that floor (80 codes of noise and 4 codes of
    /// quadratic terms: 93.3 % in a trial) the data cannot show a lack of fit that is there.
    pub fn standard() -> Vec<Scenario> {
        const ALL: (f64, f64) = (0.935, 0.965);
        const ALONE: (f64, f64) = (0.93, 0.97);
        let s = |name: &str, range: (f64, f64), noise: f64, angle: f64, ortho: f64, g: f64| Scenario {
            name: name.into(),
            noise_codes: noise,
            head_angle_arcsec: angle,
            head_orthogonality_arcsec: ortho,
            g_u_m_s2: g,
            temperature: None,
            quadratic_codes: 0.0,
            range,
        };
        let temp = TempCoefficients { bias_mg_per_c: 0.1, scale_ppm_per_c: 100.0, thermometer_c: 0.5 };
        vec![
            Scenario {
                temperature: Some(TempCoefficients { bias_mg_per_c: 0.05, ..temp }),
                quadratic_codes: 1.0,
                ..s("all", ALL, 80.0, 20.0, 30.0, 1e-3)
            },
            s("dwell_scatter", ALONE, 80.0, 0.0, 0.0, 0.0),
            s("head_angle", ALONE, 2.0, 60.0, 0.0, 0.0),
            s("head_orthogonality", ALONE, 2.0, 0.0, 60.0, 0.0),
            s("gravity", ALONE, 2.0, 0.0, 0.0, 5e-3),
            Scenario { temperature: Some(temp), ..s("temperature", ALONE, 2.0, 0.0, 0.0, 0.0) },
            Scenario { quadratic_codes: 4.0, ..s("lack_of_fit", ALONE, 2.0, 0.0, 0.0, 0.0) },
        ]
    }
}

/// The settings of a check.
#[derive(Clone, Debug)]
pub struct Settings {
    /// Units simulated per scenario.
    pub units: usize,
    /// The plan each unit is calibrated on.
    pub plan: Plan,
    /// Sample sets per position.
    pub samples: usize,
    /// Random orientations each unit is checked at.
    pub orientations: usize,
    /// Seed of every draw.
    pub seed: u64,
}

/// The outcome of one scenario.
#[derive(Clone, Debug, Serialize)]
pub struct Outcome {
    /// The scenario.
    pub scenario: Scenario,
    /// Units calibrated.
    pub units: usize,
    /// Axis values compared (units × orientations × 3).
    pub checks: usize,
    /// Of them, within the expanded uncertainty.
    pub within: usize,
    /// `within / checks`.
    pub coverage: f64,
    /// The mean over units of the largest expanded uncertainty at 1 g, m/s² (the worst axis of
    /// each unit's budget: with few degrees of freedom its scatter makes this mean of maxima
    /// larger than the budget's expectation).
    pub mean_u_m_s2: f64,
    /// The worst axis of the root mean square over units of each axis' expanded uncertainty,
    /// m/s²: the budget's expectation, comparable with a prediction made before the campaign.
    pub rms_u_m_s2: f64,
    /// The root mean square of the calibrated acceleration's error over the axis values compared
    /// (orientations none of the plans chose), m/s².
    pub rms_error_m_s2: f64,
}

/// One unit's part of an outcome.
struct UnitOutcome {
    within: usize,
    checks: usize,
    u_max: f64,
    /// Per axis, the budget's largest expanded uncertainty at 1 g, m/s².
    u_axes: [f64; 3],
    /// Sum of the squared errors of the axis values compared, (m/s²)².
    error_ss: f64,
}

/// Calibrates one simulated unit and counts its checks within U.
///
/// The budget uses the scenario's stated values, or `stated` when given (a budget that leaves a
/// simulated error out).
fn one_unit(
    s: &Scenario,
    set: &Settings,
    unit: usize,
    stated: Option<References>,
) -> Result<UnitOutcome, String> {
    let seed = set.seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ (unit as u64 + 1);
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x6d63_6865_636b);
    let g_stated = accelcal_shared::G_STANDARD;
    let g_true = g_stated + s.g_u_m_s2 * rng.sample::<f64, _>(StandardNormal);
    let mut effects: Vec<Box<dyn Effect>> = Vec::new();
    if s.head_angle_arcsec > 0.0 {
        effects.push(Box::new(AngleError { sd_mrad: s.head_angle_arcsec * ARCSEC * 1e3 }));
    }
    if s.head_orthogonality_arcsec > 0.0 {
        let n = Normal::new(0.0, s.head_orthogonality_arcsec * ARCSEC * 1e3).map_err(|e| e.to_string())?;
        effects.push(Box::new(HeadMisalignment { r_mrad: [0, 1, 2].map(|_| n.sample(&mut rng)) }));
    }
    // The thermometer reads `read_c`; the block is at `read_c` less the reading's error.
    let read_c = T_REF_DEFAULT_C + CALIBRATED_ABOVE_REF_C;
    let mut temp = None;
    if let Some(t) = s.temperature {
        let z = |rng: &mut ChaCha8Rng| rng.sample::<f64, _>(StandardNormal);
        let codes_per_mg = 1e-3 * accelcal_shared::G_STANDARD * NOMINAL_CODES_PER_G / g_true;
        effects.push(Box::new(Temperature {
            bias: t.bias_mg_per_c * codes_per_mg * z(&mut rng),
            scale: t.scale_ppm_per_c * z(&mut rng),
            t_ref: T_REF_DEFAULT_C,
        }));
        let true_c = read_c - t.thermometer_c * z(&mut rng);
        temp = Some(TempProfile { base_c: true_c, amp_c: 0.0, cycles: 0.0, phase: 0.0 });
    }
    let quadratic = (s.quadratic_codes > 0.0).then(|| {
        let per_g2 = s.quadratic_codes / (g_true * g_true);
        let mut z = || per_g2 * rng.sample::<f64, _>(StandardNormal);
        Nonlinearity { k2: z(), terms: BASIS[4..10].iter().map(|&t| (t, z())).collect() }
    });
    if let Some(q) = &quadratic {
        effects.push(Box::new(q.clone()));
    }
    let cfg = SimConfig {
        seed,
        plan: set.plan.clone(),
        samples: set.samples,
        noise: s.noise_codes,
        g: g_true,
        effects,
        temp,
        ..SimConfig::default()
    };
    let (mut campaign, truth) = simulate(&cfg);
    if let Some(t) = campaign.temp_c.as_mut() {
        t.iter_mut().for_each(|v| *v = read_c);
    }
    let pos = Positions::new(&campaign, g_stated);
    let stats = pos.channel_stats(&campaign);
    let fits = fit_positions(&pos, &stats, Method::Lsq, MODEL_4).map_err(|e| e.to_string())?;
    let refs = stated.unwrap_or(References {
        head_angle_rad: s.head_angle_arcsec * ARCSEC,
        head_orthogonality_rad: s.head_orthogonality_arcsec * ARCSEC,
        g_m_s2: s.g_u_m_s2,
        lack_of_fit_codes: None,
        temperature: s.temperature,
    });
    let fit_refs: Vec<_> = fits.iter().map(|(_, f)| f).collect();
    let b = budget(&pos, &stats, &fit_refs, refs).map_err(|e| e.to_string())?;
    let (mut within, mut error_ss) = (0, 0.0);
    for _ in 0..set.orientations {
        let d: [f64; 3] = [0, 1, 2].map(|_| rng.sample::<f64, _>(StandardNormal));
        let norm = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        let a = d.map(|v| g_true * v / norm);
        // The noise-free codes of the true unit, in the budget's axis order.
        let codes = b.order.map(|ci| {
            let t = &truth.channels[ci];
            let bent = quadratic.as_ref().map_or(0.0, |q| q.output(&SampleCtx::basic(a, ci, t.axis)));
            t.bias + (0..3).map(|j| t.k[j] * a[j]).sum::<f64>() + bent
        });
        let ahat = b.cal.apply(codes);
        let u = b.expanded_at(a);
        within += (0..3).filter(|&i| (ahat[i] - a[i]).abs() <= u[i]).count();
        error_ss += (0..3).map(|i| (ahat[i] - a[i]).powi(2)).sum::<f64>();
    }
    let u_max = b.expanded_max.into_iter().fold(0.0, f64::max);
    Ok(UnitOutcome { within, checks: 3 * set.orientations, u_max, u_axes: b.expanded_max, error_ss })
}

/// Runs one scenario; `progress` is called after each unit with the number done.
pub fn run(s: &Scenario, set: &Settings, progress: &(dyn Fn(usize) + Sync)) -> Result<Outcome, String> {
    let done = std::sync::atomic::AtomicUsize::new(0);
    let results: Result<Vec<UnitOutcome>, String> = (0..set.units)
        .into_par_iter()
        .map(|u| {
            let r = one_unit(s, set, u, None);
            progress(done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1);
            r
        })
        .collect();
    let results = results?;
    let within = results.iter().map(|r| r.within).sum::<usize>();
    let checks = results.iter().map(|r| r.checks).sum::<usize>();
    Ok(Outcome {
        scenario: s.clone(),
        units: set.units,
        checks,
        within,
        coverage: within as f64 / checks.max(1) as f64,
        mean_u_m_s2: results.iter().map(|r| r.u_max).sum::<f64>() / set.units.max(1) as f64,
        rms_u_m_s2: (0..3)
            .map(|i| {
                (results.iter().map(|r| r.u_axes[i].powi(2)).sum::<f64>() / set.units.max(1) as f64).sqrt()
            })
            .fold(0.0, f64::max),
        rms_error_m_s2: (results.iter().map(|r| r.error_ss).sum::<f64>() / checks.max(1) as f64).sqrt(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A scenario of the head alone (2 codes of noise): its angle and orthogonality errors,
    /// arcsec, stated and simulated.
    fn head_only(name: &str, angle_arcsec: f64, orthogonality_arcsec: f64) -> Scenario {
        Scenario {
            name: name.into(),
            noise_codes: 2.0,
            head_angle_arcsec: angle_arcsec,
            head_orthogonality_arcsec: orthogonality_arcsec,
            g_u_m_s2: 0.0,
            temperature: None,
            quadratic_codes: 0.0,
            range: (0.93, 0.97),
        }
    }

    /// The coverage of the first `units` units of `s` when their budgets take `stated` instead
    /// of the scenario's values.
    fn coverage_stated(s: &Scenario, set: &Settings, units: usize, stated: References) -> f64 {
        let (mut within, mut checks) = (0, 0);
        for u in 0..units {
            let o = one_unit(s, set, u, Some(stated)).unwrap();
            within += o.within;
            checks += o.checks;
        }
        within as f64 / checks as f64
    }

    /// A head whose angles are off by 30″ (one sigma) while its certificate states 3″: its
    /// budget covers 95 % either way, since the part of the angle errors left in the residuals
    /// is in the dwell scatter unless a stated head_angle explains it (then it is taken out of
    /// the scatter, not counted twice). So the head's measured value
    /// (`headsig::MeasuredAngle`), fed to the budget, names the head as the source without
    /// widening U much (94.9 % with 3″ stated, 96.0 % with 30″ at this seed).
    #[test]
    fn a_head_worse_than_its_certificate_is_covered_with_its_stated_or_measured_error() {
        let set = Settings { units: 150, plan: Plan::head(), samples: 20, orientations: 10, seed: 5 };
        let s = head_only("head out of true", 30.0, 0.0);
        let coverage = |stated_arcsec: f64| {
            let stated = References { head_angle_rad: stated_arcsec * ARCSEC, ..References::default() };
            coverage_stated(&s, &set, set.units, stated)
        };
        let (certificate, measured) = (coverage(3.0), coverage(30.0));
        eprintln!("coverage: {certificate} with the certificate's 3″, {measured} with the measured 30″");
        assert!((0.93..=0.97).contains(&certificate), "{certificate}");
        assert!((0.93..=0.97).contains(&measured), "{measured}");
    }

    #[test]
    fn a_budget_that_is_right_covers_about_95_percent_and_one_without_the_head_does_not() {
        let set = Settings { units: 150, plan: Plan::head(), samples: 20, orientations: 10, seed: 3 };
        let s = head_only("head", 60.0, 60.0);
        let out = run(&s, &set, &|_| {}).unwrap();
        assert!((0.92..=0.98).contains(&out.coverage), "{out:?}");
        // The same head, its orthogonality left out of the budget: the coverage falls.
        let stated = References { head_angle_rad: 60.0 * ARCSEC, ..References::default() };
        let coverage = coverage_stated(&s, &set, 60, stated);
        assert!(coverage < 0.9, "{coverage}");
    }

    #[test]
    fn a_quadratic_output_is_covered_by_its_measured_lack_of_fit_which_a_linear_unit_does_not_have() {
        let set = Settings { units: 150, plan: Plan::head(), samples: 100, orientations: 10, seed: 5 };
        let s = Scenario::standard().into_iter().find(|s| s.name == "lack_of_fit").unwrap();
        let out = run(&s, &set, &|_| {}).unwrap();
        assert!((0.92..=0.98).contains(&out.coverage), "{out:?}");
        // The same units without the quadratic terms: their lack of fit is not there.
        let flat = Scenario { quadratic_codes: 0.0, ..s.clone() };
        let lin = run(&flat, &set, &|_| {}).unwrap();
        assert!(lin.mean_u_m_s2 < 0.5 * out.mean_u_m_s2, "{lin:?} {out:?}");
    }
}
