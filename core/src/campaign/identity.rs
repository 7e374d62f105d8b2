//! Whose a campaign is, and whose the files made from it are: what a campaign states about its
//! unit ([`CampaignId`]: its `# device_id:` and `# serial:` lines and the SHA-256 of its content),
//! the unit's identity that `fit --json` writes next to its channels ([`Identity`]: its field
//! names are an interface), and the refusal of a file that belongs to another unit
//! ([`IdentityError`]: one line naming both values).
//!
//! The hash is of the campaign's content, the bytes every reader sees: a gzip file is hashed
//! decompressed ([`crate::input::Input`]), so a campaign and its gzipped copy have the same hash
//! (`sha256sum c.csv`, or `zcat c.csv.gz | sha256sum`, prints it); a change to any row or header
//! line changes it.

use std::io::Read;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};

use super::{open, CampaignError};
use crate::error::{Classify, Kind, Plain, Setting, Worded, Wording};

/// The header key of the unit's device id (the MCU's 96-bit unique id as 24 hex digits).
pub const DEVICE_ID_KEY: &str = "device_id";
/// The header key of the unit's serial number, as the operator knows it (`-`: none given).
pub const SERIAL_KEY: &str = "serial";
/// The header key of the gravity the campaign was acquired at, m/s².
pub const G_KEY: &str = "g_m_s2";
/// The header key of where that gravity came from: a [`super::GSource`]'s tag.
pub const G_SOURCE_KEY: &str = "g_source";

/// What a campaign file states about its unit.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct CampaignId {
    /// The file.
    pub path: PathBuf,
    /// The `# device_id:` line, lower-case hex (checked: 24 hex digits).
    pub device_id: Option<String>,
    /// The `# serial:` line (`-`, as `acquire` writes it without `--serial`, is none).
    pub serial: Option<String>,
    /// SHA-256 of the content, lower-case hex.
    pub sha256: String,
}

impl CampaignId {
    /// Reads the header lines of `path` and hashes its content.
    pub fn read(path: &Path) -> Result<CampaignId, IdentityError> {
        let header = super::header(path)?;
        let get = |k: &str| header.iter().find(|(key, _)| key == k).map(|(_, v)| v.trim().to_string());
        let device_id = match get(DEVICE_ID_KEY) {
            Some(v) if is_device_id(&v) => Some(v.to_ascii_lowercase()),
            Some(v) => return Err(IdentityError::BadDeviceId { path: path.to_owned(), value: v }),
            None => None,
        };
        let serial = get(SERIAL_KEY).filter(|s| !s.is_empty() && s != "-");
        Ok(CampaignId { path: path.to_owned(), device_id, serial, sha256: content_sha256(path)? })
    }

    /// The device id as the MCU's 12 bytes, when the campaign states one.
    pub fn device_id_bytes(&self) -> Option<[u8; 12]> {
        let s = self.device_id.as_deref()?;
        let mut id = [0u8; 12];
        for (i, b) in id.iter_mut().enumerate() {
            *b = u8::from_str_radix(&s[2 * i..2 * i + 2], 16).ok()?;
        }
        Some(id)
    }
}

/// Whether `s` is 24 hex digits.
fn is_device_id(s: &str) -> bool {
    s.len() == 24 && s.bytes().all(|b| b.is_ascii_hexdigit())
}

/// SHA-256 of a campaign's content (a gzip file decompressed), lower-case hex.
pub fn content_sha256(path: &Path) -> Result<String, CampaignError> {
    let io = |cause| CampaignError::Io { path: path.to_owned(), cause };
    let mut input = open(path)?;
    let mut hasher = Sha256::new();
    let mut buf = vec![0u8; 1 << 16];
    loop {
        match input.read(&mut buf) {
            Ok(0) => break,
            Ok(n) => hasher.update(&buf[..n]),
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(io(e)),
        }
    }
    Ok(crate::digest::hex(&hasher.finalize()))
}

/// The unit a fit belongs to, written by `fit --json` next to its channels (these field names are
/// part of the fit JSON's interface); `verify --fit` and `report --fit` check them.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Identity {
    /// The unit's device id, 24 hex digits: the record's (`fit --record`), else the campaign's
    /// `# device_id:`; `null` when neither states one (a simulated campaign fitted without a
    /// record).
    pub device_id: Option<String>,
    /// The unit's serial number, the campaign's `# serial:` line; `null` when it has none.
    pub serial: Option<String>,
    /// The gravity the fit used, m/s².
    pub g_m_s2: f64,
    /// Where that gravity came from ([`super::GSource`]'s tag); absent in a fit written before
    /// fits carried it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub g_source: Option<super::GSource>,
    /// SHA-256 of the fitted campaign's content (a gzip file decompressed), hex.
    pub campaign_sha256: String,
    /// The CRC-32 of the record written with this fit (`fit --record`), 8 hex digits as `record
    /// show` and `info` print it; `null` when no record was written.
    pub record_crc: Option<String>,
}

impl Identity {
    /// The identity in a fit JSON document (`what` names it in errors). A document without one,
    /// written by an accelcal from before fits carried it, is refused: it cannot be told from
    /// another unit's.
    pub fn of_fit_json(doc: &serde_json::Value, what: &str) -> Result<Identity, IdentityError> {
        if doc.get("campaign_sha256").is_none() {
            return Err(IdentityError::NoIdentity { what: what.to_string() });
        }
        Identity::deserialize(doc)
            .map_err(|e| IdentityError::BadIdentity { what: what.to_string(), msg: e.to_string() })
    }

    /// The CRC of the record this fit was written with (`what` names the fit, `against` the
    /// record it is to be matched to); [`IdentityError::NoRecord`] for a fit written without
    /// one, which cannot be matched to any record.
    pub fn written_record(&self, what: &str, against: &str) -> Result<&str, IdentityError> {
        self.record_crc
            .as_deref()
            .ok_or_else(|| IdentityError::NoRecord { what: what.to_string(), against: against.to_string() })
    }

    /// The serial for messages: the serial, or `(none)`.
    pub fn serial_words(&self) -> &str {
        self.serial.as_deref().unwrap_or("(none)")
    }
}

/// Two files (or a file and a node) that disagree on a value that identifies the unit.
#[derive(Debug, thiserror::Error)]
#[error("{a} has {field} {a_value} but {b} has {b_value}: {consequence}")]
pub struct Mismatch {
    /// The first side (a file, an option, a node).
    pub a: String,
    /// What is compared (`device id`, `record CRC`, ...).
    pub field: &'static str,
    /// Its value on the first side.
    pub a_value: String,
    /// The second side.
    pub b: String,
    /// Its value on the second side.
    pub b_value: String,
    /// What follows (`not the same unit`, ...).
    pub consequence: &'static str,
}

impl Classify for Mismatch {
    fn kind(&self) -> Kind {
        Kind::BadInput
    }
}

/// A file that belongs to another unit, or that cannot say whose it is.
#[derive(Debug, thiserror::Error)]
pub enum IdentityError {
    /// Two sides disagree ([`Mismatch`]).
    #[error(transparent)]
    Mismatch(Box<Mismatch>),
    /// A fit JSON without the unit's identity (written before fits carried one).
    #[error("{}", self.worded(&Plain).unwrap_or_default())]
    NoIdentity {
        /// The document.
        what: String,
    },
    /// A fit JSON whose identity fields are malformed.
    #[error("{what}: the fit's identity: {msg}")]
    BadIdentity {
        /// The document.
        what: String,
        /// What is wrong.
        msg: String,
    },
    /// A fit JSON written without a record, to be matched to one.
    #[error("{}", self.worded(&Plain).unwrap_or_default())]
    NoRecord {
        /// The fit JSON.
        what: String,
        /// The record it was to be matched to.
        against: String,
    },
    /// A campaign's `# device_id:` line that is not a device id.
    #[error("{}: `# device_id: {value}` is not 24 hex digits (the MCU's 96-bit unique id)", path.display())]
    BadDeviceId {
        /// The campaign.
        path: PathBuf,
        /// The line's value.
        value: String,
    },
    /// The campaign could not be read.
    #[error(transparent)]
    Campaign(#[from] CampaignError),
}

impl Worded for IdentityError {
    fn worded(&self, w: &dyn Wording) -> Option<String> {
        match self {
            IdentityError::NoIdentity { what } => Some(format!(
                "{what}: the fit JSON does not say whose fit it is (no `device_id`, `serial`, `g_m_s2`, \
                 `campaign_sha256`: written by an older accelcal): {}",
                w.name(Setting::RefitJson)
            )),
            IdentityError::NoRecord { what, against } => Some(format!(
                "{what}: written without a record ({}), so it cannot be matched to {against}: write the \
                 fit JSON with the record, {}",
                w.name(Setting::FitRecord),
                w.name(Setting::RefitWithRecord)
            )),
            IdentityError::Campaign(e) => e.worded(w),
            _ => None,
        }
    }
}

impl Classify for IdentityError {
    fn kind(&self) -> Kind {
        match self {
            IdentityError::Campaign(e) => e.kind(),
            IdentityError::Mismatch(_)
            | IdentityError::NoIdentity { .. }
            | IdentityError::BadIdentity { .. }
            | IdentityError::NoRecord { .. }
            | IdentityError::BadDeviceId { .. } => Kind::BadInput,
        }
    }
}

/// Refuses `a_value` ≠ `b_value` ([`Mismatch`], `a` and `b` naming the sides).
pub fn same(
    field: &'static str,
    (a, a_value): (&str, &str),
    (b, b_value): (&str, &str),
    consequence: &'static str,
) -> Result<(), IdentityError> {
    if a_value.eq_ignore_ascii_case(b_value) {
        return Ok(());
    }
    Err(IdentityError::Mismatch(Box::new(Mismatch {
        a: a.to_string(),
        field,
        a_value: a_value.to_string(),
        b: b.to_string(),
        b_value: b_value.to_string(),
        consequence,
    })))
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Write;

    #[test]
    fn a_campaign_and_its_gzipped_copy_have_one_hash_and_identity() {
        let d = tempfile::tempdir().unwrap();
        let text =
            "# device_id: 51454D552D422D4C34373545\n# serial: U-7\nt_s,alpha_deg,beta_deg,x\n0,0,0,1\n";
        let plain = d.path().join("c.csv");
        std::fs::write(&plain, text).unwrap();
        let gz = d.path().join("c.csv.gz");
        let mut enc = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
        enc.write_all(text.as_bytes()).unwrap();
        std::fs::write(&gz, enc.finish().unwrap()).unwrap();
        let a = CampaignId::read(&plain).unwrap();
        let b = CampaignId::read(&gz).unwrap();
        // `printf '…' | sha256sum` of the text above.
        assert_eq!(a.sha256, content_sha256(&plain).unwrap());
        assert_eq!(a.sha256.len(), 64);
        assert_eq!(
            (a.device_id.as_deref(), a.serial.as_deref()),
            (Some("51454d552d422d4c34373545"), Some("U-7"))
        );
        assert_eq!(a.device_id_bytes(), Some(*b"QEMU-B-L475E"));
        assert_eq!((b.sha256, b.device_id, b.serial), (a.sha256.clone(), a.device_id, a.serial));
        // One changed code: another hash.
        std::fs::write(&plain, text.replace("0,0,0,1", "0,0,0,2")).unwrap();
        assert_ne!(content_sha256(&plain).unwrap(), a.sha256);
        // `-` is no serial; a bad device id is refused naming the file.
        std::fs::write(&plain, "# serial: -\n# device_id: 1234\nt_s,alpha_deg,beta_deg,x\n").unwrap();
        let e = CampaignId::read(&plain).unwrap_err().to_string();
        assert!(
            e.ends_with("c.csv: `# device_id: 1234` is not 24 hex digits (the MCU's 96-bit unique id)"),
            "{e}"
        );
        std::fs::write(&plain, "# serial: -\nt_s,alpha_deg,beta_deg,x\n").unwrap();
        let c = CampaignId::read(&plain).unwrap();
        assert_eq!((c.device_id, c.serial), (None, None));
    }

    #[test]
    fn the_sha256_is_the_standard_one() {
        let d = tempfile::tempdir().unwrap();
        let p = d.path().join("abc");
        std::fs::write(&p, "abc").unwrap();
        // FIPS 180-2, appendix B.1.
        assert_eq!(
            content_sha256(&p).unwrap(),
            "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad"
        );
    }

    #[test]
    fn a_fit_json_without_identity_is_refused_and_one_with_it_read() {
        let old: serde_json::Value = serde_json::json!({"method": "lsq", "channels": []});
        let e = Identity::of_fit_json(&old, "f.json").unwrap_err().to_string();
        assert!(
            e.starts_with("f.json: the fit JSON does not say whose fit it is")
                && e.ends_with("fit the campaign again with this version"),
            "{e}"
        );
        let id = Identity {
            device_id: Some("51454d552d422d4c34373545".into()),
            serial: None,
            g_m_s2: 9.81,
            g_source: Some(super::super::GSource::Given { u_m_s2: Some(1e-5) }),
            campaign_sha256: "ab".repeat(32),
            record_crc: Some("b1fe3d0c".into()),
        };
        let mut doc = serde_json::to_value(&id).unwrap();
        assert_eq!(doc["g_source"], "given u=1e-5");
        doc["method"] = "lsq".into();
        assert_eq!(Identity::of_fit_json(&doc, "f.json").unwrap(), id);
        // A fit written before fits carried where g came from.
        doc.as_object_mut().unwrap().remove("g_source");
        assert_eq!(Identity::of_fit_json(&doc, "f.json").unwrap().g_source, None);
        doc["g_m_s2"] = "nine".into();
        let e = Identity::of_fit_json(&doc, "f.json").unwrap_err().to_string();
        assert!(e.starts_with("f.json: the fit's identity: invalid type"), "{e}");
    }

    #[test]
    fn a_mismatch_is_one_line_naming_both_values() {
        assert!(same("device id", ("a", "ABC"), ("b", "abc"), "not the same unit").is_ok());
        let e = same("serial", ("f.json", "U-1"), ("c.csv", "U-2"), "not the same unit").unwrap_err();
        assert_eq!(e.to_string(), "f.json has serial U-1 but c.csv has U-2: not the same unit");
        assert_eq!(e.kind(), Kind::BadInput);
    }
}
