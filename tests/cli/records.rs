//! Calibration records: what record show prints, and the records a node would refuse, neither written nor flashed.

use super::*;

/// `record show` prints every field of a record as `fit` wrote it, and the node's verdict; bad
/// bytes are bad input naming the file.
#[test]
fn record_show_prints_what_fit_wrote() {
    let d = Dir::new();
    let c = simulate(&d, "c.csv", &["--seed", "4", "--samples", "2"]);
    let id = "0102030405060708090a0b0c";
    ok(&["fit", &c, "--record", &d.s("r.rec"), "--device-id", id, "--created", "1800000000"]);
    let bytes = std::fs::read(d.p("r.rec")).unwrap();
    let rec = Record::parse(&bytes).unwrap();
    let out = ok(&["record", "show", &d.s("r.rec"), "--json", &d.s("r.json")]);
    let crc = u32::from_le_bytes(bytes[bytes.len() - 4..].try_into().unwrap());
    assert!(
        out.starts_with(&format!(
            "record {}: 156 bytes, format version 2, CRC-32 {crc:#010x}\n",
            d.s("r.rec")
        )),
        "{out}"
    );
    assert!(out.contains(&format!("device id: {id}\n")), "{out}");
    assert!(out.contains("created: 1800000000 (2027-01-15T08:00:00Z)\n"), "{out}");
    assert!(out.contains("terms: 1,ax,ay,az\n"), "{out}");
    assert!(out.contains("g: 9.81 m/s² (the gravity the fit used)\n"), "{out}");
    assert!(out.contains("node: accepts it"), "{out}");
    let j = json(&d.p("r.json"));
    assert_eq!(j["device_id"], id);
    assert_eq!(j["node_accepts"], true);
    assert_eq!(j["refusal"], Value::Null);
    assert_eq!(j["g_m_s2"], 9.81);
    assert_eq!(j["thermal"], Value::Null);
    for c in 0..3 {
        let row: Vec<f64> =
            j["coefficients"][c].as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect();
        // (serde_json's reader may be one ulp off; the printed text is exact.)
        assert!(
            row.iter().zip(&rec.coefficients[c]).all(|(a, b)| (a - b).abs() <= 1e-15 * b.abs()),
            "channel {c}"
        );
        let line = out.lines().find(|l| l.starts_with(&format!("channel {c}: "))).unwrap();
        let printed: Vec<f64> =
            line.split(": ").nth(1).unwrap().split(' ').map(|v| v.parse().unwrap()).collect();
        assert_eq!(printed, rec.coefficients[c][..4], "channel {c}: printed in full precision");
    }
    std::fs::write(d.p("bad.rec"), &bytes[..40]).unwrap();
    let e = bad(&["record", "show", &d.s("bad.rec")]);
    assert_eq!(e.trim_end(), format!("error: {}: record is truncated", d.s("bad.rec")));
    let e = bad(&["record", "show", &d.s("r.rec"), "--json", &d.s("r.rec")]);
    assert!(e.contains("is the input FILE: refusing to overwrite it"), "{e}");
}

/// `record show --fit` prints the budget of the fit that wrote the record (U, k = 2, and each
/// contributor) and puts it in its JSON; another record's fit, or a fit written without a record,
/// is refused; a test-turn fit says it has no budget.
#[test]
fn record_show_with_its_fit_states_the_expanded_uncertainty() {
    let d = Dir::new();
    let c = simulate(&d, "c.csv", &["--seed", "4", "--samples", "20"]);
    let id = "0102030405060708090a0b0c";
    let (rec, fit) = (d.s("r.rec"), d.s("f.json"));
    ok(&["fit", &c, "--record", &rec, "--device-id", id, "--head-angle-u", "15", "--json", &fit]);
    let out = ok(&["record", "show", &rec, "--fit", &fit, "--json", &d.s("show.json")]);
    let f = json(&d.p("f.json"));
    let u: Vec<f64> = (0..3).map(|i| f["uncertainty"]["U_m_s2"][i].as_f64().unwrap()).collect();
    let line = format!(
        "expanded uncertainty of the calibrated acceleration (k = 2, the largest over the orientations at 1 g): x {:.2e}, y {:.2e}, z {:.2e} m/s²",
        u[0], u[1], u[2]
    );
    assert!(out.contains(&line), "{out}");
    assert!(
        out.contains("head_angle") && out.contains("15.00 arcsec per angle and position, stated"),
        "{out}"
    );
    let j = json(&d.p("show.json"));
    // The fit's budget as it states it (serde_json's reader may be an ulp off).
    let close = |a: &Value, b: &Value| {
        (a.as_f64().unwrap() - b.as_f64().unwrap()).abs() <= 1e-12 * b.as_f64().unwrap().abs()
    };
    let (ju, fu) = (&j["uncertainty"], &f["uncertainty"]);
    assert!((0..3).all(|i| close(&ju["U_m_s2"][i], &fu["U_m_s2"][i])), "{ju}");
    for (a, b) in ju["contributors"].as_array().unwrap().iter().zip(fu["contributors"].as_array().unwrap()) {
        assert_eq!((&a["name"], &a["source"]), (&b["name"], &b["source"]));
        assert!(close(&a["u_m_s2"], &b["u_m_s2"]), "{a} {b}");
    }
    assert_eq!(ju["not_included"], fu["not_included"]);
    // Without --fit, no budget and no `uncertainty` field.
    ok(&["record", "show", &rec, "--json", &d.s("plain.json")]);
    assert!(json(&d.p("plain.json")).get("uncertainty").is_none());
    // The fit of another record (another device id gives another CRC) is refused.
    let (other, other_fit) = (d.s("o.rec"), d.s("o.json"));
    ok(&["fit", &c, "--record", &other, "--device-id", "0102030405060708090a0b0d", "--json", &other_fit]);
    let e = bad(&["record", "show", &rec, "--fit", &other_fit]);
    assert!(e.contains("record CRC") && e.contains("not the record of this fit"), "{e}");
    ok(&["fit", &c, "--json", &d.s("norec.json")]);
    let e = bad(&["record", "show", &rec, "--fit", &d.s("norec.json")]);
    assert!(e.contains("written without a record (`fit --record`)"), "{e}");
    // From the database: the fit stored with the record, the same budget; a record the
    // database never stored is refused, and so is --db beside --fit.
    let (drec, db) = (d.s("d.rec"), d.s("cal.sqlite"));
    ok(&[
        "fit",
        &c,
        "--record",
        &drec,
        "--device-id",
        id,
        "--created",
        "1800000001",
        "--head-angle-u",
        "15",
        "--db",
        &db,
    ]);
    let out = ok(&["record", "show", &drec, "--db", &db]);
    assert!(out.contains(&line), "{out}");
    let e = bad(&["record", "show", &rec, "--db", &d.s("cal.sqlite")]);
    assert!(e.contains("no run in") && e.contains("stored this record"), "{e}");
    let o = accelcal(&["record", "show", &drec, "--db", &db, "--fit", &fit]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("cannot be used with"), "{o:?}");
    // A test-turn fit has no budget: said, and `null` in the JSON.
    let six = simulate(&d, "six.csv", &["--seed", "4", "--samples", "20", "--plan", "six"]);
    let (tr, tf) = (d.s("t.rec"), d.s("t.json"));
    ok(&["fit", &six, "--method", "test-turns", "--record", &tr, "--device-id", id, "--json", &tf]);
    let out = ok(&["record", "show", &tr, "--fit", &tf, "--json", &d.s("tshow.json")]);
    assert!(out.contains(&format!("uncertainty: {tf} states no budget")), "{out}");
    assert_eq!(json(&d.p("tshow.json"))["uncertainty"], Value::Null);
}

/// A record that a node would refuse is refused by `fit --record` and by `flash` with the node's
/// reason, exit code 2, one line, and nothing is written.
#[test]
fn records_a_node_would_refuse_are_not_written_nor_flashed() {
    let d = Dir::new();
    let c = simulate(&d, "c.csv", &["--seed", "4", "--samples", "2"]);
    let (rec, j) = (d.s("r.rec"), d.s("r.json"));
    let id = "51454d552d422d4c34373545";
    let e = bad(&["fit", &c, "--terms", "ax,ay,az,ax*ay", "--record", &rec, "--device-id", id, "--json", &j]);
    assert_eq!(e.lines().count(), 1, "{e}");
    assert!(
        e.contains(&format!("{rec}: a node would refuse this record: NotModel4: the node applies model 4")),
        "{e}"
    );
    let zero = "000000000000000000000000";
    let e = bad(&["fit", &c, "--record", &rec, "--device-id", zero, "--json", &j]);
    assert!(e.contains(&format!("{rec}: a node would refuse this record: WrongDevice: ")), "{e}");
    assert!(e.contains("all zeros"), "{e}");
    let e = bad(&["fit", &c, "--record", &rec]);
    assert!(e.contains("fit --record needs --device-id HEX"), "{e}");
    assert!(!d.p("r.rec").exists() && !d.p("r.json").exists());
    // flash refuses a record no node accepts before it looks for a probe.
    ok(&["fit", &c, "--record", &d.s("good.rec"), "--device-id", id]);
    let mut r = Record::parse(&std::fs::read(d.p("good.rec")).unwrap()).unwrap();
    r.device_id = [0; 12];
    let mut buf = [0u8; accelcal_shared::record::MAX_RECORD_LEN];
    let n = r.emit(&mut buf).unwrap();
    std::fs::write(d.p("zero.rec"), &buf[..n]).unwrap();
    // record show says the same, and exits 0: it only reports.
    let out = ok(&["record", "show", &d.s("zero.rec"), "--json", &d.s("zero.json")]);
    assert!(out.contains("device id: 000000000000000000000000\n"), "{out}");
    assert!(out.contains("node: a node would refuse this record: WrongDevice: "), "{out}");
    let j = json(&d.p("zero.json"));
    assert_eq!(j["node_accepts"], false);
    assert!(j["refusal"].as_str().unwrap().contains("all zeros"), "{j}");
    let e = bad(&["flash", &d.s("zero.rec"), "--probe", "ffff:ffff"]);
    assert_eq!(e.lines().count(), 1, "{e}");
    assert!(
        e.contains(&format!("{}: a node would refuse this record: WrongDevice: ", d.s("zero.rec"))),
        "{e}"
    );
}

/// Issue 24: a record whose sensitivities no unit has (here one of −0.8 codes/(m/s²), as the
/// unturned head's campaign gave) is refused by `fit --record` (see the table of refused command
/// lines) and `flash`, and `record show` says so although a node would accept it.
#[test]
fn implausible_records_are_refused_and_record_show_says_why() {
    let d = Dir::new();
    let c = simulate(&d, "c.csv", &["--seed", "4", "--samples", "2"]);
    ok(&["fit", &c, "--record", &d.s("good.rec"), "--device-id", "51454d552d422d4c34373545"]);
    let mut r = Record::parse(&std::fs::read(d.p("good.rec")).unwrap()).unwrap();
    r.coefficients[1][2] = -0.8;
    let mut buf = [0u8; accelcal_shared::record::MAX_RECORD_LEN];
    let n = r.emit(&mut buf).unwrap();
    std::fs::write(d.p("flat.rec"), &buf[..n]).unwrap();
    let why = "implausible sensitivity: channel 1's coefficient of ay is -0.8000 codes/(m/s²), a unit's is positive \
               and 3.34 to 3340 codes/(m/s²) at g = 9.81 m/s²";
    let out = ok(&["record", "show", &d.s("flat.rec"), "--json", &d.s("flat.json")]);
    assert!(out.contains(&format!("node: would accept it, but accelcal refuses it: {why}")), "{out}");
    let j = json(&d.p("flat.json"));
    assert_eq!(j["node_accepts"], true);
    assert!(j["refusal"].as_str().unwrap().starts_with(why), "{j}");
    let e = bad(&["flash", &d.s("flat.rec"), "--probe", "ffff:ffff"]);
    assert!(e.contains(&format!("{}: {why}", d.s("flat.rec"))), "{e}");
}
