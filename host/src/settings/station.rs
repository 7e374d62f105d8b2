//! The settings of `accelcal station`: its command line (with its settings file, applied by
//! `settings::station_config`) checked and resolved into plain values before any node is touched.

use std::path::{Path, PathBuf};

use super::values::Issuer;
use crate::cli::StationArgs;
use crate::cmd::store::{named_db, DEFAULT_DB};

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
    /// `--plan`, `--samples`, `--rate-hz` of the acquisition.
    pub plan: String,
    pub samples: usize,
    pub rate_hz: Option<u32>,
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
pub fn station(a: &StationArgs) -> Station {
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
        samples: a.samples,
        rate_hz: a.rate_hz,
        verify_samples: a.verify_samples.unwrap_or(a.samples),
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
