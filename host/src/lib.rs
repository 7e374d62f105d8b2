//! `accelcal`: production calibration of analog MEMS accelerometer blocks on a dividing head.
//!
//! The library behind the `accelcal` binary: campaign files, the rig simulator, combinatorial GMDH
//! structure selection, least-squares and test-turn fits, the comparison of the two methods, plots,
//! and one module per subcommand under [`cmd`].

pub mod campaign;
pub mod cli;
pub mod cmd;
pub mod compare;
pub mod error;
pub mod gmdh;
pub mod gravity;
pub mod lsq;
pub mod output;
pub mod plot;
pub mod positions;
pub mod sim;
pub mod testturn;
