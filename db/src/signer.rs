//! Signers and their decisions on certificates (schema 9, issue 57): the register of the people
//! who may release certificates (`signer`, `signer_revocation`: global rows in the chain) and
//! each certificate's one decision (`approval`: approved for issue, or rejected, signed with
//! the signer's Ed25519 key over [`accelcal_core::certificate::approval::Decision::message`],
//! chained after its run's rows). A certificate stored and not decided is awaiting approval;
//! one an amendment replaced (`superseded`) is decided no more.

use accelcal_core::certificate::approval::{self, Decision, Meaning, SigningError};
use serde::Serialize;

use super::content::{approval_content, decision_of_row, signer_content};
use super::engine::{Tx, Val};
use super::{chain, insert_row, now_unix_s, sha256_hex, Db, DbError, RunId};

/// A signer as registered, with its revocation when it has one.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Signer {
    /// The key's fingerprint (the first 16 hex digits of the SHA-256 of the public key).
    pub fingerprint: String,
    /// The person's name.
    pub name: String,
    /// Their function ("Head of laboratory").
    pub function: String,
    /// The public key, 64 hex digits.
    pub public_key: String,
    /// Who registered it.
    pub operator: String,
    /// When, Unix seconds.
    pub registered_unix_s: i64,
    /// Its revocation, if revoked.
    pub revoked: Option<Revocation>,
}

/// A key taken out of use.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Revocation {
    /// Why.
    pub reason: String,
    /// Who revoked it.
    pub operator: String,
    /// When, Unix seconds.
    pub revoked_unix_s: i64,
}

/// A new signer ([`Db::add_signer`]).
#[derive(Clone, Debug)]
pub struct NewSigner {
    /// The person's name.
    pub name: String,
    /// Their function.
    pub function: String,
    /// The public key, 64 hex digits.
    pub public_key: String,
    /// Who registers it.
    pub operator: String,
}

/// A decision as stored, with who made it.
#[derive(Clone, Debug, PartialEq)]
pub struct StoredDecision {
    /// What was signed.
    pub decision: Decision,
    /// The run of the certificate.
    pub run_id: RunId,
    /// The signer (the key that signed).
    pub signer: Signer,
    /// The signature, 128 hex digits.
    pub signature: String,
}

impl StoredDecision {
    /// The release a renderer is told for this decision.
    pub fn release(&self) -> accelcal_core::certificate::Release {
        self.seal().release()
    }

    /// The decision as it travels with the certificate's files.
    pub fn seal(&self) -> approval::Seal {
        approval::Seal {
            number: self.decision.number.clone(),
            document_sha256: self.decision.document_sha256.clone(),
            meaning: self.decision.meaning.as_str().to_string(),
            reason: self.decision.reason.clone(),
            unix_s: self.decision.unix_s,
            signer: self.signer.name.clone(),
            function: self.signer.function.clone(),
            public_key: self.signer.public_key.clone(),
            fingerprint: self.signer.fingerprint.clone(),
            signature: self.signature.clone(),
        }
    }
}

/// Where a certificate stands.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum CertificateState {
    /// Stored, not decided.
    AwaitingApproval,
    /// Approved for issue.
    Approved,
    /// Rejected: not released.
    Rejected,
}

impl CertificateState {
    /// The state of a certificate whose decision's meaning is `meaning` (`None`: undecided).
    pub fn of(meaning: Option<&str>) -> CertificateState {
        match meaning.and_then(Meaning::parse) {
            None => CertificateState::AwaitingApproval,
            Some(Meaning::Approved) => CertificateState::Approved,
            Some(Meaning::Rejected) => CertificateState::Rejected,
        }
    }

    /// In words, as listed: `awaiting approval`, `approved`, `rejected`.
    pub fn words(self) -> &'static str {
        match self {
            CertificateState::AwaitingApproval => "awaiting approval",
            CertificateState::Approved => "approved",
            CertificateState::Rejected => "rejected",
        }
    }
}

/// A decision or a signer the register refuses.
#[derive(Debug, thiserror::Error)]
pub enum ReleaseError {
    /// The key is not registered.
    #[error("the key {fingerprint} is not a registered signer's (`accelcal signer add` registers one): nothing stored")]
    UnknownKey {
        /// Its fingerprint.
        fingerprint: String,
    },
    /// The key was revoked.
    #[error("{name}'s key {fingerprint} was revoked ({reason}): it signs nothing; nothing stored")]
    Revoked {
        /// The signer.
        name: String,
        /// The key.
        fingerprint: String,
        /// Why it was revoked.
        reason: String,
    },
    /// The signer operated the run.
    #[error("{name} operated run {run_id}: a certificate is approved by someone other than its operator (the settings file may allow self-approval: allow_self_approval = true); nothing stored")]
    SelfApproval {
        /// The signer and operator.
        name: String,
        /// The run.
        run_id: String,
    },
    /// The certificate has its decision.
    #[error("certificate {number} was {meaning} already, by {name} on {date}: a certificate has one decision; nothing stored")]
    Decided {
        /// The certificate.
        number: String,
        /// `approved for issue` or `rejected`.
        meaning: String,
        /// Who decided.
        name: String,
        /// When, `YYYY-MM-DD`.
        date: String,
    },
    /// No stored certificate has this number.
    #[error("no stored certificate is numbered {number} in {target}")]
    NoCertificate {
        /// The number.
        number: String,
        /// The database.
        target: String,
    },
    /// The certificate was replaced by an amendment.
    #[error("certificate {number} was replaced by amendment {by}: decide on {by}; nothing stored")]
    Superseded {
        /// The certificate.
        number: String,
        /// Its amendment.
        by: String,
    },
    /// The certificate's run was voided.
    #[error("certificate {number}'s run {run_id} was voided: its certificate is not released")]
    Voided {
        /// The certificate.
        number: String,
        /// The run.
        run_id: String,
    },
    /// A name that has a key in force.
    #[error("{name} has a key in force already ({fingerprint}): revoke it first (`accelcal signer revoke`)")]
    NameInForce {
        /// The name.
        name: String,
        /// The key in force.
        fingerprint: String,
    },
    /// A public key registered already.
    #[error("the key {fingerprint} is registered already (to {name})")]
    KeyRegistered {
        /// The key.
        fingerprint: String,
        /// Its signer.
        name: String,
    },
    /// No key in force has this name.
    #[error("no signer named {name} has a key in force in {target}")]
    NoSigner {
        /// The name.
        name: String,
        /// The database.
        target: String,
    },
    /// A signature, key or message that does not serve.
    #[error(transparent)]
    Signing(#[from] SigningError),
}

impl accelcal_core::error::Classify for ReleaseError {
    fn kind(&self) -> accelcal_core::error::Kind {
        match self {
            ReleaseError::Signing(e) => e.kind(),
            _ => accelcal_core::error::Kind::BadInput,
        }
    }
}

const SIGNER_COLS: &str =
    "s.fingerprint, s.name, s.function, s.public_key, s.operator, s.registered_unix_s, \
                           r.reason, r.operator, r.revoked_unix_s";

fn signers_where(tx: &mut Tx<'_>, cond: &str, args: &[Val]) -> Result<Vec<Signer>, DbError> {
    tx.query(
        &format!(
            "SELECT {SIGNER_COLS} FROM signer s LEFT JOIN signer_revocation r ON r.fingerprint = s.fingerprint \
             WHERE {cond} ORDER BY s.registered_unix_s, s.fingerprint"
        ),
        args,
    )?
    .iter()
    .map(|r| {
        Ok(Signer {
            fingerprint: r[0].text()?,
            name: r[1].text()?,
            function: r[2].text()?,
            public_key: r[3].text()?,
            operator: r[4].text()?,
            registered_unix_s: r[5].int()?,
            revoked: match &r[6] {
                Val::Null => None,
                v => Some(Revocation { reason: v.text()?, operator: r[7].text()?, revoked_unix_s: r[8].int()? }),
            },
        })
    })
    .collect()
}

/// `unix_s` as `YYYY-MM-DD` (UTC).
pub fn date_of(unix_s: i64) -> String {
    jiff::Timestamp::from_second(unix_s)
        .map(|t| t.to_zoned(jiff::tz::TimeZone::UTC).date().to_string())
        .unwrap_or_else(|_| unix_s.to_string())
}

impl Db {
    /// Registers a signer's public key (a global row in the chain). Refused when the key is
    /// registered already or the name has a key in force.
    pub fn add_signer(&mut self, s: &NewSigner) -> Result<Signer, DbError> {
        let key = approval::public_key(&s.public_key).map_err(|e| DbError::Release(e.into()))?;
        let fingerprint = approval::fingerprint(&key);
        let public_key = approval::public_hex(&key);
        let registered_unix_s = now_unix_s();
        let sha = sha256_hex(signer_content(&s.name, &s.function, &public_key).as_bytes());
        let row: Vec<Val> = vec![
            fingerprint.clone().into(),
            s.name.clone().into(),
            s.function.clone().into(),
            public_key.clone().into(),
            s.operator.clone().into(),
            registered_unix_s.into(),
            sha.into(),
        ];
        self.retried(|conn| {
            conn.transaction(|tx| {
                if let Some(k) = signers_where(
                    tx,
                    "s.public_key = $1 OR s.fingerprint = $2",
                    &[public_key.clone().into(), fingerprint.clone().into()],
                )?
                .pop()
                {
                    return Err(DbError::Release(ReleaseError::KeyRegistered {
                        fingerprint: k.fingerprint,
                        name: k.name,
                    }));
                }
                if let Some(k) =
                    signers_where(tx, "s.name = $1 AND r.reason IS NULL", &[s.name.clone().into()])?.pop()
                {
                    return Err(DbError::Release(ReleaseError::NameInForce {
                        name: k.name,
                        fingerprint: k.fingerprint,
                    }));
                }
                insert_row(tx, chain::table("signer"), &row)
            })
        })?;
        Ok(Signer {
            fingerprint,
            name: s.name.clone(),
            function: s.function.clone(),
            public_key,
            operator: s.operator.clone(),
            registered_unix_s,
            revoked: None,
        })
    }

    /// Revokes the key in force of the signer named `name` (a global row in the chain): it
    /// signs nothing after. The signer as it now stands.
    pub fn revoke_signer(&mut self, name: &str, reason: &str, operator: &str) -> Result<Signer, DbError> {
        let target = self.target();
        let at = now_unix_s();
        self.retried(|conn| {
            conn.transaction(|tx| {
                let Some(mut k) =
                    signers_where(tx, "s.name = $1 AND r.reason IS NULL", &[name.to_string().into()])?.pop()
                else {
                    return Err(DbError::Release(ReleaseError::NoSigner {
                        name: name.into(),
                        target: target.clone(),
                    }));
                };
                let row: Vec<Val> = vec![
                    k.fingerprint.clone().into(),
                    reason.to_string().into(),
                    operator.to_string().into(),
                    at.into(),
                    sha256_hex(reason.as_bytes()).into(),
                ];
                insert_row(tx, chain::table("signer_revocation"), &row)?;
                k.revoked =
                    Some(Revocation { reason: reason.into(), operator: operator.into(), revoked_unix_s: at });
                Ok(k)
            })
        })
    }

    /// Every registered signer, the oldest first, revoked ones included.
    pub fn signers(&mut self) -> Result<Vec<Signer>, DbError> {
        self.conn.reading(|tx| signers_where(tx, "1 = 1", &[]))
    }

    /// The signer whose public key is `public_key` (64 hex digits), if registered.
    pub fn signer_of_key(&mut self, public_key: &str) -> Result<Option<Signer>, DbError> {
        let pk = public_key.to_string();
        Ok(self.conn.reading(|tx| signers_where(tx, "s.public_key = $1", &[pk.clone().into()]))?.pop())
    }

    /// Stores `decision` on a stored certificate, signed by the key `public_key` with
    /// `signature`, in one transaction and after the certificate's run is checked against its
    /// chain: refused (nothing stored) for an unknown or revoked key, a signature that does not
    /// verify, a certificate that is not stored or has its decision, a voided run, and the
    /// run's own operator approving it unless `allow_self_approval`.
    pub fn decide(
        &mut self,
        decision: &Decision,
        public_key: &str,
        signature: &str,
        allow_self_approval: bool,
    ) -> Result<StoredDecision, DbError> {
        let rel = |e: ReleaseError| DbError::Release(e);
        let key = approval::public_key(public_key).map_err(|e| rel(e.into()))?;
        approval::verify(public_key, decision, signature).map_err(|e| rel(e.into()))?;
        let fingerprint = approval::fingerprint(&key);
        let target = self.target();
        let number = decision.number.clone();
        self.retried(|conn| {
            conn.transaction(|tx| {
                let signer = signers_where(tx, "s.public_key = $1", &[public_key.to_string().into()])?
                    .pop()
                    .ok_or_else(|| rel(ReleaseError::UnknownKey { fingerprint: fingerprint.clone() }))?;
                if let Some(r) = &signer.revoked {
                    return Err(rel(ReleaseError::Revoked {
                        name: signer.name.clone(),
                        fingerprint: signer.fingerprint.clone(),
                        reason: r.reason.clone(),
                    }));
                }
                let found = tx.query(
                    "SELECT n.run_id, r.operator FROM certificate_number n JOIN certificate c ON c.run_id = n.run_id \
                     JOIN run r ON r.run_id = n.run_id WHERE n.number = $1 \
                     UNION ALL SELECT a.run_id, r.operator FROM amendment a JOIN run r ON r.run_id = a.run_id \
                     WHERE a.number = $1",
                    &[number.clone().into()],
                )?;
                let Some(f) = found.first() else {
                    return Err(rel(ReleaseError::NoCertificate { number: number.clone(), target: target.clone() }));
                };
                let run_id = f[0].text()?;
                let operator = f[1].text()?;
                if !tx.query("SELECT 1 FROM void WHERE run_id = $1", &[run_id.clone().into()])?.is_empty() {
                    return Err(rel(ReleaseError::Voided { number: number.clone(), run_id }));
                }
                if let Some(s) = superseded(tx, &number)? {
                    return Err(rel(ReleaseError::Superseded { number: number.clone(), by: s.by }));
                }
                if let Some(d) = decided(tx, &number)? {
                    return Err(rel(ReleaseError::Decided {
                        number: number.clone(),
                        meaning: d.decision.meaning.as_str().into(),
                        name: d.signer.name,
                        date: date_of(d.decision.unix_s),
                    }));
                }
                if decision.meaning == Meaning::Approved && operator == signer.name && !allow_self_approval {
                    return Err(rel(ReleaseError::SelfApproval { name: signer.name.clone(), run_id }));
                }
                if let Err(mut m) = chain::verify_run(tx, &run_id)? {
                    let first = m.remove(0);
                    return Err(DbError::Tampered { run_id, first: Box::new(first), more: m.len() });
                }
                let sha = sha256_hex(approval_content(decision, &signer.fingerprint, signature)?.as_bytes());
                let row: Vec<Val> = vec![
                    run_id.clone().into(),
                    number.clone().into(),
                    decision.document_sha256.clone().into(),
                    decision.meaning.as_str().into(),
                    decision.reason.clone().into(),
                    signer.fingerprint.clone().into(),
                    signature.to_string().into(),
                    decision.unix_s.into(),
                    sha.into(),
                ];
                insert_row(tx, chain::table("approval"), &row)?;
                Ok(StoredDecision {
                    decision: decision.clone(),
                    run_id: RunId::parse(&run_id)?,
                    signer,
                    signature: signature.to_string(),
                })
            })
        })
    }

    /// The decision on certificate `number`, `None` while it awaits approval.
    pub fn decision(&mut self, number: &str) -> Result<Option<StoredDecision>, DbError> {
        let n = number.to_string();
        self.conn.reading(|tx| decided(tx, &n))
    }
}

/// The decision stored for certificate `number`.
fn decided(tx: &mut Tx<'_>, number: &str) -> Result<Option<StoredDecision>, DbError> {
    let t = chain::table("approval");
    let rows = tx.query(
        &format!("SELECT {} FROM approval WHERE number = $1", t.columns.join(", ")),
        &[number.to_string().into()],
    )?;
    let Some(row) = rows.first() else { return Ok(None) };
    let fp = row[5].text()?;
    let signer = signers_where(tx, "s.fingerprint = $1", &[fp.clone().into()])?
        .pop()
        .ok_or_else(|| DbError::schema(format!("the approval of {number} names no registered key ({fp})")))?;
    Ok(Some(StoredDecision {
        decision: decision_of_row(row)?,
        run_id: RunId::parse(&row[0].text()?)?,
        signer,
        signature: row[6].text()?,
    }))
}

/// A certificate replaced by an amendment.
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize)]
pub struct Supersession {
    /// The amendment's number.
    pub by: String,
    /// Why it was amended.
    pub reason: String,
    /// When, Unix seconds.
    pub unix_s: i64,
}

impl Supersession {
    /// What the replaced certificate's printed copies state of it.
    pub fn note(&self) -> accelcal_core::certificate::Superseded {
        accelcal_core::certificate::Superseded { by: self.by.clone(), reason: self.reason.clone() }
    }
}

/// The amendment that replaced certificate `number`, if one did.
pub(crate) fn superseded(tx: &mut Tx<'_>, number: &str) -> Result<Option<Supersession>, DbError> {
    tx.query(
        "SELECT number, reason, issued_unix_s FROM amendment WHERE replaces = $1",
        &[number.to_string().into()],
    )?
    .first()
    .map(|r| Ok(Supersession { by: r[0].text()?, reason: r[1].text()?, unix_s: r[2].int()? }))
    .transpose()
}
