//! `accelcal fit`: coefficients by least squares or test turns, and the calibration record.

use std::path::Path;

use accelcal_shared::record::{Record, MAX_CHANNELS, MAX_RECORD_LEN};
use accelcal_shared::terms::MODEL_4;
use accelcal_shared::N_BASIS;
use anyhow::Context;
use serde::Serialize;

use crate::campaign::Campaign;
use crate::cli::{FitArgs, Method};
use crate::error::bad;
use crate::lsq::{self, LsqFit};
use crate::output::{finite, write_atomic, write_json};
use crate::positions::{ChannelStats, Positions};
use crate::testturn;

/// JSON of one channel's fit.
#[derive(Serialize)]
pub struct FitChannelJson {
    channel: String,
    terms: Vec<String>,
    coefficients: Vec<f64>,
    std_errors: Vec<Option<f64>>,
    condition: Option<f64>,
    rms_codes: Option<f64>,
}

/// The JSON document of `fit`.
#[derive(Serialize)]
pub struct FitJson {
    method: &'static str,
    channels: Vec<FitChannelJson>,
}

/// Fits every channel of a campaign.
pub fn fit_all(
    c: &Campaign,
    g: f64,
    method: Method,
    structure: accelcal_shared::Structure,
) -> anyhow::Result<Vec<(String, LsqFit)>> {
    let pos = Positions::new(c, g);
    fit_positions(&pos, &pos.channel_stats(c), method, structure)
}

/// Fits every channel from its dwell statistics (all that LSQ and test turns need).
pub fn fit_positions(
    pos: &Positions,
    stats: &[ChannelStats],
    method: Method,
    structure: accelcal_shared::Structure,
) -> anyhow::Result<Vec<(String, LsqFit)>> {
    match method {
        Method::Lsq => stats
            .iter()
            .map(|s| {
                let f = lsq::fit(pos, s, structure, None)
                    .map_err(|e| bad(format!("channel `{}`: {e}", s.name)))?;
                Ok((s.name.clone(), f))
            })
            .collect(),
        Method::GravityNorm => Err(bad(
            "gravity-norm fits a raw recording, not a campaign (accelcal fit INPUT --method gravity-norm)",
        )),
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

/// Builds the record of a set of fits (all with the same structure).
pub fn record(fits: &[(String, LsqFit)], device_id: [u8; 12], created_unix_s: u64) -> anyhow::Result<Record> {
    if fits.is_empty() || fits.len() > MAX_CHANNELS {
        return Err(bad(format!(
            "a calibration record holds 1 to {MAX_CHANNELS} channels, the campaign has {}",
            fits.len()
        )));
    }
    let structure = fits[0].1.structure;
    let mut rec = Record {
        device_id,
        created_unix_s,
        structure,
        n_channels: fits.len() as u8,
        coefficients: [[0.0; N_BASIS]; MAX_CHANNELS],
    };
    for (c, (_, f)) in fits.iter().enumerate() {
        rec.coefficients[c][..f.coefficients.len()].copy_from_slice(&f.coefficients);
    }
    Ok(rec)
}

/// Writes a record file.
pub fn write_record(path: &Path, rec: &Record) -> anyhow::Result<()> {
    let mut buf = [0u8; MAX_RECORD_LEN];
    let n = rec.emit(&mut buf).map_err(|e| anyhow::anyhow!("encoding the record: {e}"))?;
    write_atomic(path, &buf[..n])
}

/// Parses 24 hex digits into a 96-bit device id.
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

/// The JSON document of a set of fits.
pub fn to_json(method: Method, fits: &[(String, LsqFit)]) -> FitJson {
    FitJson {
        method: match method {
            Method::Lsq => "lsq",
            Method::TestTurns => "test-turns",
            Method::GravityNorm => "gravity-norm",
        },
        channels: fits
            .iter()
            .map(|(name, f)| FitChannelJson {
                channel: name.clone(),
                terms: f.structure.terms().map(|t| t.to_string()).collect(),
                coefficients: f.coefficients.clone(),
                std_errors: f.std_errors.iter().map(|&v| finite(v)).collect(),
                condition: finite(f.condition).filter(|_| method == Method::Lsq),
                rms_codes: finite(f.rms),
            })
            .collect(),
    }
}

/// Prints the coefficient table.
pub fn print_table(method: Method, fits: &[(String, LsqFit)]) {
    for (name, f) in fits {
        match method {
            Method::Lsq => {
                println!("channel {name}: LSQ, condition {:.3}, residual RMS {:.2} codes", f.condition, f.rms)
            }
            Method::TestTurns => println!("channel {name}: test turns"),
            Method::GravityNorm => println!("channel {name}: gravity norm"),
        }
        println!("  {:<10} {:>16} {:>14}", "term", "coefficient", "std error");
        for ((t, c), s) in f.structure.terms().zip(&f.coefficients).zip(&f.std_errors) {
            println!("  {:<10} {:>16} {:>14}", t.to_string(), super::sig(*c, 8), super::sig(*s, 3));
        }
    }
}

/// Runs `accelcal fit`.
pub fn run(a: &FitArgs, warnings: &mut super::Warnings) -> anyhow::Result<()> {
    if a.method == Method::GravityNorm {
        return crate::gravity::cli::run(&crate::gravity::cli::GravityFitArgs {
            input: a.campaign.clone(),
            g: a.common.g,
            json: a.common.json.clone(),
            options: a.gravity.clone(),
        });
    }
    super::check_g(a.common.g)?;
    let structure = lsq::parse_terms(&a.terms).map_err(|e| bad(format!("--terms: {e}")))?;
    let device_id = parse_device_id(&a.device_id)?;
    // Streamed: the fits need the dwell statistics only, so memory does not grow with the rows.
    let r = super::reduce_campaign(&a.campaign, warnings)?;
    let fits = fit_positions(&r.positions(a.common.g), &r.channel_stats(), a.method, structure)
        .with_context(|| a.campaign.display().to_string())?;
    print_table(a.method, &fits);
    if let Some(j) = &a.common.json {
        write_json(j, &to_json(a.method, &fits))?;
    }
    if let Some(path) = &a.record {
        let created = a.created.unwrap_or_else(|| {
            std::time::SystemTime::now()
                .duration_since(std::time::UNIX_EPOCH)
                .map(|d| d.as_secs())
                .unwrap_or(0)
        });
        let rec = record(&fits, device_id, created)?;
        write_record(path, &rec)?;
        println!(
            "record: {} ({} bytes, {} channels, terms {})",
            path.display(),
            rec.len(),
            rec.n_channels,
            rec.structure
        );
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::{simulate, SimConfig};

    #[test]
    fn streaming_fit_writes_the_same_json_as_the_in_memory_fit() {
        let (c, _) = simulate(&SimConfig { samples: 7, ..SimConfig::default() });
        let mut csv = Vec::new();
        c.write(&mut csv).unwrap();
        let p = Path::new("c.csv");
        let mem = Campaign::from_reader(&csv[..], p).unwrap();
        let red = Campaign::reduce_reader(&csv[..], p).unwrap();
        for method in [Method::Lsq, Method::TestTurns] {
            let a = fit_all(&mem, 9.81, method, MODEL_4).unwrap();
            let b = fit_positions(&red.positions(9.81), &red.channel_stats(), method, MODEL_4).unwrap();
            let json = |f: &[(String, LsqFit)]| serde_json::to_string(&to_json(method, f)).unwrap();
            assert_eq!(json(&a), json(&b));
        }
    }
}
