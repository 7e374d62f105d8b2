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
//! and [`lost_sets`] says how far off it was, so the node can log a disagreement.
//!
//! [`Tracker`] is the real board's bookkeeping around them (firmware/src/board/real.rs,
//! firmware/README.md "Overruns on the real board"): the sets delivered, and where the count of
//! scans stood at the last instant it was known exactly.

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

/// The real board's count of sample sets across DMA ring overruns: the sets handed on, and the
/// time's side of the measurement (where the count of scans stood at an instant, and the trigger
/// period since). The count is known exactly after every block ([`Tracker::block`]) and after
/// every overrun; a rate change ([`Tracker::rate_changed`]) and the time in between are
/// estimated to within a set or two, which [`lost_sets`] corrects with the DMA's counter.
///
/// `RING_SETS`: sets in the DMA ring (a power of two, see [`lost_sets`]); `SCAN_LEN`: values per
/// set (DMA transfers per scan); `TIMER_MHZ`: the trigger timer's clock (constants of the board,
/// so that the node's flash holds no code to load them).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Tracker<const RING_SETS: u32, const SCAN_LEN: u32, const TIMER_MHZ: u32> {
    /// Sets handed on or counted lost: the number of the next set (wraps).
    delivered: u32,
    /// The instant of the last known count, µs (wraps every 71 min).
    at_us: u32,
    /// Scans begun by `at_us` (the DMA has written their first value; wraps).
    started: u32,
    /// The trigger period, in cycles of the timer's clock (0: not yet known).
    period: u32,
}

impl<const RING_SETS: u32, const SCAN_LEN: u32, const TIMER_MHZ: u32>
    Tracker<RING_SETS, SCAN_LEN, TIMER_MHZ>
{
    /// Nothing delivered, no scan begun, the period not yet known: the state at boot, before the
    /// trigger timer first starts.
    pub const fn new() -> Self {
        Tracker { delivered: 0, at_us: 0, started: 0, period: 0 }
    }

    /// The number of the next set to hand on (sets delivered or lost since boot; wraps).
    pub fn delivered(&self) -> u32 {
        self.delivered
    }

    /// Scans begun by `now_us`, estimated from the last known count and the trigger period.
    fn started_at(&self, now_us: u32) -> u32 {
        let n = triggers_in(now_us.wrapping_sub(self.at_us), TIMER_MHZ, self.period);
        self.started.wrapping_add(n)
    }

    /// The trigger timer was stopped, given `period` and restarted at `now_us` (read after the
    /// stop): the scans begun under the old period, plus the one the restart's update event
    /// starts, then whole new periods.
    pub fn rate_changed(&mut self, now_us: u32, period: u32) {
        self.started = self.started_at(now_us).wrapping_add(1);
        self.at_us = now_us;
        self.period = period;
    }

    /// A block of `sets` was handed on, and at `now_us` the ring held `unread` values after it
    /// (embassy-stm32's `read_exact` returns them): the count of scans begun, exactly (a scan
    /// partly written has begun).
    pub fn block(&mut self, sets: u32, unread: u32, now_us: u32) {
        self.delivered = self.delivered.wrapping_add(sets);
        self.started = self.delivered.wrapping_add(unread.div_ceil(SCAN_LEN.max(1)));
        self.at_us = now_us;
    }

    /// The ring overran and the reader was moved, at `now_us`, to the DMA's position: `ndtr`
    /// remaining transfers (see [`resume_slot`]). Returns the sets lost since the last block
    /// ([`lost_sets`]); the reader resumes at the new [`Tracker::delivered`], and the count is
    /// known exactly again.
    pub fn overrun(&mut self, ndtr: u32, now_us: u32) -> Lost {
        let slot = resume_slot(ndtr, RING_SETS, SCAN_LEN);
        let lost = lost_sets(self.delivered, self.started_at(now_us), slot, RING_SETS);
        self.delivered = self.delivered.wrapping_add(lost.sets);
        self.started = self.delivered;
        self.at_us = now_us;
        lost
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The real board's ring: 32 sets of 4 values.
    const SETS: u32 = 32;
    const SCAN: u32 = 4;
    /// Sets of one block (half the ring).
    const MAX_BLOCK_SETS: u32 = SETS / 2;

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

    /// A model of the real board's sampling (firmware/src/board/real.rs) and of embassy-stm32
    /// 0.6.0's ADC ring, in cycles of the 80 MHz clock that TIM2 (1 µs ticks) and TIM6 share:
    /// TIM6 triggers a scan every `period` cycles, from the timer's (re)start on; the DMA writes
    /// the scan's values 240, 4400, 8560 and 12720 cycles after the trigger (16× oversampled
    /// conversions: the discarded one of 15 cycles, then three of 260); a trigger that comes
    /// while a scan is still converting is ignored by the ADC. The reader takes a block when the
    /// DMA has written it, 20 µs late, unless it is stalled; it reports an overrun the way
    /// `ReadableDmaRingBuffer::read` does (more than the whole ring unread) and is then moved to
    /// the DMA's position, 1 µs later, and on to the next whole scan.
    struct Rig {
        /// Timer runs: (start cycle, period, end cycle exclusive).
        runs: Vec<(u64, u64, u64)>,
        /// Values the reader has taken or skipped (absolute, not wrapped).
        read: u64,
        tracker: Tracker<SETS, SCAN, { MHZ as u32 }>,
        /// The reader's next wake-up, cycles.
        wake: u64,
        /// µs of TIM2 at cycle 0 (the counter wraps at 2³²).
        us0: u32,
        /// Overruns seen, and the sets they lost in truth.
        overruns: Vec<u32>,
    }

    const MHZ: u64 = 80;
    const CAP: u64 = (SETS * SCAN) as u64;
    const VALUE_AT: [u64; 4] = [240, 4400, 8560, 12720];
    const BLOCK: u64 = CAP / 2;
    const LATE: u64 = 20 * MHZ;

    impl Rig {
        /// Boot: the timer starts at cycle 1000 with `period` (set_rate: stop, read the time,
        /// restart).
        fn boot(period: u64, us0: u32) -> Self {
            let mut rig = Rig {
                runs: Vec::new(),
                read: 0,
                tracker: Tracker::new(),
                wake: 0,
                us0,
                overruns: Vec::new(),
            };
            rig.change_rate(600, period);
            rig.wake = rig.value_time(BLOCK) + LATE;
            rig
        }

        fn us(&self, cycle: u64) -> u32 {
            self.us0.wrapping_add((cycle / MHZ) as u32)
        }

        /// Trigger instants that start a scan, in order (a trigger during a conversion is lost).
        fn scans(&self) -> impl Iterator<Item = u64> + '_ {
            let mut last: Option<u64> = None;
            self.runs
                .iter()
                .flat_map(|&(start, period, end)| {
                    (0..).map(move |k| start + k * period).take_while(move |&t| t < end)
                })
                .filter(move |&t| {
                    let busy = last.is_some_and(|l| t < l + VALUE_AT[3]);
                    if !busy {
                        last = Some(t);
                    }
                    !busy
                })
        }

        /// Values the DMA has written by `cycle`.
        fn written(&self, cycle: u64) -> u64 {
            self.scans()
                .take_while(|&t| t <= cycle)
                .map(|t| VALUE_AT.iter().filter(|&&d| t + d <= cycle).count() as u64)
                .sum()
        }

        /// The cycle at which the DMA writes value number `n` (1-based).
        fn value_time(&self, n: u64) -> u64 {
            let scan = (n - 1) / SCAN as u64;
            self.scans().nth(scan as usize).expect("the timer runs on")
                + VALUE_AT[((n - 1) % SCAN as u64) as usize]
        }

        /// DMA1 channel 1's CNDTR at `cycle`: counts down from the ring's length, reloads.
        fn ndtr(&self, cycle: u64) -> u32 {
            (CAP - self.written(cycle) % CAP) as u32
        }

        /// `SampleClock::set_rate` at `cycle`: TIM6 stops, the time is read, TIM6 restarts 5 µs
        /// later with `period` (its update event triggers a scan at once).
        fn change_rate(&mut self, cycle: u64, period: u64) {
            if let Some(run) = self.runs.last_mut() {
                run.2 = cycle;
            }
            self.tracker.rate_changed(self.us(cycle), period as u32);
            self.runs.push((cycle + 5 * MHZ, period, u64::MAX));
        }

        /// The reader's wake-ups before `until`; it sleeps from `stall.0` to `stall.1`.
        fn run(&mut self, until: u64, stall: (u64, u64)) {
            loop {
                let now = if (stall.0..stall.1).contains(&self.wake) { stall.1 } else { self.wake };
                if now >= until {
                    return;
                }
                let available = self.written(now) - self.read;
                if available > CAP {
                    let moved = now + MHZ;
                    let resume = self.written(moved).div_ceil(SCAN as u64) * SCAN as u64;
                    let truth = ((resume - self.read) / SCAN as u64) as u32;
                    let lost = self.tracker.overrun(self.ndtr(moved), self.us(moved));
                    assert_eq!(lost.sets, truth, "overrun at cycle {now}: {lost:?}");
                    assert!(lost.off_by.abs() <= 1, "estimate off by {} sets", lost.off_by);
                    self.overruns.push(truth);
                    self.read = resume;
                } else if available >= BLOCK {
                    self.read += BLOCK;
                    self.tracker.block(
                        BLOCK as u32 / SCAN,
                        (self.written(now) - self.read) as u32,
                        self.us(now),
                    );
                }
                assert_eq!(self.tracker.delivered() as u64, self.read / SCAN as u64);
                self.wake = self.value_time(self.read + BLOCK).max(now) + LATE;
            }
        }
    }

    /// TIM6 periods (cycles of 80 MHz) of the rates the host may set, as `set_rate` rounds them
    /// (3 kHz: ARR + 1 = 26667).
    const PERIODS: [u64; 4] = [800_000, 80_000, 26_667, 20_000];

    #[test]
    fn a_stall_of_any_length_is_counted_exactly() {
        // Stalls from none to beyond the watchdog's 4 s, across the µs counter's wrap.
        for period in PERIODS {
            for stall_ms in [0u64, 3, 8, 9, 17, 33, 100, 1000, 4300] {
                let mut rig = Rig::boot(period, u32::MAX - 2_000_000);
                let start = 500_000 * MHZ + 12_345;
                let end = start + stall_ms * 1000 * MHZ;
                rig.run(end + 50 * period * SETS as u64, (start, end));
                let sets_stalled = stall_ms * 1000 * MHZ / period;
                if sets_stalled > 2 * SETS as u64 {
                    // Beyond the ring: one overrun, and most of the stall lost (not one block).
                    assert_eq!(rig.overruns.len(), 1, "period {period} stall {stall_ms} ms");
                    assert!(rig.overruns[0] as u64 + 2 * SETS as u64 >= sets_stalled);
                    assert!(rig.overruns[0] > MAX_BLOCK_SETS);
                } else if sets_stalled < MAX_BLOCK_SETS as u64 {
                    assert!(rig.overruns.is_empty(), "period {period} stall {stall_ms} ms");
                }
            }
        }
    }

    #[test]
    fn a_rate_change_during_a_stall_is_counted_exactly() {
        for (i, old) in PERIODS.into_iter().enumerate() {
            for new in PERIODS.into_iter().filter(|&p| p != old) {
                // The change comes right after a trigger (its scan still converting: the
                // restart's scan is lost to the ADC), or between scans.
                for (case, after) in [(0u64, 2_000u64), (1, old / 2)] {
                    let mut rig = Rig::boot(old, i as u32 * 1_000_000_007);
                    let start = 300_000 * MHZ;
                    let change = rig.scans().find(|&t| t > start + 40_000 * MHZ).unwrap() + after;
                    let end = change + 200_000 * MHZ;
                    rig.run(change, (start, end));
                    rig.change_rate(change, new);
                    rig.run(end + 50 * new * SETS as u64, (start, end));
                    assert_eq!(rig.overruns.len(), 1, "{old} → {new}, case {case}");
                }
            }
        }
    }
}
