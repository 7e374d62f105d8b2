//! What users read and look at: plots (rendered in memory, written atomically) and number
//! formatting for tables. The JSON documents of each command live beside the command in `cmd`.
//!
//! - `plot` (SVG plots with plotters; the criterion plot draws the best 200 candidates of each
//!   size), `gravity_plot`, `diagnose_plot`.
//! - The certificate's renderers, which compute nothing (the document is
//!   `accelcal_core::certificate`'s): `certificate` (the HTML page through
//!   `host/templates/certificate/page.html`, carrying the document's canonical JSON in a
//!   `<script type="application/json">`), `pdf` (krilla: A4, DejaVu Sans embedded, rows never
//!   split, the document attached; `pdf::attachments` reads a PDF's attachments back) and `dcc`
//!   (PTB's Digital Calibration Certificate, schema 3.3.0, written and read with quick-xml; its
//!   `verify` renders the DCC again from its attached document and compares).

pub mod certificate;
pub mod dcc;
pub mod diagnose_plot;
pub mod gravity_plot;
pub mod pdf;
pub mod plot;

pub use accelcal_core::certificate::round::sig;
