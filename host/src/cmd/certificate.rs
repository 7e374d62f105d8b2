//! `accelcal certificate NUMBER|RUN_ID`: a stored certificate printed again, from the database
//! that holds it (opened to read). The HTML page is the page as issued; the PDF is rendered from
//! the document that page carries. Both are handed out only after the run's rows (and the
//! assets it used) match their hash chain. The DCC is rendered from that document too, and
//! `certificate verify` checks a DCC offline.

use std::path::Path;

use anyhow::Context as _;

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
    if a.pdf.is_none() && a.dcc.is_none() {
        return Ok(());
    }
    let doc = match crate::report::certificate::document_of(&html) {
        Some(d) => d.map_err(|e| bad(format!("run {run}'s stored certificate: {e}")))?,
        None => {
            return Err(bad(format!(
                "run {run}'s certificate was issued before certificates carried their document (accelcal \
                 before 0.2): only its HTML page exists; print it with --out"
            )))
        }
    };
    if let Some(pdf) = &a.pdf {
        let release = stored_release(&html);
        write_atomic(pdf, &crate::report::pdf::pdf(&doc, &release)?)?;
        outln!("certificate: run {run}'s certificate as a PDF written to {}", pdf.display())?;
    }
    if let Some(dcc) = &a.dcc {
        // The authoriser comes from the approval (signer branch): none until then.
        let xml = crate::report::dcc::dcc(&doc, None).context("rendering the DCC")?;
        write_atomic(dcc, &xml)?;
        outln!(
            "certificate: run {run}'s certificate as a DCC (XML, schema 3.3.0) written to {}",
            dcc.display()
        )?;
    }
    Ok(())
}

/// Runs `accelcal certificate verify FILE`: a DCC checked offline against the document it
/// carries. Prints "valid: …", or fails naming what differs.
pub fn verify(file: &Path) -> anyhow::Result<()> {
    let bytes = std::fs::read(file).with_context(|| format!("reading {}", file.display()))?;
    let v =
        crate::report::dcc::verify(&bytes).map_err(|e| bad(format!("not valid: {}: {e}", file.display())))?;
    // The approval hook: a signature (added by approval) is to be checked here against the
    // signer's key, from the database when given, else from the DCC alone. Until then a DCC is
    // reported as what it is: consistent with its document, and not signed.
    let number = v.doc.number.as_deref().unwrap_or("(unnumbered)");
    let approval = match (&v.authoriser, v.signed) {
        (Some(a), true) => format!(
            "names {} ({}) as authoriser; its signature is not checked by this build",
            a.name, a.function
        ),
        (Some(a), false) => format!("names {} ({}) as authoriser, without a signature", a.name, a.function),
        (None, _) => "not approved: no authoriser, no signature".to_string(),
    };
    outln!(
        "valid: certificate {number} of unit {}: the DCC states exactly its attached document (SHA-256 {}); {approval}",
        v.doc.facts.serial,
        v.sha256
    )?;
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
