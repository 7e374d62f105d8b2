//! `accelcal signer add|revoke|list`: the people who may release certificates
//! ([`accelcal_db::signer`]). `add` creates the signer's key file (Ed25519, encrypted PKCS#8:
//! [`accelcal_core::certificate::approval::key_file`]) and registers its public half.

use std::io::Write;
use std::os::unix::fs::OpenOptionsExt;
use std::path::Path;

use accelcal_core::certificate::approval;
use accelcal_core::error::{bad, environment};
use accelcal_db::signer::{date_of, NewSigner};
use accelcal_db::Db;

use super::store::{named_db, reader_spec, user_name, DEFAULT_DB};
use crate::settings::release::{AddSigner, Signer};

/// Runs `accelcal signer …`.
pub fn run(s: &Signer) -> anyhow::Result<()> {
    match s {
        Signer::Add(a) => add(a),
        Signer::Revoke { db, name, reason, operator } => {
            let mut db = Db::open(&reader_spec(db.as_deref())?)?;
            let operator = operator.clone().unwrap_or_else(user_name);
            let k = db.revoke_signer(name, reason, &operator)?;
            outln!("signer: {name}'s key {} revoked in {}: {reason}", k.fingerprint, db.target())?;
            Ok(())
        }
        Signer::List { db, json } => {
            let mut db = Db::open_existing(&reader_spec(db.as_deref())?)?;
            let list = db.signers()?;
            if *json {
                outln!("{}", serde_json::to_string_pretty(&list)?)?;
                return Ok(());
            }
            if list.is_empty() {
                outln!("signer: no signer is registered in {}", db.target())?;
            }
            for k in &list {
                let state = match &k.revoked {
                    Some(r) => format!("revoked {} ({})", date_of(r.revoked_unix_s), r.reason),
                    None => "in force".into(),
                };
                outln!(
                    "{} ({}), key {}, registered {}: {state}",
                    k.name,
                    k.function,
                    k.fingerprint,
                    date_of(k.registered_unix_s)
                )?;
            }
            Ok(())
        }
    }
}

fn add(a: &AddSigner) -> anyhow::Result<()> {
    if a.key.exists() {
        return Err(bad(format!("--key {} exists: a key file is never overwritten", a.key.display())));
    }
    let spec = named_db(a.db.as_deref()).unwrap_or_else(|| DEFAULT_DB.into());
    let mut db = Db::open(&spec)?;
    let passphrase = super::passphrase(a.passphrase_file.as_deref(), &format!("{}'s new key", a.name), true)?;
    let key = approval::generate()?;
    let text = approval::key_file(&key, &passphrase)?;
    write_new(&a.key, &text)?;
    let registered = db.add_signer(&NewSigner {
        name: a.name.clone(),
        function: a.function.clone(),
        public_key: approval::public_hex(&key.verifying_key()),
        operator: a.operator.clone().unwrap_or_else(user_name),
    });
    let k = match registered {
        Ok(k) => k,
        Err(e) => {
            // Not registered: the key file would sign nothing.
            let _ = std::fs::remove_file(&a.key);
            return Err(e.into());
        }
    };
    outln!(
        "signer: {} ({}) registered in {} with key {}; the key is in {} (encrypted with the passphrase)",
        k.name,
        k.function,
        db.target(),
        k.fingerprint,
        a.key.display()
    )?;
    Ok(())
}

/// Creates `path` (mode 0600) with `text`; refused when it exists.
fn write_new(path: &Path, text: &str) -> anyhow::Result<()> {
    let mut f = match std::fs::OpenOptions::new().write(true).create_new(true).mode(0o600).open(path) {
        Ok(f) => f,
        Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {
            return Err(bad(format!("--key {} exists: a key file is never overwritten", path.display())))
        }
        Err(e) => return Err(environment(format!("creating the key file {}", path.display()), e)),
    };
    let written = f.write_all(text.as_bytes()).and_then(|()| f.sync_all());
    if let Err(e) = written {
        let _ = std::fs::remove_file(path);
        return Err(environment(format!("writing the key file {}", path.display()), e));
    }
    Ok(())
}
