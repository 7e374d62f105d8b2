//! The station's command line on an emulated bench, spelled once: the line tests (`tests/line.rs`,
//! `tests/line/multi.rs` and the areas that start from `station_args`) and `cargo xtask bench
//! station` run the same station. xtask does not depend on the test crate, so it includes this
//! file with `#[path]`; it names nothing but `std`.

/// What every emulated station run gives besides its head and its units.
pub const SETTINGS: [&str; 12] = [
    "--plan",
    "random:24",
    "--samples",
    "200",
    "--rate-hz",
    "1000",
    "--g",
    "9.81",
    // The criterion of 24 positions of 200 noisy sets scatters by a few codes: a linear unit
    // must not be rejected for it.
    "--select-tolerance",
    "5",
    // The verifications at K = 5, as `verify_args` says why: a station runs one or two, and the
    // tests run a dozen stations that must pass (at K = 4 one CI run in about 40 would fail a
    // good unit; one did, an as-left 1 of 6 positions out).
    "--coverage",
    "5",
];

/// One unit of a station: its node's link and gdbstub, its serial and its directory.
pub struct Unit<'a> {
    pub port: &'a str,
    pub gdb: &'a str,
    pub serial: &'a str,
    pub out: &'a str,
}

/// `accelcal station` (without the program's name) on the head `head`: each unit's `--port`,
/// `--gdb`, `--serial` and `--out` in turn, then [`SETTINGS`].
pub fn station_line<'a>(head: &'a str, units: &[Unit<'a>]) -> Vec<&'a str> {
    let mut v = vec!["station", "--head", head];
    for u in units {
        v.extend_from_slice(&["--port", u.port, "--gdb", u.gdb, "--serial", u.serial, "--out", u.out]);
    }
    v.extend_from_slice(&SETTINGS);
    v
}
