//! The calibration database on SQLite (`core::db`): pieces stored once, append-only rows, a
//! writer killed mid-unit resuming, two writers at once, one schema for both engines, and
//! `accelcal history` end to end (its output a snapshot).

use crate::dbkit;
#[path = "db/fleet.rs"]
mod fleet;

use std::path::Path;

use accelcal_db::{Db, Outcome, RunId};
use dbkit::*;

fn db_file(d: &tempfile::TempDir) -> String {
    d.path().join("cal.sqlite").display().to_string()
}

#[test]
fn pieces_are_stored_once_and_a_finished_run_takes_nothing_more() {
    let d = tempfile::tempdir().unwrap();
    pieces_are_stored_once(&db_file(&d));
}

#[test]
fn calibration_rows_are_never_updated_or_deleted() {
    let d = tempfile::tempdir().unwrap();
    let spec = db_file(&d);
    let mut db = Db::open(&spec).unwrap();
    with_head_asset(&mut db);
    drop(db);
    let c = rusqlite::Connection::open(&spec).unwrap();
    for table in APPEND_ONLY {
        let e = c.execute(&format!("UPDATE {table} SET content_sha256 = 'x'"), []).unwrap_err();
        assert!(
            e.to_string().contains(&format!("append-only: {table} rows are never updated")),
            "{table}: {e}"
        );
        let e = c.execute(&format!("DELETE FROM {table}"), []).unwrap_err();
        assert!(
            e.to_string().contains(&format!("append-only: {table} rows are never deleted")),
            "{table}: {e}"
        );
    }
    let n: i64 = c.query_row("SELECT count(*) FROM run", [], |r| r.get(0)).unwrap();
    assert_eq!(n, 1);
}

#[test]
fn a_writer_killed_mid_unit_resumes_with_no_duplicate_and_no_partial_row() {
    if writer_child() {
        return;
    }
    let d = tempfile::tempdir().unwrap();
    let spec = db_file(&d);
    let run = killed_writer_resumes(
        &spec,
        module_path!(),
        "a_writer_killed_mid_unit_resumes_with_no_duplicate_and_no_partial_row",
    );
    let c = rusqlite::Connection::open(&spec).unwrap();
    for table in ["run", "campaign", "fit", "cal_record", "flash", "verification", "run_end"] {
        let n: i64 = c
            .query_row(&format!("SELECT count(*) FROM {table} WHERE run_id = ?1"), [run.to_string()], |r| {
                r.get(0)
            })
            .unwrap();
        assert_eq!(n, 1, "{table}");
    }
    let ok: String = c.query_row("PRAGMA integrity_check", [], |r| r.get(0)).unwrap();
    assert_eq!(ok, "ok");
}

#[test]
fn assets_are_registered_once_refused_when_overdue_and_traced_to_their_runs() {
    let d = tempfile::tempdir().unwrap();
    assets_register_and_trace(&db_file(&d));
}

#[test]
fn every_column_of_the_migrated_database_is_in_the_chain_in_order() {
    let d = tempfile::tempdir().unwrap();
    let spec = db_file(&d);
    drop(Db::open(&spec).unwrap());
    let c = rusqlite::Connection::open(&spec).unwrap();
    columns_are_the_chain_s(&mut |t| {
        let mut s = c.prepare(&format!("PRAGMA table_info({t})")).unwrap();
        s.query_map([], |r| r.get::<_, String>(1)).unwrap().map(|r| r.unwrap()).collect()
    });
}

#[test]
fn a_reader_does_not_wait_for_a_writer() {
    let d = tempfile::tempdir().unwrap();
    let spec = db_file(&d);
    dbkit::a_reader_does_not_wait_for_a_writer(&spec, || {
        let c = rusqlite::Connection::open(&spec).unwrap();
        c.execute_batch("BEGIN IMMEDIATE").unwrap();
        c
    });
}

#[test]
fn two_writers_at_once_lose_nothing() {
    let d = tempfile::tempdir().unwrap();
    two_writers_lose_nothing(&db_file(&d), 8);
}

/// `CREATE TABLE` blocks of a migration: table name → column names, in order.
fn tables(sql: &str) -> Vec<(String, Vec<String>)> {
    sql.split("CREATE TABLE ")
        .skip(1)
        .map(|block| {
            let (name, body) = block.split_once(" (").unwrap();
            let body = &body[..body.find("\n);").unwrap()];
            let cols = body
                .lines()
                .map(|l| l.trim())
                .filter(|l| {
                    !l.is_empty()
                        && !l.starts_with("PRIMARY KEY")
                        && !l.starts_with("UNIQUE")
                        && !l.starts_with("FOREIGN KEY")
                        && !l.starts_with("--")
                })
                .map(|l| l.split_whitespace().next().unwrap().to_string())
                .collect();
            (name.to_string(), cols)
        })
        .collect()
}

#[test]
fn both_engines_have_the_same_tables_and_columns() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../db/migrations");
    let versions = |engine: &str| -> Vec<String> {
        let mut v: Vec<String> = std::fs::read_dir(dir.join(engine))
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        v.sort();
        v
    };
    assert_eq!(versions("sqlite"), versions("postgres"));
    for v in versions("sqlite") {
        let s = tables(&std::fs::read_to_string(dir.join("sqlite").join(&v)).unwrap());
        let p = tables(&std::fs::read_to_string(dir.join("postgres").join(&v)).unwrap());
        assert_eq!(s, p, "{v}");
        let want = match &v[..4] {
            "V1__" => 8,
            "V2__" => 3,
            "V4__" | "V5__" | "V7__" | "V8__" => 1,
            "V6__" => 7,
            "V9__" => 3,
            // Columns added to `asset`, no table.
            "V11_" => 0,
            _ => 2,
        };
        assert_eq!(s.len(), want, "{v}: {s:?}");
    }
}

/// A unit with three calibrations 180 days apart whose x bias grows by 50 codes each time, an
/// unfinished run between them, and another unit.
fn three_calibrations(spec: &str) {
    let mut db = Db::open(spec).unwrap();
    for i in 0..3 {
        let t = T0 + 180 * DAY * i as i64;
        let s = start(
            RunId::parse(&format!("00000000-0000-4000-8000-00000000000{i}")).unwrap(),
            DEVICE,
            "SN-0042",
            "st-1",
            t,
        );
        calibrate(&mut db, &s, &coefs(50.0, i), (i > 0).then_some(0.004 * i as f64));
    }
    let killed = start(
        RunId::parse("00000000-0000-4000-8000-0000000000aa").unwrap(),
        DEVICE,
        "SN-0042",
        "st-2",
        T0 + 200 * DAY,
    );
    db.begin_run(&killed, None).unwrap();
    db.store_campaign(killed.run_id, &campaign(10)).unwrap();
    let other = start(RunId::new(), "00112233445566778899aabb", "SN-0043", "st-1", T0);
    calibrate(&mut db, &other, &coefs(0.0, 0), None);
}

#[test]
fn history_shows_every_run_the_drift_and_the_recalibration_date() {
    let d = tempfile::tempdir().unwrap();
    let spec = db_file(&d);
    three_calibrations(&spec);
    let json = d.path().join("h.json");
    let (code, out, err) = accelcal(&["history", "SN-0042", "--db", &spec, "--json", json.to_str().unwrap()]);
    assert_eq!(code, Some(0), "{err}");
    insta::assert_snapshot!(
        "history_stdout",
        out.replace(&spec, "<db>").replace(json.to_str().unwrap(), "<json>")
    );
    let j: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert_eq!(j["device_id"], DEVICE);
    assert_eq!(j["runs"].as_array().unwrap().len(), 4);
    assert_eq!(j["drifts"].as_array().unwrap().len(), 2);
    let x1 = &j["drifts"][0]["terms"][0];
    assert_eq!((x1["channel"].as_str(), x1["term"].as_str()), (Some("x"), Some("1")));
    // 50 codes over the own sensitivity 1670 codes/(m/s²).
    assert!((x1["delta_m_s2"].as_f64().unwrap() - 50.0 / 1670.0).abs() < 1e-12, "{x1}");
    assert!((x1["sigma_m_s2"].as_f64().unwrap() - 0.5 * 2f64.sqrt() / 1670.0).abs() < 1e-12, "{x1}");
    let rc = &j["recalibration"];
    assert_eq!(rc["limiting"]["channel"], "x");
    assert_eq!(rc["limiting"]["term"], "1");
    // r = 50/1670 m/s² per 180 days; s_r = σ·sqrt(3/194400) per day (three equally weighted
    // points at -360, -180, 0 days); τ = T / (|r| + 2 s_r).
    let sigma = 0.5 / 1670.0;
    let r = 50.0 / 1670.0 / 180.0;
    let tau = 0.05 / (r + 2.0 * sigma * (3.0f64 / 194_400.0).sqrt());
    let due = T0 + 360 * DAY + (tau * 86_400.0).round() as i64;
    assert_eq!(rc["due_unix_s"].as_i64(), Some(due), "{rc}");
    // The device id names the same unit.
    let (code, by_id, _) = accelcal(&["history", DEVICE, "--db", &spec]);
    assert_eq!(code, Some(0));
    assert_eq!(by_id, out.replace(&format!("wrote {}\n", json.display()), ""));
}

#[test]
fn history_after_one_calibration_recommends_the_maximum_interval() {
    let d = tempfile::tempdir().unwrap();
    let spec = db_file(&d);
    three_calibrations(&spec);
    let (code, out, err) = accelcal(&["history", "SN-0043", "--db", &spec, "--max-interval-days", "200"]);
    assert_eq!(code, Some(0), "{err}");
    assert!(
        out.contains(
            "recalibrate by 2026-07-20 (one calibration: no drift known yet, the calibration plus 200 days"
        ),
        "{out}"
    );
    let mut db = Db::open(&spec).unwrap();
    let runs = db.unit_runs("SN-0043").unwrap();
    assert_eq!(runs[0].end.as_ref().map(|e| e.0), Some(Outcome::Pass));
}

/// ILAC-G24 method 1: an as-found result out of tolerance at the last calibration shortens the
/// next interval to half the one the unit had served (here 200 days: 100), whatever the slow
/// drift of its coefficients allows; within tolerance, the drift's date stands. With no
/// calibration before it in the database, half of the maximum interval.
#[test]
fn an_as_found_out_of_tolerance_shortens_the_next_interval() {
    let d = tempfile::tempdir().unwrap();
    let spec = db_file(&d);
    let mut db = Db::open(&spec).unwrap();
    let unit = |db: &mut Db, serial: &str, device: &str, last_as_found: f64| {
        for (i, days) in [0, 200].into_iter().enumerate() {
            let s = start(RunId::new(), device, serial, "st-1", T0 + days * DAY);
            calibrate(db, &s, &coefs(1.0, i), (i > 0).then_some(last_as_found));
        }
    };
    unit(&mut db, "SN-IN", DEVICE, 0.03);
    unit(&mut db, "SN-OUT", "00112233445566778899aabb", 0.09);
    let first = start(RunId::new(), "0011223344556677889900cc", "SN-NEW", "st-1", T0);
    calibrate(&mut db, &first, &coefs(0.0, 0), Some(0.2));
    drop(db);
    let history = |serial: &str| {
        let json = d.path().join(format!("{serial}.json"));
        let (code, out, err) =
            accelcal(&["history", serial, "--db", &spec, "--json", json.to_str().unwrap()]);
        assert_eq!(code, Some(0), "{err}");
        let j: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
        (out, j["recalibration"].clone())
    };
    let (out, rc) = history("SN-IN");
    assert!(rc["as_found_out_of_tolerance"].is_null(), "{rc}");
    assert_eq!(rc["due_unix_s"].as_i64(), Some(T0 + 565 * DAY), "{out}");
    let (out, rc) = history("SN-OUT");
    assert_eq!(rc["due_unix_s"].as_i64(), Some(T0 + 300 * DAY), "{out}");
    let s = &rc["as_found_out_of_tolerance"];
    assert_eq!((s["served_days"].as_f64(), s["interval_days"].as_f64()), (Some(200.0), Some(100.0)), "{s}");
    assert!(
        out.contains(
            "recalibrate by 2026-10-28 (as found error 0.0900 m/s² beyond the tolerance 0.05 m/s²: half the 200 days it had served since the calibration before, ILAC-G24 method 1 (by the drift alone:"
        ),
        "{out}"
    );
    let (out, rc) = history("SN-NEW");
    assert_eq!(rc["due_unix_s"].as_i64(), Some(T0 + 183 * DAY - DAY / 2), "{out}");
    assert!(
        out.contains("half of 365 days (--max-interval-days), no calibration before it in the database"),
        "{out}"
    );
    let (code, help, _) = accelcal(&["history", "--help"]);
    assert_eq!(code, Some(0));
    assert!(help.contains("ILAC-G24 method 1"), "{help}");
}

/// Issue 59: a recalibration minutes after the last served nothing: the halved interval counts
/// the time served since the calibration before that is not a repeat (200 days: 100). An
/// interval halved below the floor (`--min-interval-days`, 30 by default) is raised to it, and
/// says so.
#[test]
fn a_halved_interval_counts_the_time_served_and_has_a_floor() {
    let d = tempfile::tempdir().unwrap();
    let spec = db_file(&d);
    let mut db = Db::open(&spec).unwrap();
    let unit = |db: &mut Db, serial: &str, device: &str, at: &[i64]| {
        for (i, &t) in at.iter().enumerate() {
            let s = start(RunId::new(), device, serial, "st-1", T0 + t);
            calibrate(db, &s, &coefs(1.0, i), (i + 1 == at.len()).then_some(0.09));
        }
    };
    unit(&mut db, "SN-AGAIN", DEVICE, &[0, 200 * DAY, 200 * DAY + 600]);
    unit(&mut db, "SN-SOON", "00112233445566778899aabb", &[0, 20 * DAY]);
    drop(db);
    let history = |serial: &str, more: &[&str]| {
        let json = d.path().join(format!("{serial}.json"));
        let mut args = vec!["history", serial, "--db", &spec, "--json", json.to_str().unwrap()];
        args.extend(more);
        let (code, out, err) = accelcal(&args);
        assert_eq!(code, Some(0), "{err}");
        let j: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
        (out, j["recalibration"].clone())
    };
    let (out, rc) = history("SN-AGAIN", &[]);
    let s = &rc["as_found_out_of_tolerance"];
    let served = s["served_days"].as_f64().unwrap();
    assert_eq!(served, (200 * DAY + 600) as f64 / DAY as f64, "since the first, not the repeat: {out}");
    assert_eq!(s["interval_days"].as_f64(), Some(served / 2.0), "{out}");
    assert_eq!(rc["due_unix_s"].as_i64(), Some(T0 + 300 * DAY + 900), "{out}");
    let (out, rc) = history("SN-SOON", &[]);
    assert_eq!(rc["as_found_out_of_tolerance"]["interval_days"].as_f64(), Some(30.0), "{out}");
    assert_eq!(rc["due_unix_s"].as_i64(), Some(T0 + 50 * DAY), "{out}");
    assert!(
        out.contains(
            "half the 20 days it had served since the calibration before, raised to the floor of 30 days"
        ),
        "{out}"
    );
    // history counts the accepted positions of a failed verification, and says so.
    assert!(out.contains("FAIL, 3 of 6 accepted, max 0.090 m/s²"), "{out}");
    let (out, rc) = history("SN-SOON", &["--min-interval-days", "5"]);
    assert_eq!(rc["due_unix_s"].as_i64(), Some(T0 + 30 * DAY), "{out}");
    assert_eq!(rc["rule"]["min_interval_days"].as_f64(), Some(5.0), "{rc}");
    let (code, _, err) = accelcal(&["history", "SN-SOON", "--db", &spec, "--min-interval-days", "400"]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("--min-interval-days 400 is longer than --max-interval-days 365"), "{err}");
}

/// Issue 59: a verification's failure names the positions outside T apart from those inside T
/// but within the guard band (a conditional pass the rule does not accept).
#[test]
fn a_failed_verification_tells_the_guard_band_from_the_tolerance() {
    use accelcal_core::conformity::Decision;
    let mut v = verification(DEVICE, 0.09, 0.05);
    assert_eq!(v.failure().unwrap().words(), "3 of 6 positions outside the tolerance");
    // Position 4 (error 0.06) judged inside T within the guard band; 5 and 6 beyond it.
    for p in &mut v.positions {
        p.decisions = Some(match p.position {
            4 => [Decision::ConditionalPass, Decision::Pass, Decision::Pass],
            5 | 6 => [Decision::Fail, Decision::Pass, Decision::Pass],
            _ => [Decision::Pass; 3],
        });
    }
    assert_eq!(
        v.failure().unwrap().words(),
        "2 of 6 positions outside the tolerance; 1 of 6 positions inside T, within the guard band (conditional pass, not accepted)"
    );
    for p in &mut v.positions {
        if p.position > 4 {
            p.decisions = Some([Decision::ConditionalPass; 3]);
        }
    }
    assert_eq!(
        v.failure().unwrap().to_string(),
        "verification failed: 3 of 6 positions inside T, within the guard band (conditional pass, not accepted)"
    );
}

#[test]
fn history_refuses_what_it_cannot_read() {
    let d = tempfile::tempdir().unwrap();
    let spec = db_file(&d);
    three_calibrations(&spec);
    // The beginning of a run id that begins several: refused, naming them.
    let (code, _, err) = accelcal(&["certificate", "00000000-0000", "--db", &spec, "-o", "x.html"]);
    assert_eq!(code, Some(2), "{err}");
    assert!(
        err.contains("00000000-0000 begins more than 3 run ids (00000000-0000-4000-8000-000000000000, "),
        "{err}"
    );
    assert!(err.contains("give more of its digits"), "{err}");
    let missing = d.path().join("none.sqlite");
    let cases: Vec<(Vec<&str>, i32, String)> = vec![
        (
            vec!["history", "SN-0042"],
            2,
            "no calibration database: give --db FILE|URL, set ACCELCAL_DB, or run where the station's calibration.sqlite is"
                .into(),
        ),
        (vec!["history", "SN-9", "--db", &spec], 2, format!("no unit `SN-9` in the database {spec}")),
        (
            vec!["history", "SN-0042", "--db", missing.to_str().unwrap()],
            2,
            format!("{}: no such database", missing.display()),
        ),
        (
            vec!["history", "SN-0042", "--db", &spec, "--tolerance-m-s2", "0"],
            2,
            "--tolerance-m-s2 must be a positive number".into(),
        ),
        (
            vec!["history", "SN-0042", "--db", &spec, "--json", &spec],
            2,
            "is the database: refusing to overwrite it".into(),
        ),
        (
            vec!["history", "SN-0042", "--db", "postgres://accelcal@127.0.0.1:1/accelcal"],
            1,
            "database postgres://accelcal@127.0.0.1:1/accelcal cannot be reached".into(),
        ),
    ];
    for (args, want_code, want) in cases {
        let (code, out, err) = accelcal(&args);
        assert_eq!(code, Some(want_code), "{args:?}: {err}");
        assert!(
            err.starts_with("error: ") && err.contains(&want) && err.lines().count() == 1,
            "{args:?}: {err}"
        );
        assert!(out.is_empty(), "{args:?}: {out}");
    }
    assert!(!missing.exists(), "a reader created the database");
}

/// Runs accelcal, which must succeed; its stdout.
fn ok(args: &[&str]) -> String {
    let (code, out, err) = accelcal(args);
    assert_eq!(code, Some(0), "{args:?}: {err}");
    out
}

/// Runs accelcal, which must refuse its input (exit 2) with one `error:` line; that line.
fn bad(args: &[&str]) -> String {
    let (code, _, err) = accelcal(args);
    assert_eq!(code, Some(2), "{args:?}: {err}");
    assert!(err.starts_with("error: ") && err.lines().count() == 1, "{args:?}: {err}");
    err
}

/// The run id a command printed (`db: run <uuid> begun in ...`).
fn run_id_in(err: &str) -> String {
    let at = err.find("db: run ").expect("a run line") + "db: run ".len();
    err[at..at + 36].to_string()
}

/// `fit`, `flash` and `report` given `--db`: each stores its piece in the run (`fit` begins it),
/// storing again is a no-op, a piece of another unit or another record is refused, and a
/// database that cannot be reached stops `flash` and `station` before they touch the node.
#[test]
fn commands_given_db_store_their_pieces_and_an_unreachable_database_stops_them_first() {
    let d = tempfile::tempdir().unwrap();
    let spec = db_file(&d);
    let p = |n: &str| d.path().join(n).display().to_string();
    let (c, r, f, cert) = (p("c.csv"), p("r.rec"), p("f.json"), p("cert.html"));
    ok(&["simulate", "--seed", "7", "--samples", "20", "-o", &c]);
    let fit = |extra: &[&str]| {
        let mut a = vec!["fit", &c, "--record", &r, "--device-id", DEVICE, "--created", "1800000000"];
        a.extend(["--json", &f, "--db", &spec]);
        a.extend(extra);
        accelcal(&a)
    };
    let (code, out, err) = fit(&[]);
    assert_eq!(code, Some(0), "{err}");
    let run = run_id_in(&err);
    assert!(err.contains(&format!("db: run {run} begun in {spec}")), "{err}");
    assert!(out.contains(&format!("db: run {run}: campaign, fit and record stored in {spec}")), "{out}");
    // Again into the same run: the same pieces, nothing written twice.
    let (code, _, err) = fit(&["--run-id", &run]);
    assert_eq!(code, Some(0), "{err}");
    let count = |table: &str| -> i64 {
        let c = rusqlite::Connection::open(&spec).unwrap();
        c.query_row(&format!("SELECT count(*) FROM {table} WHERE run_id = ?1"), [&run], |r| r.get(0)).unwrap()
    };
    for table in ["run", "campaign", "fit", "cal_record"] {
        assert_eq!(count(table), 1, "{table}");
    }
    // Another record under that run: refused, and nothing flashed.
    let other = p("other.rec");
    ok(&["fit", &c, "--record", &other, "--device-id", DEVICE, "--created", "1800000001"]);
    let e = bad(&["flash", &other, "--db", &spec, "--run-id", &run, "--gdb", "127.0.0.1:1"]);
    assert!(e.contains(&format!("is not the record run {run} stored")), "{e}");
    // The stored record gets as far as the probe (none listens here).
    let (code, _, e) = accelcal(&["flash", &r, "--db", &spec, "--run-id", &run, "--gdb", "127.0.0.1:1"]);
    assert_eq!(code, Some(1), "{e}");
    assert!(!e.contains("database"), "{e}");
    assert_eq!(count("flash"), 0);
    // An unreachable database: the error is the database's, before the probe or the node.
    let gone = "postgres://accelcal@127.0.0.1:1/accelcal";
    let (code, _, e) = accelcal(&["flash", &r, "--db", gone, "--run-id", &run, "--gdb", "127.0.0.1:1"]);
    assert_eq!(code, Some(1), "{e}");
    assert!(e.contains(&format!("database {gone} cannot be reached")) && e.lines().count() == 1, "{e}");
    let unit = d.path().join("line").join("SN-1");
    let unit_s = unit.display().to_string();
    let (code, _, e) = accelcal(&[
        "station",
        "--port",
        "/dev/null",
        "--head",
        "manual",
        "--serial",
        "SN-1",
        "--out",
        &unit_s,
        "--db",
        gone,
        "--gdb",
        "127.0.0.1:1",
    ]);
    assert_eq!(code, Some(3), "{e}");
    assert!(e.contains(&format!("database {gone} cannot be reached")) && !e.contains("step"), "{e}");
    // The certificate: not of a run without its as-left verification (issue 28 item 8; the
    // whole manual line to a certificate is in tests/line.rs).
    let report = ["report", "--campaign", &c, "--record", &r, "--fit", &f, "--out", &cert, "--db", &spec];
    let mut a = report.to_vec();
    a.extend(["--run-id", &run]);
    let e = bad(&a);
    assert!(e.contains(&format!("report --db needs --verify: run {run}'s as-left verification")), "{e}");
    assert_eq!(count("certificate"), 0);
    assert!(!Path::new(&cert).exists(), "a certificate was written");
    let e = bad(&report);
    assert!(e.contains("report --db needs --run-id"), "{e}");
}

#[test]
fn serials_stay_tied_to_their_devices_and_voided_runs_leave_history() {
    let d = tempfile::tempdir().unwrap();
    labels_and_voids(&db_file(&d));
}

#[test]
fn a_row_replaced_behind_accelcal_s_back_is_named_and_never_flashed() {
    let d = tempfile::tempdir().unwrap();
    let spec = db_file(&d);
    // SQLite's REPLACE deletes without firing the delete trigger (no recursive_triggers).
    // Schema 8's insert trigger refuses the REPLACE: dropped, as someone with write access can.
    a_changed_row_breaks_the_chain(&spec, false, &|sql| {
        rusqlite::Connection::open(&spec)
            .unwrap()
            .execute_batch(&format!("DROP TRIGGER cal_record_no_replace; {sql}"))
            .unwrap()
    });
}

/// Issue 28 item 3: 16 processes opening one new database at once all get a migrated schema.
#[test]
fn sixteen_first_opens_at_once_migrate_once() {
    let d = tempfile::tempdir().unwrap();
    let spec = db_file(&d);
    // `asset add` creates the database when it is missing (void, a reader of an existing one,
    // refuses a missing file): 16 of them at once, each its own thermometer.
    let children: Vec<_> = (0..16)
        .map(|i| {
            let id = format!("PT100-{i}");
            std::process::Command::new(env!("CARGO_BIN_EXE_accelcal"))
                .args([
                    "asset",
                    "add",
                    &id,
                    "--kind",
                    "thermometer",
                    "--certificate",
                    "C-1",
                    "--due",
                    "2099-01-01",
                ])
                .args(["--db", &spec])
                .stdout(std::process::Stdio::null())
                .stderr(std::process::Stdio::piped())
                .spawn()
                .unwrap()
        })
        .collect();
    for c in children {
        let out = c.wait_with_output().unwrap();
        // Each opened the migrated database and registered its asset.
        assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
    }
    let mut db = Db::open(&spec).unwrap();
    assert_eq!(db.schema_versions().unwrap(), vec![1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12]);
    assert_eq!(db.assets().unwrap().len(), 16);
    assert!(db.verify_chain().unwrap().mismatches.is_empty());
}

/// Issue 28 items 7 and 11: a database that cannot be written stops a writer first, naming the
/// file; `history` reads it all the same (a read-only mount is the same for SQLite). Run as an
/// unprivileged user when the tests run as root (root writes through file modes).
#[test]
fn a_read_only_database_stops_writers_first_and_serves_readers() {
    use std::os::unix::fs::PermissionsExt;
    let d = tempfile::tempdir().unwrap();
    std::fs::set_permissions(d.path(), std::fs::Permissions::from_mode(0o755)).unwrap();
    let spec = db_file(&d);
    three_calibrations(&spec);
    // Checkpointed and closed: the readers find no WAL to replay.
    rusqlite::Connection::open(&spec).unwrap().execute_batch("PRAGMA wal_checkpoint(TRUNCATE);").unwrap();
    std::fs::set_permissions(&spec, std::fs::Permissions::from_mode(0o444)).unwrap();
    let as_user = |args: &[&str]| {
        let mut c = if unsafe { libc::geteuid() } == 0 {
            let mut c = std::process::Command::new("setpriv");
            c.args(["--reuid=65534", "--regid=65534", "--clear-groups", env!("CARGO_BIN_EXE_accelcal")]);
            c
        } else {
            std::process::Command::new(env!("CARGO_BIN_EXE_accelcal"))
        };
        let out = c.args(args).env_remove("ACCELCAL_DB").current_dir(d.path()).output().unwrap();
        (
            out.status.code(),
            String::from_utf8_lossy(&out.stdout).into_owned(),
            String::from_utf8_lossy(&out.stderr).into_owned(),
        )
    };
    let (code, _, err) = as_user(&["void", &RunId::new().to_string(), "--reason", "r", "--db", &spec]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains(&format!("{spec}: the database is read-only")), "{err}");
    let (code, out, err) = as_user(&["history", "SN-0042", "--db", &spec]);
    assert_eq!(code, Some(0), "{err}");
    assert!(out.contains("3 calibrations"), "{out}");
    // And from the directory that holds the station's default file, without --db.
    let default = d.path().join("calibration.sqlite");
    std::fs::copy(&spec, &default).unwrap();
    let (code, out, err) = as_user(&["history", "SN-0042"]);
    assert_eq!(code, Some(0), "{err}");
    assert!(out.contains("calibration.sqlite") && out.contains("3 calibrations"), "{out}");
}

#[test]
fn writers_racing_on_one_run_id_store_each_row_once() {
    let d = tempfile::tempdir().unwrap();
    writers_racing_on_one_run(&db_file(&d));
}

/// Two connections of one process (a station with two nodes) and other processes opening and
/// closing the file between their writes: every write stays visible (opening a database must
/// never close a descriptor of it, which would drop the first connection's locks and let the
/// last closer delete the WAL under it).
#[test]
fn two_connections_in_one_process_keep_every_write_visible() {
    let d = tempfile::tempdir().unwrap();
    let spec = db_file(&d);
    let mut a = Db::open(&spec).unwrap();
    let _b = Db::open(&spec).unwrap();
    let s = start(RunId::new(), DEVICE, "SN-5", "st-1", T0);
    a.begin_run(&s, None).unwrap();
    let (code, out, err) = accelcal(&["db", "verify", "--db", &spec]);
    assert_eq!(code, Some(0), "{out}{err}");
    a.store_fit(s.run_id, &fit_json(&coefs(0.0, 0))).unwrap();
    let (code, out, err) = accelcal(&["db", "verify", "--db", &spec]);
    assert_eq!(code, Some(0), "{err}");
    assert!(out.contains("1 run, 2 rows, 2 ledger entries"), "{out}");
}

/// Issue 57: signers decide once, and amendments take the next number and supersede.
#[test]
fn signers_decide_once_and_amendments_supersede() {
    let d = tempfile::tempdir().unwrap();
    dbkit::release::signers_decide_and_amend(&db_file(&d));
}

#[test]
fn certificate_numbers_are_unique_stable_and_never_reused() {
    let d = tempfile::tempdir().unwrap();
    certificate_numbers_are_never_reused(&db_file(&d));
}

#[test]
fn the_recalibration_date_is_stored_with_the_number_and_decisions_are_columns() {
    let d = tempfile::tempdir().unwrap();
    let spec = db_file(&d);
    recalibration_dates_and_decisions_are_stored(&spec, &mut || {
        let c = rusqlite::Connection::open(&spec).unwrap();
        let mut s = c.prepare("SELECT run_id, decision, rule FROM verification_decision").unwrap();
        s.query_map([], |r| Ok((r.get(0)?, r.get(1)?, r.get(2)?))).unwrap().map(|r| r.unwrap()).collect()
    });
}

/// SQL run the way someone with write access does it: every trigger of the schema dropped first.
fn with_triggers_dropped(spec: &str) -> impl Fn(&str) + '_ {
    move |sql: &str| {
        let c = rusqlite::Connection::open(spec).unwrap();
        let triggers: Vec<String> = c
            .prepare("SELECT name FROM sqlite_master WHERE type = 'trigger'")
            .unwrap()
            .query_map([], |r| r.get(0))
            .unwrap()
            .collect::<Result<_, _>>()
            .unwrap();
        for t in triggers {
            c.execute_batch(&format!("DROP TRIGGER {t}")).unwrap();
        }
        c.execute_batch(&format!("PRAGMA foreign_keys = OFF; {sql}")).unwrap();
    }
}

#[test]
fn laundering_is_reported_and_no_reader_writes_a_byte() {
    let d = tempfile::tempdir().unwrap();
    let spec = db_file(&d);
    tamper::laundering_is_reported_and_no_reader_writes(&spec, false, &with_triggers_dropped(&spec));
}

#[test]
fn a_cut_tail_is_found_against_an_anchor_log_and_a_certificate() {
    let d = tempfile::tempdir().unwrap();
    let spec = db_file(&d);
    tamper::a_cut_tail_is_found_against_the_anchors(&spec, &with_triggers_dropped(&spec));
}

#[test]
fn a_missing_certificate_number_is_reported() {
    let d = tempfile::tempdir().unwrap();
    let spec = db_file(&d);
    tamper::a_missing_certificate_number_is_reported(&spec, &with_triggers_dropped(&spec));
}

#[test]
fn a_forged_asset_is_refused_by_fit_and_station() {
    let d = tempfile::tempdir().unwrap();
    let spec = db_file(&d);
    tamper::a_forged_asset_is_refused(&spec, false, &with_triggers_dropped(&spec));
}

#[test]
fn derived_edits_are_found() {
    let d = tempfile::tempdir().unwrap();
    let spec = db_file(&d);
    tamper::derived_edits_are_found(&spec, &with_triggers_dropped(&spec));
}

/// Issue 55 item 3: `fleet`, `history` and serve mark a run whose rows do not match their chain.
#[test]
fn a_tampered_run_is_marked_by_fleet_history_and_serve() {
    let d = tempfile::tempdir().unwrap();
    let spec = db_file(&d);
    tamper::a_tampered_run_is_marked_where_it_is_listed(&spec, &with_triggers_dropped(&spec));
}

/// Issue 59: a head found out of tolerance traced to its units, their dismissal and
/// recalibration; a finding or a dismissal changed behind accelcal's back is caught.
#[test]
fn a_bad_head_is_traced_to_its_units_and_their_recalls() {
    let d = tempfile::tempdir().unwrap();
    let spec = db_file(&d);
    dbkit::recall::a_bad_head_is_traced_to_its_units(&spec, &with_triggers_dropped(&spec));
}

/// Issue 59 on the command line: `asset found-bad` and `affected --dismiss` refuse with one line
/// and store nothing (the file is unchanged), and `affected --csv` writes the list the recall
/// letters are written from (a snapshot; the certificate numbers' year, the year of now, written
/// `YYYY`, and the dismissal's time `NOW`).
#[test]
fn affected_writes_the_recall_list_as_csv_and_refusals_are_one_line() {
    let d = tempfile::tempdir().unwrap();
    let spec = db_file(&d);
    let mut db = Db::open(&spec).unwrap();
    dbkit::recall::recall_line(&mut db, true);
    drop(db);
    let found_bad = |extra: &[&str]| -> Vec<String> {
        let mut v: Vec<String> =
            ["asset", "found-bad", "--db", spec.as_str()].iter().map(|s| s.to_string()).collect();
        v.extend(extra.iter().map(|s| s.to_string()));
        v
    };
    let tomorrow = accelcal_db::asset::today_utc().tomorrow().unwrap().to_string();
    let before = std::fs::read(&spec).unwrap();
    for (args, code, want) in [
        (
            found_bad(&["HEAD-9", "--certificate", "C", "--since", "2026-01-05", "--reason", "worn"]),
            1,
            "error: asset `HEAD-9` is not registered in",
        ),
        (
            found_bad(&["HEAD-1", "--certificate", "DKD-99", "--since", "2026-01-05", "--reason", "worn"]),
            2,
            "error: asset `HEAD-1`: it has no certificate DKD-99 (its certificates: DKD-17-001, DKD-17-002)",
        ),
        (
            found_bad(&["HEAD-1", "--certificate", "DKD-17-001", "--since", &tomorrow, "--reason", "worn"]),
            2,
            "is after today (",
        ),
        (
            found_bad(&["HEAD-1", "--certificate", "DKD-17-001", "--since", "2026-01-05", "--reason", " "]),
            2,
            "error: --reason is empty: say what the asset's recalibration found",
        ),
        (
            ["affected", "HEAD-1", "--db", &spec].iter().map(|s| s.to_string()).collect(),
            2,
            "error: asset `HEAD-1` was not found out of tolerance in",
        ),
    ] {
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let (got, out, err) = accelcal(&args);
        assert_eq!(got, Some(code), "{args:?}: {out}{err}");
        assert!(err.contains(want) && err.lines().count() == 1 && out.is_empty(), "{args:?}: {err}");
    }
    assert_eq!(std::fs::read(&spec).unwrap(), before, "nothing stored");
    let out = ok(&found_bad(&[
        "HEAD-1",
        "--certificate",
        "DKD-17-001",
        "--since",
        "2026-01-05",
        "--reason",
        "worn bearing",
        "--operator",
        "ana",
    ])
    .iter()
    .map(String::as_str)
    .collect::<Vec<_>>());
    assert_eq!(
        out,
        format!(
            "asset: HEAD-1 (head) certificate DKD-17-001 found out of tolerance, its runs from 2026-01-05 on affected \
             (worn bearing): recorded in {spec}\naffected: 3 runs of 3 units, 2 open (`accelcal affected HEAD-1` lists \
             them)\n"
        )
    );
    let before = std::fs::read(&spec).unwrap();
    let again =
        found_bad(&["HEAD-1", "--certificate", "DKD-17-001", "--since", "2026-01-05", "--reason", "again"]);
    let e = bad(&again.iter().map(String::as_str).collect::<Vec<_>>());
    assert!(e.contains("its certificate DKD-17-001 was found out of tolerance already (recorded "), "{e}");
    let dismiss = |extra: &[&str]| -> Vec<String> {
        let mut v: Vec<String> =
            ["affected", "HEAD-1", "--db", spec.as_str()].iter().map(|s| s.to_string()).collect();
        v.extend(extra.iter().map(|s| s.to_string()));
        v
    };
    for (args, want) in [
        (dismiss(&["--dismiss", "SN-D"]), "error: affected --dismiss needs --reason TEXT"),
        (dismiss(&["--dismiss", "SN-D", "--reason", ""]), "error: --reason is empty: say why the unit needs no recall"),
        (dismiss(&["--reason", "ok"]), "error: --reason does not apply to affected without --dismiss"),
        (dismiss(&["--dismiss", "SN-D", "--reason", "ok", "--since", "2026-01-01"]), "error: --since does not apply to affected --dismiss"),
        (dismiss(&["--dismiss", "SN-A", "--reason", "ok"]), "error: asset `HEAD-1`: no run of unit SN-A is affected by its finding (certificate DKD-17-001, since 2026-01-05): nothing to dismiss"),
        (dismiss(&["--dismiss", "SN-D", "--reason", "a\u{2028}b"]), "error: --reason"),
    ] {
        let e = bad(&args.iter().map(String::as_str).collect::<Vec<_>>());
        assert!(e.contains(want), "{args:?}: {e}");
    }
    assert_eq!(std::fs::read(&spec).unwrap(), before, "nothing stored");
    let out =
        ok(&dismiss(&["--dismiss", "SN-D", "--reason", "rejected, never released", "--operator", "qa"])
            .iter()
            .map(String::as_str)
            .collect::<Vec<_>>());
    assert!(out.starts_with("affected: unit SN-D (00000000000000000000000d) dismissed from asset HEAD-1's finding under certificate DKD-17-001 (rejected, never released): recorded in "), "{out}");

    let csv = d.path().join("recall.csv");
    let out = ok(&["affected", "HEAD-1", "--db", &spec, "--csv", csv.to_str().unwrap()]);
    assert!(out.contains(": 3 runs of 3 units, 1 open") && out.contains("wrote "), "{out}");
    let year = accelcal_db::asset::today_utc().year();
    let text = std::fs::read_to_string(&csv).unwrap();
    // The dismissal's time, the last cell of its row, is now.
    let today = accelcal_db::asset::today_utc().to_string();
    let text: String = text
        .lines()
        .map(|l| match l.rfind(',') {
            Some(at) if l[at..].contains(&today) => format!("{},\"NOW\"\n", &l[..at]),
            _ => format!("{l}\n"),
        })
        .collect();
    insta::assert_snapshot!("affected_csv", text.replace(&format!("\"{year}-0000"), "\"YYYY-0000"));
    // With --since: every run on the head from that day, those the finding covers marked.
    let out = ok(&["affected", "HEAD-1", "--since", "2026-01-01", "--db", &spec]);
    assert!(
        out.contains(&format!("affected: asset HEAD-1 since 2026-01-01 (UTC) in {spec}: 6 runs of 6 units")),
        "{out}"
    );
    let r = db_verify(&spec);
    assert!(r.contains("every row matches its hash chain"), "{r}");
}

/// `db verify`'s output.
fn db_verify(spec: &str) -> String {
    ok(&["db", "verify", "--db", spec])
}

/// A cell that does not read as its type is named by table, row and column: every such cell in
/// `db verify`; `history`, `fleet` and serve's pages list every other run and name the run that
/// does not read by its bad cell.
#[test]
fn a_bad_cell_is_named() {
    let d = tempfile::tempdir().unwrap();
    let spec = db_file(&d);
    let mut db = Db::open(&spec).unwrap();
    let run = calibrate(&mut db, &start(RunId::new(), DEVICE, "SN-1", "st-1", T0), &coefs(0.0, 0), None);
    let again =
        calibrate(&mut db, &start(RunId::new(), DEVICE, "SN-1", "st-1", T0 + 3 * DAY), &coefs(0.0, 2), None);
    let other =
        calibrate(&mut db, &start(RunId::new(), DEVICE_2, "SN-2", "st-1", T0 + 5), &coefs(0.0, 1), None);
    drop(db);
    with_triggers_dropped(&spec)(&format!("UPDATE run SET g_m_s2 = 'abc' WHERE run_id = '{run}'"));
    let cell = format!(
        "table run, row run_id = '{run}', column g_m_s2: declared DOUBLE PRECISION, holds text 'abc'"
    );
    let (code, out, err) = accelcal(&["db", "verify", "--db", &spec]);
    assert_eq!(code, Some(1), "{out}{err}");
    assert!(out.contains(&format!("bad cell: {cell}")), "{out}");
    // history: the unit's other run listed, the bad one named.
    let d2 = tempfile::tempdir().unwrap();
    let json = d2.path().join("h.json");
    let (code, out, err) = accelcal(&["history", "SN-1", "--db", &spec, "--json", json.to_str().unwrap()]);
    assert_eq!(code, Some(0), "{out}{err}");
    assert!(
        out.contains("1 run, 1 calibration") && out.contains("(and 1 run that do not read, below)"),
        "{out}"
    );
    assert!(
        out.contains(&format!("UNREADABLE, not used: run {run} does not read: bad cell: {cell}")),
        "{out}"
    );
    let h: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert_eq!(h["runs"][0]["run_id"], again.to_string(), "{h}");
    assert_eq!(h["unreadable"][0]["run_id"], run.to_string(), "{h}");
    assert_eq!(h["unreadable"][0]["bad_cells"][0]["column"], "g_m_s2", "{h}");
    let (code, out, err) = accelcal(&["history", "SN-2", "--db", &spec]);
    assert_eq!(code, Some(0), "the other unit reads: {out}{err}");
    assert!(!out.contains("UNREADABLE"), "{out}");
    // fleet: every other run in its table and JSON, the bad one named.
    let json = d2.path().join("f.json");
    let (code, out, err) = accelcal(&[
        "fleet",
        "--since",
        "2025-12-01",
        "--until",
        "2026-02-01",
        "--db",
        &spec,
        "--json",
        json.to_str().unwrap(),
    ]);
    assert_eq!(code, Some(0), "{out}{err}");
    assert!(
        out.contains(&format!(
            "UNREADABLE, left out of whatever reads its bad cells (counted): run {run} does not read: bad cell: {cell}"
        )),
        "{out}"
    );
    let f: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let ids: Vec<&str> =
        f["runs"].as_array().unwrap().iter().map(|r| r["run_id"].as_str().unwrap()).collect();
    assert_eq!(ids, [other.to_string(), again.to_string()], "{f}");
    assert_eq!(f["unreadable_runs"][0]["run_id"], run.to_string(), "{f}");
    assert_eq!(f["unreadable_runs"][0]["bad_cells"][0]["table"], "run", "{f}");
    assert_eq!(f["unreadable_runs"][0]["bad_cells"][0]["column"], "g_m_s2", "{f}");
    // serve: the overview, the fleet's table and the unit's page answer, list the other runs and
    // name the bad cell.
    let pages = dbkit::serve::statuses(
        &spec,
        &[
            "/fleet?since=2025-12-01&until=2026-02-01",
            "/charts?since=2025-12-01&until=2026-02-01",
            "/unit/SN-1",
            "/",
        ],
    );
    assert_eq!(pages[3].0, 200, "the overview (today's runs: none of these): {}", pages[3].1);
    for (i, (status, body)) in pages[..3].iter().enumerate() {
        assert_eq!(*status, 200, "page {i}: {body}");
        assert!(
            body.contains("id=\"unreadable\"")
                && body.contains(&run.to_string())
                && body.contains("column g_m_s2"),
            "page {i} names the bad cell: {body}"
        );
    }
    assert!(pages[0].1.contains("/unit/SN-2") && pages[0].1.contains("/unit/SN-1"), "{}", pages[0].1);
    assert_eq!(pages[2].1.matches("<tr id=\"run-").count(), 1, "the unit's other run: {}", pages[2].1);
}

/// A reader never migrates: an older schema tells it which command does, and `db migrate` does.
#[test]
fn readers_never_migrate_and_db_migrate_does() {
    let d = tempfile::tempdir().unwrap();
    let spec = db_file(&d);
    let mut db = Db::open(&spec).unwrap();
    calibrate(&mut db, &start(RunId::new(), DEVICE, "SN-1", "st-1", T0), &coefs(0.0, 0), None);
    drop(db);
    // Back to schema 7, as a database of the last release is.
    with_triggers_dropped(&spec)(
        "ALTER TABLE asset DROP COLUMN value_si; ALTER TABLE asset DROP COLUMN value_u_si; \
         DROP TABLE recall_dismissal; DROP TABLE asset_found_bad; DROP TABLE amendment; DROP TABLE approval; \
         DROP TABLE signer_revocation; DROP TABLE signer; DROP TABLE chain_event; \
         DELETE FROM refinery_schema_history WHERE version >= 8",
    );
    let before = std::fs::read(&spec).unwrap();
    let (code, _, err) = accelcal(&["history", "SN-1", "--db", &spec]);
    assert_eq!(code, Some(1), "{err}");
    assert!(
        err.contains("at schema version 7, this build reads version 12: run `accelcal db migrate --db"),
        "{err}"
    );
    assert_eq!(std::fs::read(&spec).unwrap(), before, "the reader wrote nothing");
    let (code, out, err) = accelcal(&["db", "migrate", "--db", &spec]);
    assert_eq!(code, Some(0), "{out}{err}");
    assert!(out.contains("is at schema version 12"), "{out}");
    let (code, out, err) = accelcal(&["history", "SN-1", "--db", &spec]);
    assert_eq!(code, Some(0), "{out}{err}");
}

/// SQL on the SQLite file as it is (the migration history has no trigger to drop).
fn plain(spec: &str, sql: &str) {
    rusqlite::Connection::open(spec).unwrap().execute_batch(sql).unwrap();
}

/// Issue 55: a damaged migration history (its newest row deleted, a cell edited) stops every
/// command with one line that names the table and what to do, and readers still write nothing;
/// `db migrate` records it again when the schema is exactly that of one of this build's
/// versions, and says to restore a backup when it is none's.
#[test]
fn a_damaged_migration_history_is_named_and_db_migrate_records_it_again() {
    let d = tempfile::tempdir().unwrap();
    let spec = db_file(&d);
    let mut db = Db::open(&spec).unwrap();
    calibrate(&mut db, &start(RunId::new(), DEVICE, "SN-1", "st-1", T0), &coefs(0.0, 0), None);
    drop(db);
    let latest = accelcal_db::schema_version();
    let table = "its migration history (table refinery_schema_history) is damaged: ";
    let cases = [
        (
            "DELETE FROM refinery_schema_history WHERE version = (SELECT MAX(version) FROM refinery_schema_history)"
                .to_string(),
            format!(
                "it records schema version {}, and the schema is that of version {latest}: the rows of the versions after {} were removed",
                latest - 1,
                latest - 1
            ),
        ),
        (
            "UPDATE refinery_schema_history SET applied_on = 'abc' WHERE version = 3".to_string(),
            "the row of version 3: its applied_on is 'abc', not a time".to_string(),
        ),
        (
            "UPDATE refinery_schema_history SET checksum = '1' WHERE version = 5".to_string(),
            "the row of version 5: its checksum is '1', not ".to_string(),
        ),
        (
            "DELETE FROM refinery_schema_history WHERE version = 2".to_string(),
            "version 2 is missing from it, and version 3 is recorded".to_string(),
        ),
    ];
    for (sql, what) in &cases {
        plain(&spec, sql);
        let before = std::fs::read(&spec).unwrap();
        for args in [
            vec!["history", "SN-1"],
            vec!["fleet", "--since", "2025-12-01", "--until", "2026-02-01"],
            vec!["db", "verify"],
        ] {
            let mut args = args.clone();
            args.extend(["--db", &spec]);
            let (code, out, err) = accelcal(&args);
            assert_eq!(code, Some(1), "{args:?}: {out}{err}");
            assert!(err.contains(table) && err.contains(what.as_str()), "{args:?}: {err}");
            assert!(err.contains(&format!("run `accelcal db migrate --db {spec}` once")), "{err}");
            assert_eq!(err.trim_end().lines().count(), 1, "one line: {err}");
        }
        assert_eq!(std::fs::read(&spec).unwrap(), before, "no reader wrote ({sql})");
        let e = Db::open(&spec).err().expect("a writer refuses the database");
        assert!(e.to_string().contains(what.as_str()), "{e}");
        let (code, out, err) = accelcal(&["db", "migrate", "--db", &spec]);
        assert_eq!(code, Some(0), "{sql}: {out}{err}");
        assert!(
            out.contains(&format!(
                "recorded again as versions 1 to {latest}, the schema being exactly that of version {latest}"
            )),
            "{out}"
        );
        let (code, out, err) = accelcal(&["history", "SN-1", "--db", &spec]);
        assert_eq!(code, Some(0), "read again after db migrate: {out}{err}");
    }
    // A schema that is no version's cannot be recorded again: a backup restores it.
    plain(&spec, "UPDATE refinery_schema_history SET name = 'x' WHERE version = 4; CREATE TABLE extra (x)");
    let (code, out, err) = accelcal(&["db", "migrate", "--db", &spec]);
    assert_eq!(code, Some(1), "{out}{err}");
    assert!(
        err.contains(table)
            && err.contains("its name is 'x', not `")
            && err.contains(
                "the schema is that of none of this build's versions: restore the database from a backup"
            ),
        "{err}"
    );
}
