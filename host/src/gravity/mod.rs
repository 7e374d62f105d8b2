//! Gravity-norm calibration of an accelerometer triad from hand-placed static holds (no dividing head).
//!
//! The pipeline is: read a raw recording ([`imutk`]), find the static holds ([`holds`]), fit the
//! 9-parameter imu_tk model on `|a| = g` ([`fit`]), and report ([`cli`], [`plot`]). [`sim`] simulates
//! a hand-placed session with a known truth so that the whole chain is tested where the answer is known.
//! See `README-gravity.md` next to this file for the method and the results on a real recording.

pub mod fit;
pub mod holds;
pub mod imutk;
mod solver;
