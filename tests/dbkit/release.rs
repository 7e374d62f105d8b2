//! Issue 57 on both engines: signers, decisions and amendments through the database's own API
//! (`tests/db.rs` runs it on SQLite, `tests/db_pg.rs` on PostgreSQL). The command-line flow
//! with real certificates is `tests/line/release.rs`.

use accelcal_core::certificate::approval::{self, Decision, Meaning};
use accelcal_db::signer::NewSigner;
use accelcal_db::{CertificateState, Db, DbError, ReleaseError, RunId};

use super::*;

/// A decision signed with `key`.
fn signed(
    key: &approval::SigningKey,
    number: &str,
    sha: &str,
    meaning: Meaning,
    reason: &str,
) -> (Decision, String) {
    let d = Decision {
        number: number.into(),
        document_sha256: sha.into(),
        meaning,
        reason: reason.into(),
        unix_s: T0,
    };
    let s = approval::sign(key, &d).unwrap();
    (d, s)
}

/// The state `history` gives a unit's run.
fn state(db: &mut Db, serial: &str) -> (Option<CertificateState>, Option<String>, Vec<String>) {
    let runs = db.unit_runs(serial).unwrap();
    let r = runs.last().unwrap();
    (r.certificate_state, r.certificate_number.clone(), r.superseded_certificates.clone())
}

/// A numbered, stored certificate is approved by a registered signer once; the operator, a
/// revoked key and a second decision are refused with nothing stored; an amendment takes the
/// next number, supersedes the first, awaits approval, and is rejected; the chain of numbers
/// goes on, and every row is in the hash chain.
pub fn signers_decide_and_amend(spec: &str) {
    let mut db = Db::open(spec).unwrap();
    let s = start(RunId::new(), DEVICE, "SN-R1", "st-1", T0);
    db.begin_run(&s, None).unwrap();
    let run = s.run_id;
    let first = db.certificate_number(run).unwrap().number;
    db.store_certificate(run, "<html>first</html>").unwrap();
    let reviewer = approval::generate().unwrap();
    let operator = approval::generate().unwrap();
    let add = |db: &mut Db, name: &str, key: &approval::SigningKey| {
        db.add_signer(&NewSigner {
            name: name.into(),
            function: "Head of laboratory".into(),
            public_key: approval::public_hex(&key.verifying_key()),
            operator: "qa".into(),
        })
        .unwrap()
    };
    add(&mut db, "Dr. R", &reviewer);
    add(&mut db, &s.operator, &operator);
    let rows = |db: &mut Db| db.verify_chain().unwrap().entries;
    let sha = "ab".repeat(32);
    let n = rows(&mut db);
    // The operator approving their own run, then with their key revoked: refused, nothing stored.
    let (d, sig) = signed(&operator, &first, &sha, Meaning::Approved, "");
    let public = approval::public_hex(&operator.verifying_key());
    let e = db.decide(&d, &public, &sig, false).unwrap_err();
    assert!(matches!(e, DbError::Release(ReleaseError::SelfApproval { .. })), "{e}");
    db.revoke_signer(&s.operator, "left", "qa").unwrap();
    let e = db.decide(&d, &public, &sig, true).unwrap_err();
    assert!(matches!(e, DbError::Release(ReleaseError::Revoked { .. })), "{e}");
    assert_eq!(rows(&mut db), n + 1, "the revocation only");
    // A signature over another decision: refused.
    let (d2, _) = signed(&reviewer, &first, &sha, Meaning::Approved, "");
    let rpub = approval::public_hex(&reviewer.verifying_key());
    assert!(db.decide(&d2, &rpub, &sig, false).is_err());
    assert_eq!(
        state(&mut db, "SN-R1"),
        (Some(CertificateState::AwaitingApproval), Some(first.clone()), vec![])
    );
    // Approved, once.
    let (d, sig) = signed(&reviewer, &first, &sha, Meaning::Approved, "");
    db.decide(&d, &rpub, &sig, false).unwrap();
    let (r, rsig) = signed(&reviewer, &first, &sha, Meaning::Rejected, "late");
    let e = db.decide(&r, &rpub, &rsig, false).unwrap_err();
    assert!(matches!(e, DbError::Release(ReleaseError::Decided { .. })), "{e}");
    assert_eq!(state(&mut db, "SN-R1").0, Some(CertificateState::Approved));

    // Amended: the next number, the first superseded, the amendment awaiting approval.
    let a =
        db.amend(&first, "address corrected", "qa", |n| Ok(format!("<html>{}</html>", n.number))).unwrap();
    let second = a.number.number.clone();
    assert_eq!(a.number.sequence, 2);
    assert_eq!(
        state(&mut db, "SN-R1"),
        (Some(CertificateState::AwaitingApproval), Some(second.clone()), vec![first.clone()])
    );
    assert_eq!(db.run_of_certificate(&second).unwrap(), Some(run));
    assert_eq!(db.number_in_force(run).unwrap(), Some(second.clone()));
    let c = db.certificate_of_number(&first).unwrap().unwrap();
    assert_eq!(c.superseded.as_ref().map(|s| s.by.as_str()), Some(second.as_str()));
    let c = db.certificate_of_number(&second).unwrap().unwrap();
    assert_eq!(c.html, format!("<html>{second}</html>"));
    assert_eq!(c.replaces, Some((first.clone(), "address corrected".into())));
    // The replaced one is neither amended nor decided again; a page that fails stores nothing.
    let n = rows(&mut db);
    assert!(matches!(db.amend(&first, "again", "qa", |_| Ok(String::new())), Err(DbError::Conflict { .. })));
    assert!(db.amend(&second, "again", "qa", |_| Err("no page".into())).is_err());
    let (d, sig) = signed(&reviewer, &first, &sha, Meaning::Approved, "");
    let e = db.decide(&d, &rpub, &sig, false).unwrap_err();
    assert!(matches!(e, DbError::Release(ReleaseError::Superseded { .. })), "{e}");
    assert_eq!(rows(&mut db), n);
    // The amendment rejected; another run's first certificate takes the next number after it.
    let (r, rsig) = signed(&reviewer, &second, &sha, Meaning::Rejected, "wrong customer");
    db.decide(&r, &rpub, &rsig, false).unwrap();
    assert_eq!(state(&mut db, "SN-R1").0, Some(CertificateState::Rejected));
    let other = start(RunId::new(), DEVICE, "SN-R1", "st-1", T0 + DAY);
    db.begin_run(&other, None).unwrap();
    assert_eq!(db.certificate_number(other.run_id).unwrap().sequence, 3, "one sequence for both");
    let third = db.amend(&second, "corrected again", "qa", |n| Ok(n.number.clone())).unwrap();
    assert_eq!(third.number.sequence, 4);
    let c = db.certificate_of_number(&first).unwrap().unwrap();
    assert_eq!(c.superseded.map(|s| s.by), Some(second.clone()), "replaced by the next, not the last");
    let r = db.verify_chain().unwrap();
    assert!(r.mismatches.is_empty(), "{:?}", r.mismatches);
}
