//! Issue 57 item 3: a station's certificate awaits approval; a registered signer approves it
//! with their key (`signer add`, `approve`), and what is refused stores nothing.

use std::path::Path;

use super::*;

/// The ledger's row count (every stored row has one entry): what a refused decision leaves.
fn ledger_rows(db: &Path) -> i64 {
    let c = rusqlite::Connection::open(db).unwrap();
    c.query_row("SELECT COUNT(*) FROM ledger", [], |r| r.get(0)).unwrap()
}

/// Runs accelcal; its exit code and stderr.
fn refused(args: &[&str]) -> (Option<i32>, String) {
    let out = common::accelcal(args);
    (out.status.code(), String::from_utf8_lossy(&out.stderr).into_owned())
}

/// The flow on the database of a station run (`dir` holds `calibration.sqlite` and the unit's
/// `certificate.pdf`), whose certificate is `number`: the
/// draft's every page is marked; a wrong passphrase, the operator approving their own run and
/// a revoked key are refused with nothing stored; a signer approves; a second decision is
/// refused; the approved certificate's PDF names the signer, their function and key
/// fingerprint and carries no DRAFT mark.
pub fn approve_a_station_certificate(dir: &Path, unit: &Path, number: &str, named: &str) {
    let db = dir.join("calibration.sqlite");
    let operator: String = rusqlite::Connection::open(&db)
        .unwrap()
        .query_row("SELECT operator FROM run", [], |r| r.get(0))
        .unwrap();
    let operator = operator.as_str();
    let dbs = db.to_str().unwrap();
    let pages = certificate_pdf(&unit.join("certificate.pdf"), named, &[]);
    assert!(pages.iter().all(|p| p.contains("DRAFT — awaiting approval")), "{pages:?}");
    let pass = dir.join("pass.txt");
    std::fs::write(&pass, "right horse\n").unwrap();
    let wrong = dir.join("wrong.txt");
    std::fs::write(&wrong, "wrong horse\n").unwrap();
    let key = dir.join("reviewer.key");
    let p = pass.to_str().unwrap();
    let k = key.to_str().unwrap();
    let out = common::succeed(&[
        "signer",
        "add",
        "Dr. A. Reviewer",
        "--function",
        "Head of laboratory",
        "--key",
        k,
        "--passphrase-file",
        p,
        "--db",
        dbs,
    ]);
    let text = String::from_utf8_lossy(&out.stdout);
    let fp = text.split("with key ").nth(1).unwrap()[..16].to_string();
    assert!(std::fs::read_to_string(&key).unwrap().starts_with("-----BEGIN ENCRYPTED PRIVATE KEY-----"));
    // A key file is never overwritten.
    let before = std::fs::read(&key).unwrap();
    let (code, err) = refused(&[
        "signer",
        "add",
        "B. Other",
        "--function",
        "Deputy",
        "--key",
        k,
        "--passphrase-file",
        p,
        "--db",
        dbs,
    ]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("exists: a key file is never overwritten"), "{err}");
    assert_eq!(std::fs::read(&key).unwrap(), before);

    // A database that is not there is refused, not created.
    let nowhere = dir.join("no-such.sqlite");
    let (code, err) =
        refused(&["approve", number, "--key", k, "--passphrase-file", p, "--db", nowhere.to_str().unwrap()]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("no such database: approve appends to an existing database"), "{err}");
    assert!(!nowhere.exists());

    // A wrong passphrase: refused, nothing stored.
    let n = ledger_rows(&db);
    let (code, err) =
        refused(&["approve", number, "--key", k, "--passphrase-file", wrong.to_str().unwrap(), "--db", dbs]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("does not open with this passphrase"), "{err}");
    assert_eq!(ledger_rows(&db), n);

    // The run's operator approving it: refused unless the settings allow it; nothing stored.
    let own = dir.join("operator.key");
    common::succeed(&[
        "signer",
        "add",
        operator,
        "--function",
        "Operator",
        "--key",
        own.to_str().unwrap(),
        "--passphrase-file",
        p,
        "--db",
        dbs,
    ]);
    let n = ledger_rows(&db);
    let (code, err) =
        refused(&["approve", number, "--key", own.to_str().unwrap(), "--passphrase-file", p, "--db", dbs]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains(&format!("{operator} operated run")), "{err}");
    assert_eq!(ledger_rows(&db), n);
    // Revoked: refused, nothing stored but the revocation.
    common::succeed(&["signer", "revoke", operator, "--reason", "left the laboratory", "--db", dbs]);
    let n = ledger_rows(&db);
    let config = dir.join("approval.toml");
    std::fs::write(&config, "allow_self_approval = true\n").unwrap();
    let (code, err) = refused(&[
        "approve",
        number,
        "--key",
        own.to_str().unwrap(),
        "--passphrase-file",
        p,
        "--config",
        config.to_str().unwrap(),
        "--db",
        dbs,
    ]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("was revoked (left the laboratory)"), "{err}");
    assert_eq!(ledger_rows(&db), n);
    let list =
        String::from_utf8_lossy(&common::succeed(&["signer", "list", "--db", dbs]).stdout).into_owned();
    assert!(list.contains("Dr. A. Reviewer (Head of laboratory)") && list.contains("revoked"), "{list}");

    // Approved, once.
    let out = common::succeed(&["approve", number, "--key", k, "--passphrase-file", p, "--db", dbs]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("approved for issue by Dr. A. Reviewer (Head of laboratory)"), "{text}");
    assert_eq!(ledger_rows(&db), n + 1);
    let (code, err) = refused(&[
        "reject",
        number,
        "--key",
        k,
        "--passphrase-file",
        p,
        "--reason",
        "second thoughts",
        "--db",
        dbs,
    ]);
    assert_eq!(code, Some(2), "{err}");
    assert!(
        err.contains(&format!("certificate {number} was approved for issue already, by Dr. A. Reviewer")),
        "{err}"
    );
    assert_eq!(ledger_rows(&db), n + 1);
    common::succeed(&["db", "verify", "--db", dbs]);

    // Printed again: approved, with the signer's name, function and key; no draft mark.
    let pdf = dir.join("approved.pdf");
    common::succeed(&["certificate", number, "--pdf", pdf.to_str().unwrap(), "--db", dbs]);
    let pages = certificate_pdf(&pdf, named, &["Dr. A. Reviewer", "Head of laboratory", &fp]);
    assert!(pages.iter().all(|p| !p.contains("DRAFT")), "{pages:?}");
    let fleet =
        String::from_utf8_lossy(&common::succeed(&["history", "A-1", "--db", dbs]).stdout).into_owned();
    assert!(fleet.contains(&format!("certificate: {number} approved")), "{fleet}");

    // Anyone checks the approved PDF offline (its document and the decision it carries), and
    // against the database.
    let pdfs = pdf.to_str().unwrap();
    let out = common::succeed(&["certificate", "verify", pdfs]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.starts_with(&format!("valid: certificate {number} of unit A-1")), "{text}");
    assert!(text.contains("approved for issue by Dr. A. Reviewer (Head of laboratory) on 20"), "{text}");
    assert!(text.contains(&format!("signing key {fp}")), "{text}");
    let out = common::succeed(&["certificate", "verify", pdfs, "--db", dbs]);
    assert!(String::from_utf8_lossy(&out.stdout).contains("the database holds the same"));
    // The draft the station wrote is not what the database now holds: it carries no decision.
    let draft = unit.join("certificate.pdf");
    common::succeed(&["certificate", "verify", draft.to_str().unwrap()]);
    let (code, err) = refused(&["certificate", "verify", draft.to_str().unwrap(), "--db", dbs]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("the file carries no decision"), "{err}");
    // One byte of the pages changed: refused, naming where.
    let mut bytes = std::fs::read(&pdf).unwrap();
    let at = bytes.len() / 3;
    bytes[at] ^= 0x20;
    let edited = dir.join("edited.pdf");
    std::fs::write(&edited, &bytes).unwrap();
    let (code, err) = refused(&["certificate", "verify", edited.to_str().unwrap()]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("not valid: "), "{err}");
    // The DCC of the approved certificate names its authoriser and checks offline.
    let dcc = dir.join("approved.xml");
    common::succeed(&["certificate", number, "--dcc", dcc.to_str().unwrap(), "--db", dbs]);
    let xml = std::fs::read_to_string(&dcc).unwrap();
    assert!(xml.contains("Dr. A. Reviewer"), "{xml}");
    let out = common::succeed(&["certificate", "verify", dcc.to_str().unwrap(), "--db", dbs]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("approved for issue by Dr. A. Reviewer (Head of laboratory)"), "{text}");
    // The decision in the DCC edited (a rejection made an approval): its signature fails.
    let forged =
        xml.replace("<dcc:mainSigner>true</dcc:mainSigner>", "<dcc:mainSigner>false</dcc:mainSigner>");
    let forged_path = dir.join("forged.xml");
    std::fs::write(&forged_path, forged).unwrap();
    let (code, err) = refused(&["certificate", "verify", forged_path.to_str().unwrap()]);
    assert_eq!(code, Some(2), "{err}");

    amend_the_certificate(dir, number, named, k, p);
}

/// The first word of `text` after `after`: a certificate number a command printed.
fn number_after(text: &str, after: &str) -> String {
    let at = text.find(after).unwrap_or_else(|| panic!("{after:?} in {text}")) + after.len();
    text[at..].split(|c: char| c.is_whitespace()).next().unwrap().to_string()
}

/// A page's words joined by single spaces (pdftotext lays a table out in columns).
fn flat(page: &str) -> String {
    page.split_whitespace().collect::<Vec<_>>().join(" ")
}

/// Item 7: the approved certificate `number` amended; the amendment awaits approval and is
/// rejected; amended again and approved: a chain of three numbers for one run. The replaced
/// ones are superseded everywhere and still print as they were, marked so, and what is refused
/// stores nothing.
fn amend_the_certificate(dir: &Path, number: &str, named: &str, k: &str, p: &str) {
    let db = dir.join("calibration.sqlite");
    let dbs = db.to_str().unwrap();
    let n = ledger_rows(&db);
    let out = common::succeed(&["amend", number, "--reason", "customer address corrected", "--db", dbs]);
    let text = String::from_utf8_lossy(&out.stdout).into_owned();
    let second = number_after(&text, "amend: certificate ");
    assert!(text.contains(&format!("replaces {number}: customer address corrected")), "{text}");
    assert_ne!(second, number);
    assert_eq!(ledger_rows(&db), n + 1, "one row, chained");
    // The replaced certificate is neither amended nor decided again: nothing stored.
    let (code, err) = refused(&["amend", number, "--reason", "again", "--db", dbs]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains(&format!("was replaced already, by {second}")), "{err}");
    let (code, err) =
        refused(&["reject", number, "--key", k, "--passphrase-file", p, "--reason", "late", "--db", dbs]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains(&format!("was replaced by amendment {second}")), "{err}");
    assert_eq!(ledger_rows(&db), n + 1);
    let history = |dbs: &str| {
        String::from_utf8_lossy(&common::succeed(&["history", "A-1", "--db", dbs]).stdout).into_owned()
    };
    let h = history(dbs);
    assert!(h.contains(&format!("certificate: {second} awaiting approval; superseded: {number}")), "{h}");

    // The original prints as it was released (approved), every page marked superseded; the
    // PDF checks offline and says so, and the database agrees.
    let old = dir.join("superseded.pdf");
    common::succeed(&["certificate", number, "--pdf", old.to_str().unwrap(), "--db", dbs]);
    let pages = certificate_pdf(&old, named, &["Dr. A. Reviewer"]);
    let mark = format!("SUPERSEDED by certificate {second}: customer address corrected");
    assert!(pages.iter().all(|pg| flat(pg).contains(&mark)), "{pages:?}");
    let out = common::succeed(&["certificate", "verify", old.to_str().unwrap(), "--db", dbs]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        text.contains(&format!("superseded by amendment {second} (customer address corrected)")),
        "{text}"
    );
    // The approved PDF printed before the amendment is still the document it was, and the
    // database says it is no longer in force.
    let before = dir.join("approved.pdf");
    let out = common::succeed(&["certificate", "verify", before.to_str().unwrap(), "--db", dbs]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains(&format!("says amendment {second} replaced it")), "{text}");
    assert!(text.contains("it is not in force"), "{text}");
    // No DCC is given for a superseded certificate.
    let (code, err) =
        refused(&["certificate", number, "--dcc", dir.join("old.xml").to_str().unwrap(), "--db", dbs]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("for the certificate in force only"), "{err}");

    // The amendment: a draft stating what it replaces and why, under its own number.
    let amended = dir.join("amended.pdf");
    common::succeed(&["certificate", &second, "--pdf", amended.to_str().unwrap(), "--db", dbs]);
    let pages = certificate_pdf(&amended, named, &[&format!("No. {second}")]);
    assert!(pages.iter().all(|pg| pg.contains("DRAFT — awaiting approval")), "{pages:?}");
    let first = flat(&pages[0]);
    assert!(
        first.contains("Replaces") && first.contains(&format!("certificate {number}, which this amendment")),
        "{first}"
    );
    common::succeed(&["certificate", "verify", amended.to_str().unwrap(), "--db", dbs]);

    // Rejected, with a reason on every page; then amended again and approved.
    let out = common::succeed(&[
        "reject",
        &second,
        "--key",
        k,
        "--passphrase-file",
        p,
        "--reason",
        "wrong customer",
        "--db",
        dbs,
    ]);
    assert!(String::from_utf8_lossy(&out.stdout).contains("the unit is not released"));
    let rejected = dir.join("rejected.pdf");
    common::succeed(&["certificate", &second, "--pdf", rejected.to_str().unwrap(), "--db", dbs]);
    let pages = certificate_pdf(&rejected, named, &[]);
    assert!(pages.iter().all(|pg| flat(pg).contains("REJECTED — not released: wrong customer")), "{pages:?}");
    assert!(history(dbs).contains(&format!("certificate: {second} rejected; superseded: {number}")));
    let out = common::succeed(&["amend", &second, "--reason", "customer corrected again", "--db", dbs]);
    let third = number_after(&String::from_utf8_lossy(&out.stdout), "amend: certificate ");
    common::succeed(&["approve", &third, "--key", k, "--passphrase-file", p, "--db", dbs]);
    let h = history(dbs);
    assert!(h.contains(&format!("certificate: {third} approved; superseded: {number}, {second}")), "{h}");
    let last = dir.join("third.pdf");
    common::succeed(&["certificate", &third, "--pdf", last.to_str().unwrap(), "--db", dbs]);
    let pages = certificate_pdf(&last, named, &["Dr. A. Reviewer"]);
    assert!(pages.iter().all(|pg| !pg.contains("DRAFT") && !pg.contains("SUPERSEDED")), "{pages:?}");
    assert!(flat(&pages[0]).contains(&format!("certificate {second}, which this amendment")), "{pages:?}");
    let out = common::succeed(&["certificate", "verify", last.to_str().unwrap(), "--db", dbs]);
    assert!(String::from_utf8_lossy(&out.stdout).contains("the database holds the same"));
    // The run's certificate in force is the last one: printing by run id gives it.
    let run: String = rusqlite::Connection::open(&db)
        .unwrap()
        .query_row("SELECT run_id FROM amendment LIMIT 1", [], |r| r.get(0))
        .unwrap();
    let by_run = dir.join("by-run.html");
    let out = common::succeed(&["certificate", &run, "-o", by_run.to_str().unwrap(), "--db", dbs]);
    assert!(String::from_utf8_lossy(&out.stdout).contains(&format!("certificate {third} (run {run})")));
    common::succeed(&["db", "verify", "--db", dbs]);
}
