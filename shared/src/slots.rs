//! The two record slots in the node's flash: how a calibration record is stored so that a new one
//! can be written at any time without the node ever being left with none.
//!
//! Each slot is one 2 KiB flash page (the STM32L4's erase unit, RM0351 §3.3.1) holding a slot
//! image; all integers little-endian:
//!
//! | offset | size | field |
//! |---|---|---|
//! | 0 | 4 | slot magic `ASL1` — the commit marker, programmed last |
//! | 4 | 4 | sequence number (serial-number arithmetic: the newer of two valid slots wins) |
//! | 8 | 2 | record length R |
//! | 10 | 2 | reserved, `0xFFFF` |
//! | 12 | 4 | CRC-32 of bytes 4..12 and of the record |
//! | 16 | R | the calibration record ([`crate::record`]) |
//! | 16+R | … | erased (`0xFF`) |
//!
//! A write goes to the slot that is *not* in force: erase its page, program the record and the
//! header's second double word, and program the double word holding the magic last. Until that
//! last double word is in, the slot is not valid and the old record stays in force; once it is,
//! the new slot's higher sequence number makes it the active one. A torn write (power cut during
//! erase or programming) leaves the target slot failing its magic or CRC check, never a mix.
//!
//! This module holds the board-independent logic: [`select`] (the node's boot-time choice),
//! [`SlotImage`] (what a writer programs) and [`write_record`] (the write sequence over any
//! [`SlotFlash`]). No-panic contract: [`select`] and [`SlotImage::parse`] accept any bytes.

use crate::record::{Record, RecordError, MAX_RECORD_LEN};

/// Size of one slot: one flash page of the STM32L4 (RM0351 §3.3.1, 2 KiB pages).
pub const SLOT_SIZE: usize = 2048;
/// Number of slots.
pub const N_SLOTS: usize = 2;
/// The commit marker at the start of a valid slot.
pub const SLOT_MAGIC: [u8; 4] = *b"ASL1";
/// Bytes before the record.
pub const SLOT_HEADER_LEN: usize = 16;
/// Flash programming unit: a 64-bit double word (RM0351 §3.3.7).
pub const PROGRAM_UNIT: usize = 8;

const _: () = assert!(SLOT_HEADER_LEN + MAX_RECORD_LEN <= SLOT_SIZE);

/// Why a slot image is not valid.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SlotError {
    /// The slot is shorter than its header or than its record length says.
    Truncated,
    /// No commit marker: the slot is erased or its write did not finish.
    NotCommitted,
    /// The slot's CRC does not match (torn write or corruption).
    BadCrc,
    /// The record length field is larger than any record, or is not its record's length.
    BadLength,
    /// The record does not parse (see [`RecordError`]).
    Record(RecordError),
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
        }
    }
}

#[cfg(feature = "std")]
impl std::error::Error for SlotError {}

/// A valid slot: its sequence number and the record bytes it holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SlotImage<'a> {
    /// Write sequence number.
    pub sequence: u32,
    /// The record, exactly `length` bytes.
    pub record: &'a [u8],
}

impl<'a> SlotImage<'a> {
    /// Checks a slot's bytes (its whole page, or at least header and record). The record itself is
    /// also parsed, so a valid slot always holds a parseable record, exactly the length field's
    /// bytes long.
    pub fn parse(slot: &'a [u8]) -> Result<SlotImage<'a>, SlotError> {
        if slot.len() < SLOT_HEADER_LEN {
            return Err(SlotError::Truncated);
        }
        if slot[0..4] != SLOT_MAGIC {
            return Err(SlotError::NotCommitted);
        }
        let len = u16::from_le_bytes([slot[8], slot[9]]) as usize;
        if len > MAX_RECORD_LEN {
            return Err(SlotError::BadLength);
        }
        if slot.len() < SLOT_HEADER_LEN + len {
            return Err(SlotError::Truncated);
        }
        let record = &slot[SLOT_HEADER_LEN..SLOT_HEADER_LEN + len];
        let want = u32::from_le_bytes([slot[12], slot[13], slot[14], slot[15]]);
        if slot_crc(&slot[4..12], record) != want {
            return Err(SlotError::BadCrc);
        }
        if Record::parse(record).map_err(SlotError::Record)?.len() != len {
            return Err(SlotError::BadLength);
        }
        let sequence = u32::from_le_bytes([slot[4], slot[5], slot[6], slot[7]]);
        Ok(SlotImage { sequence, record })
    }

    /// Builds the full page image (erased bytes `0xFF` after the record) for `record` with
    /// `sequence`. The record must parse.
    pub fn build(record: &[u8], sequence: u32) -> Result<[u8; SLOT_SIZE], SlotError> {
        let rec = Record::parse(record).map_err(SlotError::Record)?;
        let record = &record[..rec.len()];
        let mut page = [0xffu8; SLOT_SIZE];
        page[0..4].copy_from_slice(&SLOT_MAGIC);
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
    const CRC: crc::Crc<u32> = crc::Crc::<u32>::new(&crc::CRC_32_ISO_HDLC);
    let mut d = CRC.digest();
    d.update(header);
    d.update(record);
    d.finalize()
}

/// True when sequence `a` is newer than `b` (serial-number arithmetic, so it survives wrap-around).
pub fn is_newer(a: u32, b: u32) -> bool {
    (a.wrapping_sub(b) as i32) > 0
}

/// The slot in force and its contents.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Active<'a> {
    /// Slot index, 0 or 1.
    pub slot: u8,
    /// The slot's contents.
    pub image: SlotImage<'a>,
}

/// Chooses the slot in force: the valid one, or of two valid ones the newer (slot 0 on a tie).
/// When neither is valid, returns the more informative of the two errors (a committed but bad
/// slot beats an empty one).
pub fn select<'a>(slots: [&'a [u8]; N_SLOTS]) -> Result<Active<'a>, SlotError> {
    let a = SlotImage::parse(slots[0]);
    let b = SlotImage::parse(slots[1]);
    match (a, b) {
        (Ok(a), Ok(b)) if is_newer(b.sequence, a.sequence) => Ok(Active { slot: 1, image: b }),
        (Ok(a), _) => Ok(Active { slot: 0, image: a }),
        (Err(_), Ok(b)) => Ok(Active { slot: 1, image: b }),
        (Err(ea), Err(eb)) => Err(if ea == SlotError::NotCommitted { eb } else { ea }),
    }
}

/// Where and what a writer programs next, given the current slot contents.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct WritePlan {
    /// The slot to erase and program (the one not in force).
    pub slot: u8,
    /// Its sequence number (one more than the slot in force, or 1).
    pub sequence: u32,
    /// The full page to program.
    pub page: [u8; SLOT_SIZE],
    /// Bytes of `page` that must be programmed (record and header rounded up to double words);
    /// the rest stays erased.
    pub used: usize,
}

impl WritePlan {
    /// Plans writing `record` next to the current `slots` contents.
    pub fn new(slots: [&[u8]; N_SLOTS], record: &[u8]) -> Result<WritePlan, SlotError> {
        let (slot, sequence) = match select(slots) {
            Ok(active) => (1 - active.slot, active.image.sequence.wrapping_add(1)),
            Err(_) => (0, 1),
        };
        let page = SlotImage::build(record, sequence)?;
        let len = u16::from_le_bytes([page[8], page[9]]) as usize;
        let used = (SLOT_HEADER_LEN + len).div_ceil(PROGRAM_UNIT) * PROGRAM_UNIT;
        Ok(WritePlan { slot, sequence, page, used })
    }

    /// Offsets of the double words to program, in the torn-write-safe order: the record, then the
    /// header's second double word, the commit marker's double word last.
    pub fn program_order(&self) -> impl Iterator<Item = usize> + '_ {
        (SLOT_HEADER_LEN..self.used).step_by(PROGRAM_UNIT).chain([PROGRAM_UNIT, 0])
    }
}

/// Flash holding the record slots, as a writer sees it.
pub trait SlotFlash {
    /// Error of the underlying flash.
    type Error;
    /// Reads a whole slot.
    fn read(&mut self, slot: u8, out: &mut [u8; SLOT_SIZE]) -> Result<(), Self::Error>;
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

/// Writes `record` into the slot not in force, in the torn-write-safe order, then reads back and
/// checks that the new record is the one in force. Returns the plan that was carried out.
pub fn write_record<F: SlotFlash>(flash: &mut F, record: &[u8]) -> Result<WritePlan, WriteError<F::Error>> {
    let mut a = [0u8; SLOT_SIZE];
    let mut b = [0u8; SLOT_SIZE];
    flash.read(0, &mut a).map_err(WriteError::Flash)?;
    flash.read(1, &mut b).map_err(WriteError::Flash)?;
    let plan = WritePlan::new([&a, &b], record).map_err(WriteError::Slot)?;
    flash.erase(plan.slot).map_err(WriteError::Flash)?;
    for off in plan.program_order() {
        let mut dw = [0u8; PROGRAM_UNIT];
        dw.copy_from_slice(&plan.page[off..off + PROGRAM_UNIT]);
        flash.program(plan.slot, off, dw).map_err(WriteError::Flash)?;
    }
    flash.read(0, &mut a).map_err(WriteError::Flash)?;
    flash.read(1, &mut b).map_err(WriteError::Flash)?;
    match select([&a, &b]) {
        Ok(act) if act.slot == plan.slot && act.image.sequence == plan.sequence => Ok(plan),
        _ => Err(WriteError::Verify),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::record::MAX_CHANNELS;
    use crate::terms::{MODEL_4, N_BASIS};

    fn record_bytes(tag: f64) -> std::vec::Vec<u8> {
        let mut r = Record {
            device_id: *b"QEMU-B-L475E",
            created_unix_s: 1_800_000_000 + tag as u64,
            structure: MODEL_4,
            n_channels: 3,
            coefficients: [[0.0; N_BASIS]; MAX_CHANNELS],
        };
        r.coefficients[0][..4].copy_from_slice(&[32000.0 + tag, 1670.0, 3.0, -2.0]);
        r.coefficients[1][..4].copy_from_slice(&[33000.0, 1.5, 1650.0 + tag, 4.0]);
        r.coefficients[2][..4].copy_from_slice(&[31000.0, -2.5, 0.5, 1690.0]);
        let mut buf = [0u8; MAX_RECORD_LEN];
        let n = r.emit(&mut buf).unwrap();
        buf[..n].to_vec()
    }

    /// How an operation is interrupted by the power cut.
    #[derive(Clone, Copy, Debug)]
    enum Cut {
        /// Power fails after `n` whole operations.
        After(usize),
        /// Power fails in the middle of operation `n`: an erase leaves the first `k` bytes erased,
        /// a program leaves only the first `k` bytes of the double word programmed.
        During(usize, usize),
    }

    /// A simulated STM32L4 flash with two slot pages: erase sets 0xFF, programming requires an
    /// erased double word (as the real part, which flags PROGERR otherwise), and power can fail.
    struct SimFlash {
        pages: [[u8; SLOT_SIZE]; 2],
        ops: usize,
        cut: Option<Cut>,
    }

    #[derive(Debug, PartialEq, Eq)]
    enum SimError {
        PowerLost,
        ProgramNotErased,
    }

    impl SimFlash {
        fn new() -> Self {
            SimFlash { pages: [[0xff; SLOT_SIZE]; 2], ops: 0, cut: None }
        }
        /// Counts an operation; returns `Some(k)` for a torn operation, Err for a dead one.
        fn tick(&mut self) -> Result<Option<usize>, SimError> {
            let n = self.ops;
            self.ops += 1;
            match self.cut {
                Some(Cut::After(m)) if n >= m => Err(SimError::PowerLost),
                Some(Cut::During(m, _)) if n > m => Err(SimError::PowerLost),
                Some(Cut::During(m, k)) if n == m => Ok(Some(k)),
                _ => Ok(None),
            }
        }
        fn reboot(&mut self) {
            self.cut = None;
            self.ops = 0;
        }
    }

    impl SlotFlash for SimFlash {
        type Error = SimError;
        fn read(&mut self, slot: u8, out: &mut [u8; SLOT_SIZE]) -> Result<(), SimError> {
            *out = self.pages[slot as usize];
            Ok(())
        }
        fn erase(&mut self, slot: u8) -> Result<(), SimError> {
            let torn = self.tick()?;
            let page = &mut self.pages[slot as usize];
            match torn {
                None => page.fill(0xff),
                Some(k) => {
                    page[..k.min(SLOT_SIZE)].fill(0xff);
                    return Err(SimError::PowerLost);
                }
            }
            Ok(())
        }
        fn program(&mut self, slot: u8, off: usize, dw: [u8; PROGRAM_UNIT]) -> Result<(), SimError> {
            let torn = self.tick()?;
            let cell = &mut self.pages[slot as usize][off..off + PROGRAM_UNIT];
            if cell.iter().any(|&b| b != 0xff) {
                return Err(SimError::ProgramNotErased);
            }
            match torn {
                None => cell.copy_from_slice(&dw),
                Some(k) => {
                    // Programming only clears bits: a torn write leaves some bytes programmed.
                    cell[..k].copy_from_slice(&dw[..k]);
                    return Err(SimError::PowerLost);
                }
            }
            Ok(())
        }
    }

    fn boot(f: &SimFlash) -> Result<(u8, u32, std::vec::Vec<u8>), SlotError> {
        let act = select([&f.pages[0], &f.pages[1]])?;
        Ok((act.slot, act.image.sequence, act.image.record.to_vec()))
    }

    #[test]
    fn first_write_goes_to_slot_0_then_alternates() {
        let mut f = SimFlash::new();
        assert_eq!(boot(&f), Err(SlotError::NotCommitted));
        let r1 = record_bytes(1.0);
        let r2 = record_bytes(2.0);
        let p = write_record(&mut f, &r1).unwrap();
        assert_eq!((p.slot, p.sequence), (0, 1));
        assert_eq!(boot(&f).unwrap(), (0, 1, r1.clone()));
        let p = write_record(&mut f, &r2).unwrap();
        assert_eq!((p.slot, p.sequence), (1, 2));
        assert_eq!(boot(&f).unwrap(), (1, 2, r2.clone()));
        let p = write_record(&mut f, &r1).unwrap();
        assert_eq!((p.slot, p.sequence), (0, 3));
        assert_eq!(boot(&f).unwrap(), (0, 3, r1));
    }

    #[test]
    fn page_literal_header_bytes() {
        let r = record_bytes(0.0);
        let page = SlotImage::build(&r, 0x0102_0304).unwrap();
        // Model 4, three channels: 30 + 4 + 8·3·4 + 4 = 134 = 0x86 record bytes.
        assert_eq!(r.len(), 0x86);
        assert_eq!(&page[0..12], b"ASL1\x04\x03\x02\x01\x86\x00\xff\xff");
        assert_eq!(page[12..16], crc32_of(&page[4..12], &r).to_le_bytes());
        assert_eq!(&page[16..16 + r.len()], &r[..]);
        assert!(page[16 + r.len()..].iter().all(|&b| b == 0xff));
    }

    fn crc32_of(header: &[u8], record: &[u8]) -> u32 {
        let mut all = header.to_vec();
        all.extend_from_slice(record);
        crate::record::crc32(&all)
    }

    #[test]
    fn wrap_around_sequence_still_picks_the_newer() {
        let r1 = record_bytes(1.0);
        let r2 = record_bytes(2.0);
        let a = SlotImage::build(&r1, u32::MAX).unwrap();
        let b = SlotImage::build(&r2, 0).unwrap();
        assert_eq!(select([&a, &b]).unwrap().slot, 1);
        assert_eq!(select([&b, &a]).unwrap().slot, 0);
    }

    /// Power fails after every single flash operation, and in the middle of each at several byte
    /// counts; after each failure the node must boot with the old or the new record, whole.
    #[test]
    fn power_cut_at_every_operation_leaves_old_or_new() {
        let old = record_bytes(1.0);
        let new = record_bytes(2.0);
        // Start states: one record in slot 0, or (after an earlier update) in slot 1 with an older
        // record still in slot 0.
        let mut starts = std::vec::Vec::new();
        let mut f = SimFlash::new();
        write_record(&mut f, &old).unwrap();
        starts.push(f.pages);
        let mut f = SimFlash::new();
        write_record(&mut f, &record_bytes(7.0)).unwrap();
        write_record(&mut f, &old).unwrap();
        starts.push(f.pages);

        let mut checked = 0;
        for start in starts {
            // A full write's operation count: 1 erase + the programmed double words.
            let mut probe = SimFlash { pages: start, ops: 0, cut: None };
            write_record(&mut probe, &new).unwrap();
            let n_ops = probe.ops;
            assert_eq!(n_ops, 1 + (SLOT_HEADER_LEN + old.len()).div_ceil(PROGRAM_UNIT));
            let mut cuts: std::vec::Vec<Cut> = (0..=n_ops).map(Cut::After).collect();
            for m in 0..n_ops {
                for k in [1, 3, 7] {
                    cuts.push(Cut::During(m, k));
                }
            }
            cuts.push(Cut::During(0, 1000));
            for cut in cuts {
                let mut f = SimFlash { pages: start, ops: 0, cut: Some(cut) };
                let res = write_record(&mut f, &new);
                f.reboot();
                let (_, seq, rec) = boot(&f).unwrap_or_else(|e| panic!("{cut:?}: no record: {e}"));
                assert!(rec == old || rec == new, "{cut:?}: a mix");
                match cut {
                    Cut::After(m) if m >= n_ops => {
                        assert!(res.is_ok());
                        assert_eq!(rec, new);
                    }
                    _ => {
                        assert!(res.is_err(), "{cut:?}");
                        // The new record is in force only once its commit marker is complete.
                        if rec == new {
                            assert!(matches!(cut, Cut::After(m) if m == n_ops), "{cut:?}");
                        }
                    }
                }
                // The node can always be updated again after the failure.
                let p = write_record(&mut f, &new).unwrap();
                assert_eq!(p.sequence, seq.wrapping_add(1));
                assert_eq!(boot(&f).unwrap().2, new);
                checked += 1;
            }
        }
        assert_eq!(checked, 2 * (21 + 3 * 20 + 1));
    }

    #[test]
    fn corrupted_slots_are_named() {
        let r = record_bytes(1.0);
        let page = SlotImage::build(&r, 1).unwrap();
        let mut bad = page;
        bad[100] ^= 0x10;
        assert_eq!(SlotImage::parse(&bad), Err(SlotError::BadCrc));
        assert_eq!(SlotImage::parse(&page[..10]), Err(SlotError::Truncated));
        assert_eq!(SlotImage::parse(&page[..40]), Err(SlotError::Truncated));
        let mut long = page;
        long[8..10].copy_from_slice(&0xffffu16.to_le_bytes());
        assert_eq!(SlotImage::parse(&long), Err(SlotError::BadLength));
        // A length field covering the record and erased bytes after it, with the slot CRC made to
        // match: the record parses (it ignores trailing bytes), the slot is still refused (found by
        // the fuzzer, fuzz/src/slots.rs).
        let mut padded = page;
        padded[8..10].copy_from_slice(&(r.len() as u16 + 8).to_le_bytes());
        let crc = crc32_of(&padded[4..12], &padded[16..16 + r.len() + 8]);
        padded[12..16].copy_from_slice(&crc.to_le_bytes());
        assert!(Record::parse(&padded[16..16 + r.len() + 8]).is_ok());
        assert_eq!(SlotImage::parse(&padded), Err(SlotError::BadLength));
        assert_eq!(select([&[0xff; SLOT_SIZE], &bad]), Err(SlotError::BadCrc));
        assert_eq!(select([&[0; SLOT_SIZE], &[0xff; SLOT_SIZE]]), Err(SlotError::NotCommitted));
        assert_eq!(SlotImage::build(&r[..20], 1), Err(SlotError::Record(RecordError::Truncated)));
    }

    #[test]
    fn random_bytes_never_panic() {
        let mut s = 0x9E37_79B9_7F4A_7C15u64;
        let page = SlotImage::build(&record_bytes(1.0), 1).unwrap();
        for i in 0..5000 {
            let mut p = page;
            for _ in 0..(i % 8 + 1) {
                s ^= s << 13;
                s ^= s >> 7;
                s ^= s << 17;
                p[(s % 64) as usize] = (s >> 40) as u8;
            }
            let _ = select([&p, &page[..(s % 2048) as usize]]);
        }
    }
}
