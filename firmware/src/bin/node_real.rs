//! The node firmware for the B-L475E-IOT01A board: initialise, load the record, spawn.
#![no_std]
#![no_main]

use accelcal_node::{app, board, executor::Executor, tasks};

#[cortex_m_rt::entry]
fn main() -> ! {
    let board = board::init();
    let (cal, record) = app::calib::load(&board.storage);
    let node = app::node::Node { cal, record, rate_hz: board::SAMPLE_RATE_HZ };
    let executor = cortex_m::singleton!(: Executor = Executor::new()).expect("main runs once");
    executor.run(|spawner| tasks::spawn_all(spawner, board, node))
}
