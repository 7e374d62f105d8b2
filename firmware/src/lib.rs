//! The accelcal sensor node: reads an analog accelerometer triad, applies the model-4 calibration
//! record from flash, and talks the framed link protocol of `accelcal_shared::wire` over USART1.
//!
//! - [`app`] is the board-independent application: record check, calibration, protocol handling.
//!   It sees the hardware only through the traits in [`app::ports`].
//! - [`board`] is the only code that touches peripherals. Exactly one board is built: `board-real`
//!   (embassy-stm32 on the B-L475E-IOT01A) or `board-qemu` (QEMU's `b-l475e-iot01a` machine).
//! - [`executor`] is the thread-mode executor both boards run (WFI when idle).
//! - [`tasks`] glues the application's async functions to the board's concrete types as embassy
//!   tasks.
#![no_std]
#![warn(missing_docs)]

pub mod app;
pub mod board;
pub mod executor;
pub mod tasks;

/// The node's `main`, the same for every board and build: start the watchdog, initialise the
/// board, load the record, spawn the tasks; the executor's loop feeds the watchdog while the
/// sampler and the link make progress. Called once, from the binary's entry point.
pub fn run() -> ! {
    // The watchdog runs from here on: a hang in the board's bring-up or the record check resets.
    let watchdog = board::start_watchdog();
    let board = board::init();
    let (cal, record) = app::calib::load(&board.storage, board::TEMP_INPUTS);
    let device_id = app::ports::RecordStorage::device_id(&board.storage);
    let node = app::node::Node::new(cal, record, board.reset_cause, device_id, &board.clock);
    let executor =
        cortex_m::singleton!(: executor::Executor = executor::Executor::new()).expect("main runs once");
    executor.run(|spawner| tasks::spawn_all(spawner, board, node), watchdog)
}
