//! Issue 55: tampering by someone with write access to the database, on both engines. `exec` runs
//! SQL with the append-only triggers out of the way (SQLite: dropped; PostgreSQL:
//! `session_replication_role = replica`), as such a person would.

use accelcal_db::anchor::Anchor;
use accelcal_db::{AnchorLog, Db, DbError, RunId};

use super::*;

/// SQL that runs with the triggers off.
pub type Exec<'a> = &'a dyn Fn(&str);

/// What a reader may not change: the SQLite file's bytes (`None` on PostgreSQL, where the ledger's
/// count says it instead).
fn file_hash(spec: &str) -> Option<String> {
    std::fs::read(spec).ok().map(|b| accelcal_db::sha256_hex(&b))
}

fn ledger_entries(spec: &str, postgres: bool) -> i64 {
    if postgres {
        let mut c = postgres::Client::connect(spec, postgres::NoTls).unwrap();
        c.query_one("SELECT COUNT(*) FROM ledger", &[]).unwrap().get(0)
    } else {
        rusqlite::Connection::open(spec)
            .unwrap()
            .query_row("SELECT COUNT(*) FROM ledger", [], |r| r.get(0))
            .unwrap()
    }
}

/// Laundering: the ledger emptied and a fit edited with its content hash recomputed. Every reader
/// runs and writes nothing (the file's hash, the ledger's count); `db verify` reports the rows
/// without an entry; a writer refuses the database.
pub fn laundering_is_reported_and_no_reader_writes(spec: &str, postgres: bool, exec: Exec<'_>) {
    let mut db = Db::open(spec).unwrap();
    let run = with_head_asset(&mut db);
    let other =
        calibrate(&mut db, &start(RunId::new(), DEVICE_2, "SN-8", "st-1", T0 + 5), &coefs(0.0, 1), None);
    drop(db);
    let forged = fit_json(&coefs(0.0, 9));
    exec(&format!(
        "DELETE FROM ledger; UPDATE fit SET fit_json = '{forged}', content_sha256 = '{}' WHERE run_id = '{run}'",
        accelcal_db::sha256_hex(forged.as_bytes())
    ));
    let before = file_hash(spec);
    let d = tempfile::tempdir().unwrap();
    let cert = d.path().join("c.html");
    let readers: Vec<Vec<String>> = vec![
        vec!["db".into(), "verify".into()],
        vec!["history".into(), "SN-1".into()],
        vec!["fleet".into(), "--since".into(), "2025-12-01".into(), "--until".into(), "2026-02-01".into()],
        vec!["certificate".into(), run.to_string(), "--out".into(), cert.display().to_string()],
        vec!["affected".into(), "HEAD-1".into(), "--since".into(), "2025-01-01".into()],
        vec!["asset".into(), "list".into()],
    ];
    let mut outputs = Vec::new();
    for r in &readers {
        let mut args: Vec<&str> = r.iter().map(String::as_str).collect();
        args.extend(["--db", spec]);
        let (code, out, err) = accelcal(&args);
        assert_ne!(code, Some(101), "{args:?} panicked: {err}");
        outputs.push((r[0].clone(), code, out, err));
    }
    let cert_path = format!("/run/{run}/certificate");
    let pages = super::serve::statuses(spec, &["/", cert_path.as_str(), "/unit/SN-1"]);
    assert_eq!(file_hash(spec), before, "no reader wrote a byte");
    assert_eq!(ledger_entries(spec, postgres), 0, "no reader sealed the rows again");
    let (_, code, out, err) = &outputs[0];
    assert_eq!(*code, Some(1), "db verify: {out}{err}");
    assert!(out.contains("it has no ledger entry (written behind accelcal's back)"), "{out}");
    assert!(err.starts_with("error: db verify: ") && !err.contains("verification failed"), "{err}");
    let (_, code, _, err) = &outputs[3];
    assert_ne!(*code, Some(0), "the certificate of a run without its chain is not printed: {err}");
    assert!(err.contains("do not match their hash chain"), "{err}");
    assert!(!cert.exists(), "no forged certificate written");
    let (_, _, out, err) = &outputs[1];
    assert!(
        out.contains("TAMPERED, not used: its rows do not match their hash chain"),
        "history: {out}{err}"
    );
    let (_, code, out, err) = &outputs[2];
    assert_eq!(*code, Some(0), "{err}");
    assert!(
        out.contains(
            "WARNING: the database's hash chain is broken (the ledger is empty and the database holds runs)"
        ),
        "fleet: {out}"
    );
    assert_eq!(pages[0].0, 200, "the overview still answers: {}", pages[0].1);
    assert!(pages[0].1.contains("hash chain is broken"), "the overview says so: {}", pages[0].1);
    assert_eq!(pages[1].0, 409, "serve's certificate route: {}", pages[1].1);
    assert!(pages[1].1.contains("do not match their hash chain"), "{}", pages[1].1);
    assert_eq!(pages[2].0, 200, "{}", pages[2].1);
    assert!(pages[2].1.contains("TAMPERED"), "the unit page marks the run: {}", pages[2].1);
    // A writer refuses to go on.
    let e = Db::open(spec).err().expect("a writer refuses the database");
    assert!(matches!(e, DbError::ChainBroken { .. }), "{e}");
    assert!(e.to_string().contains("the ledger is empty and"), "{e}");
    let _ = other;
}

/// Tail truncation: the newest run deleted with its ledger entries. `db verify` alone cannot see
/// it; against the anchor log and against a certificate-like file holding the anchor it is
/// found, and a writer with the anchor log refuses the database.
pub fn a_cut_tail_is_found_against_the_anchors(spec: &str, exec: Exec<'_>) {
    let d = tempfile::tempdir().unwrap();
    let log_path = d.path().join("anchors.log");
    let mut db = Db::open(spec).unwrap().with_anchor_log(AnchorLog::new(&log_path)).unwrap();
    let first = calibrate(&mut db, &start(RunId::new(), DEVICE, "SN-1", "st-1", T0), &coefs(0.0, 0), None);
    let kept = db.chain_head().unwrap().unwrap();
    let number = db.certificate_number(RunId::new()).err();
    assert!(number.is_some(), "no number for a run that does not exist");
    let s2 = start(RunId::new(), DEVICE_2, "SN-2", "st-1", T0 + 5);
    db.begin_run(&s2, None).unwrap();
    db.certificate_number(s2.run_id).unwrap();
    let last = calibrate(&mut db, &s2, &coefs(0.0, 1), None);
    let head = db.chain_head().unwrap().unwrap();
    drop(db);
    let logged = AnchorLog::new(&log_path).read().unwrap();
    assert_eq!(logged.last(), Some(&head), "every write's head is logged");
    assert!(logged.contains(&kept));
    let cert = d.path().join("certificate.html");
    std::fs::write(&cert, format!("<tr><th>Ledger anchor</th><td>{}</td></tr>", head.text())).unwrap();
    let (code, out, err) = accelcal(&["db", "verify", "--db", spec, "--anchors", log_path.to_str().unwrap()]);
    assert_eq!(code, Some(0), "{out}{err}");
    assert!(out.contains("and every anchor is in it"), "{out}");
    // The newest run cut off, rows and ledger entries alike.
    let tables = [
        "run_end",
        "certificate",
        "verification",
        "flash",
        "cal_record",
        "fit",
        "campaign",
        "certificate_number",
        "verification_summary",
        "verification_parameter",
        "fit_parameter",
        "fit_summary",
        "head_observation_f32",
        "head_observation",
        "device_certificate",
        "recalibration_due",
    ];
    let mut sql: String =
        tables.iter().map(|t| format!("DELETE FROM {t} WHERE run_id = '{last}'; ")).collect();
    sql.push_str(&format!(
        "DELETE FROM run WHERE run_id = '{last}'; DELETE FROM ledger WHERE run_id = '{last}';"
    ));
    exec(&sql);
    let (code, out, err) = accelcal(&["db", "verify", "--db", spec]);
    assert_eq!(code, Some(0), "the chain alone cannot see a cut tail: {out}{err}");
    for anchors in [&log_path, &cert] {
        let (code, out, err) =
            accelcal(&["db", "verify", "--db", spec, "--anchors", anchors.to_str().unwrap()]);
        assert_eq!(code, Some(1), "{out}{err}");
        assert!(
            out.contains(&format!("but entry {} was anchored: entries were removed from its end", head.seq)),
            "{out}"
        );
        assert!(err.contains("1 anchors") || err.contains("anchors)"), "{err}");
    }
    // A writer with the log refuses; one without it still opens (the chain is whole).
    let e = Db::open(spec).unwrap().with_anchor_log(AnchorLog::new(&log_path)).err().expect("refused");
    assert!(e.to_string().contains("entries were removed from its end"), "{e}");
    // A rewritten entry (its chain value forged) is told from a cut one.
    let forged = Anchor { seq: kept.seq, chain_sha256: "0".repeat(64) };
    std::fs::write(&cert, forged.text()).unwrap();
    let (code, out, _) = accelcal(&["db", "verify", "--db", spec, "--anchors", cert.to_str().unwrap()]);
    assert_eq!(code, Some(1));
    assert!(out.contains("is not the one anchored (its chain value differs)"), "{out}");
    // A file without an anchor is the user's error.
    std::fs::write(&cert, "no anchor here").unwrap();
    let (code, _, err) = accelcal(&["db", "verify", "--db", spec, "--anchors", cert.to_str().unwrap()]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("holds no anchor"), "{err}");
    let _ = first;
}

/// A certificate number missing below the largest is reported (its rows removed, the ledger
/// made consistent again by whoever removed them is not needed to see it).
pub fn a_missing_certificate_number_is_reported(spec: &str, exec: Exec<'_>) {
    let mut db = Db::open(spec).unwrap();
    let mut runs = Vec::new();
    for i in 0..3 {
        let s = start(RunId::new(), DEVICE, "SN-1", "st-1", T0 + i * DAY);
        db.begin_run(&s, None).unwrap();
        db.certificate_number(s.run_id).unwrap();
        runs.push(s.run_id);
    }
    drop(db);
    exec(&format!("DELETE FROM certificate_number WHERE run_id = '{}'", runs[1]));
    let (code, out, _) = accelcal(&["db", "verify", "--db", spec]);
    assert_eq!(code, Some(1), "{out}");
    assert!(out.contains("certificates are numbered in sequence, and number 2 is missing"), "{out}");
}

/// A forged asset register (due date moved, uncertainty made smaller, content hash recomputed)
/// is refused by `fit --head-asset` and `station --head-asset` before anything else, and by the
/// report's and flash's check of a run that used it.
pub fn a_forged_asset_is_refused(spec: &str, postgres: bool, exec: Exec<'_>) {
    let mut db = Db::open(spec).unwrap();
    let run = with_head_asset(&mut db);
    drop(db);
    // The forged statements: due in 2199, 0.5″ instead of 3″.
    let content =
        format!("HEAD-1\nDKD-17-001\nhead\n2199-12-31\n{:?}\n{:?}", 0.5f64.to_bits(), 6.0f64.to_bits());
    let sha = accelcal_db::sha256_hex(content.as_bytes());
    let sql = format!(
        "UPDATE asset SET due_date = '2199-12-31', angle_u_arcsec = 0.5, content_sha256 = '{sha}' WHERE asset_id = 'HEAD-1'"
    );
    if !postgres {
        // REPLACE needs no trigger dropped before schema 8; now it is refused too.
        let c = rusqlite::Connection::open(spec).unwrap();
        let e = c
            .execute_batch(&format!(
                "REPLACE INTO asset SELECT asset_id, certificate, kind, '2199-12-31', 0.5, orthogonality_u_arcsec, \
                 operator, registered_unix_s, '{sha}', value_si, value_u_si FROM asset WHERE asset_id = 'HEAD-1'"
            ))
            .unwrap_err();
        assert!(e.to_string().contains("append-only: asset rows are never replaced"), "{e}");
    }
    exec(&sql);
    let (code, out, err) = accelcal(&["asset", "list", "--db", spec]);
    assert_eq!(code, Some(0), "{err}");
    assert!(out.contains("TAMPERED, not usable"), "the register lists the forged asset as such: {out}");
    let mut db = Db::open(spec).unwrap();
    let e = db.asset_certificates("HEAD-1").unwrap_err();
    assert!(matches!(e, DbError::AssetTampered { .. }), "{e}");
    assert!(e.to_string().contains("asset HEAD-1: its register rows do not match their hash chain"), "{e}");
    let e = db.verify_run(run).unwrap_err();
    assert!(
        e.to_string().contains("the asset:HEAD-1:DKD-17-001 row"),
        "the run's check covers its head: {e}"
    );
    drop(db);
    let d = tempfile::tempdir().unwrap();
    let c = d.path().join("c.csv");
    let (code, _, err) = accelcal(&["simulate", "--out", c.to_str().unwrap(), "--samples", "40"]);
    assert_eq!(code, Some(0), "{err}");
    let rec = d.path().join("r.rec");
    let (code, _, err) = accelcal(&[
        "fit",
        c.to_str().unwrap(),
        "--db",
        spec,
        "--head-asset",
        "HEAD-1",
        "--record",
        rec.to_str().unwrap(),
        "--device-id",
        DEVICE,
    ]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("asset HEAD-1: its register rows do not match their hash chain"), "{err}");
    let (code, _, err) = accelcal(&[
        "station",
        "--port",
        "/dev/accelcal-no-such-port",
        "--serial",
        "SN-9",
        "--out",
        d.path().join("u").to_str().unwrap(),
        "--head",
        "manual",
        "--db",
        spec,
        "--head-asset",
        "HEAD-1",
    ]);
    assert!(err.contains("asset HEAD-1: its register rows do not match their hash chain"), "{err}");
    assert!(!err.contains("accelcal-no-such-port"), "refused before the node is touched: {err}");
    assert_ne!(code, Some(0));
}

/// Derived rows edited behind accelcal's back (a verification's rule, a fit parameter's unit) are
/// found by `db verify`.
pub fn derived_edits_are_found(spec: &str, exec: Exec<'_>) {
    let mut db = Db::open(spec).unwrap();
    let run =
        calibrate(&mut db, &start(RunId::new(), DEVICE, "SN-1", "st-1", T0), &coefs(0.0, 0), Some(0.01));
    drop(db);
    for (sql, finding) in [
        (
            format!("UPDATE fit_parameter SET unit = 'ppm' WHERE run_id = '{run}' AND ord = 0"),
            "fit_summary/fit_parameter",
        ),
        (
            format!("UPDATE verification_summary SET rule = 'forged' WHERE run_id = '{run}' AND phase = 'as_left'"),
            "verification_summary/verification_parameter",
        ),
    ] {
        exec(&sql);
        let (code, out, _) = accelcal(&["db", "verify", "--db", spec]);
        assert_eq!(code, Some(1), "{sql}: {out}");
        assert!(out.contains(finding), "{sql}: {out}");
    }
}

/// A run whose row was edited behind accelcal's back (its operator; another run's fit, a piece
/// the fleet does not show) is marked as tampered by every reader that lists it, and the other
/// runs are shown as they are: `fleet` (text, `--json`'s `tampered`, the CSV's state),
/// `history`, and serve's fleet and unit pages. A tampered run is set aside from every count,
/// yield and population (and said so: `2 tampered runs set aside`), and charted nowhere. A
/// derived value that is not a number (SQLite: text in a REAL column; PostgreSQL: NaN) does not
/// poison a population: its run is left out of them and named.
pub fn a_tampered_run_is_marked_where_it_is_listed(spec: &str, exec: Exec<'_>) {
    let postgres = matches!(accelcal_db::Target::parse(spec), Ok(accelcal_db::Target::Postgres(_)));
    let mut db = Db::open(spec).unwrap();
    let run = calibrate(&mut db, &start(RunId::new(), DEVICE, "SN-1", "st-1", T0), &coefs(0.0, 0), None);
    let other =
        calibrate(&mut db, &start(RunId::new(), DEVICE_2, "SN-2", "st-1", T0 + 5), &coefs(0.0, 1), None);
    let fit_forged = calibrate(
        &mut db,
        &start(RunId::new(), "fedcba9876543210fedcba98", "SN-3", "st-1", T0 + 10),
        &coefs(0.0, 2),
        None,
    );
    let nan = calibrate(
        &mut db,
        &start(RunId::new(), "00112233445566778899aabb", "SN-4", "st-1", T0 + 15),
        &coefs(0.0, 3),
        None,
    );
    drop(db);
    exec(&format!("UPDATE run SET operator = 'mallory' WHERE run_id = '{run}'"));
    exec(&format!("UPDATE fit SET stored_unix_s = stored_unix_s + 1 WHERE run_id = '{fit_forged}'"));
    let not_a_number = if postgres { "'NaN'" } else { "'abc'" };
    exec(&format!("UPDATE fit_parameter SET value = {not_a_number} WHERE run_id = '{nan}' AND ord = 0"));
    let d = tempfile::tempdir().unwrap();
    let (json, csv) = (d.path().join("f.json"), d.path().join("f.csv"));
    let (code, out, err) = accelcal(&[
        "fleet",
        "--since",
        "2025-12-01",
        "--until",
        "2026-02-01",
        "--db",
        spec,
        "--json",
        json.to_str().unwrap(),
        "--csv",
        csv.to_str().unwrap(),
    ]);
    assert_eq!(code, Some(0), "{out}{err}");
    assert!(
        out.contains("TAMPERED: 2 runs whose rows do not match their hash chain (set aside")
            && out.contains(&format!("run {run} (SN-1): its run row (ledger entry "))
            && out.contains("it is not the row that was stored (its digest differs from its ledger entry's)")
            && out.contains(&format!("run {fit_forged} (SN-3): its fit row"))
            && out.contains("2 runs of 2 units (2 tampered runs set aside)")
            && out.contains("runs: 2 pass, 0 rejected")
            && out.contains("yield: first pass 2/2 units"),
        "{out}"
    );
    assert!(out.contains(&format!("run {nan} does not read")), "{out}");
    let f: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let runs = f["runs"].as_array().unwrap();
    let of = |id: &RunId| runs.iter().find(|r| r["run_id"] == id.to_string()).unwrap().clone();
    assert!(of(&run)["tampered"].as_str().unwrap().contains("its run row (ledger entry "), "{f}");
    assert!(of(&fit_forged)["tampered"].as_str().unwrap().contains("its fit row"), "{f}");
    assert!(of(&other).get("tampered").is_none(), "the other run is not marked: {f}");
    assert!(of(&nan).get("tampered").is_none(), "a derived cell is not the chain's: {f}");
    assert_eq!((f["counts"]["runs"].as_i64(), f["counts"]["tampered"].as_i64()), (Some(2), Some(2)), "{f}");
    let pops = f["populations"].as_array().unwrap();
    assert!(!pops.is_empty(), "{f}");
    for p in pops {
        // Only `other`: the tampered runs are set aside, `nan`'s value is not a number.
        assert_eq!(p["n"], 1, "{p}");
        assert!(p["mean"].as_f64().is_some_and(f64::is_finite), "{p}");
    }
    assert!(f["unreadable_runs"].as_array().unwrap().iter().any(|u| u["run_id"] == nan.to_string()), "{f}");
    let csv = std::fs::read_to_string(&csv).unwrap();
    let line = |id: &RunId| csv.lines().find(|l| l.contains(&id.to_string())).unwrap().to_string();
    assert!(line(&run).contains("\"tampered\""), "{csv}");
    assert!(line(&other).contains("\"pass\""), "{csv}");
    let charted =
        f["charts"].as_array().unwrap().iter().flat_map(|c| c["points"].as_array().unwrap().clone());
    assert!(
        charted.clone().all(|p| p["run_id"] != run.to_string() && p["run_id"] != fit_forged.to_string()),
        "a tampered run is charted nowhere: {f}"
    );
    let (_, out, err) = accelcal(&["history", "SN-1", "--db", spec]);
    assert!(out.contains("TAMPERED, not used: its rows do not match their hash chain"), "{out}{err}");
    let pages = super::serve::statuses(spec, &["/fleet?since=2025-12-01&until=2026-02-01", "/unit/SN-1"]);
    assert_eq!(pages[0].0, 200, "{}", pages[0].1);
    assert!(
        pages[0].1.contains("class=\"bad\">tampered</td>")
            && pages[0].1.contains("TAMPERED, not used: its run row")
            && pages[0].1.contains("final yield 2/2 (100.0 %); 2 tampered runs set aside."),
        "{}",
        pages[0].1
    );
    assert_eq!(pages[1].0, 200, "{}", pages[1].1);
    assert!(pages[1].1.contains("TAMPERED"), "{}", pages[1].1);
}
