//! `accelcal report`: the calibration certificate of one unit, a self-contained HTML page (plots
//! inline) laid out as ISO/IEC 17025 §7.8 asks: its number (the run's, from the database), the
//! laboratory, customer, item and condition on receipt, method, dates, traceability,
//! environment, decision rule (`verification`), who authorised it, then the results with U
//! (`results`) and the method's sections (`method`); every
//! printed page ends with the number and "Page i of n" (CSS page margin boxes). No command-line
//! wording reaches the page ([`plain`]).
//!
//! Everything on it is computed here from the unit's files, so that the page cannot disagree with
//! them: the campaign (its `acquire` header: serial, device id, firmware, g, plan, date), the
//! record written to the node (device id, CRC, coefficients), the model selection (GMDH over the
//! paper's 11 models, regularity criterion, alternate split, 1-code tolerance: what `demo` runs),
//! the LSQ fit with its standard errors, Table 2 (LSQ against test turns) and the verification
//! (`verify --json`).

use std::fmt::Write as _;

use accelcal_core::calibrate::{record_crc_hex, Method};
use accelcal_core::campaign::identity::{
    g_uncertainty, same, CampaignId, Identity, IdentityError, Mismatch, G_KEY, G_SOURCE_KEY,
};
use accelcal_core::campaign::Campaign;
use accelcal_core::document::FitDoc;
use accelcal_core::error::bad;
use accelcal_core::output::write_atomic;
use accelcal_core::positions::Positions;
use accelcal_line::node::session::device_id_hex;
use accelcal_line::verify::VerifyReport;
use accelcal_shared::record::Record;

use crate::settings::line::Report;

mod method;
mod results;
mod verification;
use crate::report::with_uncertainty;
use method::{coefficients, structure, table2};
use verification::{as_found, decision_rule, receipt, verification, verification_temperature};

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
            Some(since_last_calibration(&mut runs, *run))
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
    let (rec, device_id, crc) = (&u.rec, &u.device_id, &u.crc);
    let g = u.fit_id.g_m_s2;
    // The g's origin: the campaign's, when the fit used it, else the fit's own --g/--latitude.
    let campaign_g = u.get(G_KEY).and_then(|v| v.parse::<f64>().ok());
    let (source, source_words) = match campaign_g {
        Some(cg) if (cg - g).abs() <= 1e-9 * g => {
            let s = u.get(G_SOURCE_KEY);
            // Acquire names a stated g by its option.
            let words = match s.as_deref() {
                Some("--g") => "the value the operator stated".to_string(),
                Some(s) => plain(s),
                None => "the value stated with the campaign".to_string(),
            };
            (s, words)
        }
        _ => (None, "the value stated with the fit".to_string()),
    };
    let (g_bound, g_why) = g_uncertainty(g, source.as_deref());
    let method = match u.fit.method.as_str() {
        "test-turns" => Method::TestTurns,
        _ => Method::Lsq,
    };
    let campaign = Campaign::read(&a.campaign)?;
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
    let now = super::record::utc(super::created(None));
    let temp = u.verify.as_ref().map(verification_temperature);
    let mut budget = u.fit.uncertainty.clone();
    if let (Some(b), Some((_, id, cert))) =
        (&mut budget, assets.iter().find(|(k, _, _)| *k == accelcal_db::asset::AssetKind::Head))
    {
        name_head_asset(b, id, cert);
    }
    let numbered = number.as_ref().map(|n| n.number.clone());
    let page_no = numbered.as_deref().map_or("draft, not numbered".to_string(), |n| format!("No. {n}"));
    let mut h = String::new();
    let _ = write!(
        h,
        "<!doctype html><html lang=\"en\"><head><meta charset=\"utf-8\"><title>Calibration certificate {}</title><style>{CSS}@page{{@bottom-left{{content:\"Calibration certificate {} \\2014  accelerometer triad {}\";{FOOT}}}@bottom-right{{content:\"Page \" counter(page) \" of \" counter(pages);{FOOT}}}}}</style></head><body>",
        esc(&page_no),
        css_text(&page_no),
        css_text(&serial)
    );
    let lab = match &a.issuer.laboratory {
        Some(l) => format!(
            "<div class=\"lab\"><b>{}</b>{}</div>",
            esc(l),
            a.issuer.laboratory_address.as_deref().map(|s| format!("<br>{}", esc(s))).unwrap_or_default()
        ),
        None => String::new(),
    };
    let _ = write!(
        h,
        "<div class=\"top\"><div><h1>Calibration certificate {}</h1><div>Accelerometer triad {}</div></div>{lab}</div>",
        esc(&page_no),
        esc(&serial)
    );
    let verdict = match &u.verify {
        Some(v) if v.pass && v.decision.is_some() => format!(
            "<span class=\"pass\">CONFORMS: every position accepted by the decision rule ({}), {}</span>",
            esc(v.specification.as_ref().map_or("", |s| s.rule.name())),
            esc(temp.as_deref().unwrap_or_default())
        ),
        Some(v) if v.pass => format!(
            "<span class=\"pass\">VERIFIED: every position within its tolerance on every axis, {}</span>",
            esc(temp.as_deref().unwrap_or_default())
        ),
        Some(v) => format!(
            "<span class=\"fail\">NOT VERIFIED: {} of {} positions outside tolerance</span>",
            v.positions.iter().filter(|p| !p.pass).count(),
            v.positions.len()
        ),
        None => "<span class=\"fail\">not verified after calibration</span>".into(),
    };
    let found = match u.as_found.as_ref().and_then(|v| v.decision) {
        Some(d) if d.out_of_tolerance() => {
            format!(" <span class=\"fail\">AS FOUND OUT OF TOLERANCE ({})</span>", d.name())
        }
        _ => String::new(),
    };
    let _ = write!(h, "<p class=\"verdict\">{verdict}{found}</p><table class=\"id\">");
    let plan = u.get("plan").unwrap_or_else(|| "-".into());
    let mut rows: Vec<(&str, String)> = Vec::new();
    if let Some(c) = &a.issuer.customer {
        rows.push(("Customer", c.clone()));
    }
    rows.push((
        "Item",
        format!(
            "accelerometer triad, serial {serial}; node device id (MCU) {device_id}, firmware {}",
            u.get("firmware").unwrap_or_else(|| "-".into())
        ),
    ));
    rows.push(("Condition on receipt", receipt(u.as_found.as_ref())));
    rows.push((
        "Method",
        format!(
            "static calibration in the Earth's gravity on a dividing head (the principle of ISO 16063-16), plan {plan}; \
             output model 4 (u = u0 + k·a per channel) chosen by combinatorial GMDH (regularity criterion, the simplest model within one code of the best); coefficients by {}; accelcal {}",
            method_words(method),
            env!("CARGO_PKG_VERSION")
        ),
    ));
    rows.push((
        "Record",
        format!(
            "CRC {crc}, created {}, {} ({} bytes, format {})",
            super::record::utc(rec.created_unix_s),
            match rec.thermal {
                Some(t) => format!(
                    "model 4 with thermal terms {}, t = temp_c − {} °C, calibrated {} to {} °C, temperature from the {}",
                    rec.structure,
                    t.t_ref_c,
                    t.t_min_c,
                    t.t_max_c,
                    t.source.name()
                ),
                None => format!("model 4 ({})", rec.structure),
            },
            rec.len(),
            rec.version()
        ),
    ));
    rows.push((
        "Dates",
        format!(
            "calibrated {} (campaign acquired); issued {now}",
            u.get("date").unwrap_or_else(|| "-".into())
        ),
    ));
    rows.push((
        "g (local gravity)",
        format!("{} m/s² ({}; {g_why})", with_uncertainty(g, g_bound), plain(&source_words)),
    ));
    let head = match assets.iter().find(|(k, _, _)| *k == accelcal_db::asset::AssetKind::Head) {
        Some((_, id, cert)) => format!("dividing head {id}, calibration certificate {cert}"),
        None => "the dividing head is not a registered asset: its angles are traceable only as stated in the budget".into(),
    };
    let others: Vec<String> = assets
        .iter()
        .filter(|(k, _, _)| *k != accelcal_db::asset::AssetKind::Head)
        .map(|(kind, id, cert)| format!("{} {id}, calibration certificate {cert}", kind.name()))
        .collect();
    rows.push((
        "Traceability",
        format!(
            "g from {}; {head}{}",
            plain(&source_words),
            others.iter().map(|o| format!("; {o}")).collect::<String>()
        ),
    ));
    rows.push((
        "Environment",
        temp.clone().map_or("temperature not measured (no verification after calibration)".into(), |t| {
            format!("verified {t}")
        }),
    ));
    rows.push(("Decision rule", decision_rule(u.verify.as_ref())));
    rows.push((
        "Campaign",
        // No file path: where the operator kept the campaign is not the customer's business; its
        // SHA-256 identifies it (issue 57).
        format!(
            "plan {}, {} sets per position; SHA-256 {}",
            esc(&plan),
            esc(&u.get("samples").unwrap_or_else(|| "-".into())),
            &u.fit_id.campaign_sha256[..16]
        ),
    ));
    if let Some((_, p)) = &run {
        rows.push(("Calibrated by", p.start.operator.clone()));
    }
    rows.push((
        "Authorised by",
        a.issuer
            .authorised_by
            .clone()
            .unwrap_or_else(|| "not authorised: a draft, not a certificate of calibration".into()),
    ));
    // The hash chain's head at issue, kept outside the database by every copy of this page:
    // `db verify --anchors CERTIFICATE` finds a database cut short or rewritten behind it.
    if let Some(rdb) = &mut db {
        if let Some(anchor) = rdb.db.chain_head()? {
            rows.push(("Ledger anchor", anchor.text()));
        }
    }
    for (k, v) in rows {
        let v = if k == "Campaign" { v } else { esc(&v) };
        let _ = write!(h, "<tr><th class=\"l\">{k}</th><td class=\"l\">{v}</td></tr>");
    }
    h.push_str("</table>");
    h.push_str(&results::section(rec, &u.fit, budget.as_ref()));
    h.push_str(
        "<p class=\"small\">The results relate only to the item calibrated. This certificate shall not be reproduced except in \
         full without the laboratory's written approval. The expanded uncertainty is the standard uncertainty multiplied by the \
         coverage factor k, evaluated after the GUM (JCGM 100:2008) by a method validated by Monte Carlo simulation after JCGM 101:2008.</p>",
    );
    if let Some(v) = &u.as_found {
        h.push_str(&as_found(v));
    }
    if let Some(v) = &u.verify {
        h.push_str(&verification(v, temp.as_deref().unwrap_or_default())?);
    }
    if let Some(d) = &since_last {
        h.push_str(&drift_since_last(d));
    }
    h.push_str(&coefficients(rec, &u.fit, method)?);
    h.push_str(&structure(&sel, rec, &u.fit));
    h.push_str(&table2(cmp.as_ref(), method)?);
    h.push_str("</body></html>\n");
    write_atomic(&a.out, h.as_bytes())?;
    outln!(
        "report: certificate of unit {serial} (device {device_id}, record CRC {crc}) written to {}",
        a.out.display()
    )?;
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

/// The unit's history with run `run` counted as its latest calibration.
fn since_last_calibration(
    runs: &mut [accelcal_db::RunSummary],
    run: accelcal_db::RunId,
) -> accelcal_db::history::History {
    use accelcal_db::Outcome;
    for r in runs.iter_mut().filter(|r| r.start.run_id == run && r.end.is_none()) {
        r.end = Some((Outcome::Pass, "this certificate".into(), accelcal_db::now_unix_s()));
    }
    accelcal_db::history::history(runs, accelcal_db::history::DEFAULT_RULE)
}

/// The drift of the coefficients since the unit's last calibration, and the recommended
/// recalibration date.
fn drift_since_last(h: &accelcal_db::history::History) -> String {
    let mut s = String::new();
    let last = h.drifts.last().filter(|d| Some(d.to) == h.runs.iter().filter_map(|r| r.calibration).max());
    match last {
        Some(d) => {
            let _ = write!(
                s,
                "<h2>Drift since the last calibration ({:.0} days ago): change of each coefficient as an error at 1 g, m/s² &plusmn; standard uncertainty</h2><table><tr><th class=\"l\">channel</th><th>bias</th><th>ax</th><th>ay</th><th>az</th></tr>",
                d.days
            );
            for ch in ["x", "y", "z"] {
                let _ = write!(s, "<tr><td class=\"l\">{ch}</td>");
                for t in d.terms.iter().filter(|t| t.channel == ch) {
                    let _ = write!(
                        s,
                        "<td>{} &plusmn; {}</td>",
                        crate::report::sig(t.delta_m_s2, 3),
                        crate::report::sig(t.sigma_m_s2, 2)
                    );
                }
                s.push_str("</tr>");
            }
            s.push_str("</table>");
        }
        None => s.push_str("<h2>Drift since the last calibration</h2><p>First calibration of this unit in the database: no drift yet.</p>"),
    }
    let rc = &h.recalibration;
    let due =
        rc.due_unix_s.map_or("-".to_string(), |t| super::record::utc(t.max(0) as u64)[..10].to_string());
    let _ = write!(
        s,
        "<p>Recommended recalibration by <b>{due}</b>: {} (tolerance {} m/s² at 1 g, k = {}, at most {} days; from the drift of each coefficient over the unit's calibrations, shortened after an as-found result out of tolerance as ILAC-G24 method 1).</p>",
        esc(&plain(&rc.basis)),
        rc.rule.tolerance_m_s2,
        rc.rule.coverage,
        rc.rule.max_interval_days
    );
    s
}

/// The method's short label.
fn label(m: Method) -> &'static str {
    match m {
        Method::Lsq => "LSQ",
        Method::TestTurns => "test turns",
    }
}

/// The style of the page's footer (its margin boxes).
const FOOT: &str = "font:7pt sans-serif;color:#444";

/// Text as a CSS string's content inside the page's `<style>`: quotes and backslashes escaped,
/// `<` and `>` as CSS escapes (a `</style>` in a serial number must not end the element),
/// control characters left out.
fn css_text(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars().filter(|c| !c.is_control()) {
        match c {
            '"' | '\\' => {
                out.push('\\');
                out.push(c);
            }
            '<' => out.push_str("\\3C "),
            '>' => out.push_str("\\3E "),
            c => out.push(c),
        }
    }
    out
}

/// Text for the page without the tool's command-line wording: a parenthesis that names an
/// option (`(not stated: --head-angle-u)`) is left out, and a remaining `--option` loses its
/// dashes.
pub(crate) fn plain(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    let mut rest = s;
    while let Some(open) = rest.find('(') {
        let Some(close) = rest[open..].find(')').map(|c| open + c) else { break };
        let inner = &rest[open..=close];
        out.push_str(&rest[..open]);
        if !inner.contains("--") {
            out.push_str(inner);
        } else if out.ends_with(' ') {
            out.pop();
        }
        rest = &rest[close + 1..];
    }
    out.push_str(rest);
    out.replace(" --", " ").replace("`", "")
}

/// The method in words.
fn method_words(m: Method) -> &'static str {
    match m {
        Method::Lsq => "least squares (LSQ) over every position",
        Method::TestTurns => "test turns",
    }
}

/// The page's style: A4 pages, compact tables, two columns of plots.
const CSS: &str = "@page{size:A4;margin:9mm 9mm 11mm}.top{display:flex;justify-content:space-between;gap:6mm}.lab{text-align:right}body{font:8.5pt/1.25 sans-serif;margin:0;color:#111}\
h1{font-size:13pt;margin:0 0 3px}h2{font-size:9.5pt;margin:7px 0 3px;border-bottom:1px solid #888}\
table{border-collapse:collapse;width:100%}td,th{border:1px solid #ccc;padding:1px 4px;text-align:right;\
font-variant-numeric:tabular-nums}th{background:#eee;font-weight:600}.l{text-align:left}.id th{width:24%}\
.pass{color:#060}.fail{color:#b00;font-weight:bold}.verdict{font-size:10.5pt;margin:2px 0 5px}\
.small{font-size:7.5pt;margin:1px 0 3px}.cols{display:flex;gap:5mm;align-items:flex-start}.cols>div{flex:1;min-width:0}\
.cols>div.wide{flex:1.6}svg{width:100%;height:auto}.budget td:not(.l){white-space:nowrap}h2{break-after:avoid}tr,.small{break-inside:avoid}";

/// The head rows of a budget whose values the run's registered head stated (the station passes
/// the asset's values to its fit step, which knows no register): named by the asset, as a fit
/// with `--db --head-asset` names them itself.
fn name_head_asset(b: &mut accelcal_core::uncertainty::UncertaintyJson, id: &str, cert: &str) {
    for c in b.contributors.iter_mut().filter(|c| c.name.starts_with("head_")) {
        if c.source.ends_with(", stated") {
            c.source = format!("{} by head asset {id}, certificate {cert}", c.source);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::{css_text, plain};

    #[test]
    fn command_line_wording_is_kept_off_the_page() {
        assert_eq!(plain("default 9.81 m/s² (no --g or --latitude given)"), "default 9.81 m/s²");
        assert_eq!(
            plain("the head's angle setting error (not stated: --head-angle-u); the rest (as stated)"),
            "the head's angle setting error; the rest (as stated)"
        );
        assert_eq!(plain("at most 365 days (--max-interval-days), or less"), "at most 365 days, or less");
        assert_eq!(plain("the campaign's `# g_m_s2:` line"), "the campaign's # g_m_s2: line");
        assert_eq!(plain("an unclosed (paren"), "an unclosed (paren");
    }

    #[test]
    fn text_in_a_css_string_cannot_end_it() {
        assert_eq!(css_text(r#"U-42"; } body { x"#), r#"U-42\"; } body { x"#);
        assert_eq!(css_text("a\\b\nc"), "a\\\\bc");
        assert_eq!(css_text("</style><b>"), "\\3C /style\\3E \\3C b\\3E ");
    }
}
