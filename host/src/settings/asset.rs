//! The settings of `asset add|list|show|found-bad` and `affected`: the register of the line's
//! reference equipment and its recalls, the command line checked and resolved into plain values
//! before anything is opened.

use std::path::{Path, PathBuf};

use accelcal_core::error::bad;
use accelcal_db::asset::{Date, StatedValue};
use accelcal_db::{AssetKind, Target};

use crate::cli::{AffectedArgs, AssetCommand, AssetDb};
use crate::cmd::store::{named_db, DEFAULT_DB};

/// `accelcal asset …`, settled.
#[derive(Clone, Debug, PartialEq)]
pub enum Asset {
    /// `asset add`.
    Add(Add),
    /// `asset list`.
    List(Listing),
    /// `asset show ID`.
    Show(Show),
    /// `asset found-bad ID`.
    FoundBad(FoundBad),
}

/// `asset found-bad`: a finding to record.
#[derive(Clone, Debug, PartialEq)]
pub struct FoundBad {
    /// `--db` as given (`None`: `ACCELCAL_DB`, else the station's file here; it must exist).
    pub db: Option<String>,
    /// The asset.
    pub id: String,
    /// `--certificate`, trimmed.
    pub certificate: String,
    /// `--since`: not after today.
    pub since: Date,
    /// `--reason`, trimmed, not empty.
    pub reason: String,
    /// `--operator` (`None`: the user's name).
    pub operator: Option<String>,
    /// `--anchor-log`.
    pub anchor_log: Option<PathBuf>,
}

/// `asset add`: an asset's certificate to register.
#[derive(Clone, Debug, PartialEq)]
pub struct Add {
    /// `--db` as given (`None`: `ACCELCAL_DB`, else the station's file here, created if missing).
    pub db: Option<String>,
    /// The asset's id.
    pub id: String,
    /// What it is.
    pub kind: AssetKind,
    /// Its certificate's number, trimmed.
    pub certificate: String,
    /// The certificate's due date.
    pub due: Date,
    /// A head's stated uncertainties, arcsec (one sigma): given for a head, 0 for the others.
    pub angle_u_arcsec: f64,
    pub orthogonality_u_arcsec: f64,
    /// A gravity survey's g and its standard uncertainty, m/s² (`--value`, `--u`).
    pub value: Option<StatedValue>,
    /// `--operator` (`None`: the user's name).
    pub operator: Option<String>,
    /// `--anchor-log`.
    pub anchor_log: Option<std::path::PathBuf>,
}

/// `asset list`.
#[derive(Clone, Debug, PartialEq)]
pub struct Listing {
    /// `--db` as given.
    pub db: Option<String>,
    /// `--json`: not the database.
    pub json: Option<PathBuf>,
}

/// `asset show ID`.
#[derive(Clone, Debug, PartialEq)]
pub struct Show {
    /// `--db` as given.
    pub db: Option<String>,
    /// The asset.
    pub id: String,
    /// `--json`: not the database.
    pub json: Option<PathBuf>,
}

/// `accelcal affected`, settled.
#[derive(Clone, Debug, PartialEq)]
pub struct Affected {
    /// `--db` as given.
    pub db: Option<String>,
    /// The asset.
    pub asset: String,
    /// `--certificate`: only the runs under this certificate of the asset.
    pub certificate: Option<String>,
    /// What to do.
    pub action: AffectedAction,
}

/// What `affected` does.
#[derive(Clone, Debug, PartialEq)]
pub enum AffectedAction {
    /// List the runs.
    List {
        /// `--since`: every run from this day on (UTC); `None`: the runs the asset's findings
        /// affect.
        since: Option<Date>,
        /// `--json`: not the database.
        json: Option<PathBuf>,
        /// `--csv`: not the database, nor `--json`.
        csv: Option<PathBuf>,
    },
    /// `--dismiss SERIAL --reason TEXT`: record that the unit needs no recall.
    Dismiss {
        /// The unit: a serial or a device id.
        unit: String,
        /// `--reason`, trimmed, not empty.
        reason: String,
        /// `--operator` (`None`: the user's name).
        operator: Option<String>,
        /// `--anchor-log`.
        anchor_log: Option<PathBuf>,
    },
}

/// An asset command's settings from its command line.
pub fn asset(c: &AssetCommand) -> anyhow::Result<Asset> {
    Ok(match c {
        AssetCommand::Add(a) => {
            let kind = AssetKind::from(a.kind);
            let stated = [(a.angle_u, "--angle-u"), (a.orthogonality_u, "--orthogonality-u")];
            if kind == AssetKind::Head {
                if let Some((_, option)) = stated.iter().find(|(v, _)| v.is_none()) {
                    return Err(bad(format!(
                        "asset add --kind head needs {option} ARCSEC: the head's certificate states it, and the \
                         uncertainty budget of every unit calibrated on the head takes it (give 0 if the \
                         certificate states it as negligible)"
                    )));
                }
            } else if let Some((_, option)) = stated.iter().find(|(v, _)| v.is_some()) {
                return Err(bad(format!(
                    "{option} does not apply to asset add --kind {} (a dividing head states it)",
                    kind.name()
                )));
            }
            let value = match (kind, a.value, a.u) {
                (AssetKind::Gravity, Some(value), Some(u)) => Some(StatedValue { value: Some(value), u }),
                (AssetKind::Thermometer, None, Some(u)) => Some(StatedValue { value: None, u }),
                (AssetKind::Gravity, v, _) => {
                    return Err(bad(format!(
                        "asset add --kind gravity needs {} M_S2: the survey's certificate states g and its standard \
                         uncertainty, which every fit at the site takes",
                        if v.is_none() { "--value" } else { "--u" }
                    )))
                }
                (_, None, None) => None,
                (kind, v, _) => {
                    return Err(bad(format!(
                        "{} does not apply to asset add --kind {} (a gravity survey states it; a thermometer states --u)",
                        if v.is_some() { "--value" } else { "--u" },
                        kind.name()
                    )))
                }
            };
            Asset::Add(Add {
                value,
                db: a.store.db.clone(),
                id: a.id.clone(),
                kind,
                certificate: a.certificate.trim().to_string(),
                due: a.due,
                angle_u_arcsec: a.angle_u.unwrap_or(0.0),
                orthogonality_u_arcsec: a.orthogonality_u.unwrap_or(0.0),
                operator: a.operator.clone(),
                anchor_log: a.anchor_log.clone(),
            })
        }
        AssetCommand::List(a) => {
            json_is_not_the_db(&a.store, a.json.as_deref())?;
            Asset::List(Listing { db: a.store.db.clone(), json: a.json.clone() })
        }
        AssetCommand::Show(a) => {
            json_is_not_the_db(&a.store, a.json.as_deref())?;
            Asset::Show(Show { db: a.store.db.clone(), id: a.id.clone(), json: a.json.clone() })
        }
        AssetCommand::FoundBad(a) => {
            let today = accelcal_db::asset::today_utc();
            if a.since > today {
                return Err(bad(format!(
                    "--since {} is after today ({today}, UTC): a finding covers runs already made (the first day \
                     whose runs are in doubt)",
                    a.since
                )));
            }
            let reason = a.reason.trim();
            if reason.is_empty() {
                return Err(bad(
                    "--reason is empty: say what the asset's recalibration found (it is stored with the finding)",
                ));
            }
            let certificate = a.certificate.trim();
            if certificate.is_empty() {
                return Err(bad("--certificate is empty: give the asset's certificate it was used under"));
            }
            if let Some(spec) = named_db(a.store.db.as_deref()) {
                super::values::existing_db(&spec, "asset found-bad")?;
            }
            Asset::FoundBad(FoundBad {
                db: a.store.db.clone(),
                id: a.id.clone(),
                certificate: certificate.to_string(),
                since: a.since,
                reason: reason.to_string(),
                operator: a.operator.clone(),
                anchor_log: a.anchor_log.clone(),
            })
        }
    })
}

/// `affected`'s settings from its command line.
pub fn affected(a: &AffectedArgs) -> anyhow::Result<Affected> {
    let certificate = a.certificate.as_deref().map(|c| c.trim().to_string());
    let action = match &a.dismiss {
        None => {
            for (given, option) in [
                (a.reason.is_some(), "--reason"),
                (a.operator.is_some(), "--operator"),
                (a.anchor_log.is_some(), "--anchor-log"),
            ] {
                if given {
                    return Err(bad(format!(
                        "{option} does not apply to affected without --dismiss (it lists, it stores nothing)"
                    )));
                }
            }
            json_is_not_the_db(&a.store, a.json.as_deref())?;
            json_is_not_the_db(&a.store, a.csv.as_deref())?;
            if let (Some(j), Some(c)) = (&a.json, &a.csv) {
                if j == c {
                    return Err(bad(format!("--json and --csv are both {}: give two files", j.display())));
                }
            }
            AffectedAction::List { since: a.since, json: a.json.clone(), csv: a.csv.clone() }
        }
        Some(unit) => {
            for (given, option) in
                [(a.since.is_some(), "--since"), (a.json.is_some(), "--json"), (a.csv.is_some(), "--csv")]
            {
                if given {
                    return Err(bad(format!(
                        "{option} does not apply to affected --dismiss (it stores the dismissal, it lists nothing)"
                    )));
                }
            }
            let reason = a.reason.as_deref().map(str::trim).unwrap_or_default();
            if a.reason.is_none() {
                return Err(bad("affected --dismiss needs --reason TEXT: why the unit needs no recall"));
            }
            if reason.is_empty() {
                return Err(bad(
                    "--reason is empty: say why the unit needs no recall (it is stored with it)",
                ));
            }
            if unit.trim().is_empty() {
                return Err(bad("--dismiss is empty: give the unit's serial (or its device id)"));
            }
            if let Some(spec) = named_db(a.store.db.as_deref()) {
                super::values::existing_db(&spec, "affected --dismiss")?;
            }
            AffectedAction::Dismiss {
                unit: unit.trim().to_string(),
                reason: reason.to_string(),
                operator: a.operator.clone(),
                anchor_log: a.anchor_log.clone(),
            }
        }
    };
    Ok(Affected { db: a.store.db.clone(), asset: a.asset.clone(), certificate, action })
}

fn json_is_not_the_db(store: &AssetDb, json: Option<&Path>) -> anyhow::Result<()> {
    let Some(j) = json else { return Ok(()) };
    let spec = named_db(store.db.as_deref()).unwrap_or_else(|| DEFAULT_DB.into());
    if let Target::Sqlite(f) = Target::parse(&spec)? {
        if j == f {
            return Err(bad(format!("--json {} is the database: refusing to overwrite it", j.display())));
        }
    }
    Ok(())
}
