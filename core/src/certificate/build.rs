//! [`build`]: the certificate document from the run's pieces, laid out as ISO/IEC 17025 §7.8
//! asks: the identification (laboratory, customer, item, condition on receipt, method, dates,
//! place, traceability, environment, decision rule, people), the results with U (§7.8.2.1 j,
//! §7.8.4.1), the as-found and as-left verifications (§7.8.6) and the drift with the recommended
//! recalibration. Engineering material (GMDH, the paper's Table 2, standard errors of the fit)
//! belongs to the technical report, not here. Values follow ILAC-P14 ([`super::round::Ilac`]).
//! No command-line wording reaches the page ([`plain`]).

use accelcal_shared::record::Record;

use super::round::{sig, Ilac};
use super::{
    Block, Certificate, Chart, Column, Equipment, Facts, Field, Paragraph, Parameter, Party, Quantity,
    Section, Series, Span, Style, Table, FORMAT,
};
use crate::conformity::RuleKind;
use crate::document::verify::VerifyReport;
use crate::document::FitDoc;
use crate::ieee1293::{Parameters, G_N, MID_SCALE_CODES};
use crate::output::utc_date_time;
use crate::uncertainty::UncertaintyJson;

const AXES: [&str; 3] = ["x", "y", "z"];

/// Who issues the certificate and for whom (the settings' `[issuer]`).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct IssuerInput {
    /// The laboratory's name.
    pub laboratory: Option<String>,
    /// Its address.
    pub laboratory_address: Option<String>,
    /// Its country, ISO 3166-1 alpha-2, checked by the caller.
    pub laboratory_country: Option<String>,
    /// The customer.
    pub customer: Option<String>,
    /// The customer's address or contact.
    pub customer_address: Option<String>,
    /// When the item was received, `YYYY-MM-DD`.
    pub received: Option<String>,
    /// Where it is calibrated (station and site).
    pub place: Option<String>,
}

/// Local gravity as the fit used it.
#[derive(Clone, Debug, PartialEq)]
pub struct GravityInput {
    /// g, m/s².
    pub g_m_s2: f64,
    /// Where it came from, which gives its uncertainty.
    pub source: crate::campaign::GSource,
}

/// The environment's temperature, read on a registered thermometer the run used.
#[derive(Clone, Debug, PartialEq)]
pub struct EnvironmentInput {
    /// The reading, °C.
    pub celsius: f64,
    /// The thermometer's standard uncertainty of a reading, K, as its certificate states it
    /// (`None`: registered without one).
    pub u_k: Option<f64>,
    /// The thermometer's asset id.
    pub thermometer: String,
    /// Its certificate in force for the run.
    pub certificate: String,
}

/// A registered reference the run used.
#[derive(Clone, Debug, PartialEq)]
pub struct AssetRef {
    /// `head`, `thermometer`, `gravity`.
    pub kind: String,
    /// The asset's id.
    pub id: String,
    /// Its certificate in force.
    pub certificate: String,
}

/// The change of one coefficient since the last calibration.
#[derive(Clone, Debug, PartialEq)]
pub struct TermChange {
    /// The channel (`x`, `y`, `z`).
    pub channel: String,
    /// The term (`1`, `ax`, `ay`, `az`).
    pub term: String,
    /// The change, as an error at 1 g, m/s².
    pub delta_m_s2: f64,
    /// Its standard uncertainty, m/s².
    pub sigma_m_s2: f64,
}

/// The drift since the last calibration and the recommended recalibration (the unit's history).
#[derive(Clone, Debug, PartialEq)]
pub struct DriftInput {
    /// The drift from the last calibration to this one: days between them, and each
    /// coefficient's change.
    pub last: Option<(f64, Vec<TermChange>)>,
    /// The recommended date, Unix seconds.
    pub due_unix_s: Option<i64>,
    /// What set it, in words.
    pub basis: String,
    /// The rule's tolerance at 1 g, m/s².
    pub tolerance_m_s2: f64,
    /// Its coverage factor.
    pub coverage: f64,
    /// Its longest interval, days.
    pub max_interval_days: f64,
}

/// What a certificate is built from: the run's stored pieces, checked to be of one unit by the
/// caller.
pub struct Inputs<'a> {
    /// The certificate's number, when the database gave one.
    pub number: Option<&'a str>,
    /// When it is issued, Unix seconds.
    pub issued_unix_s: i64,
    /// Who issues it, for whom.
    pub issuer: &'a IssuerInput,
    /// The campaign's header lines.
    pub header: &'a [(String, String)],
    /// The campaign's SHA-256.
    pub campaign_sha256: &'a str,
    /// The record written to the node.
    pub record: &'a Record,
    /// Its CRC (hex).
    pub record_crc: &'a str,
    /// Its device id (hex).
    pub device_id: &'a str,
    /// The fit.
    pub fit: &'a FitDoc,
    /// Its budget, with the registered head named where it stated the head's values.
    pub budget: Option<&'a UncertaintyJson>,
    /// The serial number.
    pub serial: &'a str,
    /// Local gravity.
    pub gravity: GravityInput,
    /// The as-left verification.
    pub verify: Option<&'a VerifyReport>,
    /// The as-found verification.
    pub as_found: Option<&'a VerifyReport>,
    /// The registered references the run used.
    pub assets: &'a [AssetRef],
    /// Who operated the run, as registered.
    pub operator: Option<&'a str>,
    /// The unit's drift and recalibration, from the database.
    pub drift: Option<DriftInput>,
    /// The environment's temperature on a registered thermometer, when one was read.
    pub environment: Option<EnvironmentInput>,
    /// The sample sets the campaign lost in transit, when it states the rate to count them by.
    pub transit: Option<crate::campaign::transit::Transit>,
    /// The chain's head at issue.
    pub anchor: Option<&'a str>,
    /// The certificate this one replaces (an amendment), with the reason.
    pub replaces: Option<(&'a str, &'a str)>,
    /// accelcal's version.
    pub software: &'a str,
}

impl Inputs<'_> {
    fn get(&self, k: &str) -> Option<&str> {
        self.header.iter().find(|(key, _)| key == k).map(|(_, v)| v.as_str())
    }
}

fn p(text: impl Into<String>) -> Block {
    Block::Paragraph(Paragraph { spans: vec![Span::plain(text)], small: false })
}

fn small(text: impl Into<String>) -> Block {
    Block::Paragraph(Paragraph { spans: vec![Span::plain(text)], small: true })
}

fn col(head: impl Into<String>, numeric: bool, width: f64) -> Column {
    Column { head: head.into(), numeric, width }
}

fn section(heading: impl Into<String>, blocks: Vec<Block>) -> Section {
    Section { heading: Some(heading.into()), blocks }
}

/// A decision word styled by whether it accepts.
fn decision_span(word: String, pass: bool) -> Span {
    Span::styled(word, if pass { Style::Pass } else { Style::Fail })
}

const REPLACES: &str = "Replaces";
const DATES: &str = "Dates";
const ANCHOR: &str = "Ledger anchor";

fn title(page_no: &str) -> String {
    format!("Calibration certificate {page_no}")
}

fn footer(page_no: &str, serial: &str) -> String {
    format!("Calibration certificate {page_no} — accelerometer triad {serial}")
}

fn replaces_text(number: &str, reason: &str) -> String {
    format!("certificate {number}, which this amendment supersedes: {reason}")
}

fn dates_text(received: Option<&str>, calibrated: Option<&str>, issued: &str) -> String {
    let received = received.map(|d| format!("received {d}; ")).unwrap_or_default();
    format!("{received}calibrated {} (campaign acquired); issued {issued}", calibrated.unwrap_or("-"))
}

/// What an amendment changes ([`amend`]).
#[derive(Clone, Copy, Debug)]
pub struct Amend<'a> {
    /// The amendment's number.
    pub number: &'a str,
    /// The number of the certificate it replaces.
    pub replaces: &'a str,
    /// Why.
    pub reason: &'a str,
    /// When it is issued, Unix seconds.
    pub issued_unix_s: i64,
    /// The hash chain's head at its issue.
    pub anchor: Option<&'a str>,
}

/// The amendment of certificate `doc` (`accelcal amend`): the same results of the same run,
/// under a new number, stating the certificate it replaces and why, issued now. Everything
/// else is stated as `doc` states it.
pub fn amend(doc: &Certificate, a: &Amend<'_>) -> Certificate {
    let page_no = format!("No. {}", a.number);
    let mut out = doc.clone();
    out.number = Some(a.number.to_string());
    out.title = title(&page_no);
    out.footer = footer(&page_no, &doc.facts.serial);
    out.facts.issued = utc_date_time(a.issued_unix_s);
    out.facts.replaces = Some(a.replaces.to_string());
    out.facts.anchor = a.anchor.map(str::to_string).or(out.facts.anchor);
    out.identification.retain(|f| f.label != REPLACES);
    out.identification.insert(0, Field { label: REPLACES.into(), text: replaces_text(a.replaces, a.reason) });
    let dates = dates_text(out.facts.received.as_deref(), out.facts.calibrated.as_deref(), &out.facts.issued);
    for f in &mut out.identification {
        match f.label.as_str() {
            DATES => f.text = dates.clone(),
            ANCHOR => f.text = out.facts.anchor.clone().unwrap_or_default(),
            _ => {}
        }
    }
    out
}

/// The certificate of one unit.
pub fn build(i: &Inputs<'_>) -> Certificate {
    let page_no = i.number.map_or("draft, not numbered".to_string(), |n| format!("No. {n}"));
    let temp = i.verify.map(verification_temperature);
    let method =
        if i.fit.method == "test-turns" { "test turns" } else { "least squares (LSQ) over every position" };
    let plan = i.get("plan").unwrap_or("-");
    let firmware = i.get("firmware").map(str::to_string);
    let issued = utc_date_time(i.issued_unix_s);
    let calibrated = i.get("date").map(str::to_string);
    let g = &i.gravity;

    let mut verdict = match i.verify {
        Some(v) if v.pass && v.decision.is_some() => vec![Span::styled(
            format!(
                "CONFORMS: every position accepted by the decision rule ({}), {}",
                v.specification.as_ref().map_or("", |s| s.rule.name()),
                temp.as_ref().map_or("", |t| t.0.as_str())
            ),
            Style::Pass,
        )],
        Some(v) if v.pass => vec![Span::styled(
            format!(
                "VERIFIED: every position within its tolerance on every axis, {}",
                temp.as_ref().map_or("", |t| t.0.as_str())
            ),
            Style::Pass,
        )],
        Some(v) => vec![Span::styled(
            format!("NOT VERIFIED: {}", v.failure().map_or_else(|| "interrupted".to_string(), |f| f.words())),
            Style::Fail,
        )],
        None => vec![Span::styled("not verified after calibration", Style::Fail)],
    };
    if let Some(d) = i.as_found.and_then(|v| v.decision).filter(|d| d.out_of_tolerance()) {
        verdict.push(Span::plain(" "));
        verdict.push(Span::styled(format!("AS FOUND OUT OF TOLERANCE ({})", d.name()), Style::Fail));
    }

    let party = |name: &Option<String>, address: &Option<String>| {
        name.as_ref().map(|n| Party { name: n.clone(), address: address.clone(), country: None })
    };
    let customer = party(&i.issuer.customer, &i.issuer.customer_address);
    let mut rows: Vec<Field> = Vec::new();
    let mut row = |label: &str, text: String| rows.push(Field { label: label.into(), text });
    if let Some((number, reason)) = i.replaces {
        row(REPLACES, replaces_text(number, reason));
    }
    if let Some(c) = &customer {
        row(
            "Customer",
            match &c.address {
                Some(a) => format!("{}, {a}", c.name),
                None => c.name.clone(),
            },
        );
    }
    row(
        "Item",
        format!(
            "accelerometer triad, serial {}; node device id (MCU) {}, firmware {}",
            i.serial,
            i.device_id,
            firmware.as_deref().unwrap_or("-")
        ),
    );
    row("Condition on receipt", receipt(i.as_found));
    row(
        "Method",
        format!(
            "static calibration in the Earth's gravity on a dividing head (the principle of ISO 16063-16), plan {plan}; \
             output model 4 (u = u0 + k·a per channel) chosen by combinatorial GMDH (regularity criterion, the simplest \
             model within one code of the best); coefficients by {method}; accelcal {}",
            i.software
        ),
    );
    let rec = i.record;
    row(
        "Record",
        format!(
            "CRC {}, created {}, {} ({} bytes, format {})",
            i.record_crc,
            utc_date_time(i64::try_from(rec.created_unix_s).unwrap_or(i64::MAX)),
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
    );
    row(DATES, dates_text(i.issuer.received.as_deref(), calibrated.as_deref(), &issued));
    if let Some(place) = &i.issuer.place {
        row("Place of calibration", place.clone());
    }
    row("g (local gravity)", {
        let (u, why) = g.source.standard_u(g.g_m_s2);
        let value = match Ilac::of(g.g_m_s2, 2.0 * u) {
            Some(r) => format!("{} ± {} m/s² (U, k = 2)", r.value(false), r.u()),
            None => format!("{} m/s²", g.g_m_s2),
        };
        format!("{value}: {}; {why}", plain(&g.source.words()))
    });
    let head = match i.assets.iter().find(|a| a.kind == "head") {
        Some(a) => format!("dividing head {}, calibration certificate {}", a.id, a.certificate),
        None => "the dividing head is not a registered asset: its angles are traceable only as stated in the budget"
            .into(),
    };
    let others: String = i
        .assets
        .iter()
        .filter(|a| a.kind != "head")
        .map(|a| format!("; {} {}, calibration certificate {}", a.kind, a.id, a.certificate))
        .collect();
    row("Traceability", format!("g from {}; {head}{others}", plain(&g.source.words())));
    let node =
        temp.as_ref().map_or("temperature not measured (no verification after calibration)".into(), |t| {
            format!("verified {}", t.0)
        });
    row(
        "Environment",
        match &i.environment {
            Some(e) => format!("{}; {node}", environment_text(e)),
            None => node,
        },
    );
    let rule = decision_rule(i.verify);
    row("Decision rule", rule.clone());
    row(
        "Campaign",
        // No file path: where the operator kept the campaign is not the customer's business; its
        // SHA-256 identifies it.
        format!(
            "plan {plan}, {} sets per position{}; SHA-256 {}",
            i.get("samples").unwrap_or("-"),
            i.transit.map(|t| format!("; {}", t.words())).unwrap_or_default(),
            &i.campaign_sha256[..16.min(i.campaign_sha256.len())]
        ),
    );
    if let Some(op) = i.operator {
        row("Calibrated by", op.to_string());
    }
    // The hash chain's head at issue, kept outside the database by every copy of this page:
    // `db verify --anchors CERTIFICATE` finds a database cut short or rewritten behind it.
    if let Some(a) = i.anchor {
        row(ANCHOR, a.to_string());
    }

    let (results, u_axis, parameters) = results(rec, i.fit, i.budget);
    let mut sections = results;
    sections.push(Section {
        heading: None,
        blocks: vec![small(
            "The results relate only to the item calibrated. This certificate shall not be reproduced except in full \
             without the laboratory's written approval. The expanded uncertainty is the standard uncertainty multiplied by \
             the coverage factor k, evaluated after the GUM (JCGM 100:2008) by a method validated by Monte Carlo \
             simulation after JCGM 101:2008.",
        )],
    });
    if let Some(v) = i.as_found {
        sections.push(as_found(v));
    }
    if let Some(v) = i.verify {
        sections.push(as_left(v, temp.as_ref().map_or("", |t| t.0.as_str())));
    }
    let due = i.drift.as_ref().and_then(|d| d.due_unix_s).map(|t| utc_date_time(t)[..10].to_string());
    if let Some(d) = &i.drift {
        sections.push(drift(d, due.as_deref()));
    }

    let mut equipment: Vec<Equipment> = i
        .assets
        .iter()
        .map(|a| Equipment { kind: a.kind.clone(), id: a.id.clone(), certificate: a.certificate.clone() })
        .collect();
    equipment.sort_by(|a, b| (a.kind.as_str(), a.id.as_str()).cmp(&(b.kind.as_str(), b.id.as_str())));
    let facts = Facts {
        serial: i.serial.to_string(),
        device_id: i.device_id.to_string(),
        firmware,
        record_crc: i.record_crc.to_string(),
        campaign_sha256: i.campaign_sha256.to_string(),
        customer,
        received: i.issuer.received.clone(),
        place: i.issuer.place.clone(),
        calibrated,
        issued,
        operator: i.operator.map(str::to_string),
        method: method.to_string(),
        software: i.software.to_string(),
        gravity: Quantity {
            value: g.g_m_s2,
            u: Some(2.0 * g.source.standard_u(g.g_m_s2).0),
            k: Some(2.0),
            unit: "m/s²".into(),
        },
        temperature: match &i.environment {
            Some(e) => Some(Quantity {
                value: e.celsius,
                u: e.u_k.map(|u| 2.0 * u),
                k: e.u_k.map(|_| 2.0),
                unit: "°C".into(),
            }),
            None => temp.as_ref().map(|t| Quantity { value: t.1, u: None, k: None, unit: "°C".into() }),
        },
        temperature_source: match &i.environment {
            Some(e) => {
                Some(format!("thermometer {}, calibration certificate {}", e.thermometer, e.certificate))
            }
            None => temp.as_ref().map(|_| "the node's own sensor, not a traceable thermometer".into()),
        },
        u_axis,
        coefficients: rec
            .coefficients
            .iter()
            .take(rec.n_channels as usize)
            .map(|r| r[..4].to_vec())
            .collect(),
        parameters,
        decision: i.verify.and_then(|v| v.decision).map(|d| d.name().to_string()),
        decision_rule: rule,
        equipment,
        recalibration_due: due,
        anchor: i.anchor.map(str::to_string),
        replaces: i.replaces.map(|(n, _)| n.to_string()),
    };
    Certificate {
        format: FORMAT,
        number: i.number.map(str::to_string),
        title: title(&page_no),
        subtitle: format!("Accelerometer triad {}", i.serial),
        footer: footer(&page_no, i.serial),
        laboratory: party(&i.issuer.laboratory, &i.issuer.laboratory_address)
            .map(|p| Party { country: i.issuer.laboratory_country.clone(), ..p }),
        verdict,
        identification: rows,
        sections,
        facts,
    }
}

/// The covariance of the model-4 coefficients of channels x, y, z × terms 1, ax, ay, az, and its
/// coverage factor: the budget's, else the fit's standard errors alone (diagonal, k = 2).
struct Cov {
    m: [[f64; 12]; 12],
    k: f64,
    from_budget: bool,
}

impl Cov {
    fn of(fit: &FitDoc, budget: Option<&UncertaintyJson>) -> Cov {
        let mut m = [[0.0; 12]; 12];
        if let Some(b) =
            budget.filter(|b| b.covariance.len() == 12 && b.covariance.iter().all(|r| r.len() == 12))
        {
            for (i, row) in b.covariance.iter().enumerate() {
                m[i].copy_from_slice(row);
            }
            return Cov { m, k: b.k, from_budget: true };
        }
        for c in 0..3 {
            let ch = fit.channels.get(c);
            for (t, term) in ["1", "ax", "ay", "az"].iter().enumerate() {
                let at = ch.and_then(|ch| ch.term_index(term));
                let se = at.and_then(|i| ch?.std_errors.get(i).copied().flatten()).unwrap_or(f64::NAN);
                m[4 * c + t][4 * c + t] = se * se;
            }
        }
        Cov { m, k: 2.0, from_budget: false }
    }

    /// The expanded uncertainty of `f` whose gradient over the 12 coefficients is `grad`.
    fn expanded(&self, grad: &[(usize, f64)]) -> f64 {
        let mut v = 0.0;
        for &(i, gi) in grad {
            for &(j, gj) in grad {
                v += gi * self.m[i][j] * gj;
            }
        }
        self.k * v.max(0.0).sqrt()
    }
}

/// `v ± U` as ILAC-P14 asks; the value alone, to four significant digits, when U is not known.
fn stated(v: f64, u: f64, signed: bool) -> String {
    match Ilac::of(v, u) {
        Some(r) => format!("{} ± {}", r.value(signed), r.u()),
        None if signed && v >= 0.0 => format!("+{}", sig(v, 4)),
        None => sig(v, 4),
    }
}

/// The results: U per axis, the IEEE 1293 parameters with their U, the budget; and the same as
/// numbers.
fn results(
    rec: &Record,
    fit: &FitDoc,
    budget: Option<&UncertaintyJson>,
) -> (Vec<Section>, Option<[Quantity; 3]>, Vec<Parameter>) {
    let cov = Cov::of(fit, budget);
    let k = cov.k;
    let mut blocks = Vec::new();
    let heading;
    let u_axis = match budget {
        Some(b) => {
            heading = format!(
                "Results: expanded uncertainty U (k = {k}, about 95 % coverage) of the calibrated acceleration, the \
                 largest over the orientations at 1 g"
            );
            let mut columns = vec![col("", false, 1.4)];
            columns.extend(AXES.iter().map(|a| col(format!("axis {a}"), true, 1.0)));
            let line = |label: &str, f: &dyn Fn(f64) -> String| {
                let mut r = vec![Span::plain(label)];
                r.extend(b.u_m_s2.iter().map(|&u| Span::plain(f(u))));
                r
            };
            blocks.push(Block::Table(Table {
                columns,
                rows: vec![line("U, m/s²", &|u| sig(u, 2)), line("U, mg", &|u| sig(u / G_N * 1e3, 2))],
            }));
            Some(b.u_m_s2.map(|u| Quantity { value: u, u: None, k: Some(k), unit: "m/s²".into() }))
        }
        None => {
            heading = "Results".to_string();
            blocks.push(p(
                "The expanded uncertainty of the calibrated acceleration is not evaluated: its budget is made for a \
                 least-squares fit of model 4, and this record was fitted otherwise. The coefficients' uncertainties \
                 below are those of the fit's noise alone (k = 2).",
            ));
            None
        }
    };
    let mut columns = vec![
        col("channel", false, 0.7),
        col("bias K0, mg ± U", true, 1.3),
        col("scale factor K1, codes/g ± U", true, 1.5),
    ];
    columns.extend(AXES.iter().map(|a| col(format!("misalignment δ toward {a}, µrad ± U"), true, 1.4)));
    let mut rows = Vec::new();
    let mut params = Vec::new();
    for c in 0..3.min(rec.n_channels as usize) {
        let row = &rec.coefficients[c];
        let kc = row[c + 1];
        let (i0, ik) = (4 * c, 4 * c + c + 1);
        let b = row[0] - MID_SCALE_CODES;
        let pr = Parameters::of(c, [row[0], row[1], row[2], row[3]]);
        let u_k0 = cov.expanded(&[(i0, 1.0 / kc), (ik, -b / (kc * kc))]) / G_N * 1e3;
        let u_k1 = cov.expanded(&[(ik, G_N)]);
        let q = |value: f64, u: f64, unit: &str| Quantity {
            value,
            u: u.is_finite().then_some(u),
            k: u.is_finite().then_some(k),
            unit: unit.into(),
        };
        params.push(Parameter {
            channel: AXES[c].into(),
            name: "bias_k0".into(),
            quantity: q(pr.k0_mg, u_k0, "mg"),
        });
        params.push(Parameter {
            channel: AXES[c].into(),
            name: "scale_factor_k1".into(),
            quantity: q(pr.k1_codes_per_g, u_k1, "codes/g"),
        });
        let mut cells = vec![
            Span::plain(AXES[c]),
            Span::plain(stated(pr.k0_mg, u_k0, true)),
            Span::plain(stated(pr.k1_codes_per_g, u_k1, false)),
        ];
        for j in 0..3 {
            if j == c {
                cells.push(Span::plain("—"));
                continue;
            }
            let kj = row[j + 1];
            let d = pr.delta_urad[j];
            let u_d = cov.expanded(&[(4 * c + j + 1, 1.0 / kc), (ik, -kj / (kc * kc))]) * 1e6;
            params.push(Parameter {
                channel: AXES[c].into(),
                name: format!("misalignment_toward_{}", AXES[j]),
                quantity: q(d, u_d, "µrad"),
            });
            cells.push(Span::plain(stated(d, u_d, true)));
        }
        rows.push(cells);
    }
    blocks.push(Block::Table(Table { columns, rows }));
    blocks.push(small(format!(
        "IEEE Std 1293 names for the record's model 4 (u = u0 + k·a per channel, codes): K1 = k along the channel's own \
         axis, per g (gn = {G_N} m/s²); K0 = (u0 − {MID_SCALE_CODES:.0}) / K1, the input at which the output is the \
         converter's mid-scale; δ = k toward another axis / k along its own. Values are rounded to the last digit of \
         their U, which has two significant digits (ILAC-P14). {}",
        if cov.from_budget {
            "Their U comes from the budget's combined covariance."
        } else {
            "Their U comes from the fit's standard errors alone."
        }
    )));
    let mut out = vec![section(heading, blocks)];
    if let Some(b) = budget {
        out.push(budget_section(b));
    }
    (out, u_axis, params)
}

/// The budget: each contributor's standard uncertainty of the calibrated acceleration and its
/// share of the combined variance, and what it leaves out.
fn budget_section(b: &UncertaintyJson) -> Section {
    let columns = vec![
        col("uncertainty contributor", false, 2.2),
        col("type", true, 0.5),
        col("u, m/s²", true, 0.9),
        col("share, %", true, 0.7),
        col("from", false, 3.6),
    ];
    let mut rows: Vec<Vec<Span>> = b
        .contributors
        .iter()
        .map(|c| {
            vec![
                Span::plain(contributor_words(&c.name)),
                Span::plain(c.kind.clone()),
                Span::plain(sig(c.u_m_s2, 2)),
                Span::plain(format!("{:.1}", 100.0 * c.share)),
                Span::plain(plain(&c.source)),
            ]
        })
        .collect();
    // The sum, where the contributors are taken where U is stated: √Σu² and k·√Σu² = U.
    let stated = b.stated_at.as_ref().and_then(|s| {
        let i = AXES.iter().position(|a| *a == s.axis)?;
        Some((s, b.u_m_s2[i]))
    });
    if let Some((_, u_axis)) = stated {
        let uc = b.contributors.iter().map(|c| c.u_m_s2 * c.u_m_s2).sum::<f64>().sqrt();
        rows.push(vec![
            Span::styled("combined standard uncertainty u_c = √Σu²", Style::Strong),
            Span::plain(""),
            Span::styled(sig(uc, 2), Style::Strong),
            Span::plain("100.0"),
            Span::plain(""),
        ]);
        let p = b
            .coverage_probability
            .map_or(String::new(), |p| format!(", coverage probability {:.1} %", 100.0 * p));
        rows.push(vec![
            Span::styled(format!("expanded uncertainty U = k·u_c, k = {}", b.k), Style::Strong),
            Span::plain(""),
            Span::styled(sig(u_axis, 2), Style::Strong),
            Span::plain(""),
            Span::plain(format!("the U stated for this axis{p}")),
        ]);
    }
    let mut blocks = vec![Block::Table(Table { columns, rows })];
    if !b.not_included.is_empty() {
        let words: Vec<String> = b.not_included.iter().map(|n| plain(n)).collect();
        blocks.push(small(format!("Not included in U: {}.", words.join("; "))));
    }
    let heading = match stated {
        Some((s, _)) => format!(
            "Uncertainty budget of the calibrated acceleration along {} at ({}) m/s², the orientation at 1 g where U is \
             largest",
            s.axis,
            s.acceleration_m_s2.iter().map(|v| format!("{v:+.2}")).collect::<Vec<_>>().join(", ")
        ),
        None => "Uncertainty budget of the calibrated acceleration (each contributor at its own worst axis and \
                 orientation; shares averaged over the orientations)"
            .to_string(),
    };
    section(heading, blocks)
}

/// A contributor's name in words.
fn contributor_words(name: &str) -> String {
    match name {
        "dwell_scatter" => "scatter of the dwell means (repeatability)".into(),
        "head_angle" => "dividing head: angle setting".into(),
        "head_orthogonality" => "dividing head: axis orthogonality".into(),
        "gravity" => "local gravity g".into(),
        "quantisation" => "ADC quantisation".into(),
        "temperature" => "temperature against the reference temperature".into(),
        "lack_of_fit" => "model 4's lack of fit (against the quadratic model)".into(),
        other => other.replace('_', " "),
    }
}

/// The unit's condition on receipt: its as-found verification.
fn receipt(v: Option<&VerifyReport>) -> String {
    let Some(v) = v else {
        return "no calibration record in force, or not verified as found".into();
    };
    let crc = v.record["crc"].as_str().unwrap_or("(none)");
    let max = v.max_abs_error_m_s2();
    let outcome = match v.decision {
        Some(d) if d.out_of_tolerance() => format!("OUT OF TOLERANCE ({})", d.name()),
        Some(d) => d.name().to_string(),
        None if v.pass => "within the consistency bound".into(),
        None => "outside the consistency bound".into(),
    };
    format!("verified as found with its record in force (CRC {crc}): {outcome}, largest error {max:.4} m/s²")
}

/// The decision rule and the statement of conformity it supports (ILAC-G8).
fn decision_rule(v: Option<&VerifyReport>) -> String {
    match v.and_then(|v| v.specification.as_ref().map(|s| (v, s))) {
        Some((v, s)) => {
            let w = match s.guard_band_m_s2 {
                Some(w) => format!("guard band w = {w} m/s²"),
                None => "guard band w = U of each result".into(),
            };
            let rule = match s.rule {
                RuleKind::Simple => {
                    "simple acceptance (ILAC-G8 §4.2.1): accepted when the error is within the limit".to_string()
                }
                RuleKind::GuardBand => format!(
                    "guard band (ILAC-G8 §4.2.2): accepted when the error is within the limit less the guard band, {w}"
                ),
            };
            let params = match s.describe_parameters() {
                p if p.is_empty() => String::new(),
                p => format!(" and {p} (from the ±axis positions; the guard band for these is U)"),
            };
            format!(
                "specification of {}: |error| ≤ T = {} m/s² on each component at each position{params}; {rule}; \
                 conformity: {}",
                s.unit_type,
                s.acceleration_error_m_s2,
                v.decision.map_or("-", |d| d.name())
            )
        }
        None => "no specification: the verification is a consistency check of the calibration, not a statement of \
                 conformity"
            .into(),
    }
}

/// The environment's temperature as read on its registered thermometer, with U (k = 2) by
/// ILAC-P14 when the thermometer's certificate states its uncertainty.
fn environment_text(e: &EnvironmentInput) -> String {
    let value = match e.u_k.and_then(|u| Ilac::of(e.celsius, 2.0 * u)) {
        Some(r) => format!("{} ± {} °C (U, k = 2)", r.value(false), r.u()),
        None => format!("{:.1} °C (the thermometer's certificate states no uncertainty)", e.celsius),
    };
    format!("{value}, read on thermometer {}, calibration certificate {}", e.thermometer, e.certificate)
}

/// The temperature of a verification in words, and the node's mean over the positions.
fn verification_temperature(v: &VerifyReport) -> (String, f64) {
    let temps: Vec<f64> = v.positions.iter().filter_map(|p| p.temp_c).collect();
    let chamber = v.chamber_c.map(|c| format!(", chamber set to {c} °C")).unwrap_or_default();
    if temps.is_empty() {
        return (format!("temperature not reported by the node{chamber}"), f64::NAN);
    }
    let mean = temps.iter().sum::<f64>() / temps.len() as f64;
    let (lo, hi) = temps.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &t| (l.min(t), h.max(t)));
    (
        format!(
            "at {mean:.1} °C (the unit's own sensor, not a traceable thermometer; {lo:.1} to {hi:.1} °C over the \
             positions{chamber})"
        ),
        mean,
    )
}

/// The as-found verification: the record the unit came in with, its decision and, against a
/// specification, each position.
fn as_found(v: &VerifyReport) -> Section {
    let failed = v.positions.iter().filter(|p| !p.pass).count();
    let max = v.max_abs_error_m_s2();
    let crc = v.record["crc"].as_str().unwrap_or("(none)");
    let n = v.positions.len();
    let (word, rest) = match v.decision {
        Some(d) if d.accepted() => (
            decision_span("PASS".into(), true),
            format!(": every one of {n} positions accepted by the decision rule"),
        ),
        Some(d) if d.out_of_tolerance() => (
            decision_span(format!("OUT OF TOLERANCE ({})", d.name()), false),
            format!(": {failed} of {n} positions not accepted"),
        ),
        Some(d) => (
            decision_span(d.name().to_uppercase(), false),
            format!(": {failed} of {n} positions within the limit but not by the guard band"),
        ),
        None if v.pass => {
            (decision_span("PASS".into(), true), format!(": every one of {n} positions within its tolerance"))
        }
        None => {
            (decision_span("FAIL".into(), false), format!(": {failed} of {n} positions outside tolerance"))
        }
    };
    let rule = if v.specification.is_some() { "specification" } else { "pass" };
    let mut blocks = vec![Block::Paragraph(Paragraph {
        spans: vec![
            word,
            Span::plain(format!("{rest}; largest error {max:.5} m/s²; {rule}: {}", plain(&v.tolerance_rule))),
        ],
        small: false,
    })];
    if v.specification.is_some() {
        blocks.extend(position_tables(v));
    }
    section(format!("As found (before recalibration), with the record in force then (CRC {crc})"), blocks)
}

/// The as-left verification: each position's error and tolerance per axis, and the chart.
fn as_left(v: &VerifyReport, temp: &str) -> Section {
    let rule = if v.specification.is_some() { "Specification" } else { "Pass" };
    let mut blocks = vec![small(format!("{rule}: {}", plain(&v.tolerance_rule)))];
    blocks.extend(position_tables(v));
    blocks.push(Block::Chart(Chart {
        title: "Verification error per position".into(),
        x_label: "position".into(),
        y_label: "error, m/s²".into(),
        series: AXES
            .iter()
            .enumerate()
            .map(|(i, n)| Series {
                name: format!("error {n}"),
                points: v.positions.iter().map(|p| (p.position as f64, p.error_m_s2[i])).collect(),
            })
            .collect(),
    }));
    section(
        format!("As left: verification on the head after flashing, {temp}: error of the calibrated output"),
        blocks,
    )
}

/// A verification's positions (error per axis and, against a specification, U of each and the
/// decision; else the consistency bound), and its parameters when the specification limits them.
fn position_tables(v: &VerifyReport) -> Vec<Block> {
    let bound = if v.specification.is_some() { "U" } else { "tolerance" };
    let mut columns = vec![col("position", true, 0.8), col("α, β, °", true, 1.1)];
    columns.extend(AXES.iter().map(|a| col(format!("error {a}, m/s²"), true, 1.1)));
    columns.extend(AXES.iter().map(|a| col(format!("{bound} {a}, m/s²"), true, 1.1)));
    columns.push(col("decision", false, 1.3));
    let rows = v
        .positions
        .iter()
        .map(|p| {
            let t = p.u_expanded_m_s2.unwrap_or(p.tolerance_m_s2);
            let word = match p.decisions.and_then(|d| d.into_iter().max()) {
                Some(d) if d.accepted() => d.name().to_string(),
                Some(d) => d.name().to_uppercase(),
                None if p.pass => "pass".into(),
                None => "FAIL".into(),
            };
            let mut r = vec![
                Span::plain(p.position.to_string()),
                Span::plain(format!("{}, {}", p.alpha_deg, p.beta_deg)),
            ];
            r.extend(p.error_m_s2.iter().map(|e| Span::plain(format!("{e:+.5}"))));
            r.extend(t.iter().map(|t| Span::plain(format!("{t:.5}"))));
            r.push(decision_span(word, p.pass));
            r
        })
        .collect();
    let mut out = vec![Block::Table(Table { columns, rows })];
    if let Some(params) = v.parameters.as_ref().filter(|p| !p.is_empty()) {
        let columns = vec![
            col("parameter (from the ±axis positions)", false, 2.0),
            col("axis", false, 0.6),
            col("error", true, 1.1),
            col("U", true, 1.1),
            col("limit", true, 1.1),
            col("decision", false, 1.2),
        ];
        let rows = params
            .iter()
            .map(|c| {
                let word = if c.decision.accepted() {
                    c.decision.name().to_string()
                } else {
                    c.decision.name().to_uppercase()
                };
                // ILAC-P14: U to two significant digits, the value to U's last digit; each cell
                // says its unit, which differs from row to row.
                let unit = &c.unit;
                let (value, u) = match Ilac::of(c.value, c.u_expanded) {
                    Some(r) => (r.value(true), r.u()),
                    None => (format!("{:+}", c.value), format!("{}", c.u_expanded)),
                };
                vec![
                    Span::plain(c.parameter.replace('_', " ")),
                    Span::plain(c.axis.clone()),
                    Span::plain(format!("{value} {unit}")),
                    Span::plain(format!("{u} {unit}")),
                    Span::plain(format!("{} {unit}", c.limit)),
                    decision_span(word, c.decision.accepted()),
                ]
            })
            .collect();
        out.push(Block::Table(Table { columns, rows }));
    }
    out
}

/// The drift of the coefficients since the unit's last calibration, and the recommended
/// recalibration date.
fn drift(d: &DriftInput, due: Option<&str>) -> Section {
    let mut blocks = Vec::new();
    let heading = match &d.last {
        Some((days, terms)) => {
            let mut columns = vec![col("channel", false, 0.8)];
            columns
                .extend(["bias", "ax", "ay", "az"].iter().map(|t| col(format!("{t}, m/s² ± u"), true, 1.3)));
            let rows = AXES
                .iter()
                .map(|ch| {
                    let mut r = vec![Span::plain(*ch)];
                    r.extend(terms.iter().filter(|t| t.channel == *ch).map(|t| {
                        Span::plain(format!("{} ± {}", sig(t.delta_m_s2, 3), sig(t.sigma_m_s2, 2)))
                    }));
                    r
                })
                .collect();
            blocks.push(Block::Table(Table { columns, rows }));
            format!(
                "Drift since the last calibration ({days:.0} days ago): change of each coefficient as an error at 1 g, \
                 with its standard uncertainty"
            )
        }
        None => {
            blocks.push(p("First calibration of this unit in the database: no drift yet."));
            "Drift since the last calibration".to_string()
        }
    };
    blocks.push(Block::Paragraph(Paragraph {
        spans: vec![
            Span::plain("Recommended recalibration by "),
            Span::styled(due.unwrap_or("-"), Style::Strong),
            Span::plain(format!(": {}.", plain(&d.basis))),
        ],
        small: false,
    }));
    section(heading, blocks)
}

/// Text for the page without the tool's command-line wording: a parenthesis that names an
/// option (`(not stated: --head-angle-u)`) is left out, and a remaining `--option` loses its
/// dashes.
pub fn plain(s: &str) -> String {
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
    out.replace(" --", " ").replace('`', "")
}

#[cfg(test)]
mod tests {
    use super::plain;

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
}
