//! Certificate numbers (schema 4) and the recalibration date a certificate states (schema 5):
//! given once per run in one transaction, the same when the certificate is printed again.

use super::content::{certificate_number_content, recalibration_due_content};
use super::engine::{Tx, Val};
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
                let sequence = tx.query("SELECT COALESCE(MAX(sequence), 0) FROM certificate_number", &[])?[0]
                    [0]
                .int()?
                    + 1;
                let issued_unix_s = now_unix_s();
                let year = jiff::Timestamp::from_second(issued_unix_s)
                    .map(|t| t.to_zoned(jiff::tz::TimeZone::UTC).year())
                    .unwrap_or(1970);
                let number = format!("{year}-{sequence:06}");
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

/// Certificate numbers are given in sequence (1, 2, 3…, `YEAR-SEQUENCE`): a sequence missing
/// below the largest is a certificate whose rows were removed.
pub(crate) fn gaps(tx: &mut Tx<'_>) -> Result<Vec<chain::Mismatch>, DbError> {
    let seqs: Vec<i64> = tx
        .query("SELECT sequence FROM certificate_number ORDER BY sequence", &[])?
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

impl Db {
    /// The run whose certificate has number `number`, `None` when no certificate has it.
    pub fn run_of_certificate(&mut self, number: &str) -> Result<Option<RunId>, DbError> {
        let n = Val::from(number.to_string());
        let rows = self.conn.reading(|tx| {
            tx.query("SELECT run_id FROM certificate_number WHERE number = $1", std::slice::from_ref(&n))
        })?;
        match rows.first() {
            Some(r) => {
                let id = r[0].text()?;
                Ok(Some(RunId::parse(&id)?))
            }
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
