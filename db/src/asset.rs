//! The line's registered reference equipment: the dividing head, a thermometer, the gravity value
//! (ISO/IEC 17025 §6.4–6.5). Each asset is registered once per calibration certificate of its
//! own, with the certificate's due date and, for a head, the uncertainties the budget takes from
//! it; the certificate registered last is the one in force. A run stores which asset (and which
//! of its certificates) it used, one per kind, so that an asset found out of tolerance at its own
//! recalibration names every run and unit it calibrated since a date ([`crate::recall`]).
//!
//! Dates are calendar days in UTC (`YYYY-MM-DD`); an asset may be used on its due date, not after.

/// A calendar day (the register's dates).
pub use jiff::civil::Date;
use serde::Serialize;

use super::content::{asset_content, run_asset_content};
use super::engine::{Tx, Val};
use super::piece::insert_row;
use super::{chain, sha256_hex, Db, DbError, RunId, Stored};
use accelcal_core::error::{Classify, Kind};

/// What an asset is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum AssetKind {
    /// A dividing head: its angle setting error and axis non-orthogonality enter the budget.
    Head,
    /// A thermometer (the chamber's, the node's reference).
    Thermometer,
    /// A gravity value (a survey of the site).
    Gravity,
}

impl AssetKind {
    /// The kind as stored and as the command line spells it.
    pub fn name(self) -> &'static str {
        match self {
            AssetKind::Head => "head",
            AssetKind::Thermometer => "thermometer",
            AssetKind::Gravity => "gravity",
        }
    }

    /// The kind as a message names one: `head`, `thermometer`, `gravity survey`.
    pub fn noun(self) -> &'static str {
        match self {
            AssetKind::Gravity => "gravity survey",
            k => k.name(),
        }
    }

    pub(crate) fn from_sql(s: &str) -> Result<AssetKind, DbError> {
        match s {
            "head" => Ok(AssetKind::Head),
            "thermometer" => Ok(AssetKind::Thermometer),
            "gravity" => Ok(AssetKind::Gravity),
            other => Err(DbError::schema(format!("an asset of kind `{other}`"))),
        }
    }
}

/// One certificate of a registered asset.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Asset {
    /// The asset's id (letters, digits, `.`, `_`, `-`), as the line names it (`--head-asset`).
    pub asset_id: String,
    /// What it is.
    pub kind: AssetKind,
    /// The number of the asset's own calibration certificate.
    pub certificate: String,
    /// The last day (UTC) the asset may be used under this certificate.
    pub due_date: Date,
    /// A head: the one-sigma setting error of each head angle, arcseconds (0 for other kinds).
    pub angle_u_arcsec: f64,
    /// A head: the one-sigma of each of the three rotations of its axes, arcseconds (0 for
    /// other kinds).
    pub orthogonality_u_arcsec: f64,
    /// Who registered it.
    pub operator: String,
    /// When, seconds since the Unix epoch.
    pub registered_unix_s: i64,
    /// What its certificate states besides a head's uncertainties, in SI units: a gravity
    /// survey's g and its standard uncertainty (m/s²), a thermometer's standard uncertainty of a
    /// reading (K, no value); `None` for a head, or a thermometer registered without one.
    pub value: Option<StatedValue>,
}

/// What an asset's certificate states: a value (a gravity survey's g) and a standard uncertainty
/// (of that value, or of a thermometer's readings), in SI units.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct StatedValue {
    /// The value (a gravity survey's g); `None` for a thermometer.
    pub value: Option<f64>,
    /// The standard uncertainty (one sigma).
    pub u: f64,
}

/// An asset the line cannot use, or cannot register.
#[derive(Debug, thiserror::Error)]
pub enum AssetError {
    /// Not registered.
    #[error("asset `{asset_id}` is not registered in {target} (register it with `accelcal asset add`)")]
    Unknown {
        /// The asset asked for.
        asset_id: String,
        /// The database.
        target: String,
    },
    /// Its certificate in force is past its due date.
    #[error(
        "asset `{asset_id}` is overdue: its certificate {certificate} was due {due_date} (today is {today}, UTC); \
         recalibrate it and register its new certificate with `accelcal asset add`"
    )]
    Overdue {
        /// The asset.
        asset_id: String,
        /// Its certificate in force.
        certificate: String,
        /// Its due date.
        due_date: Date,
        /// Today.
        today: Date,
    },
    /// Registered as another kind.
    #[error("asset `{asset_id}` is a {is}, not a {wanted}")]
    WrongKind {
        /// The asset.
        asset_id: String,
        /// Its kind.
        is: &'static str,
        /// The kind the command needs.
        wanted: &'static str,
    },
    /// A field the register refuses.
    #[error("asset `{asset_id}`: {why}")]
    Bad {
        /// The asset.
        asset_id: String,
        /// What is wrong.
        why: String,
    },
}

impl Classify for AssetError {
    fn kind(&self) -> Kind {
        match self {
            // The line's equipment is not fit for use: the environment, not the input (a
            // station's exit code 3).
            AssetError::Unknown { .. } | AssetError::Overdue { .. } | AssetError::WrongKind { .. } => {
                Kind::Environment
            }
            AssetError::Bad { .. } => Kind::BadInput,
        }
    }
}

/// A `YYYY-MM-DD` date (exactly that form: what the register stores).
pub fn parse_date(s: &str) -> Result<Date, String> {
    let d: Date = s.trim().parse().map_err(|e| format!("`{s}` is not a date YYYY-MM-DD: {e}"))?;
    if d.to_string() != s.trim() {
        return Err(format!("`{s}` is not a date YYYY-MM-DD"));
    }
    Ok(d)
}

/// Today, UTC.
pub fn today_utc() -> Date {
    jiff::Timestamp::now().to_zoned(jiff::tz::TimeZone::UTC).date()
}

/// The first second (UTC) of `d`, since the Unix epoch.
pub fn start_of_day_unix_s(d: Date) -> i64 {
    d.to_zoned(jiff::tz::TimeZone::UTC).map(|z| z.timestamp().as_second()).unwrap_or(i64::MIN)
}

const ASSET_COLUMNS: &str = "asset_id, certificate, kind, due_date, angle_u_arcsec, orthogonality_u_arcsec, \
                             operator, registered_unix_s, value_si, value_u_si";

fn asset_of(r: &[Val]) -> Result<Asset, DbError> {
    Ok(Asset {
        asset_id: r[0].text()?,
        certificate: r[1].text()?,
        kind: AssetKind::from_sql(&r[2].text()?)?,
        due_date: parse_date(&r[3].text()?).map_err(DbError::schema)?,
        angle_u_arcsec: r[4].real()?,
        orthogonality_u_arcsec: r[5].real()?,
        operator: r[6].text()?,
        registered_unix_s: r[7].int()?,
        value: match (&r[8], &r[9]) {
            (Val::Null, Val::Null) => None,
            (Val::Null, u) => Some(StatedValue { value: None, u: u.real()? }),
            (v, u) => Some(StatedValue { value: Some(v.real()?), u: u.real()? }),
        },
    })
}

/// The row `add_asset` inserts: the columns of `chain::table("asset")` in their order, its hash
/// (index 8) NULL until [`asset_content`] of the row gives it.
fn asset_row(a: &Asset) -> Vec<Val> {
    let (value, u) = match a.value {
        Some(v) => (v.value.map_or(Val::Null, Val::from), v.u.into()),
        None => (Val::Null, Val::Null),
    };
    vec![
        a.asset_id.clone().into(),
        a.certificate.clone().into(),
        a.kind.name().into(),
        a.due_date.to_string().into(),
        a.angle_u_arcsec.into(),
        a.orthogonality_u_arcsec.into(),
        a.operator.clone().into(),
        a.registered_unix_s.into(),
        Val::Null,
        value,
        u,
    ]
}

/// Every certificate of asset `id`, oldest first.
fn certificates(tx: &mut Tx<'_>, id: &str) -> Result<Vec<Asset>, DbError> {
    tx.query(
        &format!(
            "SELECT {ASSET_COLUMNS} FROM asset WHERE asset_id = $1 ORDER BY registered_unix_s, certificate"
        ),
        &[id.to_string().into()],
    )?
    .iter()
    .map(|r| asset_of(r))
    .collect()
}

/// [`DbError::AssetTampered`] for asset `id` when its rows' check found `bad` ones, naming the
/// first; nothing when it found none.
pub(crate) fn untampered(id: &str, mut bad: Vec<chain::Mismatch>) -> Result<(), DbError> {
    if bad.is_empty() {
        return Ok(());
    }
    let first = bad.remove(0);
    Err(DbError::AssetTampered { asset_id: id.into(), first: Box::new(first), more: bad.len() })
}

/// Checks what `asset add` registers.
fn check(a: &Asset) -> Result<(), AssetError> {
    let bad = |why: String| AssetError::Bad { asset_id: a.asset_id.clone(), why };
    if a.asset_id.is_empty()
        || a.asset_id.len() > 64
        || !a.asset_id.bytes().all(|b| b.is_ascii_alphanumeric() || b"._-".contains(&b))
    {
        return Err(bad("an asset id is 1 to 64 letters, digits, `.`, `_` or `-`".into()));
    }
    for (field, v) in [("certificate", &a.certificate), ("operator", &a.operator)] {
        accelcal_core::text::single_line(field, v).map_err(|e| bad(e.to_string()))?;
        if v.trim().is_empty() {
            return Err(bad(format!("its {field} is empty")));
        }
    }
    let stated = [("angle", a.angle_u_arcsec), ("orthogonality", a.orthogonality_u_arcsec)];
    for (what, u) in stated {
        if !(0.0..=3600.0).contains(&u) {
            return Err(bad(format!("its {what} uncertainty {u} arcsec is not between 0 and 3600")));
        }
        if a.kind != AssetKind::Head && u != 0.0 {
            return Err(bad(format!("a {} states no {what} uncertainty (a head does)", a.kind.name())));
        }
    }
    match (a.kind, a.value) {
        (AssetKind::Gravity, None | Some(StatedValue { value: None, .. })) => Err(bad(
            "a gravity survey states the value of g and its standard uncertainty (--value, --u)".into(),
        )),
        (AssetKind::Gravity, Some(StatedValue { value: Some(value), u })) => {
            if !(value.is_finite() && (9.7..=9.9).contains(&value)) {
                return Err(bad(format!("its g {value} m/s² is not between 9.7 and 9.9 m/s²")));
            }
            if !(u.is_finite() && u > 0.0 && u < 0.01) {
                return Err(bad(format!("its standard uncertainty {u} m/s² is not in (0, 0.01) m/s²")));
            }
            Ok(())
        }
        (AssetKind::Thermometer, Some(StatedValue { value: None, u })) => {
            if !(u.is_finite() && u > 0.0 && u <= 10.0) {
                return Err(bad(format!("its standard uncertainty {u} K is not in (0, 10] K")));
            }
            Ok(())
        }
        (kind, Some(_)) => Err(bad(format!("a {} states no such value", kind.name()))),
        (_, None) => Ok(()),
    }
}

impl Db {
    /// Registers a certificate of an asset (a new asset, or one recalibrated). The same
    /// certificate registered again with the same statements is a no-op; with other statements,
    /// refused (a certificate is registered once); an asset keeps its kind.
    pub fn add_asset(&mut self, a: &Asset) -> Result<Stored, DbError> {
        check(a).map_err(DbError::Asset)?;
        let mut row = asset_row(a);
        let sha = sha256_hex(asset_content(&row)?.as_bytes());
        row[8] = sha.clone().into();
        self.retried(|conn| {
            conn.transaction(|tx| {
                let known = certificates(tx, &a.asset_id)?;
                if let Some(other) = known.iter().find(|k| k.kind != a.kind) {
                    return Err(DbError::Asset(AssetError::Bad {
                        asset_id: a.asset_id.clone(),
                        why: format!("it is registered as a {}, not a {}", other.kind.name(), a.kind.name()),
                    }));
                }
                if let Some(same) = known.iter().find(|k| k.certificate == a.certificate) {
                    let same_row = asset_row(same);
                    return if sha256_hex(asset_content(&same_row)?.as_bytes()) == sha {
                        Ok(Stored::Already)
                    } else {
                        Err(DbError::Asset(AssetError::Bad {
                            asset_id: a.asset_id.clone(),
                            why: format!(
                                "its certificate {} is registered already with other statements (a certificate is \
                                 registered once; a recalibration has a new certificate number)",
                                a.certificate
                            ),
                        }))
                    };
                }
                insert_row(tx, chain::table("asset"), &row)?;
                Ok(Stored::New)
            })
        })
    }

    /// Every asset's certificate in force (its latest), by id.
    pub fn assets(&mut self) -> Result<Vec<Asset>, DbError> {
        let all: Vec<Asset> = self.conn.transaction(|tx| {
            tx.query(
                &format!(
                    "SELECT {ASSET_COLUMNS} FROM asset ORDER BY asset_id, registered_unix_s, certificate"
                ),
                &[],
            )?
            .iter()
            .map(|r| asset_of(r))
            .collect()
        })?;
        let mut latest: Vec<Asset> = Vec::new();
        for a in all {
            match latest.last_mut() {
                Some(l) if l.asset_id == a.asset_id => *l = a,
                _ => latest.push(a),
            }
        }
        Ok(latest)
    }

    /// Whether asset `id`'s register rows match their hash chain: `None`, else the first row that
    /// does not, in words (a reader lists such an asset as tampered, never as in force).
    pub fn asset_tampered(&mut self, id: &str) -> Result<Option<String>, DbError> {
        let bad = self.conn.reading(|tx| chain::verify_asset(tx, id))?;
        Ok(bad.first().map(|m| format!("its register rows do not match their hash chain: {m}")))
    }

    /// Every certificate of asset `id`, oldest first ([`AssetError::Unknown`] when it has none).
    /// Its register rows are checked against their hash chain first
    /// ([`DbError::AssetTampered`]): a forged certificate, due date or uncertainty is never used.
    pub fn asset_certificates(&mut self, id: &str) -> Result<Vec<Asset>, DbError> {
        let (all, bad) = self.conn.reading(|tx| Ok((certificates(tx, id)?, chain::verify_asset(tx, id)?)))?;
        untampered(id, bad)?;
        if all.is_empty() {
            return Err(DbError::Asset(AssetError::Unknown { asset_id: id.into(), target: self.target() }));
        }
        Ok(all)
    }

    /// Asset `id`'s certificate in force, when the asset is a `kind` and not overdue on `today`.
    pub fn asset_in_force(&mut self, id: &str, kind: AssetKind, today: Date) -> Result<Asset, DbError> {
        let a = self.asset_certificates(id)?.pop().expect("an asset with a certificate");
        if a.kind != kind {
            return Err(DbError::Asset(AssetError::WrongKind {
                asset_id: id.into(),
                is: a.kind.noun(),
                wanted: kind.noun(),
            }));
        }
        if today > a.due_date {
            return Err(DbError::Asset(AssetError::Overdue {
                asset_id: id.into(),
                certificate: a.certificate,
                due_date: a.due_date,
                today,
            }));
        }
        Ok(a)
    }

    /// Stores that run `run` used `a` (under the certificate `a` names): one asset of each kind
    /// per run, the same one again a no-op, another refused.
    pub fn store_run_asset(&mut self, run: RunId, a: &Asset) -> Result<Stored, DbError> {
        let kind = a.kind.name();
        let sha = sha256_hex(run_asset_content(kind, &a.asset_id, &a.certificate).as_bytes());
        self.store(
            run,
            super::Piece {
                table: "run_asset",
                what: "head asset",
                second: Some(("kind", kind)),
                values: vec![
                    a.asset_id.clone().into(),
                    a.certificate.clone().into(),
                    super::now_unix_s().into(),
                ],
                sha,
            },
        )
    }

    /// The assets run `run` used: kind, asset id, certificate.
    pub fn run_assets(&mut self, run: RunId) -> Result<Vec<(AssetKind, String, String)>, DbError> {
        let rows = self.conn.transaction(|tx| {
            tx.query(
                "SELECT kind, asset_id, certificate FROM run_asset WHERE run_id = $1 ORDER BY kind",
                &[run.to_string().into()],
            )
        })?;
        rows.iter().map(|r| Ok((AssetKind::from_sql(&r[0].text()?)?, r[1].text()?, r[2].text()?))).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dates_are_read_in_one_form_only() {
        assert_eq!(parse_date("2027-06-30").unwrap().to_string(), "2027-06-30");
        for bad in ["2027-6-30", "20270630", "2027-02-30", "30.06.2027", "", "2027-06-30T00:00"] {
            assert!(parse_date(bad).is_err(), "{bad}");
        }
        assert_eq!(start_of_day_unix_s(parse_date("1970-01-02").unwrap()), 86_400);
    }
}
