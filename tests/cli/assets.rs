//! The register of reference equipment (`asset add|list|show`), `fit --head-asset` taking the
//! head's stated uncertainties from it, and reverse traceability (`affected`).

use super::*;

fn run_asset(db: &str, id: &str, cert: &str, due: &str, extra: &[&str]) -> String {
    let mut args = vec!["asset", "add", id, "--certificate", cert, "--due", due, "--db", db];
    args.extend_from_slice(extra);
    ok(&args)
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
        ("H_2! --kind gravity --certificate C --due 2099-01-01", "letters, digits"),
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

    let list = d.s("assets.json");
    let out = ok(&["asset", "list", "--db", &db, "--json", &list]);
    assert!(out.contains("assets in") && out.contains(": 2"), "{out}");
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
    assert!(f.contains(": 1 runs of 1 units") && f.contains("DKD-K-15-01") && f.contains("open"), "{f}");
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
        let args = fit_db(id, &j);
        let o = accelcal(&args.iter().map(String::as_str).collect::<Vec<_>>());
        assert_eq!(o.status.code(), Some(1), "{o:?}");
        assert!(String::from_utf8_lossy(&o.stderr).contains(why), "{o:?}");
        assert!(!Path::new(&j).exists(), "nothing written");
    }
    let e = bad(&["fit", &c, "--head-asset", "HEAD-7"]);
    assert!(e.contains("--head-asset does not apply to a command without --db"), "{e}");
    let o = accelcal(&["fit", &c, "--db", &db, "--head-asset", "HEAD-7", "--head-angle-u", "3"]);
    assert_eq!(o.status.code(), Some(2), "{o:?}");
    let e = bad(&["fit", &c, "--method", "test-turns", "--db", &db, "--head-asset", "HEAD-7"]);
    assert!(e.contains("--head-asset does not apply to fit --method test-turns"), "{e}");
}
