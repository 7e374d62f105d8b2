//! Issue 28: the line's records survive every crash and every mistake. The station is killed
//! (SIGKILL to its process group, as a power cut stops it) at each boundary between its journal
//! and the database, one after the other, and run again each time: the unit finishes, the
//! database holds each piece once and the node runs the stored record, on SQLite and PostgreSQL.
//! The manual line ends its run as the station does; a mislabelled unit is refused; a replaced
//! record is said plainly.

use super::*;

/// The kill points in the order one station run passes them (`store::crash_point` in the
/// binary): each journal write after a step, and each store into the database (`db:flash` is in
/// the flash step's process, `db:certificate` and `db:end-report` in the report step's). The
/// last three are [`TAIL`] on SQLite; on PostgreSQL the report step is killed after it ended
/// the run ([`TAIL_REPORT_ENDED`]), which the station must then journal.
const POINTS: [&str; 16] = [
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
    "db:certificate-number",
];

/// The end of a line killed after the certificate was stored, after the station journalled it,
/// and after the station ended the run; the last run: none.
const TAIL: [&str; 4] = ["db:certificate", "journal:certificate", "db:end", ""];

/// The end of a line whose report step is killed after it stored the certificate and ended the
/// run, before the station journalled the step.
const TAIL_REPORT_ENDED: [&str; 2] = ["db:end-report", ""];

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
const TABLES: [(&str, i64); 11] = [
    ("run", 1),
    ("campaign", 1),
    ("fit", 1),
    ("cal_record", 1),
    ("flash", 1),
    ("verification", 2),
    ("certificate_number", 1),
    ("recalibration_due", 1),
    ("certificate", 1),
    ("run_end", 1),
    ("ledger", 11),
];

/// A first unit's whole line, then a second unit on the same node (a record in force, so its
/// as-found verification runs) killed at every point in turn.
fn killed_at_every_boundary(db: &str, tail: &[&str], count: &dyn Fn(&str, &str) -> i64) {
    let _one = one_bench();
    let dir = tempfile::tempdir().unwrap();
    let (truth, _) = unit(dir.path(), "u", 23, 10);
    let em = Emulator::start(&truth, &[]);
    let a = dir.path().join("unit-a");
    succeed(&station_args(&em, "K-1", &a, &["--db", db]));
    let b = dir.path().join("unit-b");
    let args = station_args(&em, "K-2", &b, &["--db", db, "--relabel", "node reused for K-2"]);
    for &point in POINTS.iter().chain(tail) {
        let (code, err) = station_crashing_at(&args, point);
        if point.is_empty() {
            assert_eq!(code, Some(0), "the run after every kill: {err}");
        } else {
            assert_eq!(
                code, None,
                "not killed at {point} (the point was passed before, or never reached): {err}"
            );
            assert!(err.contains(&format!("crash point {point}: killed")), "{point}: {err}");
        }
        // The record in force is the one this run or the last flashed: never a false alarm.
        assert!(!err.contains("no longer runs"), "{point}: {err}");
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
    killed_at_every_boundary(&db, &TAIL, &count);
}

#[test]
fn a_station_killed_at_every_boundary_finishes_on_postgresql() {
    let pg = dbkit::Cluster::start();
    let url = pg.url.clone();
    let count = |table: &str, run: &str| -> i64 {
        let mut c = postgres::Client::connect(&url, postgres::NoTls).unwrap();
        c.query_one(&format!("SELECT count(*) FROM {table} WHERE run_id = $1"), &[&run]).unwrap().get(0)
    };
    killed_at_every_boundary(&pg.url, &TAIL_REPORT_ENDED, &count);
}

/// The run id a command printed (`db: run <uuid> begun in ...`).
fn run_id_in(err: &str) -> String {
    let at = err.find("db: run ").expect("a run line") + "db: run ".len();
    err[at..at + 36].to_string()
}

/// Issue 28 items 5, 6 and 8 on one bench:
/// - the manual line (`fit --db`, `flash --db`, `verify --phase as-left --db`, `report --db`)
///   ends its run `pass` as the station does, and `report` certifies nothing before the as-left
///   verification is stored;
/// - a station given another unit's serial on this node is refused before a run begins, and
///   `void` takes a run out of history;
/// - a node whose record was replaced since its certificate is said so, naming both CRCs, by
///   the station in the unit's finished directory and at the next unit's as-found.
#[test]
fn the_manual_line_ends_its_run_and_mistakes_are_said_plainly() {
    let _one = one_bench();
    let dir = tempfile::tempdir().unwrap();
    let p = |n: &str| dir.path().join(n);
    let db = p("line.sqlite").display().to_string();
    let (truth, _) = unit(dir.path(), "u", 29, 10);
    let em = Emulator::start(&truth, &[]);
    let device = "51454d552d422d4c34373545";
    // The manual line of unit M-1.
    let campaign = p("m.csv");
    succeed(&acquire_args(&em, "random:24", "200", &campaign, &["--rate-hz", "1000", "--serial", "M-1"]));
    let (rec, fit) = (p("m.rec"), p("m.json"));
    let out = accelcal(&[
        "fit",
        s(&campaign),
        "--record",
        s(&rec),
        "--json",
        s(&fit),
        "--device-id",
        device,
        "--db",
        &db,
    ]);
    assert_eq!(out.status.code(), Some(0), "{out:?}");
    let run = run_id_in(&String::from_utf8_lossy(&out.stderr));
    succeed(&["flash", s(&rec), "--db", &db, "--run-id", &run, "--gdb", &em.gdb, "--port", &em.port]);
    let cert = p("m.html");
    let report = [
        "report",
        "--campaign",
        s(&campaign),
        "--record",
        s(&rec),
        "--fit",
        s(&fit),
        "--out",
        s(&cert),
        "--db",
        &db,
        "--run-id",
        &run,
    ];
    // A verification that is not the stored as-left one: nothing certified.
    let as_left = p("m-left.json");
    succeed(&verify_args(&em, &fit, &as_left, &[]));
    let mut early = report.to_vec();
    early.extend(["--verify", s(&as_left)]);
    let e = common::bad(&early);
    assert!(e.contains(&format!("run {run} holds no as-left verification")), "{e}");
    assert!(!cert.exists());
    succeed(&verify_args(&em, &fit, &as_left, &["--db", &db, "--run-id", &run, "--phase", "as-left"]));
    let out = succeed(&early);
    assert!(String::from_utf8_lossy(&out.stdout).contains("the run ended pass"), "{out:?}");
    let h = String::from_utf8_lossy(&succeed(&["history", "M-1", "--db", &db]).stdout).to_string();
    assert!(h.contains("1 run, 1 calibration") && !h.contains("unfinished"), "{h}");
    let crc_m = json(&fit)["record_crc"].as_str().unwrap().to_string();

    // The station with another unit's serial on this node (device of M-1): refused, no run.
    let w = p("unit-w");
    let out = accelcal(&station_args(&em, "W-9", &w, &["--db", &db]));
    let e = String::from_utf8_lossy(&out.stderr).to_string();
    assert_eq!(out.status.code(), Some(2), "{e}");
    assert!(
        e.contains(&format!("device {device} is unit M-1 in the database")) && e.contains("--relabel"),
        "{e}"
    );
    let h = String::from_utf8_lossy(&succeed(&["history", device, "--db", &db]).stdout).to_string();
    assert!(h.contains("1 run,"), "a run was begun: {h}");

    // Unit M-1's line at the station (a relabel-free recalibration), then another record
    // flashed by hand: the finished directory says the node no longer runs its certificate's.
    let a = p("unit-m");
    succeed(&station_args(&em, "M-1", &a, &["--db", &db]));
    let crc_a = json(&a.join("fit.json"))["record_crc"].as_str().unwrap().to_string();
    succeed(&["flash", s(&rec), "--gdb", &em.gdb, "--port", &em.port]);
    let out = accelcal(&station_args(&em, "M-1", &a, &["--db", &db]));
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(
        err.contains(&format!("the node no longer runs its certified record: it runs record CRC {crc_m}"))
            && err.contains(&format!("certified record CRC {crc_a}")),
        "{err}"
    );
    // A new unit's line on that node: its as-found says so too, before anything changes.
    let b = p("unit-m2");
    let mut child = Command::new(env!("CARGO_BIN_EXE_accelcal"))
        .args(station_args(&em, "M-1", &b, &["--db", &db]))
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut lines = BufReader::new(child.stderr.take().unwrap()).lines();
    let warned =
        lines.by_ref().map_while(Result::ok).find(|l| l.contains("WARNING") || l.contains("step 3/8"));
    let _ = child.kill();
    let _ = child.wait();
    let warned = warned.unwrap_or_default();
    assert!(
        warned.contains(&format!("the node no longer runs its certified record: it runs record CRC {crc_m}"))
            && warned.contains(&format!("flashed record CRC {crc_a}")),
        "{warned}"
    );

    // Void the manual run: history lists it voided and counts one calibration.
    let out = succeed(&["void", &run, "--reason", "made on the manual line by mistake", "--db", &db]);
    assert!(String::from_utf8_lossy(&out.stdout).contains(&format!("void: run {run} of device {device}")));
    let h = String::from_utf8_lossy(&succeed(&["history", device, "--db", &db]).stdout).to_string();
    assert!(h.contains("voided") && h.contains("made on the manual line by mistake"), "{h}");
    assert!(h.contains(", 1 calibration"), "{h}");
    em.stop();
}
