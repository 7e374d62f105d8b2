//! The calibration record: the versioned binary format that carries a fitted model from the host
//! to the node's flash.
//!
//! Layout (all integers and floats little-endian). Format version 1 has a 30-byte header; version
//! 2 adds 22 bytes after it (H = 30 or 52):
//!
//! | offset | size | field |
//! |---|---|---|
//! | 0 | 4 | magic `ACAL` |
//! | 4 | 2 | format version (1 or 2) |
//! | 6 | 2 | total length in bytes, CRC included |
//! | 8 | 12 | device id (the MCU's 96-bit unique id) |
//! | 20 | 8 | creation time, seconds since the Unix epoch |
//! | 28 | 1 | number of channels C (1..=8) |
//! | 29 | 1 | number of terms T (1..=25; version 1: 1..=20, no term in `t`) |
//! | 30 | 8 | version 2: local gravity the fit used, m/s², f64 (finite, 9.7..9.9) |
//! | 38 | 4 | version 2: reference temperature t_ref, °C, f32 (`t = temp_c − t_ref`) |
//! | 42 | 4 | version 2: lowest calibrated temperature, °C, f32 |
//! | 46 | 4 | version 2: highest calibrated temperature, °C, f32 |
//! | 50 | 1 | version 2: temperature input (0 none, 1 the MCU's sensor, 2 the front end's channel) |
//! | 51 | 1 | version 2: reserved, 0 |
//! | H | T | term indices into [`crate::BASIS`], strictly increasing, the first 0 (intercept) |
//! | H+T | 8·C·T | coefficients, f64, channel by channel, in term order |
//! | end−4 | 4 | CRC-32 (ISO-HDLC) of every byte before it |
//!
//! A record holds terms in `t` exactly when it names a temperature input; the three temperatures
//! are then finite with t_min < t_max, and zero with no input. [`Record::emit`] writes version 1
//! for a record with neither g nor temperature (what a version-1 build wrote), else version 2.
//!
//! No-panic contract: [`Record::parse`] returns `Ok` or a typed [`RecordError`] for every byte
//! string; it checks the length before every field access. Every bit flip and every truncation of a
//! valid record is rejected (CRC-32 detects all 1-bit errors; a truncation breaks the length
//! field's agreement or the CRC).

use crate::terms::{Structure, N_ACCEL_BASIS, N_BASIS};

/// Magic bytes at the start of every record.
pub const MAGIC: [u8; 4] = *b"ACAL";
/// The newest format version this crate reads and writes (it also reads and writes version 1).
pub const FORMAT_VERSION: u16 = 2;
/// Most channels one record holds.
pub const MAX_CHANNELS: usize = 8;
/// Bytes of the version-1 header before the term list.
pub const HEADER_LEN: usize = 30;
/// Bytes of the version-2 header before the term list.
pub const HEADER_LEN_V2: usize = 52;
/// Largest possible record, in bytes.
pub const MAX_RECORD_LEN: usize = HEADER_LEN_V2 + N_BASIS + 8 * MAX_CHANNELS * N_BASIS + 4;
/// Range of local gravity a version-2 record may state, m/s² (the Earth's surface spans
/// 9.76..9.84).
pub const G_RANGE: core::ops::RangeInclusive<f64> = 9.7..=9.9;

mod field {
    use core::ops::Range;
    pub const MAGIC: Range<usize> = 0..4;
    pub const VERSION: Range<usize> = 4..6;
    pub const LENGTH: Range<usize> = 6..8;
    pub const DEVICE_ID: Range<usize> = 8..20;
    pub const CREATED: Range<usize> = 20..28;
    pub const N_CHANNELS: usize = 28;
    pub const N_TERMS: usize = 29;
    pub const G: Range<usize> = 30..38;
    pub const T_REF: Range<usize> = 38..42;
    pub const T_MIN: Range<usize> = 42..46;
    pub const T_MAX: Range<usize> = 46..50;
    pub const TEMP_SOURCE: usize = 50;
    pub const RESERVED: usize = 51;
}

/// Where a node with a thermal record reads its temperature.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum TempSource {
    /// The MCU's internal sensor (ADC1, factory-calibrated; RM0351 §16.4.32).
    Mcu,
    /// The front end's temperature channel (sent with every code set).
    FrontEnd,
}

impl TempSource {
    /// The byte in the record.
    pub const fn code(self) -> u8 {
        match self {
            TempSource::Mcu => 1,
            TempSource::FrontEnd => 2,
        }
    }

    /// The source of a record byte (0 is "none").
    pub const fn from_code(c: u8) -> Option<TempSource> {
        match c {
            1 => Some(TempSource::Mcu),
            2 => Some(TempSource::FrontEnd),
            _ => None,
        }
    }

    /// Name as the host tool spells it (`mcu`, `front-end`).
    pub const fn name(self) -> &'static str {
        match self {
            TempSource::Mcu => "mcu",
            TempSource::FrontEnd => "front-end",
        }
    }
}

/// The temperature part of a thermal record.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Thermal {
    /// Reference temperature, °C: the model's `t` is `temp_c − t_ref_c`.
    pub t_ref_c: f32,
    /// Lowest temperature of the calibration campaign, °C.
    pub t_min_c: f32,
    /// Highest temperature of the calibration campaign, °C.
    pub t_max_c: f32,
    /// Where the node reads the temperature.
    pub source: TempSource,
}

/// Bit by bit, without the 1 KiB lookup table (the node's flash budget): 8 rounds of 7
/// instructions a byte on the node, ≈ 2 ms at 80 MHz for a 2 KiB slot, checked at boot only.
const CRC: crc::Crc<u32, crc::NoTable> = crc::Crc::<u32, crc::NoTable>::new(&crc::CRC_32_ISO_HDLC);

/// CRC-32 (ISO-HDLC, the zlib/Ethernet one) of `bytes`.
pub fn crc32(bytes: &[u8]) -> u32 {
    CRC.checksum(bytes)
}

/// Why bytes are not a valid record.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum RecordError {
    /// Fewer bytes than the header or than the length field says.
    Truncated,
    /// The magic is not `ACAL` (e.g. erased flash).
    BadMagic,
    /// A format version this code does not read.
    UnsupportedVersion(u16),
    /// The length field disagrees with the channel and term counts.
    BadLength,
    /// Channel count is 0 or above [`MAX_CHANNELS`].
    BadChannelCount,
    /// Term count is 0 or above 20, or the term list is not strictly increasing from the intercept.
    BadTerms,
    /// The CRC does not match.
    BadCrc,
    /// Version 2: terms in `t` without a temperature input or the reverse, a temperature range
    /// that is empty or not finite, a gravity outside [`G_RANGE`], or a reserved byte not zero.
    BadThermal,
    /// A coefficient is NaN or infinite.
    NonFinite,
    /// The output buffer is too small (emit only).
    BufferTooSmall,
}

impl core::fmt::Display for RecordError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            RecordError::Truncated => f.write_str("record is truncated"),
            RecordError::BadMagic => f.write_str("not a calibration record (bad magic)"),
            RecordError::UnsupportedVersion(v) => {
                write!(f, "unsupported record format version {v} (this build reads versions 1 and {FORMAT_VERSION})")
            }
            RecordError::BadLength => f.write_str("record length field is inconsistent"),
            RecordError::BadChannelCount => f.write_str("record channel count out of range"),
            RecordError::BadTerms => f.write_str("record term list is invalid"),
            RecordError::BadCrc => f.write_str("record CRC mismatch"),
            RecordError::BadThermal => {
                f.write_str("record's gravity or temperature fields are inconsistent with its terms")
            }
            RecordError::NonFinite => f.write_str("record holds a non-finite coefficient"),
            RecordError::BufferTooSmall => f.write_str("buffer too small for the record"),
        }
    }
}

#[cfg(feature = "std")]
impl std::error::Error for RecordError {}

/// A calibration record: the model structure and per-channel coefficients for one device.
///
/// Equality compares what the record holds: coefficient slots beyond `n_channels` and the
/// structure's term count are not part of it.
#[derive(Clone, Copy, Debug)]
pub struct Record {
    /// The device (MCU unique id) the record was made for.
    pub device_id: [u8; 12],
    /// Creation time, seconds since the Unix epoch.
    pub created_unix_s: u64,
    /// The model's terms.
    pub structure: Structure,
    /// Number of channels in use (1..=8).
    pub n_channels: u8,
    /// Coefficients: `coefficients[c][n]` belongs to channel `c` and the `n`-th term of
    /// `structure` in canonical order. Codes, codes per (m/s²)ⁿ, codes per °C…
    pub coefficients: [[f64; N_BASIS]; MAX_CHANNELS],
    /// Local gravity the fit used, m/s² (`None`: a version-1 record, which does not say).
    pub g_m_s2: Option<f64>,
    /// The temperature part, exactly when the structure holds terms in `t`.
    pub thermal: Option<Thermal>,
}

impl PartialEq for Record {
    fn eq(&self, o: &Record) -> bool {
        let (n_ch, n_t) = (self.n_channels as usize, self.structure.len());
        self.device_id == o.device_id
            && self.created_unix_s == o.created_unix_s
            && self.structure == o.structure
            && self.n_channels == o.n_channels
            && self.g_m_s2 == o.g_m_s2
            && self.thermal == o.thermal
            && (0..n_ch.min(MAX_CHANNELS)).all(|c| self.coefficients[c][..n_t] == o.coefficients[c][..n_t])
    }
}

fn u16_at(b: &[u8], r: core::ops::Range<usize>) -> u16 {
    let mut a = [0u8; 2];
    a.copy_from_slice(&b[r]);
    u16::from_le_bytes(a)
}

fn f32_at(b: &[u8], r: core::ops::Range<usize>) -> f32 {
    let mut a = [0u8; 4];
    a.copy_from_slice(&b[r]);
    f32::from_le_bytes(a)
}

impl Record {
    /// The format version [`Record::emit`] writes: 1 for a record with neither gravity nor
    /// temperature, else 2.
    pub fn version(&self) -> u16 {
        if self.g_m_s2.is_none() && self.thermal.is_none() {
            1
        } else {
            2
        }
    }

    fn header_len(&self) -> usize {
        if self.version() == 1 {
            HEADER_LEN
        } else {
            HEADER_LEN_V2
        }
    }

    /// Number of bytes [`Record::emit`] writes.
    pub fn len(&self) -> usize {
        self.header_len() + self.structure.len() + 8 * self.n_channels as usize * self.structure.len() + 4
    }

    /// Checks what version 2 adds: gravity in range, terms in `t` exactly with a temperature
    /// input, and a finite, non-empty temperature range.
    fn check_v2(&self) -> Result<(), RecordError> {
        if self.g_m_s2.is_some_and(|g| !G_RANGE.contains(&g)) {
            return Err(RecordError::BadThermal);
        }
        match self.thermal {
            None if self.structure.is_thermal() => Err(RecordError::BadThermal),
            None => Ok(()),
            Some(_) if !self.structure.is_thermal() => Err(RecordError::BadThermal),
            Some(t) => {
                let ok = t.t_ref_c.is_finite()
                    && t.t_min_c.is_finite()
                    && t.t_max_c.is_finite()
                    && t.t_min_c < t.t_max_c;
                if ok {
                    Ok(())
                } else {
                    Err(RecordError::BadThermal)
                }
            }
        }
    }

    /// Never true: a record has a header.
    pub fn is_empty(&self) -> bool {
        false
    }

    /// Parses and checks a record at the start of `bytes` (trailing bytes, e.g. the rest of an
    /// erased flash page, are ignored). Never panics.
    pub fn parse(bytes: &[u8]) -> Result<Record, RecordError> {
        if bytes.len() < HEADER_LEN {
            return Err(RecordError::Truncated);
        }
        if bytes[field::MAGIC] != MAGIC {
            return Err(RecordError::BadMagic);
        }
        let version = u16_at(bytes, field::VERSION);
        let (header, n_basis) = match version {
            1 => (HEADER_LEN, N_ACCEL_BASIS),
            2 => (HEADER_LEN_V2, N_BASIS),
            v => return Err(RecordError::UnsupportedVersion(v)),
        };
        let len = u16_at(bytes, field::LENGTH) as usize;
        let n_ch = bytes[field::N_CHANNELS] as usize;
        let n_t = bytes[field::N_TERMS] as usize;
        if n_ch == 0 || n_ch > MAX_CHANNELS {
            return Err(RecordError::BadChannelCount);
        }
        if n_t == 0 || n_t > n_basis {
            return Err(RecordError::BadTerms);
        }
        if len != header + n_t + 8 * n_ch * n_t + 4 {
            return Err(RecordError::BadLength);
        }
        if bytes.len() < len {
            return Err(RecordError::Truncated);
        }
        let body = &bytes[..len - 4];
        let mut crc = [0u8; 4];
        crc.copy_from_slice(&bytes[len - 4..len]);
        if crc32(body) != u32::from_le_bytes(crc) {
            return Err(RecordError::BadCrc);
        }
        let terms = &body[header..header + n_t];
        if terms[0] != 0 {
            return Err(RecordError::BadTerms);
        }
        let mut mask = 0u32;
        let mut prev: Option<u8> = None;
        for &t in terms {
            if t as usize >= n_basis || prev.is_some_and(|p| t <= p) {
                return Err(RecordError::BadTerms);
            }
            mask |= 1 << t;
            prev = Some(t);
        }
        let mut rec = Record {
            device_id: [0; 12],
            created_unix_s: 0,
            structure: Structure::from_mask(mask),
            n_channels: n_ch as u8,
            coefficients: [[0.0; N_BASIS]; MAX_CHANNELS],
            g_m_s2: None,
            thermal: None,
        };
        if version == 2 {
            let mut g = [0u8; 8];
            g.copy_from_slice(&body[field::G]);
            rec.g_m_s2 = Some(f64::from_le_bytes(g));
            let source = body[field::TEMP_SOURCE];
            let temps = [f32_at(body, field::T_REF), f32_at(body, field::T_MIN), f32_at(body, field::T_MAX)];
            if body[field::RESERVED] != 0 {
                return Err(RecordError::BadThermal);
            }
            match TempSource::from_code(source) {
                Some(source) => {
                    rec.thermal =
                        Some(Thermal { t_ref_c: temps[0], t_min_c: temps[1], t_max_c: temps[2], source })
                }
                None if source == 0 && temps == [0.0; 3] => {}
                None => return Err(RecordError::BadThermal),
            }
            rec.check_v2()?;
        }
        rec.device_id.copy_from_slice(&body[field::DEVICE_ID]);
        let mut t8 = [0u8; 8];
        t8.copy_from_slice(&body[field::CREATED]);
        rec.created_unix_s = u64::from_le_bytes(t8);
        let coef = &body[header + n_t..];
        for (n, chunk) in coef.chunks_exact(8).enumerate() {
            t8.copy_from_slice(chunk);
            let v = f64::from_le_bytes(t8);
            if !v.is_finite() {
                return Err(RecordError::NonFinite);
            }
            rec.coefficients[n / n_t][n % n_t] = v;
        }
        Ok(rec)
    }

    /// Writes the record into `buf` and returns the number of bytes written.
    pub fn emit(&self, buf: &mut [u8]) -> Result<usize, RecordError> {
        let n_ch = self.n_channels as usize;
        if n_ch == 0 || n_ch > MAX_CHANNELS {
            return Err(RecordError::BadChannelCount);
        }
        let version = self.version();
        if version == 1 && self.structure.is_thermal() {
            return Err(RecordError::BadThermal);
        }
        self.check_v2()?;
        let len = self.len();
        if buf.len() < len {
            return Err(RecordError::BufferTooSmall);
        }
        let n_t = self.structure.len();
        let header = self.header_len();
        buf[field::MAGIC].copy_from_slice(&MAGIC);
        buf[field::VERSION].copy_from_slice(&version.to_le_bytes());
        buf[field::LENGTH].copy_from_slice(&(len as u16).to_le_bytes());
        buf[field::DEVICE_ID].copy_from_slice(&self.device_id);
        buf[field::CREATED].copy_from_slice(&self.created_unix_s.to_le_bytes());
        buf[field::N_CHANNELS] = n_ch as u8;
        buf[field::N_TERMS] = n_t as u8;
        if version == 2 {
            // check_v2 refused a thermal record without g only through the structure; a v2
            // record without g (thermal, g not known) states 0, which parse refuses: require g.
            let g = self.g_m_s2.ok_or(RecordError::BadThermal)?;
            buf[field::G].copy_from_slice(&g.to_le_bytes());
            let (temps, source) = match self.thermal {
                Some(t) => ([t.t_ref_c, t.t_min_c, t.t_max_c], t.source.code()),
                None => ([0.0; 3], 0),
            };
            buf[field::T_REF].copy_from_slice(&temps[0].to_le_bytes());
            buf[field::T_MIN].copy_from_slice(&temps[1].to_le_bytes());
            buf[field::T_MAX].copy_from_slice(&temps[2].to_le_bytes());
            buf[field::TEMP_SOURCE] = source;
            buf[field::RESERVED] = 0;
        }
        for (n, i) in self.structure.indices().enumerate() {
            buf[header + n] = i as u8;
        }
        let mut at = header + n_t;
        for c in 0..n_ch {
            for n in 0..n_t {
                let v = self.coefficients[c][n];
                if !v.is_finite() {
                    return Err(RecordError::NonFinite);
                }
                buf[at..at + 8].copy_from_slice(&v.to_le_bytes());
                at += 8;
            }
        }
        let crc = crc32(&buf[..at]);
        buf[at..at + 4].copy_from_slice(&crc.to_le_bytes());
        Ok(len)
    }

    /// A record holding a triad's model-4 calibration (the inverse of [`Record::model4`]).
    pub fn from_model4(device_id: [u8; 12], created_unix_s: u64, m: &crate::linear::Model4) -> Record {
        let mut r = Record {
            device_id,
            created_unix_s,
            structure: crate::terms::MODEL_4,
            n_channels: 3,
            coefficients: [[0.0; N_BASIS]; MAX_CHANNELS],
            g_m_s2: None,
            thermal: None,
        };
        for c in 0..3 {
            r.coefficients[c][..4].copy_from_slice(&[m.u0[c], m.k[c][0], m.k[c][1], m.k[c][2]]);
        }
        r
    }

    /// The triad's model-4 calibration, when the record holds exactly model 4 for 3 channels.
    pub fn model4(&self) -> Option<crate::linear::Model4> {
        if self.structure != crate::terms::MODEL_4 || self.n_channels != 3 {
            return None;
        }
        let mut m = crate::linear::Model4 { u0: [0.0; 3], k: [[0.0; 3]; 3] };
        for c in 0..3 {
            m.u0[c] = self.coefficients[c][0];
            m.k[c] = [self.coefficients[c][1], self.coefficients[c][2], self.coefficients[c][3]];
        }
        Some(m)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::terms::MODEL_4;
    use proptest::prelude::*;

    #[test]
    fn crc32_is_iso_hdlc() {
        // The catalogue's check value of CRC-32/ISO-HDLC (the zlib one), whichever implementation.
        assert_eq!(crc32(b"123456789"), 0xCBF4_3926);
        assert_eq!(crc32(b""), 0);
    }

    fn sample() -> Record {
        let mut r = Record {
            device_id: *b"\x01\x02\x03\x04\x05\x06\x07\x08\x09\x0a\x0b\x0c",
            created_unix_s: 1_795_000_000,
            structure: MODEL_4,
            n_channels: 3,
            coefficients: [[0.0; N_BASIS]; MAX_CHANNELS],
            g_m_s2: None,
            thermal: None,
        };
        r.coefficients[0][..4].copy_from_slice(&[32000.5, 1670.0, 3.0, -2.0]);
        r.coefficients[1][..4].copy_from_slice(&[33000.25, 1.5, 1650.0, 4.0]);
        r.coefficients[2][..4].copy_from_slice(&[31000.0, -2.5, 0.5, 1690.0]);
        r
    }

    fn bytes(r: &Record) -> std::vec::Vec<u8> {
        let mut buf = [0u8; MAX_RECORD_LEN];
        let n = r.emit(&mut buf).unwrap();
        buf[..n].to_vec()
    }

    #[test]
    fn literal_bytes_of_a_small_record() {
        let mut r = sample();
        r.n_channels = 1;
        r.structure = Structure::INTERCEPT;
        r.coefficients[0][0] = 1.0;
        let b = bytes(&r);
        assert_eq!(b.len(), 30 + 1 + 8 + 4);
        assert_eq!(&b[..8], b"ACAL\x01\x00\x2b\x00");
        assert_eq!(&b[28..31], &[1, 1, 0]);
        assert_eq!(&b[31..39], &1.0f64.to_le_bytes());
        assert_eq!(Record::parse(&b).unwrap(), r);
    }

    #[test]
    fn round_trip_and_trailing_bytes() {
        let r = sample();
        let mut b = bytes(&r);
        assert_eq!(b.len(), r.len());
        assert_eq!(Record::parse(&b).unwrap(), r);
        b.extend_from_slice(&[0xff; 100]);
        assert_eq!(Record::parse(&b).unwrap(), r);
        assert_eq!(r.model4().unwrap().k[1][1], 1650.0);
        let m = r.model4().unwrap();
        assert_eq!(Record::from_model4(r.device_id, r.created_unix_s, &m), r);
    }

    #[test]
    fn erased_flash_and_wrong_version_are_named() {
        assert_eq!(Record::parse(&[0xff; 64]), Err(RecordError::BadMagic));
        let mut b = bytes(&sample());
        b[4] = 3;
        assert_eq!(Record::parse(&b), Err(RecordError::UnsupportedVersion(3)));
    }

    fn thermal_sample() -> Record {
        let mut r = sample();
        r.g_m_s2 = Some(9.80665);
        r.structure = Structure::from_indices(&[1, 2, 3, 20, 22]);
        for c in 0..3 {
            r.coefficients[c][4] = -3.0 + c as f64;
            r.coefficients[c][5] = 0.167;
        }
        r.thermal =
            Some(Thermal { t_ref_c: 25.0, t_min_c: -10.0, t_max_c: 50.0, source: TempSource::FrontEnd });
        r
    }

    #[test]
    fn version_2_round_trips_with_gravity_and_temperature() {
        let r = thermal_sample();
        let b = bytes(&r);
        assert_eq!(&b[4..6], &[2, 0]);
        assert_eq!(b.len(), 52 + 6 + 8 * 3 * 6 + 4);
        assert_eq!(Record::parse(&b).unwrap(), r);
        // A version-2 record without temperature: gravity alone.
        let mut m4 = sample();
        m4.g_m_s2 = Some(9.8);
        let b = bytes(&m4);
        assert_eq!((b[4], b[50]), (2, 0));
        assert_eq!(Record::parse(&b).unwrap(), m4);
        // Version 1 stays version 1, and cannot hold a term in t.
        assert_eq!(bytes(&sample())[4], 1);
        let mut v1t = thermal_sample();
        v1t.g_m_s2 = None;
        v1t.thermal = None;
        assert_eq!(v1t.emit(&mut [0u8; MAX_RECORD_LEN]), Err(RecordError::BadThermal));
    }

    #[test]
    fn inconsistent_temperature_fields_are_refused() {
        let mut no_source = thermal_sample();
        no_source.thermal = None;
        assert_eq!(no_source.emit(&mut [0u8; MAX_RECORD_LEN]), Err(RecordError::BadThermal));
        let mut empty = thermal_sample();
        empty.thermal.as_mut().unwrap().t_max_c = -10.0;
        assert_eq!(empty.emit(&mut [0u8; MAX_RECORD_LEN]), Err(RecordError::BadThermal));
        let mut far_g = thermal_sample();
        far_g.g_m_s2 = Some(1.0);
        assert_eq!(far_g.emit(&mut [0u8; MAX_RECORD_LEN]), Err(RecordError::BadThermal));
        // Bytes that say "no input" but hold terms in t, with a valid CRC.
        let mut b = bytes(&thermal_sample());
        b[50] = 0;
        b[38..50].fill(0);
        let n = b.len();
        let crc = crc32(&b[..n - 4]);
        b[n - 4..].copy_from_slice(&crc.to_le_bytes());
        assert_eq!(Record::parse(&b), Err(RecordError::BadThermal));
        b[50] = 7;
        let crc = crc32(&b[..n - 4]);
        b[n - 4..].copy_from_slice(&crc.to_le_bytes());
        assert_eq!(Record::parse(&b), Err(RecordError::BadThermal));
    }

    #[test]
    fn every_bit_flip_and_truncation_is_rejected() {
        let b = bytes(&sample());
        let b2 = bytes(&thermal_sample());
        for i in 0..b2.len() * 8 {
            let mut c = b2.clone();
            c[i / 8] ^= 1 << (i % 8);
            assert!(Record::parse(&c).is_err(), "flip of bit {i} accepted (version 2)");
        }
        for i in 0..b.len() * 8 {
            let mut c = b.clone();
            c[i / 8] ^= 1 << (i % 8);
            assert!(Record::parse(&c).is_err(), "flip of bit {i} accepted");
        }
        for n in 0..b.len() {
            assert!(Record::parse(&b[..n]).is_err(), "truncation to {n} accepted");
        }
    }

    #[test]
    fn emit_refuses_non_finite_and_small_buffers() {
        let mut r = sample();
        assert_eq!(r.emit(&mut [0u8; 10]), Err(RecordError::BufferTooSmall));
        r.coefficients[2][3] = f64::INFINITY;
        assert_eq!(r.emit(&mut [0u8; MAX_RECORD_LEN]), Err(RecordError::NonFinite));
    }

    proptest! {
        #[test]
        fn any_bytes_parse_or_error(data in proptest::collection::vec(any::<u8>(), 0..1500)) {
            let _ = Record::parse(&data);
        }

        #[test]
        fn valid_header_with_random_body_never_panics(
            body in proptest::collection::vec(any::<u8>(), 0..400), n_ch in 0u8..10, n_t in 0u8..22
        ) {
            let mut b = bytes(&sample());
            b[28] = n_ch;
            b[29] = n_t;
            b.truncate(30);
            b.extend_from_slice(&body);
            let _ = Record::parse(&b);
        }
    }
}
