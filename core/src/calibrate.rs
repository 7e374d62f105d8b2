//! Fitting the coefficients of a campaign's channels (LSQ or test turns) and building the
//! calibration record the node applies.

use std::path::Path;

use accelcal_shared::boot::{self, BootError};
use accelcal_shared::record::{Record, Thermal, MAX_CHANNELS, MAX_RECORD_LEN};
use accelcal_shared::terms::MODEL_4;
use accelcal_shared::{Structure, N_BASIS};

use crate::campaign::Campaign;
use crate::error::bad;
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
pub fn check_record_g(g: f64) -> anyhow::Result<()> {
    if !accelcal_shared::record::G_RANGE.contains(&g) {
        return Err(bad(format!(
            "a record states the local gravity its fit used, 9.7 to 9.9 m/s² on the Earth's surface; \
             the fit used {g} m/s² (--g)"
        )));
    }
    Ok(())
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
        return Err(bad(if structure.is_thermal() {
            format!("the terms `{structure}` hold the temperature: the record needs --temp-input (mcu or front-end)")
        } else {
            "--temp-input applies to a record with terms in t only".to_string()
        }));
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

/// Refuses a record that a node would refuse (the node's own check, [`boot::gate`]): bad input
/// naming `path` (the record file, read or about to be written), with the node's reason as the
/// node reports it.
pub fn gate(path: &Path, rec: &Record) -> anyhow::Result<()> {
    boot::gate(rec).map_err(|e| bad(format!("{}: {}", path.display(), refusal(e))))
}

/// Why a node would refuse a record, as the node reports it (the fault's name first), with what
/// to do about it.
pub fn refusal(e: BootError) -> String {
    let reason = match e {
        // The node reports a record for no device like one for another device; say which.
        BootError::NoDeviceId => format!("WrongDevice: {e}"),
        _ => e.fault().to_string(),
    };
    let hint = match e {
        BootError::NoDeviceId => " (give the MCU's unique id: `fit --device-id HEX`)",
        BootError::NotModel4 => {
            " (fit it with `--terms ax,ay,az`, the default, optionally with t, t^2, ax*t, ay*t, az*t)"
        }
        _ => "",
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
pub fn parse_device_id(s: &str) -> anyhow::Result<[u8; 12]> {
    let s = s.trim();
    if s.len() != 24 || !s.bytes().all(|b| b.is_ascii_hexdigit()) {
        return Err(bad(format!(
            "--device-id must be 24 hex digits (the MCU's 96-bit unique id), got `{s}`"
        )));
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
