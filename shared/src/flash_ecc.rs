//! What the node's NMI handler does with a flash ECC error: the pure decision, tested on the host.
//!
//! On the STM32L4 every 64-bit flash double word carries 8 ECC bits. A power cut during a page
//! erase or a double-word program can leave a double word whose ECC does not match its data;
//! reading it sets `FLASH_ECCR.ECCD` and raises a non-maskable interrupt (RM0351 §3.3.2 "Error
//! code correction"). The node reads its record slots with that in mind: a double ECC error whose
//! address lies in a record slot makes that slot unreadable (so it is "slot invalid", and the other
//! slot's record stays in force); any other NMI resets the MCU.
//!
//! `FLASH_ECCR` (offset 0x18 of FLASH at 0x4002_2000, RM0351 §3.7.8), bit layout as in
//! stm32-metapac 21.0.0 `peripherals/flash_l4.rs` (`Eccr`):
//!
//! | bits | field | meaning |
//! |---|---|---|
//! | 18:0 | `ADDR_ECC` | byte offset, within its bank, of the double word that failed |
//! | 19 | `BK_ECC` | bank of the failure (0: bank 1, 1: bank 2) |
//! | 20 | `SYSF_ECC` | the failure is in system flash |
//! | 24 | `ECCIE` | interrupt enable for corrected (single) errors |
//! | 30 | `ECCC` | a single error was corrected; write 1 to clear |
//! | 31 | `ECCD` | a double error was detected (NMI); write 1 to clear |

use crate::contract::{FLASH_BANK_SIZE, FLASH_BASE, N_SLOTS, SLOT0_ADDR, SLOT_SIZE};

/// Address of `FLASH_ECCR` (FLASH base 0x4002_2000 + 0x18, RM0351 §3.7.8).
pub const FLASH_ECCR_ADDR: u32 = 0x4002_2018;
/// `ADDR_ECC`, bits 18:0.
pub const ADDR_ECC_MASK: u32 = 0x0007_FFFF;
/// `BK_ECC`, bit 19.
pub const BK_ECC: u32 = 1 << 19;
/// `SYSF_ECC`, bit 20.
pub const SYSF_ECC: u32 = 1 << 20;
/// `ECCIE`, bit 24.
pub const ECCIE: u32 = 1 << 24;
/// `ECCC`, bit 30 (write 1 to clear).
pub const ECCC: u32 = 1 << 30;
/// `ECCD`, bit 31 (write 1 to clear).
pub const ECCD: u32 = 1 << 31;

/// The value to write to `FLASH_ECCR` before a record slot is read, from its value now: clears
/// `ECCC` and `ECCD` (write 1 to clear) and keeps `ECCIE`. While either flag is set the flash does
/// not update `ADDR_ECC`/`BK_ECC` for a new error (RM0351 §3.7.8, FLASH_ECCR; §3.3.2), so a
/// single error corrected earlier (in the application's flash, say) would leave its address there,
/// and a double error in the slot that follows would reach the NMI handler with the old address:
/// not a slot, so a reset, at every boot. Cleared first, the register names the slot's own error.
pub fn rearm(eccr: u32) -> u32 {
    (eccr & ECCIE) | ECCC | ECCD
}

/// What the NMI handler must do.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum NmiAction {
    /// A double ECC error in record slot `slot`: write `clear` to `FLASH_ECCR` (clears `ECCD`,
    /// keeps `ECCIE`, leaves `ECCC` alone), mark the slot unreadable and return.
    SlotUnreadable {
        /// The slot holding the failing double word.
        slot: u8,
        /// Value to write to `FLASH_ECCR`.
        clear: u32,
    },
    /// Anything else (no double ECC error, one outside the record slots, in system flash, or a
    /// clock-security NMI): reset the MCU.
    Reset,
}

/// Decides from a `FLASH_ECCR` value. Assumes the default bank mapping (option bit BFB2 = 0:
/// bank 2 at 0x0808_0000), which `accelcal flash` and the firmware never change.
pub fn nmi_action(eccr: u32) -> NmiAction {
    if eccr & ECCD == 0 || eccr & SYSF_ECC != 0 {
        return NmiAction::Reset;
    }
    let bank_start = if eccr & BK_ECC != 0 { FLASH_BASE + FLASH_BANK_SIZE } else { FLASH_BASE };
    let addr = bank_start + (eccr & ADDR_ECC_MASK);
    match addr.checked_sub(SLOT0_ADDR).map(|off| off as usize / SLOT_SIZE) {
        Some(slot) if slot < N_SLOTS => {
            NmiAction::SlotUnreadable { slot: slot as u8, clear: (eccr & ECCIE) | ECCD }
        }
        _ => NmiAction::Reset,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn double_errors_in_the_slots_mark_the_slot_everything_else_resets() {
        // Bank 2 offsets of the slots: 0x080F_F000 - 0x0808_0000 = 0x7_F000.
        let d2 = ECCD | BK_ECC;
        assert_eq!(nmi_action(d2 | 0x7_F000), NmiAction::SlotUnreadable { slot: 0, clear: ECCD });
        assert_eq!(nmi_action(d2 | 0x7_F7F8), NmiAction::SlotUnreadable { slot: 0, clear: ECCD });
        assert_eq!(nmi_action(d2 | 0x7_F800), NmiAction::SlotUnreadable { slot: 1, clear: ECCD });
        assert_eq!(nmi_action(d2 | 0x7_FFF8), NmiAction::SlotUnreadable { slot: 1, clear: ECCD });
        // ECCIE survives the clear, a pending ECCC is not cleared with it.
        assert_eq!(
            nmi_action(d2 | ECCIE | ECCC | 0x7_F808),
            NmiAction::SlotUnreadable { slot: 1, clear: ECCIE | ECCD }
        );
        // The page before the slots (application flash), the same offset in bank 1, system flash.
        assert_eq!(nmi_action(d2 | 0x7_EFF8), NmiAction::Reset);
        assert_eq!(nmi_action(ECCD | 0x7_F000), NmiAction::Reset);
        assert_eq!(nmi_action(d2 | SYSF_ECC | 0x7_F000), NmiAction::Reset);
        // No double error: a corrected one, or another NMI source (e.g. the clock security system).
        assert_eq!(nmi_action(BK_ECC | ECCC | 0x7_F000), NmiAction::Reset);
        assert_eq!(nmi_action(0), NmiAction::Reset);
        // Bits above ADDR_ECC that are not fields do not move the address.
        assert_eq!(nmi_action(d2 | 1 << 22 | 0x7_F000), NmiAction::SlotUnreadable { slot: 0, clear: ECCD });
    }

    #[test]
    fn rearming_clears_both_flags_and_keeps_the_interrupt_enable() {
        assert_eq!(rearm(0), ECCC | ECCD);
        assert_eq!(rearm(ECCIE), ECCIE | ECCC | ECCD);
        // A corrected error latched in application flash (bank 1): its address is not kept.
        assert_eq!(rearm(ECCC | ECCIE | 0x1_2340), ECCIE | ECCC | ECCD);
        assert_eq!(rearm(u32::MAX), ECCIE | ECCC | ECCD);
        // After the rearm, a double error in a slot is seen with the slot's own address.
        let latched_elsewhere = ECCC | 0x0_0100; // bank 1, application flash
        assert_eq!(nmi_action(latched_elsewhere | ECCD), NmiAction::Reset);
        assert_eq!(
            nmi_action(rearm(latched_elsewhere) & ECCIE | ECCD | BK_ECC | 0x7_F800),
            NmiAction::SlotUnreadable { slot: 1, clear: ECCD }
        );
    }

    #[test]
    fn every_eccr_value_decides_without_panicking() {
        let mut s = 0x2545_F491u32;
        for _ in 0..100_000 {
            s ^= s << 13;
            s ^= s >> 17;
            s ^= s << 5;
            if let NmiAction::SlotUnreadable { slot, clear } = nmi_action(s) {
                assert!(slot < 2 && clear & ECCD != 0 && clear & ECCC == 0);
            }
        }
    }
}
