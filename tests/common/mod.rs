//! Running the `accelcal` binary from the integration tests: one definition of what success and
//! bad input look like from outside (exit code, one line, no panic). Each test binary includes
//! this with `mod common;` and uses what it needs.
#![allow(dead_code)]

use std::process::{Command, Output};

/// Runs the binary.
pub fn accelcal(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_accelcal")).args(args).output().expect("the binary runs")
}

/// Runs a command that must succeed; returns its output.
pub fn succeed(args: &[&str]) -> Output {
    let out = accelcal(args);
    assert!(
        out.status.success(),
        "accelcal {args:?} failed: {}\n{}",
        String::from_utf8_lossy(&out.stderr),
        String::from_utf8_lossy(&out.stdout)
    );
    out
}

/// Runs a command that must succeed; returns its stdout.
pub fn ok(args: &[&str]) -> String {
    String::from_utf8_lossy(&succeed(args).stdout).into_owned()
}

/// Runs a command that must fail with exit code 2 and a single-line error, without a panic;
/// returns that line.
pub fn bad(args: &[&str]) -> String {
    let out = accelcal(args);
    let err = String::from_utf8_lossy(&out.stderr).to_string();
    assert_eq!(out.status.code(), Some(2), "accelcal {args:?}: {err}");
    assert_eq!(err.trim_end().lines().count(), 1, "one line expected from {args:?}: {err}");
    assert!(!err.contains("panicked"), "{err}");
    err.trim_end().to_string()
}
