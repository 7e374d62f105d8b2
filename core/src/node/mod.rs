//! Talking to the sensor node (the firmware in `firmware/`): replaying a campaign through the QEMU
//! build ([`hil`]), writing a calibration record into a real node's flash through a debug probe
//! ([`flash`]), and showing a node's live stream ([`monitor`]). [`link`] frames the protocol of
//! `accelcal_shared::wire` over any byte stream.

pub mod flash;
pub mod hil;
pub mod link;
pub mod monitor;

/// Flash addresses of the two record slots (the repository's `memory.x`: the last two 2 KiB pages
/// of the STM32L475VG's 1 MiB flash).
pub const RECORD_SLOTS: [u64; 2] = [0x080F_F000, 0x080F_F800];

/// Device id of the QEMU node (QEMU does not model the MCU's unique-id area). A record replayed
/// through `accelcal hil` must carry it; see `firmware/src/board/qemu/mod.rs`.
pub const QEMU_DEVICE_ID: [u8; 12] = *b"QEMU-B-L475E";

/// Address of the STM32L4's 96-bit unique device id (RM0351 §50.1).
pub const UID_ADDR: u64 = 0x1FFF_7590;
