//! Fuzz target: the record slots ([`SlotImage::parse`], [`slots::select`] over two slot images, and
//! [`WritePlan`] next to whatever the slots hold, or next to one of them unreadable).
//!
//! An input is two slot images: a little-endian `u16` giving slot 0's length, slot 0's bytes, and
//! slot 1's bytes (the rest). Slots may be short: a version-1 slot image is valid without its
//! erased tail; a version-2 one needs its whole page (its commit is the last double word).
//!
//! Properties checked on every input:
//! - `SlotImage::parse` and `select` return (never panic);
//! - an accepted slot is what its header says: a format magic (version 1, or version 2 with its
//!   commit double word holding the commit magic and the header's CRC), its sequence number,
//!   exactly the record length's bytes after the header, a record that parses and fills them; and
//!   `SlotImage::build` (version 2) or `build_v1` of that record and sequence gives back the same
//!   header, record and commit bytes (the reserved field apart, which `parse` does not check but
//!   the CRC covers);
//! - `select` agrees with the two `parse` results: it picks a valid slot whenever there is one, never
//!   the older of two valid ones, the same image when the slots are swapped (unless the two
//!   sequence numbers are equal or exactly 2³¹ apart, where the order decides), and when neither
//!   slot is valid one of the two errors, "not committed" only if both are;
//! - writing a record next to any slot contents (the plan's page into the plan's slot) makes it the
//!   one in force with the plan's sequence number, and leaves the record that was in force intact
//!   in the other slot; the same when either slot is unreadable (the plan then never targets the
//!   other, readable slot if it is the one in force).
//!
//! Fix-ups, per slot: the record fix-ups of the record target on the slot's record (1 in 2), the
//! slot's length field set to the record's (1 in 4), a format magic restored (1 in 8), a version-2
//! commit magic restored on a whole page (1 in 4), and the slot CRC recomputed over what the length
//! field covers (1 in 2; on a whole page its copy in the commit double word too).

use accelcal_shared::record::{crc32, Record};
use accelcal_shared::slots::{
    self, is_newer, SlotError, SlotImage, SlotReading, WritePlan, COMMIT_MAGIC, COMMIT_OFFSET,
    SLOT_HEADER_LEN, SLOT_MAGIC_V1, SLOT_MAGIC_V2, SLOT_SIZE,
};
use accelcal_shared::terms::Structure;

use crate::record::{fix_up_record, model4_record, record};
use crate::rng::Rng;
use crate::Target;

/// The slots target and its tally of outcomes.
#[derive(Default)]
pub struct SlotsTarget {
    /// Slot images by outcome: valid, then the [`SlotError`] kinds in [`OUTCOMES`] order.
    parsed: [u64; 7],
    /// `select` results: slot 0, slot 1, none.
    selected: [u64; 3],
}

const OUTCOMES: [&str; 7] =
    ["valid", "Truncated", "NotCommitted", "BadCrc", "BadLength", "Record", "Unreadable"];

fn outcome(r: &Result<SlotImage<'_>, SlotError>) -> usize {
    match r {
        Ok(_) => 0,
        Err(SlotError::Truncated) => 1,
        Err(SlotError::NotCommitted) => 2,
        Err(SlotError::BadCrc) => 3,
        Err(SlotError::BadLength) => 4,
        Err(SlotError::Record(_)) => 5,
        Err(SlotError::Unreadable) => 6,
    }
}

/// The record every write check writes.
fn new_record() -> Vec<u8> {
    record(3, Structure::from_indices(&[1, 2, 3, 4]), |c, n| (c * 7 + n) as f64 + 0.5)
}

/// A version-1 slot image without its erased tail.
fn compact_slot(record: &[u8], sequence: u32) -> Vec<u8> {
    let page = SlotImage::build_v1(record, sequence).expect("seed records are valid");
    page[..SLOT_HEADER_LEN + record.len()].to_vec()
}

/// A whole version-2 slot page.
fn page_v2(record: &[u8], sequence: u32) -> Vec<u8> {
    SlotImage::build(record, sequence).expect("seed records are valid").to_vec()
}

/// An input from two slot images.
fn input(a: &[u8], b: &[u8]) -> Vec<u8> {
    let mut v = (a.len() as u16).to_le_bytes().to_vec();
    v.extend_from_slice(a);
    v.extend_from_slice(b);
    v
}

/// The two slot images of an input (slot 0 is cut short when the input is).
fn split(input: &[u8]) -> (&[u8], &[u8]) {
    if input.len() < 2 {
        return (&[], &[]);
    }
    let rest = &input[2..];
    let n = (u16::from_le_bytes([input[0], input[1]]) as usize).min(rest.len());
    rest.split_at(n)
}

/// The slot fix-ups (module docs), in place.
fn fix_up_slot(rng: &mut Rng, slot: &mut [u8]) {
    if slot.len() < SLOT_HEADER_LEN {
        return;
    }
    let (header, rec) = slot.split_at_mut(SLOT_HEADER_LEN);
    if rng.one_in(2) {
        fix_up_record(rng, rec);
    }
    if rec.len() >= 8 && rng.one_in(4) {
        header[8..10].copy_from_slice(&rec[6..8]);
    }
    if rng.one_in(8) {
        header[0..4].copy_from_slice(if rng.one_in(2) { &SLOT_MAGIC_V1 } else { &SLOT_MAGIC_V2 });
    }
    let commit = COMMIT_OFFSET - SLOT_HEADER_LEN;
    let whole_page = rec.len() >= SLOT_SIZE - SLOT_HEADER_LEN;
    if whole_page && rng.one_in(4) {
        rec[commit..commit + 4].copy_from_slice(&COMMIT_MAGIC);
    }
    let len = u16::from_le_bytes([header[8], header[9]]) as usize;
    if len <= rec.len() && rng.one_in(2) {
        let crc = crc32(&[&header[4..12], &rec[..len]].concat()).to_le_bytes();
        header[12..16].copy_from_slice(&crc);
        if whole_page {
            rec[commit + 4..commit + 8].copy_from_slice(&crc);
        }
    }
}

/// The properties of a slot that `parse` accepted.
fn check_accepted(slot: &[u8], img: &SlotImage<'_>) -> Result<(), String> {
    let len = u16::from_le_bytes([slot[8], slot[9]]) as usize;
    let magic = if img.version == 1 { SLOT_MAGIC_V1 } else { SLOT_MAGIC_V2 };
    if slot[0..4] != magic {
        return Err(format!("a version-{} slot without its format magic is accepted", img.version));
    }
    if img.version == 2 && (slot.len() < SLOT_SIZE || slot[COMMIT_OFFSET..COMMIT_OFFSET + 4] != COMMIT_MAGIC)
    {
        return Err("a version-2 slot without its commit double word is accepted".into());
    }
    if img.version == 2 && slot[COMMIT_OFFSET + 4..SLOT_SIZE] != slot[12..16] {
        return Err("a version-2 slot whose commit does not carry its CRC is accepted".into());
    }
    if img.sequence != u32::from_le_bytes([slot[4], slot[5], slot[6], slot[7]]) {
        return Err("the accepted slot's sequence is not its header's".into());
    }
    if img.record != &slot[SLOT_HEADER_LEN..SLOT_HEADER_LEN + len] {
        return Err("the accepted record is not the length field's bytes after the header".into());
    }
    let rec =
        Record::parse(img.record).map_err(|e| format!("an accepted slot's record does not parse: {e}"))?;
    if rec.len() != len {
        return Err(format!("the slot's length field says {len} bytes, its record has {}", rec.len()));
    }
    let build = if img.version == 1 { SlotImage::build_v1 } else { SlotImage::build };
    let page = build(img.record, img.sequence)
        .map_err(|e| format!("an accepted slot's record does not build: {e}"))?;
    let same = |r: core::ops::Range<usize>| page[r.clone()] == slot[r];
    let reserved_erased = slot[10..12] == [0xff, 0xff];
    let commit_same = img.version == 1 || !reserved_erased || same(COMMIT_OFFSET..SLOT_SIZE);
    if !same(0..10)
        || !same(SLOT_HEADER_LEN..SLOT_HEADER_LEN + len)
        || (reserved_erased && !same(10..16))
        || !commit_same
    {
        return Err("an accepted slot does not build back to the same bytes".into());
    }
    Ok(())
}

impl SlotsTarget {
    /// The properties of `select` against the two `parse` results.
    fn check_select(&mut self, a: &[u8], b: &[u8]) -> Result<(), String> {
        let parsed = [SlotImage::parse(a), SlotImage::parse(b)];
        match slots::select([a, b]) {
            Ok(act) => {
                self.selected[act.slot as usize] += 1;
                let (chosen, other) = (act.slot as usize, 1 - act.slot as usize);
                if parsed[chosen] != Ok(act.image) {
                    return Err(format!("select picks slot {chosen}, which does not parse to that image"));
                }
                if let Ok(o) = &parsed[other] {
                    if is_newer(o.sequence, act.image.sequence) {
                        return Err(format!("select picks the older of two valid slots ({chosen})"));
                    }
                    let ordered = is_newer(act.image.sequence, o.sequence);
                    let swapped = slots::select([b, a]).map(|s| s.image);
                    if ordered && swapped != Ok(act.image) {
                        return Err("select picks another image when the slots are swapped".into());
                    }
                }
            }
            Err(e) => {
                self.selected[2] += 1;
                let [ea, eb] = [parsed[0].err(), parsed[1].err()];
                let (Some(ea), Some(eb)) = (ea, eb) else {
                    return Err("select finds no slot in force although one is valid".into());
                };
                if e != ea && e != eb {
                    return Err(format!("select reports {e:?}, neither slot's error ({ea:?}, {eb:?})"));
                }
                if e == SlotError::NotCommitted && (ea, eb) != (e, e) {
                    return Err("select reports an empty slot although a committed one is bad".into());
                }
            }
        }
        Ok(())
    }
}

/// The properties of writing [`new_record`] next to the slots `a` and `b`, as read and with each
/// of them unreadable in turn.
fn check_write(a: &[u8], b: &[u8]) -> Result<(), String> {
    check_write_readings([Some(a), Some(b)])?;
    check_write_readings([None, Some(b)])?;
    check_write_readings([Some(a), None])
}

fn check_write_readings(readings: [SlotReading<'_>; 2]) -> Result<(), String> {
    let new = new_record();
    let before = slots::select_readings(readings).ok().map(|act| (act.slot, act.image.record.to_vec()));
    let plan = WritePlan::from_readings(readings, &new).map_err(|e| format!("no write plan: {e}"))?;
    if let Some((slot, _)) = &before {
        if plan.slot == *slot {
            return Err("the write plan targets the slot in force".into());
        }
    }
    let mut after: [Option<Vec<u8>>; 2] = readings.map(|r| r.map(<[u8]>::to_vec));
    after[plan.slot as usize] = Some(plan.page.to_vec());
    let after_readings = [after[0].as_deref(), after[1].as_deref()];
    let act = slots::select_readings(after_readings).map_err(|e| format!("after a write: {e}"))?;
    if act.slot != plan.slot || act.image.sequence != plan.sequence || act.image.record != new {
        return Err("after a write the new record is not the one in force".into());
    }
    if let Some((slot, record)) = before {
        let kept = slots::parse_reading(after_readings[slot as usize]).map(|i| i.record.to_vec());
        if kept != Ok(record) {
            return Err("a write damaged the record that was in force".into());
        }
    }
    Ok(())
}

impl Target for SlotsTarget {
    fn name(&self) -> &'static str {
        "slots"
    }

    fn seeds(&self) -> Vec<Vec<u8>> {
        let m4 = model4_record();
        let one = record(1, Structure::INTERCEPT, |_, _| 1.0);
        let torn = {
            let mut s = compact_slot(&m4, 9);
            s[0..4].fill(0xff);
            s
        };
        let full_page = SlotImage::build_v1(&one, 3).expect("valid").to_vec();
        let uncommitted = {
            let mut p = page_v2(&m4, 12);
            p[COMMIT_OFFSET..].fill(0xff);
            p
        };
        vec![
            input(&compact_slot(&m4, 1), &compact_slot(&one, 2)),
            input(&compact_slot(&one, u32::MAX), &compact_slot(&m4, 0)),
            input(&[0xff; 32], &compact_slot(&m4, 7)),
            input(&compact_slot(&m4, 5), &torn),
            input(&compact_slot(&m4, 4), &compact_slot(&one, 4)),
            input(&full_page, &[0xff; SLOT_SIZE / 4]),
            input(&page_v2(&m4, 10), &compact_slot(&one, 9)),
            input(&page_v2(&one, 11), &uncommitted),
        ]
    }

    fn fix_up(&self, rng: &mut Rng, data: &mut Vec<u8>) {
        if data.len() < 2 {
            return;
        }
        let n = (u16::from_le_bytes([data[0], data[1]]) as usize).min(data.len() - 2);
        let (a, b) = data[2..].split_at_mut(n);
        fix_up_slot(rng, a);
        fix_up_slot(rng, b);
    }

    fn check(&mut self, input: &[u8], _rng: &mut Rng) -> Result<(), String> {
        let (a, b) = split(input);
        for slot in [a, b] {
            let p = SlotImage::parse(slot);
            self.parsed[outcome(&p)] += 1;
            if let Ok(img) = &p {
                check_accepted(slot, img)?;
            }
        }
        self.check_select(a, b)?;
        check_write(a, b)
    }

    fn summary(&self) -> String {
        let slots: Vec<String> = OUTCOMES
            .iter()
            .zip(self.parsed)
            .filter(|(_, n)| *n > 0)
            .map(|(name, n)| format!("{name} {n}"))
            .collect();
        let [s0, s1, none] = self.selected;
        format!(
            "slot images: {}; select: slot 0 {s0}, slot 1 {s1}, none {none} (write checked after each)",
            slots.join(", ")
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn seeds_pass_and_reach_every_select_outcome() {
        let mut t = SlotsTarget::default();
        let mut rng = Rng::new(0);
        for s in t.seeds() {
            t.check(&s, &mut rng).unwrap();
        }
        assert!(t.selected[0] > 0 && t.selected[1] > 0, "{:?}", t.selected);
        assert_eq!(t.parsed[0], 12, "{:?}", t.parsed);
    }

    #[test]
    fn fix_up_lets_mutated_slots_past_both_crcs() {
        // A coefficient byte of slot 0's record changed: the slot CRC fails; fix-ups repair both.
        let t = SlotsTarget::default();
        let mut s = t.seeds().remove(0);
        s[2 + SLOT_HEADER_LEN + 40] ^= 0x10;
        assert_eq!(SlotImage::parse(split(&s).0), Err(SlotError::BadCrc));
        let mut rng = Rng::new(3);
        let fixed = (0..256).any(|_| {
            let mut d = s.clone();
            t.fix_up(&mut rng, &mut d);
            SlotImage::parse(split(&d).0).is_ok()
        });
        assert!(fixed);
    }

    #[test]
    fn the_properties_hold_on_two_valid_slots_and_catch_a_wrong_image() {
        let m4 = model4_record();
        let (a, b) = (compact_slot(&m4, 1), compact_slot(&m4, 2));
        let mut t = SlotsTarget::default();
        t.check_select(&a, &b).unwrap();
        assert_eq!(t.selected, [0, 1, 0]);
        assert!(check_write(&a, &b).is_ok());
        assert!(check_accepted(&a, &SlotImage::parse(&b).unwrap()).is_err());
    }
}
