//! How a run's piece is stored: one row in one transaction, after the checks every piece shares
//! (the run exists, is neither finished nor voided, holds no other piece of the kind), with its
//! ledger entry ([`chain`]) and its derived rows.

use super::engine::{Tx, Val};
use super::{chain, Db, DbError, RunId, Stored};

/// One piece of a run, ready to insert.
pub(crate) struct Piece {
    pub(crate) table: &'static str,
    /// Its name in messages.
    pub(crate) what: &'static str,
    /// The second key column and its value: a verification's `phase`, a run asset's `kind`.
    pub(crate) second: Option<(&'static str, &'static str)>,
    /// The values of the columns after `run_id` (and the second key), without `content_sha256`, in the
    /// order of [`chain::TABLES`].
    pub(crate) values: Vec<Val>,
    pub(crate) sha: String,
}

impl Db {
    /// Inserts a piece in one transaction: after checking that the run exists, is not
    /// finished nor voided, and holds no other piece of the kind (the same one: [`Stored::Already`]).
    pub(crate) fn store(&mut self, run: RunId, p: Piece) -> Result<Stored, DbError> {
        self.store_deriving(run, p, &|_, _| Ok(()))
    }

    /// [`Db::store`], and `derive` writes the piece's derived rows ([`crate::derived`]) in the same
    /// transaction when the piece is new.
    pub(crate) fn store_deriving(
        &mut self,
        run: RunId,
        p: Piece,
        derive: &dyn Fn(&mut Tx<'_>, &str) -> Result<(), DbError>,
    ) -> Result<Stored, DbError> {
        let run_s = run.to_string();
        let table = chain::table(p.table);
        let mut row = vec![Val::from(run_s.clone())];
        if let Some((_, v)) = p.second {
            row.push(v.into());
        }
        row.extend(p.values);
        row.push(p.sha.clone().into());
        debug_assert_eq!(row.len(), table.columns.len(), "{}: a value per column", p.table);
        self.retried(|conn| {
            conn.transaction(|tx| {
                let id = Val::from(run_s.clone());
                if tx.query("SELECT 1 FROM run WHERE run_id = $1", std::slice::from_ref(&id))?.is_empty() {
                    return Err(DbError::NoRun { run_id: run_s.clone() });
                }
                if let Some(r) =
                    tx.query("SELECT reason FROM void WHERE run_id = $1", std::slice::from_ref(&id))?.first()
                {
                    return Err(DbError::Conflict {
                        run_id: run_s.clone(),
                        what: format!(
                            "the run is voided ({}): its {} cannot be stored",
                            r[0].text()?,
                            p.what
                        ),
                    });
                }
                if p.table != "run_end" {
                    if let Some(r) = tx
                        .query("SELECT outcome FROM run_end WHERE run_id = $1", std::slice::from_ref(&id))?
                        .first()
                    {
                        return Err(DbError::Conflict {
                            run_id: run_s.clone(),
                            what: format!(
                                "the run is finished ({}): its {} cannot be stored",
                                r[0].text()?,
                                p.what
                            ),
                        });
                    }
                }
                let mut key = vec![id];
                let mut key_sql = "run_id = $1".to_string();
                if let Some((col, v)) = p.second {
                    key.push(v.into());
                    key_sql.push_str(&format!(" AND {col} = $2"));
                }
                let found =
                    tx.query(&format!("SELECT content_sha256 FROM {} WHERE {key_sql}", p.table), &key)?;
                if let Some(r) = found.first() {
                    return if r[0].text()? == p.sha {
                        Ok(Stored::Already)
                    } else {
                        Err(DbError::Conflict {
                            run_id: run_s.clone(),
                            what: format!(
                                "it holds another {} already (a run stores each piece once)",
                                p.what
                            ),
                        })
                    };
                }
                insert_row(tx, table, &row)?;
                derive(tx, &run_s)?;
                Ok(Stored::New)
            })
        })
    }
}

/// Inserts a row and its ledger entry ([`chain::insert_row`]).
pub(crate) use super::chain::insert_row;
