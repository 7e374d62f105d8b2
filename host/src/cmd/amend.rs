//! `accelcal amend NUMBER --reason TEXT`: a stored certificate issued again under a new number.
//! The certificate in force is read back (after its run's chain is checked), its document
//! amended ([`accelcal_core::certificate::amend`]: the new number, "replaces NUMBER" and the
//! reason, the date of issue and the chain's head now) and stored as a draft page by
//! [`accelcal_db::Db::amend`], which gives the number and refuses, with nothing stored, a
//! certificate replaced already, a voided run or a run whose rows do not match their chain.

use accelcal_core::certificate::{amend, Amend, Release};
use accelcal_core::error::bad;
use accelcal_db::Db;

use super::store::{reader_spec, user_name};
use crate::settings::release::Amend as Settings;

/// Runs `accelcal amend`.
pub fn run(a: &Settings) -> anyhow::Result<()> {
    let mut db = Db::open(&reader_spec(a.db.as_deref())?)?;
    let stored = db
        .certificate_of_number(&a.number)?
        .ok_or_else(|| bad(format!("no certificate is numbered {} in {}", a.number, db.target())))?;
    let doc = match crate::report::certificate::document_of(&stored.html) {
        Some(d) => d.map_err(|e| bad(format!("certificate {}: its stored document: {e}", a.number)))?,
        None => {
            return Err(bad(format!(
                "certificate {} was issued before certificates carried their document: it cannot be amended",
                a.number
            )))
        }
    };
    // The chain's head before the amendment is stored, as a first certificate states it.
    let anchor = db.chain_head()?.map(|h| h.text());
    let operator = a.operator.clone().unwrap_or_else(user_name);
    let done = db.amend(&a.number, &a.reason, &operator, |n| {
        let amended = amend(
            &doc,
            &Amend {
                number: &n.number,
                replaces: &a.number,
                reason: &a.reason,
                issued_unix_s: n.issued_unix_s,
                anchor: anchor.as_deref(),
            },
        );
        crate::report::certificate::html(&amended, &Release::Draft).map_err(|e| format!("{e:#}"))
    })?;
    outln!(
        "amend: certificate {} (run {}) replaces {}: {}; it awaits approval (`accelcal approve {}`), and {} is superseded; stored in {}",
        done.number.number,
        done.run,
        done.replaces,
        done.reason,
        done.number.number,
        done.replaces,
        db.target()
    )?;
    Ok(())
}
