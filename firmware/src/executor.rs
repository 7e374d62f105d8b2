//! A thread-mode embassy executor that sleeps with WFI between polls.
//!
//! embassy-executor's stock Cortex-M executor sleeps with WFE, which QEMU implements as a no-op
//! (the idle loop would spin at 100 % host CPU and flood instruction traces). WFI halts both the
//! real core and QEMU's until an interrupt. The pender sets a flag; the loop checks it with
//! interrupts masked before sleeping, so a wake-up between the poll and the WFI is never lost
//! (WFI returns on a pending interrupt even while PRIMASK masks it, ARMv7-M ARM §B1.5.19).
//!
//! The loop is the node's main loop: after each poll of the ready tasks it feeds the independent
//! watchdog, but only when the sampler and the link transmitter have both made progress since
//! the last feed ([`Progress`]). An iteration is one poll (microseconds: a block calibrated, a
//! frame encoded, no task busy-waits) and one sleep until the next interrupt; the transmitter
//! finishes a frame at least every [`STATUS_PERIOD`](crate::app::node::STATUS_PERIOD) of 1 s (the
//! status) and the real board's sampler a block at least every 160 ms, so a healthy node feeds
//! about once a second. The watchdog's timeout (4 s on the real board,
//! `board::WATCHDOG_TIMEOUT_US`) is reached when a task never yields, interrupts starve thread
//! mode, the sampler's source or the transmitter stops, or every task waits for something that
//! never comes.

use core::sync::atomic::{AtomicBool, Ordering};

use embassy_executor::{raw, Spawner};

use crate::app::ports::Watchdog;
use crate::app::progress::Progress;

static PENDING: AtomicBool = AtomicBool::new(true);

#[unsafe(export_name = "__pender")]
fn pender(_context: *mut ()) {
    PENDING.store(true, Ordering::Release);
}

/// The node's executor. Create it once, in `main`, and call [`Executor::run`].
pub struct Executor {
    inner: raw::Executor,
}

impl Executor {
    /// A new executor.
    pub fn new() -> Self {
        Executor { inner: raw::Executor::new(core::ptr::null_mut()) }
    }

    /// Spawns the initial tasks with `init` and runs them forever, feeding `watchdog` after a
    /// poll in which the sampler and the transmitter have both progressed since the last feed.
    pub fn run(&'static mut self, init: impl FnOnce(Spawner), mut watchdog: impl Watchdog) -> ! {
        init(self.inner.spawner());
        let mut progress = Progress::default();
        loop {
            PENDING.store(false, Ordering::Release);
            // SAFETY: called from thread mode only, never from the pender.
            unsafe { self.inner.poll() };
            if progress.moved() {
                watchdog.feed();
            }
            cortex_m::interrupt::disable();
            if !PENDING.load(Ordering::Acquire) {
                cortex_m::asm::wfi();
            }
            // SAFETY: re-enables what the line above disabled; no critical section spans it.
            unsafe { cortex_m::interrupt::enable() };
        }
    }
}

impl Default for Executor {
    fn default() -> Self {
        Self::new()
    }
}
