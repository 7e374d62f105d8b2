//! The settings of `accelcal station`: its command line (with its settings file, applied by
//! `settings::station_config`) checked and resolved into plain values before any node is touched.

use std::path::{Path, PathBuf};

use accelcal_core::error::bad;
use accelcal_core::sim::plan::{PlanHeader, RATE_KEY, SAMPLES_KEY};

use super::values::Issuer;
use super::Given;
use crate::cli::{Command, Range, StationArgs};
use crate::cmd::store::{named_db, DEFAULT_DB};
use crate::resolved::PlanDwell;

/// One node on the head: its link, its unit's serial, its directory, its flash route.
#[derive(Clone, Debug, PartialEq)]
pub struct StationUnit {
    pub port: String,
    pub serial: String,
    pub dir: PathBuf,
    /// `--gdb` (a GDB server) or `--probe` (a debug probe) for this node, when given.
    pub gdb: Option<String>,
    pub probe: Option<String>,
}

/// `accelcal station`, settled.
pub struct Station {
    /// The nodes on the head, in the order of `--port` (with `--check-standard`, each unit is the
    /// check standard).
    pub units: Vec<StationUnit>,
    /// `--check-standard SERIAL`: a check of the station, not a calibration.
    pub check_standard: Option<String>,
    /// The nodes' link: baud rate and how long a request waits for its answer, s.
    pub baud: u32,
    pub timeout_s: f64,
    /// The head, how long a driven head's move may take (s), the read-back tolerance (arcsec)
    /// and the wait after a move (s) when given.
    pub head: accelcal_line::head::HeadSpec,
    pub head_timeout_s: f64,
    pub head_tolerance_arcsec: Option<f64>,
    pub settle_s: Option<f64>,
    /// A Zaber head's axes and scale, as given (passed on to the steps).
    pub zaber: crate::cli::ZaberArgs,
    /// `--plan`, `--samples`, `--rate-hz` of the acquisition (the samples and rate the plan
    /// file's header states, when it does).
    pub plan: String,
    pub samples: usize,
    pub rate_hz: Option<u32>,
    /// The dwell the plan file's header states, which `samples` and `rate_hz` took.
    pub plan_dwell: Option<PlanDwell>,
    /// `--verify-samples`, else `--samples`: sets per position of each verification.
    pub verify_samples: usize,
    /// `--criterion`: the selection's external criterion.
    pub criterion: crate::cli::CriterionArg,
    /// `--select-tolerance`, codes.
    pub select_tolerance: f64,
    /// What the verifications are judged against: `--spec`, else the scatter at `--coverage`.
    pub coverage: Option<f64>,
    pub spec: Option<PathBuf>,
    /// `--as-found-fit`: the unit's last fit, for the as-found verification.
    pub as_found_fit: Option<PathBuf>,
    /// `--chip`: the MCU a probe writes.
    pub chip: String,
    /// The database: `--db`, else `ACCELCAL_DB`, else `calibration.sqlite` beside the first
    /// unit's directory.
    pub db: String,
    /// `--anchor-log`: where every chain head the run writes is appended.
    pub anchor_log: Option<PathBuf>,
    /// `--head-asset`: the head in the register.
    pub head_asset: Option<String>,
    /// `--thermometer-asset`: the environment's registered thermometer (with `--ambient-c`).
    pub thermometer_asset: Option<String>,
    /// The unit type's temperature coefficients (all or none).
    pub tempco: Option<accelcal_core::uncertainty::TempCoefficients>,
    /// `--station` (`None`: the host name), `--operator` (`None`: the user's name).
    pub station_name: Option<String>,
    pub operator: Option<String>,
    /// `--relabel`: the reason a serial moves to another device.
    pub relabel: Option<String>,
    /// The certificate's issuer.
    pub issuer: Issuer,
}

/// `station`'s settings (the command line checked by `settings::check`, the settings file
/// applied before, so that every option here is given or defaulted).
pub fn station(a: &StationArgs, plan: Option<&PlanDwell>) -> Station {
    let units = (0..a.ports.len())
        .map(|i| StationUnit {
            port: a.ports[i].clone(),
            serial: a.check_standard.clone().unwrap_or_else(|| a.serials[i].clone()),
            dir: a.outs[i].clone(),
            gdb: a.gdb.get(i).cloned(),
            probe: a.probe.get(i).cloned(),
        })
        .collect();
    Station {
        units,
        check_standard: a.check_standard.clone(),
        baud: a.baud,
        timeout_s: a.timeout_s,
        head: a.head().parse().expect("settings::check parsed the station's head"),
        head_timeout_s: a.head_timeout_s,
        head_tolerance_arcsec: a.head_tolerance_arcsec,
        settle_s: a.settle_s,
        zaber: a.zaber.clone(),
        plan: a.plan.clone(),
        samples: plan.and_then(|p| p.samples).unwrap_or(a.samples),
        rate_hz: plan.and_then(|p| p.rate_hz).or(a.rate_hz),
        // The campaign's dwell, not the plan's: a long designed dwell does not lengthen the
        // verifications.
        verify_samples: a.verify_samples.unwrap_or(a.samples),
        plan_dwell: plan.cloned(),
        criterion: a.criterion,
        select_tolerance: a.select_tolerance,
        coverage: a.coverage,
        spec: a.spec.clone(),
        as_found_fit: a.as_found_fit.clone(),
        chip: a.chip.clone(),
        db: db_spec(a),
        anchor_log: a.anchor_log.clone(),
        head_asset: a.head_asset.clone(),
        thermometer_asset: a.thermometer_asset.clone(),
        tempco: a.tempco.coefficients(),
        station_name: a.station_name.clone(),
        operator: a.operator.clone(),
        relabel: a.relabel.clone(),
        issuer: Issuer::of(&a.issuer),
    }
}

/// `station --plan FILE`: the dwell the plan file's header states (`plan --design` writes
/// `# samples:` and `# rate_hz:`), which the station takes. A `--samples` or `--rate-hz` (or
/// their keys in the settings file) that contradicts it is refused, naming both values; one
/// equal to it is fine. `None` for a built-in plan, a command other than `station`, or a file
/// that is not there (the acquisition names it).
pub fn plan_dwell(command: &Command, given: &Given) -> anyhow::Result<Option<PlanDwell>> {
    let Command::Station(a) = command else { return Ok(None) };
    let builtin = matches!(a.plan.as_str(), "head" | "six" | "tumble24") || a.plan.starts_with("random:");
    let path = Path::new(&a.plan);
    if builtin || !path.is_file() {
        return Ok(None);
    }
    let header = PlanHeader::read(path).map_err(|e| bad(format!("{}: {e}", given.name("plan"))))?;
    let plan = path.display();
    let samples = match header.samples {
        Some(n) => {
            Range::Sets
                .count(n)
                .map_err(|m| bad(format!("the plan {plan}'s `# {SAMPLES_KEY}: {n}` {m} for the station")))?;
            if given.has("samples") && a.samples != n {
                return Err(contradicts(given.name("samples"), a.samples, &plan, SAMPLES_KEY, n));
            }
            Some(n)
        }
        None => None,
    };
    let rate_hz = match header.rate_hz {
        Some(r) => {
            let hz = Some(r)
                .filter(|r| r.fract() == 0.0 && *r <= f64::from(u32::MAX))
                .map(|r| r as u32)
                .ok_or_else(|| ": not a whole number of Hz".to_string())
                .and_then(crate::cli::range::rate_hz)
                .map_err(|m| {
                    bad(format!("the plan {plan}'s `# {RATE_KEY}: {r}` is not a rate the node takes{m}"))
                })?;
            if given.has("rate_hz") && a.rate_hz != Some(hz) {
                let station = a.rate_hz.map_or_else(String::new, |v| v.to_string());
                return Err(contradicts(given.name("rate_hz"), station, &plan, RATE_KEY, hz));
            }
            Some(hz)
        }
        None => None,
    };
    Ok(Some(PlanDwell { path: path.to_path_buf(), samples, rate_hz }))
}

/// The refusal of a station setting (`name`, given as `value`) that contradicts its plan file's
/// header line `# key: file`.
fn contradicts(
    name: String,
    value: impl std::fmt::Display,
    plan: &impl std::fmt::Display,
    key: &str,
    file: impl std::fmt::Display,
) -> anyhow::Error {
    bad(format!(
        "{name} {value} contradicts the plan {plan} (designed with `# {key}: {file}`): give {file}, or leave it out and the station takes the plan's"
    ))
}

/// The station's database: `--db`, else `ACCELCAL_DB`, else `calibration.sqlite` beside the
/// unit's directory (every unit of a line in one file).
fn db_spec(a: &StationArgs) -> String {
    if let Some(s) = named_db(a.db.as_deref()) {
        return s;
    }
    let first = a.outs.first().map(PathBuf::as_path).unwrap_or(Path::new("."));
    match first.parent().filter(|p| !p.as_os_str().is_empty()) {
        Some(parent) => parent.join(DEFAULT_DB).display().to_string(),
        None => DEFAULT_DB.into(),
    }
}
