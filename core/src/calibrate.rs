//! Fitting the coefficients of a campaign's channels (LSQ or test turns) and building the
//! calibration record the node applies.
//!
//! [`Method`] is the fitting method (LSQ, test turns); [`fit_positions`] and [`fit_all`] fit every
//! channel from its dwell statistics; [`record`] builds the calibration record of a set of fits.
//! [`gate`] makes a record a node would refuse bad input with the node's reason
//! (`shared::boot::gate`), and so is one whose sensitivities no unit has ([`implausible`]: their
//! sign and [`sensitivity_range`] against the 16-bit code span and g); `fit --record`, `flash`
//! and `record show` (which prints the same [`verdict`]) all go through it.
//! [`parse_device_id`] reads a device id as the command line and the documents write it.

use std::path::Path;

use accelcal_shared::boot::{self, BootError};
use accelcal_shared::record::{Record, Thermal, MAX_CHANNELS, MAX_RECORD_LEN};
use accelcal_shared::terms::MODEL_4;
use accelcal_shared::{Structure, N_BASIS};

use crate::campaign::{Campaign, CodeRange};
use crate::error::{bad, Classify, Kind, Plain, Setting, Worded, Wording};
use crate::lsq::{self, LsqFit};
use crate::output::write_atomic;
use crate::positions::{ChannelStats, Positions};
use crate::testturn;

/// How the coefficients of a campaign are fitted.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Method {
    /// Batch least squares over every position (any model).
    Lsq,
    /// Test turns: each axis along +g and −g (model 4 only).
    TestTurns,
}

impl Method {
    /// The name used on the command line and in JSON.
    pub fn name(self) -> &'static str {
        match self {
            Method::Lsq => "lsq",
            Method::TestTurns => "test-turns",
        }
    }
}

/// Fits every channel of an in-memory campaign.
pub fn fit_all(
    c: &Campaign,
    g: f64,
    method: Method,
    structure: Structure,
) -> anyhow::Result<Vec<(String, LsqFit)>> {
    let pos = Positions::new(c, g);
    fit_positions(&pos, &pos.channel_stats(c), method, structure)
}

/// Fits every channel from its dwell statistics (all that LSQ and test turns need).
pub fn fit_positions(
    pos: &Positions,
    stats: &[ChannelStats],
    method: Method,
    structure: Structure,
) -> anyhow::Result<Vec<(String, LsqFit)>> {
    pos.check_terms(structure).map_err(bad)?;
    match method {
        Method::Lsq => stats
            .iter()
            .map(|s| {
                let f = lsq::fit(pos, s, structure, None)
                    .map_err(|e| bad(format!("channel `{}`: {e}", s.name)))?;
                Ok((s.name.clone(), f))
            })
            .collect(),
        Method::TestTurns => {
            if structure != MODEL_4 {
                return Err(bad(format!(
                    "test turns determine model 4 (1,ax,ay,az) only, not `{structure}`"
                )));
            }
            let pairs = testturn::Pairs::find(pos)?;
            Ok(stats.iter().map(|s| (s.name.clone(), testturn::fit(pos, s, &pairs))).collect())
        }
    }
}

/// Refuses a gravity a record cannot state ([`accelcal_shared::record::G_RANGE`]).
pub fn check_record_g(g: f64) -> Result<(), RecordError> {
    if !accelcal_shared::record::G_RANGE.contains(&g) {
        return Err(RecordError::G { g });
    }
    Ok(())
}

/// Why a record cannot be made, or why a node (or a plausible unit) would refuse one.
#[derive(Debug, thiserror::Error)]
pub enum RecordError {
    /// A gravity outside what a record states.
    #[error("{}", self.worded(&Plain).unwrap_or_default())]
    G {
        /// The fit's gravity, m/s².
        g: f64,
    },
    /// A thermal structure without a temperature input, or an input without one.
    #[error("{}", self.worded(&Plain).unwrap_or_default())]
    TempInput {
        /// The structure (thermal when the input is missing).
        structure: Structure,
    },
    /// A device id that is not 24 hex digits.
    #[error("{}", self.worded(&Plain).unwrap_or_default())]
    DeviceId {
        /// What was given.
        value: String,
    },
    /// Sensitivities that no unit has ([`implausible`]).
    #[error("{0}")]
    Implausible(String),
    /// What a node's own check says ([`boot::gate`]).
    #[error("{}", self.worded(&Plain).unwrap_or_default())]
    Refused(BootError),
    /// A record's refusal, with the record file's path.
    #[error("{}: {}", path.display(), why)]
    File {
        /// The record file.
        path: std::path::PathBuf,
        /// Why.
        why: Box<RecordError>,
    },
}

impl Worded for RecordError {
    fn worded(&self, w: &dyn Wording) -> Option<String> {
        Some(match self {
            RecordError::G { g } => format!(
                "a record states the local gravity its fit used, 9.7 to 9.9 m/s² on the Earth's surface; \
                 the fit used {g} m/s² ({})",
                w.name(Setting::G)
            ),
            RecordError::TempInput { structure } if structure.is_thermal() => format!(
                "the terms `{structure}` hold the temperature: the record needs {} (mcu or front-end)",
                w.name(Setting::TempInput)
            ),
            RecordError::TempInput { .. } => {
                format!("{} applies to a record with terms in t only", w.name(Setting::TempInput))
            }
            RecordError::DeviceId { value } => format!(
                "{} must be 24 hex digits (the MCU's 96-bit unique id), got `{value}`",
                w.name(Setting::DeviceId)
            ),
            RecordError::Implausible(_) => return None,
            RecordError::Refused(e) => refusal(*e, w),
            RecordError::File { path, why } => {
                format!("{}: {}", path.display(), why.worded(w).unwrap_or_else(|| why.to_string()))
            }
        })
    }
}

impl Classify for RecordError {
    fn kind(&self) -> Kind {
        Kind::BadInput
    }
}

/// Builds the record of a set of fits (all with the same structure), fitted with gravity `g`
/// (m/s², written into the record) and, for a structure with terms in `t`, the temperature part.
pub fn record(
    fits: &[(String, LsqFit)],
    device_id: [u8; 12],
    created_unix_s: u64,
    g: f64,
    thermal: Option<Thermal>,
) -> anyhow::Result<Record> {
    if fits.is_empty() || fits.len() > MAX_CHANNELS {
        return Err(bad(format!(
            "a calibration record holds 1 to {MAX_CHANNELS} channels, the campaign has {}",
            fits.len()
        )));
    }
    check_record_g(g)?;
    let structure = fits[0].1.structure;
    if structure.is_thermal() != thermal.is_some() {
        return Err(RecordError::TempInput { structure }.into());
    }
    let mut rec = Record {
        device_id,
        created_unix_s,
        structure,
        n_channels: fits.len() as u8,
        coefficients: [[0.0; N_BASIS]; MAX_CHANNELS],
        g_m_s2: Some(g),
        thermal,
    };
    for (c, (_, f)) in fits.iter().enumerate() {
        rec.coefficients[c][..f.coefficients.len()].copy_from_slice(&f.coefficients);
    }
    Ok(rec)
}

/// Refuses a record that a node would refuse (the node's own check, [`boot::gate`]) or whose
/// sensitivities no unit has ([`implausible`]): bad input naming `path` (the record file, read or
/// about to be written), with the node's reason as the node reports it, or the implausible one.
pub fn gate(path: &Path, rec: &Record) -> anyhow::Result<()> {
    verdict(rec).map_err(|why| RecordError::File { path: path.to_owned(), why: Box::new(why) }.into())
}

/// Why `fit`, `flash` and `record show` refuse a record: an implausible sensitivity
/// ([`implausible`]) first (it says what went wrong: the sensitivities of a head that was never
/// turned are also a matrix the node cannot invert), then the node's refusal ([`refusal`]).
pub fn verdict(rec: &Record) -> Result<(), RecordError> {
    implausible(rec).map_or(Ok(()), |why| Err(RecordError::Implausible(why)))?;
    boot::gate(rec).map_err(RecordError::Refused)
}

/// The widest full scale a plausible unit has, in g: a record whose sensitivity says more (one g
/// is a few codes) was fitted from positions that did not move, not from a unit.
pub const MAX_FULL_SCALE_G: f64 = 1000.0;

/// The plausible sensitivities of a unit along its own axis, codes per m/s², at gravity `g`
/// (m/s²), for codes spanning the 16-bit ranges ([`CodeRange`], both 65,535 codes): from the
/// full scale of [`MAX_FULL_SCALE_G`] (half the span over the sensitivity) to one that puts +1 g
/// and −1 g at the two ends of the range (a unit turned in gravity reads both).
pub fn sensitivity_range(g: f64) -> std::ops::RangeInclusive<f64> {
    let span = CodeRange::ALL.map(|c| c.rails().1 - c.rails().0).into_iter().fold(0.0, f64::max);
    span / (2.0 * MAX_FULL_SCALE_G * g)..=span / (2.0 * g)
}

/// Why a record's sensitivities are implausible, or `None`: each channel's coefficient of its own
/// axis (channel 0 of `ax`, 1 of `ay`, 2 of `az`) must be positive (a channel reads more along its
/// axis) and within [`sensitivity_range`] at the record's g (9.81 m/s² when it does not state
/// one). Issue 24: a campaign of six positions at which the head was never turned gave a record
/// of −0.8 codes/(m/s²) that a node accepts.
pub fn implausible(rec: &Record) -> Option<String> {
    let g = rec.g_m_s2.unwrap_or(accelcal_shared::G_STANDARD);
    let range = sensitivity_range(g);
    let terms: Vec<String> = rec.structure.terms().map(|t| t.to_string()).collect();
    for (c, axis) in ["ax", "ay", "az"].into_iter().enumerate().take(rec.n_channels as usize) {
        let Some(i) = terms.iter().position(|t| t == axis) else { continue };
        let k = rec.coefficients[c][i];
        if !range.contains(&k) {
            return Some(format!(
                "implausible sensitivity: channel {c}'s coefficient of {axis} is {k:.4} codes/(m/s²), a unit's is \
                 positive and {:.2} to {:.0} codes/(m/s²) at g = {g} m/s² (16-bit codes, full scale ±1 g to ±{} g): \
                 was the head turned between the positions?",
                range.start(),
                range.end(),
                MAX_FULL_SCALE_G
            ));
        }
    }
    None
}

/// Why a node would refuse a record, as the node reports it (the fault's name first), with what
/// to do about it.
pub fn refusal(e: BootError, w: &dyn Wording) -> String {
    let reason = match e {
        // The node reports a record for no device like one for another device; say which.
        BootError::NoDeviceId => format!("WrongDevice: {e}"),
        _ => e.fault().to_string(),
    };
    let hint = match e {
        BootError::NoDeviceId => format!(" (give the MCU's unique id: {})", w.name(Setting::FitDeviceId)),
        BootError::NotModel4 => format!(
            " (fit it with {}, the default, optionally with t, t^2, ax*t, ay*t, az*t)",
            w.name(Setting::Model4Terms)
        ),
        _ => String::new(),
    };
    format!("a node would refuse this record: {reason}{hint}")
}

/// The bytes of a record file.
pub fn record_bytes(rec: &Record) -> anyhow::Result<Vec<u8>> {
    let mut buf = [0u8; MAX_RECORD_LEN];
    let n = rec.emit(&mut buf).map_err(|e| anyhow::anyhow!("encoding the record: {e}"))?;
    Ok(buf[..n].to_vec())
}

/// The CRC-32 of a record's bytes as `record show`, `info` and the fit JSON's `record_crc` state
/// it: 8 lower-case hex digits of the CRC over everything before the CRC field (its last 4
/// bytes).
pub fn record_crc_hex(bytes: &[u8]) -> String {
    format!("{:08x}", accelcal_shared::record::crc32(&bytes[..bytes.len().saturating_sub(4)]))
}

/// Writes a record file (atomically).
pub fn write_record(path: &Path, rec: &Record) -> anyhow::Result<()> {
    write_atomic(path, &record_bytes(rec)?)
}

/// Parses 24 hex digits into a 96-bit device id (as `accelcal fit --device-id` takes it).
pub fn parse_device_id(s: &str) -> Result<[u8; 12], RecordError> {
    let s = s.trim();
    if s.len() != 24 || !s.bytes().all(|b| b.is_ascii_hexdigit()) {
        return Err(RecordError::DeviceId { value: s.to_string() });
    }
    let mut id = [0u8; 12];
    for (i, b) in id.iter_mut().enumerate() {
        *b = u8::from_str_radix(&s[2 * i..2 * i + 2], 16).expect("checked hex");
    }
    Ok(id)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::{simulate, SimConfig};

    #[test]
    fn sensitivities_no_unit_has_are_refused() {
        let rec = |k: f64| {
            let mut c = [[0.0; N_BASIS]; MAX_CHANNELS];
            for (i, row) in c.iter_mut().take(3).enumerate() {
                row[0] = 32768.0;
                row[1 + i] = if i == 1 { k } else { 1670.0 };
            }
            Record {
                device_id: *b"QEMU-B-L475E",
                created_unix_s: 1,
                structure: MODEL_4,
                n_channels: 3,
                coefficients: c,
                g_m_s2: Some(9.81),
                thermal: None,
            }
        };
        // The simulated unit (~1670), the real Xsens unit (~414): plausible.
        for k in [1670.0, 414.4, 3.4, 3339.0] {
            assert!(verdict(&rec(k)).is_ok(), "{k}");
        }
        // The unturned head of issue 24, a sign flip, a unit whose ±1 g exceeds the code range.
        for k in [-0.8, 0.8, -1670.0, 3341.0] {
            let e = verdict(&rec(k)).unwrap_err().to_string();
            assert!(e.starts_with("implausible sensitivity: channel 1's coefficient of ay is"), "{e}");
            assert!(e.contains("3.34 to 3340 codes/(m/s²) at g = 9.81 m/s²"), "{e}");
        }
        let e = gate(Path::new("r.rec"), &rec(-0.8)).unwrap_err().to_string();
        assert!(
            e.starts_with("r.rec: implausible sensitivity: channel 1's coefficient of ay is -0.8000"),
            "{e}"
        );
    }

    #[test]
    fn streaming_and_in_memory_reads_give_the_same_fits() {
        let (c, _) = simulate(&SimConfig { samples: 7, ..SimConfig::default() });
        let mut csv = Vec::new();
        c.write(&mut csv).unwrap();
        let p = Path::new("c.csv");
        let mem = Campaign::from_reader(&csv[..], p).unwrap();
        let red = Campaign::reduce_reader(&csv[..], p).unwrap();
        for method in [Method::Lsq, Method::TestTurns] {
            let a = fit_all(&mem, 9.81, method, MODEL_4).unwrap();
            let b = fit_positions(&red.positions(9.81), &red.channel_stats(), method, MODEL_4).unwrap();
            assert_eq!(a.len(), b.len());
            for ((na, fa), (nb, fb)) in a.iter().zip(&b) {
                assert_eq!(na, nb);
                assert_eq!(fa.coefficients, fb.coefficients, "{method:?} {na}");
                assert_eq!(fa.std_errors().len(), fb.std_errors().len());
                for (x, y) in fa.std_errors().iter().zip(&fb.std_errors()) {
                    assert!(x == y || (x.is_nan() && y.is_nan()), "{method:?} {na}: {x} vs {y}");
                }
                assert!(fa.rms == fb.rms || (fa.rms.is_nan() && fb.rms.is_nan()));
            }
        }
    }
}
