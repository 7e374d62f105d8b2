//! `accelcal-shared`: the no_std core of accelcal, shared by the host tool and the firmware.
//!
//! It holds the dividing-head kinematics, the polynomial model terms and the paper's candidate
//! models, the test-turn formulas, the application of a linear (model 4) calibration in f64, f32 and
//! fixed point, the binary calibration record, the node's link protocol and record slots, its boot
//! decision ([`boot`]), its flash-ECC NMI decision ([`flash_ecc`]) and the node contract
//! ([`contract`]: addresses, ids, baud rates, fixed-point scale).
//!
//! Architecture invariants: this crate does no I/O, never allocates, and never panics on untrusted
//! bytes (the record parser returns a typed error for any input).
#![cfg_attr(not(any(test, feature = "std")), no_std)]
#![deny(unsafe_code)]
#![warn(missing_docs)]
// `!(x > t)` is deliberate: a NaN must fail every range check. Index loops mirror the math.
#![allow(clippy::neg_cmp_op_on_partial_ord, clippy::needless_range_loop)]

pub mod boot;
pub mod contract;
pub mod flash_ecc;
pub mod frontend;
pub mod kinematics;
pub mod linear;
pub mod mcu_temp;
pub mod overrun;
pub mod record;
pub mod slots;
pub mod terms;
pub mod testturn;
pub mod thermal;
pub mod wire;

pub use kinematics::{gravity, normal_gravity, G_STANDARD};
pub use terms::{Basis, Structure, Term, BASIS, N_ACCEL_BASIS, N_BASIS};
