//! Cells that do not read as their column's type. PostgreSQL keeps every value in its column's
//! type; SQLite keeps whatever was written (`UPDATE run SET g_m_s2 = 'abc'` behind accelcal's
//! back), and a reader that meets such a cell can only say what it expected. [`scan`] names
//! each such cell by its table, its row's key and its column, from the schema's own declared
//! types (`PRAGMA table_info`; the engine's `scan_cells`), so that `db verify`
//! lists them all and a reader's failure names the first.

use serde::Serialize;

use super::val::Val;
use super::DbError;

/// A cell whose stored type is not its column's.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct BadCell {
    /// The table.
    pub table: String,
    /// The row: its key columns and values (`run_id = …`), or its rowid.
    pub row: String,
    /// The column.
    pub column: String,
    /// The type the column declares.
    pub declared: String,
    /// What it holds: SQLite's storage class and the value, escaped and cut short.
    pub read: String,
}

impl std::fmt::Display for BadCell {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "table {}, row {}, column {}: declared {}, holds {}",
            self.table, self.row, self.column, self.declared, self.read
        )
    }
}

impl BadCell {
    /// The run its row belongs to, when the row's key begins with `run_id` (every run's table).
    pub fn run_id(&self) -> Option<&str> {
        self.row.strip_prefix("run_id = '")?.split('\'').next()
    }
}

/// A run a reader that lists runs (`history`, `fleet`, `serve`) could not read: set aside and
/// shown as such, named by its bad cells, while every other run is listed.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct UnreadableRun {
    /// The run.
    pub run_id: String,
    /// Its cells that do not read as their column's type (empty when none was found: then
    /// `error` is all there is).
    pub bad_cells: Vec<BadCell>,
    /// What the reader met first, in words.
    pub error: String,
}

impl std::fmt::Display for UnreadableRun {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "run {} does not read: ", self.run_id)?;
        if self.bad_cells.is_empty() {
            return write!(f, "{}", self.error);
        }
        let cells: Vec<String> = self.bad_cells.iter().map(|c| format!("bad cell: {c}")).collect();
        write!(f, "{}", cells.join("; "))
    }
}

/// Runs set aside by a listing: each run's id and why its row does not read.
pub(crate) type SetAside = Vec<(String, String)>;

/// The rows of a listing decoded by `f`, each alone: with `tolerant`, a row that does not read
/// as its types (a [`DbError::Schema`]) is set aside as its run (column `run_col`) and why,
/// and the others are kept; any other failure, or any failure when not `tolerant`, is the
/// result.
pub(crate) fn each_row<T>(
    tolerant: bool,
    rows: &[Vec<Val>],
    run_col: usize,
    mut f: impl FnMut(&[Val]) -> Result<T, DbError>,
) -> Result<(Vec<T>, SetAside), DbError> {
    let mut out = Vec::with_capacity(rows.len());
    let mut aside = Vec::new();
    for r in rows {
        match f(r) {
            Ok(v) => out.push(v),
            Err(e) => aside.push(set_aside(tolerant, r, run_col, e)?),
        }
    }
    Ok((out, aside))
}

/// The run of `row` (column `run_col`) and why it does not read, when `tolerant` and `e` is a
/// failure to read a cell as its type; otherwise `e`.
pub(crate) fn set_aside(
    tolerant: bool,
    row: &[Val],
    run_col: usize,
    e: DbError,
) -> Result<(String, String), DbError> {
    match e {
        DbError::Schema { what } if tolerant => match row.get(run_col).map(Val::text) {
            Some(Ok(run)) => Ok((run, what)),
            _ => Err(DbError::Schema { what }),
        },
        e => Err(e),
    }
}
