//! `plan --design N|auto`: a designed plan that the other commands read, its JSON, its
//! comparison with the paper's plan, and the options that do not apply refused.

use super::*;

#[test]
fn a_designed_plan_is_a_plan_file_that_simulate_and_select_read() {
    let d = Dir::new();
    let like = simulate(&d, "like.csv", &["--samples", "40", "--effect", "angle_error=sd_mrad:0.1"]);
    let (plan, doc) = (d.s("designed.csv"), d.s("designed.json"));
    let out = ok(&[
        "plan",
        "--design",
        "16",
        "--like",
        &like,
        "--head-angle-u",
        "20",
        "--out",
        &plan,
        "--json",
        &doc,
    ]);
    assert!(
        out.contains("plan design: 16 positions x 400 sample sets (4 s at 100 Hz), head time 224 s"),
        "{out}"
    );
    assert!(out.contains("by the alternate split"), "{out}");
    // The campaign states g but no rate: its g, the default rate, each said.
    let at = format!(
        "at rate 100 Hz (the default: --like {like} states no `# rate_hz:` and --rate-hz was not given); g = 9.81 m/s²"
    );
    assert!(out.contains(&at), "{out}");
    assert!(out.contains(&format!("(--like {like}: the campaign's `# g_m_s2:`")), "{out}");
    // The plan file states its dwell, which the station takes.
    let text = std::fs::read_to_string(&plan).unwrap();
    assert!(text.contains("\n# samples: 400\n# rate_hz: 100\nalpha_deg,beta_deg\n"), "{text}");
    let j = json(Path::new(&doc));
    assert_eq!(j["positions"], 16);
    assert_eq!(j["samples_per_position"], 400);
    assert_eq!(j["head_time_s"], 224.0);
    assert_eq!(j["selection"], "alternate");
    assert_eq!(j["angles"].as_array().unwrap().len(), 16);
    let u = j["U_m_s2"].as_f64().unwrap();
    let axes: Vec<f64> = j["U_axes_m_s2"].as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect();
    assert_eq!(axes.iter().copied().fold(0.0, f64::max), u);
    assert_eq!(j["criteria"]["worst_U_m_s2"].as_f64().unwrap(), u);
    // The unit type is the earlier campaign's: its noise (80 codes) read from its dwells.
    assert!(j["unit_type"].as_str().unwrap().contains("noise per sample x 8"), "{}", j["unit_type"]);
    let plans: Vec<&str> =
        j["compared"].as_array().unwrap().iter().map(|c| c["plan"].as_str().unwrap()).collect();
    assert_eq!(plans, ["head (paper)", "tumble24", "six", "designed"]);
    // The paper's plan, at the same dwell, with 62 positions is better in U and costs more time.
    let paper = &j["compared"][0];
    assert_eq!(paper["positions"], 62);
    assert_eq!(paper["head_time_s"], 868.0);
    assert!(paper["U_m_s2"].as_f64().unwrap() < u);
    // simulate, plan and select read it; GMDH's default split ranks the paper's models on it.
    let c = simulate(&d, "c.csv", &["--plan", &plan, "--samples", "50"]);
    let listed = ok(&["plan", "--plan", &plan]);
    assert!(listed.contains("16 positions"), "{listed}");
    let sel = ok(&["select", &c]);
    assert!(sel.contains("model 4") || sel.contains("1,ax,ay,az"), "{sel}");
    // The same seed, the same plan.
    let again = d.s("again.csv");
    ok(&["plan", "--design", "16", "--like", &like, "--head-angle-u", "20", "--out", &again]);
    assert_eq!(std::fs::read_to_string(&plan).unwrap(), std::fs::read_to_string(&again).unwrap());
}

/// Issue 59: `--like` gives the node's rate (`# rate_hz:`) and g (`# g_m_s2:`, `# g_source:`)
/// besides the noise, unless `--rate-hz` or `--g` says otherwise; one line says which.
#[test]
fn like_gives_the_rate_and_g_of_its_campaign_unless_the_command_line_does() {
    let d = Dir::new();
    let sim = simulate(&d, "sim.csv", &["--samples", "40", "--g", "9.7803"]);
    let text = std::fs::read_to_string(&sim).unwrap();
    let like = d.s("like.csv");
    // An acquired campaign's header states its rate; the simulated one does not.
    std::fs::write(&like, text.replacen("# g_source:", "# rate_hz: 500\n# g_source:", 1)).unwrap();
    let (plan, doc) = (d.s("p.csv"), d.s("p.json"));
    let out = ok(&["plan", "--design", "8", "--like", &like, "--out", &plan, "--json", &doc]);
    let at = format!("at rate 500 Hz (--like {like}'s `# rate_hz:`); g = 9.7803 m/s²");
    assert!(out.contains(&at), "{out}");
    assert!(out.contains(&format!("(--like {like}: the campaign's `# g_m_s2:`")), "{out}");
    assert!(
        out.contains(&format!("noise per sample from --like {like}'s scatter within its dwells")),
        "{out}"
    );
    assert!(out.contains("8 positions x 400 sample sets (0.8 s at 500 Hz)"), "{out}");
    assert_eq!(json(Path::new(&doc))["rate_hz"], 500.0);
    let text = std::fs::read_to_string(&plan).unwrap();
    assert!(text.contains("\n# samples: 400\n# rate_hz: 500\n"), "{text}");
    // The command line's rate and g win.
    let args =
        ["plan", "--design", "8", "--like", &like, "--rate-hz", "200", "--g", "9.80665", "--out", &plan];
    let out = ok(&args);
    assert!(out.contains("at rate 200 Hz (--rate-hz); g = 9.80665 m/s²"), "{out}");
    assert!(!out.contains("the campaign's `# g_m_s2:`"), "{out}");
    // Without --like, the defaults and --noise.
    let out = ok(&["plan", "--design", "8", "--noise", "80", "--out", &plan]);
    assert!(out.contains("at rate 100 Hz (the default: --rate-hz was not given); g = 9.81 m/s²"), "{out}");
    assert!(out.contains("noise per sample from --noise"), "{out}");
}

#[test]
fn auto_reaches_the_paper_plan_s_u_in_less_head_time() {
    let d = Dir::new();
    let doc = d.s("auto.json");
    let common = ["--noise", "80", "--head-angle-u", "20", "--g", "9.80665", "--out"];
    let mut args = vec!["plan", "--design", "auto"];
    args.extend_from_slice(&common);
    let plan = d.s("auto.csv");
    args.extend_from_slice(&[&plan, "--json", &doc]);
    let out = ok(&args);
    assert!(out.contains("target U = "), "{out}");
    let j = json(Path::new(&doc));
    let paper = &j["compared"][0];
    assert_eq!(j["target_U_m_s2"], paper["U_m_s2"]);
    assert!(j["U_m_s2"].as_f64().unwrap() <= j["target_U_m_s2"].as_f64().unwrap());
    let (t, t_paper) = (j["head_time_s"].as_f64().unwrap(), paper["head_time_s"].as_f64().unwrap());
    assert!(t < 0.75 * t_paper, "{t} s against the paper's {t_paper} s");
    let n = j["positions"].as_u64().unwrap() as f64;
    let s = j["samples_per_position"].as_u64().unwrap() as f64;
    assert_eq!(t, n * (10.0 + s / 100.0));
}

/// In a chamber: the plan is the positions, run at each setpoint; U is predicted for the linear
/// thermal model at the worst end of the calibrated range (the factor 1/3 + 30²/1800 on the
/// noise and head-angle variances), and the head time counts every pass and its soak.
#[test]
fn a_chamber_plan_states_its_passes_soaks_and_u_at_the_worst_temperature() {
    let d = Dir::new();
    let (plan, doc, one, one_plan) = (d.s("t.csv"), d.s("t.json"), d.s("one.json"), d.s("one.csv"));
    let common = ["plan", "--design", "16", "--noise", "80", "--head-angle-u", "20", "--g", "9.80665"];
    let mut args = common.to_vec();
    args.extend_from_slice(&["--chamber=-10,20,50", "--soak-s", "600", "--out", &plan, "--json", &doc]);
    let out = ok(&args);
    assert!(
        out.contains(
            "run at each chamber setpoint (acquire --chamber=-10,20,50): 3 passes, 600 s of soak each"
        ),
        "{out}"
    );
    assert!(out.contains("the worst temperature of -10..50 °C (variance factor 0.833)"), "{out}");
    assert!(out.contains("the thermometer's uncertainty"), "{out}");
    let j = json(Path::new(&doc));
    assert_eq!(j["chamber"]["setpoints_c"], serde_json::json!([-10.0, 20.0, 50.0]));
    assert_eq!(j["chamber"]["passes"], 3);
    assert!((j["chamber"]["variance_factor"].as_f64().unwrap() - 5.0 / 6.0).abs() < 1e-12);
    // 3 passes of 16 × (10 s + 4 s), each after 600 s of soak.
    assert_eq!(j["head_time_s"], 3.0 * (16.0 * 14.0 + 600.0));
    assert_eq!(j["compared"][0]["head_time_s"], 3.0 * (62.0 * 14.0 + 600.0));
    // 48 dwells of 400 samples: the noise is estimated within them, on 48 × 399 degrees of
    // freedom, so k is 2. Of 2 samples each, on 48: the head's angles (Type B) beside it, k is
    // Student's t a little above 2 (t(48) = 2.011).
    assert_eq!(j["k"].as_f64(), Some(2.0));
    let mut args = common.to_vec();
    let (few, few_plan) = (d.s("few.json"), d.s("few.csv"));
    args.extend_from_slice(&["--chamber=-10,20,50", "--samples", "2", "--out", &few_plan, "--json", &few]);
    ok(&args);
    let j2 = json(Path::new(&few));
    let (k, nu) = (j2["k"].as_f64().unwrap(), j2["nu_eff"].as_f64().unwrap());
    assert!(nu > 48.0 && nu < 61.0 && k > 2.0 && k < 2.011, "k {k}, nu_eff {nu}");
    // The same plan in one pass states more.
    let mut args = common.to_vec();
    args.extend_from_slice(&["--out", &one_plan, "--json", &one]);
    ok(&args);
    let (u, u1) = (j["U_m_s2"].as_f64().unwrap(), json(Path::new(&one))["U_m_s2"].as_f64().unwrap());
    assert!(u < u1, "{u} in the chamber, {u1} in one pass");
    // The plan file is an ordinary plan: simulate runs it in the chamber.
    simulate(&d, "c.csv", &["--plan", &plan, "--samples", "20", "--chamber=-10,50", "--soak-s", "10"]);
    // What does not apply, or is not a chamber, is refused.
    let mut args = common.to_vec();
    args.extend_from_slice(&["--chamber", "20,20", "--out", &plan]);
    let e = bad(&args);
    assert!(e.contains("--chamber") && e.contains("two different setpoints"), "{e}");
    let mut args = common.to_vec();
    args.extend_from_slice(&["--chamber=-10,50", "--montecarlo", "20", "--out", &plan]);
    let e = bad(&args);
    assert!(e.contains("--montecarlo does not apply with --chamber"), "{e}");
    let mut args = common.to_vec();
    args.extend_from_slice(&["--soak-s", "600", "--out", &plan]);
    assert_eq!(accelcal(&args).status.code(), Some(2), "--soak-s without --chamber");
}

#[test]
fn the_design_s_options_are_refused_where_they_do_not_apply() {
    let d = Dir::new();
    let out = d.s("p.csv");
    let e = bad(&["plan", "--design", "24", "--noise", "80"]);
    assert!(e.contains("--design needs --out FILE"), "{e}");
    let e = bad(&["plan", "--design", "24", "--out", &out]);
    assert!(e.contains("--like CAMPAIGN") && e.contains("--noise CODES"), "{e}");
    let e = bad(&["plan", "--design", "24", "--noise", "80", "--target-U", "1e-3", "--out", &out]);
    assert!(e.contains("--target-U applies to --design auto only"), "{e}");
    let e = bad(&["plan", "--design", "5", "--noise", "80", "--out", &out]);
    assert!(e.contains("5 positions are too few"), "{e}");
    let e = bad(&["plan", "--design", "auto", "--noise", "80", "--target-U", "1e-9", "--out", &out]);
    assert!(e.contains("no plan reaches U = 1.000e-9 m/s²"), "{e}");
    let e = bad(&["plan", "--design", "24", "--noise", "80", "--beta-step-deg", "100", "--out", &out]);
    assert!(e.contains("β step"), "{e}");
    let e = bad(&["plan", "--design", "24", "--like", &d.s("missing.csv"), "--out", &out]);
    assert!(e.contains("--like") && e.contains("missing.csv"), "{e}");
    let like = simulate(&d, "like.csv", &["--samples", "20"]);
    let before = std::fs::read(&like).unwrap();
    let e = bad(&["plan", "--design", "12", "--like", &like, "--out", &like]);
    assert!(e.contains("is also --like: the designed plan would overwrite it"), "{e}");
    let e = bad(&["plan", "--design", "12", "--like", &like, "--out", &out, "--json", &like]);
    assert!(e.contains("--json is also --like"), "{e}");
    let e = bad(&["plan", "--design", "12", "--noise", "80", "--out", &out, "--json", &out]);
    assert!(e.contains("is also --json"), "{e}");
    assert_eq!(std::fs::read(&like).unwrap(), before, "the campaign is untouched");
    assert!(!Path::new(&out).exists(), "nothing is written on bad input");
    // Options of the design without --design, and a plan with it, are refused by the parser.
    for args in [
        &["plan", "--noise", "80"][..],
        &["plan", "--design", "24", "--plan", "six", "--noise", "80", "--out", &out][..],
        &["plan", "--design", "24", "--like", &out, "--noise", "80", "--out", &out][..],
    ] {
        let o = accelcal(args);
        assert_eq!(o.status.code(), Some(2), "{args:?}");
    }
}

#[test]
fn the_design_s_report_is_what_users_read() {
    let d = Dir::new();
    let plan = d.s("d.csv");
    let out = ok(&[
        "plan",
        "--design",
        "12",
        "--noise",
        "80",
        "--head-angle-u",
        "20",
        "--g",
        "9.80665",
        "--out",
        &plan,
    ]);
    let text = out.replace(d.0.path().to_str().unwrap(), "[dir]");
    insta::assert_snapshot!("plan_design_text", text);
}
