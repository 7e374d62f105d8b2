use super::search::{design, design_auto, AutoTarget, Head, MIN_POSITIONS};
use super::*;
use crate::sim::effects::AngleError;
use crate::sim::{simulate, Plan, SimConfig};
use crate::uncertainty::{budget, References, ARCSEC};

const G: f64 = accelcal_shared::G_STANDARD;

fn head() -> Head {
    Head { alpha_step_deg: 15.0, beta_step_deg: 15.0, beta_max_deg: 90.0 }
}

fn stated() -> Stated {
    Stated { head_angle_rad: 20.0 * ARCSEC, g_m_s2: 1e-4, chamber: None }
}

/// A simulated campaign: 80 codes of noise, the head's angles off by 20″ (one sigma).
fn campaign(plan: Plan, samples: usize, seed: u64) -> Campaign {
    let cfg = SimConfig {
        seed,
        plan,
        samples,
        noise: 80.0,
        effects: vec![Box::new(AngleError { sd_mrad: 20.0 * ARCSEC * 1e3 })],
        ..SimConfig::default()
    };
    simulate(&cfg).0
}

/// The budget of a simulated unit (as [`campaign`]) fitted with model 4 by least squares, with
/// the head's and g's stated uncertainties.
fn unit_budget(plan: Plan, samples: usize, seed: u64) -> crate::uncertainty::Budget {
    let c = campaign(plan, samples, seed);
    let pos = Positions::new(&c, G);
    let stats = pos.channel_stats(&c);
    let fits = fit_positions(&pos, &stats, Method::Lsq, MODEL_4).unwrap();
    let refs: Vec<_> = fits.iter().map(|(_, f)| f).collect();
    let r = References {
        head_angle_rad: stated().head_angle_rad,
        g_m_s2: stated().g_m_s2,
        ..References::default()
    };
    budget(&pos, &stats, &refs, r).unwrap()
}

#[test]
fn the_head_reaches_every_alpha_at_each_beta_and_each_pole_once() {
    let r = head().reachable().unwrap();
    assert_eq!(r.len(), 24 * 11 + 2);
    assert_eq!(r.iter().filter(|p| p.1 == 90.0).count(), 1);
    let limited = Head { beta_max_deg: 60.0, ..head() }.reachable().unwrap();
    assert_eq!(limited.len(), 24 * 9);
    assert!(Head { alpha_step_deg: 0.0, ..head() }.reachable().is_err());
}

#[test]
fn an_earlier_campaign_gives_the_unit_s_noise_and_sensitivities() {
    let c = campaign(Plan::head(), 200, 3);
    let p = Prior::from_campaign(&c, G, "like.csv").unwrap();
    for ax in 0..3 {
        assert!((p.noise_codes[ax] / 80.0 - 1.0).abs() < 0.03, "{:?}", p.noise_codes);
        let own = p.model.k[ax][ax] * G / crate::sim::NOMINAL_CODES_PER_G;
        assert!((own - 1.0).abs() < 0.05, "{own}");
    }
}

/// The prediction is the budget's, before the campaign: over simulated units on the paper's
/// plan, the budgets' mean U (from their own dwell scatter) is the predicted U.
#[test]
fn the_prediction_is_what_the_budgets_state_after_the_campaign() {
    let samples = 100;
    let prior = Prior::from_campaign(&campaign(Plan::head(), samples, 100), G, "like").unwrap();
    let predicted = predict(&Plan::head().positions, samples, &prior, &stated(), G).unwrap();
    let mut sum = 0.0;
    let units = 12;
    for seed in 0..units {
        let b = unit_budget(Plan::head(), samples, seed);
        sum += b.expanded_max.into_iter().fold(0.0, f64::max);
    }
    let mean = sum / units as f64;
    let ratio = predicted.worst_m_s2 / mean;
    assert!(
        (0.93..1.07).contains(&ratio),
        "predicted {:.4e}, budgets' mean {mean:.4e}",
        predicted.worst_m_s2
    );
    // Noise dominates at 1 s of dwell; the head's angle errors are there too.
    let part = |n: &str| predicted.parts.iter().find(|p| p.name == n).unwrap().u_m_s2;
    assert!(part("noise") > part("head_angle") && part("head_angle") > 0.0, "{predicted:?}");
}

#[test]
fn a_designed_plan_beats_the_paper_s_and_a_random_one_of_its_size() {
    let prior = Prior::nominal(80.0, G).unwrap();
    let d = design(24, 400, &prior, &stated(), G, &head(), 1).unwrap();
    assert_eq!(d.positions.len(), 24);
    assert_eq!(d.selection, order::Selection::Alternate);
    let random = predict(&Plan::random(24, 1).positions, 400, &prior, &stated(), G).unwrap();
    assert!(
        d.prediction.worst_m_s2 < random.worst_m_s2,
        "{} vs {}",
        d.prediction.worst_m_s2,
        random.worst_m_s2
    );
    // Per position, better than the paper's plan: U²·N is what a position buys.
    let paper = predict(&Plan::head().positions, 400, &prior, &stated(), G).unwrap();
    let per = |p: &Prediction, n: f64| p.worst_m_s2.powi(2) * n;
    assert!(per(&d.prediction, 24.0) < per(&paper, 62.0), "{d:?} {paper:?}");
    // The same seed, the same plan.
    let again = design(24, 400, &prior, &stated(), G, &head(), 1).unwrap();
    assert_eq!(again.positions, d.positions);
    // Every position is one the head reaches.
    let reach = head().reachable().unwrap();
    assert!(d.positions.iter().all(|p| p.1.abs() == 90.0 || reach.contains(p)));
}

#[test]
fn auto_reaches_the_target_in_less_head_time_than_the_paper_s_plan() {
    let prior = Prior::nominal(80.0, G).unwrap();
    let paper = predict(&Plan::head().positions, 400, &prior, &stated(), G).unwrap();
    let target = AutoTarget { u_m_s2: paper.worst_m_s2, rate_hz: 100.0, move_s: 10.0 };
    let d = design_auto(&target, &prior, &stated(), G, &head(), 1, &|_| {}).unwrap();
    assert!(d.prediction.worst_m_s2 <= target.u_m_s2, "{d:?}");
    let t = head_time_s(d.positions.len(), d.samples, 100.0, 10.0);
    let t_paper = head_time_s(62, 400, 100.0, 10.0);
    assert!(
        t < 0.75 * t_paper,
        "{t} s against {t_paper} s: {} positions of {} samples",
        d.positions.len(),
        d.samples
    );
}

#[test]
fn too_few_or_too_many_positions_are_refused() {
    let prior = Prior::nominal(80.0, G).unwrap();
    let few = design(MIN_POSITIONS - 1, 100, &prior, &stated(), G, &head(), 1).unwrap_err();
    assert!(matches!(few, DesignError::TooFew { n: 7, min: 8 }), "{few}");
    let many = design(300, 100, &prior, &stated(), G, &head(), 1).unwrap_err();
    assert!(matches!(many, DesignError::TooMany { n: 300, reachable: 266 }), "{many}");
    let unreachable = AutoTarget { u_m_s2: 1e-9, rate_hz: 100.0, move_s: 10.0 };
    let e = design_auto(&unreachable, &prior, &stated(), G, &head(), 1, &|_| {}).unwrap_err();
    assert!(matches!(e, DesignError::Unreachable { .. }), "{e}");
}

/// The chamber's factor: `1/J + (t − t̄)²/S_tt` at the range's worse end.
#[test]
fn the_chamber_factor_is_the_linear_fits_variance_at_the_range_end() {
    let c = Chamber::new(vec![-10.0, 20.0, 50.0], 900.0).unwrap();
    // t̄ = 20, S_tt = 1800, the end 30 away: 1/3 + 900/1800.
    assert!((c.factor() - (1.0 / 3.0 + 0.5)).abs() < 1e-12);
    assert_eq!(Chamber::new(vec![-10.0, 50.0], 0.0).unwrap().factor(), 1.0);
    assert_eq!(c.head_time_s(100.0), 3.0 * 1000.0);
    assert!(Chamber::new(vec![20.0, 20.0], 900.0).is_err());
    assert!(Chamber::new(vec![20.0], 900.0).is_err());
    assert!(Chamber::new(vec![20.0, f64::NAN], 900.0).is_err());
    assert!(Chamber::new(vec![0.0, 20.0], -1.0).is_err());
}

/// The prediction in a chamber is what the linear thermal model, fitted by least squares on the
/// plan run at each setpoint with the noise and the head's angle errors drawn anew at every
/// dwell, gives at the worst end of the calibrated range: the variance of the calibrated
/// acceleration at its worst orientation, estimated over 6,000 such campaigns, is the predicted
/// one within 8 % (measured: 5.4 % above it; each point's estimate has a standard error of 1.8 %,
/// and the largest of 200 such estimates runs high by a few of them). With the factor left out
/// (`1/J` alone) the ratio is 2.7.
#[test]
fn a_chamber_prediction_is_the_thermal_fits_variance_at_the_worst_temperature() {
    use nalgebra::{DMatrix, DVector, Matrix3, Vector3};
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};
    let setpoints = vec![-10.0, 20.0, 50.0];
    let (sigma, samples) = (80.0, 400usize);
    let prior = Prior::nominal(sigma, G).unwrap();
    let stated = Stated {
        head_angle_rad: 20.0 * ARCSEC,
        g_m_s2: 0.0,
        chamber: Some(Chamber::new(setpoints.clone(), 900.0).unwrap()),
    };
    let plan = Plan::tumble24().positions;
    let p = predict(&plan, samples, &prior, &stated, G).unwrap();
    // 72 dwells, 8 coefficients: k = 2.
    assert_eq!(p.k, 2.0);
    let predicted = (p.worst_m_s2 / p.k).powi(2);
    // Below one pass of the same plan by at least the factor's square root (5/6 scales every part
    // here, u(g) being 0; the one pass's k is also larger).
    let one = predict(&plan, samples, &prior, &Stated { chamber: None, ..stated.clone() }, G).unwrap();
    assert!(
        p.worst_m_s2 < one.worst_m_s2 * (5.0f64 / 6.0).sqrt() * 1.001,
        "{} {}",
        p.worst_m_s2,
        one.worst_m_s2
    );

    let k = prior.model.k;
    let points = sphere(200).into_iter().map(|d| d.map(|v| v * G)).collect::<Vec<_>>();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
    let noise = Normal::new(0.0, sigma / (samples as f64).sqrt()).unwrap();
    let angle = Normal::new(0.0, stated.head_angle_rad).unwrap();
    let rows = plan.len() * setpoints.len();
    let trials = 6000;
    let mut sum2 = vec![[0.0f64; 3]; points.len()];
    for _ in 0..trials {
        let mut x = DMatrix::<f64>::zeros(rows, 8);
        let mut y = [DVector::<f64>::zeros(rows), DVector::zeros(rows), DVector::zeros(rows)];
        for (j, &t) in setpoints.iter().enumerate() {
            for (i, &(al, be)) in plan.iter().enumerate() {
                let r = j * plan.len() + i;
                let a = accelcal_shared::gravity(al, be, G);
                let e = (angle.sample(&mut rng), angle.sample(&mut rng));
                let truth = accelcal_shared::gravity(al + e.0.to_degrees(), be + e.1.to_degrees(), G);
                let tt = t - 25.0;
                let row = [1.0, a[0], a[1], a[2], tt, a[0] * tt, a[1] * tt, a[2] * tt];
                for (c, v) in row.iter().enumerate() {
                    x[(r, c)] = *v;
                }
                for ch in 0..3 {
                    y[ch][r] = (0..3).map(|m| k[ch][m] * truth[m]).sum::<f64>() + noise.sample(&mut rng);
                }
            }
        }
        let xtx_inv = (x.transpose() * &x).try_inverse().unwrap();
        // The model-4 coefficients in force at 50 °C (the end farther from the mean 20 °C is
        // either; -10 °C as well): c + c_t·t.
        let tt = 50.0 - 25.0;
        let mut u0 = Vector3::zeros();
        let mut kk = Matrix3::zeros();
        for ch in 0..3 {
            let c = &xtx_inv * x.transpose() * &y[ch];
            u0[ch] = c[0] + c[4] * tt;
            for m in 0..3 {
                kk[(ch, m)] = c[1 + m] + c[5 + m] * tt;
            }
        }
        let kinv_hat = kk.try_inverse().unwrap();
        for (pi, a) in points.iter().enumerate() {
            let a = Vector3::from(*a);
            let u = Matrix3::from_row_slice(&k.concat()) * a;
            let err = kinv_hat * (u - u0) - a;
            for ax in 0..3 {
                sum2[pi][ax] += err[ax] * err[ax];
            }
        }
    }
    let empirical = sum2.iter().flat_map(|v| v.iter()).fold(0.0f64, |m, &v| m.max(v / trials as f64));
    let ratio = empirical / predicted;
    assert!(
        (ratio - 1.0).abs() < 0.08,
        "empirical {empirical:.4e}, predicted {predicted:.4e} (m/s²)², ratio {ratio:.3}"
    );
}

/// On a designed plan of 16 positions a linear unit is given a lack of fit on 2.3 % of its
/// channels, as on the paper's plan (about 6.7 % of the units have one on some axis): the
/// test's limit is a quantile of its weighted χ², which has few degrees of freedom on so few
/// positions. Its mean and two spreads, before, gave 31 of these 300 units one (10.3 %).
#[test]
fn a_linear_unit_on_few_positions_is_seldom_given_a_lack_of_fit() {
    let samples = 100;
    let d = design(16, samples, &Prior::nominal(80.0, G).unwrap(), &stated(), G, &head(), 1).unwrap();
    let plan = Plan { positions: d.positions.clone() };
    let units = 300;
    let mut given = 0;
    for seed in 0..units {
        let b = unit_budget(plan.clone(), samples, 1000 + seed);
        let lof = b.contributors.iter().find(|c| c.name == "lack_of_fit").unwrap();
        given += usize::from(lof.u_m_s2 > 0.0);
    }
    let rate = given as f64 / units as f64;
    eprintln!("lack of fit given to {given} of {units} linear units");
    // 1 − (1 − 0.0228)³ = 6.7 %; the binomial's σ over 300 units is 1.4 points (16 here).
    assert!((0.03..0.09).contains(&rate), "{given} of {units}");
}
