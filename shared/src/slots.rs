//! The two record slots in the node's flash: how a calibration record is stored so that a new one
//! can be written at any time without the node ever being left with none.
//!
//! Each slot is one 2 KiB flash page (the STM32L4's erase unit, RM0351 §3.3.1; addresses in
//! [`crate::contract`]) holding a slot image; all integers little-endian. Two formats are read,
//! [`SlotImage::build`] writes version 2.
//!
//! Version 2 (written since the commit moved to the end of the page):
//!
//! | offset | size | field |
//! |---|---|---|
//! | 0 | 4 | format magic `ASL2` (not a commit marker: it is programmed first) |
//! | 4 | 4 | sequence number (serial-number arithmetic: the newer of two valid slots wins) |
//! | 8 | 2 | record length R |
//! | 10 | 2 | reserved, `0xFFFF` |
//! | 12 | 4 | CRC-32 of bytes 4..12 and of the record |
//! | 16 | R | the calibration record ([`crate::record`]) |
//! | 16+R | … | erased (`0xFF`) |
//! | 2040 | 4 | commit magic `CMT2` — in the page's last double word, programmed last |
//! | 2044 | 4 | copy of the CRC at offset 12 (ties the commit to this write) |
//!
//! Version 1 (read only): the same header with magic `ASL1` at offset 0 as the commit marker and
//! no commit double word. It relied on a writer programming the first double word last, which the
//! probe-rs STM32L4 flash loader does not do.
//!
//! A write goes to the slot that is *not* in force. `accelcal flash` hands the whole page to the
//! probe-rs flash loader, which erases it and programs every double word in ascending address order
//! ([`WritePlan::program_order`]). The commit double word is the last one programmed: until it is
//! complete the slot is not valid and the old record stays in force; once it is, the new slot's
//! higher sequence number makes it the active one. A torn write (power cut during erase or
//! programming) leaves the target slot without its commit, failing its CRC, or with a double word
//! whose ECC does not match (unreadable: the node's NMI handler turns that into
//! [`SlotError::Unreadable`], see [`crate::flash_ecc`]); never a mix.
//!
//! This module holds the board-independent logic: [`select_readings`] (which slot is in force,
//! used by the boot decision [`crate::boot::decide`]), [`SlotImage`] (the formats), [`WritePlan`]
//! and [`write_record`] (the write sequence over any [`SlotFlash`]). No-panic contract:
//! [`select`], [`select_readings`] and [`SlotImage::parse`] accept any bytes.

pub use crate::contract::{N_SLOTS, SLOT_SIZE};
use crate::record::{Record, RecordError, MAX_RECORD_LEN};

/// The version-1 format magic at offset 0, which was also its commit marker.
pub const SLOT_MAGIC_V1: [u8; 4] = *b"ASL1";
/// The version-2 format magic at offset 0.
pub const SLOT_MAGIC_V2: [u8; 4] = *b"ASL2";
/// The version-2 commit magic, at [`COMMIT_OFFSET`].
pub const COMMIT_MAGIC: [u8; 4] = *b"CMT2";
/// Offset of the version-2 commit double word: the page's last double word.
pub const COMMIT_OFFSET: usize = SLOT_SIZE - PROGRAM_UNIT;
/// Bytes before the record.
pub const SLOT_HEADER_LEN: usize = 16;
/// Flash programming unit: a 64-bit double word (RM0351 §3.3.7).
pub const PROGRAM_UNIT: usize = 8;

const _: () = assert!(SLOT_HEADER_LEN + MAX_RECORD_LEN <= COMMIT_OFFSET);

/// Why a slot image is not valid.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum SlotError {
    /// The slot is shorter than its header, its record length, or (version 2) a whole page.
    Truncated,
    /// No commit: the slot is erased or its write did not finish.
    NotCommitted,
    /// The slot's CRC does not match (torn write or corruption).
    BadCrc,
    /// The record length field is larger than any record, or is not its record's length.
    BadLength,
    /// The record does not parse (see [`RecordError`]).
    Record(RecordError),
    /// The slot could not be read: a double word failed its ECC check (a write or erase cut by a
    /// power loss).
    Unreadable,
}

impl SlotError {
    /// How much the error says about the slot: a committed but bad slot says more than an
    /// unreadable one, which says more than an empty one.
    fn weight(self) -> u8 {
        match self {
            SlotError::NotCommitted => 0,
            SlotError::Unreadable => 1,
            _ => 2,
        }
    }
}

impl core::fmt::Display for SlotError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            SlotError::Truncated => f.write_str("record slot is truncated"),
            SlotError::NotCommitted => f.write_str("record slot is empty or its write did not finish"),
            SlotError::BadCrc => f.write_str("record slot CRC mismatch"),
            SlotError::BadLength => {
                f.write_str("record slot length field is out of range or disagrees with its record")
            }
            SlotError::Record(e) => write!(f, "record slot holds an invalid record: {e}"),
            SlotError::Unreadable => {
                f.write_str("record slot is unreadable (flash ECC error: a write or erase was cut)")
            }
        }
    }
}

#[cfg(feature = "std")]
impl std::error::Error for SlotError {}

/// A valid slot: its format version, sequence number and the record bytes it holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SlotImage<'a> {
    /// Slot format version, 1 or 2.
    pub version: u8,
    /// Write sequence number.
    pub sequence: u32,
    /// The record, exactly `length` bytes.
    pub record: &'a [u8],
}

impl<'a> SlotImage<'a> {
    /// Checks a slot's bytes (version 2: the whole page; version 1: at least header and record).
    /// The record itself is also parsed, so a valid slot always holds a parseable record, exactly
    /// the length field's bytes long.
    pub fn parse(slot: &'a [u8]) -> Result<SlotImage<'a>, SlotError> {
        if slot.len() < SLOT_HEADER_LEN {
            return Err(SlotError::Truncated);
        }
        let version = match [slot[0], slot[1], slot[2], slot[3]] {
            SLOT_MAGIC_V1 => 1,
            SLOT_MAGIC_V2 => 2,
            _ => return Err(SlotError::NotCommitted),
        };
        let crc = [slot[12], slot[13], slot[14], slot[15]];
        if version == 2 {
            let commit = slot.get(COMMIT_OFFSET..SLOT_SIZE).ok_or(SlotError::Truncated)?;
            if commit[0..4] != COMMIT_MAGIC || commit[4..8] != crc {
                return Err(SlotError::NotCommitted);
            }
        }
        let len = u16::from_le_bytes([slot[8], slot[9]]) as usize;
        if len > MAX_RECORD_LEN {
            return Err(SlotError::BadLength);
        }
        if slot.len() < SLOT_HEADER_LEN + len {
            return Err(SlotError::Truncated);
        }
        let record = &slot[SLOT_HEADER_LEN..SLOT_HEADER_LEN + len];
        if slot_crc(&slot[4..12], record) != u32::from_le_bytes(crc) {
            return Err(SlotError::BadCrc);
        }
        if Record::parse(record).map_err(SlotError::Record)?.len() != len {
            return Err(SlotError::BadLength);
        }
        let sequence = u32::from_le_bytes([slot[4], slot[5], slot[6], slot[7]]);
        Ok(SlotImage { version, sequence, record })
    }

    /// Builds the full version-2 page image (erased bytes `0xFF` between the record and the
    /// commit double word) for `record` with `sequence`. The record must parse.
    pub fn build(record: &[u8], sequence: u32) -> Result<[u8; SLOT_SIZE], SlotError> {
        let mut page = Self::build_header(SLOT_MAGIC_V2, record, sequence)?;
        page[COMMIT_OFFSET..COMMIT_OFFSET + 4].copy_from_slice(&COMMIT_MAGIC);
        let crc = [page[12], page[13], page[14], page[15]];
        page[COMMIT_OFFSET + 4..SLOT_SIZE].copy_from_slice(&crc);
        Ok(page)
    }

    /// Builds a version-1 page image, as nodes written before version 2 hold it (for tests and
    /// tools that must produce old slots; writers use [`SlotImage::build`]).
    pub fn build_v1(record: &[u8], sequence: u32) -> Result<[u8; SLOT_SIZE], SlotError> {
        Self::build_header(SLOT_MAGIC_V1, record, sequence)
    }

    fn build_header(magic: [u8; 4], record: &[u8], sequence: u32) -> Result<[u8; SLOT_SIZE], SlotError> {
        let rec = Record::parse(record).map_err(SlotError::Record)?;
        let record = &record[..rec.len()];
        let mut page = [0xffu8; SLOT_SIZE];
        page[0..4].copy_from_slice(&magic);
        page[4..8].copy_from_slice(&sequence.to_le_bytes());
        page[8..10].copy_from_slice(&(record.len() as u16).to_le_bytes());
        page[10..12].copy_from_slice(&[0xff, 0xff]);
        let crc = slot_crc(&page[4..12], record);
        page[12..16].copy_from_slice(&crc.to_le_bytes());
        page[SLOT_HEADER_LEN..SLOT_HEADER_LEN + record.len()].copy_from_slice(record);
        Ok(page)
    }
}

fn slot_crc(header: &[u8], record: &[u8]) -> u32 {
    // Bit by bit, as `record::crc32` (no 1 KiB table in the node's flash).
    const CRC: crc::Crc<u32, crc::NoTable> = crc::Crc::<u32, crc::NoTable>::new(&crc::CRC_32_ISO_HDLC);
    let mut d = CRC.digest();
    d.update(header);
    d.update(record);
    d.finalize()
}

/// True when sequence `a` is newer than `b` (serial-number arithmetic, so it survives wrap-around).
pub fn is_newer(a: u32, b: u32) -> bool {
    (a.wrapping_sub(b) as i32) > 0
}

/// What reading one slot gave: its bytes, or `None` when a double word of it could not be read
/// (flash ECC error).
pub type SlotReading<'a> = Option<&'a [u8]>;

/// Checks one slot reading: an unreadable slot is [`SlotError::Unreadable`].
pub fn parse_reading(reading: SlotReading<'_>) -> Result<SlotImage<'_>, SlotError> {
    reading.map_or(Err(SlotError::Unreadable), SlotImage::parse)
}

/// The slot in force and its contents.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Active<'a> {
    /// Slot index, 0 or 1.
    pub slot: u8,
    /// The slot's contents.
    pub image: SlotImage<'a>,
}

/// Chooses the slot in force from two slot readings: the valid one, or of two valid ones the newer
/// (slot 0 on a tie). When neither is valid, returns the more informative of the two errors (a
/// committed but bad slot beats an unreadable one, which beats an empty one; slot 0 on a tie).
pub fn select_readings<'a>(readings: [SlotReading<'a>; N_SLOTS]) -> Result<Active<'a>, SlotError> {
    let a = parse_reading(readings[0]);
    let b = parse_reading(readings[1]);
    match (a, b) {
        (Ok(a), Ok(b)) if is_newer(b.sequence, a.sequence) => Ok(Active { slot: 1, image: b }),
        (Ok(a), _) => Ok(Active { slot: 0, image: a }),
        (Err(_), Ok(b)) => Ok(Active { slot: 1, image: b }),
        (Err(ea), Err(eb)) => Err(if eb.weight() > ea.weight() { eb } else { ea }),
    }
}

/// [`select_readings`] for two slots that were both read.
pub fn select<'a>(slots: [&'a [u8]; N_SLOTS]) -> Result<Active<'a>, SlotError> {
    select_readings(slots.map(Some))
}

/// Where and what a writer programs next, given the current slot contents.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct WritePlan {
    /// The slot to erase and program (the one not in force; an unreadable slot is never in force).
    pub slot: u8,
    /// Its sequence number (one more than the slot in force, or 1).
    pub sequence: u32,
    /// The full page to program (version 2).
    pub page: [u8; SLOT_SIZE],
}

impl WritePlan {
    /// Plans writing `record` next to the current slot readings.
    pub fn from_readings(
        readings: [SlotReading<'_>; N_SLOTS],
        record: &[u8],
    ) -> Result<WritePlan, SlotError> {
        let (slot, sequence) = match select_readings(readings) {
            Ok(active) => (1 - active.slot, active.image.sequence.wrapping_add(1)),
            Err(_) => (0, 1),
        };
        let page = SlotImage::build(record, sequence)?;
        Ok(WritePlan { slot, sequence, page })
    }

    /// Plans writing `record` next to two slots that were both read.
    pub fn new(slots: [&[u8]; N_SLOTS], record: &[u8]) -> Result<WritePlan, SlotError> {
        Self::from_readings(slots.map(Some), record)
    }

    /// Offsets of the double words to program after the page erase, in the order the probe-rs
    /// STM32L4 flash loader programs a page it is given whole: every double word (erased ones
    /// included), ascending. The commit double word ([`COMMIT_OFFSET`]) comes last.
    pub fn program_order(&self) -> impl Iterator<Item = usize> {
        (0..SLOT_SIZE).step_by(PROGRAM_UNIT)
    }
}

/// How one slot read went (the bytes go to the caller's buffer).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SlotRead {
    /// Every double word was read.
    Complete,
    /// A double word failed its ECC check; the buffer's contents mean nothing.
    Unreadable,
}

/// Flash holding the record slots, as a writer sees it.
pub trait SlotFlash {
    /// Error of the underlying flash.
    type Error;
    /// Reads a whole slot.
    fn read(&mut self, slot: u8, out: &mut [u8; SLOT_SIZE]) -> Result<SlotRead, Self::Error>;
    /// Erases one slot's page (every byte becomes `0xFF`).
    fn erase(&mut self, slot: u8) -> Result<(), Self::Error>;
    /// Programs one double word at `offset` (a multiple of [`PROGRAM_UNIT`]) of an erased slot.
    fn program(&mut self, slot: u8, offset: usize, dword: [u8; PROGRAM_UNIT]) -> Result<(), Self::Error>;
}

/// Why [`write_record`] failed.
#[derive(Debug, PartialEq, Eq)]
pub enum WriteError<E> {
    /// The record is not valid; nothing was written.
    Slot(SlotError),
    /// The flash failed.
    Flash(E),
    /// Read-back after writing does not select the new record.
    Verify,
}

/// Reads both slots into `bufs`; the readings borrow them.
fn read_both<'b, F: SlotFlash>(
    flash: &mut F,
    bufs: &'b mut [[u8; SLOT_SIZE]; N_SLOTS],
) -> Result<[SlotReading<'b>; N_SLOTS], F::Error> {
    let [a, b] = bufs;
    let ra = flash.read(0, a)?;
    let rb = flash.read(1, b)?;
    let pick = |r: SlotRead, buf: &'b [u8; SLOT_SIZE]| (r == SlotRead::Complete).then_some(&buf[..]);
    Ok([pick(ra, a), pick(rb, b)])
}

/// Writes `record` into the slot not in force the way `accelcal flash` does (erase the page, then
/// every double word in ascending order, [`WritePlan::program_order`]), then reads back and checks
/// that the new record is the one in force. Returns the plan that was carried out.
pub fn write_record<F: SlotFlash>(flash: &mut F, record: &[u8]) -> Result<WritePlan, WriteError<F::Error>> {
    let mut bufs = [[0u8; SLOT_SIZE]; N_SLOTS];
    let readings = read_both(flash, &mut bufs).map_err(WriteError::Flash)?;
    let plan = WritePlan::from_readings(readings, record).map_err(WriteError::Slot)?;
    flash.erase(plan.slot).map_err(WriteError::Flash)?;
    for off in plan.program_order() {
        let mut dw = [0u8; PROGRAM_UNIT];
        dw.copy_from_slice(&plan.page[off..off + PROGRAM_UNIT]);
        flash.program(plan.slot, off, dw).map_err(WriteError::Flash)?;
    }
    let readings = read_both(flash, &mut bufs).map_err(WriteError::Flash)?;
    match select_readings(readings) {
        Ok(act) if act.slot == plan.slot && act.image.sequence == plan.sequence => Ok(plan),
        _ => Err(WriteError::Verify),
    }
}

#[cfg(test)]
#[path = "slots_tests.rs"]
mod tests;
