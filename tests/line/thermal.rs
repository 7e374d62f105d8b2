//! A thermal record on the emulated bench: verify in the chamber with and without it.

use super::*;

/// Temperature compensation end to end in emulation (issue 16): a unit with a bias coefficient
/// of 3 codes/°C and a sensitivity coefficient of 100 ppm/°C in the bench's thermal chamber; a
/// thermal campaign acquired at −10, 20 and 50 °C (`acquire --chamber`, the node's temperature
/// recorded as `temp_c`); GMDH keeps the thermal terms; a model-4 record and a thermal record
/// (t and the ·t terms, the front end's input) flashed in turn through the gdbstub; `verify
/// --chamber` at the three temperatures. The model-4 record leaves an error that grows with the
/// distance from the campaign's middle temperature and fails at the ends; the thermal record
/// passes everywhere, its worst error a fraction of the model-4 record's. Prints the table the
/// guide quotes (docs/src/thermal.md).
#[test]
fn thermal_record_removes_the_temperature_error_in_verify() {
    let _bench = one_bench();
    let dir = tempfile::tempdir().unwrap();
    let p = |n: &str| dir.path().join(n);
    let truth = p("u16.json");
    ok(&[
        "simulate",
        "--seed",
        "16",
        "--samples",
        "2",
        "-o",
        s(&p("u16-sim.csv")),
        "--truth",
        s(&truth),
        "--effect",
        "temperature=bias:3,scale:100",
        "--chamber=25",
        "--soak-s",
        "0",
        "--thermal-lag-s",
        "0",
    ]);
    let em = Emulator::start(&truth, &["--chamber", "20", "--thermal-lag-s", "1"]);
    let c = p("thermal.csv");
    let out = succeed(&acquire_args(
        &em,
        "six",
        "200",
        &c,
        &["--rate-hz", "500", "--chamber=-10,20,50", "--soak-s", "6", "--serial", "U16"],
    ));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("position 18/18"), "{err}");
    let text = std::fs::read_to_string(&c).unwrap();
    assert!(text.contains("# chamber: -10,20,50 °C, soak 6 s\n"), "{}", &text[..600.min(text.len())]);
    assert!(text.contains("t_s,alpha_deg,beta_deg,temp_c,x,y,z\n"));

    // The campaign's temperatures are the chamber's, as the node read them.
    let camp = accelcal_core::campaign::Campaign::read(&c).unwrap();
    let pos = accelcal_core::positions::Positions::new(&camp, 9.81);
    for (k, t) in pos.temp_c.as_ref().unwrap().iter().enumerate() {
        let want = [-10.0, 20.0, 50.0][k / 6];
        assert!((t - want).abs() < 0.2, "position {k}: {t} °C, chamber {want} °C");
    }

    let id = "51454d552d422d4c34373545";
    let (m4, th) = (p("m4.rec"), p("thermal.rec"));
    fit(&c, &p("m4.json"), &["--record", s(&m4), "--device-id", id]);
    let terms = "ax,ay,az,t,ax*t,ay*t,az*t";
    fit(
        &c,
        &p("th.json"),
        &["--terms", terms, "--record", s(&th), "--device-id", id, "--temp-input", "front-end"],
    );

    let verify_at = |fit_json: &str, temp: f64, name: &str| -> (f64, bool, f64) {
        let temp = temp.to_string();
        let extra = ["--samples", "200", "--chamber", &temp, "--soak-s", "6"];
        let out = accelcal(&verify_args(&em, &p(fit_json), &p(name), &extra));
        assert!(matches!(out.status.code(), Some(0 | 1)), "{}", String::from_utf8_lossy(&out.stderr));
        verify_summary(&p(name))
    };
    let mut table = Vec::new();
    for (rec, fit_json) in [(&m4, "m4.json"), (&th, "th.json")] {
        let out = ok(&["flash", s(rec), "--gdb", &em.gdb, "--port", &em.port]);
        assert!(out.contains("confirmed over"), "{out}");
        for temp in [-10.0, 20.0, 50.0] {
            let (worst, pass, node_temp) = verify_at(fit_json, temp, &format!("v-{fit_json}-{temp}.json"));
            assert!((node_temp - temp).abs() < 0.2, "{fit_json} at {temp} °C: the node read {node_temp} °C");
            table.push((fit_json, temp, worst, pass));
        }
    }
    println!("record     chamber   worst |error|   verify");
    for (f, t, w, pass) in &table {
        println!(
            "{:<10} {:>5} °C   {:.5} m/s²    {}",
            f.trim_end_matches(".json"),
            t,
            w,
            if *pass { "pass" } else { "FAIL" }
        );
    }
    let worst = |f: &str, t: f64| table.iter().find(|r| r.0 == f && r.1 == t).unwrap();
    for t in [-10.0, 50.0] {
        assert!(!worst("m4.json", t).3, "model 4 passes at {t} °C: {table:?}");
        assert!(worst("th.json", t).2 < worst("m4.json", t).2 / 5.0, "{table:?}");
    }
    for t in [-10.0, 20.0, 50.0] {
        assert!(worst("th.json", t).3, "the thermal record fails at {t} °C: {table:?}");
    }
    em.stop();
}
