//! The uncertainty budget of `fit` (the `uncertainty` object of its JSON) and its Monte Carlo
//! check (`uncertainty-check`).

use super::*;

#[test]
fn fit_states_the_expanded_uncertainty_its_covariance_and_contributors() {
    let d = Dir::new();
    let c = simulate(&d, "c.csv", &["--samples", "40", "--effect", "angle_error=sd_mrad:0.1"]);
    let (plain, head) = (d.s("plain.json"), d.s("head.json"));
    let out = ok(&["fit", &c, "--json", &plain]);
    assert!(out.contains("expanded uncertainty of the calibrated acceleration (k = 2"), "{out}");
    assert!(out.contains("not included: the head's axis orthogonality (none given)"), "{out}");
    let printed = ok(&["fit", &c, "--head-angle-u", "20", "--head-orthogonality-u", "30", "--json", &head]);
    let (p, h) = (json(Path::new(&plain)), json(Path::new(&head)));
    let u = &h["uncertainty"];
    assert_eq!(u["k"], 2.0);
    let names: Vec<&str> =
        u["coefficients"].as_array().unwrap().iter().map(|v| v.as_str().unwrap()).collect();
    assert_eq!(names[..5], ["x:1", "x:ax", "x:ay", "x:az", "y:1"]);
    let cov = u["covariance"].as_array().unwrap();
    assert_eq!(cov.len(), 12);
    for (i, row) in cov.iter().enumerate() {
        let row = row.as_array().unwrap();
        assert_eq!(row.len(), 12);
        assert!(row[i].as_f64().unwrap() > 0.0);
        for (j, v) in row.iter().enumerate() {
            // Symmetric.
            let w = cov[j][i].as_f64().unwrap();
            let scale = (row[i].as_f64().unwrap() * cov[j][j].as_f64().unwrap()).sqrt();
            assert!((v.as_f64().unwrap() - w).abs() <= 1e-9 * scale, "{i} {j}: {v} {w}");
        }
    }
    let shares: f64 =
        u["contributors"].as_array().unwrap().iter().map(|c| c["share"].as_f64().unwrap()).sum();
    assert!((shares - 1.0).abs() < 1e-9, "{shares}");
    // Issue 59: the budget adds up on paper where U is stated, and says where and how likely.
    let at = &u["stated_at"];
    let axis = ["x", "y", "z"].iter().position(|a| at["axis"] == *a).unwrap();
    let uc: f64 = u["contributors"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| c["u_m_s2"].as_f64().unwrap().powi(2))
        .sum::<f64>()
        .sqrt();
    let k = u["k"].as_f64().unwrap();
    let stated = u["U_m_s2"][axis].as_f64().unwrap();
    assert!((k * uc / stated - 1.0).abs() < 1e-9, "{} {stated}", k * uc);
    let coverage = u["coverage_probability"].as_f64().unwrap();
    assert!((0.95..0.96).contains(&coverage), "{coverage}");
    assert!(
        printed.contains(&format!("the contributors along {} at (", at["axis"].as_str().unwrap())),
        "{printed}"
    );
    assert!(printed.contains("expanded U = k·u_c"), "{printed}");
    let names: Vec<&str> =
        u["contributors"].as_array().unwrap().iter().map(|c| c["name"].as_str().unwrap()).collect();
    assert_eq!(
        names,
        [
            "dwell_scatter",
            "head_angle",
            "head_orthogonality",
            "gravity",
            "quantisation",
            "temperature",
            "lack_of_fit"
        ]
    );
    let lof = &u["contributors"][6];
    assert_eq!(lof["type"], "A");
    assert!(
        lof["source"].as_str().unwrap().contains("GMDH's criterion gap to the best of the paper's 11 models"),
        "{lof}"
    );
    let said: Vec<&str> = u["not_included"].as_array().unwrap().iter().map(|v| v.as_str().unwrap()).collect();
    assert!(said.iter().any(|n| n.starts_with("terms of the output above the second degree")), "{said:?}");
    // A head stated but without errors changes U by little (the scatter it would explain is
    // taken out, its own covariance put in) ...
    let ux = |v: &Value, i: usize| v["uncertainty"]["U_m_s2"][i].as_f64().unwrap();
    for i in 0..3 {
        let (a, b) = (ux(&p, i), ux(&h, i));
        assert!(a > 0.0 && a < 0.05 && (b / a - 1.0).abs() < 0.1, "axis {i}: {a} {b}");
    }
    // A head whose stages are out of square: without a stated orthogonality only the part of
    // the rotation the fit cannot absorb shows, as dwell scatter; stated, the rotation is its own
    // contributor, the larger share, and the scatter it explains is taken out of the Type A.
    let m = simulate(
        &d,
        "m.csv",
        &[
            "--samples",
            "40",
            "--noise",
            "2",
            "--effect",
            "head_misalignment=rx_mrad:0.3,ry_mrad:-0.3,rz_mrad:0.3",
        ],
    );
    let (mp, mh) = (d.s("mp.json"), d.s("mh.json"));
    ok(&["fit", &m, "--json", &mp]);
    ok(&["fit", &m, "--head-orthogonality-u", "60", "--json", &mh]);
    let (mp, mh) = (json(Path::new(&mp)), json(Path::new(&mh)));
    let field = |v: &Value, name: &str, key: &str| {
        let c = v["uncertainty"]["contributors"].as_array().unwrap();
        c.iter().find(|c| c["name"] == name).unwrap()[key].as_f64().unwrap()
    };
    assert!(field(&mh, "head_orthogonality", "share_mean") > 0.5, "{mh}");
    let scatter = |v: &Value| field(v, "dwell_scatter", "u_m_s2");
    // Unstated, what the fit cannot absorb of the rotation is seen as dwell scatter and as model
    // 4's lack of fit (the data cannot tell the head's rotation from the unit's quadratic
    // terms); stated, it is the head's, and neither keeps it.
    let lof = |v: &Value| field(v, "lack_of_fit", "u_m_s2");
    assert!(lof(&mp) > 0.0 && lof(&mh) == 0.0, "{} {}", lof(&mp), lof(&mh));
    let seen = scatter(&mp).hypot(lof(&mp));
    assert!(scatter(&mh) < 0.2 * seen, "{seen} {}", scatter(&mh));
    for i in 0..3 {
        assert!((ux(&mh, i) / ux(&mp, i) - 1.0).abs() < 0.25, "axis {i}: {} {}", ux(&mp, i), ux(&mh, i));
    }
    // Six positions do not determine the quadratic model: the fit has its budget, and says the
    // lack of fit is not measured.
    let six = simulate(&d, "six.csv", &["--samples", "20", "--plan", "six"]);
    let sj = d.s("six.json");
    ok(&["fit", &six, "--json", &sj]);
    let said = json(Path::new(&sj))["uncertainty"]["not_included"].to_string();
    assert!(said.contains("not measured: the plan's 6 positions are too few"), "{said}");
    // No budget for test turns, nor for a block that is not a triad.
    let tt = d.s("tt.json");
    ok(&["fit", &c, "--method", "test-turns", "--json", &tt]);
    assert!(json(Path::new(&tt)).get("uncertainty").is_none());
    let b = simulate(&d, "b.csv", &["--samples", "20", "--layout", "block:2"]);
    let bj = d.s("b.json");
    ok(&["fit", &b, "--json", &bj]);
    assert!(json(Path::new(&bj)).get("uncertainty").is_none());
    let e = bad(&["fit", &b, "--head-angle-u", "20"]);
    assert!(e.contains("triad"), "{e}");
}

/// Gravity's contributor follows where g came from, resolved once: the campaign's `# g_m_s2:`
/// (a number, taken as rounded), `--latitude` (normal gravity), or nobody (the assumed 9.81 m/s²,
/// within 0.03 m/s² anywhere at sea level: before, a campaign without the line was budgeted as
/// if 9.81 had been given, 0.005 m/s²).
#[test]
fn gravity_s_contributor_follows_where_g_came_from() {
    let d = Dir::new();
    let c = simulate(&d, "c.csv", &["--samples", "20"]);
    let text = std::fs::read_to_string(&c).unwrap();
    assert!(text.starts_with("# g_m_s2: 9.81\n"), "{}", &text[..40]);
    let plain = d.s("plain.csv");
    std::fs::write(&plain, text.lines().filter(|l| !l.starts_with("# g_")).collect::<Vec<_>>().join("\n"))
        .unwrap();
    let gravity = |campaign: &str, extra: &[&str]| {
        let j = d.s("g.json");
        let mut args = vec!["fit", campaign, "--json", &j];
        args.extend_from_slice(extra);
        ok(&args);
        let doc = json(Path::new(&j));
        let c = doc["uncertainty"]["contributors"].as_array().unwrap().clone();
        let g = c.into_iter().find(|c| c["name"] == "gravity").unwrap();
        (g["u_m_s2"].as_f64().unwrap(), g["source"].as_str().unwrap().to_string())
    };
    let (header, why) = gravity(&c, &[]);
    assert!(why.contains("as given, taken as rounded") && why.contains("bound 5.0e-3"), "{why}");
    let (site, why) = gravity(&c, &["--latitude", "50.45"]);
    assert!(why.contains("normal gravity") && why.contains("bound 1.0e-3"), "{why}");
    let (assumed, why) = gravity(&plain, &[]);
    assert!(why.contains("assumed, the site unknown") && why.contains("bound 3.0e-2"), "{why}");
    assert!(site < header && header < assumed, "{site} {header} {assumed}");
    let (given, why) = gravity(&plain, &["--g", "9.81"]);
    assert!(why.contains("as given") && (given - header).abs() < 1e-12 * header, "{why}");
}

#[test]
fn stated_temperature_coefficients_count_the_calibration_temperature_against_the_reference() {
    let d = Dir::new();
    // Calibrated at 31 °C for the reference 25 °C (`--t-ref` default).
    let c = simulate(&d, "t.csv", &["--samples", "20", "--noise", "2", "--temp-profile", "31:0:0"]);
    let j = d.s("t.json");
    let out = ok(&[
        "fit",
        &c,
        "--bias-tempco-u",
        "0.1",
        "--scale-tempco-u",
        "0",
        "--thermometer-u",
        "0",
        "--json",
        &j,
    ]);
    assert!(out.contains("calibrated at 31.0 °C"), "{out}");
    assert!(!out.contains("not included: the temperature"), "{out}");
    let v = json(Path::new(&j));
    let t = v["uncertainty"]["contributors"]
        .as_array()
        .unwrap()
        .iter()
        .find(|c| c["name"] == "temperature")
        .unwrap()
        .clone();
    // 0.1 mg/°C × 6 °C = 0.6 mg on each axis.
    let u = t["u_m_s2"].as_f64().unwrap();
    assert!((u - 0.6e-3 * 9.80665).abs() < 1e-5, "{t}");
    assert_eq!(t["type"], "B");
    // The three go together; without the campaign's temperatures there is nothing to count from.
    let out = accelcal(&["fit", &c, "--bias-tempco-u", "0.1"]);
    assert_eq!(out.status.code(), Some(2));
    let e = String::from_utf8_lossy(&out.stderr);
    assert!(e.contains("--scale-tempco-u") && e.contains("--thermometer-u"), "{e}");
    let plain = simulate(&d, "p.csv", &["--samples", "20"]);
    let e =
        bad(&["fit", &plain, "--bias-tempco-u", "0.1", "--scale-tempco-u", "50", "--thermometer-u", "0.2"]);
    assert!(e.contains("no `temp_c` column"), "{e}");
    let e = bad(&[
        "fit",
        &c,
        "--method",
        "test-turns",
        "--bias-tempco-u",
        "0.1",
        "--scale-tempco-u",
        "50",
        "--thermometer-u",
        "0.2",
    ]);
    assert!(e.contains("--bias-tempco-u"), "{e}");
}

#[test]
fn the_monte_carlo_check_passes_for_the_budget_and_writes_its_table() {
    let d = Dir::new();
    let j = d.s("mc.json");
    let out =
        ok(&["uncertainty-check", "--units", "300", "--samples", "20", "--orientations", "10", "--json", &j]);
    assert!(out.contains("the budget holds"), "{out}");
    let v = json(Path::new(&j));
    assert_eq!(v["passed"], true);
    let params: Vec<&str> =
        v["parameter_rules"].as_array().unwrap().iter().map(|r| r["parameter"].as_str().unwrap()).collect();
    assert_eq!(params, ["bias", "scale_factor", "misalignment"]);
    for r in v["parameter_rules"].as_array().unwrap() {
        let far = r["shares"][0].as_f64().unwrap();
        assert!((0.015..=0.025).contains(&far), "{r}");
    }
    let names: Vec<&str> =
        v["scenarios"].as_array().unwrap().iter().map(|s| s["scenario"]["name"].as_str().unwrap()).collect();
    assert_eq!(
        names,
        ["all", "dwell_scatter", "head_angle", "head_orthogonality", "gravity", "temperature", "lack_of_fit"]
    );
    for s in v["scenarios"].as_array().unwrap() {
        assert_eq!(s["checks"], 300 * 10 * 3);
        let c = s["coverage"].as_f64().unwrap();
        assert!((0.92..=0.98).contains(&c), "{s}");
    }
    let out = accelcal(&["uncertainty-check", "--units", "10"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("--units"));
}
