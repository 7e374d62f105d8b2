//! `accelcal-core`: the calibration core of accelcal, free of any user interface.
//!
//! Campaign files and recordings ([`campaign`], [`reduce`], [`gravity::imutk`]), the rig
//! simulator ([`sim`]), combinatorial GMDH structure selection ([`gmdh`]), least-squares and
//! test-turn fits and the calibration record ([`lsq`], [`testturn`], [`calibrate`]), the
//! comparison of the two methods ([`compare`]), gravity-norm calibration ([`gravity`]), the
//! sim-to-real diagnosis ([`diagnose`]), the host side of the sensor node ([`node`]) and the
//! emulated bench that feeds the QEMU node ([`emulate`]).
//!
//! Nothing here parses a command line, prints, draws or shows progress: the `accelcal` binary
//! does that. Errors say themselves whether they are the user's input to fix ([`exit`]).

// `!(x > t)` is deliberate: a NaN must fail every range check. Index loops mirror the math.
#![allow(clippy::neg_cmp_op_on_partial_ord, clippy::needless_range_loop)]
pub mod acquire;
pub mod calibrate;
pub mod campaign;
pub mod compare;
pub mod db;
pub mod diagnose;
pub mod effects;
pub mod emulate;
pub mod error;
pub mod exit;
pub mod gmdh;
pub mod gravity;
pub mod input;
pub mod lsq;
pub mod node;
pub mod output;
pub mod positions;
pub mod reduce;
pub mod sim;
pub mod station;
pub mod testturn;
pub mod text;
pub mod verify;
