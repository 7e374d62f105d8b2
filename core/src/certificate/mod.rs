//! The calibration certificate as one typed document (issue 57): everything a certificate states,
//! built once by [`build`] from the run's stored pieces, then read by every renderer (the HTML
//! page, the PDF, the DCC XML) without computing anything.
//!
//! The document has two faces:
//! - **what is printed**: the title, the verdict, the identification table and the sections, as
//!   ready text, tables and charts ([`Block`]); a renderer lays them out and nothing more;
//! - **what machines read** ([`Facts`]): the same results as numbers with their units and
//!   expanded uncertainties, for the DCC and for `certificate verify`.
//!
//! Its canonical form is its JSON ([`Certificate::canonical_json`]: serde's field order, no
//! white space); [`Certificate::sha256`] of that is what an approval signs and what the database
//! chains. Whether the document is approved is not part of it: a renderer is told the release
//! ([`Release`]) and marks a draft on every page.

pub mod approval;
mod build;
pub mod round;

pub use build::{
    amend, build, Amend, AssetRef, DriftInput, EnvironmentInput, GravityInput, Inputs, IssuerInput,
    TermChange,
};

use serde::{Deserialize, Serialize};

/// The document format's version: a reader refuses another.
pub const FORMAT: u32 = 1;

/// Where an HTML page of a certificate carries its document: the canonical JSON, escaped for a
/// `<script>` element (`<`, `>` and `&` as `\u` escapes), is the text of the element this opens
/// ([`Certificate::of_page`] reads it back; the database reads a stored certificate's customer
/// there).
pub const PAGE_SCRIPT_OPEN: &str = "<script type=\"application/json\" id=\"accelcal-certificate\">";

/// One certificate.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Certificate {
    /// [`FORMAT`].
    pub format: u32,
    /// The certificate's number (`2026-000017`), `None` for a page printed without a database.
    pub number: Option<String>,
    /// The heading: "Calibration certificate No. 2026-000017".
    pub title: String,
    /// The line under it: "Accelerometer triad U-0042".
    pub subtitle: String,
    /// The text of every page's footer before "Page i of n".
    pub footer: String,
    /// The laboratory that issues it.
    pub laboratory: Option<Party>,
    /// The statement at the top (conformity, verified, not verified).
    pub verdict: Vec<Span>,
    /// The identification table of page 1, in order.
    pub identification: Vec<Field>,
    /// The sections, in order.
    pub sections: Vec<Section>,
    /// The numbers behind the text, for machines.
    pub facts: Facts,
}

/// A laboratory or a customer.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Party {
    /// Its name.
    pub name: String,
    /// Its address or contact, one line.
    pub address: Option<String>,
    /// Its country, ISO 3166-1 alpha-2 (`DE`): the laboratory's, for the DCC (absent in a
    /// document made before it was stated, and for the customer).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub country: Option<String>,
}

/// A row of the identification table.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Field {
    /// What it is ("Customer").
    pub label: String,
    /// Its text.
    pub text: String,
}

/// Text with a style.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Span {
    /// The text.
    pub text: String,
    /// How it stands out.
    pub style: Style,
}

/// How a piece of text stands out.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Style {
    /// Plain.
    Plain,
    /// Bold.
    Strong,
    /// A good outcome (green).
    Pass,
    /// A bad outcome (red, bold).
    Fail,
}

impl Span {
    /// Plain text.
    pub fn plain(text: impl Into<String>) -> Span {
        Span { text: text.into(), style: Style::Plain }
    }

    /// Text in `style`.
    pub fn styled(text: impl Into<String>, style: Style) -> Span {
        Span { text: text.into(), style }
    }
}

/// A section: a heading and what follows it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Section {
    /// The heading, `None` for text that continues the previous section.
    pub heading: Option<String>,
    /// Its content, in order.
    pub blocks: Vec<Block>,
}

/// A piece of a section.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Block {
    /// A paragraph.
    Paragraph(Paragraph),
    /// A table.
    Table(Table),
    /// A line chart.
    Chart(Chart),
}

/// A paragraph.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Paragraph {
    /// Its text.
    pub spans: Vec<Span>,
    /// Small print.
    pub small: bool,
}

/// A table: its columns and rows of cells, each as printed.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Table {
    /// The columns.
    pub columns: Vec<Column>,
    /// The rows; each has one cell per column.
    pub rows: Vec<Vec<Span>>,
}

/// A table's column.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Column {
    /// Its head, with the unit of its values.
    pub head: String,
    /// Text (left) or numbers (right).
    pub numeric: bool,
    /// Its share of the table's width, relative to the other columns'.
    pub width: f64,
}

/// A line chart.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Chart {
    /// Its title.
    pub title: String,
    /// The x axis' label.
    pub x_label: String,
    /// The y axis' label, with the unit.
    pub y_label: String,
    /// The lines.
    pub series: Vec<Series>,
}

/// One line of a chart.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Series {
    /// Its name in the legend.
    pub name: String,
    /// Its points, (x, y).
    pub points: Vec<(f64, f64)>,
}

/// A value with its unit and, when known, its expanded uncertainty and coverage factor.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Quantity {
    /// The value.
    pub value: f64,
    /// The expanded uncertainty U, in the value's unit.
    pub u: Option<f64>,
    /// The coverage factor of U.
    pub k: Option<f64>,
    /// The unit, as the SI brochure writes it (`m/s²`, `mg`, `µrad`, `°C`).
    pub unit: String,
}

/// A coefficient-derived parameter of one channel (IEEE Std 1293 names).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Parameter {
    /// The channel (`x`, `y`, `z`).
    pub channel: String,
    /// The parameter: `bias_k0`, `scale_factor_k1`, `misalignment_toward_x` …
    pub name: String,
    /// Its value and U.
    pub quantity: Quantity,
}

/// A registered reference the run used.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Equipment {
    /// Its kind (`head`, `thermometer`, `gravity`).
    pub kind: String,
    /// Its asset id.
    pub id: String,
    /// Its own calibration certificate.
    pub certificate: String,
}

/// The numbers behind the printed text.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Facts {
    /// The triad's serial number.
    pub serial: String,
    /// The node's device id (hex).
    pub device_id: String,
    /// The node's firmware.
    pub firmware: Option<String>,
    /// The record's CRC (hex).
    pub record_crc: String,
    /// The campaign's SHA-256 (hex).
    pub campaign_sha256: String,
    /// The customer.
    pub customer: Option<Party>,
    /// When the item was received (as the settings state it).
    pub received: Option<String>,
    /// Where it was calibrated (station and site).
    pub place: Option<String>,
    /// When it was calibrated (the campaign's date).
    pub calibrated: Option<String>,
    /// When the certificate was issued, `YYYY-MM-DDTHH:MM:SSZ`.
    pub issued: String,
    /// Who operated the run, as registered.
    pub operator: Option<String>,
    /// The method in words.
    pub method: String,
    /// The version of accelcal that issued it.
    pub software: String,
    /// Local gravity with its U.
    pub gravity: Quantity,
    /// The environment's temperature: read on a registered thermometer, else the node's own
    /// sensor during the as-left verification; with where it came from.
    pub temperature: Option<Quantity>,
    /// Where the temperature came from.
    pub temperature_source: Option<String>,
    /// U of the calibrated acceleration per axis (x, y, z), m/s².
    pub u_axis: Option<[Quantity; 3]>,
    /// The 12 model-4 coefficients (channels x, y, z × terms 1, ax, ay, az) as the record holds
    /// them: codes and codes/(m/s²).
    pub coefficients: Vec<Vec<f64>>,
    /// The IEEE 1293 parameters with U.
    pub parameters: Vec<Parameter>,
    /// The as-left decision (`pass`, `conditional pass`, `fail` …), when judged.
    pub decision: Option<String>,
    /// The decision rule in words.
    pub decision_rule: String,
    /// The registered references the run used.
    pub equipment: Vec<Equipment>,
    /// The recommended recalibration date, `YYYY-MM-DD`.
    pub recalibration_due: Option<String>,
    /// The hash chain's head at issue (`accelcal-anchor seq=N chain_sha256=HEX`).
    pub anchor: Option<String>,
    /// The number of the certificate this one replaces (an amendment).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub replaces: Option<String>,
}

/// Who released the document, as a renderer is told it: not part of the document.
#[derive(Clone, Debug, PartialEq)]
pub enum Release {
    /// Not approved: every page says "DRAFT — awaiting approval".
    Draft,
    /// Approved by a signer.
    Approved {
        /// The signer's name.
        name: String,
        /// Their function.
        function: String,
        /// The date of the approval, `YYYY-MM-DD`.
        date: String,
        /// The signing key's fingerprint.
        fingerprint: String,
    },
    /// Rejected by a signer: every page says "REJECTED — not released: REASON".
    Rejected {
        /// The signer's name.
        name: String,
        /// Their function.
        function: String,
        /// The date of the rejection, `YYYY-MM-DD`.
        date: String,
        /// The signing key's fingerprint.
        fingerprint: String,
        /// Why.
        reason: String,
    },
    /// Authorised as the settings state it (no signature, no database: `report
    /// --authorised-by`): the page says who, as it always did.
    Stated {
        /// The name the settings give.
        name: String,
    },
    /// Replaced by an amendment (`accelcal amend`): printed as it was released, and every page
    /// says "SUPERSEDED by certificate N: REASON".
    Superseded {
        /// The amendment that replaced it.
        by: Superseded,
        /// How it was released before.
        was: Box<Release>,
    },
}

/// The amendment that replaced a certificate, as the superseded certificate's copies state it
/// (and a PDF carries, as [`Superseded::ATTACHMENT`]).
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Superseded {
    /// The amendment's number.
    pub by: String,
    /// Why it was amended.
    pub reason: String,
}

impl Superseded {
    /// Its name as a PDF attachment.
    pub const ATTACHMENT: &'static str = "accelcal-superseded.json";
}

impl Release {
    /// The mark every page of a draft carries.
    pub const DRAFT_MARK: &'static str = "DRAFT — awaiting approval";

    /// The beginning of the mark every page of a rejected certificate carries.
    pub const REJECTED_MARK: &'static str = "REJECTED — not released";

    /// The beginning of the mark every page of a replaced certificate carries.
    pub const SUPERSEDED_MARK: &'static str = "SUPERSEDED by certificate";

    /// The mark on every page, when there is one.
    pub fn mark(&self) -> Option<String> {
        match self {
            Release::Draft => Some(Release::DRAFT_MARK.into()),
            Release::Rejected { reason, .. } => Some(format!("{}: {reason}", Release::REJECTED_MARK)),
            Release::Superseded { by, .. } => {
                Some(format!("{} {}: {}", Release::SUPERSEDED_MARK, by.by, by.reason))
            }
            _ => None,
        }
    }

    /// The amendment that replaced the certificate, when one did.
    pub fn superseded(&self) -> Option<&Superseded> {
        match self {
            Release::Superseded { by, .. } => Some(by),
            _ => None,
        }
    }

    /// The "Authorised by" line.
    pub fn authorised_by(&self) -> String {
        match self {
            Release::Draft => "not yet approved: a draft, not a certificate of calibration".into(),
            Release::Approved { name, function, date, fingerprint } => {
                format!("{name}, {function}; approved for issue on {date} (signing key {fingerprint})")
            }
            Release::Rejected { name, function, date, fingerprint, .. } => {
                format!("not released: rejected by {name}, {function}, on {date} (signing key {fingerprint})")
            }
            Release::Stated { name } => name.clone(),
            Release::Superseded { was, .. } => was.authorised_by(),
        }
    }
}

/// A document that does not read.
#[derive(Debug, thiserror::Error)]
pub enum DocumentError {
    /// Not a certificate document.
    #[error("not a certificate document: {0}")]
    Json(#[from] serde_json::Error),
    /// Another format.
    #[error("a certificate document of format {found}; this accelcal reads format {FORMAT}")]
    Format {
        /// The format it has.
        found: u32,
    },
}

impl crate::error::Classify for DocumentError {
    fn kind(&self) -> crate::error::Kind {
        crate::error::Kind::BadInput
    }
}

impl Certificate {
    /// The canonical bytes: compact JSON in the fields' declared order.
    pub fn canonical_json(&self) -> String {
        serde_json::to_string(self).expect("a certificate serialises (no map keys but strings)")
    }

    /// SHA-256 of [`Certificate::canonical_json`], lower-case hex: what an approval signs.
    pub fn sha256(&self) -> String {
        crate::digest::sha256_hex(self.canonical_json().as_bytes())
    }

    /// The document an HTML page of a certificate carries (after [`PAGE_SCRIPT_OPEN`]), `None`
    /// for a page that carries none (written before pages carried their document, issue 57).
    pub fn of_page(html: &str) -> Option<Result<Certificate, DocumentError>> {
        let start = html.find(PAGE_SCRIPT_OPEN)? + PAGE_SCRIPT_OPEN.len();
        let end = start + html[start..].find("</script>")?;
        Some(Certificate::parse(&html[start..end]))
    }

    /// Reads a document's canonical JSON, refusing another format.
    pub fn parse(text: &str) -> Result<Certificate, DocumentError> {
        #[derive(Deserialize)]
        struct Probe {
            format: u32,
        }
        let p: Probe = serde_json::from_str(text)?;
        if p.format != FORMAT {
            return Err(DocumentError::Format { found: p.format });
        }
        Ok(serde_json::from_str(text)?)
    }

    /// Every section's tables, charts and paragraphs, for renderers that walk them.
    pub fn blocks(&self) -> impl Iterator<Item = &Block> {
        self.sections.iter().flat_map(|s| s.blocks.iter())
    }
}
