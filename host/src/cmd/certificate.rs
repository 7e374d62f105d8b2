//! `accelcal certificate NUMBER|RUN_ID`: a stored certificate printed again, from the database
//! that holds it (opened to read). The HTML page is the page as issued; the PDF is rendered from
//! the document that page carries. Both are handed out only after the run's rows (and the
//! assets it used) match their hash chain.

use accelcal_core::certificate::Release;
use accelcal_core::error::bad;
use accelcal_core::output::write_atomic;
use accelcal_db::Db;

use super::store::reader_spec;
use crate::settings::reader::{Certificate, Which};

/// Runs `accelcal certificate`.
pub fn run(a: &Certificate) -> anyhow::Result<()> {
    let mut db = Db::open_existing(&reader_spec(a.db.as_deref())?)?;
    let run = match &a.which {
        Which::Run(run) => *run,
        Which::Number(n) => db
            .run_of_certificate(n)?
            .ok_or_else(|| bad(format!("no certificate is numbered {n} in {}", db.target())))?,
    };
    let Some(html) = db.certificate_html(run)? else {
        return Err(bad(format!("run {run} has no certificate in {}", db.target())));
    };
    if let Some(out) = &a.out {
        write_atomic(out, html.as_bytes())?;
        outln!("certificate: run {run}'s certificate, as issued, written to {}", out.display())?;
    }
    if let Some(pdf) = &a.pdf {
        let doc = match crate::report::certificate::document_of(&html) {
            Some(d) => d.map_err(|e| bad(format!("run {run}'s stored certificate: {e}")))?,
            None => {
                return Err(bad(format!(
                    "run {run}'s certificate was issued before certificates carried their document (accelcal \
                     before 0.2): only its HTML page exists; print it with --out"
                )))
            }
        };
        let release = stored_release(&html);
        write_atomic(pdf, &crate::report::pdf::pdf(&doc, &release)?)?;
        outln!("certificate: run {run}'s certificate as a PDF written to {}", pdf.display())?;
    }
    Ok(())
}

/// The release the stored page states: the name on its "Authorised by" line as it was issued
/// (`report --authorised-by`), else a draft.
fn stored_release(html: &str) -> Release {
    const ROW: &str = "<th class=\"l\">Authorised by</th><td class=\"l\">";
    let Some(at) = html.find(ROW) else { return Release::Draft };
    let rest = &html[at + ROW.len()..];
    let text = rest[..rest.find("</td>").unwrap_or(0)].to_string();
    if html.contains("<p class=\"draft\">") || text.is_empty() {
        return Release::Draft;
    }
    Release::Stated { name: unescape(&text) }
}

/// HTML text back to the text it escapes (askama's five entities, and the escaper's `\u{…}`
/// left as it is).
fn unescape(s: &str) -> String {
    s.replace("&lt;", "<")
        .replace("&gt;", ">")
        .replace("&quot;", "\"")
        .replace("&#x27;", "'")
        .replace("&#39;", "'")
        .replace("&amp;", "&")
}
