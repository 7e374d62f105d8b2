//! `accelcal report`: the calibration certificate of one unit, a self-contained HTML page (plots
//! inline) that prints on one A4 page.
//!
//! Everything on it is computed here from the unit's files, so that the page cannot disagree with
//! them: the campaign (its `acquire` header: serial, device id, firmware, g, plan, date), the
//! record written to the node (device id, CRC, coefficients), the model selection (GMDH over the
//! paper's 11 models, regularity criterion, alternate split, 1-code tolerance: what `demo` runs),
//! the LSQ fit with its standard errors, Table 2 (LSQ against test turns) and the verification
//! (`verify --json`).

use std::fmt::Write as _;

use accelcal_core::calibrate::{fit_positions, Method};
use accelcal_core::campaign::Campaign;
use accelcal_core::error::bad;
use accelcal_core::output::write_atomic;
use accelcal_core::positions::Positions;
use accelcal_core::verify::VerifyReport;
use accelcal_shared::record::{crc32, Record};

use crate::cli::ReportArgs;
use crate::report::plot::lines_svg;

/// HTML-escapes text.
fn esc(s: &str) -> String {
    s.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;").replace('"', "&quot;")
}

/// Runs `accelcal report`.
pub fn run(a: &ReportArgs) -> anyhow::Result<()> {
    let header = accelcal_core::campaign::header(&a.campaign)?;
    let get = |k: &str| header.iter().find(|(key, _)| key == k).map(|(_, v)| v.clone());
    let rec_bytes = std::fs::read(&a.record)
        .map_err(|e| bad(format!("{}: cannot read the record: {e}", a.record.display())))?;
    let rec = Record::parse(&rec_bytes).map_err(|e| bad(format!("{}: {e}", a.record.display())))?;
    let crc = crc32(&rec_bytes[..rec.len() - 4]);
    let device_id = accelcal_core::node::session::device_id_hex(&rec.device_id);
    if let Some(d) = get("device_id") {
        if d != device_id {
            return Err(bad(format!(
                "{} is for device {device_id}, the campaign {} was acquired from {d}: not the same unit",
                a.record.display(),
                a.campaign.display()
            )));
        }
    }
    let verify: Option<VerifyReport> = match &a.verify {
        Some(p) => {
            let text =
                std::fs::read_to_string(p).map_err(|e| bad(format!("{}: cannot read: {e}", p.display())))?;
            let v: VerifyReport = serde_json::from_str(&text)
                .map_err(|e| bad(format!("{}: not `accelcal verify --json` output: {e}", p.display())))?;
            if v.device_id != device_id {
                return Err(bad(format!(
                    "{}: verified device {}, the record is for {device_id}",
                    p.display(),
                    v.device_id
                )));
            }
            let v_crc = v.record["crc"].as_str().unwrap_or("");
            if v_crc != format!("{crc:08x}") {
                return Err(bad(format!(
                    "{}: the node ran record CRC {v_crc} during verification, {} has CRC {crc:08x}",
                    p.display(),
                    a.record.display()
                )));
            }
            Some(v)
        }
        None => None,
    };
    let (g, g_source) = match (a.g, get("g_m_s2").and_then(|v| v.parse::<f64>().ok())) {
        (Some(g), _) => (g, "--g".to_string()),
        (None, Some(g)) => (g, format!("the campaign's ({})", get("g_source").unwrap_or_default())),
        (None, None) => {
            eprintln!(
                "note: {}",
                super::g_fallback(&format!(
                    "{} does not state its gravity (`# g_m_s2:`) and --g was not given",
                    a.campaign.display()
                ))
            );
            (accelcal_shared::G_STANDARD, "default 9.81 m/s² (not stated by the campaign)".into())
        }
    };
    let campaign = Campaign::read(&a.campaign)?;
    // The positions at the record's reference temperature; a thermal record's structure is
    // chosen among the linear-thermal candidates, and its coefficients are those of its terms.
    let mut pos = Positions::new(&campaign, g);
    if let Some(t) = rec.thermal {
        pos.t_ref_c = t.t_ref_c as f64;
    }
    let stats = pos.channel_stats(&campaign);
    let mut settings = super::select::paper_settings();
    if rec.structure.is_thermal() {
        settings.basis = accelcal_shared::Basis::LinearThermal;
    }
    let sel = super::select::compute_on(&pos, &stats, &[], &settings)?;
    let lsq = fit_positions(&pos, &stats, Method::Lsq, rec.structure)?;
    let cmp = accelcal_core::compare::compute(&campaign, None, g).ok();

    let mut h = String::new();
    let serial = get("serial").unwrap_or_else(|| "-".into());
    let now = super::record::utc(super::created(None));
    let _ = write!(
        h,
        "<!doctype html><html lang=\"en\"><head><meta charset=\"utf-8\"><title>Calibration certificate {}</title><style>{CSS}</style></head><body>",
        esc(&serial)
    );
    let _ = write!(h, "<h1>Calibration certificate &mdash; accelerometer triad {}</h1>", esc(&serial));
    let verdict = match &verify {
        Some(v) if v.pass => {
            "<span class=\"pass\">VERIFIED: every position within tolerance</span>".to_string()
        }
        Some(v) => format!(
            "<span class=\"fail\">NOT VERIFIED: {} of {} positions outside tolerance</span>",
            v.positions.iter().filter(|p| !p.pass).count(),
            v.positions.len()
        ),
        None => "<span class=\"fail\">not verified (no verification given)</span>".into(),
    };
    let _ = write!(h, "<p class=\"verdict\">{verdict}</p><table class=\"id\">");
    let rows = [
        ("Unit serial", serial.clone()),
        ("Device id (MCU)", device_id.clone()),
        ("Firmware", get("firmware").unwrap_or_else(|| "-".into())),
        (
            "Record",
            format!(
                "CRC {crc:08x}, created {}, {} ({} bytes, format {})",
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
                    None => "model 4".to_string(),
                },
                rec.len(),
                rec.version()
            ),
        ),
        ("g used", format!("{g} m/s² ({})", g_source)),
        (
            "Campaign",
            format!(
                "{} &mdash; plan {}, {} sets per position, acquired {}",
                esc(&a.campaign.display().to_string()),
                esc(&get("plan").unwrap_or_else(|| "-".into())),
                esc(&get("samples").unwrap_or_else(|| "-".into())),
                esc(&get("date").unwrap_or_else(|| "-".into()))
            ),
        ),
        ("Issued", format!("{now} by accelcal {}", env!("CARGO_PKG_VERSION"))),
    ];
    for (k, v) in rows {
        let v = if k == "Campaign" { v } else { esc(&v) };
        let _ = write!(h, "<tr><th class=\"l\">{k}</th><td class=\"l\">{v}</td></tr>");
    }
    h.push_str("</table>");

    // Model structure.
    h.push_str("<h2>Model structure (combinatorial GMDH, regularity criterion, 1-code tolerance)</h2><table><tr><th class=\"l\">channel</th><th class=\"l\">selected terms</th><th>criterion, codes</th><th>best, codes</th><th class=\"l\">why</th></tr>");
    for s in &sel {
        let c = s.selected();
        let best = s
            .candidates
            .iter()
            .filter(|c| c.criterion.is_some())
            .min_by(|a, b| a.criterion.partial_cmp(&b.criterion).expect("finite criteria"))
            .expect("a selection has an identifiable candidate");
        let why = if c.structure == best.structure {
            "the best candidate".to_string()
        } else {
            format!("simplest within 1 code of the best ({})", best.structure)
        };
        let _ = write!(
            h,
            "<tr><td class=\"l\">{}</td><td class=\"l\">{}</td><td>{:.2}</td><td>{:.2}</td><td class=\"l\">{}</td></tr>",
            esc(&s.channel),
            c.structure,
            c.criterion.unwrap_or(f64::NAN),
            s.best,
            esc(&why)
        );
    }
    h.push_str("</table>");

    // Coefficients.
    let _ = write!(h, "<h2>Coefficients in force (record), &plusmn; standard error of the LSQ fit of this campaign</h2><table><tr><th class=\"l\">channel</th>");
    for (i, t) in rec.structure.terms().enumerate() {
        let head = match (i, t.to_string().as_str()) {
            (0, _) => "u0, codes".to_string(),
            (1, _) => "k·ax, codes/(m/s²)".to_string(),
            (2, _) => "k·ay".to_string(),
            (3, _) => "k·az".to_string(),
            (_, "t") => "t, codes/°C".to_string(),
            (_, "t^2") => "t², codes/°C²".to_string(),
            (_, name) => format!("{name}, codes/(m/s²)/°C"),
        };
        let _ = write!(h, "<th>{}</th>", esc(&head));
    }
    h.push_str("<th>residual RMS, codes</th></tr>");
    let mut max_rel = 0.0f64;
    for (c, (name, fit)) in lsq.iter().enumerate() {
        let _ = write!(h, "<tr><td class=\"l\">{}</td>", esc(name));
        let se = fit.std_errors();
        for t in 0..rec.structure.len() {
            let v = rec.coefficients.get(c).map_or(f64::NAN, |row| row[t]);
            max_rel = max_rel.max(((v - fit.coefficients[t]) / se[t].max(1e-12)).abs());
            let _ = write!(h, "<td>{v:.4} &plusmn; {:.4}</td>", se[t]);
        }
        let _ = write!(h, "<td>{:.2}</td></tr>", fit.rms);
    }
    h.push_str("</table>");
    if max_rel > 1.0 {
        let _ = write!(
            h,
            "<p class=\"fail\">The record differs from this campaign's LSQ fit by up to {max_rel:.1} standard errors: it was not fitted by LSQ from this campaign.</p>"
        );
    }

    // Table 2.
    h.push_str("<div class=\"cols\"><div>");
    match &cmp {
        Some(r) => {
            let _ = write!(h, "<h2>LSQ against test turns (Table 2), m/s², {} held-out positions</h2><table><tr><th class=\"l\">channel</th><th>mean LSQ</th><th>mean TT</th><th>std LSQ</th><th>std TT</th></tr>", r.validation_positions);
            for ch in &r.channels {
                let _ = write!(
                    h,
                    "<tr><td class=\"l\">{}</td><td>{:.5}</td><td>{:.5}</td><td>{:.5}</td><td>{:.5}</td></tr>",
                    esc(&ch.channel),
                    ch.lsq.mean_error,
                    ch.test_turns.mean_error,
                    ch.lsq.std_error,
                    ch.test_turns.std_error
                );
            }
            h.push_str("</table>");
        }
        None => {
            h.push_str("<h2>LSQ against test turns</h2><p>Not computed: the plan has no test-turn pairs.</p>")
        }
    }
    h.push_str("</div><div>");
    h.push_str(&fit_plot(cmp.as_ref())?);
    h.push_str("</div></div>");

    // Verification.
    if let Some(v) = &verify {
        let _ = write!(
            h,
            "<h2>Verification on the head after flashing (g = {} m/s²)</h2><p class=\"small\">{}</p><div class=\"cols\"><div><table><tr><th>pos.</th><th>&alpha;, &beta; (deg)</th><th>error x</th><th>error y</th><th>error z</th><th>tolerance</th><th></th></tr>",
            v.g_m_s2,
            esc(&v.tolerance_rule)
        );
        for p in &v.positions {
            let tol = p.tolerance_m_s2.iter().cloned().fold(0.0, f64::max);
            let _ = write!(
                h,
                "<tr><td>{}</td><td>{}, {}</td><td>{:+.5}</td><td>{:+.5}</td><td>{:+.5}</td><td>{:.5}</td><td class=\"{}\">{}</td></tr>",
                p.position,
                p.alpha_deg,
                p.beta_deg,
                p.error_m_s2[0],
                p.error_m_s2[1],
                p.error_m_s2[2],
                tol,
                if p.pass { "pass" } else { "fail" },
                if p.pass { "pass" } else { "FAIL" }
            );
        }
        h.push_str("</table></div><div>");
        let series: Vec<(String, Vec<(f64, f64)>)> = ["x", "y", "z"]
            .iter()
            .enumerate()
            .map(|(i, n)| {
                (
                    format!("error {n}"),
                    v.positions.iter().map(|p| (p.position as f64, p.error_m_s2[i])).collect(),
                )
            })
            .collect();
        h.push_str(&lines_svg("Verification error per position", "position", "m/s²", &series, (640, 330))?);
        h.push_str("</div></div>");
    }
    h.push_str("</body></html>\n");
    write_atomic(&a.out, h.as_bytes())?;
    println!(
        "report: certificate of unit {serial} (device {device_id}, record CRC {crc:08x}) written to {}",
        a.out.display()
    );
    Ok(())
}

/// The LSQ calibration's error per held-out position (Table 2's data), inline SVG.
fn fit_plot(cmp: Option<&accelcal_core::compare::Comparison>) -> anyhow::Result<String> {
    let Some(r) = cmp else { return Ok(String::new()) };
    let series: Vec<(String, Vec<(f64, f64)>)> = r
        .per_position
        .lsq
        .iter()
        .map(|(n, ys)| (n.clone(), ys.iter().enumerate().map(|(k, &y)| (k as f64 + 1.0, y)).collect()))
        .collect();
    lines_svg("LSQ: error per held-out position", "held-out position", "m/s²", &series, (640, 330))
}

/// The page's style: one A4 page, compact tables, two columns of plots.
const CSS: &str = "@page{size:A4;margin:9mm}body{font:8.5pt/1.25 sans-serif;margin:0;color:#111}\
h1{font-size:13pt;margin:0 0 3px}h2{font-size:9.5pt;margin:7px 0 3px;border-bottom:1px solid #888}\
table{border-collapse:collapse;width:100%}td,th{border:1px solid #ccc;padding:1px 4px;text-align:right;\
font-variant-numeric:tabular-nums}th{background:#eee;font-weight:600}.l{text-align:left}.id th{width:24%}\
.pass{color:#060}.fail{color:#b00;font-weight:bold}.verdict{font-size:10.5pt;margin:2px 0 5px}\
.small{font-size:7.5pt;margin:1px 0 3px}.cols{display:flex;gap:5mm;align-items:flex-start}.cols>div{flex:1;min-width:0}\
svg{width:100%;height:auto}";
