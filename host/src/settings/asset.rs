//! The settings of `asset add|list|show` and `affected`: the register of the line's reference
//! equipment, its command line checked and resolved into plain values before anything is opened.

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
    /// `--since`: its runs from this day on (UTC).
    pub since: Date,
    /// `--json`: not the database.
    pub json: Option<PathBuf>,
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
                (AssetKind::Gravity, Some(value), Some(u)) => Some(StatedValue { value, u }),
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
                        "{} does not apply to asset add --kind {} (a gravity survey states it)",
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
    })
}

/// `affected`'s settings from its command line.
pub fn affected(a: &AffectedArgs) -> anyhow::Result<Affected> {
    json_is_not_the_db(&a.store, a.json.as_deref())?;
    Ok(Affected { db: a.store.db.clone(), asset: a.asset.clone(), since: a.since, json: a.json.clone() })
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
