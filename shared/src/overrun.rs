//! How many sample sets a DMA ring overrun lost: the pure arithmetic of the real board's sampler,
//! tested on the host.
//!
//! The real board's ADC writes one scan (a fixed number of values) per trigger into a circular
//! DMA ring of [`RING_SETS`](Self) sets; embassy-stm32 0.6.0's ring buffer
//! (`src/dma/ringbuffer/mod.rs`, `ReadableDmaRingBuffer::len`) reports an overrun only once more
//! than the whole ring is unread, and then (`reset`) moves the reader to where the DMA writes now.
//! The sets in between are lost, however many laps that was: the loss is not bounded by the
//! ring. Two measurements give it exactly:
//!
//! - the DMA's remaining-transfer counter (NDTR) at the moment the reader is moved gives the set
//!   the reader resumes at *modulo the ring* ([`resume_slot`]): exact, but blind to whole laps;
//! - the time since the scan count was last known, at the trigger period the timer really runs
//!   at ([`triggers_in`]), gives the same number to within a few sets (the phase of the trigger,
//!   the instants at which the time is read), but counts the laps. The node's watchdog bounds a
//!   gap to a few seconds (a sampler that makes no progress is not fed), so u32 microseconds do.
//!
//! [`lost_sets`] combines them: the count congruent to the exact residue that is nearest to the
//! time's estimate. It is exact while the estimate is off by less than half a ring (16 sets for
//! the real board's 32-set ring); the estimate's error is a few sets (the trigger's phase, the
//! instants at which the time is read, a trigger dropped during the injected temperature read),
//! and [`lost_sets`] says how far off it was, so the node can log a disagreement. The firmware's
//! use of it is not on this branch yet (firmware/README.md, "Overruns on the real board").

/// Whole trigger periods in `elapsed_us` microseconds, for a timer clocked at `timer_mhz` MHz
/// that triggers every `period` of its cycles (for STM32 TIM6, `(PSC + 1)·(ARR + 1)`). A period
/// of 0 (not yet known) gives 0. In u32: exact up to `u32::MAX / timer_mhz` µs (53 s at 80 MHz),
/// saturating beyond (the node's watchdog resets it long before a gap that long).
pub fn triggers_in(elapsed_us: u32, timer_mhz: u32, period: u32) -> u32 {
    elapsed_us.saturating_mul(timer_mhz).checked_div(period).unwrap_or(0)
}

/// The ring slot (set index modulo `ring_sets`) a reader moved to the DMA's write position
/// resumes at: the first whole scan at or after the position. `ndtr` is the DMA's remaining
/// transfers (it counts down from `ring_sets · scan_len` and reloads in circular mode),
/// `scan_len` the values per set. A `scan_len` or `ring_sets` of 0 gives 0.
pub fn resume_slot(ndtr: u32, ring_sets: u32, scan_len: u32) -> u32 {
    let cap = ring_sets.saturating_mul(scan_len);
    if cap == 0 {
        return 0;
    }
    let pos = (cap - ndtr % cap) % cap;
    pos.div_ceil(scan_len) % ring_sets
}

/// The sets lost across an overrun, and how far the estimate was from it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Lost {
    /// Sets lost: the reader resumes at `delivered + sets`.
    pub sets: u32,
    /// `sets − estimate` (a few sets at most when the time base and the trigger agree).
    pub off_by: i32,
}

/// The sets lost between the `delivered`-th set (the first not handed on) and the one the reader
/// resumes at, whose ring slot is `resume_slot` (exact, see [`resume_slot`]), given the time's
/// estimate `started` of the sets whose scan had begun by then (see [`triggers_in`]). All
/// counters wrap. The result is the count `≡ resume_slot − delivered (mod ring_sets)` nearest to
/// `started − delivered`, never negative (an estimate below `delivered` gives the smallest such
/// count). `ring_sets` must divide 2³² (a power of two, as the real board's 32) for the residue to
/// survive the counters' wrap; 0 gives the estimate.
pub fn lost_sets(delivered: u32, started: u32, resume_slot: u32, ring_sets: u32) -> Lost {
    let estimate = started.wrapping_sub(delivered);
    // An estimate "below" delivered shows as a huge wrapped value: treat it as 0.
    let estimate = if estimate > u32::MAX / 2 { 0 } else { estimate };
    if ring_sets == 0 {
        return Lost { sets: estimate, off_by: 0 };
    }
    let residue = resume_slot.wrapping_sub(delivered) % ring_sets;
    // Offset from the estimate to the next count with the right residue, in 0..ring_sets.
    let up = (residue + ring_sets - estimate % ring_sets) % ring_sets;
    let sets = if up <= ring_sets / 2 || estimate < ring_sets - up {
        estimate + up
    } else {
        estimate + up - ring_sets
    };
    Lost { sets, off_by: sets.wrapping_sub(estimate) as i32 }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The real board's ring: 32 sets of 4 values.
    const SETS: u32 = 32;
    const SCAN: u32 = 4;

    #[test]
    fn triggers_follow_the_timers_real_period() {
        // 1 s, TIM6 at 80 MHz: 4 kHz exactly, and 3 kHz rounded to the slower side (ARR + 1 =
        // 26667: 2999.96 Hz, so 50 s give 149,998 triggers, not 150,000).
        assert_eq!(triggers_in(1_000_000, 80, 20_000), 4000);
        assert_eq!(triggers_in(50_000_000, 80, 26_667), 149_998);
        // Whole periods only; nothing before the period is known.
        assert_eq!(triggers_in(249, 80, 20_000), 0);
        assert_eq!(triggers_in(250, 80, 20_000), 1);
        assert_eq!(triggers_in(1_000_000, 80, 0), 0);
        // Saturates past 53 s at 80 MHz instead of wrapping.
        assert_eq!(triggers_in(u32::MAX, 80, 1), u32::MAX);
    }

    #[test]
    fn the_resume_slot_is_the_next_whole_scan() {
        // NDTR counts down from 128: 128 is position 0, 1 is the last value of the ring.
        assert_eq!(resume_slot(128, SETS, SCAN), 0);
        assert_eq!(resume_slot(0, SETS, SCAN), 0);
        assert_eq!(resume_slot(127, SETS, SCAN), 1); // first value of set 0 written
        assert_eq!(resume_slot(124, SETS, SCAN), 1); // set 0 complete
        assert_eq!(resume_slot(123, SETS, SCAN), 2);
        assert_eq!(resume_slot(1, SETS, SCAN), 0); // set 31 under way: resume at set 0 (wrapped)
        assert_eq!(resume_slot(200, SETS, SCAN), resume_slot(200 % 128, SETS, SCAN));
        assert_eq!(resume_slot(5, 0, SCAN), 0);
        assert_eq!(resume_slot(5, SETS, 0), 0);
    }

    #[test]
    fn the_loss_is_exact_for_estimates_within_half_a_ring() {
        for delivered in [0u32, 7, 1_000_000, u32::MAX - 40, u32::MAX] {
            for true_lost in [0u32, 1, 31, 32, 33, 100, 1000, 123_457] {
                let resume = delivered.wrapping_add(true_lost);
                let slot = resume % SETS;
                for err in -15i32..=15 {
                    let started = resume.wrapping_add(err as u32);
                    let got = lost_sets(delivered, started, slot, SETS);
                    if true_lost as i64 + err as i64 >= 0 {
                        assert_eq!(got.sets, true_lost, "delivered {delivered} lost {true_lost} err {err}");
                        assert_eq!(got.off_by, -err);
                    } else {
                        // An estimate below what was delivered: the smallest count with the residue.
                        assert_eq!(got.sets, true_lost);
                    }
                }
            }
        }
    }

    #[test]
    fn the_sample_counter_wraps_through_zero() {
        // Delivered just below 2^32, resumed past it: slot arithmetic wraps with the counter.
        let delivered = u32::MAX - 9; // slot (2^32 − 10) mod 32 = 22
        let resume = delivered.wrapping_add(50); // 40 → slot 8
        assert_eq!(resume, 40);
        assert_eq!(lost_sets(delivered, 41, resume % SETS, SETS).sets, 50);
        assert_eq!(lost_sets(delivered, 30, resume % SETS, SETS).sets, 50);
    }

    #[test]
    fn an_estimate_off_by_more_than_half_a_ring_is_reported() {
        // 17 sets off: the nearest count with the residue is a lap away, and off_by says so.
        let got = lost_sets(0, 100 + 17, 100 % SETS, SETS);
        assert_eq!(got, Lost { sets: 132, off_by: 15 });
        assert_eq!(lost_sets(0, 5, 3, 0), Lost { sets: 5, off_by: 0 });
    }
}
