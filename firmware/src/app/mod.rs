//! The board-independent application: what the node does, whatever it runs on.
//!
//! At boot [`calib::load`] picks the record slot in force, checks the record (magic, version, CRC,
//! the MCU's unique id, model 4) and inverts it once. From then on every sample set goes through
//! [`calib::Calibration::apply_block`] and leaves the node as a [`Block`](accelcal_shared::wire::Block)
//! — calibrated, or raw codes flagged uncalibrated when there is no valid record, never garbage
//! presented as calibrated data. [`node`] holds the async loops the tasks run.

pub mod calib;
pub mod node;
pub mod ports;
pub mod progress;
