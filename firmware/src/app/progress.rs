//! The evidence the main loop feeds the watchdog on: progress counters that the sampler and the
//! link transmitter bump, and the rule that both must have moved since the last feed.
//!
//! "Progress" is what the node must keep doing whether or not the host talks to it: the sampler
//! takes a block from its source (a good block or an overrun; on the real board TIM6 paces the
//! ADC, so a block comes at least every 160 ms, at 100 Hz), and the transmitter finishes sending
//! a frame (the status task queues one every [`STATUS_PERIOD`](super::node::STATUS_PERIOD),
//! live blocks come on top). The receiving side is not counted: a link with no host is idle by
//! design, and a receiver that stops cannot be told from a silent host. A stuck transmitter (the
//! UART's DMA never completing), a sampler that stops (the ADC, its DMA or TIM6), a task that never
//! yields, or a dead executor all stop the feeds, and the watchdog resets the MCU.

use core::sync::atomic::{AtomicU32, Ordering};

/// Blocks the sampler has taken from its source (good or lost), since boot; wraps.
pub static SAMPLED: AtomicU32 = AtomicU32::new(0);
/// Frames the transmitter has finished sending, since boot; wraps.
pub static SENT: AtomicU32 = AtomicU32::new(0);

/// Counts one unit of progress.
pub fn bump(counter: &AtomicU32) {
    counter.fetch_add(1, Ordering::Relaxed);
}

/// The counters as the main loop last fed the watchdog.
#[derive(Default)]
pub struct Progress {
    last: (u32, u32),
}

impl Progress {
    /// `true` when both the sampler and the transmitter have moved since the last `true` (the
    /// caller then feeds the watchdog).
    pub fn moved(&mut self) -> bool {
        let now = (SAMPLED.load(Ordering::Relaxed), SENT.load(Ordering::Relaxed));
        if now.0 != self.last.0 && now.1 != self.last.1 {
            self.last = now;
            true
        } else {
            false
        }
    }
}
