//! An embassy-time driver for QEMU: time is the host's monotonic clock, read through semihosting
//! (the ARM semihosting operations `SYS_ELAPSED`, 0x30, and `SYS_TICKFREQ`, 0x31), and SysTick
//! interrupts every [`PERIOD_US`] µs to fire the alarms. SysTick is the one timer QEMU's
//! b-l475e-iot01a models (its TIMx and RTC are stubs), but it cannot count time there: QEMU cannot
//! deliver 50,000 interrupts a second, a SysTick that expires while the last one is still pending
//! is lost, and a driver that counted the interrupts ran 3 to 4 times slower than the host (the
//! node's 1 s status came every 3.5 s, and a loaded machine stretched it past `monitor`'s 5 s).
//!
//! The period is short for a reason of QEMU's, not of the node's: QEMU's USART model takes one
//! received byte per iteration of QEMU's main loop, and an idle main loop iterates only when a
//! timer expires. The 20 µs SysTick makes it iterate as fast as QEMU can, so the front end's bytes
//! on USART2 (and the host's on USART1) flow without keeping a host core busy. The clock is read
//! on every [`CHECK_EVERY`]-th interrupt only (a semihosting call leaves the translated code and
//! takes QEMU's big lock), so an alarm fires some milliseconds late; the node's one timer is the
//! 1 s status period.

use core::cell::{Cell, RefCell};
use core::task::Waker;

use cortex_m::peripheral::syst::SystClkSource;
use cortex_m::peripheral::SYST;
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
/// The alarms are checked on every this many SysTick interrupts (5 ms of SysTick periods; more
/// when QEMU loses interrupts).
const CHECK_EVERY: u32 = 5000 / PERIOD_US;

/// Semihosting operation numbers (ARM semihosting specification).
const SYS_ELAPSED: usize = 0x30;
const SYS_TICKFREQ: usize = 0x31;

struct HostClockDriver {
    /// The host clock's ticks per second (`SYS_TICKFREQ`; QEMU counts nanoseconds).
    host_hz: Mutex<Cell<u64>>,
    /// SysTick interrupts since the alarms were last checked.
    ticks: Mutex<Cell<u32>>,
    alarm_at: Mutex<Cell<u64>>,
    queue: Mutex<RefCell<Queue>>,
}

embassy_time_driver::time_driver_impl!(static DRIVER: HostClockDriver = HostClockDriver {
    host_hz: Mutex::new(Cell::new(0)),
    ticks: Mutex::new(Cell::new(0)),
    alarm_at: Mutex::new(Cell::new(u64::MAX)),
    queue: Mutex::new(RefCell::new(Queue::new())),
});

/// Asks the host for its tick frequency, then starts SysTick. Ends the emulation when the host
/// has no clock to offer (a semihosting host without `SYS_ELAPSED`).
pub(super) fn init(syst: &mut SYST) {
    // SAFETY: `SYS_TICKFREQ` takes no argument block (r1 = 0) and returns the frequency in r0.
    let hz = unsafe { cortex_m_semihosting::syscall1(SYS_TICKFREQ, 0) };
    if hz == 0 || hz == usize::MAX || host_elapsed().is_none() {
        super::fail(format_args!("the semihosting host has no clock (SYS_TICKFREQ {hz:#x})"));
    }
    critical_section::with(|cs| DRIVER.host_hz.borrow(cs).set(hz as u64));
    syst.set_clock_source(SystClkSource::Core);
    syst.set_reload(RELOAD);
    syst.clear_current();
    syst.enable_interrupt();
    syst.enable_counter();
}

/// The host's clock: ticks since the emulation started (`SYS_ELAPSED`), `None` if refused.
fn host_elapsed() -> Option<u64> {
    let mut block = [0u32; 2];
    // SAFETY: `SYS_ELAPSED` writes the 64-bit count into the two-word block r1 points to (least
    // significant word first) and returns 0, or −1 when it cannot.
    let r = unsafe { cortex_m_semihosting::syscall1(SYS_ELAPSED, block.as_mut_ptr() as usize) };
    (r == 0).then(|| u64::from(block[0]) | (u64::from(block[1]) << 32))
}

impl HostClockDriver {
    fn now_cs(&self, cs: critical_section::CriticalSection) -> u64 {
        let hz = self.host_hz.borrow(cs).get().max(1);
        // The host's clock is monotonic (`init` checked that it answers); 128-bit product: no
        // overflow for any frequency.
        let ticks = host_elapsed().unwrap_or_else(|| super::fail(format_args!("SYS_ELAPSED refused")));
        (u128::from(ticks) * u128::from(TICK_HZ) / u128::from(hz)) as u64
    }

    fn on_tick(&self) {
        critical_section::with(|cs| {
            let ticks = self.ticks.borrow(cs);
            ticks.set(ticks.get() + 1);
            let alarm_at = self.alarm_at.borrow(cs).get();
            if ticks.get() < CHECK_EVERY || alarm_at == u64::MAX {
                return;
            }
            ticks.set(0);
            let now = self.now_cs(cs);
            if now >= alarm_at {
                let next = self.queue.borrow(cs).borrow_mut().next_expiration(now);
                self.alarm_at.borrow(cs).set(next);
            }
        });
    }
}

impl Driver for HostClockDriver {
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
