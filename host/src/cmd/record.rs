//! `accelcal record show`: what a calibration record file holds, whether a node would accept it
//! (the node's own check, `accelcal_shared::boot::gate`), and whether `fit --record` and `flash`
//! would (`accelcal_core::calibrate::verdict`: also refuses sensitivities no unit has).

use accelcal_core::calibrate::{record_crc_hex, verdict};
use accelcal_core::campaign::identity::{same, Identity};
use accelcal_core::error::bad;
use accelcal_core::output::write_json;
use accelcal_core::uncertainty::UncertaintyJson;
use accelcal_line::node::session::device_id_hex;
use accelcal_shared::boot;
use accelcal_shared::record::{Record, FORMAT_VERSION};
use serde::Serialize;

use crate::settings::line::RecordShow;

/// The JSON written by `record show --json`.
#[derive(Debug, Serialize)]
pub struct RecordJson {
    /// Record length in bytes, CRC included.
    pub length: usize,
    /// Record format version.
    pub format_version: u16,
    /// CRC-32 (ISO-HDLC) as stored, `0x` and 8 hex digits.
    pub crc32: String,
    /// Device id, 24 hex digits (as `fit --device-id` takes it).
    pub device_id: String,
    /// Creation time, seconds since the Unix epoch.
    pub created_unix_s: u64,
    /// Creation time as a UTC date and time (ISO 8601).
    pub created_utc: String,
    /// The model's terms, in record order.
    pub terms: Vec<String>,
    /// Coefficients per channel, in term order (codes, codes per (m/s²)ⁿ, codes per °C…).
    pub coefficients: Vec<Vec<f64>>,
    /// Local gravity the fit used, m/s² (`null` in a format-1 record, which does not say).
    pub g_m_s2: Option<f64>,
    /// The temperature part of a record with terms in t (`null` otherwise).
    pub thermal: Option<ThermalJson>,
    /// Whether a node (every build, with the record's device id) accepts the record.
    pub node_accepts: bool,
    /// Why accelcal refuses it: a node's refusal as the node reports it, or an implausible
    /// sensitivity that a node would accept (`null` when neither).
    pub refusal: Option<String>,
    /// With `--fit` or `--db`: the fit's uncertainty budget, as `fit --json` states it (`null`
    /// when that fit has none, e.g. test turns); absent without them.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub uncertainty: Option<Option<UncertaintyJson>>,
}

/// The record's description.
pub fn describe(bytes: &[u8], rec: &Record) -> RecordJson {
    let n = rec.len();
    let mut crc = [0u8; 4];
    crc.copy_from_slice(&bytes[n - 4..n]);
    let n_t = rec.structure.len();
    let node = boot::gate(rec);
    RecordJson {
        length: n,
        format_version: FORMAT_VERSION,
        crc32: format!("{:#010x}", u32::from_le_bytes(crc)),
        device_id: device_id_hex(&rec.device_id),
        created_unix_s: rec.created_unix_s,
        created_utc: utc(rec.created_unix_s),
        terms: rec.structure.terms().map(|t| t.to_string()).collect(),
        coefficients: (0..rec.n_channels as usize).map(|c| rec.coefficients[c][..n_t].to_vec()).collect(),
        g_m_s2: rec.g_m_s2,
        thermal: rec.thermal.map(|t| ThermalJson {
            t_ref_c: t.t_ref_c,
            t_min_c: t.t_min_c,
            t_max_c: t.t_max_c,
            input: t.source.name(),
        }),
        node_accepts: node.is_ok(),
        refusal: verdict(rec).err().map(|r| {
            accelcal_core::error::Worded::worded(&r, &crate::words::Flags).unwrap_or_else(|| r.to_string())
        }),
        uncertainty: None,
    }
}

/// The uncertainty budget of the fit JSON document `text` (`f_name` names it), once it is shown
/// to be the fit that wrote the record at `path`: the same record CRC (`crc`, as
/// [`record_crc_hex`] gives it) and device id (`device`).
fn budget_of(
    text: &str,
    f_name: &str,
    path: &str,
    (crc, device): (&str, &str),
) -> anyhow::Result<Option<UncertaintyJson>> {
    let doc: serde_json::Value =
        serde_json::from_str(text).map_err(|e| bad(format!("{f_name}: not a JSON document: {e}")))?;
    let id = Identity::of_fit_json(&doc, f_name)?;
    let fit_crc = id.written_record(f_name, path)?;
    same("record CRC", (f_name, fit_crc), (path, crc), "not the record of this fit")?;
    if let Some(d) = &id.device_id {
        same("device id", (f_name, d), (path, device), "not the same unit")?;
    }
    UncertaintyJson::of_fit_json(&doc)
        .map_err(|e| bad(format!("{f_name}: `uncertainty` is not a budget: {e}")))
}

/// The fit JSON `record show` reads the budget from: `--fit`'s file, or the one the database
/// stored with the record (CRC `crc` of device `device`); with its name for messages. `None`
/// when neither is given.
fn fit_text(
    a: &RecordShow,
    path: &str,
    (crc, device): (&str, &str),
) -> anyhow::Result<Option<(String, String)>> {
    if let Some(f) = &a.fit {
        let name = f.display().to_string();
        let text =
            std::fs::read_to_string(f).map_err(|e| bad(format!("{name}: cannot read the fit JSON: {e}")))?;
        return Ok(Some((text, name)));
    }
    let Some(spec) = &a.db else { return Ok(None) };
    let mut db = accelcal_db::Db::open_existing(spec)?;
    let crc32 = u32::from_str_radix(crc, 16).map_err(|e| anyhow::anyhow!("record CRC {crc}: {e}"))?;
    match db.fit_of_record(device, crc32)? {
        Some(text) => Ok(Some((text, format!("the fit {} stored with record {crc}", db.target())))),
        None => Err(bad(format!(
            "{path}: no run in {} stored this record (device {device}, CRC {crc}), so it has no fit there",
            db.target()
        ))),
    }
}

/// The temperature part of a record, as `record show --json` writes it.
#[derive(Debug, Serialize)]
pub struct ThermalJson {
    /// Reference temperature, °C: the terms' t is `temp_c − t_ref_c`.
    pub t_ref_c: f32,
    /// Lowest calibrated temperature, °C.
    pub t_min_c: f32,
    /// Highest calibrated temperature, °C.
    pub t_max_c: f32,
    /// Where the node reads the temperature: `mcu` or `front-end`.
    pub input: &'static str,
}

/// Runs `accelcal record show`.
pub fn run_show(a: &RecordShow) -> anyhow::Result<()> {
    let path = a.file.display();
    let bytes = std::fs::read(&a.file).map_err(|e| bad(format!("{path}: cannot read the record: {e}")))?;
    let rec = Record::parse(&bytes).map_err(|e| bad(format!("{path}: {e}")))?;
    let mut j = describe(&bytes, &rec);
    let (name, crc) = (path.to_string(), record_crc_hex(&bytes[..rec.len()]));
    let fit = fit_text(a, &name, (&crc, &j.device_id))?;
    if let Some((text, f_name)) = &fit {
        j.uncertainty = Some(budget_of(text, f_name, &name, (&crc, &j.device_id))?);
    }
    outln!("record {path}: {} bytes, format version {}, CRC-32 {}", j.length, j.format_version, j.crc32)?;
    outln!("device id: {}", j.device_id)?;
    outln!("created: {} ({})", j.created_unix_s, j.created_utc)?;
    match j.g_m_s2 {
        Some(g) => outln!("g: {g} m/s² (the gravity the fit used)")?,
        None => outln!("g: not stated (format version 1)")?,
    }
    outln!("terms: {}", j.terms.join(","))?;
    if let Some(t) = &j.thermal {
        outln!(
            "temperature: t = temp_c − {} °C, calibrated {} to {} °C, read from the {}",
            t.t_ref_c,
            t.t_min_c,
            t.t_max_c,
            if t.input == "mcu" { "MCU's sensor" } else { "front end's channel" }
        )?;
    }
    for (c, coef) in j.coefficients.iter().enumerate() {
        let v: Vec<String> = coef.iter().map(|v| v.to_string()).collect();
        outln!("channel {c}: {}", v.join(" "))?;
    }
    match &j.refusal {
        None if j.thermal.is_some() => outln!(
            "node: accepts it (model 4 with thermal terms on three channels, invertible over the calibrated range in f32 and fixed point)"
        )?,
        None => outln!("node: accepts it (model 4 on three channels, invertible in f32 and fixed point)")?,
        Some(r) if j.node_accepts => outln!("node: would accept it, but accelcal refuses it: {r}")?,
        Some(r) => outln!("node: {r}")?,
    }
    match (&fit, &j.uncertainty) {
        (Some(_), Some(Some(b))) => super::uncertainty::print_budget(b)?,
        (Some((_, name)), _) => outln!(
            "uncertainty: {name} states no budget (one is worked out for a model-4 triad fitted by least squares)"
        )?,
        (None, _) => {}
    }
    if let Some(p) = &a.json {
        write_json(p, &j)?;
        outln!("wrote {}", p.display())?;
    }
    Ok(())
}

/// A Unix time as `YYYY-MM-DDTHH:MM:SSZ` ([`accelcal_core::output::utc_date_time`]).
pub fn utc(unix_s: u64) -> String {
    accelcal_core::output::utc_date_time(i64::try_from(unix_s).unwrap_or(i64::MAX))
}

#[cfg(test)]
mod tests {
    use super::utc;

    #[test]
    fn unix_times_become_utc_dates() {
        assert_eq!(utc(0), "1970-01-01T00:00:00Z");
        assert_eq!(utc(951_782_400), "2000-02-29T00:00:00Z");
        assert_eq!(utc(1_800_000_000), "2027-01-15T08:00:00Z");
        assert_eq!(utc(4_102_444_799), "2099-12-31T23:59:59Z");
    }
}
