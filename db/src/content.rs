//! What each chained row's `content_sha256` hashes, one function per table whose content is not
//! one column: shared by the code that stores a row (`asset`, `certificate`, `label`, `lib`) and
//! the chain that checks it again (`chain`). It imports none of them, so that neither imports
//! the other to reach it.

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
    Ok(format!(
        "{}\n{}\n{}\n{}\n{:?}\n{:?}",
        row[0].text()?,
        row[1].text()?,
        row[2].text()?,
        row[3].text()?,
        row[4].real()?.to_bits(),
        row[5].real()?.to_bits()
    ))
}

/// What a run_asset row's `content_sha256` hashes.
pub(crate) fn run_asset_content(kind: &str, asset_id: &str, certificate: &str) -> String {
    format!("{kind}\n{asset_id}\n{certificate}")
}

/// What a recalibration_due row's `content_sha256` hashes.
pub(crate) fn recalibration_due_content(due_unix_s: i64, basis: &str) -> String {
    format!("{due_unix_s}\n{basis}")
}

/// What a certificate_number row's `content_sha256` hashes.
pub(crate) fn certificate_number_content(sequence: i64, number: &str) -> String {
    format!("{sequence}\n{number}")
}
