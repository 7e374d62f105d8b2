//! What each chained row's `content_sha256` hashes, one function per table whose content is not
//! one column: shared by the code that stores a row (`asset`, `certificate`, `label`, `lib`) and
//! the chain that checks it again (`chain`). It imports none of them, so that neither imports
//! the other to reach it.

use accelcal_core::certificate::approval::{Decision, Meaning};

use super::val::Val;
use super::{sha256_hex, DbError, RunStart};

/// A run start's content hash (what `begin_run` stores).
pub fn run_content(s: &RunStart) -> String {
    sha256_hex(serde_json::to_string(s).expect("a run start serialises").as_bytes())
}

/// What a relabel row's `content_sha256` hashes.
pub fn relabel_content(device: &str, old: &str, new: &str, reason: &str) -> String {
    format!("{device}\n{old}\n{new}\n{reason}")
}

/// What a chain_event row's `content_sha256` hashes.
pub fn event_content(kind: &str, detail: &str) -> String {
    format!("{kind}\n{detail}")
}

/// What an asset row's `content_sha256` hashes: what the certificate states (not who registered
/// it when), so that registering the same certificate again is a no-op.
pub(crate) fn asset_content(row: &[Val]) -> Result<String, DbError> {
    let mut text = format!(
        "{}\n{}\n{}\n{}\n{:?}\n{:?}",
        row[0].text()?,
        row[1].text()?,
        row[2].text()?,
        row[3].text()?,
        row[4].real()?.to_bits(),
        row[5].real()?.to_bits()
    );
    // A stated value (schema 11, after the row's hash) is covered; a row without one hashes as
    // before it.
    match (row.get(9).unwrap_or(&Val::Null), row.get(10).unwrap_or(&Val::Null)) {
        (Val::Null, Val::Null) => {}
        // A thermometer's uncertainty without a value.
        (Val::Null, u) => text.push_str(&format!("\n-\n{:?}", u.real()?.to_bits())),
        (v, u) => text.push_str(&format!("\n{:?}\n{:?}", v.real()?.to_bits(), u.real()?.to_bits())),
    }
    Ok(text)
}

/// What a run_asset row's `content_sha256` hashes.
pub(crate) fn run_asset_content(kind: &str, asset_id: &str, certificate: &str) -> String {
    format!("{kind}\n{asset_id}\n{certificate}")
}

/// What a recalibration_due row's `content_sha256` hashes.
pub(crate) fn recalibration_due_content(due_unix_s: i64, basis: &str) -> String {
    format!("{due_unix_s}\n{basis}")
}

/// What an amendment row's `content_sha256` hashes: its number and place in the sequence, the
/// number it replaces and why, and its page.
pub(crate) fn amendment_content(
    sequence: i64,
    number: &str,
    replaces: &str,
    reason: &str,
    html: &str,
) -> String {
    format!("{sequence}\n{number}\n{replaces}\n{reason}\n{html}")
}

/// What an asset_found_bad row's `content_sha256` hashes: the finding (asset, certificate, the
/// first day affected) and why.
pub(crate) fn found_bad_content(asset_id: &str, certificate: &str, since: &str, reason: &str) -> String {
    format!("{asset_id}\n{certificate}\n{since}\n{reason}")
}

/// What a recall_dismissal row's `content_sha256` hashes: the finding, the unit and why.
pub(crate) fn dismissal_content(
    asset_id: &str,
    certificate: &str,
    device_id: &str,
    serial: &str,
    reason: &str,
) -> String {
    format!("{asset_id}\n{certificate}\n{device_id}\n{serial}\n{reason}")
}

/// What a certificate_number row's `content_sha256` hashes.
pub(crate) fn certificate_number_content(sequence: i64, number: &str) -> String {
    format!("{sequence}\n{number}")
}

/// What a signer row's `content_sha256` hashes.
pub(crate) fn signer_content(name: &str, function: &str, public_key: &str) -> String {
    format!("{name}\n{function}\n{public_key}")
}

/// What an approval row's `content_sha256` hashes: the signed message, the key's fingerprint and
/// the signature, one line each.
pub(crate) fn approval_content(d: &Decision, fingerprint: &str, signature: &str) -> Result<String, DbError> {
    let m = d.message().map_err(|e| DbError::schema(format!("an approval row: {e}")))?;
    Ok(format!("{}{fingerprint}\n{signature}", String::from_utf8_lossy(&m)))
}

/// The decision an approval row holds (columns in `chain::TABLES`' order).
pub(crate) fn decision_of_row(row: &[Val]) -> Result<Decision, DbError> {
    let meaning = row[3].text()?;
    Ok(Decision {
        number: row[1].text()?,
        document_sha256: row[2].text()?,
        meaning: Meaning::parse(&meaning)
            .ok_or_else(|| DbError::schema(format!("an approval's meaning {meaning:?}")))?,
        reason: row[4].text()?,
        unix_s: row[7].int()?,
    })
}
