//! Talking to the sensor node (the firmware in `firmware/`): running its QEMU build ([`qemu`]: the
//! link on a socket or a pty, the emulated front end, slot images, a gdbstub), replaying a campaign
//! through it ([`hil`]), writing a calibration record into a node's flash through a debug probe
//! or a GDB server ([`flash`], [`gdb`]), showing a node's live stream ([`monitor`]), asking it who
//! it is and what it streams ([`session`]).
//! [`link`] frames the protocol of `accelcal_shared::wire` over any byte stream.

pub mod flash;
pub mod gdb;
pub mod hil;
pub mod link;
pub mod monitor;
pub mod port;
pub mod qemu;
pub mod session;

/// Flash addresses of the two record slots (`accelcal_shared::contract`, checked against the
/// repository's `memory.x`: the last two 2 KiB pages of the STM32L475VG's 1 MiB flash).
pub const RECORD_SLOTS: [u64; 2] = [contract::SLOT_ADDRS[0] as u64, contract::SLOT_ADDRS[1] as u64];

/// Device id of the QEMU node (QEMU does not model the MCU's unique-id area). A record replayed
/// through `accelcal hil` must carry it.
pub use accelcal_shared::contract::QEMU_DEVICE_ID;

/// Whether a read that failed with `e` found nothing yet and may be tried again: its timeout
/// expired (`TimedOut`, or `WouldBlock` as a socket reports it) or a signal cut it
/// (`Interrupted`). A loop that reads again checks its own deadline or stop flag first.
pub fn read_again(e: &std::io::Error) -> bool {
    matches!(
        e.kind(),
        std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut | std::io::ErrorKind::Interrupted
    )
}

/// Address of the STM32L4's 96-bit unique device id (`accelcal_shared::contract::UID_ADDR`).
pub const UID_ADDR: u64 = contract::UID_ADDR as u64;

use accelcal_shared::contract;
