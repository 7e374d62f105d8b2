//! accelcal host library.

pub mod gravity;
