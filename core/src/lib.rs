//! `accelcal-core`: the calibration library of accelcal, free of any user interface and of any
//! device.
//!
//! Campaign files and recordings ([`campaign`], [`reduce`], [`gravity::imutk`]), the rig
//! simulator ([`sim`]), combinatorial GMDH structure selection ([`gmdh`]), least-squares and
//! test-turn fits and the calibration record ([`lsq`], [`testturn`], [`calibrate`]), the
//! comparison of the two methods ([`compare`]), gravity-norm calibration ([`gravity`]) and the
//! sim-to-real diagnosis ([`diagnose`]).
//!
//! Nothing here opens a serial port, starts a process, touches a database, parses a command line,
//! prints, draws or shows progress: the line (`accelcal-line`), the database (`accelcal-db`) and
//! the `accelcal` binary do. Cargo holds that rule: this crate depends on none of them, nor on
//! probe-rs, serialport or a database client. Errors say themselves what they are ([`error`]:
//! the user's input to fix, the environment, a rejected unit); the binary maps that to exit codes.

// `!(x > t)` is deliberate: a NaN must fail every range check. Index loops mirror the math.
#![allow(clippy::neg_cmp_op_on_partial_ord, clippy::needless_range_loop)]
pub mod calibrate;
pub mod campaign;
pub mod certificate;
pub mod compare;
pub mod conformity;
pub mod design;
pub mod diagnose;
pub mod digest;
pub mod document;
pub mod effects;
pub mod error;
pub mod gmdh;
pub mod gravity;
pub mod headsig;
pub mod ieee1293;
pub mod input;
pub mod lsq;
pub mod output;
pub mod positions;
pub mod reduce;
pub mod sim;
pub mod spc;
pub mod testturn;
pub mod text;
pub mod uncertainty;
