//! accelcal host library.
