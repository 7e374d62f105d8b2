//! The certificate as a Digital Calibration Certificate: PTB's DCC XML (schema 3.3.0, quantities
//! in D-SI 2.2.1), written with quick-xml's `Writer` (every text and attribute escaped by it).
//! Nothing is computed here beyond spelling units in D-SI syntax: every number is the
//! document's [`Facts`]. The document itself rides along as `dcc:document` (its canonical JSON in
//! base64, `application/json`), so `certificate verify` can check a DCC offline: [`verify`]
//! re-renders the DCC from the attached document and compares the two.
//!
//! What an approval adds is an argument, not part of the document: the signed decision
//! ([`Seal`]), whose signer is written as the main signer among the responsible persons
//! ([`Authoriser`]) and which rides along itself in `dcc:comment` (an element of accelcal's own
//! namespace, [`APPROVAL_NS`], which the schema admits there without validating it), so that
//! `certificate verify` checks the signature offline too. No XML signature (`ds:Signature`)
//! is written: the seal signs the document's SHA-256, which the DCC's rendering is checked
//! against.

use base64::Engine as _;
use quick_xml::events::{BytesDecl, BytesEnd, BytesStart, BytesText, Event};
use quick_xml::Writer;

use accelcal_core::certificate::approval::{Meaning, Seal};
use accelcal_core::certificate::{Certificate, DocumentError, Facts, Quantity};

/// The DCC schema version written (`schemaVersion`).
pub const SCHEMA_VERSION: &str = "3.3.0";
/// Where that schema is published.
pub const SCHEMA_LOCATION: &str = "https://ptb.de/dcc https://ptb.de/dcc/v3.3.0/dcc.xsd";
/// The attached document's file name inside the DCC.
pub const DOCUMENT_FILE: &str = "certificate-document.json";

/// The namespace of the element that carries the signed decision in `dcc:comment`.
pub const APPROVAL_NS: &str = "urn:accelcal:approval:v1";

/// Who approved the certificate for issue, as an approval states it (the main signer).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Authoriser {
    /// The signer's name.
    pub name: String,
    /// Their function.
    pub function: String,
}

/// The DCC of `doc`, with its signed decision when it has one (an approval names its signer as
/// the main signer).
pub fn dcc(doc: &Certificate, seal: Option<&Seal>) -> std::io::Result<Vec<u8>> {
    let authoriser = seal
        .filter(|s| Meaning::parse(&s.meaning) == Some(Meaning::Approved))
        .map(|s| Authoriser { name: s.signer.clone(), function: s.function.clone() });
    let authoriser = authoriser.as_ref();
    let mut x = X { w: Writer::new_with_indent(Vec::new(), b' ', 1) };
    x.w.write_event(Event::Decl(BytesDecl::new("1.0", Some("UTF-8"), None)))?;
    let root = BytesStart::new("dcc:digitalCalibrationCertificate").with_attributes([
        ("xmlns:dcc", "https://ptb.de/dcc"),
        ("xmlns:si", "https://ptb.de/si"),
        ("xmlns:xsi", "http://www.w3.org/2001/XMLSchema-instance"),
        ("xsi:schemaLocation", SCHEMA_LOCATION),
        ("schemaVersion", SCHEMA_VERSION),
    ]);
    x.w.write_event(Event::Start(root))?;
    administrative(&mut x, doc, authoriser)?;
    measurement(&mut x, &doc.facts)?;
    if let Some(seal) = seal {
        let json = serde_json::to_string(seal).map_err(std::io::Error::other)?;
        x.open("dcc:comment")?;
        x.w.write_event(Event::Start(
            BytesStart::new("accelcal:approval")
                .with_attributes([("xmlns:accelcal", APPROVAL_NS), ("mimeType", "application/json")]),
        ))?;
        x.w.write_event(Event::Text(BytesText::new(
            &base64::engine::general_purpose::STANDARD.encode(json),
        )))?;
        x.w.write_event(Event::End(BytesEnd::new("accelcal:approval")))?;
        x.close("dcc:comment")?;
    }
    x.open("dcc:document")?;
    x.text_el("dcc:name", "The certificate document (accelcal's canonical JSON), SHA-256 in coreData")?;
    x.leaf("dcc:fileName", DOCUMENT_FILE)?;
    x.leaf("dcc:mimeType", "application/json")?;
    let b64 = base64::engine::general_purpose::STANDARD.encode(doc.canonical_json());
    x.leaf("dcc:dataBase64", &b64)?;
    x.close("dcc:document")?;
    x.close("dcc:digitalCalibrationCertificate")?;
    let mut out = x.w.into_inner();
    out.push(b'\n');
    Ok(out)
}

/// The writer and the few shapes every element takes.
struct X {
    w: Writer<Vec<u8>>,
}

type R = std::io::Result<()>;

impl X {
    fn open(&mut self, name: &str) -> R {
        self.w.write_event(Event::Start(BytesStart::new(name)))
    }
    fn open_with(&mut self, name: &str, attrs: &[(&str, &str)]) -> R {
        self.w.write_event(Event::Start(BytesStart::new(name).with_attributes(attrs.iter().copied())))
    }
    fn close(&mut self, name: &str) -> R {
        self.w.write_event(Event::End(BytesEnd::new(name)))
    }
    /// `<name>text</name>`, the text escaped.
    fn leaf(&mut self, name: &str, text: &str) -> R {
        self.open(name)?;
        self.w.write_event(Event::Text(BytesText::new(text)))?;
        self.close(name)
    }
    /// A `dcc:textType` element: `<name><dcc:content lang="en">text</dcc:content></name>`.
    fn text_el(&mut self, name: &str, text: &str) -> R {
        self.open(name)?;
        self.open_with("dcc:content", &[("lang", "en")])?;
        self.w.write_event(Event::Text(BytesText::new(text)))?;
        self.close("dcc:content")?;
        self.close(name)
    }
    /// A contact: its name and its location (the address as one line, or "not stated").
    fn contact(&mut self, name: &str, who: &str, address: Option<&str>) -> R {
        self.open(name)?;
        self.text_el("dcc:name", who)?;
        self.open("dcc:location")?;
        self.text_el("dcc:further", address.unwrap_or("not stated"))?;
        self.close("dcc:location")?;
        self.close(name)
    }
    fn identification(&mut self, issuer: &str, value: &str, what: &str) -> R {
        self.open("dcc:identification")?;
        self.leaf("dcc:issuer", issuer)?;
        self.leaf("dcc:value", not_empty(value))?;
        self.text_el("dcc:name", what)?;
        self.close("dcc:identification")
    }
    /// A `dcc:quantity` holding an `si:real`, with its expanded uncertainty when it has one.
    fn quantity(&mut self, name: &str, q: &Quantity, unit: &str) -> R {
        self.open("dcc:quantity")?;
        self.text_el("dcc:name", name)?;
        self.real(q.value, unit, q.u.zip(q.k))?;
        self.close("dcc:quantity")
    }
    fn real(&mut self, value: f64, unit: &str, u_k: Option<(f64, f64)>) -> R {
        self.open("si:real")?;
        self.leaf("si:value", &number(value))?;
        self.leaf("si:unit", unit)?;
        if let Some((u, k)) = u_k {
            self.open("si:measurementUncertaintyUnivariate")?;
            self.open("si:expandedMU")?;
            self.leaf("si:valueExpandedMU", &number(u))?;
            self.leaf("si:coverageFactor", &number(k))?;
            self.leaf("si:coverageProbability", coverage_probability(k))?;
            self.close("si:expandedMU")?;
            self.close("si:measurementUncertaintyUnivariate")?;
        }
        self.close("si:real")
    }
    fn statement(&mut self, name: &str, declaration: &str, extra: impl FnOnce(&mut X) -> R) -> R {
        self.open("dcc:statement")?;
        self.text_el("dcc:name", name)?;
        self.text_el("dcc:declaration", declaration)?;
        extra(self)?;
        self.close("dcc:statement")
    }
}

fn administrative(x: &mut X, doc: &Certificate, authoriser: Option<&Authoriser>) -> R {
    let f = &doc.facts;
    x.open("dcc:administrativeData")?;
    x.open("dcc:dccSoftware")?;
    software(x, &f.software)?;
    x.close("dcc:dccSoftware")?;

    x.open("dcc:coreData")?;
    // ISO 3166's "unknown or unspecified" when the laboratory did not state its country
    // (`--laboratory-country`, station.toml's `laboratory.country`).
    let country = doc.laboratory.as_ref().and_then(|l| l.country.as_deref()).unwrap_or("ZZ");
    x.leaf("dcc:countryCodeISO3166_1", country)?;
    x.leaf("dcc:usedLangCodeISO639_1", "en")?;
    x.leaf("dcc:mandatoryLangCodeISO639_1", "en")?;
    let unnumbered = format!("unnumbered {} {}", not_empty(&f.serial), f.record_crc);
    x.leaf("dcc:uniqueIdentifier", doc.number.as_deref().unwrap_or(&unnumbered))?;
    x.open("dcc:identifications")?;
    x.identification(
        "calibrationLaboratory",
        &doc.sha256(),
        "SHA-256 of the certificate document (dcc:document), what an approval signs",
    )?;
    if let Some(anchor) = &f.anchor {
        x.identification("calibrationLaboratory", anchor, "The hash chain's head at issue")?;
    }
    x.close("dcc:identifications")?;
    if let Some(d) = f.received.as_deref().and_then(date) {
        x.leaf("dcc:receiptDate", d)?;
    }
    let performed =
        f.calibrated.as_deref().and_then(date).or_else(|| date(&f.issued)).unwrap_or("1970-01-01");
    x.leaf("dcc:beginPerformanceDate", performed)?;
    x.leaf("dcc:endPerformanceDate", performed)?;
    x.leaf("dcc:performanceLocation", "laboratory")?;
    if let Some(d) = date(&f.issued) {
        x.leaf("dcc:issueDate", d)?;
    }
    x.close("dcc:coreData")?;

    item(x, doc)?;

    x.open("dcc:calibrationLaboratory")?;
    let lab = doc.laboratory.as_ref();
    x.contact(
        "dcc:contact",
        lab.map_or("not stated", |l| l.name.as_str()),
        lab.and_then(|l| l.address.as_deref()).or(f.place.as_deref()),
    )?;
    x.close("dcc:calibrationLaboratory")?;

    x.open("dcc:respPersons")?;
    let operator = f.operator.as_deref().unwrap_or("not recorded");
    x.open("dcc:respPerson")?;
    x.open("dcc:person")?;
    x.text_el("dcc:name", operator)?;
    x.close("dcc:person")?;
    x.leaf("dcc:role", "Calibrated by")?;
    x.close("dcc:respPerson")?;
    if let Some(a) = authoriser {
        x.open("dcc:respPerson")?;
        x.open("dcc:person")?;
        x.text_el("dcc:name", &a.name)?;
        x.close("dcc:person")?;
        x.leaf("dcc:role", not_empty(&a.function))?;
        x.leaf("dcc:mainSigner", "true")?;
        x.close("dcc:respPerson")?;
    }
    x.close("dcc:respPersons")?;

    let customer = f.customer.as_ref();
    x.contact(
        "dcc:customer",
        customer.map_or("not stated", |c| c.name.as_str()),
        customer.and_then(|c| c.address.as_deref()),
    )?;

    x.open("dcc:statements")?;
    let decision = f.decision.as_deref().and_then(conformity);
    x.statement("Decision on conformity (as left)", &f.decision_rule, |x| match decision {
        Some(c) => x.leaf("dcc:conformity", c),
        None => Ok(()),
    })?;
    if let Some(due) = &f.recalibration_due {
        x.statement(
            "Recommended recalibration",
            "The date by which the unit should be recalibrated.",
            |x| match date(due) {
                Some(d) => x.leaf("dcc:date", d),
                None => Ok(()),
            },
        )?;
    }
    x.close("dcc:statements")?;
    x.close("dcc:administrativeData")
}

fn software(x: &mut X, release: &str) -> R {
    x.open("dcc:software")?;
    x.text_el("dcc:name", "accelcal")?;
    x.leaf("dcc:release", not_empty(release))?;
    x.leaf("dcc:type", "application")?;
    x.close("dcc:software")
}

/// The calibrated item: the triad, identified by its serial, its node's device id, its record's
/// CRC and its campaign's SHA-256; its firmware as installed software.
fn item(x: &mut X, doc: &Certificate) -> R {
    let f = &doc.facts;
    x.open("dcc:items")?;
    x.open("dcc:item")?;
    x.text_el("dcc:name", &doc.subtitle)?;
    if let Some(fw) = &f.firmware {
        x.open("dcc:installedSoftwares")?;
        x.open("dcc:software")?;
        x.text_el("dcc:name", "Node firmware")?;
        x.leaf("dcc:release", not_empty(fw))?;
        x.leaf("dcc:type", "firmware")?;
        x.close("dcc:software")?;
        x.close("dcc:installedSoftwares")?;
    }
    x.open("dcc:identifications")?;
    x.identification("calibrationLaboratory", &f.serial, "Serial number")?;
    x.identification("manufacturer", &f.device_id, "Node device id (hex)")?;
    x.identification("calibrationLaboratory", &f.record_crc, "Calibration record CRC (hex)")?;
    x.identification("calibrationLaboratory", &f.campaign_sha256, "SHA-256 of the campaign")?;
    x.close("dcc:identifications")?;
    x.close("dcc:item")?;
    x.close("dcc:items")
}

fn measurement(x: &mut X, f: &Facts) -> R {
    x.open("dcc:measurementResults")?;
    x.open("dcc:measurementResult")?;
    x.text_el("dcc:name", "Static calibration of the accelerometer triad")?;
    x.open("dcc:usedMethods")?;
    for (name, text, norm) in [
        ("Calibration in static positions of the dividing head", f.method.as_str(), Some("ISO 16063-16")),
        (
            "Model 4 (offset and 3 × 3 sensitivity per channel), selected by GMDH",
            "The model the record holds.",
            None,
        ),
        ("Weighted least squares", "The coefficients and their covariance.", None),
    ] {
        x.open("dcc:usedMethod")?;
        x.text_el("dcc:name", name)?;
        x.open("dcc:description")?;
        x.open_with("dcc:content", &[("lang", "en")])?;
        x.w.write_event(Event::Text(BytesText::new(text)))?;
        x.close("dcc:content")?;
        x.close("dcc:description")?;
        if let Some(n) = norm {
            x.leaf("dcc:norm", n)?;
        }
        x.close("dcc:usedMethod")?;
    }
    x.close("dcc:usedMethods")?;
    x.open("dcc:usedSoftware")?;
    software(x, &f.software)?;
    x.close("dcc:usedSoftware")?;
    if !f.equipment.is_empty() {
        x.open("dcc:measuringEquipments")?;
        for e in &f.equipment {
            x.open("dcc:measuringEquipment")?;
            x.text_el("dcc:name", &format!("Registered {} asset", e.kind))?;
            x.open("dcc:certificate")?;
            x.text_el("dcc:referral", "Its calibration certificate")?;
            x.leaf("dcc:referralID", not_empty(&e.certificate))?;
            x.leaf("dcc:procedure", "as registered in the calibration database")?;
            x.leaf("dcc:value", not_empty(&e.certificate))?;
            x.close("dcc:certificate")?;
            x.open("dcc:identifications")?;
            x.identification("calibrationLaboratory", &e.id, "Asset id")?;
            x.close("dcc:identifications")?;
            x.close("dcc:measuringEquipment")?;
        }
        x.close("dcc:measuringEquipments")?;
    }
    x.open("dcc:influenceConditions")?;
    condition(x, "Local gravity", None, &f.gravity)?;
    if let Some(t) = &f.temperature {
        let source = f.temperature_source.as_deref().unwrap_or("not stated");
        let text = format!("Environment temperature during the calibration, from {source}.");
        condition(x, "Temperature", Some(&text), t)?;
    }
    x.close("dcc:influenceConditions")?;

    x.open("dcc:results")?;
    result_list(x, "Model-4 coefficients (x, y, z × 1, ax, ay, az), as the record holds them", |x| {
        for (c, row) in f.coefficients.iter().enumerate() {
            for (t, &v) in row.iter().enumerate() {
                let name = format!("{} {}", AXES.get(c).unwrap_or(&"?"), TERMS.get(t).unwrap_or(&"?"));
                x.open("dcc:quantity")?;
                x.text_el("dcc:name", &name)?;
                x.real(v, if t == 0 { "\\one" } else { "\\metre\\tothe{-1}\\second\\tothe{2}" }, None)?;
                x.close("dcc:quantity")?;
            }
        }
        Ok(())
    })?;
    if !f.parameters.is_empty() {
        result_list(x, "IEEE Std 1293 parameters with expanded uncertainty", |x| {
            for p in &f.parameters {
                x.quantity(&format!("{} {}", p.channel, p.name), &p.quantity, &dsi_unit(&p.quantity.unit))?;
            }
            Ok(())
        })?;
    }
    if let Some(u) = &f.u_axis {
        result_list(x, "Expanded uncertainty U of the calibrated acceleration per axis", |x| {
            for (a, q) in AXES.iter().zip(u) {
                x.open("dcc:quantity")?;
                x.text_el("dcc:name", &format!("U {a}"))?;
                x.real(q.value, &dsi_unit(&q.unit), None)?;
                x.close("dcc:quantity")?;
            }
            Ok(())
        })?;
    }
    x.close("dcc:results")?;
    x.close("dcc:measurementResult")?;
    x.close("dcc:measurementResults")
}

const AXES: [&str; 3] = ["x", "y", "z"];
const TERMS: [&str; 4] = ["1", "ax", "ay", "az"];

fn condition(x: &mut X, name: &str, description: Option<&str>, q: &Quantity) -> R {
    x.open("dcc:influenceCondition")?;
    x.text_el("dcc:name", name)?;
    if let Some(d) = description {
        x.text_el("dcc:description", d)?;
    }
    x.open("dcc:data")?;
    x.quantity(name, q, &dsi_unit(&q.unit))?;
    x.close("dcc:data")?;
    x.close("dcc:influenceCondition")
}

fn result_list(x: &mut X, name: &str, items: impl FnOnce(&mut X) -> R) -> R {
    x.open("dcc:result")?;
    x.text_el("dcc:name", name)?;
    x.open("dcc:data")?;
    x.open("dcc:list")?;
    items(x)?;
    x.close("dcc:list")?;
    x.close("dcc:data")?;
    x.close("dcc:result")
}

/// A unit as the document writes it (the SI brochure's symbols) in D-SI syntax. Units that are
/// not SI (the codes of the converter, milli-g) are written with D-SI's non-SI mark `|`.
pub fn dsi_unit(unit: &str) -> String {
    match unit {
        "m/s²" => "\\metre\\second\\tothe{-2}".into(),
        "°C" => "\\degreecelsius".into(),
        "µrad" => "\\micro\\radian".into(),
        "rad" => "\\radian".into(),
        "codes" => "\\one".into(),
        "codes/(m/s²)" => "\\metre\\tothe{-1}\\second\\tothe{2}".into(),
        other => format!("|{other}"),
    }
}

/// A number as D-SI's `decimalType` writes it: Rust's shortest round-trip form, `NaN` for what
/// is not finite.
fn number(v: f64) -> String {
    if v.is_finite() {
        format!("{v}")
    } else {
        "NaN".into()
    }
}

/// The coverage probability stated with a coverage factor: about 95 % for k = 2 (GUM), else not
/// stated (`NaN`, as D-SI allows).
fn coverage_probability(k: f64) -> &'static str {
    if k == 2.0 {
        "0.95"
    } else {
        "NaN"
    }
}

/// The document's decision as DCC's conformity status.
fn conformity(decision: &str) -> Option<&'static str> {
    match decision {
        "pass" => Some("pass"),
        "fail" => Some("fail"),
        "conditional pass" => Some("conditionalPass"),
        "conditional fail" => Some("conditionalFail"),
        _ => None,
    }
}

/// The `YYYY-MM-DD` a text starts with, when it starts with one.
fn date(s: &str) -> Option<&str> {
    let d = s.get(..10)?;
    let b = d.as_bytes();
    let digits = |r: std::ops::Range<usize>| b[r].iter().all(u8::is_ascii_digit);
    (digits(0..4) && b[4] == b'-' && digits(5..7) && b[7] == b'-' && digits(8..10)).then_some(d)
}

/// A text for a `notEmptyStringType`: "-" for an empty one.
fn not_empty(s: &str) -> &str {
    if s.trim().is_empty() {
        "-"
    } else {
        s
    }
}

/// What [`verify`] found in a DCC that holds its document.
#[derive(Debug)]
pub struct Verified {
    /// The attached document.
    pub doc: Certificate,
    /// The signed decision it carries (not yet checked: [`Seal::check`]).
    pub seal: Option<Seal>,
}

/// Why a DCC is not valid.
#[derive(Debug, thiserror::Error)]
pub enum Invalid {
    /// Not XML that reads.
    #[error("not a readable XML file: {0}")]
    Xml(String),
    /// No attached document.
    #[error("the DCC carries no accelcal certificate document (dcc:document with {DOCUMENT_FILE})")]
    NoDocument,
    /// The attachment is not base64.
    #[error("the attached document is not base64: {0}")]
    Base64(#[from] base64::DecodeError),
    /// The attachment is not a document.
    #[error("the attached document does not read: {0}")]
    Document(#[from] DocumentError),
    /// The attachment is not the canonical form of the document it reads as.
    #[error("the attached document is not in canonical form: it was edited")]
    NotCanonical,
    /// The DCC's content differs from the document's.
    #[error(
        "the DCC differs from its attached document at line {line}: the file has `{found}`, the document gives `{expected}`"
    )]
    Differs {
        /// The line (1-based).
        line: usize,
        /// The file's line, trimmed.
        found: String,
        /// The re-rendered line, trimmed.
        expected: String,
    },
    /// Rendering failed.
    #[error("rendering the document again: {0}")]
    Render(#[from] std::io::Error),
}

/// Checks a DCC offline: reads its attached document, checks that the attachment is that
/// document's canonical form, and that the DCC is exactly what the document renders to (with the
/// main signer it names). A signature, when the approval branch adds one, is checked by the
/// caller from [`Verified::signed`] and [`Verified::sha256`]. Never panics on any bytes.
pub fn verify(bytes: &[u8]) -> Result<Verified, Invalid> {
    let found = scan(bytes)?;
    let b64 = found.document.ok_or(Invalid::NoDocument)?;
    let b64: String = b64.chars().filter(|c| !c.is_ascii_whitespace()).collect();
    let json = base64::engine::general_purpose::STANDARD.decode(b64.as_bytes())?;
    let text = String::from_utf8(json).map_err(|e| Invalid::Xml(format!("attached document: {e}")))?;
    let doc = Certificate::parse(&text)?;
    if doc.canonical_json() != text {
        return Err(Invalid::NotCanonical);
    }
    let seal: Option<Seal> = match &found.approval {
        Some(b64) => {
            let b64: String = b64.chars().filter(|c| !c.is_ascii_whitespace()).collect();
            let json = base64::engine::general_purpose::STANDARD.decode(b64.as_bytes())?;
            Some(
                serde_json::from_slice(&json)
                    .map_err(|e| Invalid::Xml(format!("the attached decision: {e}")))?,
            )
        }
        None => None,
    };
    let again = dcc(&doc, seal.as_ref())?;
    let again = String::from_utf8_lossy(&again);
    let file = String::from_utf8_lossy(bytes);
    let mut a = file.lines();
    let mut b = again.lines();
    let mut line = 0;
    loop {
        line += 1;
        match (a.next(), b.next()) {
            (None, None) => break,
            (x, y) if x == y => continue,
            (x, y) => {
                let cut = |s: Option<&str>| {
                    let s = s.unwrap_or("(end of file)").trim();
                    s.chars().take(200).collect::<String>()
                };
                return Err(Invalid::Differs { line, found: cut(x), expected: cut(y) });
            }
        }
    }
    Ok(Verified { doc, seal })
}

/// What a pass over the XML finds: the attached document's and decision's base64.
#[derive(Default)]
struct Scan {
    document: Option<String>,
    approval: Option<String>,
}

/// One pass over the XML: the attached document and the signed decision. The rest of the file
/// is checked by rendering it again.
fn scan(bytes: &[u8]) -> Result<Scan, Invalid> {
    let text = std::str::from_utf8(bytes).map_err(|e| Invalid::Xml(e.to_string()))?;
    let mut reader = quick_xml::Reader::from_str(text);
    let mut path: Vec<String> = Vec::new();
    let mut out = Scan::default();
    loop {
        let ev = reader
            .read_event()
            .map_err(|e| Invalid::Xml(format!("at byte {}: {e}", reader.error_position())))?;
        match ev {
            Event::Start(s) => path.push(String::from_utf8_lossy(s.name().as_ref()).into_owned()),
            Event::End(_) => {
                path.pop();
            }
            Event::Text(t) => {
                let t = t.xml_content().map_err(|e| Invalid::Xml(e.to_string()))?.into_owned();
                let tail: Vec<&str> = path.iter().rev().take(3).map(String::as_str).collect();
                match tail.as_slice() {
                    ["dcc:dataBase64", "dcc:document", "dcc:digitalCalibrationCertificate"] => {
                        out.document.get_or_insert_with(String::new).push_str(&t)
                    }
                    ["accelcal:approval", "dcc:comment", "dcc:digitalCalibrationCertificate"] => {
                        out.approval.get_or_insert_with(String::new).push_str(&t)
                    }
                    _ => {}
                }
            }
            Event::Eof => break,
            _ => {}
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::{date, dsi_unit, verify, Invalid};

    #[test]
    fn units_are_spelled_in_d_si() {
        assert_eq!(dsi_unit("m/s²"), "\\metre\\second\\tothe{-2}");
        assert_eq!(dsi_unit("µrad"), "\\micro\\radian");
        assert_eq!(dsi_unit("mg"), "|mg");
    }

    #[test]
    fn dates_are_read_from_their_start() {
        assert_eq!(date("2026-12-07T10:00:00Z"), Some("2026-12-07"));
        assert_eq!(date("2026-12"), None);
        assert_eq!(date("soon after 2026"), None);
        assert_eq!(date("2026-1é-07"), None);
    }

    #[test]
    fn untrusted_bytes_are_refused_without_a_panic() {
        for bytes in [&b""[..], b"\xff\xfe", b"<a><b></a>", b"<dcc:document>", b"<?xml version=\"1.0\"?><x/>"]
        {
            assert!(verify(bytes).is_err());
        }
        let no_doc = b"<dcc:digitalCalibrationCertificate><dcc:document><dcc:dataBase64>!!</dcc:dataBase64>\
                       </dcc:document></dcc:digitalCalibrationCertificate>";
        assert!(matches!(verify(no_doc), Err(Invalid::Base64(_))));
    }
}
