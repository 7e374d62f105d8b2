//! `accelcal fit`: coefficients by least squares or test turns, and the calibration record.

use accelcal_core::calibrate::{fit_positions, gate, record, record_bytes, record_crc_hex, Method};
use accelcal_core::campaign::identity::{CampaignId, Identity};
use accelcal_core::document::{FitChannelDoc, FitDoc};
use accelcal_core::error::bad;
use accelcal_core::lsq::LsqFit;
use accelcal_core::output::{finite, write_atomic, write_json};
use accelcal_line::node::session::device_id_hex;
use anyhow::Context;

use accelcal_core::positions::{ChannelStats, Positions};
use accelcal_core::uncertainty::{self, Budget, References, UncertaintyJson, ARCSEC};

use crate::settings::campaign::{Fit, FitSettings};

/// The JSON document of a set of fits of the unit `identity`; `t_ref_c` (°C) is stated when a
/// fit has a term in `t`.
pub fn to_json(
    method: Method,
    fits: &[(String, LsqFit)],
    t_ref_c: f64,
    identity: Identity,
    uncertainty: Option<&Budget>,
) -> FitDoc {
    let thermal = fits.iter().any(|(_, f)| f.structure.is_thermal());
    FitDoc {
        version: accelcal_core::document::FIT_VERSION,
        method: method.name().to_string(),
        identity: Some(identity),
        t_ref_c: thermal.then_some(t_ref_c),
        channels: fits
            .iter()
            .map(|(name, f)| FitChannelDoc {
                channel: name.clone(),
                terms: f.structure.terms().map(|t| t.to_string()).collect(),
                coefficients: f.coefficients.clone(),
                std_errors: f.std_errors().into_iter().map(finite).collect(),
                covariance: f.covariance.iter().map(|r| r.iter().map(|&v| finite(v)).collect()).collect(),
                condition: finite(f.condition).filter(|_| method == Method::Lsq),
                rms_codes: finite(f.rms),
            })
            .collect(),
        uncertainty: uncertainty.map(UncertaintyJson::from),
    }
}

/// Prints the coefficient table.
pub fn print_table(method: Method, fits: &[(String, LsqFit)]) -> anyhow::Result<()> {
    for (name, f) in fits {
        match method {
            Method::Lsq => {
                outln!("channel {name}: LSQ, condition {:.3}, residual RMS {:.2} codes", f.condition, f.rms)?
            }
            Method::TestTurns => outln!("channel {name}: test turns")?,
        }
        outln!("  {:<10} {:>16} {:>14}", "term", "coefficient", "std error")?;
        for ((t, c), s) in f.structure.terms().zip(&f.coefficients).zip(&f.std_errors()) {
            outln!(
                "  {:<10} {:>16} {:>14}",
                t.to_string(),
                crate::report::sig(*c, 8),
                crate::report::sig(*s, 3)
            )?;
        }
    }
    Ok(())
}

/// Runs `accelcal fit` at the gravity `g` (the user's, the campaign's or the assumed 9.81).
pub fn run(s: &FitSettings, g: &super::Gravity, warnings: &mut super::Warnings) -> anyhow::Result<()> {
    let a = match s {
        FitSettings::GravityNorm(a) => return super::gravity::run(a, g),
        FitSettings::Campaign(a) => a,
    };
    let (method, structure) = (a.method, a.structure);
    let unit = CampaignId::read(&a.campaign.path)?;
    let device_id = record_device_id(a, a.device_id, &unit)?;
    let mut db = super::store::open(a.store.as_ref())?;
    // A survey named by --gravity-asset is read before anything is computed or written.
    let (g, survey) = &crate::app::gravity::resolve(g, db.as_mut().map(|r| &mut r.db))?;
    // The head's register entry, checked before anything is computed or written.
    let head = match (&a.head_asset, &mut db) {
        (Some(id), Some(rdb)) => {
            Some(rdb.db.asset_in_force(id, accelcal_db::AssetKind::Head, accelcal_db::asset::today_utc())?)
        }
        (Some(_), None) => return Err(bad("--head-asset needs --db: the asset is read from its register")),
        (None, _) => None,
    };
    // What the head's own units measure of its angle error, beside its certificate.
    let measured = match (&head, &mut db) {
        (Some(h), Some(rdb)) => super::fleet::measured_head_angle(&mut rdb.db, &h.asset_id)?,
        _ => None,
    };
    let head_u = match &head {
        Some(h) => HeadU {
            angle: Some(h.angle_u_arcsec),
            orthogonality: Some(h.orthogonality_u_arcsec),
            asset: Some(h),
            measured,
        },
        None => HeadU {
            angle: a.head_angle_u,
            orthogonality: a.head_orthogonality_u,
            asset: None,
            measured: None,
        },
    };
    if let (Some(h), Some(m)) = (&head, &measured) {
        warnings.extend(super::fleet::over_certificate(h, m).as_slice());
    }
    // Streamed: the fits need the dwell statistics only, so memory does not grow with the rows.
    let r = super::reduce_campaign(&a.campaign.path, a.campaign.codes, warnings)?;
    let mut pos = r.positions(g.g);
    pos.t_ref_c = a.t_ref_c;
    let stats = r.channel_stats();
    let fits = fit_positions(&pos, &stats, method, structure)
        .with_context(|| a.campaign.path.display().to_string())?;
    // The record is built and checked first: a record a node would refuse writes nothing.
    let rec = match &a.record {
        Some(path) => {
            let thermal = match (a.temp_input, pos.temp_range()) {
                (Some(input), Some((lo, hi))) => Some(accelcal_shared::record::Thermal {
                    t_ref_c: a.t_ref_c as f32,
                    t_min_c: lo as f32,
                    t_max_c: hi as f32,
                    source: input,
                }),
                (Some(_), None) => {
                    return Err(bad(format!(
                        "{}: --temp-input needs the campaign's temperature, and it has no `temp_c` column",
                        a.campaign.path.display()
                    )))
                }
                (None, _) => None,
            };
            let rec = record(&fits, device_id.unwrap_or_default(), super::created(a.created), g.g, thermal)?;
            gate(path, &rec)?;
            Some((path, record_bytes(&rec)?, rec))
        }
        None => None,
    };
    print_table(method, &fits)?;
    let header = accelcal_core::campaign::header(&a.campaign.path)?;
    let get = |k: &str| header.iter().find(|(key, _)| key == k).map(|(_, v)| v.clone()).unwrap_or_default();
    let budget = fit_budget(a, head_u, method, &pos, &stats, &fits, g)?;
    // Typed on this command line: a campaign's g was announced where it was typed.
    if let (Some(_), super::Source::Stated(accelcal_core::campaign::GSource::Given { u_m_s2: None })) =
        (&budget, &g.source)
    {
        warnings.note(format!(
            "u(g) = {:.1e} m/s²: g = {} m/s² as typed is taken as rounded, half a unit of its last digit \
             (give --g-u with the standard uncertainty of the survey it came from)",
            g.standard_u().0,
            g.g
        ));
    }
    if let Some(b) = &budget {
        super::uncertainty::print_budget(&UncertaintyJson::from(b))?;
    }
    let identity = Identity {
        device_id: device_id.map(|d| device_id_hex(&d)).or(unit.device_id),
        serial: unit.serial,
        g_m_s2: g.g,
        g_source: Some(g.provenance()),
        campaign_sha256: unit.sha256,
        record_crc: rec.as_ref().map(|(_, bytes, _)| record_crc_hex(bytes)),
    };
    let doc = to_json(method, &fits, a.t_ref_c, identity.clone(), budget.as_ref());
    if let Some(j) = &a.campaign.json {
        write_json(j, &doc)?;
    }
    if let Some((path, bytes, rec)) = &rec {
        write_atomic(path, bytes)?;
        outln!(
            "record: {} ({} bytes, {} channels, terms {}, device {}, CRC {})",
            path.display(),
            rec.len(),
            rec.n_channels,
            rec.structure,
            device_id_hex(&rec.device_id),
            record_crc_hex(bytes)
        )?;
    }
    if let Some(rdb) = &mut db {
        let Some(device_id) = identity.device_id.clone() else {
            return Err(bad(format!(
                "fit --db needs the unit's device id: {} has no `# device_id:` line (give --record with --device-id)",
                a.campaign.path.display()
            )));
        };
        let run = rdb.begin_or_continue(super::store::Begin {
            device_id,
            serial: identity.serial.clone().unwrap_or_default(),
            head: String::new(),
            firmware_version: get("firmware"),
            g: (g.g, g.stored()),
        })?;
        for asset in [&head, survey].into_iter().flatten() {
            rdb.db.store_run_asset(run, asset)?;
        }
        let json = serde_json::to_string_pretty(&doc).context("serialising the fit")?;
        let bytes = rec.as_ref().map(|(_, b, _)| b.as_slice());
        super::store::fit_pieces(&mut rdb.db, run, &a.campaign.path, &json, bytes)?;
        // Said once every piece is stored: an output that fails leaves no run begun and empty
        // (stderr's lines never stop a command, see `crate::out`).
        for (what, asset) in [("head", &head), ("gravity survey", survey)] {
            if let Some(h) = asset {
                outln!(
                    "db: run {run}: {what} {} (certificate {}, due {}) stored",
                    h.asset_id,
                    h.certificate,
                    h.due_date
                )?;
            }
        }
        outln!(
            "db: run {run}: campaign, fit{} stored in {}",
            if bytes.is_some() { " and record" } else { "" },
            rdb.db.target()
        )?;
    }
    Ok(())
}

/// The head's stated uncertainties, arcsec (one sigma): `--head-angle-u` and
/// `--head-orthogonality-u`, or the register entry of `--head-asset`.
struct HeadU<'a> {
    angle: Option<f64>,
    orthogonality: Option<f64>,
    /// The register entry they come from.
    asset: Option<&'a accelcal_db::Asset>,
    /// The head's angle error as its own units measure it (the register's head, with `--db`):
    /// the budget takes the larger of it and the stated `angle`.
    measured: Option<accelcal_core::headsig::MeasuredAngle>,
}

impl HeadU<'_> {
    /// The head angle's standard uncertainty the budget takes, arcsec.
    fn angle_u(&self) -> Option<f64> {
        match (self.angle, self.measured) {
            (Some(stated), Some(m)) => Some(stated.max(m.rms_arcsec)),
            (stated, _) => stated,
        }
    }
}

/// The uncertainty budget of an lsq fit of a model-4 triad (`None` for another fit, which the
/// settings let through only without the head's stated uncertainties, or a campaign
/// whose channels are not a triad: then those options are refused here). The standard uncertainty
/// of g is its source's bound taken as rectangular (bound/√3).
fn fit_budget(
    a: &Fit,
    head: HeadU<'_>,
    method: Method,
    pos: &Positions,
    stats: &[ChannelStats],
    fits: &[(String, LsqFit)],
    g: &super::Gravity,
) -> anyhow::Result<Option<Budget>> {
    if method != Method::Lsq || fits.iter().any(|(_, f)| f.structure != accelcal_shared::terms::MODEL_4) {
        return Ok(None);
    }
    let stated = head.angle.is_some() || head.orthogonality.is_some() || a.tempco.is_some();
    let (u_g, why) = g.standard_u();
    let refs = References {
        head_angle_rad: head.angle_u().unwrap_or(0.0) * ARCSEC,
        head_orthogonality_rad: head.orthogonality.unwrap_or(0.0) * ARCSEC,
        g_m_s2: u_g,
        // GMDH needs a plan whose split identifies its candidates; on fewer positions the lack of
        // fit is not measured, and the budget says so.
        lack_of_fit_codes: lack_of_fit_codes(pos, stats),
        temperature: a.tempco,
    };
    let only: Vec<&LsqFit> = fits.iter().map(|(_, f)| f).collect();
    match uncertainty::budget(pos, stats, &only, refs) {
        Ok(mut b) => {
            if let Some(c) = b.contributors.iter_mut().find(|c| c.name == "gravity") {
                c.source = format!("g {why}");
            }
            if let Some(h) = head.asset {
                for c in b.contributors.iter_mut().filter(|c| c.name.starts_with("head_")) {
                    c.source = format!(
                        "{} by head asset {}, certificate {} (due {})",
                        c.source, h.asset_id, h.certificate, h.due_date
                    );
                    match (c.name == "head_angle", head.measured) {
                        (true, Some(m)) if m.rms_arcsec > h.angle_u_arcsec => {
                            c.source = format!(
                                "{:.2} arcsec per angle and position, measured by the head's last {} units (RMS over {} head angles): more than the {} arcsec that head asset {}'s certificate {} (due {}) states",
                                m.rms_arcsec, m.units, m.angles, h.angle_u_arcsec, h.asset_id, h.certificate, h.due_date
                            );
                        }
                        (true, Some(m)) => {
                            c.source = format!(
                                "{}; its last {} units measure {:.2} arcsec (RMS over {} head angles)",
                                c.source, m.units, m.rms_arcsec, m.angles
                            );
                        }
                        _ => {}
                    }
                }
            }
            Ok(Some(b))
        }
        Err(uncertainty::UncertaintyError::NotATriad(_)) if !stated => Ok(None),
        Err(e) => Err(anyhow::Error::new(e).context(a.campaign.path.display().to_string())),
    }
}

/// Model 4's lack of fit per channel, codes (the GMDH criterion gap, in the order of `stats`):
/// `None` for a campaign that is not a triad or a plan on which GMDH identifies no candidate.
fn lack_of_fit_codes(pos: &Positions, stats: &[ChannelStats]) -> Option<[f64; 3]> {
    uncertainty::lack_of_fit::criterion_gap(pos, stats).ok()?.try_into().ok()
}

/// The device id of `fit --record`: the campaign's `# device_id:` line, which `--device-id` may
/// repeat but not contradict, else `--device-id`; refused when neither gives one. `None` without
/// `--record`.
fn record_device_id(a: &Fit, given: Option<[u8; 12]>, unit: &CampaignId) -> anyhow::Result<Option<[u8; 12]>> {
    if a.record.is_none() {
        return Ok(None);
    }
    let campaign = unit.device_id_bytes();
    match (given, campaign) {
        (Some(g), Some(c)) if g != c => Err(bad(format!(
            "--device-id {} contradicts {}'s `# device_id: {}`: not the same unit (leave --device-id out: the \
             campaign's is used)",
            device_id_hex(&g),
            a.campaign.path.display(),
            device_id_hex(&c)
        ))),
        (Some(id), _) | (None, Some(id)) => Ok(Some(id)),
        (None, None) => Err(bad(format!(
            "fit --record needs --device-id HEX, the MCU's 96-bit unique id (`accelcal info` shows it): {} has no \
             `# device_id:` line, and a node accepts only a record made for it",
            a.campaign.path.display()
        ))),
    }
}
