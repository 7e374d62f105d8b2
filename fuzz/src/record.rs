//! Fuzz target: the calibration record parser ([`Record::parse`]).
//!
//! Properties checked on every input: `parse` returns (never panics); whatever it accepts, `emit`
//! writes back to exactly the bytes it read (`record.len()` bytes; trailing bytes are ignored by
//! design). Besides the generic mutations, an input gets its length field made consistent with its
//! channel and term counts (1 in 4) and its CRC recomputed where the length field puts it (1 in 2),
//! so that mutated records get past the CRC check to the term and coefficient checks.

use accelcal_shared::record::{crc32, Record, RecordError, MAX_CHANNELS, MAX_RECORD_LEN};
use accelcal_shared::terms::{Structure, MODEL_4, N_BASIS};
use accelcal_shared::wire::RECORD_ERROR_NAMES;

use crate::rng::Rng;
use crate::Target;

/// The record target and its tally of outcomes.
#[derive(Default)]
pub struct RecordTarget {
    accepted: u64,
    rejected: [u64; RECORD_ERROR_NAMES.len()],
}

/// The bytes of a record for the QEMU node's device id with `coef(channel, term)` coefficients.
pub(crate) fn record(n_channels: u8, structure: Structure, coef: impl Fn(usize, usize) -> f64) -> Vec<u8> {
    let mut r = Record {
        device_id: accelcal_shared::contract::QEMU_DEVICE_ID,
        created_unix_s: 1_800_000_000,
        structure,
        n_channels,
        coefficients: [[0.0; N_BASIS]; MAX_CHANNELS],
        // A structure with thermal terms needs gravity and its temperature part (record format 2).
        g_m_s2: structure.is_thermal().then_some(9.81),
        thermal: structure.is_thermal().then_some(accelcal_shared::record::Thermal {
            t_ref_c: 25.0,
            t_min_c: -10.0,
            t_max_c: 50.0,
            source: accelcal_shared::record::TempSource::FrontEnd,
        }),
    };
    for c in 0..n_channels as usize {
        for n in 0..structure.len() {
            r.coefficients[c][n] = coef(c, n);
        }
    }
    let mut buf = [0u8; MAX_RECORD_LEN];
    let n = r.emit(&mut buf).expect("seed records are valid");
    buf[..n].to_vec()
}

fn error_index(e: RecordError) -> usize {
    accelcal_shared::wire::record_error_code(e) as usize - 1
}

/// The model-4 seed record.
pub(crate) fn model4_record() -> Vec<u8> {
    record(3, MODEL_4, |c, n| if n == c + 1 { 1670.0 } else { 32000.0 / (n + 1) as f64 })
}

/// The record fix-ups, in place: makes the length field agree with the channel and term counts
/// (1 in 4) and recomputes the CRC where the length field puts it (1 in 2).
pub(crate) fn fix_up_record(rng: &mut Rng, data: &mut [u8]) {
    if data.len() >= 30 && rng.one_in(4) {
        let len = 30 + data[29] as usize + 8 * data[28] as usize * data[29] as usize + 4;
        data[6..8].copy_from_slice(&(len as u16).to_le_bytes());
    }
    if data.len() >= 8 && rng.one_in(2) {
        let len = u16::from_le_bytes([data[6], data[7]]) as usize;
        if (4..=data.len()).contains(&len) {
            let crc = crc32(&data[..len - 4]);
            data[len - 4..len].copy_from_slice(&crc.to_le_bytes());
        }
    }
}

impl Target for RecordTarget {
    fn name(&self) -> &'static str {
        "record"
    }

    fn seeds(&self) -> Vec<Vec<u8>> {
        let model4 = model4_record();
        let mut erased_tail = model4.clone();
        erased_tail.extend_from_slice(&[0xff; 64]);
        vec![
            model4,
            erased_tail,
            record(1, Structure::INTERCEPT, |_, _| 1.0),
            record(8, Structure::from_mask(u32::MAX), |c, n| (c * 31 + n) as f64 * -0.125),
            record(2, Structure::from_indices(&[3, 7, 19]), |_, n| {
                [f64::MIN_POSITIVE / 4.0, -0.0, 1e300][n % 3]
            }),
        ]
    }

    fn fix_up(&self, rng: &mut Rng, data: &mut Vec<u8>) {
        fix_up_record(rng, data);
    }

    fn check(&mut self, input: &[u8], _rng: &mut Rng) -> Result<(), String> {
        let rec = match Record::parse(input) {
            Ok(rec) => rec,
            Err(e) => {
                self.rejected[error_index(e)] += 1;
                return Ok(());
            }
        };
        self.accepted += 1;
        let mut buf = [0u8; MAX_RECORD_LEN];
        let n = rec.emit(&mut buf).map_err(|e| format!("an accepted record does not emit: {e}"))?;
        if n != rec.len() || n > input.len() || buf[..n] != input[..n] {
            return Err(format!("an accepted record re-emits to other bytes ({n} bytes emitted)"));
        }
        Ok(())
    }

    fn summary(&self) -> String {
        let mut s = format!("accepted (round trip checked) {}", self.accepted);
        for (name, n) in RECORD_ERROR_NAMES.iter().zip(self.rejected) {
            if n > 0 {
                s += &format!(", {name} {n}");
            }
        }
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn seeds_parse_and_round_trip() {
        let mut t = RecordTarget::default();
        let mut rng = Rng::new(0);
        for s in t.seeds() {
            assert!(Record::parse(&s).is_ok());
            t.check(&s, &mut rng).unwrap();
        }
        assert_eq!(t.accepted, 5);
    }

    #[test]
    fn fix_up_lets_mutated_records_past_the_crc() {
        // A coefficient byte changed, then the CRC fixed: the record is accepted again.
        let t = RecordTarget::default();
        let mut s = t.seeds().remove(0);
        s[40] ^= 0x10;
        assert_eq!(Record::parse(&s).err(), Some(RecordError::BadCrc));
        let mut rng = Rng::new(3);
        let mut fixed = false;
        for _ in 0..64 {
            let mut d = s.clone();
            t.fix_up(&mut rng, &mut d);
            fixed |= Record::parse(&d).is_ok();
        }
        assert!(fixed);
    }
}
