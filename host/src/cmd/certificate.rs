//! `accelcal certificate NUMBER|RUN_ID`: a stored certificate printed again, from the database
//! that holds it (opened to read), with its release as the database holds it (a draft, or the
//! signed decision: [`accelcal_db::signer`]). The HTML page, the PDF and the DCC are rendered
//! from the document the stored page carries (a page from before documents is printed as
//! stored). All are handed out only after the run's rows (and the assets it used) match their
//! hash chain. `certificate verify` checks a DCC offline.

use anyhow::Context as _;

use accelcal_core::certificate::approval::Seal;
use accelcal_core::certificate::{Certificate as Document, Release, Superseded};
use accelcal_core::error::bad;
use accelcal_core::output::write_atomic;
use accelcal_db::Db;

use super::store::reader_spec;
use crate::app::certificate::Stored;
use crate::settings::reader::Certificate;

/// Runs `accelcal certificate`.
pub fn run(a: &Certificate) -> anyhow::Result<()> {
    let mut db = Db::open_existing(&reader_spec(a.db.as_deref())?)?;
    let c = Stored::read(&mut db, &a.which)?;
    let run = c.run;
    let which = c
        .number
        .as_ref()
        .map_or_else(|| format!("run {run}'s certificate"), |n| format!("certificate {n} (run {run})"));
    if let Some(s) = &c.superseded {
        outln!(
            "certificate: {which} was replaced by amendment {} ({}): printed as it was, marked SUPERSEDED on every page",
            s.by,
            s.reason
        )?;
    }
    if let Some(out) = &a.out {
        let html = c.page(&mut db)?;
        write_atomic(out, html.as_bytes())?;
        outln!("certificate: {which}, as issued, written to {}", out.display())?;
    }
    if a.pdf.is_none() && a.dcc.is_none() {
        return Ok(());
    }
    let doc = match crate::report::certificate::document_of(&c.html) {
        Some(d) => d.map_err(|e| bad(format!("{which}: its stored document: {e}")))?,
        None => {
            return Err(bad(format!(
            "{which} was issued before certificate pages carried their document: only its HTML page exists; \
                 print it with --out"
        )))
        }
    };
    let (release, seal) = c.release(&mut db, &doc)?;
    if let Some(pdf) = &a.pdf {
        write_atomic(pdf, &crate::report::pdf::pdf(&doc, &release, seal.as_ref())?)?;
        outln!("certificate: {which} as a PDF written to {}", pdf.display())?;
    }
    if let Some(dcc) = &a.dcc {
        if let Some(s) = &c.superseded {
            return Err(bad(format!(
                "{which} was replaced by amendment {}: a machine-readable certificate is given for the certificate \
                 in force only (`certificate {} --dcc`); the PDF of this one is marked SUPERSEDED",
                s.by, s.by
            )));
        }
        let xml = crate::report::dcc::dcc(&doc, seal.as_ref()).context("rendering the DCC")?;
        write_atomic(dcc, &xml)?;
        outln!("certificate: {which} as a DCC (XML, schema 3.3.0) written to {}", dcc.display())?;
    }
    Ok(())
}

/// Runs `accelcal certificate verify FILE [--db DB]`: a PDF or a DCC checked against the document
/// it carries, offline, and against the database when one is given. Prints "valid: …", or fails
/// naming what differs.
pub fn verify(a: &crate::settings::reader::CertificateVerify) -> anyhow::Result<()> {
    let file = &a.file;
    let bytes = std::fs::read(file).with_context(|| format!("reading {}", file.display()))?;
    let invalid = |why: String| bad(format!("not valid: {}: {why}", file.display()));
    let (doc, seal, superseded, what) = if bytes.starts_with(b"%PDF-") {
        let (doc, seal, superseded) = verify_pdf(&bytes).map_err(|e| invalid(format!("{e:#}")))?;
        (doc, seal, superseded, "the PDF is exactly the rendering of its attached document")
    } else {
        let v = crate::report::dcc::verify(&bytes).map_err(|e| invalid(e.to_string()))?;
        (v.doc, v.seal, None, "the DCC states exactly its attached document")
    };
    let number = doc.number.clone().unwrap_or_else(|| "(unnumbered)".into());
    let sha = doc.sha256();
    // Against the database: the certificate of that number is this document, its decision is
    // the one the file carries, and an amendment that replaced it is the one the file states.
    let mut in_db = String::new();
    if let Some(spec) = &a.db {
        let mut db = Db::open_existing(spec)?;
        let c = db
            .certificate_of_number(&number)?
            .ok_or_else(|| invalid(format!("no certificate is numbered {number} in {}", db.target())))?;
        let stored = match crate::report::certificate::document_of(&c.html) {
            Some(d) => d.map_err(|e| invalid(format!("the stored certificate {number}: {e}")))?,
            None => return Err(invalid(format!("the stored certificate {number} carries no document"))),
        };
        if stored.sha256() != sha {
            return Err(invalid(format!(
                "the file's document (SHA-256 {sha}) is not certificate {number} as stored in {} (SHA-256 {})",
                db.target(),
                stored.sha256()
            )));
        }
        let decided = db.decision(&number)?.map(|d| d.seal());
        if decided != seal {
            return Err(invalid(match (&decided, &seal) {
                (Some(d), None) => format!(
                    "certificate {number} was {} in the database; the file carries no decision",
                    d.meaning
                ),
                (None, Some(_)) => format!(
                    "the file carries a decision that the database does not hold for certificate {number}"
                ),
                _ => format!("the file's decision on certificate {number} is not the one the database holds"),
            }));
        }
        let replaced = c.superseded.as_ref().map(accelcal_db::certificate::Supersession::note);
        in_db = match (&replaced, &superseded) {
            (Some(r), None) => format!(
                "; the database holds the same, and says amendment {} replaced it ({}): it is not in force",
                r.by, r.reason
            ),
            (r, f) if r == f => "; the database holds the same".into(),
            _ => {
                return Err(invalid(format!(
                    "the file says certificate {number} was replaced, and the database does not say so"
                )))
            }
        };
    }
    let release = match &seal {
        Some(s) => {
            let d = s.check().map_err(|e| invalid(e.to_string()))?;
            if d.number != number || d.document_sha256 != sha {
                return Err(invalid(format!(
                    "the signed decision is on certificate {} (document SHA-256 {}), not on this one ({number}, {sha})",
                    d.number, d.document_sha256
                )));
            }
            let date: String = accelcal_core::output::utc_date_time(s.unix_s).chars().take(10).collect();
            format!("{} by {} ({}) on {date}, signing key {}", s.meaning, s.signer, s.function, s.fingerprint)
        }
        None => "not approved: it carries no signed decision".into(),
    };
    let replaced =
        superseded.map(|s| format!("; superseded by amendment {} ({})", s.by, s.reason)).unwrap_or_default();
    outln!(
        "valid: certificate {number} of unit {}: {what} (SHA-256 {sha}); {release}{replaced}{in_db}",
        doc.facts.serial
    )?;
    Ok(())
}

/// A PDF's attached document and decision, checked: the PDF renders again to the same bytes from
/// them (one edited character anywhere differs), and the decision, when there is one, is signed
/// by its key over this document.
fn verify_pdf(bytes: &[u8]) -> anyhow::Result<(Document, Option<Seal>, Option<Superseded>)> {
    let files = crate::report::pdf::attachments(bytes)?;
    let find = |name: &str| files.iter().find(|(n, _)| n == name).map(|(_, b)| b.as_slice());
    let json = find(crate::report::pdf::ATTACHMENT)
        .ok_or_else(|| anyhow::anyhow!("it carries no certificate document (not a PDF accelcal wrote)"))?;
    let text = std::str::from_utf8(json).context("its attached document is not UTF-8")?;
    let doc = Document::parse(text).context("its attached document")?;
    if doc.canonical_json() != text {
        anyhow::bail!("its attached document is not in canonical form: it was edited");
    }
    let seal: Option<Seal> = find(Seal::ATTACHMENT)
        .map(|b| serde_json::from_slice(b).context("its attached decision"))
        .transpose()?;
    let superseded: Option<Superseded> = find(Superseded::ATTACHMENT)
        .map(|b| serde_json::from_slice(b).context("its attached amendment note"))
        .transpose()?;
    let mut release = seal.as_ref().map_or(Release::Draft, Seal::release);
    if let Some(by) = &superseded {
        release = Release::Superseded { by: by.clone(), was: Box::new(release) };
    }
    let again = crate::report::pdf::pdf(&doc, &release, seal.as_ref())?;
    if again != bytes {
        let at = again.iter().zip(bytes).position(|(x, y)| x != y).unwrap_or(again.len().min(bytes.len()));
        anyhow::bail!(
            "the pages differ from the rendering of its attached document from byte {at} on (the file was edited, \
             or written by another version of accelcal)"
        );
    }
    Ok((doc, seal, superseded))
}
