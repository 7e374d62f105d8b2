//! Tests of the record slots: formats, selection, and the power-cut simulation of a write in the
//! order `accelcal flash` really uses, on a simulated STM32L4 flash with its failure modes.

use super::*;
use crate::boot::{self, Arithmetic};
use crate::record::MAX_CHANNELS;
use crate::terms::{MODEL_4, N_BASIS};

const ID: [u8; 12] = *b"QEMU-B-L475E";

fn record_bytes(tag: f64) -> std::vec::Vec<u8> {
    let mut r = Record {
        device_id: ID,
        created_unix_s: 1_800_000_000 + tag as u64,
        structure: MODEL_4,
        n_channels: 3,
        coefficients: [[0.0; N_BASIS]; MAX_CHANNELS],
        g_m_s2: None,
        thermal: None,
    };
    r.coefficients[0][..4].copy_from_slice(&[32000.0 + tag, 1670.0, 3.0, -2.0]);
    r.coefficients[1][..4].copy_from_slice(&[33000.0, 1.5, 1650.0 + tag, 4.0]);
    r.coefficients[2][..4].copy_from_slice(&[31000.0, -2.5, 0.5, 1690.0]);
    let mut buf = [0u8; MAX_RECORD_LEN];
    let n = r.emit(&mut buf).unwrap();
    buf[..n].to_vec()
}

/// Double words in a page.
const DWORDS: usize = SLOT_SIZE / PROGRAM_UNIT;

/// One double word of the simulated flash.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Dw {
    /// Erased: reads `0xFF`, may be programmed.
    Erased,
    /// Programmed (data and ECC written): reads its data, cannot be programmed again before an
    /// erase (the STM32L4 flags PROGERR).
    Programmed([u8; PROGRAM_UNIT]),
    /// Data and ECC inconsistent after a cut: reading it raises a double ECC error.
    Unreadable,
}

/// How a power cut tears the operation it interrupts.
#[derive(Clone, Copy, Debug)]
enum Tear {
    /// Program: the double word is left with inconsistent ECC.
    ProgramUnreadable,
    /// Program: only the first `k` bytes took their value (ECC happens to be consistent).
    ProgramPartial(usize),
    /// Erase: the first `k` double words are erased, the next one is unreadable, the rest hold
    /// their old contents.
    ErasePrefix(usize),
    /// Erase: the first `k` double words are erased, the rest hold their old contents.
    ErasePrefixClean(usize),
    /// Erase: every double word of the page is left unreadable.
    EraseAllUnreadable,
}

/// When the power fails.
#[derive(Clone, Copy, Debug)]
enum Cut {
    /// After `n` whole operations.
    After(usize),
    /// In the middle of operation `n`.
    During(usize, Tear),
}

/// A simulated STM32L4 flash with two slot pages: programming granularity of a double word,
/// programming only an erased double word, unreadable double words after a cut, and power cuts.
struct SimFlash {
    pages: [[Dw; DWORDS]; 2],
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
        SimFlash { pages: [[Dw::Erased; DWORDS]; 2], ops: 0, cut: None }
    }
    fn with(pages: [[Dw; DWORDS]; 2], cut: Option<Cut>) -> Self {
        SimFlash { pages, ops: 0, cut }
    }
    /// Counts an operation; returns `Some(tear)` for a torn operation, Err for a dead one.
    fn tick(&mut self) -> Result<Option<Tear>, SimError> {
        let n = self.ops;
        self.ops += 1;
        match self.cut {
            Some(Cut::After(m)) if n >= m => Err(SimError::PowerLost),
            Some(Cut::During(m, _)) if n > m => Err(SimError::PowerLost),
            Some(Cut::During(m, t)) if n == m => Ok(Some(t)),
            _ => Ok(None),
        }
    }
    fn reboot(&mut self) {
        self.cut = None;
        self.ops = 0;
    }
    /// The slot as the node reads it: bytes, or `None` when a double word is unreadable.
    fn reading(&self, slot: usize) -> Option<[u8; SLOT_SIZE]> {
        let mut out = [0u8; SLOT_SIZE];
        for (dw, chunk) in self.pages[slot].iter().zip(out.chunks_exact_mut(PROGRAM_UNIT)) {
            match dw {
                Dw::Erased => chunk.fill(0xff),
                Dw::Programmed(d) => chunk.copy_from_slice(d),
                Dw::Unreadable => return None,
            }
        }
        Some(out)
    }
    fn load(&mut self, slot: usize, page: &[u8; SLOT_SIZE]) {
        for (dw, chunk) in self.pages[slot].iter_mut().zip(page.chunks_exact(PROGRAM_UNIT)) {
            *dw = Dw::Programmed(chunk.try_into().unwrap());
        }
    }
}

impl SlotFlash for SimFlash {
    type Error = SimError;
    fn read(&mut self, slot: u8, out: &mut [u8; SLOT_SIZE]) -> Result<SlotRead, SimError> {
        Ok(match self.reading(slot as usize) {
            Some(bytes) => {
                *out = bytes;
                SlotRead::Complete
            }
            None => SlotRead::Unreadable,
        })
    }
    fn erase(&mut self, slot: u8) -> Result<(), SimError> {
        let torn = self.tick()?;
        let page = &mut self.pages[slot as usize];
        match torn {
            None => page.fill(Dw::Erased),
            Some(Tear::ErasePrefix(k)) => {
                page[..k].fill(Dw::Erased);
                page[k] = Dw::Unreadable;
                return Err(SimError::PowerLost);
            }
            Some(Tear::ErasePrefixClean(k)) => {
                page[..k].fill(Dw::Erased);
                return Err(SimError::PowerLost);
            }
            Some(_) => {
                page.fill(Dw::Unreadable);
                return Err(SimError::PowerLost);
            }
        }
        Ok(())
    }
    fn program(&mut self, slot: u8, off: usize, data: [u8; PROGRAM_UNIT]) -> Result<(), SimError> {
        assert_eq!(off % PROGRAM_UNIT, 0, "programming is by whole double words");
        let torn = self.tick()?;
        let dw = &mut self.pages[slot as usize][off / PROGRAM_UNIT];
        if *dw != Dw::Erased {
            return Err(SimError::ProgramNotErased);
        }
        match torn {
            None => *dw = Dw::Programmed(data),
            Some(Tear::ProgramPartial(k)) => {
                let mut d = [0xff; PROGRAM_UNIT];
                d[..k].copy_from_slice(&data[..k]);
                *dw = Dw::Programmed(d);
                return Err(SimError::PowerLost);
            }
            Some(_) => {
                *dw = Dw::Unreadable;
                return Err(SimError::PowerLost);
            }
        }
        Ok(())
    }
}

/// The node's boot decision on the simulated flash: (slot, sequence, record bytes).
fn boot(f: &SimFlash) -> Result<(u8, u32, std::vec::Vec<u8>), boot::BootError> {
    let (a, b) = (f.reading(0), f.reading(1));
    let readings = [a.as_ref().map(|p| &p[..]), b.as_ref().map(|p| &p[..])];
    let b = boot::decide(readings, &ID, Arithmetic::F32, boot::TempInputs::ALL)?;
    let mut buf = [0u8; MAX_RECORD_LEN];
    let n = b.record.emit(&mut buf).unwrap();
    Ok((b.slot, b.sequence, buf[..n].to_vec()))
}

#[test]
fn first_write_goes_to_slot_0_then_alternates() {
    let mut f = SimFlash::new();
    assert_eq!(boot(&f), Err(boot::BootError::NoSlot(SlotError::NotCommitted)));
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

fn crc32_of(header: &[u8], record: &[u8]) -> u32 {
    let mut all = header.to_vec();
    all.extend_from_slice(record);
    crate::record::crc32(&all)
}

#[test]
fn page_literal_bytes_of_both_versions() {
    let r = record_bytes(0.0);
    // Model 4, three channels: 30 + 4 + 8·3·4 + 4 = 134 = 0x86 record bytes.
    assert_eq!(r.len(), 0x86);
    let crc = crc32_of(b"\x04\x03\x02\x01\x86\x00\xff\xff", &r).to_le_bytes();
    let page = SlotImage::build(&r, 0x0102_0304).unwrap();
    assert_eq!(&page[0..12], b"ASL2\x04\x03\x02\x01\x86\x00\xff\xff");
    assert_eq!(page[12..16], crc);
    assert_eq!(&page[16..16 + r.len()], &r[..]);
    assert!(page[16 + r.len()..2040].iter().all(|&b| b == 0xff));
    assert_eq!(&page[2040..2044], b"CMT2");
    assert_eq!(page[2044..2048], crc);
    let v1 = SlotImage::build_v1(&r, 0x0102_0304).unwrap();
    assert_eq!(&v1[0..12], b"ASL1\x04\x03\x02\x01\x86\x00\xff\xff");
    assert_eq!(v1[12..16], crc);
    assert_eq!(&v1[16..16 + r.len()], &r[..]);
    assert!(v1[16 + r.len()..].iter().all(|&b| b == 0xff));
    fn img(p: &[u8]) -> SlotImage<'_> {
        SlotImage::parse(p).unwrap()
    }
    assert_eq!(img(&page), SlotImage { version: 2, sequence: 0x0102_0304, record: &r });
    assert_eq!(img(&v1), SlotImage { version: 1, sequence: 0x0102_0304, record: &r });
    // A version-1 slot reads without its erased tail; a version-2 slot needs its whole page.
    assert_eq!(img(&v1[..16 + r.len()]).version, 1);
    assert_eq!(SlotImage::parse(&page[..2047]), Err(SlotError::Truncated));
}

#[test]
fn a_version_2_slot_is_valid_only_with_its_commit() {
    let r = record_bytes(0.0);
    let page = SlotImage::build(&r, 7).unwrap();
    let mut no_commit = page;
    no_commit[2040..].fill(0xff);
    assert_eq!(SlotImage::parse(&no_commit), Err(SlotError::NotCommitted));
    // A commit whose CRC copy is another write's.
    let mut stale = page;
    stale[2044] ^= 1;
    assert_eq!(SlotImage::parse(&stale), Err(SlotError::NotCommitted));
    let mut half = page;
    half[2044..].fill(0xff);
    assert_eq!(SlotImage::parse(&half), Err(SlotError::NotCommitted));
    // Commit in place but the record damaged: the CRC catches it.
    let mut bad = page;
    bad[100] ^= 0x10;
    assert_eq!(SlotImage::parse(&bad), Err(SlotError::BadCrc));
}

#[test]
fn old_format_slots_still_read_and_a_write_next_to_one_is_version_2() {
    let (r1, r2) = (record_bytes(1.0), record_bytes(2.0));
    let mut f = SimFlash::new();
    f.load(0, &SlotImage::build_v1(&r1, 41).unwrap());
    assert_eq!(boot(&f).unwrap(), (0, 41, r1.clone()));
    let p = write_record(&mut f, &r2).unwrap();
    assert_eq!((p.slot, p.sequence), (1, 42));
    let b = f.reading(1).unwrap();
    assert_eq!(SlotImage::parse(&b).unwrap().version, 2);
    assert_eq!(boot(&f).unwrap(), (1, 42, r2));
}

#[test]
fn wrap_around_sequence_still_picks_the_newer() {
    let r1 = record_bytes(1.0);
    let r2 = record_bytes(2.0);
    let a = SlotImage::build(&r1, u32::MAX).unwrap();
    let b = SlotImage::build_v1(&r2, 0).unwrap();
    assert_eq!(select([&a, &b]).unwrap().slot, 1);
    assert_eq!(select([&b, &a]).unwrap().slot, 0);
}

#[test]
fn an_unreadable_slot_is_never_in_force_and_is_planned_as_the_target() {
    let r = record_bytes(1.0);
    let page = SlotImage::build(&r, 9).unwrap();
    assert_eq!(select_readings([None, Some(&page)]).unwrap().slot, 1);
    assert_eq!(select_readings([Some(&page), None]).unwrap().slot, 0);
    assert_eq!(select_readings([None, None]), Err(SlotError::Unreadable));
    assert_eq!(select_readings([None, Some(&[0xff; SLOT_SIZE])]), Err(SlotError::Unreadable));
    let mut bad = page;
    bad[100] ^= 1;
    assert_eq!(select_readings([None, Some(&bad)]), Err(SlotError::BadCrc));
    let p = WritePlan::from_readings([Some(&page), None], &r).unwrap();
    assert_eq!((p.slot, p.sequence), (1, 10));
    let p = WritePlan::from_readings([None, Some(&page)], &r).unwrap();
    assert_eq!((p.slot, p.sequence), (0, 10));
    let p = WritePlan::from_readings([None, None], &r).unwrap();
    assert_eq!((p.slot, p.sequence), (0, 1));
    // The writer recovers an unreadable page: erase, then program.
    let mut f = SimFlash::new();
    f.load(0, &page);
    f.pages[1][17] = Dw::Unreadable;
    let p = write_record(&mut f, &record_bytes(2.0)).unwrap();
    assert_eq!((p.slot, p.sequence), (1, 10));
    assert_eq!(boot(&f).unwrap().2, record_bytes(2.0));
}

#[test]
fn the_program_order_is_the_probes_and_ends_with_the_commit() {
    let p = WritePlan::new([&[0xff; SLOT_SIZE], &[0xff; SLOT_SIZE]], &record_bytes(1.0)).unwrap();
    let order: std::vec::Vec<usize> = p.program_order().collect();
    assert_eq!(order.len(), SLOT_SIZE / PROGRAM_UNIT);
    assert!(order.windows(2).all(|w| w[1] == w[0] + PROGRAM_UNIT));
    assert_eq!((order[0], *order.last().unwrap()), (0, COMMIT_OFFSET));
    // Every double word before the last one programmed leaves the slot uncommitted.
    let mut page = [0xffu8; SLOT_SIZE];
    for &off in &order[..order.len() - 1] {
        page[off..off + PROGRAM_UNIT].copy_from_slice(&p.page[off..off + PROGRAM_UNIT]);
        assert_eq!(SlotImage::parse(&page), Err(SlotError::NotCommitted), "after {off}");
    }
}

/// The start states of the power-cut test: one record in slot 0; an older record in slot 0 and
/// the current one in slot 1; the current one in a version-1 slot 0 next to an unreadable slot 1.
fn start_states(old: &[u8]) -> std::vec::Vec<[[Dw; DWORDS]; 2]> {
    let mut starts = std::vec::Vec::new();
    let mut f = SimFlash::new();
    write_record(&mut f, old).unwrap();
    starts.push(f.pages);
    let mut f = SimFlash::new();
    write_record(&mut f, &record_bytes(7.0)).unwrap();
    write_record(&mut f, old).unwrap();
    starts.push(f.pages);
    let mut f = SimFlash::new();
    f.load(0, &SlotImage::build_v1(old, 3).unwrap());
    f.load(1, &SlotImage::build(&record_bytes(5.0), 2).unwrap());
    f.pages[1][40] = Dw::Unreadable;
    starts.push(f.pages);
    starts
}

/// Power fails after every single flash operation of a write in the probe's order (page erase,
/// then every double word ascending), and in the middle of each in every way the simulated flash
/// tears; after each failure the node's boot decision must be the old or the new record, whole, and
/// the node must be updatable again.
#[test]
fn power_cut_at_every_operation_leaves_old_or_new() {
    let old = record_bytes(1.0);
    let new = record_bytes(2.0);
    let mut checked = 0;
    for start in start_states(&old) {
        assert_eq!(boot(&SimFlash::with(start, None)).unwrap().2, old);
        let mut probe = SimFlash::with(start, None);
        write_record(&mut probe, &new).unwrap();
        let n_ops = probe.ops;
        assert_eq!(n_ops, 1 + DWORDS);
        let mut cuts: std::vec::Vec<Cut> = (0..=n_ops).map(Cut::After).collect();
        for k in [0, 1, 2, 100, DWORDS - 1] {
            cuts.push(Cut::During(0, Tear::ErasePrefix(k)));
        }
        for k in [0, 1, 100, DWORDS - 1, DWORDS] {
            cuts.push(Cut::During(0, Tear::ErasePrefixClean(k)));
        }
        cuts.push(Cut::During(0, Tear::EraseAllUnreadable));
        for m in 1..n_ops {
            cuts.push(Cut::During(m, Tear::ProgramUnreadable));
            for k in [1, 4, 7] {
                cuts.push(Cut::During(m, Tear::ProgramPartial(k)));
            }
        }
        for cut in cuts {
            let mut f = SimFlash::with(start, Some(cut));
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
                    // The new record is in force only once its commit double word is complete.
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
    let per_start = (DWORDS + 2) + 11 + 4 * DWORDS;
    assert_eq!(checked, 3 * per_start);
}

/// The version-1 write order (record, header, commit marker at offset 0 last) is what the old
/// power-cut test checked; in the probe's ascending order the version-1 marker lands first and a
/// cut after it leaves a committed slot whose record is incomplete. The version-1 CRC still
/// refuses it, which is why old slots stay readable; this shows why version 2 moved the commit.
#[test]
fn in_the_probes_order_a_version_1_marker_lands_first() {
    let r = record_bytes(1.0);
    let v1 = SlotImage::build_v1(&r, 1).unwrap();
    let mut page = [0xffu8; SLOT_SIZE];
    page[..PROGRAM_UNIT].copy_from_slice(&v1[..PROGRAM_UNIT]);
    assert_eq!(&page[0..4], &SLOT_MAGIC_V1);
    assert_ne!(SlotImage::parse(&page), Err(SlotError::NotCommitted));
    assert!(SlotImage::parse(&page).is_err());
}

#[test]
fn corrupted_slots_are_named() {
    let r = record_bytes(1.0);
    for page in [SlotImage::build(&r, 1).unwrap(), SlotImage::build_v1(&r, 1).unwrap()] {
        let mut bad = page;
        bad[100] ^= 0x10;
        assert_eq!(SlotImage::parse(&bad), Err(SlotError::BadCrc));
        assert_eq!(SlotImage::parse(&page[..10]), Err(SlotError::Truncated));
        let mut long = page;
        long[8..10].copy_from_slice(&0xffffu16.to_le_bytes());
        assert_eq!(SlotImage::parse(&long), Err(SlotError::BadLength));
        // A length field covering the record and erased bytes after it, with the slot CRC (and
        // its version-2 copy) made to match: the record parses (it ignores trailing bytes), the
        // slot is still refused (found by the fuzzer, fuzz/src/slots.rs).
        let mut padded = page;
        padded[8..10].copy_from_slice(&(r.len() as u16 + 8).to_le_bytes());
        let crc = crc32_of(&padded[4..12], &padded[16..16 + r.len() + 8]).to_le_bytes();
        padded[12..16].copy_from_slice(&crc);
        if padded[0..4] == SLOT_MAGIC_V2 {
            padded[2044..2048].copy_from_slice(&crc);
        }
        assert!(Record::parse(&padded[16..16 + r.len() + 8]).is_ok());
        assert_eq!(SlotImage::parse(&padded), Err(SlotError::BadLength));
        assert_eq!(select([&[0xff; SLOT_SIZE], &bad]), Err(SlotError::BadCrc));
    }
    let v1 = SlotImage::build_v1(&r, 1).unwrap();
    assert_eq!(SlotImage::parse(&v1[..40]), Err(SlotError::Truncated));
    assert_eq!(select([&[0; SLOT_SIZE], &[0xff; SLOT_SIZE]]), Err(SlotError::NotCommitted));
    assert_eq!(SlotImage::build(&r[..20], 1), Err(SlotError::Record(RecordError::Truncated)));
}

#[test]
fn random_bytes_never_panic() {
    let mut s = 0x9E37_79B9_7F4A_7C15u64;
    for page in [
        SlotImage::build(&record_bytes(1.0), 1).unwrap(),
        SlotImage::build_v1(&record_bytes(1.0), 1).unwrap(),
    ] {
        for i in 0..5000 {
            let mut p = page;
            for _ in 0..(i % 8 + 1) {
                s ^= s << 13;
                s ^= s >> 7;
                s ^= s << 17;
                let at = if s & 1 == 0 { s % 64 } else { 2040 + s % 8 };
                p[at as usize] = (s >> 40) as u8;
            }
            let cut = (s % 2049) as usize;
            let _ = select([&p, &page[..cut]]);
            let _ = select_readings([None, Some(&p[..cut])]);
        }
    }
}
