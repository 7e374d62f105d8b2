//! Unit tests of `uncertainty`.

use super::*;
use crate::calibrate::{fit_all, Method};
use crate::sim::{simulate, SimConfig};

#[test]
fn the_head_kinematics_without_errors_are_the_campaigns() {
    for (al, be) in [(0.0, 0.0), (30.0, -60.0), (120.0, 90.0), (-45.0, 30.0)] {
        let a = head_accel(al, be, 0.0, 0.0, [0.0; 3], 9.81);
        let b = accelcal_shared::gravity(al, be, 9.81);
        for i in 0..3 {
            assert!((a[i] - b[i]).abs() < 1e-12, "{al} {be}: {a:?} {b:?}");
        }
    }
}

fn unit(noise: f64) -> (Positions, Vec<ChannelStats>, Vec<LsqFit>) {
    simulated(SimConfig { samples: 50, noise, ..SimConfig::default() })
}

#[test]
fn each_stated_reference_adds_its_contributor_and_the_shares_add_up() {
    let (pos, stats, fits) = unit(80.0);
    let refs = |a: f64, o: f64, g: f64| References {
        head_angle_rad: a * ARCSEC,
        head_orthogonality_rad: o * ARCSEC,
        g_m_s2: g,
        ..References::default()
    };
    let fits: Vec<&LsqFit> = fits.iter().collect();
    let none = budget(&pos, &stats, &fits, refs(0.0, 0.0, 0.0)).unwrap();
    let all = budget(&pos, &stats, &fits, refs(20.0, 30.0, 1e-3)).unwrap();
    let share: f64 = all.contributors.iter().map(|c| c.share).sum();
    assert!((share - 1.0).abs() < 1e-9, "{share}");
    let mean: f64 = all.contributors.iter().map(|c| c.share_mean).sum();
    assert!((mean - 1.0).abs() < 1e-9, "{mean}");
    // The budget adds up where U is stated: √Σu² × k is the largest U, on its axis.
    let (axis, _) = all.stated;
    let uc = all.contributors.iter().map(|c| c.u_m_s2 * c.u_m_s2).sum::<f64>().sqrt();
    let largest = all.expanded_max.iter().fold(0.0f64, |m, &u| m.max(u));
    assert!(
        (all.k * uc / all.expanded_max[axis] - 1.0).abs() < 1e-9,
        "{} {:?}",
        all.k * uc,
        all.expanded_max
    );
    assert_eq!(all.expanded_max[axis], largest);
    assert!(all.contributors.iter().all(|c| c.u_m_s2 <= c.u_worst_m_s2 * (1.0 + 1e-12)));
    assert!((all.coverage_probability - 0.9545).abs() < 1e-3, "{}", all.coverage_probability);
    let u = |b: &Budget, name: &str| b.contributors.iter().find(|c| c.name == name).unwrap().u_worst_m_s2;
    assert_eq!(u(&none, "head_orthogonality"), 0.0);
    assert!(u(&all, "head_orthogonality") > 0.0 && u(&all, "gravity") > 0.0);
    // g's relative error scales the acceleration: at 1 g, u = g·u(g)/g = u(g).
    assert!((u(&all, "gravity") - 1e-3).abs() < 2e-5, "{}", u(&all, "gravity"));
    // Every stated reference adds variance (the lack of fit, measured from the same data
    // either way, aside: a head's stated rotation raises the floor it is seen above).
    let lof = |b: &Budget| b.contributors.iter().find(|c| c.name == "lack_of_fit").unwrap().covariance;
    for a in sphere(20).into_iter().map(|d| d.map(|v| v * 9.80665)) {
        let un = none.variance_at(&(none.covariance - lof(&none)), a);
        let ua = all.variance_at(&(all.covariance - lof(&all)), a);
        assert!((0..3).all(|i| ua[i] > un[i] && un[i] > 0.0), "{un:?} {ua:?}");
    }
    assert_eq!(none.not_included.len(), 4, "{:?}", none.not_included);
    // A calibrated acceleration of the fitted model's own codes is the acceleration.
    let a = [1.0, -2.0, 9.0];
    let codes = [0, 1, 2].map(|r| {
        let m = &all.model;
        m.u0[r] + (0..3).map(|j| m.k[r][j] * a[j]).sum::<f64>()
    });
    let back = all.cal.apply(codes);
    assert!((0..3).all(|i| (back[i] - a[i]).abs() < 1e-9), "{back:?}");
}

fn simulated(cfg: SimConfig) -> (Positions, Vec<ChannelStats>, Vec<LsqFit>) {
    let (c, _) = simulate(&cfg);
    let pos = Positions::new(&c, cfg.g);
    let stats = pos.channel_stats(&c);
    let fits = fit_all(&c, cfg.g, Method::Lsq, MODEL_4).unwrap().into_iter().map(|(_, f)| f).collect();
    (pos, stats, fits)
}

#[test]
fn the_lack_of_fit_a_quadratic_term_leaves_is_measured_and_in_u_and_a_linear_unit_has_none() {
    use crate::sim::effects::Nonlinearity;
    let lof = |b: &Budget| b.contributors.iter().find(|c| c.name == "lack_of_fit").unwrap().u_m_s2;
    let plain = SimConfig { samples: 100, noise: 2.0, ..SimConfig::default() };
    let (pos, stats, fits) = simulated(plain);
    let gaps = lack_of_fit::criterion_gap(&pos, &stats).unwrap();
    assert!(gaps.iter().all(|&v| (0.0..0.2).contains(&v)), "{gaps:?}");
    let fits: Vec<&LsqFit> = fits.iter().collect();
    let linear = budget(&pos, &stats, &fits, References::default()).unwrap();
    // A linear unit: at most what the scatter leaves above its threshold (0.1 code = 6e-5 m/s²).
    assert!(lof(&linear) < 6e-5, "{}", lof(&linear));
    let k2 = 6.0 / (9.80665f64 * 9.80665);
    let bent = SimConfig {
        samples: 100,
        noise: 2.0,
        effects: vec![Box::new(Nonlinearity { k2, terms: Vec::new() })],
        ..SimConfig::default()
    };
    let (pos, stats, fits) = simulated(bent);
    let gaps = lack_of_fit::criterion_gap(&pos, &stats).unwrap();
    assert!(gaps.iter().all(|&v| (0.8..3.0).contains(&v)), "{gaps:?}");
    let fits: Vec<&LsqFit> = fits.iter().collect();
    let with = References { lack_of_fit_codes: Some([gaps[0], gaps[1], gaps[2]]), ..References::default() };
    let b = budget(&pos, &stats, &fits, with).unwrap();
    // 6 codes of a_own²/g² leave 6·√(4/45) ≈ 1.8 codes RMS about its projection on the
    // linear functions over the sphere; 1.8 codes at 16384 codes/g is 1.07e-3 m/s².
    let u = lof(&b);
    assert!((0.9e-3..1.3e-3).contains(&u), "{u}");
    assert!((0..3).all(|i| b.expanded_max[i] > linear.expanded_max[i]), "{:?}", b.expanded_max);
    let source = &b.contributors.iter().find(|c| c.name == "lack_of_fit").unwrap().source;
    assert!(source.contains(&format!("x {:.2}", gaps[b.order[0]])), "{source}");
    assert!(b.not_included.iter().any(|n| n.contains("above the second degree")), "{:?}", b.not_included);
    // Six positions do not determine the quadratic model: not measured, and said so.
    let six = SimConfig { plan: crate::sim::Plan::six(), samples: 20, ..SimConfig::default() };
    let (pos, stats, fits) = simulated(six);
    let fits: Vec<&LsqFit> = fits.iter().collect();
    let b = budget(&pos, &stats, &fits, References::default()).unwrap();
    assert_eq!(lof(&b), 0.0);
    assert!(
        b.not_included.iter().any(|n| n.contains("not measured: the plan's 6 positions")),
        "{:?}",
        b.not_included
    );
}

#[test]
fn a_stated_temperature_coefficient_counts_the_distance_to_the_reference_temperature() {
    use crate::sim::TempProfile;
    let at = |base_c: f64| SimConfig {
        samples: 50,
        noise: 2.0,
        temp: Some(TempProfile { base_c, amp_c: 0.0, cycles: 0.0, phase: 0.0 }),
        ..SimConfig::default()
    };
    let t = TempCoefficients { bias_mg_per_c: 0.1, scale_ppm_per_c: 0.0, thermometer_c: 0.0 };
    let u = |base_c: f64, t: TempCoefficients| {
        let (pos, stats, fits) = simulated(at(base_c));
        let fits: Vec<&LsqFit> = fits.iter().collect();
        let b = budget(&pos, &stats, &fits, References { temperature: Some(t), ..References::default() })
            .unwrap();
        assert!(!b.not_included.iter().any(|n| n.contains("temperature")), "{:?}", b.not_included);
        b.contributors.iter().find(|c| c.name == "temperature").unwrap().u_m_s2
    };
    // 0.1 mg/°C, 5 °C from the reference (25 °C): 0.5 mg.
    let five = u(30.0, t);
    assert!((five - 0.5e-3 * 9.80665).abs() < 1e-5, "{five}");
    assert_eq!(u(25.0, t), 0.0);
    let read = u(25.0, TempCoefficients { thermometer_c: 2.0, ..t });
    assert!((read - 0.2e-3 * 9.80665).abs() < 1e-5, "{read}");
    // 100 ppm/°C over 5 °C: 500 ppm of 1 g on the sensitive axis.
    let scale = u(30.0, TempCoefficients { bias_mg_per_c: 0.0, scale_ppm_per_c: 100.0, thermometer_c: 0.0 });
    assert!((scale - 5e-4 * 9.80665).abs() < 2e-5, "{scale}");
    // Without the campaign's temperatures there is nothing to count from.
    let (pos, stats, fits) = unit(2.0);
    let fits: Vec<&LsqFit> = fits.iter().collect();
    let e = budget(&pos, &stats, &fits, References { temperature: Some(t), ..References::default() })
        .unwrap_err();
    assert_eq!(e, UncertaintyError::NoTemperature);
}

#[test]
fn what_is_not_a_model_4_triad_is_refused() {
    let (pos, stats, fits) = unit(80.0);
    let two: Vec<&LsqFit> = fits.iter().take(2).collect();
    let e = budget(&pos, &stats, &two, References::default()).unwrap_err();
    assert!(e.to_string().contains("triad"), "{e}");
    let all: Vec<&LsqFit> = fits.iter().collect();
    let e = budget(&pos, &stats, &all, References { g_m_s2: f64::NAN, ..References::default() }).unwrap_err();
    assert!(matches!(e, UncertaintyError::BadStated(v) if v.is_nan()), "{e}");
}

#[test]
fn the_coverage_factor_is_student_s_t_for_few_degrees_of_freedom_and_2_for_many() {
    let k = |nu: f64| coverage_factor(&[(1.0, nu)]).0;
    assert!((k(2.0) - 4.3027).abs() < 1e-3, "{}", k(2.0));
    assert!((k(10.0) - 2.2281).abs() < 1e-3, "{}", k(10.0));
    assert!((k(58.0) - 2.0017).abs() < 1e-3, "{}", k(58.0));
    assert_eq!(k(61.0), K_COVERAGE);
    assert_eq!(k(1e12), K_COVERAGE);
    assert_eq!(k(f64::INFINITY), K_COVERAGE);
    // Welch–Satterthwaite: a Type A part of 2 degrees of freedom beside an equal Type B part
    // has ν_eff = (1 + 1)² / (1²/2) = 8.
    let (k8, nu) = coverage_factor(&[(1.0, 2.0), (1.0, f64::INFINITY)]);
    assert!((nu - 8.0).abs() < 1e-12 && (k8 - 2.3060).abs() < 1e-3, "{k8} {nu}");
    // Nothing of Type A: 2.
    assert_eq!(coverage_factor(&[(1.0, f64::INFINITY), (0.0, 3.0)]), (K_COVERAGE, f64::INFINITY));
}

#[test]
fn the_variance_at_an_orientation_is_the_jacobian_s_quadratic_form() {
    let (pos, stats, fits) = unit(80.0);
    let fits: Vec<&LsqFit> = fits.iter().collect();
    let b =
        budget(&pos, &stats, &fits, References { head_angle_rad: 20.0 * ARCSEC, ..References::default() })
            .unwrap();
    // Any symmetric covariance: the budget's plus a dense one of its own.
    let extra = Cov12::from_fn(|i, j| ((i * 7 + j * 7) as f64 * 0.3).cos() * 1e-3);
    let cov = b.covariance + extra * extra.transpose();
    for a in [[9.8, 0.0, 0.0], [3.0, -4.0, 8.5], [-5.0, 5.0, 6.6]] {
        // ∂â/∂u0_c = −K⁻¹e_c, ∂â/∂k_c = −K⁻¹e_c·aᵀ.
        let jac = SMatrix::<f64, 3, N_COEF>::from_fn(|i, k| -b.cal.m[i][k / 4] * row(a)[k % 4]);
        let want = (jac * cov * jac.transpose()).diagonal();
        let got = b.variance_at(&cov, a);
        for i in 0..3 {
            assert!((got[i] / want[i] - 1.0).abs() < 1e-12, "{a:?} axis {i}: {} {}", got[i], want[i]);
        }
    }
}
