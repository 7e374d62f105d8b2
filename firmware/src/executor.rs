//! A thread-mode embassy executor that sleeps with WFI between polls.
//!
//! embassy-executor's stock Cortex-M executor sleeps with WFE, which QEMU implements as a no-op
//! (the idle loop would spin at 100 % host CPU and flood instruction traces). WFI halts both the
//! real core and QEMU's until an interrupt. The pender sets a flag; the loop checks it with
//! interrupts masked before sleeping, so a wake-up between the poll and the WFI is never lost
//! (WFI returns on a pending interrupt even while PRIMASK masks it, ARMv7-M ARM §B1.5.19).

use core::sync::atomic::{AtomicBool, Ordering};

use embassy_executor::{raw, Spawner};

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

    /// Spawns the initial tasks with `init` and runs them forever.
    pub fn run(&'static mut self, init: impl FnOnce(Spawner)) -> ! {
        init(self.inner.spawner());
        loop {
            PENDING.store(false, Ordering::Release);
            // SAFETY: called from thread mode only, never from the pender.
            unsafe { self.inner.poll() };
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
