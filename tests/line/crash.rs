//! Issue 28: the line's records survive every crash and every mistake. The station is killed
//! (SIGKILL to its process group, as a power cut stops it) at each boundary between its journal
//! and the database, one after the other, and run again each time: the unit finishes, the
//! database holds each piece once and the node runs the stored record, on SQLite and PostgreSQL.
//! The manual line ends its run as the station does; a mislabelled unit is refused; a replaced
//! record is said plainly.

use super::*;

/// The kill points in the order one station run passes them (`store::crash_point` in the
/// binary): each journal write after a step, and each store into the database (`db:flash` is in
/// the flash step's process, `db:certificate` in the report step's).
const POINTS: [&str; 19] = [
    "journal:info",
    "journal:run",
    "db:run",
    "journal:as-found",
    "db:as-found",
    "journal:acquire",
    "db:campaign",
    "journal:select",
    "journal:fit",
    "db:fit",
    "db:record",
    "db:flash",
    "journal:flash",
    "journal:as-left",
    "db:as-left",
    "db:certificate",
    "journal:certificate",
    "db:end",
    // The last run: none.
    "",
];

/// Runs the station with `ACCELCAL_CRASH_AT=point` in its own process group; its exit code
/// (`None`: killed) and stderr.
fn station_crashing_at(args: &[&str], point: &str) -> (Option<i32>, String) {
    use std::os::unix::process::CommandExt;
    let out = Command::new(env!("CARGO_BIN_EXE_accelcal"))
        .args(args)
        .env("ACCELCAL_CRASH_AT", point)
        .env_remove("ACCELCAL_DB")
        .process_group(0)
        .stdin(Stdio::null())
        .output()
        .unwrap();
    (out.status.code(), String::from_utf8_lossy(&out.stderr).into_owned())
}

/// The rows of each table of run `run`, through `count(table, run)`.
const TABLES: [(&str, i64); 9] = [
    ("run", 1),
    ("campaign", 1),
    ("fit", 1),
    ("cal_record", 1),
    ("flash", 1),
    ("verification", 2),
    ("certificate", 1),
    ("run_end", 1),
    ("ledger", 9),
];

/// A first unit's whole line, then a second unit on the same node (a record in force, so its
/// as-found verification runs) killed at every point in turn.
fn killed_at_every_boundary(db: &str, count: &dyn Fn(&str, &str) -> i64) {
    let _one = one_bench();
    let dir = tempfile::tempdir().unwrap();
    let (truth, _) = unit(dir.path(), "u", 23, 10);
    let em = Emulator::start(&truth, &[]);
    let a = dir.path().join("unit-a");
    succeed(&station_args(&em, "K-1", &a, &["--db", db]));
    let b = dir.path().join("unit-b");
    let args = station_args(&em, "K-2", &b, &["--db", db, "--relabel", "node reused for K-2"]);
    for point in POINTS {
        let (code, err) = station_crashing_at(&args, point);
        if point.is_empty() {
            assert_eq!(code, Some(0), "the run after every kill: {err}");
        } else {
            assert_eq!(code, None, "not killed at {point} (the point was passed before, or never reached): {err}");
            assert!(err.contains(&format!("crash point {point}: killed")), "{point}: {err}");
        }
    }
    // Once more: finished before, nothing to do.
    let out = succeed(&args);
    assert!(String::from_utf8_lossy(&out.stdout).contains("PASS, finished before"), "{out:?}");
    let run = json(&b.join("station.json"))["run_id"].as_str().unwrap().to_string();
    for (table, n) in TABLES {
        assert_eq!(count(table, &run), n, "{table} of run {run}");
    }
    // One run per unit: no orphan.
    let h = String::from_utf8_lossy(&succeed(&["history", "51454d552d422d4c34373545", "--db", db]).stdout)
        .to_string();
    assert!(h.contains("2 runs, 2 calibrations") && !h.contains("unfinished"), "{h}");
    let v = succeed(&["db", "verify", "--db", db]);
    assert!(String::from_utf8_lossy(&v.stdout).contains("every row matches"), "{v:?}");
    // The node runs the record the run stored.
    let crc = json(&b.join("fit.json"))["record_crc"].as_str().unwrap().to_string();
    assert_runs_record(&em, &dir.path().join("info.json"), &crc);
    em.stop();
}

#[test]
fn a_station_killed_at_every_boundary_finishes_on_sqlite() {
    let d = tempfile::tempdir().unwrap();
    let db = d.path().join("line.sqlite").display().to_string();
    let count = |table: &str, run: &str| -> i64 {
        let c = rusqlite::Connection::open(&db).unwrap();
        c.query_row(&format!("SELECT count(*) FROM {table} WHERE run_id = ?1"), [run], |r| r.get(0)).unwrap()
    };
    killed_at_every_boundary(&db, &count);
}

#[test]
fn a_station_killed_at_every_boundary_finishes_on_postgresql() {
    let pg = dbkit::Cluster::start();
    let url = pg.url.clone();
    let count = |table: &str, run: &str| -> i64 {
        let mut c = postgres::Client::connect(&url, postgres::NoTls).unwrap();
        c.query_one(&format!("SELECT count(*) FROM {table} WHERE run_id = $1"), &[&run]).unwrap().get(0)
    };
    killed_at_every_boundary(&pg.url, &count);
}
