//! `accelcal`: production calibration of analog MEMS accelerometer blocks on a dividing head.
//!
//! The library behind the `accelcal` binary: campaign files, the rig simulator, combinatorial GMDH
//! structure selection, least-squares and test-turn fits, the comparison of the two methods, plots,
//! and one module per subcommand under [`cmd`].

// `!(x > t)` is deliberate: a NaN must fail every range check. Index loops mirror the math.
#![allow(clippy::neg_cmp_op_on_partial_ord, clippy::needless_range_loop)]
pub mod campaign;
pub mod cli;
pub mod cmd;
pub mod compare;
pub mod diagnose;
pub mod error;
pub mod gmdh;
pub mod gravity;
pub mod lsq;
pub mod node;
pub mod output;
pub mod plot;
pub mod positions;
pub mod reduce;
pub mod sim;
pub mod testturn;
