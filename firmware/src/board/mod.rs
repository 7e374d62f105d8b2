//! The board layer: the only code that touches peripherals. It turns the chip into the
//! application's ports ([`crate::app::ports`]) and documents pins and registers.
//!
//! Exactly one board is compiled in, chosen by a cargo feature:
//! - `board-real`: the B-L475E-IOT01A with embassy-stm32 (the only module importing it);
//! - `board-qemu`: QEMU's `b-l475e-iot01a` machine, whose ADC, DMA, timers and flash controller are
//!   stubs: a time driver on the host's clock (semihosting) with SysTick alarms, USART1 by
//!   32-bit register access, live samples from an emulated front end on USART2, replayed ones
//!   over the link.

#[cfg(all(feature = "board-real", feature = "board-qemu"))]
compile_error!("choose one board: features `board-real` and `board-qemu` exclude each other");
#[cfg(not(any(feature = "board-real", feature = "board-qemu")))]
compile_error!("choose a board: enable feature `board-real` or `board-qemu`");

use accelcal_shared::contract::SLOT_ADDRS;
use accelcal_shared::slots::{SlotRead, PROGRAM_UNIT, SLOT_SIZE};
use accelcal_shared::wire::ResetCause;

#[cfg(feature = "board-qemu")]
mod qemu;
#[cfg(feature = "board-qemu")]
pub use qemu::*;

#[cfg(feature = "board-real")]
mod real;
#[cfg(feature = "board-real")]
pub use real::*;

/// The board's parts, ready for the application: what each board's `init` returns.
pub struct Board {
    /// Host link, receiving half.
    pub rx: LinkRxImpl,
    /// Host link, sending half.
    pub tx: LinkTxImpl,
    /// Record slots and device id.
    pub storage: Storage,
    /// Live sample sets (the real board's ADC; QEMU's emulated front end on USART2).
    pub source: SourceImpl,
    /// The sampling rate (the real board's TIM6; what QEMU's front end is told).
    pub clock: SampleClockImpl,
    /// Why the MCU last reset (RCC_CSR; QEMU's model of it).
    pub reset_cause: ResetCause,
}

/// Reads record slot `slot` (at [`SLOT_ADDRS`], reserved in `memory.x`) into `out` with volatile
/// 32-bit loads, one double word at a time. `faulted()` says whether a flash ECC error was reported
/// for this slot since the read began (the real board's NMI handler sets it); it is asked after
/// every double word and once more at the end, after a barrier, so that an NMI taken a few
/// instructions late is still seen. The bytes of a faulted read are discarded: the slot is
/// [`SlotRead::Unreadable`].
fn read_slot_with(slot: u8, out: &mut [u8; SLOT_SIZE], faulted: impl Fn() -> bool) -> SlotRead {
    let Some(&base) = SLOT_ADDRS.get(slot as usize) else {
        return SlotRead::Unreadable;
    };
    for (i, dw) in out.chunks_exact_mut(PROGRAM_UNIT).enumerate() {
        let addr = (base as usize + i * PROGRAM_UNIT) as *const u32;
        // SAFETY: the slot pages are mapped, readable flash for the program's lifetime (memory.x
        // keeps the linker out of them and the firmware never writes flash); `addr` is 4-aligned
        // and inside the page. An ECC error on the load is an NMI, not a bus fault.
        let (lo, hi) = unsafe { (core::ptr::read_volatile(addr), core::ptr::read_volatile(addr.add(1))) };
        cortex_m::asm::dsb();
        cortex_m::asm::isb();
        if faulted() {
            return SlotRead::Unreadable;
        }
        dw[..4].copy_from_slice(&lo.to_le_bytes());
        dw[4..].copy_from_slice(&hi.to_le_bytes());
    }
    cortex_m::asm::dsb();
    cortex_m::asm::isb();
    if faulted() {
        return SlotRead::Unreadable;
    }
    SlotRead::Complete
}
