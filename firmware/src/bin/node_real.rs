//! The node firmware for the B-L475E-IOT01A board. Its `main` is the library's
//! [`accelcal_node::run`], the same body for every board.
#![no_std]
#![no_main]

#[cortex_m_rt::entry]
fn main() -> ! {
    accelcal_node::run()
}
