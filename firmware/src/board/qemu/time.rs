//! An embassy-time driver on SysTick, the one timer QEMU's b-l475e-iot01a models (its TIMx are
//! stubs). SysTick interrupts every [`PERIOD_US`] µs; `now` adds the counter's progress within the
//! period, in the 1 MHz ticks embassy-time is configured for (`tick-hz-1_000_000`).
//!
//! The period is short for a reason of QEMU's, not of the node's: QEMU's USART model takes one
//! received byte per iteration of QEMU's main loop, and an idle main loop iterates only when a
//! timer expires. A 50 µs SysTick makes it iterate 20,000 times a second, so the front end's bytes
//! on USART2 (and the host's on USART1) flow at up to 20 kB/s without keeping a host core busy.

use core::cell::{Cell, RefCell};
use core::task::Waker;

use cortex_m::peripheral::syst::SystClkSource;
use cortex_m::peripheral::{SCB, SYST};
use cortex_m_rt::exception;
use critical_section::Mutex;
use embassy_time_driver::{Driver, TICK_HZ};
use embassy_time_queue_utils::Queue;

/// Core clock after reset: MSI at 4 MHz (RM0351 §6.2.3); SysTick counts it (CLKSOURCE = 1).
const CORE_HZ: u32 = 4_000_000;
/// SysTick period, µs.
const PERIOD_US: u32 = 20;
/// SysTick reload for that period (ARMv7-M ARM §B3.3.3, SYST_RVR holds period − 1).
const RELOAD: u32 = CORE_HZ / 1_000_000 * PERIOD_US - 1;
/// embassy-time ticks per SysTick period.
const TICKS_PER_PERIOD: u64 = TICK_HZ * PERIOD_US as u64 / 1_000_000;

struct SysTickDriver {
    periods: Mutex<Cell<u64>>,
    alarm_at: Mutex<Cell<u64>>,
    queue: Mutex<RefCell<Queue>>,
}

embassy_time_driver::time_driver_impl!(static DRIVER: SysTickDriver = SysTickDriver {
    periods: Mutex::new(Cell::new(0)),
    alarm_at: Mutex::new(Cell::new(u64::MAX)),
    queue: Mutex::new(RefCell::new(Queue::new())),
});

pub(super) fn init(syst: &mut SYST) {
    syst.set_clock_source(SystClkSource::Core);
    syst.set_reload(RELOAD);
    syst.clear_current();
    syst.enable_interrupt();
    syst.enable_counter();
}

impl SysTickDriver {
    fn now_cs(&self, cs: critical_section::CriticalSection) -> u64 {
        let mut periods = self.periods.borrow(cs).get();
        let mut val = SYST::get_current();
        // The counter wrapped but the interrupt has not run yet (it is masked here).
        if SCB::is_pendst_pending() {
            periods += 1;
            val = SYST::get_current();
        }
        let within = (RELOAD - val.min(RELOAD)) as u64;
        periods * TICKS_PER_PERIOD + within * TICKS_PER_PERIOD / (RELOAD as u64 + 1)
    }

    fn on_tick(&self) {
        critical_section::with(|cs| {
            let periods = self.periods.borrow(cs);
            periods.set(periods.get() + 1);
            let now = periods.get() * TICKS_PER_PERIOD;
            if now >= self.alarm_at.borrow(cs).get() {
                let next = self.queue.borrow(cs).borrow_mut().next_expiration(now);
                self.alarm_at.borrow(cs).set(next);
            }
        });
    }
}

impl Driver for SysTickDriver {
    fn now(&self) -> u64 {
        critical_section::with(|cs| self.now_cs(cs))
    }

    fn schedule_wake(&self, at: u64, waker: &Waker) {
        critical_section::with(|cs| {
            let mut queue = self.queue.borrow(cs).borrow_mut();
            if queue.schedule_wake(at, waker) {
                let next = queue.next_expiration(self.now_cs(cs));
                self.alarm_at.borrow(cs).set(next);
            }
        });
    }
}

#[exception]
fn SysTick() {
    DRIVER.on_tick();
}
