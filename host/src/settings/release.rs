//! The settled command lines of `signer add|revoke|list`, `approve` and `reject`: names and
//! reasons one line each (`check_text` did that), the key file not the database nor the
//! passphrase file, the certificate number written as one, and `--config`'s
//! `allow_self_approval` read and checked before the database or the key is opened.

use std::path::PathBuf;

use accelcal_core::certificate::approval::Meaning;
use accelcal_core::error::bad;

use crate::cli::{AmendArgs, DecideArgs, RejectArgs, SignerAddArgs, SignerCommand};

/// `accelcal signer …`, settled.
#[derive(Clone, Debug, PartialEq)]
pub enum Signer {
    /// `signer add`.
    Add(AddSigner),
    /// `signer revoke`.
    Revoke {
        /// `--db` as given.
        db: Option<String>,
        /// The signer.
        name: String,
        /// `--reason`.
        reason: String,
        /// `--operator`.
        operator: Option<String>,
    },
    /// `signer list`.
    List {
        /// `--db` as given.
        db: Option<String>,
        /// `--json`.
        json: bool,
    },
}

/// `accelcal signer add`, settled.
#[derive(Clone, Debug, PartialEq)]
pub struct AddSigner {
    /// `--db` as given.
    pub db: Option<String>,
    /// The signer's name.
    pub name: String,
    /// `--function`.
    pub function: String,
    /// `--key`: created, never overwritten.
    pub key: PathBuf,
    /// `--passphrase-file`, else the terminal.
    pub passphrase_file: Option<PathBuf>,
    /// `--operator`.
    pub operator: Option<String>,
}

/// `accelcal approve` or `reject`, settled.
#[derive(Clone, Debug, PartialEq)]
pub struct Decide {
    /// `--db` as given.
    pub db: Option<String>,
    /// The certificate's number.
    pub number: String,
    /// Approve or reject.
    pub meaning: Meaning,
    /// A rejection's `--reason` (empty for an approval).
    pub reason: String,
    /// `--key`.
    pub key: PathBuf,
    /// `--passphrase-file`, else the terminal.
    pub passphrase_file: Option<PathBuf>,
    /// `--config`'s `allow_self_approval` (false without it).
    pub allow_self_approval: bool,
}

/// `accelcal amend`, settled.
#[derive(Clone, Debug, PartialEq)]
pub struct Amend {
    /// `--db` as given.
    pub db: Option<String>,
    /// The certificate amended.
    pub number: String,
    /// `--reason`.
    pub reason: String,
    /// `--operator`.
    pub operator: Option<String>,
}

/// `amend`'s settings from its command line.
pub fn amend(a: &AmendArgs) -> anyhow::Result<Amend> {
    number(&a.number)?;
    nonempty("--reason", &a.reason)?;
    accelcal_core::text::single_line("--reason", &a.reason)?;
    if let Some(spec) = crate::cmd::store::named_db(a.reader.db.as_deref()) {
        super::values::existing_db(&spec, "amend")?;
    }
    Ok(Amend {
        db: a.reader.db.clone(),
        number: a.number.clone(),
        reason: a.reason.clone(),
        operator: a.operator.clone(),
    })
}

/// Refuses what is not written as a certificate number.
fn number(n: &str) -> anyhow::Result<()> {
    if accelcal_db::certificate::is_number(n) {
        Ok(())
    } else {
        Err(bad(format!("{n:?} is not a certificate number (YYYY-NNNNNN, as printed on it)")))
    }
}

/// `signer …`'s settings from its command line.
pub fn signer(c: &SignerCommand) -> anyhow::Result<Signer> {
    Ok(match c {
        SignerCommand::Add(a) => Signer::Add(add(a)?),
        SignerCommand::Revoke(a) => {
            nonempty("the signer's name", &a.name)?;
            nonempty("--reason", &a.reason)?;
            Signer::Revoke {
                db: a.reader.db.clone(),
                name: a.name.clone(),
                reason: a.reason.clone(),
                operator: a.operator.clone(),
            }
        }
        SignerCommand::List(a) => Signer::List { db: a.reader.db.clone(), json: a.json },
    })
}

fn add(a: &SignerAddArgs) -> anyhow::Result<AddSigner> {
    nonempty("the signer's name", &a.name)?;
    nonempty("--function", &a.function)?;
    if a.passphrase_file.as_ref() == Some(&a.key) {
        return Err(bad(format!("--passphrase-file and --key are the same file {}", a.key.display())));
    }
    if a.reader.db.as_deref().map(std::path::Path::new) == Some(a.key.as_path()) {
        return Err(bad(format!("--key {} is the database", a.key.display())));
    }
    Ok(AddSigner {
        db: a.reader.db.clone(),
        name: a.name.clone(),
        function: a.function.clone(),
        key: a.key.clone(),
        passphrase_file: a.passphrase_file.clone(),
        operator: a.operator.clone(),
    })
}

/// `approve`'s settings from its command line.
pub fn approve(a: &DecideArgs) -> anyhow::Result<Decide> {
    decide(a, Meaning::Approved, String::new())
}

/// `reject`'s settings from its command line.
pub fn reject(a: &RejectArgs) -> anyhow::Result<Decide> {
    nonempty("--reason", &a.reason)?;
    decide(&a.decide, Meaning::Rejected, a.reason.clone())
}

fn decide(a: &DecideArgs, meaning: Meaning, reason: String) -> anyhow::Result<Decide> {
    number(&a.number)?;
    if a.passphrase_file.as_ref() == Some(&a.key) {
        return Err(bad(format!("--passphrase-file and --key are the same file {}", a.key.display())));
    }
    // A decision is on a stored certificate: a missing database file is refused, not created.
    if let Some(spec) = crate::cmd::store::named_db(a.reader.db.as_deref()) {
        super::values::existing_db(&spec, if meaning == Meaning::Approved { "approve" } else { "reject" })?;
    }
    let allow_self_approval = match &a.config {
        Some(path) => super::station_config::allow_self_approval(path)?,
        None => false,
    };
    Ok(Decide {
        db: a.reader.db.clone(),
        number: a.number.clone(),
        meaning,
        reason,
        key: a.key.clone(),
        passphrase_file: a.passphrase_file.clone(),
        allow_self_approval,
    })
}

fn nonempty(what: &str, v: &str) -> anyhow::Result<()> {
    if v.trim().is_empty() {
        return Err(bad(format!("{what} is empty")));
    }
    Ok(())
}
