//! The register of reference equipment (`asset add|list|show`), `fit --head-asset` taking the
//! head's stated uncertainties from it, and reverse traceability (`affected`).

use super::*;

fn run_asset(db: &str, id: &str, cert: &str, due: &str, extra: &[&str]) -> String {
    let mut args = vec!["asset", "add", id, "--certificate", cert, "--due", due, "--db", db];
    args.extend_from_slice(extra);
    ok(&args)
}

/// `args` (a `fit` writing `json`) refused as the line's equipment (exit 1), saying `why`, with
/// nothing written.
fn refused_nothing_written(args: &[String], why: &str, json: &str) {
    let o = accelcal(&args.iter().map(String::as_str).collect::<Vec<_>>());
    assert_eq!(o.status.code(), Some(1), "{o:?}");
    assert!(String::from_utf8_lossy(&o.stderr).contains(why), "{o:?}");
    assert!(!Path::new(json).exists(), "nothing written");
}

#[test]
fn assets_are_registered_listed_shown_and_refused_where_they_do_not_apply() {
    let d = Dir::new();
    let db = d.s("cal.sqlite");
    let head = ["--kind", "head", "--angle-u", "4", "--orthogonality-u", "6"];
    let out = run_asset(&db, "HEAD-7", "DKD-K-15-01", "2099-12-31", &head);
    assert!(out.contains("asset: HEAD-7 (head) certificate DKD-K-15-01, due 2099-12-31, angle u 4 arcsec, orthogonality u 6 arcsec (one sigma): registered in"), "{out}");
    let again = run_asset(&db, "HEAD-7", "DKD-K-15-01", "2099-12-31", &head);
    assert!(again.contains("was registered already"), "{again}");
    // A thermometer states no head uncertainties; a head states both; dates in one form; a
    // certificate is registered once (other statements under its number are refused).
    for (line, want) in [
        (
            "T-1 --kind thermometer --certificate C --due 2099-01-01 --angle-u 1",
            "--angle-u does not apply to asset add --kind thermometer",
        ),
        (
            "H-2 --kind head --certificate C --due 2099-01-01 --angle-u 1",
            "asset add --kind head needs --orthogonality-u ARCSEC",
        ),
        ("H_2! --kind gravity --certificate C --due 2099-01-01 --value 9.81 --u 1e-5", "letters, digits"),
        (
            "G-1 --kind gravity --certificate C --due 2099-01-01 --u 1e-5",
            "asset add --kind gravity needs --value M_S2",
        ),
        (
            "G-1 --kind gravity --certificate C --due 2099-01-01 --value 9.81",
            "asset add --kind gravity needs --u M_S2",
        ),
        (
            "G-1 --kind gravity --certificate C --due 2099-01-01 --value 98.1 --u 1e-5",
            "not between 9.7 and 9.9",
        ),
        (
            "G-1 --kind gravity --certificate C --due 2099-01-01 --value 9.81 --u 0",
            "is not in (0, 0.01) m/s²",
        ),
        (
            "T-1 --kind thermometer --certificate C --due 2099-01-01 --value 9.81",
            "--value does not apply to asset add --kind thermometer",
        ),
        (
            "T-1 --kind thermometer --certificate C --due 2099-01-01 --u 20",
            "its standard uncertainty 20 K is not in (0, 10] K",
        ),
        (
            "H-3 --kind head --certificate C --due 2099-01-01 --angle-u 1 --orthogonality-u 1 --u 1",
            "--u does not apply to asset add --kind head",
        ),
        (
            "HEAD-7 --kind head --certificate DKD-K-15-01 --due 2098-12-31 --angle-u 4 --orthogonality-u 6",
            "registered already with other statements",
        ),
    ] {
        let mut args = vec!["asset", "add"];
        args.extend(line.split(' '));
        args.extend(["--db", &db]);
        let e = bad(&args);
        assert!(e.contains(want), "{line}: {e}");
    }
    let o = accelcal(&[
        "asset",
        "add",
        "H-2",
        "--kind",
        "head",
        "--certificate",
        "C",
        "--due",
        "31.12.2099",
        "--db",
        &db,
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("`31.12.2099` is not a date YYYY-MM-DD"), "{o:?}");
    let out = run_asset(&db, "PT100-3", "DAkkS-T-9", "2020-06-30", &["--kind", "thermometer"]);
    assert!(out.contains("registered"), "{out}");
    let out =
        run_asset(&db, "PT100-4", "DAkkS-T-10", "2099-06-30", &["--kind", "thermometer", "--u", "0.05"]);
    assert!(
        out.contains("asset: PT100-4 (thermometer) certificate DAkkS-T-10, due 2099-06-30, u 0.05 K per reading (one sigma): registered"),
        "{out}"
    );

    let list = d.s("assets.json");
    let out = ok(&["asset", "list", "--db", &db, "--json", &list]);
    assert!(out.contains("assets in") && out.contains(": 3"), "{out}");
    assert!(out.lines().any(|l| l.contains("PT100-3") && l.contains("OVERDUE")), "{out}");
    assert!(out.lines().any(|l| l.contains("HEAD-7") && l.contains("in force (")), "{out}");
    let j = json(Path::new(&list));
    let assets = j["assets"].as_array().unwrap();
    assert_eq!(assets[0]["asset_id"], "HEAD-7");
    assert_eq!(assets[0]["kind"], "head");
    assert_eq!(assets[0]["due_date"], "2099-12-31");
    assert_eq!(assets[0]["angle_u_arcsec"], 4.0);
    assert_eq!(assets[0]["overdue"], false);
    assert_eq!(assets[1]["overdue"], true);

    let out = ok(&["asset", "show", "HEAD-7", "--db", &db]);
    assert!(
        out.contains("asset HEAD-7 (head) in") && out.contains("certificate DKD-K-15-01 in force"),
        "{out}"
    );
    let e = accelcal(&["asset", "show", "NOPE", "--db", &db]);
    assert_eq!(e.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&e.stderr).contains("asset `NOPE` is not registered"), "{e:?}");
    // Readers never create a database.
    let missing = d.s("none.sqlite");
    assert_eq!(accelcal(&["asset", "list", "--db", &missing]).status.code(), Some(2));
    assert!(!Path::new(&missing).exists());
}

#[test]
fn fit_takes_the_head_s_uncertainties_from_its_asset_and_the_run_names_it() {
    let d = Dir::new();
    let db = d.s("cal.sqlite");
    let c = simulate(&d, "c.csv", &["--samples", "40"]);
    run_asset(
        &db,
        "HEAD-7",
        "DKD-K-15-01",
        "2099-12-31",
        &["--kind", "head", "--angle-u", "20", "--orthogonality-u", "30"],
    );
    run_asset(
        &db,
        "HEAD-OLD",
        "DKD-K-09-01",
        "2021-01-31",
        &["--kind", "head", "--angle-u", "20", "--orthogonality-u", "30"],
    );
    run_asset(&db, "PT100-3", "DAkkS-T-9", "2099-06-30", &["--kind", "thermometer"]);
    let (by_asset, stated) = (d.s("asset.json"), d.s("stated.json"));
    let rec = d.s("r.rec");
    let unit = ["--record", rec.as_str(), "--device-id", "51454d552d422d4c34373545"];
    let fit_db = |id: &str, json: &str| -> Vec<String> {
        let mut v: Vec<String> = ["fit", &c, "--db", &db, "--head-asset", id, "--json", json]
            .iter()
            .map(|s| s.to_string())
            .collect();
        v.extend(unit.iter().map(|s| s.to_string()));
        v
    };
    let args = fit_db("HEAD-7", &by_asset);
    let out = ok(&args.iter().map(String::as_str).collect::<Vec<_>>());
    assert!(out.contains("head HEAD-7 (certificate DKD-K-15-01, due 2099-12-31) stored"), "{out}");
    ok(&["fit", &c, "--head-angle-u", "20", "--head-orthogonality-u", "30", "--json", &stated]);
    let (a, s) = (json(Path::new(&by_asset)), json(Path::new(&stated)));
    assert_eq!(
        a["uncertainty"]["U_m_s2"], s["uncertainty"]["U_m_s2"],
        "the asset's statements, the same budget"
    );
    let src = a["uncertainty"]["contributors"][1]["source"].as_str().unwrap();
    assert!(src.contains("stated by head asset HEAD-7, certificate DKD-K-15-01 (due 2099-12-31)"), "{src}");

    let f =
        ok(&["affected", "HEAD-7", "--since", "2000-01-01", "--db", &db, "--json", &d.s("affected.json")]);
    assert!(f.contains(": 1 run of 1 unit") && f.contains("DKD-K-15-01") && f.contains("open"), "{f}");
    let j = json(&d.p("affected.json"));
    assert_eq!(j["runs"].as_array().unwrap().len(), 1);
    assert_eq!(j["runs"][0]["certified"], false);
    assert_eq!(j["units"], 1);
    let none = ok(&["affected", "HEAD-7", "--since", "2999-01-01", "--db", &db]);
    assert!(none.contains(": 0 runs of 0 units"), "{none}");
    let show = ok(&["asset", "show", "HEAD-7", "--db", &db]);
    assert!(show.lines().any(|l| l.contains("DKD-K-15-01") && l.trim_end().ends_with('1')), "{show}");

    // Refused: an overdue head, a thermometer as the head, an unknown one (exit 1: the line's
    // equipment, nothing written), the asset without a database, with stated values beside it.
    for (id, why) in [
        ("HEAD-OLD", "asset `HEAD-OLD` is overdue: its certificate DKD-K-09-01 was due 2021-01-31"),
        ("PT100-3", "asset `PT100-3` is a thermometer, not a head"),
        ("HEAD-9", "asset `HEAD-9` is not registered"),
    ] {
        let j = d.s(&format!("{id}.json"));
        refused_nothing_written(&fit_db(id, &j), why, &j);
    }
    let e = bad(&["fit", &c, "--head-asset", "HEAD-7"]);
    assert!(e.contains("--head-asset does not apply to a command without --db"), "{e}");
    let o = accelcal(&["fit", &c, "--db", &db, "--head-asset", "HEAD-7", "--head-angle-u", "3"]);
    assert_eq!(o.status.code(), Some(2), "{o:?}");
    let e = bad(&["fit", &c, "--method", "test-turns", "--db", &db, "--head-asset", "HEAD-7"]);
    assert!(e.contains("--head-asset does not apply to fit --method test-turns"), "{e}");
}

/// Issue 59, "g is a reference like the head": a gravity survey registered with its value and
/// standard uncertainty sets g and u(g) of `fit --gravity-asset`, whose budget is then the one of
/// `--g` with `--g-u` the same; the run stores the survey, so `affected` finds it. A g typed
/// without `--g-u` keeps the rounding rule and says so once.
#[test]
fn a_gravity_survey_sets_g_and_its_uncertainty_and_the_run_names_it() {
    let d = Dir::new();
    let db = d.s("cal.sqlite");
    let c = simulate(&d, "c.csv", &["--samples", "40", "--g", "9.810547"]);
    let survey = ["--kind", "gravity", "--value", "9.810547", "--u", "2e-6"];
    let out = run_asset(&db, "G-SITE", "BKG-2026-17", "2099-12-31", &survey);
    assert!(out.contains("asset: G-SITE (gravity) certificate BKG-2026-17, due 2099-12-31, g = 9.810547 m/s², u 2.0e-6 m/s² (one sigma): registered"), "{out}");
    run_asset(&db, "G-OLD", "BKG-2019-02", "2020-12-31", &survey);
    run_asset(&db, "PT100-3", "DAkkS-T-9", "2099-06-30", &["--kind", "thermometer"]);
    let (by_survey, typed) = (d.s("survey.json"), d.s("typed.json"));
    let unit = ["--record", &d.s("r.rec"), "--device-id", "51454d552d422d4c34373545"].map(String::from);
    let fit_db = |id: &str, json: &str| -> Vec<String> {
        let mut v: Vec<String> = ["fit", &c, "--db", &db, "--gravity-asset", id, "--json", json]
            .iter()
            .map(|s| s.to_string())
            .collect();
        v.extend(unit.iter().cloned());
        v
    };
    let args = fit_db("G-SITE", &by_survey);
    let out = ok(&args.iter().map(String::as_str).collect::<Vec<_>>());
    assert!(out.contains("gravity survey G-SITE (certificate BKG-2026-17, due 2099-12-31) stored"), "{out}");
    let o = accelcal(&["fit", &c, "--g", "9.810547", "--g-u", "2e-6", "--json", &typed]);
    assert_eq!(o.status.code(), Some(0), "{o:?}");
    assert!(!String::from_utf8_lossy(&o.stderr).contains("taken as rounded"), "{o:?}");
    let (a, t) = (json(Path::new(&by_survey)), json(Path::new(&typed)));
    assert_eq!(a["uncertainty"]["U_m_s2"], t["uncertainty"]["U_m_s2"], "the survey's u, the same budget");
    assert_eq!(a["g_m_s2"], 9.810547);
    assert_eq!(a["g_source"], "survey u=2e-6 asset=G-SITE certificate=BKG-2026-17");
    assert_eq!(t["g_source"], "given u=2e-6");
    let gravity = |doc: &serde_json::Value| {
        doc["uncertainty"]["contributors"]
            .as_array()
            .unwrap()
            .iter()
            .find(|c| c["name"] == "gravity")
            .unwrap()
            .clone()
    };
    let src = gravity(&a)["source"].as_str().unwrap().to_string();
    assert!(src.contains("survey G-SITE, certificate BKG-2026-17: u = 2.0e-6 m/s² as certified"), "{src}");
    // Typed without --g-u: half a unit of the last digit, rectangular, said once.
    let o = accelcal(&["fit", &c, "--g", "9.810547", "--json", &d.s("rounded.json")]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(err.matches("taken as rounded").count(), 1, "{err}");
    assert!(err.contains("give --g-u"), "{err}");
    let f = ok(&["affected", "G-SITE", "--since", "2000-01-01", "--db", &db]);
    assert!(f.contains(": 1 run of 1 unit") && f.contains("BKG-2026-17"), "{f}");

    // Refused, nothing written: an overdue survey, a thermometer as the survey, an unknown one.
    for (id, why) in [
        ("G-OLD", "asset `G-OLD` is overdue: its certificate BKG-2019-02 was due 2020-12-31"),
        ("PT100-3", "asset `PT100-3` is a thermometer, not a gravity survey"),
        ("G-9", "asset `G-9` is not registered"),
    ] {
        let j = d.s(&format!("{id}.json"));
        refused_nothing_written(&fit_db(id, &j), why, &j);
    }
    // The command line: one source of g; --g-u with --g only, a standard uncertainty.
    for (line, want) in [
        (vec!["--gravity-asset", "G-SITE"], "--gravity-asset does not apply to a command without --db"),
        (
            vec!["--db", &db, "--gravity-asset", "G-SITE", "--g", "9.81"],
            "--gravity-asset and --g both give gravity",
        ),
        (
            vec!["--db", &db, "--gravity-asset", "G-SITE", "--latitude", "50"],
            "--gravity-asset and --latitude both give",
        ),
        (vec!["--g-u", "1e-6"], "--g-u needs --g"),
        (vec!["--g", "9.81", "--g-u", "0"], "--g-u must be a standard uncertainty in (0, 0.1) m/s², got 0"),
        // gravity-norm stores no run, so it reads no survey either.
        (
            vec!["--method", "gravity-norm", "--db", &db, "--gravity-asset", "G-SITE"],
            "--db does not apply to fit --method gravity-norm",
        ),
    ] {
        let mut args = vec!["fit", c.as_str()];
        args.extend(line.iter().copied());
        let e = bad(&args);
        assert!(e.contains(want), "{line:?}: {e}");
    }
}
