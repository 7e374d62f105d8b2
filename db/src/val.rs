//! A value passed to or read from a statement, the same on both engines: what every module
//! that reads rows takes, below the engine that binds it (`engine` maps it to each driver's
//! types) and the readers that decode it.

use super::DbError;

/// One value passed to or read from a statement.
#[derive(Clone, Debug, PartialEq)]
pub enum Val {
    /// SQL NULL (read only: every column is `NOT NULL`; outer joins give it).
    Null,
    /// `BIGINT`.
    Int(i64),
    /// `DOUBLE PRECISION`.
    Real(f64),
    /// `TEXT`.
    Text(String),
    /// `BLOB` / `BYTEA`.
    Bytes(Vec<u8>),
    /// `BOOLEAN` (SQLite stores 0 or 1).
    Bool(bool),
}

impl From<&str> for Val {
    fn from(s: &str) -> Val {
        Val::Text(s.into())
    }
}
impl From<String> for Val {
    fn from(s: String) -> Val {
        Val::Text(s)
    }
}
impl From<i64> for Val {
    fn from(v: i64) -> Val {
        Val::Int(v)
    }
}
impl From<f64> for Val {
    fn from(v: f64) -> Val {
        Val::Real(v)
    }
}
impl From<bool> for Val {
    fn from(v: bool) -> Val {
        Val::Bool(v)
    }
}
impl From<Vec<u8>> for Val {
    fn from(v: Vec<u8>) -> Val {
        Val::Bytes(v)
    }
}

impl Val {
    /// The text, `None` for NULL.
    pub(crate) fn opt_text(&self) -> Result<Option<String>, DbError> {
        match self {
            Val::Null => Ok(None),
            v => v.text().map(Some),
        }
    }

    /// The text, or the schema is not what this build expects.
    pub fn text(&self) -> Result<String, DbError> {
        match self {
            Val::Text(s) => Ok(s.clone()),
            other => Err(DbError::schema(format!("expected text, read {other:?}"))),
        }
    }

    /// The integer.
    pub fn int(&self) -> Result<i64, DbError> {
        match self {
            Val::Int(v) => Ok(*v),
            other => Err(DbError::schema(format!("expected an integer, read {other:?}"))),
        }
    }

    /// The number.
    pub fn real(&self) -> Result<f64, DbError> {
        match self {
            Val::Real(v) => Ok(*v),
            Val::Int(v) => Ok(*v as f64),
            other => Err(DbError::schema(format!("expected a number, read {other:?}"))),
        }
    }

    /// The bytes.
    pub fn bytes(&self) -> Result<Vec<u8>, DbError> {
        match self {
            Val::Bytes(v) => Ok(v.clone()),
            other => Err(DbError::schema(format!("expected bytes, read {other:?}"))),
        }
    }
}
