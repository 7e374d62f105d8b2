//! Issue 59 on both engines: recalls, from a head found out of tolerance at its own
//! recalibration to the list the letters are written from (`tests/db.rs` runs it on SQLite,
//! `tests/db_pg.rs` on PostgreSQL). The database's API, `affected`, `fleet` and `serve` over HTTP.

use accelcal_core::certificate::{Certificate, Facts, Party, Quantity, Span, FORMAT, PAGE_SCRIPT_OPEN};
use accelcal_db::recall::RecallState;
use accelcal_db::{Asset, Db, DbError, Outcome, Phase, RunId};

use super::tamper::Exec;
use super::*;

/// The head found out of tolerance: its first certificate, then the one its recalibration gave.
pub const BAD: &str = "DKD-17-001";
/// The first day the finding covers.
pub const SINCE: &str = "2026-01-05";

/// A certificate page that carries its document, naming `customer`.
pub fn page(serial: &str, number: &str, customer: Option<&str>) -> String {
    let doc = Certificate {
        format: FORMAT,
        number: Some(number.into()),
        title: format!("Calibration certificate No. {number}"),
        subtitle: format!("Accelerometer triad {serial}"),
        footer: format!("Calibration certificate No. {number}"),
        laboratory: None,
        verdict: vec![Span::plain("VERIFIED")],
        identification: Vec::new(),
        sections: Vec::new(),
        facts: Facts {
            serial: serial.into(),
            device_id: "00".into(),
            firmware: None,
            record_crc: "0".into(),
            campaign_sha256: "0".into(),
            customer: customer.map(|c| Party {
                name: c.into(),
                address: Some("Hauptstrasse 1".into()),
                country: None,
            }),
            received: None,
            place: None,
            calibrated: None,
            issued: "2026-01-01T00:00:00Z".into(),
            operator: None,
            method: "lsq".into(),
            software: "0".into(),
            gravity: Quantity { value: G, u: None, k: None, unit: "m/s²".into() },
            temperature: None,
            temperature_source: None,
            u_axis: None,
            coefficients: Vec::new(),
            parameters: Vec::new(),
            decision: None,
            decision_rule: String::new(),
            equipment: Vec::new(),
            recalibration_due: None,
            anchor: None,
            replaces: None,
        },
    };
    format!("<html><body><h1>{number}</h1>{PAGE_SCRIPT_OPEN}{}</script></body></html>", doc.canonical_json())
}

/// A fixed run id (`…00000000b1`): the same list on every run of the test.
pub fn run_id(tag: &str) -> RunId {
    RunId::parse(&format!("00000000-0000-4000-8000-{tag:0>12}")).unwrap()
}

/// A unit's device id.
fn device(n: u32) -> String {
    format!("{n:024x}")
}

/// One run of a unit: begun on `head` (if any), numbered and certified for `customer` when it
/// passes (`certify`), ended with `outcome`. The certificate's number, when it has one.
#[allow(clippy::too_many_arguments)]
fn run_on(
    db: &mut Db,
    tag: &str,
    serial: &str,
    unit: u32,
    t: i64,
    head: Option<&Asset>,
    certify: Option<&str>,
    outcome: Outcome,
) -> (RunId, Option<String>) {
    let s = start(run_id(tag), &device(unit), serial, "st-1", t);
    let run = s.run_id;
    db.begin_run(&s, None).unwrap();
    if let Some(h) = head {
        db.store_run_asset(run, h).unwrap();
    }
    let number = certify.map(|_| db.certificate_number(run).unwrap().number);
    let c = coefs(0.0, unit as usize);
    db.store_campaign(run, &campaign(300)).unwrap();
    db.store_fit(run, &fit_json(&c)).unwrap();
    if outcome == Outcome::Pass {
        let rec = db.store_record(run, &record(&s.device_id, &c)).unwrap();
        db.record_flashed(&rec).unwrap();
        db.store_verification(run, Phase::AsLeft, &verification(&s.device_id, 0.002, 0.05)).unwrap();
    }
    if let (Some(customer), Some(n)) = (certify, &number) {
        db.store_certificate(run, &page(serial, n, Some(customer))).unwrap();
    }
    let reason = if outcome == Outcome::Pass { "verified" } else { "selection beyond model 4" };
    db.finish_run(run, outcome, reason).unwrap();
    (run, number)
}

/// What [`recall_line`] stored.
pub struct RecallLine {
    /// SN-B's certificate number (approved), SN-C's first and its amendment (in force).
    pub b_number: String,
    pub c_first: String,
    pub c_number: String,
    /// SN-E's (its run voided).
    pub e_number: String,
}

/// The line: HEAD-1 under its certificate [`BAD`] calibrated SN-A before [`SINCE`], then SN-B
/// (certified for Acme AG, approved), SN-C (for Beta GmbH, its certificate amended), SN-D
/// (rejected, no certificate) and SN-E (voided) from that day on; SN-F on HEAD-1's next
/// certificate; SN-B again on HEAD-2 (`recalibrate_b`: a later run on another reference) and SN-C
/// again without a head linked (which supersedes nothing). Run ids `…a1` to `…f1`, `…b2`, `…c2`.
pub fn recall_line(db: &mut Db, recalibrate_b: bool) -> RecallLine {
    let head = head_asset("HEAD-1", BAD, "2099-12-31", 3.0, T0 - 30 * DAY);
    db.add_asset(&head).unwrap();
    let next = head_asset("HEAD-1", "DKD-17-002", "2099-12-31", 3.0, T0 + 15 * DAY);
    db.add_asset(&next).unwrap();
    let other = head_asset("HEAD-2", "DKD-22-001", "2099-12-31", 2.0, T0 - 30 * DAY);
    db.add_asset(&other).unwrap();
    run_on(db, "a1", "SN-A", 0xa, T0 + DAY, Some(&head), Some("Acme AG"), Outcome::Pass);
    let (_, b) = run_on(db, "b1", "SN-B", 0xb, T0 + 10 * DAY, Some(&head), Some("Acme AG"), Outcome::Pass);
    let (_, c) = run_on(db, "c1", "SN-C", 0xc, T0 + 11 * DAY, Some(&head), Some("Beta GmbH"), Outcome::Pass);
    run_on(db, "d1", "SN-D", 0xd, T0 + 12 * DAY, Some(&head), None, Outcome::Rejected);
    let (e, e_number) =
        run_on(db, "e1", "SN-E", 0xe, T0 + 13 * DAY, Some(&head), Some("Acme AG"), Outcome::Pass);
    db.void_run(e, "mislabelled", "qa").unwrap();
    run_on(db, "f1", "SN-F", 0xf, T0 + 20 * DAY, Some(&next), Some("Acme AG"), Outcome::Pass);
    run_on(db, "c2", "SN-C", 0xc, T0 + 41 * DAY, None, Some("Beta GmbH"), Outcome::Pass);
    if recalibrate_b {
        run_on(db, "b2", "SN-B", 0xb, T0 + 40 * DAY, Some(&other), Some("Acme AG"), Outcome::Pass);
    }
    // SN-B's certificate approved; SN-C's amended (the amendment in force, for the same customer).
    let (b, c) = (b.unwrap(), c.unwrap());
    let reviewer = accelcal_core::certificate::approval::generate().unwrap();
    let public = accelcal_core::certificate::approval::public_hex(&reviewer.verifying_key());
    db.add_signer(&accelcal_db::signer::NewSigner {
        name: "Dr. R".into(),
        function: "Head of laboratory".into(),
        public_key: public.clone(),
        operator: "qa".into(),
    })
    .unwrap();
    let d = accelcal_core::certificate::approval::Decision {
        number: b.clone(),
        document_sha256: "ab".repeat(32),
        meaning: accelcal_core::certificate::approval::Meaning::Approved,
        reason: String::new(),
        unix_s: T0 + 10 * DAY,
    };
    let sig = accelcal_core::certificate::approval::sign(&reviewer, &d).unwrap();
    db.decide(&d, &public, &sig, false).unwrap();
    let amended =
        db.amend(&c, "customer address corrected", "qa", |n| Ok(page("SN-C", &n.number, Some("Beta GmbH"))));
    let c_number = amended.unwrap().number.number;
    RecallLine { b_number: b, c_first: c, c_number, e_number: e_number.unwrap() }
}

/// The ledger's latest entry: what a refusal must leave as it was.
fn head_of(db: &mut Db) -> i64 {
    db.chain_head().unwrap().map(|a| a.seq).unwrap_or(0)
}

/// The refusal's message (an asset refusal, exit code 2 or 1).
fn refused(r: Result<impl std::fmt::Debug, DbError>) -> String {
    match r {
        Err(e) => e.to_string(),
        Ok(v) => panic!("not refused: {v:?}"),
    }
}

/// The serials of a finding's units still open.
fn open_serials(db: &mut Db) -> Vec<String> {
    let r = db.recalls(None).unwrap();
    assert_eq!(r.len(), 1);
    r[0].open().iter().map(|x| x.serial.clone()).collect()
}

/// Found bad since a day, `affected` lists exactly the runs under that certificate from that day
/// on, with their serial, certificate in force and its state, customer, and whether a later
/// calibration on another reference superseded them; refusals store nothing; a dismissal and a
/// recalibration on another head each take a unit out of `fleet`'s and `serve`'s attention; a
/// finding or a dismissal changed behind accelcal's back is caught by `db verify`.
pub fn a_bad_head_is_traced_to_its_units(spec: &str, exec: Exec<'_>) {
    let mut db = Db::open(spec).unwrap();
    let line = recall_line(&mut db, false);
    let year = accelcal_db::asset::today_utc().year();
    assert!(line.b_number.starts_with(&format!("{year}-")), "{}", line.b_number);

    // Not found bad yet: `affected` without --since says how to record it; nothing is open.
    let (code, _, err) = accelcal(&["affected", "HEAD-1", "--db", spec]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("asset `HEAD-1` was not found out of tolerance in"), "{err}");
    assert!(db.recalls(None).unwrap().is_empty());

    // Refusals: an unknown asset or certificate, a day after today, an empty or multi-line reason.
    let since = accelcal_db::asset::parse_date(SINCE).unwrap();
    let tomorrow = accelcal_db::asset::today_utc().tomorrow().unwrap();
    let before = head_of(&mut db);
    for (asset, cert, day, reason, want) in [
        ("HEAD-9", BAD, since, "worn", "asset `HEAD-9` is not registered"),
        (
            "HEAD-1",
            "DKD-99",
            since,
            "worn",
            "it has no certificate DKD-99 (its certificates: DKD-17-001, DKD-17-002)",
        ),
        ("HEAD-1", BAD, tomorrow, "worn", "is after today"),
        ("HEAD-1", BAD, since, "  ", "the reason is empty"),
        ("HEAD-1", BAD, since, "worn\nbearing", "reason"),
    ] {
        let e = refused(db.record_found_bad(asset, cert, day, reason, "ana"));
        assert!(e.contains(want), "{asset} {cert} {day} {reason:?}: {e}");
    }
    assert_eq!(head_of(&mut db), before, "nothing stored");

    let f = db.record_found_bad("HEAD-1", BAD, since, "worn bearing: 40\" at 90°", "ana").unwrap();
    assert_eq!((f.kind, f.since), (accelcal_db::AssetKind::Head, since));
    let stored = head_of(&mut db);
    assert_eq!(stored, before + 1, "one row in the chain");
    let e = refused(db.record_found_bad("HEAD-1", BAD, since, "again", "ana"));
    assert!(
        e.contains("was found out of tolerance already") && e.contains("a finding is recorded once"),
        "{e}"
    );
    assert_eq!(head_of(&mut db), stored, "nothing stored");

    // The runs under the bad certificate from that day on: not SN-A (before), nor SN-F (the next
    // certificate), nor SN-C's later run without a head.
    let recall = db.recall("HEAD-1").unwrap();
    assert_eq!(recall.len(), 1);
    let mut runs = recall[0].runs.clone();
    db.customers(&mut runs).unwrap();
    /// What a recall letter takes of a run: serial, run, certificate, customer, certified, state.
    type Listed<'a> = (&'a str, &'a str, Option<&'a str>, Option<&'a str>, bool, Option<RecallState>);
    let got: Vec<Listed> = runs
        .iter()
        .map(|r| {
            (
                r.serial.as_str(),
                r.run_id.as_str(),
                r.certificate_number.as_deref(),
                r.customer.as_deref(),
                r.certified,
                r.recall,
            )
        })
        .collect();
    let (b1, c1, d1, e1) = (run_id("b1").to_string(), run_id("c1").to_string(), run_id("d1"), run_id("e1"));
    let (d1, e1) = (d1.to_string(), e1.to_string());
    assert_eq!(
        got,
        [
            (
                "SN-B",
                b1.as_str(),
                Some(line.b_number.as_str()),
                Some("Acme AG"),
                true,
                Some(RecallState::Open)
            ),
            (
                "SN-C",
                c1.as_str(),
                Some(line.c_number.as_str()),
                Some("Beta GmbH"),
                true,
                Some(RecallState::Open)
            ),
            ("SN-D", d1.as_str(), None, None, false, Some(RecallState::Open)),
            (
                "SN-E",
                e1.as_str(),
                Some(line.e_number.as_str()),
                Some("Acme AG"),
                true,
                Some(RecallState::Voided)
            ),
        ]
    );
    assert_ne!(line.c_first, line.c_number, "the amendment's number is the one in force");
    use accelcal_db::CertificateState as S;
    let states: Vec<Option<S>> = runs.iter().map(|r| r.certificate_state).collect();
    assert_eq!(states, [Some(S::Approved), Some(S::AwaitingApproval), None, Some(S::AwaitingApproval)]);
    assert_eq!(runs[3].voided.as_deref(), Some("mislabelled"));
    assert!(runs.iter().all(|r| r.superseded_by.is_none() && r.certificate == BAD));
    assert_eq!(open_serials(&mut db), ["SN-B", "SN-C", "SN-D"]);
    // `affected --since` lists every run on the asset from a day, marking those the finding covers.
    let all = db.affected("HEAD-1", T0).unwrap();
    let marked: Vec<(&str, bool)> = all.iter().map(|r| (r.serial.as_str(), r.recall.is_some())).collect();
    assert_eq!(
        marked,
        [("SN-A", false), ("SN-B", true), ("SN-C", true), ("SN-D", true), ("SN-E", true), ("SN-F", false)]
    );

    // Dismissals: refused for a unit the finding does not affect (or only by a voided run), an
    // asset not found bad, an empty reason; SN-D dismissed once.
    let before = head_of(&mut db);
    for (asset, unit, reason, want) in [
        ("HEAD-1", "SN-A", "ok", "no run of unit SN-A is affected by its finding"),
        ("HEAD-1", "SN-E", "ok", "no run of unit SN-E is affected"),
        ("HEAD-2", "SN-D", "ok", "it was not found out of tolerance"),
        ("HEAD-9", "SN-D", "ok", "asset `HEAD-9` is not registered"),
        ("HEAD-1", "SN-D", " ", "the reason is empty"),
    ] {
        let e = refused(db.dismiss(asset, None, unit, reason, "qa"));
        assert!(e.contains(want), "{asset} {unit}: {e}");
    }
    let e = refused(db.dismiss("HEAD-1", Some("DKD-17-002"), "SN-D", "ok", "qa"));
    assert!(e.contains("it was not found out of tolerance under certificate DKD-17-002"), "{e}");
    assert_eq!(head_of(&mut db), before, "nothing stored");
    let d = db.dismiss("HEAD-1", None, "SN-D", "rejected at the station, never released", "qa").unwrap();
    assert_eq!((d.device_id.as_str(), d.certificate.as_str()), (device(0xd).as_str(), BAD));
    let e = refused(db.dismiss("HEAD-1", None, &device(0xd), "again", "qa"));
    assert!(e.contains("was dismissed already under certificate DKD-17-001"), "{e}");
    assert_eq!(head_of(&mut db), before + 1);
    assert_eq!(open_serials(&mut db), ["SN-B", "SN-C"], "the dismissal takes SN-D out");

    // SN-B calibrated again on HEAD-2: superseded, out of the attention. SN-C's later run had no
    // head linked: it may have been on the bad one, and SN-C stays open.
    run_on(
        &mut db,
        "b2",
        "SN-B",
        0xb,
        T0 + 40 * DAY,
        Some(&head_asset("HEAD-2", "DKD-22-001", "2099-12-31", 2.0, T0 - 30 * DAY)),
        Some("Acme AG"),
        Outcome::Pass,
    );
    assert_eq!(open_serials(&mut db), ["SN-C"], "the recalibration takes SN-B out");
    let r = &db.recalls(None).unwrap()[0];
    let units: Vec<(&str, RecallState)> =
        r.units().iter().map(|u| (u.run.serial.as_str(), u.state)).collect();
    assert_eq!(
        units,
        [("SN-B", RecallState::Recalibrated), ("SN-C", RecallState::Open), ("SN-D", RecallState::Dismissed)]
    );
    let b = &r.runs[0].superseded_by.as_ref().unwrap();
    assert_eq!((b.run_id.clone(), b.asset_id.as_str()), (run_id("b2").to_string(), "HEAD-2"));
    let report = db.verify_chain().unwrap();
    assert!(report.mismatches.is_empty(), "{:?}", report.mismatches);
    drop(db);

    // The command line: `affected` with --json and --csv, `fleet`, serve's overview and unit page.
    let dir = tempfile::tempdir().unwrap();
    let (json, csv) = (dir.path().join("a.json"), dir.path().join("a.csv"));
    let (code, out, err) = accelcal(&[
        "affected",
        "HEAD-1",
        "--db",
        spec,
        "--json",
        json.to_str().unwrap(),
        "--csv",
        csv.to_str().unwrap(),
    ]);
    assert_eq!(code, Some(0), "{err}");
    assert!(out.contains("certificate DKD-17-001, out of tolerance from 2026-01-05 on"), "{out}");
    assert!(out.contains(": 3 runs of 3 units, 1 open"), "{out}");
    assert!(out.contains("affected: 1 unit open: recall each"), "{out}");
    let j: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert_eq!(
        (j["since"].as_str(), j["open_units"].as_i64(), j["units"].as_i64()),
        (Some(SINCE), Some(1), Some(4))
    );
    assert_eq!(j["found_bad"][0]["reason"], "worn bearing: 40\" at 90°");
    let runs = j["runs"].as_array().unwrap();
    assert_eq!(runs.len(), 4);
    assert_eq!(runs[0]["customer"], "Acme AG");
    assert_eq!(runs[0]["certificate_state"], "approved");
    assert_eq!(runs[0]["recall"], "recalibrated");
    assert_eq!(runs[0]["superseded_by"]["run_id"], run_id("b2").to_string());
    assert_eq!(runs[1]["certificate_number"], line.c_number.as_str());
    assert_eq!(runs[1]["recall"], "open");
    assert_eq!(runs[2]["dismissed"]["reason"], "rejected at the station, never released");
    let csv = std::fs::read_to_string(&csv).unwrap();
    assert_eq!(csv.lines().count(), 5, "{csv}");
    assert!(csv.lines().nth(2).unwrap().contains("\"Beta GmbH\",\"open\","), "{csv}");

    let (fj, fc) = (dir.path().join("f.json"), dir.path().join("f.csv"));
    let (code, out, err) = accelcal(&[
        "fleet",
        "--db",
        spec,
        "--since",
        "2026-01-01",
        "--until",
        "2026-01-31",
        "--json",
        fj.to_str().unwrap(),
        "--csv",
        fc.to_str().unwrap(),
    ]);
    assert_eq!(code, Some(0), "{err}");
    // The CSV's runs: what became of each run the finding covers, and the reference.
    let mut rows = csv::Reader::from_path(&fc).unwrap();
    let header = rows.headers().unwrap().clone();
    let col = |name: &str| header.iter().position(|h| h == name).unwrap();
    let records: Vec<csv::StringRecord> = rows.records().map(|r| r.unwrap()).collect();
    // Issue 59: the customer its certificate in force names (SN-C's: the amendment's), none for
    // a run without a certificate.
    assert_eq!(header.iter().next_back(), Some("customer"));
    for r in &records {
        let want = match (&r[col("serial")], r[col("certificate_number")].is_empty()) {
            (_, true) => "",
            ("SN-C", false) => "Beta GmbH",
            (_, false) => "Acme AG",
        };
        assert_eq!(&r[col("customer")], want, "{r:?}");
    }
    assert!(records.iter().any(|r| &r[col("customer")] == "Beta GmbH"));
    let recall: Vec<(String, String, String)> = records
        .into_iter()
        .map(|r| {
            (
                r[col("serial")].to_string(),
                r[col("recall")].to_string(),
                r[col("recall_reference")].to_string(),
            )
        })
        .collect();
    let reference = format!("HEAD-1 {BAD}");
    for (serial, state) in [
        ("SN-A", ""),
        ("SN-B", "recalibrated"),
        ("SN-C", "open"),
        ("SN-D", "dismissed"),
        ("SN-E", "voided"),
        ("SN-F", ""),
    ] {
        let want = (
            serial.to_string(),
            state.to_string(),
            if state.is_empty() { String::new() } else { reference.clone() },
        );
        assert!(recall.contains(&want), "{want:?} not in {recall:?}");
    }
    assert!(
        out.contains("  recall: HEAD-1 (head) certificate DKD-17-001, out of tolerance from 2026-01-05 on (worn bearing: 40\" at 90°): 3 units, 1 recalibrated, 1 dismissed, 1 open"),
        "{out}"
    );
    assert!(out.contains(&format!("    SN-C ({}) run {c1}", device(0xc))), "{out}");
    let f: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&fj).unwrap()).unwrap();
    let recalls = f["recalls"].as_array().unwrap();
    assert_eq!(recalls.len(), 1);
    let open: Vec<&str> =
        recalls[0]["open_units"].as_array().unwrap().iter().map(|r| r["serial"].as_str().unwrap()).collect();
    assert_eq!(open, ["SN-C"]);
    assert_eq!(
        (recalls[0]["recalibrated_units"].as_i64(), recalls[0]["dismissed_units"].as_i64()),
        (Some(1), Some(1))
    );
    // Every field `fleet --json` had is still there.
    for k in ["counts", "as_found_out_of_tolerance", "units_due", "assets_due", "runs", "chain_broken"] {
        assert!(f.get(k).is_some(), "{k}");
    }
    let overview = super::serve::page(spec, "/");
    let at = overview.find("<table id=\"recalls\">").expect("the overview lists the recalls");
    let table = &overview[at..at + overview[at..].find("</table>").unwrap()];
    assert!(
        table.contains("SN-C")
            && table.contains(&c1)
            && table.contains("HEAD-1 (head) certificate DKD-17-001"),
        "{table}"
    );
    assert!(
        !table.contains("SN-B") && !table.contains("SN-D"),
        "recalibrated and dismissed units are not: {table}"
    );
    let unit = super::serve::page(spec, "/unit/SN-C");
    assert!(unit.contains("Recall: run ") && unit.contains("--dismiss SN-C --reason TEXT"), "{unit}");
    let unit = super::serve::page(spec, "/unit/SN-B");
    assert!(unit.contains("recalibrated 2026-02-10 by run"), "{unit}");

    // A finding, and a dismissal, changed behind accelcal's back: `db verify` names them,
    // `affected` refuses the asset, `fleet` marks the finding and takes no dismissal of it.
    exec("UPDATE asset_found_bad SET since_date = '2026-01-12' WHERE asset_id = 'HEAD-1'");
    exec("UPDATE recall_dismissal SET reason = 'forged' WHERE asset_id = 'HEAD-1'");
    let mut db = Db::open_existing(spec).unwrap();
    let report = db.verify_chain().unwrap();
    let pieces: Vec<&str> = report.mismatches.iter().map(|m| m.piece.as_str()).collect();
    let dismissal = format!("recall_dismissal:HEAD-1:{BAD}:{}", device(0xd));
    assert_eq!(
        pieces,
        [format!("asset_found_bad:HEAD-1:{BAD}").as_str(), dismissal.as_str()],
        "{:?}",
        report.mismatches
    );
    assert!(report.mismatches.iter().all(|m| m.what.contains("its digest differs from its ledger entry's")));
    let e = db.recall("HEAD-1").unwrap_err();
    assert!(matches!(e, DbError::AssetTampered { .. }), "{e}");
    let r = db.recalls(None).unwrap();
    assert!(
        r[0].tampered.as_deref().unwrap().contains("do not match their hash chain"),
        "{:?}",
        r[0].tampered
    );
    let (code, out, _) = accelcal(&["db", "verify", "--db", spec]);
    assert_eq!(code, Some(1), "{out}");
    assert!(out.contains(&format!("asset_found_bad:HEAD-1:{BAD}")), "{out}");
    let (code, _, err) = accelcal(&["affected", "HEAD-1", "--db", spec]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("asset HEAD-1: its register rows do not match their hash chain"), "{err}");
}
