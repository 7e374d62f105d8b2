//! Issue 55 item 7: output that cannot be written (a full disk, `/dev/full`) ends a command with
//! `error:` and the environment's exit code, never a panic; a run begun in the database is
//! completed even when its progress lines cannot be written.

use std::process::{Command, Output, Stdio};

fn full() -> Stdio {
    std::fs::OpenOptions::new().write(true).open("/dev/full").expect("/dev/full opens").into()
}

/// Runs the binary with its standard output on `/dev/full`.
fn stdout_full(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_accelcal")).args(args).stdout(full()).output().expect("the binary runs")
}

#[test]
fn a_full_standard_output_ends_with_an_error_and_exit_code_1_not_a_panic() {
    let d = tempfile::tempdir().unwrap();
    let p = |n: &str| d.path().join(n).display().to_string();
    let campaign = p("c.csv");
    let demo = p("demo");
    let cases: [&[&str]; 3] = [
        &["plan", "--plan", "six"],
        &["simulate", "--seed", "3", "--samples", "5", "-o", &campaign],
        &["demo", "--out", &demo],
    ];
    for args in cases {
        let out = stdout_full(args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{args:?}: {err}");
        assert!(!err.contains("panicked"), "{args:?}: {err}");
        let last = err.trim_end().lines().last().unwrap_or_default();
        assert!(last.starts_with("error: writing to standard output: "), "{args:?}: {err}");
        assert!(last.contains("No space left on device"), "{args:?}: {err}");
    }
}

/// `fit --db 2>/dev/full`: the run's progress line ("db: run … begun") cannot be written, the
/// run is still completed with every piece, and the exit code says stderr failed.
#[test]
fn a_full_standard_error_does_not_leave_a_begun_run_without_its_pieces() {
    let d = tempfile::tempdir().unwrap();
    let p = |n: &str| d.path().join(n).display().to_string();
    let (c, r, db) = (p("c.csv"), p("r.rec"), p("cal.sqlite"));
    crate::common::ok(&["simulate", "--seed", "7", "--samples", "20", "-o", &c]);
    let out = Command::new(env!("CARGO_BIN_EXE_accelcal"))
        .args(["fit", &c, "--record", &r, "--device-id", "0123456789abcdef01234567", "--db", &db])
        .stderr(full())
        .output()
        .expect("the binary runs");
    assert_eq!(out.status.code(), Some(1));
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(stdout.contains("campaign, fit and record stored in"), "{stdout}");
    let conn = rusqlite::Connection::open(&db).unwrap();
    let count = |table: &str| -> i64 {
        conn.query_row(&format!("SELECT count(*) FROM {table}"), [], |row| row.get(0)).unwrap()
    };
    for table in ["run", "campaign", "fit", "cal_record"] {
        assert_eq!(count(table), 1, "{table}");
    }
}
