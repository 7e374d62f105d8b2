//! The board layer: the only code that touches peripherals. It turns the chip into the
//! application's ports ([`crate::app::ports`]) and documents pins and registers.
//!
//! Exactly one board is compiled in, chosen by a cargo feature:
//! - `board-real`: the B-L475E-IOT01A with embassy-stm32 (the only module importing it);
//! - `board-qemu`: QEMU's `b-l475e-iot01a` machine, whose ADC, DMA, timers and flash controller are
//!   stubs: SysTick time driver, USART1 by 32-bit register access, samples over the link.

#[cfg(all(feature = "board-real", feature = "board-qemu"))]
compile_error!("choose one board: features `board-real` and `board-qemu` exclude each other");
#[cfg(not(any(feature = "board-real", feature = "board-qemu")))]
compile_error!("choose a board: enable feature `board-real` or `board-qemu`");

use accelcal_shared::slots::{N_SLOTS, SLOT_SIZE};

#[cfg(feature = "board-qemu")]
mod qemu;
#[cfg(feature = "board-qemu")]
pub use qemu::*;

#[cfg(feature = "board-real")]
mod real;
#[cfg(feature = "board-real")]
pub use real::*;

unsafe extern "C" {
    // Defined in the repository's memory.x: two 2 KiB pages at the end of flash, outside the
    // FLASH region the linker fills.
    static __record_slot0: [u8; SLOT_SIZE];
    static __record_slot1: [u8; SLOT_SIZE];
}

/// The two record slots as memory-mapped flash (reserved in `memory.x`).
pub fn record_slots() -> [&'static [u8; SLOT_SIZE]; N_SLOTS] {
    // SAFETY: memory.x places both symbols on flash pages that nothing in the firmware writes;
    // they are plain readable memory for the program's lifetime.
    unsafe { [&*core::ptr::addr_of!(__record_slot0), &*core::ptr::addr_of!(__record_slot1)] }
}

/// Address of the MCU's 96-bit unique device id (RM0351 §50.1, "Unique device ID register").
pub const UID_ADDR: usize = 0x1FFF_7590;
