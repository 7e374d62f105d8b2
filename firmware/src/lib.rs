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
