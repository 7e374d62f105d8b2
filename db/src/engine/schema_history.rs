//! The migration history (`refinery_schema_history`, refinery's table) checked against this
//! build's migrations before a database is read or migrated. refinery trusts the table: a row
//! deleted makes it apply that migration again (`table chain_event already exists`), an edited
//! `applied_on` makes it panic, a version missing in the middle is skipped in silence. Every
//! command checks the table first ([`problem`], and [`schema_version`] when the table
//! says the schema is older than it is) and says what is wrong with it in one line
//! ([`DbError::MigrationHistory`]); `accelcal db migrate` records the history again when the
//! schema is exactly that of one of this build's versions ([`repair`]; on PostgreSQL, its
//! tables are those of one version's).

use super::{embedded, history_exists, Tx, Val};
use crate::DbError;

/// One migration of this build, as refinery records it.
struct Known {
    version: i64,
    name: String,
    checksum: String,
    /// The tables its SQL creates ([`tables_created`]).
    tables: Vec<String>,
}

/// The tables `CREATE TABLE [IF NOT EXISTS] name` statements of `sql` create, lower-cased.
fn tables_created(sql: &str) -> Vec<String> {
    let words: Vec<String> = sql
        .split(|c: char| !(c.is_ascii_alphanumeric() || c == '_'))
        .filter(|w| !w.is_empty())
        .map(str::to_ascii_lowercase)
        .collect();
    let mut out = Vec::new();
    for (i, w) in words.iter().enumerate() {
        if w == "create" && words.get(i + 1).is_some_and(|t| t == "table") {
            let at = if words.get(i + 2).is_some_and(|x| x == "if") { i + 5 } else { i + 2 };
            out.extend(words.get(at).cloned());
        }
    }
    out
}

fn known(postgres: bool) -> Vec<Known> {
    let runner = if postgres {
        embedded::postgres::migrations::runner()
    } else {
        embedded::sqlite::migrations::runner()
    };
    let mut out: Vec<Known> = runner
        .get_migrations()
        .iter()
        .map(|m| Known {
            version: i64::from(m.version()),
            name: m.name().to_string(),
            checksum: m.checksum().to_string(),
            tables: tables_created(m.sql().unwrap_or_default()),
        })
        .collect();
    out.sort_by_key(|k| k.version);
    out
}

/// A cell as a message shows it: `NULL`, or quoted, control characters escaped, cut at 40.
fn shown(v: &Option<String>) -> String {
    match v {
        None => "NULL".into(),
        Some(s) => format!("'{}'", s.chars().take(40).flat_map(char::escape_debug).collect::<String>()),
    }
}

/// The history's rows as text (a cell that is not its type reads as what it holds), each
/// `[version, name, applied_on, checksum]`.
fn rows(tx: &mut Tx<'_>) -> Result<Vec<[Option<String>; 4]>, DbError> {
    let rows = tx.query(
        "SELECT CAST(version AS TEXT), CAST(name AS TEXT), CAST(applied_on AS TEXT), CAST(checksum AS TEXT) \
         FROM refinery_schema_history",
        &[],
    )?;
    rows.iter()
        .map(|r| {
            let cell = |i: usize| -> Result<Option<String>, DbError> {
                match &r[i] {
                    Val::Null => Ok(None),
                    v => v.text().map(Some),
                }
            };
            Ok([cell(0)?, cell(1)?, cell(2)?, cell(3)?])
        })
        .collect()
}

/// The highest version the history records that reads as one (`None`: none).
fn recorded(rows: &[[Option<String>; 4]]) -> Option<i64> {
    rows.iter().filter_map(|r| r[0].as_deref()?.parse::<i64>().ok()).max()
}

/// What is wrong with the history, in words, or `None`: every row is one of this build's
/// migrations as refinery recorded it (version, name, checksum, a time it was applied), from
/// version 1 without a gap (a later build's versions above this build's are left to
/// the engine's version check). `None` too when there is no history yet.
pub(crate) fn problem(tx: &mut Tx<'_>) -> Result<Option<String>, DbError> {
    if !history_exists(tx)? {
        return Ok(None);
    }
    let known = known(matches!(tx, Tx::Postgres(..)));
    let latest = known.last().map_or(0, |k| k.version);
    let mut versions = Vec::new();
    for r in rows(tx)? {
        let Some(v) = r[0].as_deref().and_then(|v| v.parse::<i64>().ok()) else {
            return Ok(Some(format!("a row's version is {}, not a whole number", shown(&r[0]))));
        };
        let at = format!("the row of version {v}");
        match known.iter().find(|k| k.version == v) {
            Some(k) if r[1].as_deref() != Some(k.name.as_str()) => {
                return Ok(Some(format!("{at}: its name is {}, not `{}`", shown(&r[1]), k.name)));
            }
            Some(k) if r[3].as_deref() != Some(k.checksum.as_str()) => {
                return Ok(Some(format!(
                    "{at}: its checksum is {}, not {} (migration {})",
                    shown(&r[3]),
                    k.checksum,
                    k.name
                )));
            }
            None if v <= latest => {
                return Ok(Some(format!("{at}: no migration of this build has that version")))
            }
            _ => {}
        }
        if r[2].as_deref().and_then(|t| t.parse::<jiff::Timestamp>().ok()).is_none() {
            return Ok(Some(format!("{at}: its applied_on is {}, not a time", shown(&r[2]))));
        }
        versions.push(v);
    }
    versions.sort_unstable();
    for (i, v) in versions.iter().enumerate() {
        let want = i as i64 + 1;
        if *v != want {
            return Ok(Some(format!("version {want} is missing from it, and version {v} is recorded")));
        }
    }
    Ok(None)
}

/// A SQLite schema as `sqlite_master` holds it: each table, index, trigger and view with its SQL.
type Schema = Vec<(String, String, String)>;

const SCHEMA_SQL: &str = "SELECT type, name, COALESCE(sql, '') FROM sqlite_master \
     WHERE name NOT LIKE 'sqlite\\_%' ESCAPE '\\' ORDER BY type, name";

/// The version of this build whose schema the database's is, exactly, or `None` when it is
/// none of them. SQLite: every table, index and trigger with its SQL, as a new database
/// migrated to that version in memory has them. PostgreSQL (where no database is at hand to
/// migrate aside, and a reader may not create one): the tables of the search path's schemas,
/// as the migrations up to that version create them, no more and no fewer.
pub(crate) fn schema_version(tx: &mut Tx<'_>) -> Result<Option<i64>, DbError> {
    if matches!(tx, Tx::Postgres(..)) {
        return pg_schema_version(tx);
    }
    let have: Schema = tx
        .query(SCHEMA_SQL, &[])?
        .iter()
        .map(|r| Ok((r[0].text()?, r[1].text()?, r[2].text()?)))
        .collect::<Result<_, DbError>>()?;
    let fresh =
        |e: String| DbError::Migration { cause: format!("a new schema in memory to compare with: {e}") };
    let mut mem = rusqlite::Connection::open_in_memory().map_err(|e| fresh(e.to_string()))?;
    for k in known(false) {
        let v = i32::try_from(k.version).map_err(|e| fresh(e.to_string()))?;
        embedded::sqlite::migrations::runner()
            .set_target(refinery::Target::Version(v))
            .run(&mut mem)
            .map_err(|e| fresh(e.to_string()))?;
        let schema: Schema = mem
            .prepare(SCHEMA_SQL)
            .and_then(|mut s| {
                s.query_map([], |r| Ok((r.get(0)?, r.get(1)?, r.get(2)?)))?.collect::<Result<_, _>>()
            })
            .map_err(|e| fresh(e.to_string()))?;
        if schema == have {
            return Ok(Some(k.version));
        }
    }
    Ok(None)
}

/// [`schema_version`] on PostgreSQL: the version whose migrations create exactly the tables
/// there are (the history's own table aside).
fn pg_schema_version(tx: &mut Tx<'_>) -> Result<Option<i64>, DbError> {
    let mut have: Vec<String> = tx
        .query(
            "SELECT tablename FROM pg_catalog.pg_tables WHERE schemaname = ANY (current_schemas(false)) \
             AND tablename <> 'refinery_schema_history'",
            &[],
        )?
        .iter()
        .map(|r| r[0].text())
        .collect::<Result<_, _>>()?;
    have.sort_unstable();
    let mut created: Vec<String> = Vec::new();
    let mut found = None;
    for k in known(true) {
        // A table rebuilt by a later version (schema 10's `approval`) is created twice.
        created.extend(k.tables);
        created.sort_unstable();
        created.dedup();
        if created == have {
            found = Some(k.version);
        }
    }
    Ok(found)
}

/// What is wrong with the history: its [`problem`], or rows of the newest versions
/// deleted, the schema being that of a later version than the history records.
pub(crate) fn damage(tx: &mut Tx<'_>) -> Result<Option<String>, DbError> {
    if let Some(p) = problem(tx)? {
        return Ok(Some(p));
    }
    if !history_exists(tx)? {
        return Ok(None);
    }
    let recorded = recorded(&rows(tx)?);
    let latest = known(matches!(tx, Tx::Postgres(..))).last().map_or(0, |k| k.version);
    match recorded {
        Some(r) if r < latest => Ok(schema_version(tx)?.filter(|v| *v > r).map(|v| {
            format!(
                "it records schema version {r}, and the schema is that of version {v}: the rows of the versions after {r} were removed"
            )
        })),
        _ => Ok(None),
    }
}

/// Records the history again (`accelcal db migrate`): when it is damaged ([`damage`])
/// and the schema is exactly that of one of this build's versions, its rows become those of
/// the versions up to it (a row's time kept where it was one); what was done, in words, or
/// `None` when the history is sound. A schema that is no version's is
/// [`DbError::MigrationHistory`]: only a backup restores it.
pub(crate) fn repair(tx: &mut Tx<'_>, target: &str) -> Result<Option<String>, DbError> {
    if !history_exists(tx)? {
        return Ok(None);
    }
    let postgres = matches!(tx, Tx::Postgres(..));
    let rows = rows(tx)?;
    let Some(what) = damage(tx)? else {
        return Ok(None);
    };
    let Some(v) = schema_version(tx)? else {
        return Err(DbError::MigrationHistory {
            target: target.into(),
            what: format!("{what}, and the schema is that of none of this build's versions"),
            repairable: false,
        });
    };
    let now = jiff::Timestamp::now().to_string();
    tx.execute("DELETE FROM refinery_schema_history", &[])?;
    for k in known(postgres).into_iter().filter(|k| k.version <= v) {
        let kept = rows
            .iter()
            .find(|r| r[0].as_deref() == Some(k.version.to_string().as_str()))
            .and_then(|r| r[2].clone())
            .filter(|t| t.parse::<jiff::Timestamp>().is_ok());
        tx.execute(
            "INSERT INTO refinery_schema_history (version, name, applied_on, checksum) \
             VALUES (CAST($1 AS bigint), $2, $3, $4)",
            &[
                Val::Int(k.version),
                k.name.into(),
                kept.unwrap_or_else(|| now.clone()).into(),
                k.checksum.into(),
            ],
        )?;
    }
    Ok(Some(format!(
        "{what}: recorded again as versions 1 to {v}, the schema being exactly that of version {v}"
    )))
}
