//! The settings of the commands that talk to a node over its link and need no head (`info`,
//! `output`, `monitor`), of `record show`, `flash`, `report`, `hil` and the emulated bench
//! (`emulate`): plain values, after `settings::check` has checked
//! the line (the timeouts positive, the rate one the node takes, the outputs distinct).

use std::path::PathBuf;
use std::time::Duration;

use accelcal_shared::wire::Output;

use accelcal_core::error::bad;

use accelcal_core::campaign::CodeRange;

use super::values::{FlashRoute, Issuer, RunStore};
use crate::cli::{
    EmulateArgs, FlashArgs, HilArgs, InfoArgs, MonitorArgs, OutputArg, OutputArgs, PortArgs, RecordShowArgs,
    ReportArgs,
};

/// A node's link: its serial port (or `tcp:HOST:PORT`), baud rate and how long a request waits
/// for its answer.
#[derive(Clone, Debug, PartialEq)]
pub struct Link {
    pub port: String,
    pub baud: u32,
    pub timeout: Duration,
}

impl Link {
    /// The link `--port`, `--baud` and `--timeout-s` name.
    pub fn of(a: &PortArgs) -> Link {
        Link { port: a.port.clone(), baud: a.baud, timeout: Duration::from_secs_f64(a.timeout_s) }
    }
}

/// `accelcal info`, settled.
#[derive(Clone, Debug, PartialEq)]
pub struct Info {
    pub link: Link,
    /// `--json`.
    pub json: Option<PathBuf>,
}

/// `info`'s settings.
pub fn info(a: &InfoArgs) -> Info {
    Info { link: Link::of(&a.link), json: a.json.clone() }
}

/// `accelcal output`, settled.
#[derive(Clone, Debug, PartialEq)]
pub struct SetOutput {
    pub link: Link,
    /// What the node streams from now on.
    pub mode: Output,
}

/// `output`'s settings.
pub fn output(a: &OutputArgs) -> SetOutput {
    let mode = match a.mode {
        OutputArg::Calibrated => Output::Calibrated,
        OutputArg::Raw => Output::Raw,
    };
    SetOutput { link: Link::of(&a.link), mode }
}

/// `accelcal monitor`, settled.
#[derive(Clone, Debug, PartialEq)]
pub struct Monitor {
    pub port: String,
    pub baud: u32,
    /// `--count`: blocks shown before it stops (`None`: until Ctrl-C).
    pub count: Option<u64>,
    /// `--rate-hz`: the rate asked of the node first (`None`: its own).
    pub rate_hz: Option<u32>,
    /// `--timeout-s`: a silence this long is an error.
    pub silence: Duration,
}

/// `monitor`'s settings.
pub fn monitor(a: &MonitorArgs) -> Monitor {
    Monitor {
        port: a.port.clone(),
        baud: a.baud,
        count: a.count,
        rate_hz: a.rate_hz,
        silence: Duration::from_secs_f64(a.timeout_s),
    }
}

/// `accelcal record show`, settled.
#[derive(Clone, Debug, PartialEq)]
pub struct RecordShow {
    /// The record file.
    pub file: PathBuf,
    /// `--fit`: the fit JSON its budget is read from; else `--db`, the database that stored it.
    pub fit: Option<PathBuf>,
    pub db: Option<String>,
    /// `--json`.
    pub json: Option<PathBuf>,
}

/// `record show`'s settings.
pub fn record_show(a: &RecordShowArgs) -> RecordShow {
    RecordShow { file: a.file.clone(), fit: a.fit.clone(), db: a.db.clone(), json: a.json.clone() }
}

/// `accelcal emulate`, settled.
#[derive(Clone, Debug, PartialEq)]
pub struct Emulate {
    /// The node's firmware ELF and the QEMU that runs it.
    pub elf: PathBuf,
    pub qemu_bin: PathBuf,
    /// One node per `--unit`, with its `--seed` and `--record` when given (once each, in order).
    pub units: Vec<EmulatedUnit>,
    /// `--head-speed`, degrees per second (positive).
    pub head_speed_deg_s: f64,
    /// `--rate-factor` in (0, 100].
    pub rate_factor: f64,
    /// `--gdb-port`, `--head-port` (0: any free port).
    pub gdb_port: u16,
    pub head_port: u16,
    /// `--first-node`, from 0.
    pub first_node: usize,
    /// `--chamber`, °C, and `--thermal-lag-s` (≥ 0): the sensor's temperature.
    pub chamber_c: f64,
    pub thermal_lag_s: f64,
}

/// One emulated node's unit.
#[derive(Clone, Debug, PartialEq)]
pub struct EmulatedUnit {
    /// The unit file.
    pub file: PathBuf,
    /// `--seed` (`None`: the unit's own).
    pub seed: Option<u64>,
    /// `--record`: the calibration record in its flash at start.
    pub record: Option<PathBuf>,
}

/// `emulate`'s settings (the counts of `--seed` and `--record` are checked by `settings::check`).
pub fn emulate(a: &EmulateArgs) -> anyhow::Result<Emulate> {
    if !accelcal_line::node::head::CHAMBER_RANGE_C.contains(&a.chamber) {
        return Err(bad(format!("--chamber must be a temperature in -60..=150 °C, got {}", a.chamber)));
    }
    if !(a.thermal_lag_s.is_finite() && a.thermal_lag_s >= 0.0) {
        return Err(bad(format!(
            "--thermal-lag-s must be a number of seconds >= 0, got {}",
            a.thermal_lag_s
        )));
    }
    let units = a
        .unit
        .iter()
        .enumerate()
        .map(|(i, file)| EmulatedUnit {
            file: file.clone(),
            seed: a.seed.get(i).copied(),
            record: a.record.get(i).cloned(),
        })
        .collect();
    Ok(Emulate {
        elf: a.elf.clone(),
        qemu_bin: a.qemu_bin.clone(),
        units,
        head_speed_deg_s: a.head_speed,
        rate_factor: a.rate_factor,
        gdb_port: a.gdb_port.unwrap_or(0),
        head_port: a.head_port.unwrap_or(0),
        first_node: usize::from(a.first_node) - 1,
        chamber_c: a.chamber,
        thermal_lag_s: a.thermal_lag_s,
    })
}

/// `accelcal flash`, settled.
#[derive(Clone, Debug, PartialEq)]
pub struct Flash {
    /// The record file written.
    pub record: PathBuf,
    /// How the MCU is reached.
    pub route: FlashRoute,
    /// `--port`, `--baud`: the node's link, to confirm the record after the reset.
    pub port: Option<String>,
    pub baud: u32,
    /// `--cut-after` (a GDB route only): the write is cut after this many bytes.
    pub cut_after: Option<usize>,
    /// `--db` and `--run-id`: the run whose stored record is written.
    pub store: Option<RunStore>,
}

/// `flash`'s settings (the options of the other route refused by `settings::check`).
pub fn flash(a: &FlashArgs) -> anyhow::Result<Flash> {
    let route = match &a.gdb {
        Some(g) => FlashRoute::Gdb(g.clone()),
        None => FlashRoute::Probe { chip: a.chip.clone(), probe: a.probe.clone() },
    };
    Ok(Flash {
        record: a.record.clone(),
        route,
        port: a.port.clone(),
        baud: a.baud,
        cut_after: a.cut_after,
        store: RunStore::of(&a.run)?,
    })
}

/// `accelcal hil`, settled.
#[derive(Clone, Debug, PartialEq)]
pub struct Hil {
    /// `--qemu`: the node's firmware ELF, and the QEMU that runs it.
    pub elf: PathBuf,
    pub qemu_bin: PathBuf,
    /// `--record`: the calibration record the node applies.
    pub record: PathBuf,
    /// The campaign replayed, and its range of codes (`None`: its `# codes:` line).
    pub campaign: PathBuf,
    pub codes: Option<CodeRange>,
    /// `--out`: the node's calibrated output.
    pub out: PathBuf,
    /// `--timeout-s`: how long the node may stay silent.
    pub timeout: Duration,
}

/// `hil`'s settings.
pub fn hil(a: &HilArgs) -> Hil {
    Hil {
        elf: a.elf.clone(),
        qemu_bin: a.qemu_bin.clone(),
        record: a.record.clone(),
        campaign: a.campaign.clone(),
        codes: a.codes,
        out: a.out.clone(),
        timeout: Duration::from_secs_f64(a.timeout_s),
    }
}

/// `accelcal report`, settled.
#[derive(Clone, Debug, PartialEq)]
pub struct Report {
    /// The unit's campaign, record and fit JSON, and its as-left verification JSON.
    pub campaign: PathBuf,
    pub record: PathBuf,
    pub fit: PathBuf,
    pub verify: Option<PathBuf>,
    /// `--as-found`: the verification before the calibration.
    pub as_found: Option<PathBuf>,
    /// `--g`, m/s²: must be the fit's when given.
    pub g: Option<f64>,
    /// `--out`: the certificate.
    pub out: PathBuf,
    /// `--db` and `--run-id`: the run the certificate is stored with.
    pub store: Option<RunStore>,
    /// Who issues it, for whom.
    pub issuer: Issuer,
}

/// `report`'s settings (g, the issuer and the files' distinctness checked by `settings::check`).
pub fn report(a: &ReportArgs) -> anyhow::Result<Report> {
    Ok(Report {
        campaign: a.campaign.clone(),
        record: a.record.clone(),
        fit: a.fit.clone(),
        verify: a.verify.clone(),
        as_found: a.as_found.clone(),
        g: a.g,
        out: a.out.clone(),
        store: RunStore::of(&a.run)?,
        issuer: Issuer::of(&a.issuer),
    })
}
