//! The node firmware for QEMU's `b-l475e-iot01a` machine: start the watchdog,
//! initialise, load the record, spawn; the executor's loop feeds the watchdog while the sampler
//! and the link make progress.
#![no_std]
#![no_main]

use accelcal_node::{app, board, executor::Executor, tasks};

#[cortex_m_rt::entry]
fn main() -> ! {
    // The watchdog runs from here on: a hang in the board's bring-up or the record check resets.
    let watchdog = board::start_watchdog();
    let board = board::init();
    let (cal, record) = app::calib::load(&board.storage, board::TEMP_INPUTS);
    let device_id = app::ports::RecordStorage::device_id(&board.storage);
    let node = app::node::Node::new(cal, record, board.reset_cause, device_id, &board.clock);
    let executor = cortex_m::singleton!(: Executor = Executor::new()).expect("main runs once");
    executor.run(|spawner| tasks::spawn_all(spawner, board, node), watchdog)
}
