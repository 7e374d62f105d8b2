//! The integration tests, one test binary (`cargo nextest run -p accelcal --test tests`): one
//! link of the workspace instead of one per area, and the shared helpers compiled once. Each
//! module is an area; nextest names a test by its path (`line::station::...`), so an area runs
//! alone with a filter on that path (`cargo nextest run -E 'test(/^line::/)'`). They use the
//! libraries and run the binary (`CARGO_BIN_EXE_accelcal`).

// Helpers shared by the areas.
mod common;
mod dbkit;
mod support;

/// Bad input of every kind: one line, exit code 2, nothing written.
mod bad_input;
/// The calibration core and the GMDH engine on simulated data.
mod calibration;
/// The binary end to end.
mod cli;
/// Signed and unsigned codes.
mod codes;
/// The calibration database (SQLite): runs, assets, the fleet, `serve`.
mod db;
/// The same on PostgreSQL (throwaway clusters).
mod db_pg;
/// `diagnose`: each effect found, clean campaigns clean.
mod diagnose;
/// The README's and the guide's examples against the binary.
mod docs;
/// Gravity-norm on simulation and on the real recording.
mod gravity;
/// The node's QEMU build in the loop.
mod hil;
/// 100,000 sample sets through the QEMU node.
mod hil_load;
/// The production line in emulation.
mod line;
/// The live path: the node in QEMU fed by a paced front end.
mod live;
/// Temperature compensation.
mod thermal;
