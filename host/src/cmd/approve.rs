//! `accelcal approve NUMBER` and `accelcal reject NUMBER`: a signer's one decision on a stored
//! certificate. The key file is decrypted with its passphrase, the stored certificate's document
//! read back from its page (after its run's chain is checked), and the decision
//! ([`accelcal_core::certificate::approval::Decision`]) signed and stored by
//! [`accelcal_db::Db::decide`], which checks the key, the signature, self-approval and the run's
//! chain again in its transaction. Refused: nothing is stored.

use accelcal_core::certificate::approval::{self, Decision, Meaning};
use accelcal_core::error::{bad, environment};
use accelcal_db::signer::date_of;
use accelcal_db::Db;

use super::store::reader_spec;
use crate::settings::release::Decide;

/// Runs `accelcal approve` or `accelcal reject`.
pub fn run(a: &Decide) -> anyhow::Result<()> {
    let mut db = Db::open(&reader_spec(a.db.as_deref())?)?;
    let stored = db
        .certificate_of_number(&a.number)?
        .ok_or_else(|| bad(format!("no certificate is numbered {} in {}", a.number, db.target())))?;
    let (run, html) = (stored.run, stored.html);
    let doc = match crate::report::certificate::document_of(&html) {
        Some(d) => d.map_err(|e| bad(format!("certificate {}: its stored document: {e}", a.number)))?,
        None => {
            return Err(bad(format!(
                "certificate {} was issued before certificates carried their document: it cannot be signed",
                a.number
            )))
        }
    };
    let text = std::fs::read_to_string(&a.key)
        .map_err(|e| environment(format!("reading the key file {}", a.key.display()), e))?;
    let passphrase = super::passphrase(a.passphrase_file.as_deref(), &a.key.display().to_string(), false)?;
    let key = approval::open_key_file(&text, &passphrase).map_err(|e| {
        anyhow::Error::new(e).context(format!("the key file {}: nothing stored", a.key.display()))
    })?;
    let decision = Decision {
        number: a.number.clone(),
        document_sha256: doc.sha256(),
        meaning: a.meaning,
        reason: a.reason.clone(),
        unix_s: accelcal_db::now_unix_s(),
    };
    let signature = approval::sign(&key, &decision)?;
    let public = approval::public_hex(&key.verifying_key());
    let stored = db.decide(&decision, &public, &signature, a.allow_self_approval)?;
    let who = format!("{} ({})", stored.signer.name, stored.signer.function);
    let date = date_of(decision.unix_s);
    match a.meaning {
        Meaning::Approved => outln!(
            "approve: certificate {} (run {run}) approved for issue by {who} on {date}, key {}; stored in {}",
            a.number,
            stored.signer.fingerprint,
            db.target()
        )?,
        Meaning::Rejected => outln!(
            "reject: certificate {} (run {run}) rejected by {who} on {date}, key {}: {}; the unit is not released; stored in {}",
            a.number,
            stored.signer.fingerprint,
            a.reason,
            db.target()
        )?,
    }
    Ok(())
}
