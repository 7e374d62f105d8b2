//! `accelcal report`: the calibration certificate of one unit. It reads the unit's files and
//! checks that they are of one unit (the campaign's `acquire` header: serial, device id,
//! firmware, g, plan, date; the record written to the node; the fit JSON; the verifications),
//! takes the number, the drift and the assets from the database, and builds the certificate
//! document ([`accelcal_core::certificate::build`]), which the HTML page and the PDF render.
//! `--technical` writes the engineering material the certificate leaves out: the coefficients
//! with their standard errors, GMDH's model selection (the paper's 11 models, regularity
//! criterion, alternate split, 1-code tolerance) and the paper's Table 2.

use std::fmt::Write as _;

use accelcal_core::calibrate::{record_crc_hex, Method};
use accelcal_core::campaign::identity::{
    same, CampaignId, Identity, IdentityError, Mismatch, G_KEY, G_SOURCE_KEY,
};
use accelcal_core::campaign::{Campaign, GSource};
use accelcal_core::document::FitDoc;
use accelcal_core::error::bad;
use accelcal_core::output::write_atomic;
use accelcal_core::positions::Positions;
use accelcal_line::node::session::device_id_hex;
use accelcal_line::verify::VerifyReport;
use accelcal_shared::record::Record;

use crate::settings::line::Report;

mod method;
use accelcal_core::certificate::{
    AssetRef, DriftInput, GravityInput, Inputs, IssuerInput, Release, TermChange,
};
use method::{coefficients, structure, table2};

/// HTML-escapes text.
fn esc(s: &str) -> String {
    s.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;").replace('"', "&quot;")
}

/// The inputs of a certificate, read and checked to belong to one unit.
struct Unit {
    /// The campaign's header lines.
    header: Vec<(String, String)>,
    /// The record's bytes, parsed.
    rec: Record,
    /// Its CRC (hex).
    crc: String,
    /// Its device id (hex).
    device_id: String,
    /// The fit JSON.
    fit: FitDoc,
    /// Whose fit it is.
    fit_id: Identity,
    /// The verification, when given.
    verify: Option<VerifyReport>,
    /// The as-found verification (with the record the unit came in with), when given.
    as_found: Option<VerifyReport>,
}

impl Unit {
    fn get(&self, k: &str) -> Option<String> {
        self.header.iter().find(|(key, _)| key == k).map(|(_, v)| v.clone())
    }
}

/// Reads the campaign's header and hash, the record, the fit JSON and the verification, and
/// refuses any of them that is not of the same unit (one line naming both values): the campaign
/// and the record (device id), the fit and the campaign (SHA-256 of its content), the fit and the
/// record (the record's CRC, device id), the verification and the record (device id, CRC), the
/// verification's g and the fit's (the certificate states one g).
fn read_unit(a: &Report) -> anyhow::Result<Unit> {
    let campaign = CampaignId::read(&a.campaign)?;
    let header = accelcal_core::campaign::header(&a.campaign)?;
    let rec_bytes = std::fs::read(&a.record)
        .map_err(|e| bad(format!("{}: cannot read the record: {e}", a.record.display())))?;
    let rec = Record::parse(&rec_bytes).map_err(|e| bad(format!("{}: {e}", a.record.display())))?;
    let crc = record_crc_hex(&rec_bytes[..rec.len()]);
    let device_id = device_id_hex(&rec.device_id);
    let (c_name, r_name, f_name) =
        (a.campaign.display().to_string(), a.record.display().to_string(), a.fit.display().to_string());
    if let Some(d) = &campaign.device_id {
        same("device id", (&c_name, d), (&r_name, &device_id), "not the same unit")?;
    }
    let text = std::fs::read_to_string(&a.fit)
        .map_err(|e| bad(format!("{f_name}: cannot read the fit JSON: {e}")))?;
    let fit: serde_json::Value =
        serde_json::from_str(&text).map_err(|e| bad(format!("{f_name}: not a JSON document: {e}")))?;
    let fit_id = Identity::of_fit_json(&fit, &f_name)?;
    // `parse` checks the version (a fit a later accelcal wrote is refused), as every reader does.
    let fit = FitDoc::parse(&text).map_err(|e| bad(format!("{f_name}: not `fit --json` output: {e}")))?;
    same(
        "campaign SHA-256",
        (&f_name, &fit_id.campaign_sha256),
        (&c_name, &campaign.sha256),
        "not the campaign of this fit",
    )?;
    let fit_crc = fit_id.written_record(&f_name, &r_name)?;
    same("record CRC", (&f_name, fit_crc), (&r_name, &crc), "not the record of this fit")?;
    if let Some(given) = a.g {
        same_g((&f_name, fit_id.g_m_s2), ("--g", given))?;
    }
    // A verification of this unit (device id).
    let read_verification = |p: &std::path::Path| -> anyhow::Result<(String, VerifyReport)> {
        let v_name = p.display().to_string();
        let v = VerifyReport::read(p)?;
        same("device id", (&v_name, &v.device_id), (&r_name, &device_id), "not the same unit")?;
        Ok((v_name, v))
    };
    let verify = match &a.verify {
        Some(p) => {
            let (v_name, v) = read_verification(p)?;
            let v_crc = v.record["crc"].as_str().unwrap_or("(none)");
            same(
                "record CRC",
                (&v_name, v_crc),
                (&r_name, &crc),
                "the node did not run this record when it was verified",
            )?;
            same_g((&v_name, v.g_m_s2), (&f_name, fit_id.g_m_s2))?;
            Some(v)
        }
        None => None,
    };
    let as_found = a.as_found.as_deref().map(|p| read_verification(p).map(|(_, v)| v)).transpose()?;
    Ok(Unit { header, rec, crc, device_id, fit, fit_id, verify, as_found })
}

/// Refuses two gravities that differ (beyond the last digits of a round trip through text): the
/// certificate states one g.
fn same_g((a, ga): (&str, f64), (b, gb): (&str, f64)) -> anyhow::Result<()> {
    if (ga - gb).abs() <= 1e-9 * gb.abs() {
        return Ok(());
    }
    Err(IdentityError::Mismatch(Box::new(Mismatch {
        a: a.to_string(),
        field: "g",
        a_value: format!("{ga} m/s²"),
        b: b.to_string(),
        b_value: format!("{gb} m/s²"),
        consequence: "the certificate states one g (verify with the fit's g)",
    }))
    .into())
}

/// Runs `accelcal report`.
pub fn run(a: &Report) -> anyhow::Result<()> {
    let mut u = read_unit(a)?;
    let mut db = super::store::open(a.store.as_ref())?;
    let run = match &mut db {
        Some(rdb) => Some(rdb.existing("report")?),
        None => None,
    };
    if let Some((run, p)) = &run {
        if !p.start.device_id.eq_ignore_ascii_case(&u.device_id) {
            return Err(bad(format!(
                "--run-id {run} is a run of device {}, not of the record's device {}",
                p.start.device_id, u.device_id
            )));
        }
        if p.certificate {
            return Err(bad(format!("run {run} holds its certificate already (a run has one certificate)")));
        }
    }
    if let (Some(rdb), Some((run, p))) = (&mut db, &run) {
        let Some(v) = &u.verify else {
            return Err(bad(format!(
                "report --db needs --verify: run {run}'s as-left verification, which the certificate states"
            )));
        };
        super::store::check_certifiable(&mut rdb.db, *run, p, v)?;
    }
    // The unit's calibrations before this run, and this run as the next one (it ends `pass`
    // when its certificate is issued): the drift since the last calibration.
    let mut since_last = match (&mut db, &run) {
        (Some(rdb), Some((run, _))) => {
            let mut runs = rdb.db.unit_runs(&u.device_id)?;
            if u.as_found.is_none() {
                u.as_found = runs.iter().find(|r| r.start.run_id == *run).and_then(|r| r.as_found.clone());
            }
            Some(since_last_calibration(&mut runs, *run, a.issuer.recal_rule()))
        }
        _ => None,
    };
    // The registered reference equipment the run used (`station --head-asset`, `fit --db
    // --head-asset`): named on the certificate by asset id and certificate.
    let assets = match (&mut db, &run) {
        (Some(rdb), Some((run, _))) => rdb.db.run_assets(*run)?,
        _ => Vec::new(),
    };
    // The certificate's number: the run's, given once and never again to another.
    // The recalibration date it states is stored with it, and a certificate printed again
    // states the date stored first.
    let number = match (&mut db, &run) {
        (Some(rdb), Some((run, _))) => {
            let due = since_last.as_ref().and_then(|h| {
                let rc = &h.recalibration;
                rc.due_unix_s
                    .map(|due_unix_s| accelcal_db::RecalibrationDue { due_unix_s, basis: rc.basis.clone() })
            });
            let n = match due {
                Some(due) => {
                    let (n, stored) = rdb.db.certificate_number_with_due(*run, &due)?;
                    if let (Some(h), Some(d)) = (&mut since_last, stored) {
                        h.recalibration.due_unix_s = Some(d.due_unix_s);
                        h.recalibration.basis = d.basis;
                    }
                    n
                }
                None => rdb.db.certificate_number(*run)?,
            };
            super::store::crash_point("db:certificate-number");
            Some(n)
        }
        _ => None,
    };
    let g = u.fit_id.g_m_s2;
    // Where g came from: the run's (a station or `fit --db` stored it, a survey named there),
    // else the fit's identity, else the campaign's line when the fit used its g.
    let same = |x: f64| (x - g).abs() <= 1e-9 * g;
    let known = |s: &GSource| *s != GSource::Unstated;
    let g_source = run
        .as_ref()
        .filter(|(_, p)| same(p.start.g_m_s2))
        .map(|(_, p)| GSource::parse(&p.start.g_source))
        .filter(known)
        .or_else(|| u.fit_id.g_source.clone().filter(known))
        .or_else(|| {
            let campaign_g = u.get(G_KEY).and_then(|v| v.parse::<f64>().ok()).filter(|cg| same(*cg));
            campaign_g.and(u.get(G_SOURCE_KEY)).map(|s| GSource::parse(&s))
        })
        .unwrap_or(GSource::Unstated);
    let serial = u.fit_id.serial.clone().unwrap_or_else(|| "-".into());
    let mut budget = u.fit.uncertainty.clone();
    if let (Some(b), Some((_, id, cert))) =
        (&mut budget, assets.iter().find(|(k, _, _)| *k == accelcal_db::asset::AssetKind::Head))
    {
        name_head_asset(b, id, cert);
    }
    // The hash chain's head at issue, kept outside the database by every copy of the page.
    let anchor = match &mut db {
        Some(rdb) => rdb.db.chain_head()?.map(|a| a.text()),
        None => None,
    };
    let asset_refs: Vec<AssetRef> = assets
        .iter()
        .map(|(kind, id, cert)| AssetRef {
            kind: kind.name().to_string(),
            id: id.clone(),
            certificate: cert.clone(),
        })
        .collect();
    let operator = run.as_ref().map(|(_, p)| p.start.operator.clone());
    // The sets lost in transit, counted from the campaign's rows at its `# rate_hz:`.
    let transit = accelcal_core::campaign::transit::Transit::of_file(&a.campaign)?;
    let environment = match (a.issuer.ambient_c, &mut db) {
        (Some(celsius), Some(rdb)) => Some(environment(&mut rdb.db, &assets, celsius)?),
        // The settings refuse --ambient-c without --db.
        _ => None,
    };
    let issuer = IssuerInput {
        laboratory: a.issuer.laboratory.clone(),
        laboratory_address: a.issuer.laboratory_address.clone(),
        laboratory_country: a.issuer.laboratory_country.clone(),
        customer: a.issuer.customer.clone(),
        customer_address: a.issuer.customer_address.clone(),
        received: a.issuer.received.clone(),
        place: a.issuer.place.clone(),
    };
    let doc = accelcal_core::certificate::build(&Inputs {
        number: number.as_ref().map(|n| n.number.as_str()),
        issued_unix_s: i64::try_from(super::created(None)).unwrap_or(i64::MAX),
        issuer: &issuer,
        header: &u.header,
        campaign_sha256: &u.fit_id.campaign_sha256,
        record: &u.rec,
        record_crc: &u.crc,
        device_id: &u.device_id,
        fit: &u.fit,
        budget: budget.as_ref(),
        serial: &serial,
        gravity: GravityInput { g_m_s2: g, source: g_source },
        verify: u.verify.as_ref(),
        as_found: u.as_found.as_ref(),
        assets: &asset_refs,
        operator: operator.as_deref(),
        drift: since_last.as_ref().map(drift_input),
        environment,
        transit,
        anchor: anchor.as_deref(),
        replaces: None,
        software: env!("CARGO_PKG_VERSION"),
    });
    // With a database the certificate awaits approval (`accelcal approve`): a draft until a
    // signer approves it. Without one, the name the settings state.
    let release = match (&a.issuer.authorised_by, number.is_some()) {
        (Some(name), false) => Release::Stated { name: name.clone() },
        _ => Release::Draft,
    };
    let h = crate::report::certificate::html(&doc, &release)?;
    write_atomic(&a.out, h.as_bytes())?;
    outln!(
        "report: certificate of unit {serial} (device {}, record CRC {}) written to {}",
        u.device_id,
        u.crc,
        a.out.display()
    )?;
    if let Some(p) = &a.pdf {
        write_atomic(p, &crate::report::pdf::pdf(&doc, &release, None)?)?;
        outln!("report: its PDF written to {}", p.display())?;
    }
    if let Some(p) = &a.dcc {
        // The authoriser comes from an approval (the signer's branch): none here.
        write_atomic(p, &crate::report::dcc::dcc(&doc, None)?)?;
        outln!("report: its DCC (XML, schema 3.3.0) written to {}", p.display())?;
    }
    if let Some(p) = &a.technical {
        write_atomic(p, technical(&a.campaign, &u)?.as_bytes())?;
        outln!("report: the technical report written to {}", p.display())?;
    }
    if let (Some(rdb), Some((run, _))) = (&mut db, &run) {
        rdb.db.store_certificate(*run, &h)?;
        super::store::crash_point("db:certificate");
        // The run is complete: it ends as the station ends it.
        rdb.db.finish_run(*run, accelcal_db::Outcome::Pass, super::store::PASS_REASON)?;
        super::store::crash_point("db:end-report");
        outln!("db: run {run}: certificate stored in {}; the run ended pass", rdb.db.target())?;
    }
    Ok(())
}

/// The technical report (`report --technical`): the engineering material behind the record,
/// which the certificate leaves out: the coefficients with the fit's standard errors, the model
/// structure GMDH selects, and the paper's Table 2.
fn technical(campaign_path: &std::path::Path, u: &Unit) -> anyhow::Result<String> {
    let rec = &u.rec;
    let g = u.fit_id.g_m_s2;
    let method = match u.fit.method.as_str() {
        "test-turns" => Method::TestTurns,
        _ => Method::Lsq,
    };
    let campaign = Campaign::read(campaign_path)?;
    // The positions at the record's reference temperature; a thermal record's structure is
    // chosen among the linear-thermal candidates, and its coefficients are those of its terms.
    let mut pos = Positions::new(&campaign, g);
    if let Some(t) = rec.thermal {
        pos.t_ref_c = t.t_ref_c as f64;
    }
    let stats = pos.channel_stats(&campaign);
    let mut settings = accelcal_core::gmdh::Settings::paper();
    if rec.structure.is_thermal() {
        settings.basis = accelcal_shared::Basis::LinearThermal;
    }
    let sel = super::select::compute_on(&pos, &stats, &[], &settings)?;
    let cmp = accelcal_core::compare::compute(&campaign, None, g).ok();
    let serial = u.fit_id.serial.clone().unwrap_or_else(|| "-".into());
    let mut h = String::new();
    let _ = write!(
        h,
        "<!doctype html><html lang=\"en\"><head><meta charset=\"utf-8\"><title>Technical report, accelerometer triad {}</title><style>{CSS}</style></head><body><h1>Technical report: accelerometer triad {}</h1><p>Device {}, record CRC {}, campaign SHA-256 {}. Engineering material behind the calibration; not part of the certificate.</p>",
        esc(&serial),
        esc(&serial),
        esc(&u.device_id),
        esc(&u.crc),
        esc(&u.fit_id.campaign_sha256)
    );
    h.push_str(&coefficients(rec, &u.fit, method)?);
    h.push_str(&structure(&sel, rec, &u.fit));
    h.push_str(&table2(cmp.as_ref(), method)?);
    h.push_str("</body></html>\n");
    Ok(h)
}

/// The unit's drift and recalibration as the certificate states them.
fn drift_input(h: &accelcal_db::history::History) -> DriftInput {
    let last = h.drifts.last().filter(|d| Some(d.to) == h.runs.iter().filter_map(|r| r.calibration).max());
    let rc = &h.recalibration;
    DriftInput {
        last: last.map(|d| {
            (
                d.days,
                d.terms
                    .iter()
                    .map(|t| TermChange {
                        channel: t.channel.to_string(),
                        term: t.term.to_string(),
                        delta_m_s2: t.delta_m_s2,
                        sigma_m_s2: t.sigma_m_s2,
                    })
                    .collect(),
            )
        }),
        due_unix_s: rc.due_unix_s,
        basis: rc.basis.clone(),
        tolerance_m_s2: rc.rule.tolerance_m_s2,
        coverage: rc.rule.coverage,
        max_interval_days: rc.rule.max_interval_days,
    }
}

/// The unit's history with run `run` counted as its latest calibration.
fn since_last_calibration(
    runs: &mut [accelcal_db::RunSummary],
    run: accelcal_db::RunId,
    rule: accelcal_db::history::RecalRule,
) -> accelcal_db::history::History {
    use accelcal_db::Outcome;
    for r in runs.iter_mut().filter(|r| r.start.run_id == run && r.end.is_none()) {
        r.end = Some((Outcome::Pass, "this certificate".into(), accelcal_db::now_unix_s()));
    }
    accelcal_db::history::history(runs, rule)
}

/// The method's short label.
fn label(m: Method) -> &'static str {
    match m {
        Method::Lsq => "LSQ",
        Method::TestTurns => "test turns",
    }
}

/// The technical report's style.
const CSS: &str = "body{font:9pt/1.3 sans-serif;margin:12mm;color:#111}h1{font-size:13pt}h2{font-size:10pt;border-bottom:1px solid #888}\
table{border-collapse:collapse;width:100%}td,th{border:1px solid #ccc;padding:1px 4px;text-align:right}th{background:#eee}.l{text-align:left}\
.small{font-size:8pt}.cols>div{margin-bottom:4mm}svg{width:100%;max-width:170mm;height:auto}";

/// The head rows of a budget whose values the run's registered head stated (the station passes
/// the asset's values to its fit step, which knows no register): named by the asset, as a fit
/// with `--db --head-asset` names them itself.
/// The environment's temperature `celsius` as read on the thermometer the run used, with the
/// thermometer's stated uncertainty from the certificate it was used under.
fn environment(
    db: &mut accelcal_db::Db,
    assets: &[(accelcal_db::AssetKind, String, String)],
    celsius: f64,
) -> anyhow::Result<accelcal_core::certificate::EnvironmentInput> {
    let Some((_, id, certificate)) =
        assets.iter().find(|(k, _, _)| *k == accelcal_db::AssetKind::Thermometer)
    else {
        return Err(bad(
            "--ambient-c: the run used no registered thermometer to read it on (station --thermometer-asset)",
        ));
    };
    let used = db.asset_certificates(id)?.into_iter().find(|c| &c.certificate == certificate);
    Ok(accelcal_core::certificate::EnvironmentInput {
        celsius,
        u_k: used.and_then(|c| c.value).map(|v| v.u),
        thermometer: id.clone(),
        certificate: certificate.clone(),
    })
}

fn name_head_asset(b: &mut accelcal_core::uncertainty::UncertaintyJson, id: &str, cert: &str) {
    for c in b.contributors.iter_mut().filter(|c| c.name.starts_with("head_")) {
        if c.source.ends_with(", stated") {
            c.source = format!("{} by head asset {id}, certificate {cert}", c.source);
        }
    }
}
