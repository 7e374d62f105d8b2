//! A certificate's release by a person (issue 57 item 3): the bytes a signer signs
//! ([`Decision::message`], the one definition of the signed message), the signing key's
//! fingerprint, and the key file (an Ed25519 key in encrypted PKCS#8, PEM).
//!
//! Pure: no file, no terminal, no database. The host reads and writes the key file and the
//! passphrase; the database checks a signature with [`verify`] before it stores it.

use ed25519_dalek::pkcs8::{DecodePrivateKey, EncodePrivateKey};
use ed25519_dalek::{Signature, Signer};
/// The key types a signer holds, for callers that keep one.
pub use ed25519_dalek::{SigningKey, VerifyingKey};

/// The first line of every signed message: its format and version. A new format gets a new
/// line, and the old one keeps verifying.
pub const MESSAGE_HEADER: &str = "accelcal-approval v1";

/// What a signer's decision means.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Meaning {
    /// The certificate may be issued.
    Approved,
    /// It may not: the unit is not released.
    Rejected,
}

impl Meaning {
    /// The words signed and stored: `approved for issue`, `rejected`.
    pub fn as_str(self) -> &'static str {
        match self {
            Meaning::Approved => "approved for issue",
            Meaning::Rejected => "rejected",
        }
    }

    /// The meaning whose words are `s`.
    pub fn parse(s: &str) -> Option<Meaning> {
        [Meaning::Approved, Meaning::Rejected].into_iter().find(|m| m.as_str() == s)
    }
}

/// One decision on one certificate: what is signed.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Decision {
    /// The certificate's number (`2026-000017`).
    pub number: String,
    /// The certificate document's [`super::Certificate::sha256`].
    pub document_sha256: String,
    /// Approved or rejected.
    pub meaning: Meaning,
    /// Why (a rejection's reason; empty for an approval).
    pub reason: String,
    /// When it was signed, Unix seconds.
    pub unix_s: i64,
}

impl Decision {
    /// The signed bytes: six lines, each ended by `\n`:
    ///
    /// ```text
    /// accelcal-approval v1
    /// NUMBER
    /// DOCUMENT_SHA256
    /// MEANING
    /// REASON
    /// UNIX_S
    /// ```
    ///
    /// Refused ([`SigningError::NotOneLine`]) when a field holds a line break, so that no two
    /// decisions have the same bytes.
    pub fn message(&self) -> Result<Vec<u8>, SigningError> {
        for (field, v) in
            [("number", &self.number), ("document sha256", &self.document_sha256), ("reason", &self.reason)]
        {
            if v.contains(['\n', '\r']) {
                return Err(SigningError::NotOneLine { field });
            }
        }
        Ok(format!(
            "{MESSAGE_HEADER}\n{}\n{}\n{}\n{}\n{}\n",
            self.number,
            self.document_sha256,
            self.meaning.as_str(),
            self.reason,
            self.unix_s
        )
        .into_bytes())
    }
}

/// A key or signature that does not serve.
#[derive(Debug, thiserror::Error)]
pub enum SigningError {
    /// The key file does not decrypt with this passphrase (or is not an encrypted PKCS#8 file).
    #[error("the key file does not open with this passphrase (a wrong passphrase, or not an accelcal key file: an encrypted PKCS#8 Ed25519 key, PEM)")]
    WrongPassphrase,
    /// The key could not be written.
    #[error("the key cannot be encrypted: {cause}")]
    Encrypt {
        /// pkcs8's message.
        cause: String,
    },
    /// The system's random source failed.
    #[error("the system's random source failed: {cause}")]
    Random {
        /// The message.
        cause: String,
    },
    /// A public key that is not 32 bytes of hex, or not a point of the curve.
    #[error("not an Ed25519 public key: {why}")]
    BadPublicKey {
        /// Why.
        why: String,
    },
    /// A signature that is not 64 bytes of hex.
    #[error("not an Ed25519 signature: {why}")]
    BadSignature {
        /// Why.
        why: String,
    },
    /// The signature is not the key's over these bytes.
    #[error("the signature does not verify with the signer's key: the decision or the document differ from what was signed")]
    Invalid,
    /// A field of the signed message holds a line break.
    #[error("the {field} of a decision must be one line")]
    NotOneLine {
        /// Which field.
        field: &'static str,
    },
}

impl crate::error::Classify for SigningError {
    fn kind(&self) -> crate::error::Kind {
        match self {
            SigningError::Encrypt { .. } | SigningError::Random { .. } => crate::error::Kind::Environment,
            _ => crate::error::Kind::BadInput,
        }
    }
}

/// A new signing key from the operating system's random source.
pub fn generate() -> Result<SigningKey, SigningError> {
    use rand::TryRngCore;
    let mut secret = [0u8; 32];
    rand::rngs::OsRng
        .try_fill_bytes(&mut secret)
        .map_err(|e| SigningError::Random { cause: e.to_string() })?;
    Ok(SigningKey::from_bytes(&secret))
}

/// The key file's text: `key` as PKCS#8 (RFC 5958) encrypted with `passphrase` (PBES2: scrypt,
/// log₂N 15, r 8, p 1; AES-256-CBC), PEM (`-----BEGIN ENCRYPTED PRIVATE KEY-----`).
pub fn key_file(key: &SigningKey, passphrase: &str) -> Result<String, SigningError> {
    key.to_pkcs8_encrypted_pem(passphrase.as_bytes(), pkcs8::LineEnding::LF)
        .map(|s| s.to_string())
        .map_err(|e| SigningError::Encrypt { cause: e.to_string() })
}

/// The key a key file holds, decrypted with `passphrase`.
pub fn open_key_file(text: &str, passphrase: &str) -> Result<SigningKey, SigningError> {
    SigningKey::from_pkcs8_encrypted_pem(text, passphrase.as_bytes())
        .map_err(|_| SigningError::WrongPassphrase)
}

/// A public key as stored: 64 lower-case hex digits.
pub fn public_hex(key: &VerifyingKey) -> String {
    crate::digest::hex(&key.to_bytes())
}

/// A public key's fingerprint as printed and stored: the first 16 hex digits of the SHA-256 of
/// its 32 bytes.
pub fn fingerprint(key: &VerifyingKey) -> String {
    crate::digest::sha256_hex(&key.to_bytes())[..16].to_string()
}

/// The public key `hex` stands for.
pub fn public_key(hex: &str) -> Result<VerifyingKey, SigningError> {
    let b: [u8; 32] = unhex(hex)
        .and_then(|v| v.try_into().ok())
        .ok_or_else(|| SigningError::BadPublicKey { why: "64 hex digits expected".into() })?;
    VerifyingKey::from_bytes(&b).map_err(|e| SigningError::BadPublicKey { why: e.to_string() })
}

/// The signature of `decision` by `key`, 128 lower-case hex digits.
pub fn sign(key: &SigningKey, decision: &Decision) -> Result<String, SigningError> {
    Ok(crate::digest::hex(&key.sign(&decision.message()?).to_bytes()))
}

/// Checks that `signature_hex` is `public_hex`'s signature of `decision` (RFC 8032, strict).
pub fn verify(public_hex: &str, decision: &Decision, signature_hex: &str) -> Result<(), SigningError> {
    let key = public_key(public_hex)?;
    let b: [u8; 64] = unhex(signature_hex)
        .and_then(|v| v.try_into().ok())
        .ok_or_else(|| SigningError::BadSignature { why: "128 hex digits expected".into() })?;
    key.verify_strict(&decision.message()?, &Signature::from_bytes(&b)).map_err(|_| SigningError::Invalid)
}

/// A signed decision as it travels with a certificate's file (a PDF's attachment
/// `accelcal-approval.json`): what was signed, the key that signed it, and the signer's name and
/// function as registered. [`Seal::check`] needs nothing else, so a customer can check a file
/// offline; against the database, the key is also the one registered for that name.
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct Seal {
    /// The certificate's number.
    pub number: String,
    /// The document's SHA-256.
    pub document_sha256: String,
    /// `approved for issue` or `rejected`.
    pub meaning: String,
    /// A rejection's reason (empty for an approval).
    pub reason: String,
    /// When it was signed, Unix seconds.
    pub unix_s: i64,
    /// The signer's name, as registered.
    pub signer: String,
    /// Their function, as registered.
    pub function: String,
    /// The signing key's public half, 64 hex digits.
    pub public_key: String,
    /// Its fingerprint ([`fingerprint`]).
    pub fingerprint: String,
    /// The signature of [`Decision::message`], 128 hex digits.
    pub signature: String,
}

impl Seal {
    /// The attachment's name in a PDF.
    pub const ATTACHMENT: &'static str = "accelcal-approval.json";

    /// The decision it signs.
    pub fn decision(&self) -> Result<Decision, SigningError> {
        let meaning = Meaning::parse(&self.meaning).ok_or_else(|| SigningError::BadSignature {
            why: format!("the meaning {:?} is neither approved for issue nor rejected", self.meaning),
        })?;
        Ok(Decision {
            number: self.number.clone(),
            document_sha256: self.document_sha256.clone(),
            meaning,
            reason: self.reason.clone(),
            unix_s: self.unix_s,
        })
    }

    /// Checks the seal on its own: the fingerprint is its key's, and the signature is its
    /// key's over the decision.
    pub fn check(&self) -> Result<Decision, SigningError> {
        let key = public_key(&self.public_key)?;
        if fingerprint(&key) != self.fingerprint {
            return Err(SigningError::BadPublicKey {
                why: format!(
                    "the fingerprint {} is not this key's ({})",
                    self.fingerprint,
                    fingerprint(&key)
                ),
            });
        }
        let d = self.decision()?;
        verify(&self.public_key, &d, &self.signature)?;
        Ok(d)
    }

    /// The release a renderer is told for this decision.
    pub fn release(&self) -> super::Release {
        let (name, function, fingerprint) =
            (self.signer.clone(), self.function.clone(), self.fingerprint.clone());
        let date = crate::output::utc_date_time(self.unix_s).chars().take(10).collect();
        match Meaning::parse(&self.meaning) {
            Some(Meaning::Approved) => super::Release::Approved { name, function, date, fingerprint },
            _ => super::Release::Rejected { name, function, date, fingerprint, reason: self.reason.clone() },
        }
    }
}

/// Bytes from hex, `None` for anything else.
fn unhex(s: &str) -> Option<Vec<u8>> {
    if !s.len().is_multiple_of(2) {
        return None;
    }
    (0..s.len()).step_by(2).map(|i| s.get(i..i + 2).and_then(|p| u8::from_str_radix(p, 16).ok())).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn decision() -> Decision {
        Decision {
            number: "2026-000001".into(),
            document_sha256: "ab".repeat(32),
            meaning: Meaning::Approved,
            reason: String::new(),
            unix_s: 1_780_000_000,
        }
    }

    #[test]
    fn the_message_is_six_lines() {
        let m = String::from_utf8(decision().message().unwrap()).unwrap();
        assert_eq!(
            m,
            format!(
                "accelcal-approval v1\n2026-000001\n{}\napproved for issue\n\n1780000000\n",
                "ab".repeat(32)
            )
        );
        let mut d = decision();
        d.reason = "a\nb".into();
        assert!(matches!(d.message(), Err(SigningError::NotOneLine { field: "reason" })));
    }

    #[test]
    fn a_key_file_opens_with_its_passphrase_only_and_signs() {
        let key = SigningKey::from_bytes(&[7; 32]);
        let text = key_file(&key, "right horse").unwrap();
        assert!(text.starts_with("-----BEGIN ENCRYPTED PRIVATE KEY-----"), "{text}");
        assert!(matches!(open_key_file(&text, "wrong horse"), Err(SigningError::WrongPassphrase)));
        let back = open_key_file(&text, "right horse").unwrap();
        assert_eq!(back.to_bytes(), key.to_bytes());
        let public = public_hex(&key.verifying_key());
        let sig = sign(&back, &decision()).unwrap();
        verify(&public, &decision(), &sig).unwrap();
        let mut other = decision();
        other.meaning = Meaning::Rejected;
        assert!(matches!(verify(&public, &other, &sig), Err(SigningError::Invalid)));
        assert_eq!(fingerprint(&key.verifying_key()).len(), 16);
        assert!(public_key("zz").is_err());
        assert!(verify(&public, &decision(), "00").is_err());
        // A seal checks on its own, and fails when a field it signs is changed.
        let d = decision();
        let seal = Seal {
            number: d.number.clone(),
            document_sha256: d.document_sha256.clone(),
            meaning: d.meaning.as_str().into(),
            reason: d.reason.clone(),
            unix_s: d.unix_s,
            signer: "A. Reviewer".into(),
            function: "Head of laboratory".into(),
            public_key: public,
            fingerprint: fingerprint(&key.verifying_key()),
            signature: sig,
        };
        assert_eq!(seal.check().unwrap(), d);
        assert!(matches!(seal.release(), super::super::Release::Approved { .. }));
        let mut edited = seal.clone();
        edited.document_sha256 = "cd".repeat(32);
        assert!(matches!(edited.check(), Err(SigningError::Invalid)));
        let mut other_key = seal.clone();
        other_key.fingerprint = "0".repeat(16);
        assert!(other_key.check().is_err());
    }
}
