//! A gravity survey read from the register: `--gravity-asset ID` (`fit`, `verify`, `station`, and
//! the settings file's `gravity_asset`) becomes the survey's g and its standard uncertainty, with
//! the survey named ([`GSource::Survey`]), once the command has its database open. The run then
//! stores which survey and certificate it used, as it does its head
//! ([`accelcal_db::Db::store_run_asset`]), so that `affected` finds it.

use accelcal_core::campaign::GSource;
use accelcal_core::error::bad;
use accelcal_db::{Asset, AssetKind, Db};

use crate::resolved::{Gravity, Source};

/// The gravity `g` resolves to: a survey read from `db` when it names a gravity asset (its
/// certificate in force, refused when overdue, unknown, tampered or not a gravity survey), with
/// the asset read; any other gravity as it is.
pub fn resolve(g: &Gravity, db: Option<&mut Db>) -> anyhow::Result<(Gravity, Option<Asset>)> {
    let Source::Asset { id } = &g.source else {
        return Ok((g.clone(), None));
    };
    let Some(db) = db else {
        return Err(bad("--gravity-asset needs --db: the survey is read from the database's register"));
    };
    let asset = db.asset_in_force(id, AssetKind::Gravity, accelcal_db::asset::today_utc())?;
    Ok((of_survey(&asset)?, Some(asset)))
}

/// The gravity a registered survey states.
pub fn of_survey(asset: &Asset) -> anyhow::Result<Gravity> {
    let Some((value, u)) = asset.value.and_then(|v| Some((v.value?, v.u))) else {
        return Err(bad(format!(
            "gravity asset {} certificate {} states no value of g (registered before schema 11): register its \
             certificate again with --value and --u",
            asset.asset_id, asset.certificate
        )));
    };
    Ok(Gravity {
        g: value,
        source: Source::Stated(GSource::Survey {
            asset: asset.asset_id.clone(),
            certificate: asset.certificate.clone(),
            u_m_s2: u,
        }),
    })
}
