//! `accelcal-line`: the calibration line's side of accelcal, on top of the calibration library
//! (`accelcal-core`).
//!
//! The host side of the sensor node ([`node`]: its serial link and session, QEMU and the GDB
//! client, flashing record slots, hardware-in-the-loop checks), the dividing heads ([`head`]),
//! the emulated bench that feeds the QEMU node ([`emulate`]), acquisition of a campaign on the
//! head ([`acquire`]), live verification of a calibrated node ([`verify`]) and the station's
//! journal ([`station`]).
//!
//! No database (`accelcal-db` sits beside this crate, on the core alone: neither imports the
//! other), no command line, no printing: the `accelcal` binary does that. This is the only crate
//! that depends on probe-rs, serialport and socket2.

#![allow(clippy::neg_cmp_op_on_partial_ord, clippy::needless_range_loop)]
pub mod acquire;
pub mod emulate;
pub mod head;
pub mod node;
pub mod station;
pub mod verify;
