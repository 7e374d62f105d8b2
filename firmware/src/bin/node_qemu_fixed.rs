//! The node firmware for QEMU's `b-l475e-iot01a` machine, calibrating in fixed point (the
//! `fixed-point` feature: the build for FPU-less parts, tested in QEMU). Its `main` is the library's
//! [`accelcal_node::run`], the same body for every board.
#![no_std]
#![no_main]

#[cortex_m_rt::entry]
fn main() -> ! {
    accelcal_node::run()
}
