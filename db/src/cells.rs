//! Cells that do not read as their column's type. PostgreSQL keeps every value in its column's
//! type; SQLite keeps whatever was written (`UPDATE run SET g_m_s2 = 'abc'` behind accelcal's
//! back), and a reader that meets such a cell can only say what it expected. [`scan`] names
//! each such cell by its table, its row's key and its column, from the schema's own declared
//! types (`PRAGMA table_info`; the engine's [`crate::engine`] `scan_cells`), so that `db verify`
//! lists them all and a reader's failure names the first.

use serde::Serialize;

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
