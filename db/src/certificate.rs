//! Certificate numbers (schema 4) and the recalibration date a certificate states (schema 5):
//! given once per run in one transaction, the same when the certificate is printed again.

use super::content::{amendment_content, certificate_number_content, recalibration_due_content};
use super::engine::{Tx, Val};
use super::signer::superseded;
pub use super::signer::Supersession;
use super::{chain, insert_row, now_unix_s, sha256_hex, Db, DbError, RunId};

/// A certificate's number ([`Db::certificate_number`]).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct CertificateNumber {
    /// Its place among the database's certificates, from 1.
    pub sequence: i64,
    /// As printed: `YEAR-SEQUENCE` (`2026-000017`).
    pub number: String,
    /// When it was given, Unix seconds.
    pub issued_unix_s: i64,
}

/// The recalibration date a certificate states ([`Db::certificate_number_with_due`]).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RecalibrationDue {
    /// The date, Unix seconds.
    pub due_unix_s: i64,
    /// What set it, in words.
    pub basis: String,
}

/// Whether `s` is written as a certificate number is (`2026-000017`: a year, a dash, six or
/// more digits), as opposed to a run id.
pub fn is_number(s: &str) -> bool {
    match s.split_once('-') {
        Some((y, n)) => {
            y.len() == 4 && n.len() >= 6 && y.bytes().chain(n.bytes()).all(|b| b.is_ascii_digit())
        }
        None => false,
    }
}

impl Db {
    /// The number of run `run`'s certificate: the one it was given, else the next one, stored
    /// (`certificate_number`: the largest sequence plus one, `YEAR-SEQUENCE`). A number is
    /// never given twice, and a run has one: printing its certificate again prints the same.
    /// Refused for a voided run, and (a new number) for a finished one.
    pub fn certificate_number(&mut self, run: RunId) -> Result<CertificateNumber, DbError> {
        self.number(run, None).map(|(n, _)| n)
    }

    /// [`Db::certificate_number`], and the recalibration date the certificate states
    /// (`recalibration_due`), stored in the same transaction when the number is given: the
    /// stored date when the run has one (printing again states the date first stated), else
    /// `due`. A run numbered without a date keeps none.
    pub fn certificate_number_with_due(
        &mut self,
        run: RunId,
        due: &RecalibrationDue,
    ) -> Result<(CertificateNumber, Option<RecalibrationDue>), DbError> {
        self.number(run, Some(due))
    }

    fn number(
        &mut self,
        run: RunId,
        due: Option<&RecalibrationDue>,
    ) -> Result<(CertificateNumber, Option<RecalibrationDue>), DbError> {
        let run_s = run.to_string();
        let table = chain::table("certificate_number");
        let due_table = chain::table("recalibration_due");
        self.retried(|conn| {
            conn.transaction(|tx| {
                let id = Val::from(run_s.clone());
                if tx.query("SELECT 1 FROM run WHERE run_id = $1", std::slice::from_ref(&id))?.is_empty() {
                    return Err(DbError::NoRun { run_id: run_s.clone() });
                }
                let refused = |tx: &mut Tx<'_>, sql: &str, state: &str| -> Result<(), DbError> {
                    match tx.query(sql, std::slice::from_ref(&id))?.first() {
                        Some(r) => Err(DbError::Conflict {
                            run_id: run_s.clone(),
                            what: format!(
                                "the run is {state} ({}): its certificate cannot be numbered",
                                r[0].text()?
                            ),
                        }),
                        None => Ok(()),
                    }
                };
                // A voided run's certificate is not printed again; a finished run's keeps its
                // number, but gets none after its end.
                refused(tx, "SELECT reason FROM void WHERE run_id = $1", "voided")?;
                let given = tx.query(
                    "SELECT sequence, number, issued_unix_s FROM certificate_number WHERE run_id = $1",
                    std::slice::from_ref(&id),
                )?;
                if let Some(r) = given.first() {
                    let stored = tx
                        .query(
                            "SELECT due_unix_s, basis FROM recalibration_due WHERE run_id = $1",
                            std::slice::from_ref(&id),
                        )?
                        .first()
                        .map(|d| {
                            Ok::<_, DbError>(RecalibrationDue {
                                due_unix_s: d[0].int()?,
                                basis: d[1].text()?,
                            })
                        })
                        .transpose()?;
                    let number = CertificateNumber {
                        sequence: r[0].int()?,
                        number: r[1].text()?,
                        issued_unix_s: r[2].int()?,
                    };
                    return Ok((number, stored));
                }
                refused(tx, "SELECT outcome FROM run_end WHERE run_id = $1", "finished")?;
                let (sequence, number, issued_unix_s) = next_number(tx)?;
                let sha = sha256_hex(certificate_number_content(sequence, &number).as_bytes());
                let row: Vec<Val> = vec![
                    id.clone(),
                    sequence.into(),
                    number.clone().into(),
                    issued_unix_s.into(),
                    sha.into(),
                ];
                insert_row(tx, table, &row)?;
                if let Some(d) = due {
                    let sha = sha256_hex(recalibration_due_content(d.due_unix_s, &d.basis).as_bytes());
                    let row: Vec<Val> = vec![
                        id,
                        d.due_unix_s.into(),
                        d.basis.clone().into(),
                        issued_unix_s.into(),
                        sha.into(),
                    ];
                    insert_row(tx, due_table, &row)?;
                    let device =
                        tx.query("SELECT device_id FROM run WHERE run_id = $1", &[run_s.clone().into()])?;
                    if let Some(d) = device.first() {
                        super::derived::refresh_device_certificate(tx, &d[0].text()?)?;
                    }
                }
                Ok((CertificateNumber { sequence, number, issued_unix_s }, due.cloned()))
            })
        })
    }
}

/// The next certificate number: the largest sequence of the run's first certificates and of
/// the amendments plus one, `YEAR-SEQUENCE` in the year of now (UTC), and now.
fn next_number(tx: &mut Tx<'_>) -> Result<(i64, String, i64), DbError> {
    let sequence = tx.query(
        "SELECT COALESCE(MAX(s), 0) FROM (SELECT sequence AS s FROM certificate_number \
         UNION ALL SELECT sequence AS s FROM amendment) AS given",
        &[],
    )?[0][0]
        .int()?
        + 1;
    let issued_unix_s = now_unix_s();
    let year = jiff::Timestamp::from_second(issued_unix_s)
        .map(|t| t.to_zoned(jiff::tz::TimeZone::UTC).year())
        .unwrap_or(1970);
    Ok((sequence, format!("{year}-{sequence:06}"), issued_unix_s))
}

/// Certificate numbers are given in sequence (1, 2, 3…, `YEAR-SEQUENCE`), to runs and to
/// amendments alike: a sequence missing below the largest is a certificate whose rows were
/// removed.
pub(crate) fn gaps(tx: &mut Tx<'_>) -> Result<Vec<chain::Mismatch>, DbError> {
    let seqs: Vec<i64> = tx
        .query(
            "SELECT sequence FROM certificate_number UNION ALL SELECT sequence FROM amendment ORDER BY 1",
            &[],
        )?
        .iter()
        .map(|r| r[0].int())
        .collect::<Result<_, _>>()?;
    let mut out = Vec::new();
    let mut want = 1;
    for s in seqs {
        if s > want {
            let missing = if s - want == 1 {
                format!("number {want} is missing")
            } else {
                format!("numbers {want} to {} are missing", s - 1)
            };
            out.push(chain::Mismatch {
                seq: 0,
                run_id: String::new(),
                piece: "certificate_number".into(),
                what: format!(
                    "certificates are numbered in sequence, and {missing} (their rows were removed)"
                ),
            });
        }
        want = s + 1;
    }
    Ok(out)
}

/// An amended certificate ([`Db::amend`]): a new number for the same run.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Amendment {
    /// The run.
    pub run: RunId,
    /// The new number.
    pub number: CertificateNumber,
    /// The number it replaces.
    pub replaces: String,
    /// Why.
    pub reason: String,
}

/// One of a run's certificates as stored ([`Db::certificate_of_number`]).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct StoredCertificate {
    /// Its run.
    pub run: RunId,
    /// Its number.
    pub number: String,
    /// Its page, as issued (it carries its document).
    pub html: String,
    /// The certificate it replaces and why, for an amendment.
    pub replaces: Option<(String, String)>,
    /// The amendment that replaced it, if one did.
    pub superseded: Option<Supersession>,
}

/// The number of run `$1`'s certificate in force: its newest amendment's (the one nothing
/// replaces), else its first.
pub(crate) const IN_FORCE: &str = "COALESCE((SELECT a.number FROM amendment a WHERE a.run_id = $1 \
     AND NOT EXISTS (SELECT 1 FROM amendment b WHERE b.replaces = a.number)), \
     (SELECT n.number FROM certificate_number n WHERE n.run_id = $1))";

/// The run of certificate `number` (a first certificate or an amendment).
fn run_of(tx: &mut Tx<'_>, number: &str) -> Result<Option<String>, DbError> {
    let n = Val::from(number.to_string());
    tx.query(
        "SELECT run_id FROM certificate_number WHERE number = $1 UNION ALL SELECT run_id FROM amendment WHERE number = $1",
        std::slice::from_ref(&n),
    )?
    .first()
    .map(|r| r[0].text())
    .transpose()
}

impl Db {
    /// Issues an amendment of certificate `number` in one transaction: a new number (the same
    /// sequence as every certificate's) for the same run, replacing `number`, stored with its
    /// page, which `page` renders for the new number (it awaits approval as any certificate
    /// does). Refused, with nothing stored, when `number` is not stored, was replaced already
    /// (amend the one in force), its run was voided, or the run's rows do not match their chain.
    pub fn amend(
        &mut self,
        number: &str,
        reason: &str,
        operator: &str,
        mut page: impl FnMut(&CertificateNumber) -> Result<String, String>,
    ) -> Result<Amendment, DbError> {
        let target = self.target();
        self.retried(|conn| {
            conn.transaction(|tx| {
                let Some(run_id) = run_of(tx, number)? else {
                    return Err(DbError::Release(super::ReleaseError::NoCertificate {
                        number: number.into(),
                        target: target.clone(),
                    }));
                };
                let conflict = |what: String| DbError::Conflict { run_id: run_id.clone(), what };
                if let Some(s) = superseded(tx, number)? {
                    return Err(conflict(format!(
                        "certificate {number} was replaced already, by {} ({}): amend the certificate in force, {}",
                        s.by, s.reason, s.by
                    )));
                }
                if let Some(r) = tx.query("SELECT reason FROM void WHERE run_id = $1", &[run_id.clone().into()])?.first() {
                    return Err(conflict(format!(
                        "the run was voided ({}): its certificate is not issued again",
                        r[0].text()?
                    )));
                }
                if let Err(mut m) = chain::verify_run(tx, &run_id)? {
                    let first = m.remove(0);
                    return Err(DbError::Tampered { run_id, first: Box::new(first), more: m.len() });
                }
                let (sequence, new, issued_unix_s) = next_number(tx)?;
                let given = CertificateNumber { sequence, number: new.clone(), issued_unix_s };
                let html = page(&given).map_err(|e| conflict(format!("its amended page: {e}")))?;
                let sha = sha256_hex(amendment_content(sequence, &new, number, reason, &html).as_bytes());
                let row: Vec<Val> = vec![
                    run_id.clone().into(),
                    new.clone().into(),
                    sequence.into(),
                    number.to_string().into(),
                    reason.to_string().into(),
                    operator.to_string().into(),
                    html.into(),
                    issued_unix_s.into(),
                    sha.into(),
                ];
                insert_row(tx, chain::table("amendment"), &row)?;
                Ok(Amendment {
                    run: RunId::parse(&run_id)?,
                    number: given,
                    replaces: number.to_string(),
                    reason: reason.to_string(),
                })
            })
        })
    }

    /// Certificate `number` as stored (a run's first certificate or an amendment), with what it
    /// replaces and what replaced it; `None` when no stored certificate has that number.
    /// [`DbError::Tampered`] when its run's rows do not match their hash chain.
    pub fn certificate_of_number(&mut self, number: &str) -> Result<Option<StoredCertificate>, DbError> {
        let Some(run) = self.run_of_certificate(number)? else { return Ok(None) };
        self.verify_run(run)?;
        let n = number.to_string();
        self.conn.reading(|tx| {
            let page = tx.query(
                "SELECT c.html, NULL, NULL FROM certificate_number n JOIN certificate c ON c.run_id = n.run_id \
                 WHERE n.number = $1 UNION ALL SELECT html, replaces, reason FROM amendment WHERE number = $1",
                &[n.clone().into()],
            )?;
            let Some(p) = page.first() else { return Ok(None) };
            let replaces = match &p[1] {
                Val::Null => None,
                v => Some((v.text()?, p[2].text()?)),
            };
            Ok(Some(StoredCertificate {
                run,
                number: n.clone(),
                html: p[0].text()?,
                replaces,
                superseded: superseded(tx, &n)?,
            }))
        })
    }

    /// The number of run `run`'s certificate in force (its newest amendment's, else its
    /// first), `None` when it has none (read only).
    pub fn number_in_force(&mut self, run: RunId) -> Result<Option<String>, DbError> {
        let id = run.to_string();
        self.conn.reading(|tx| {
            tx.query(&format!("SELECT {IN_FORCE}"), &[id.clone().into()])?
                .first()
                .and_then(|r| r[0].opt_text().transpose())
                .transpose()
        })
    }

    /// The runs whose id begins with `prefix` (hex digits and dashes, lower case), at most
    /// `limit`, in order.
    pub fn runs_with_prefix(&mut self, prefix: &str, limit: i64) -> Result<Vec<RunId>, DbError> {
        let pattern = format!("{prefix}%");
        self.conn
            .reading(|tx| {
                tx.query(
                    "SELECT run_id FROM run WHERE run_id LIKE $1 ORDER BY run_id LIMIT $2",
                    &[pattern.clone().into(), limit.into()],
                )
            })?
            .iter()
            .map(|r| RunId::parse(&r[0].text()?))
            .collect()
    }

    /// The run whose certificate has number `number` (a first certificate or an amendment),
    /// `None` when no certificate has it.
    pub fn run_of_certificate(&mut self, number: &str) -> Result<Option<RunId>, DbError> {
        let n = number.to_string();
        match self.conn.reading(|tx| run_of(tx, &n))? {
            Some(id) => Ok(Some(RunId::parse(&id)?)),
            None => Ok(None),
        }
    }

    /// The certificate stored for run `run` (`report`'s page, as issued), `None` when it has
    /// none; [`DbError::Tampered`] when the run's rows (or the assets it used) do not match
    /// their hash chain: a forged certificate is never handed out as issued.
    pub fn certificate_html(&mut self, run: RunId) -> Result<Option<String>, DbError> {
        let id = Val::from(run.to_string());
        if self.conn.reading(|tx| {
            Ok(tx.query("SELECT 1 FROM certificate WHERE run_id = $1", std::slice::from_ref(&id))?.is_empty())
        })? {
            return Ok(None);
        }
        self.verify_run(run)?;
        self.conn.reading(|tx| {
            tx.query("SELECT html FROM certificate WHERE run_id = $1", std::slice::from_ref(&id))?
                .first()
                .map(|r| r[0].text())
                .transpose()
        })
    }
}
