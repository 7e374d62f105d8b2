//! `accelcal certificate NUMBER|RUN_ID`: a stored certificate printed again, from the database
//! that holds it (opened to read), with its release as the database holds it (a draft, or the
//! signed decision: [`accelcal_db::signer`]). The HTML page, the PDF and the DCC are rendered
//! from the document the stored page carries (a page from before documents is printed as
//! stored). All are handed out only after the run's rows (and the assets it used) match their
//! hash chain. `certificate verify` checks a DCC offline.

use std::path::Path;

use anyhow::Context as _;

use accelcal_core::certificate::{Certificate as Document, Release};
use accelcal_core::error::bad;
use accelcal_core::output::write_atomic;
use accelcal_db::Db;
use accelcal_db::RunId;

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
        // The page as stored while it awaits approval; once decided, the document it carries
        // rendered with the decision.
        let html = match crate::report::certificate::document_of(&html) {
            Some(Ok(doc)) => match release(&mut db, run, &doc)? {
                Release::Draft => html.clone(),
                r => crate::report::certificate::html(&doc, &r)?,
            },
            _ => html.clone(),
        };
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
                "run {run}'s certificate was issued before certificate pages carried their document: only its \
                 HTML page exists; print it with --out"
            )))
        }
    };
    let release = release(&mut db, run, &doc)?;
    if let Some(pdf) = &a.pdf {
        write_atomic(pdf, &crate::report::pdf::pdf(&doc, &release)?)?;
        outln!("certificate: run {run}'s certificate as a PDF written to {}", pdf.display())?;
    }
    if let Some(dcc) = &a.dcc {
        // The authoriser of an approved certificate; a draft or a rejected one names none.
        let authoriser = match &release {
            Release::Approved { name, function, .. } => {
                Some(crate::report::dcc::Authoriser { name: name.clone(), function: function.clone() })
            }
            _ => None,
        };
        let xml = crate::report::dcc::dcc(&doc, authoriser.as_ref()).context("rendering the DCC")?;
        write_atomic(dcc, &xml)?;
        outln!(
            "certificate: run {run}'s certificate as a DCC (XML, schema 3.3.0) written to {}",
            dcc.display()
        )?;
    }
    Ok(())
}

/// The certificate's release as the database holds it: its signed decision, else a draft. A
/// decision that signed another document than the one stored is refused.
fn release(db: &mut Db, run: RunId, doc: &Document) -> anyhow::Result<Release> {
    let Some(number) = db.number_of_run(run)? else { return Ok(Release::Draft) };
    let Some(d) = db.decision(&number)? else { return Ok(Release::Draft) };
    if d.decision.document_sha256 != doc.sha256() {
        return Err(bad(format!(
            "certificate {number}: its decision signed document {}, and the stored page carries {}: not printed",
            d.decision.document_sha256,
            doc.sha256()
        )));
    }
    Ok(d.release())
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
