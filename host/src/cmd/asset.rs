//! `accelcal asset add|list|show` (the register of the line's reference equipment,
//! [`accelcal_db::asset`]); `asset found-bad` and `affected` are recalls (`super::recall`).

use accelcal_core::output::{utc_date_time, write_json};
use accelcal_db::asset::{today_utc, Date};
use accelcal_db::{AffectedRun, Asset, AssetKind, Db, Stored};
use anyhow::Context;
use serde::Serialize;

use super::store::{named_db, reader_spec, user_name, DEFAULT_DB};
use crate::settings::asset as settings;

/// Runs `accelcal asset …`.
pub fn run(c: &settings::Asset) -> anyhow::Result<()> {
    match c {
        settings::Asset::Add(a) => add(a),
        settings::Asset::List(a) => list(a),
        settings::Asset::Show(a) => show(a),
        settings::Asset::FoundBad(a) => super::recall::found_bad(a),
    }
}

fn add(a: &settings::Add) -> anyhow::Result<()> {
    let spec = named_db(a.db.as_deref()).unwrap_or_else(|| DEFAULT_DB.into());
    let mut db = super::store::with_anchor_log(Db::open(&spec)?, a.anchor_log.as_deref())?;
    let asset = Asset {
        asset_id: a.id.clone(),
        kind: a.kind,
        certificate: a.certificate.clone(),
        due_date: a.due,
        angle_u_arcsec: a.angle_u_arcsec,
        orthogonality_u_arcsec: a.orthogonality_u_arcsec,
        operator: a.operator.clone().unwrap_or_else(user_name),
        registered_unix_s: accelcal_db::now_unix_s(),
        value: a.value,
    };
    let stored = db.add_asset(&asset)?;
    outln!(
        "asset: {} ({}) certificate {}, due {}{}: {} in {}",
        asset.asset_id,
        asset.kind.name(),
        asset.certificate,
        asset.due_date,
        stated(&asset),
        if stored == Stored::New { "registered" } else { "was registered already" },
        db.target()
    )?;
    let in_force = db.asset_certificates(&asset.asset_id)?.pop().expect("the asset just registered");
    if in_force.certificate != asset.certificate {
        outln!(
            "asset: {}'s certificate in force is {} (registered later)",
            asset.asset_id,
            in_force.certificate
        )?;
    }
    let today = today_utc();
    if today > in_force.due_date {
        errln!(
            "warning: {} is overdue (due {}, today {today} UTC): a station refuses it until a new certificate is registered",
            asset.asset_id, in_force.due_date
        );
    }
    Ok(())
}

/// A head's stated uncertainties, for a line of output.
fn stated(a: &Asset) -> String {
    match a.kind {
        AssetKind::Head => format!(
            ", angle u {} arcsec, orthogonality u {} arcsec (one sigma)",
            a.angle_u_arcsec, a.orthogonality_u_arcsec
        ),
        AssetKind::Gravity => match a.value.and_then(|v| Some((v.value?, v.u))) {
            Some((g, u)) => format!(", g = {g} m/s², u {u:.1e} m/s² (one sigma)"),
            None => ", no value stated (registered before schema 11: register its certificate again)".into(),
        },
        AssetKind::Thermometer => match a.value {
            Some(v) => format!(", u {} K per reading (one sigma)", v.u),
            None => ", no uncertainty stated".into(),
        },
    }
}

/// Whether an asset may be used today, in words.
pub(crate) fn status(due: Date, today: Date) -> String {
    match today.until(due).map(|s| s.get_days()).unwrap_or(0) {
        d if d < 0 => format!("OVERDUE ({} days)", -d),
        0 => "due today".into(),
        d => format!("in force ({d} days left)"),
    }
}

/// `asset list --json`.
#[derive(Serialize)]
struct ListJson {
    /// Today, UTC.
    today: Date,
    assets: Vec<AssetJson>,
}

#[derive(Serialize)]
struct AssetJson {
    #[serde(flatten)]
    asset: Asset,
    overdue: bool,
    /// Why its register rows are not the ones stored, when they are not.
    #[serde(skip_serializing_if = "Option::is_none")]
    tampered: Option<String>,
}

fn list(a: &settings::Listing) -> anyhow::Result<()> {
    let mut db = Db::open_existing(&reader_spec(a.db.as_deref())?)?;
    let assets = db.assets()?;
    let today = today_utc();
    outln!("assets in {} (today {today}, UTC): {}", db.target(), assets.len())?;
    if !assets.is_empty() {
        outln!(
            "  {:<16} {:<12} {:<20} {:<11} {:<26} {:>9} {:>9}",
            "id",
            "kind",
            "certificate",
            "due",
            "status",
            "angle u\"",
            "orth. u\""
        )?;
    }
    // An asset whose register rows do not match their chain is never listed as in force.
    let mut tampered = Vec::with_capacity(assets.len());
    for x in &assets {
        tampered.push(db.asset_tampered(&x.asset_id)?);
    }
    for (x, forged) in assets.iter().zip(&tampered) {
        let head = x.kind == AssetKind::Head;
        let u = |v: f64| if head { format!("{v}") } else { "-".into() };
        let state =
            if forged.is_some() { "TAMPERED, not usable".to_string() } else { status(x.due_date, today) };
        outln!(
            "  {:<16} {:<12} {:<20} {:<11} {:<26} {:>9} {:>9}",
            x.asset_id,
            x.kind.name(),
            x.certificate,
            x.due_date.to_string(),
            state,
            u(x.angle_u_arcsec),
            u(x.orthogonality_u_arcsec)
        )?;
        if let Some(why) = forged {
            outln!("    {}: {why}", x.asset_id)?;
        }
    }
    if let Some(j) = &a.json {
        let doc = ListJson {
            today,
            assets: assets
                .into_iter()
                .zip(tampered)
                .map(|(asset, tampered)| AssetJson { overdue: today > asset.due_date, asset, tampered })
                .collect(),
        };
        write_json(j, &doc).with_context(|| format!("writing {}", j.display()))?;
        outln!("wrote {}", j.display())?;
    }
    Ok(())
}

/// `asset show --json`.
#[derive(Serialize)]
struct ShowJson {
    asset_id: String,
    today: Date,
    overdue: bool,
    /// Every certificate, oldest first; the last is in force.
    certificates: Vec<Asset>,
    /// Every run that used the asset, oldest first.
    runs: Vec<AffectedRun>,
}

fn show(a: &settings::Show) -> anyhow::Result<()> {
    let mut db = Db::open_existing(&reader_spec(a.db.as_deref())?)?;
    let certificates = db.asset_certificates(&a.id)?;
    let runs = db.affected(&a.id, i64::MIN)?;
    let today = today_utc();
    let last = certificates.last().expect("an asset has a certificate");
    outln!(
        "asset {} ({}) in {}: certificate {} in force, due {}: {}{}",
        a.id,
        last.kind.name(),
        db.target(),
        last.certificate,
        last.due_date,
        status(last.due_date, today),
        stated(last)
    )?;
    outln!("  {:<20} {:<11} {:<21} {:<12} {:>5}", "certificate", "due", "registered (UTC)", "by", "runs")?;
    for c in &certificates {
        outln!(
            "  {:<20} {:<11} {:<21} {:<12} {:>5}",
            c.certificate,
            c.due_date.to_string(),
            utc_date_time(c.registered_unix_s),
            c.operator,
            runs.iter().filter(|r| r.certificate == c.certificate).count()
        )?;
    }
    if let Some(j) = &a.json {
        let doc = ShowJson {
            asset_id: a.id.clone(),
            today,
            overdue: today > last.due_date,
            certificates: certificates.clone(),
            runs,
        };
        write_json(j, &doc).with_context(|| format!("writing {}", j.display()))?;
        outln!("wrote {}", j.display())?;
    }
    Ok(())
}
