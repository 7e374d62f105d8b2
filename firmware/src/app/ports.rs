//! The small traits through which the application sees a board.
#![allow(async_fn_in_trait)]

use accelcal_shared::slots::{SlotRead, SLOT_SIZE};
use accelcal_shared::wire::{Codes, MAX_BLOCK};

/// The receiving half of the host link.
pub trait LinkRx {
    /// Waits for at least one byte and returns how many were put into `buf`.
    async fn read(&mut self, buf: &mut [u8]) -> usize;
}

/// The sending half of the host link.
pub trait LinkTx {
    /// Sends all of `bytes`.
    async fn write_all(&mut self, bytes: &[u8]);
}

/// Sample sets lost before the application could read them.
#[derive(Clone, Copy, Debug, PartialEq, Eq, defmt::Format)]
pub struct Overrun {
    /// Number of sample sets lost.
    pub lost: u32,
}

/// A source of live sample sets (the ADC on the real board, the emulated front end on QEMU), each
/// with the temperature of the board's temperature input.
pub trait SampleSource {
    /// Waits for the next block of sample sets and copies it into `out`, and each set's
    /// temperature (°C) into `temp_c` (a board that reads the temperature once per block gives
    /// every set of the block that reading); returns how many sets. An `Err` reports sets lost
    /// since the last call; the source keeps running.
    async fn read_block(
        &mut self,
        out: &mut [Codes; MAX_BLOCK],
        temp_c: &mut [f32; MAX_BLOCK],
    ) -> Result<usize, Overrun>;
}

/// What paces the live samples (the real board's TIM6 triggering the ADC): its rate can change
/// at run time, and its configuration can be read back from the registers.
pub trait SampleClock {
    /// Sampling rate per channel now in force, Hz.
    fn rate_hz(&self) -> u32;
    /// Sets the sampling rate per channel (the caller has checked it with
    /// [`accelcal_shared::wire::check_rate`]), then reads the trigger configuration back; returns
    /// what [`SampleClock::trigger_ok`] returns.
    fn set_rate(&mut self, hz: u32) -> bool;
    /// Reads the trigger configuration back from the registers and compares it with what the
    /// board programmed; `false` on a mismatch (the board logs the fields that differ).
    fn trigger_ok(&self) -> bool;
}

/// The independent watchdog: it resets the MCU unless fed in time.
pub trait Watchdog {
    /// Reloads the watchdog's counter.
    fn feed(&mut self);
}

/// Where the calibration records live and whose they must be.
pub trait RecordStorage {
    /// Reads record slot `slot` (0 or 1) into `out`. A slot that cannot be read (a double word
    /// failed its flash ECC check) is [`SlotRead::Unreadable`] and `out` means nothing.
    fn read_slot(&self, slot: u8, out: &mut [u8; SLOT_SIZE]) -> SlotRead;
    /// The MCU's 96-bit unique id, which a record's device id must equal.
    fn device_id(&self) -> [u8; 12];
}
