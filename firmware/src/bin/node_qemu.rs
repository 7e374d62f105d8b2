//! The node firmware for QEMU's `b-l475e-iot01a` machine (calibration in f32). Its `main` is the library's
//! [`accelcal_node::run`], the same body for every board.
#![no_std]
#![no_main]

#[cortex_m_rt::entry]
fn main() -> ! {
    accelcal_node::run()
}
