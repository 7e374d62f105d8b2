//! The settings of the commands that talk to a node over its link (`info`, `output`, `monitor`,
//! `acquire`, `verify`), of `record show`, `flash`, `report`, `hil` and the emulated bench
//! (`emulate`): plain values, after `settings::check` has checked
//! the line (the timeouts positive, the rate one the node takes, the outputs distinct).

use std::path::PathBuf;
use std::time::Duration;

use accelcal_shared::wire::Output;

use accelcal_core::error::bad;

use accelcal_core::campaign::CodeRange;

use accelcal_core::sim::Plan;
use accelcal_line::acquire::StaticRule;
use accelcal_line::head::{HeadSettings, HeadSpec, Settle, ZaberAxes};

use super::values::{FlashRoute, Issuer, RunStore};
use crate::cli::{
    AcquireArgs, EmulateArgs, FlashArgs, HilArgs, InfoArgs, MonitorArgs, OutputArg, OutputArgs, PortArgs,
    RecordShowArgs, ReportArgs, VerifyArgs,
};
use crate::resolved::Gravity;

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
    fn of(a: &PortArgs) -> Link {
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
    /// `--head`: the emulated head's protocol, and `--head-fault` at `--head-fault-at`.
    pub head: accelcal_line::emulate::bench::HeadDialect,
    pub head_fault: Option<accelcal_line::emulate::fault::HeadFault>,
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

use crate::cli::HeadDialectArg;
use accelcal_line::emulate::bench::HeadDialect;
use accelcal_line::emulate::fault::HeadFault;

/// `emulate`'s settings (the counts of `--seed` and `--record` are checked by `settings::check`).
pub fn emulate(a: &EmulateArgs) -> anyhow::Result<Emulate> {
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
        head: match a.head_dialect {
            HeadDialectArg::Sim => HeadDialect::Sim,
            HeadDialectArg::Zaber => HeadDialect::Zaber,
            HeadDialectArg::ZaberPty => HeadDialect::ZaberPty,
        },
        head_fault: a.head_fault.zip(a.head_fault_at).map(|(kind, at_move)| HeadFault { kind, at_move }),
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
        store: RunStore::existing(&a.run, "flash --db")?,
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
    /// `--pdf`: the certificate as a PDF.
    pub pdf: Option<PathBuf>,
    /// `--dcc`: the certificate as a DCC (XML).
    pub dcc: Option<PathBuf>,
    /// `--technical`: the technical report.
    pub technical: Option<PathBuf>,
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
        pdf: a.pdf.clone(),
        dcc: a.dcc.clone(),
        technical: a.technical.clone(),
        store: RunStore::existing(&a.run, "report --db")?,
        issuer: Issuer::of(&a.issuer),
    })
}

/// The chamber options of `acquire`/`verify`, checked: the soak is required with a setpoint and
/// refused without one.
fn soak_of(setpoints: &[f64], soak_s: Option<f64>) -> anyhow::Result<Option<Duration>> {
    match (setpoints.is_empty(), soak_s) {
        (true, None) => Ok(None),
        (true, Some(_)) => Err(bad("--soak-s applies with --chamber only")),
        (false, None) => Err(bad("--chamber needs --soak-s (seconds to wait at each setpoint)")),
        (false, Some(s)) => {
            if let Some(t) = setpoints.iter().find(|t| !accelcal_line::head::CHAMBER_RANGE_C.contains(*t)) {
                return Err(bad(format!("--chamber {t}: a setpoint must be in -60..=150 °C")));
            }
            Ok(Some(Duration::from_secs_f64(s)))
        }
    }
}

/// `accelcal acquire`, settled.
pub struct Acquire {
    /// One node per `--port`, each with its `--out` and `--serial` (once each, in order).
    pub nodes: Vec<AcquireNode>,
    pub baud: u32,
    /// `--timeout-s`: how long a request waits for its answer.
    pub answer_timeout: Duration,
    pub head: HeadSettings,
    /// The head's part of the settled rule.
    pub settle: Settle,
    /// `--plan` as given, and the plan.
    pub plan_spec: String,
    pub plan: Plan,
    /// `--samples` per position and `--rate-hz` (`None`: the defaults, or with `--resume` the
    /// campaign's).
    pub samples: Option<usize>,
    pub rate_hz: Option<u32>,
    /// The gravity the command line states (`None`: the campaign's with `--resume`, else 9.81,
    /// announced).
    pub stated: Option<Gravity>,
    /// `--resume`: continue the campaigns.
    pub resume: bool,
    /// When a position is static (`--static-window`, `--static-z`) and how long it may take to
    /// become so (`--settle-timeout-s`).
    pub rule: StaticRule,
    pub settle_timeout: Duration,
    /// `--chamber` and `--soak-s`.
    pub chamber: Option<accelcal_line::acquire::Chamber>,
}

/// One node of an acquisition.
#[derive(Clone, Debug, PartialEq)]
pub struct AcquireNode {
    pub port: String,
    pub out: PathBuf,
    pub serial: Option<String>,
}

/// `acquire`'s settings (the counts of `--out` and `--serial` checked by `settings::check`).
pub fn acquire(a: &AcquireArgs, stated: Option<&Gravity>) -> anyhow::Result<Acquire> {
    let plan = Plan::from_spec(&a.plan, 1).map_err(|e| bad(format!("--plan {e}")))?;
    let soak = soak_of(&a.chamber, a.soak_s)?;
    let nodes = a
        .port
        .iter()
        .enumerate()
        .map(|(i, port)| AcquireNode {
            port: port.clone(),
            out: a.out[i].clone(),
            serial: a.serial.get(i).cloned(),
        })
        .collect();
    Ok(Acquire {
        nodes,
        baud: a.baud,
        answer_timeout: Duration::from_secs_f64(a.timeout_s),
        head: head_settings(&a.head, a.head_timeout_s, a.zaber.axes()),
        settle: settle(a.head_tolerance_arcsec, a.settle_s),
        plan_spec: a.plan.clone(),
        plan,
        samples: a.samples,
        rate_hz: a.rate_hz,
        stated: stated.cloned(),
        resume: a.resume,
        rule: StaticRule { window: a.static_window, z: a.static_z, ..StaticRule::default() },
        settle_timeout: Duration::from_secs_f64(a.settle_timeout_s),
        chamber: soak.map(|soak| accelcal_line::acquire::Chamber { setpoints_c: a.chamber.clone(), soak }),
    })
}

/// What a verification's errors are judged by.
#[derive(Clone, Debug, PartialEq)]
pub enum Judged {
    /// `--tolerance`, m/s².
    Tolerance(f64),
    /// The tolerance derived from the measured scatter, with the fit's uncertainty when `--fit`
    /// is given, at the coverage factor `--coverage`.
    Derived { fit: Option<PathBuf>, k: f64 },
}

/// `accelcal verify`, settled.
pub struct Verify {
    pub link: Link,
    pub head: HeadSettings,
    /// The head's part of the settled rule.
    pub settle: Settle,
    /// `--plan` and `--samples` per position.
    pub plan: Plan,
    pub samples: usize,
    pub judged: Judged,
    /// `--spec`: the product specification the parameters are decided against, with the head's
    /// stated uncertainties (arcsec) its budget takes.
    pub spec: Option<PathBuf>,
    pub head_angle_u: Option<f64>,
    pub head_orthogonality_u: Option<f64>,
    /// The gravity the command line states (`None`: the fit's, else 9.81, announced).
    pub stated: Option<Gravity>,
    pub settle_timeout: Duration,
    /// `--chamber` (one setpoint) and its soak.
    pub chamber: Option<(f64, Duration)>,
    /// `--json`.
    pub json: Option<PathBuf>,
    /// `--db`, `--run-id`, `--relabel`, and which verification of the run it is (`--phase`).
    pub store: Option<RunStore>,
    pub phase: accelcal_db::Phase,
}

/// `verify`'s settings (`--coverage` and `--fit` refused with `--tolerance` by `settings::check`).
pub fn verify(a: &VerifyArgs, stated: Option<&Gravity>) -> anyhow::Result<Verify> {
    let plan = Plan::from_spec(&a.plan, 1).map_err(|e| bad(format!("--plan {e}")))?;
    let judged = match a.tolerance {
        Some(t) => Judged::Tolerance(t),
        None => Judged::Derived {
            fit: a.fit.clone(),
            k: a.coverage.unwrap_or(accelcal_line::verify::DEFAULT_COVERAGE),
        },
    };
    let soak = soak_of(a.chamber.as_slice(), a.soak_s)?;
    Ok(Verify {
        link: Link::of(&a.link),
        head: head_settings(&a.head, a.head_timeout_s, a.zaber.axes()),
        settle: settle(a.head_tolerance_arcsec, a.settle_s),
        plan,
        samples: a.samples,
        judged,
        spec: a.spec.clone(),
        head_angle_u: a.head_angle_u,
        head_orthogonality_u: a.head_orthogonality_u,
        stated: stated.cloned(),
        settle_timeout: Duration::from_secs_f64(a.settle_timeout_s),
        chamber: a.chamber.zip(soak),
        json: a.json.clone(),
        store: RunStore::of(&a.run)?,
        phase: match a.phase {
            crate::cli::PhaseArg::AsFound => accelcal_db::Phase::AsFound,
            crate::cli::PhaseArg::AsLeft => accelcal_db::Phase::AsLeft,
        },
    })
}

/// The head `--head`, `--head-timeout-s` and the Zaber options name.
fn head_settings(spec: &HeadSpec, timeout_s: f64, zaber: ZaberAxes) -> HeadSettings {
    HeadSettings { spec: spec.clone(), timeout: Duration::from_secs_f64(timeout_s), zaber }
}

/// The settled rule of `--head-tolerance-arcsec` and `--settle-s`.
fn settle(tolerance_arcsec: f64, settle_s: f64) -> Settle {
    Settle { tolerance_arcsec, wait: Duration::from_secs_f64(settle_s) }
}
