//! A stored certificate as the database holds it, shared by `certificate`, `approve`,
//! `amend` and `serve`: the certificate a number or a run names, and its release (the signed
//! decision, superseded when an amendment replaced it).

use accelcal_core::certificate::approval::Seal;
use accelcal_core::certificate::{Certificate as Document, Release};
use accelcal_core::error::bad;
use accelcal_db::{Db, RunId};

use crate::settings::reader::Which;

/// A certificate as the database holds it: its run, its number (a page stored without one, as
/// `bench-fleet` stores them, has none), its page, and the amendment that replaced it.
pub struct Stored {
    /// Its run.
    pub run: RunId,
    /// Its number.
    pub number: Option<String>,
    /// Its page as stored.
    pub html: String,
    /// The amendment that replaced it.
    pub superseded: Option<accelcal_db::certificate::Supersession>,
}

/// The one run whose id begins with `prefix`; refused naming them when several do.
fn run_with_prefix(db: &mut Db, prefix: &str) -> anyhow::Result<RunId> {
    let found = db.runs_with_prefix(prefix, 4)?;
    match found.as_slice() {
        [one] => Ok(*one),
        [] => Err(bad(format!("no run id begins with {prefix} in {}", db.target()))),
        more => {
            let list: Vec<String> = more.iter().take(3).map(|r| r.to_string()).collect();
            let many = if more.len() > 3 { "more than 3".to_string() } else { more.len().to_string() };
            Err(bad(format!(
                "{prefix} begins {many} run ids ({}{}): give more of its digits",
                list.join(", "),
                if more.len() > 3 { ", …" } else { "" }
            )))
        }
    }
}

impl Stored {
    /// The certificate `which` names: a number, or a run or the beginning of its id (its
    /// certificate in force).
    pub fn read(db: &mut Db, which: &Which) -> anyhow::Result<Stored> {
        let run = match which {
            Which::Number(_) => None,
            Which::Run(run) => Some(*run),
            Which::RunPrefix(p) => Some(run_with_prefix(db, p)?),
        };
        let number = match (which, run) {
            (Which::Number(n), _) => n.clone(),
            (_, Some(run)) => match db.number_in_force(run)? {
                Some(n) => n,
                None => {
                    let html = db
                        .certificate_html(run)?
                        .ok_or_else(|| bad(format!("run {run} has no certificate in {}", db.target())))?;
                    return Ok(Stored { run, number: None, html, superseded: None });
                }
            },
            (_, None) => unreachable!("a run id or its beginning names a run"),
        };
        let c = db
            .certificate_of_number(&number)?
            .ok_or_else(|| bad(format!("no certificate is numbered {number} in {}", db.target())))?;
        Ok(Stored { run: c.run, number: Some(number), html: c.html, superseded: c.superseded })
    }

    /// The certificate's release as the database holds it: its signed decision, else a draft, and
    /// superseded when an amendment replaced it. A decision that signed another document than the
    /// one stored is refused.
    pub fn release(&self, db: &mut Db, doc: &Document) -> anyhow::Result<(Release, Option<Seal>)> {
        let decided = match &self.number {
            Some(n) => db.decision(n)?,
            None => None,
        };
        let (release, seal) = match decided {
            None => (Release::Draft, None),
            Some(d) => {
                if d.decision.document_sha256 != doc.sha256() {
                    return Err(bad(format!(
                    "certificate {}: its decision signed document {}, and the stored page carries {}: not printed",
                    d.decision.number,
                    d.decision.document_sha256,
                    doc.sha256()
                )));
                }
                let seal = d.seal();
                (seal.release(), Some(seal))
            }
        };
        Ok(match &self.superseded {
            Some(s) => (Release::Superseded { by: s.note(), was: Box::new(release) }, seal),
            None => (release, seal),
        })
    }

    /// The HTML page as printed: as stored while it awaits approval and nothing replaced it
    /// (or when it carries no document); else the document it carries rendered with its
    /// decision and its amendment.
    pub fn page(&self, db: &mut Db) -> anyhow::Result<String> {
        Ok(match crate::report::certificate::document_of(&self.html) {
            Some(Ok(doc)) => match self.release(db, &doc)?.0 {
                Release::Draft => self.html.clone(),
                r => crate::report::certificate::html(&doc, &r)?,
            },
            _ => self.html.clone(),
        })
    }
}
