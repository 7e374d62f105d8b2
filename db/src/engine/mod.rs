//! The two database engines behind one small interface: a connection (SQLite file or PostgreSQL
//! server), its migrations, and transactions that run statements written once for both (`$1`,
//! `$2`… placeholders in order of first use, which SQLite reads as numbered parameters too).
//! Nothing above this module knows which engine it talks to.
//!
//! - `Target`: what `--db` (or `ACCELCAL_DB`) names: `postgres://…` or `host=…` words for
//!   PostgreSQL, another `scheme://` refused, anything else a SQLite file.
//! - `Conn`: rusqlite with the bundled SQLite (WAL, `synchronous=FULL`, foreign keys, a busy
//!   timeout), or the synchronous `postgres` client (its errors in the server's words,
//!   `pg_cause`). The migrations of `db/migrations/{sqlite,postgres}/V<n>__*.sql` are embedded
//!   and applied by refinery on open, one opener at a time (SQLite: an exclusive flock(2) on the
//!   database's directory, not on the file, whose other descriptors would drop SQLite's own fcntl
//!   locks when closed; PostgreSQL: an advisory lock); `schema_history` checks refinery's
//!   history against this build's migrations.
//! - `Access`: `Write` refuses, at open, a file or directory that cannot be written
//!   (`DbError::ReadOnly`); `Read` never writes: SQLite opened read-only (a read-only file or
//!   mount with `immutable=1`), no migration, no seal, no backfill, and a database at another
//!   schema version or with derived rows pending is `DbError::NeedsMigration`.
//! - `Tx`: one transaction. A writer's is SQLite's `BEGIN IMMEDIATE`, or PostgreSQL's under a
//!   transaction-level advisory lock, so writers append to the ledger one at a time. A reader's
//!   (`Conn::reading`) is deferred on SQLite and `REPEATABLE READ, READ ONLY` without the lock
//!   on PostgreSQL: one snapshot, and a reader never waits for a writer nor for another reader.
//!   Statements are prepared once per connection (`Statements` on PostgreSQL, rusqlite's cache
//!   on SQLite). A unique-key violation is `DbError::Raced`, and `Db` tries the store once more.
//! - `scan_cells`: every cell that does not read as its declared type (`db verify`).

mod schema_history;

use std::path::{Path, PathBuf};
use std::time::Duration;

use postgres::types::{to_sql_checked, IsNull, ToSql as PgToSql, Type};

use super::cells::BadCell;
use super::DbError;

/// The migrations of each engine (`core/migrations/<engine>/V<n>__<name>.sql`), embedded.
pub(crate) mod embedded {
    pub mod sqlite {
        refinery::embed_migrations!("migrations/sqlite");
    }
    pub mod postgres {
        refinery::embed_migrations!("migrations/postgres");
    }
}

/// How long a SQLite writer waits for another's lock, and a PostgreSQL connection attempt
/// lasts, before it fails.
const WAIT: Duration = Duration::from_secs(10);

/// Where the database is: `postgres://…` / `postgresql://…` (or libpq `key=value` words with
/// `host=`), else the path of a SQLite file.
#[derive(Clone, Debug, PartialEq)]
pub enum Target {
    /// A SQLite file.
    Sqlite(PathBuf),
    /// A PostgreSQL server (the connection string as given).
    Postgres(String),
}

impl Target {
    /// Reads a `--db` / `ACCELCAL_DB` value.
    pub fn parse(spec: &str) -> Result<Target, DbError> {
        let s = spec.trim();
        if s.is_empty() {
            return Err(DbError::BadTarget { spec: spec.into(), why: "it is empty".into() });
        }
        if s.starts_with("postgres://") || s.starts_with("postgresql://") || s.contains("host=") {
            s.parse::<postgres::Config>()
                .map_err(|e| DbError::BadTarget { spec: redact(s), why: e.to_string() })?;
            return Ok(Target::Postgres(s.into()));
        }
        // `postgress://…`, `sqlite://…`, `http://…`: a URL of a scheme this build does not open is
        // refused, not taken for a SQLite file of that name.
        if let Some((scheme, _)) = s.split_once("://") {
            return Err(DbError::BadTarget {
                spec: redact(s),
                why: format!(
                    "`{scheme}://` is not a database this build opens: PostgreSQL is postgres:// or postgresql://, a SQLite database is a file path"
                ),
            });
        }
        Ok(Target::Sqlite(PathBuf::from(s)))
    }

    /// The target for messages, without a password.
    pub fn display(&self) -> String {
        match self {
            Target::Sqlite(p) => p.display().to_string(),
            Target::Postgres(s) => redact(s),
        }
    }
}

/// A connection string with its password (`user:secret@` or `password=secret`) replaced by `***`.
fn redact(s: &str) -> String {
    if let Some((scheme, rest)) = s.split_once("://") {
        if let Some((userinfo, host)) = rest.split_once('@') {
            if let Some((user, _)) = userinfo.split_once(':') {
                return format!("{scheme}://{user}:***@{host}");
            }
        }
        return s.into();
    }
    s.split_whitespace()
        .map(|w| if w.starts_with("password=") { "password=***".to_string() } else { w.to_string() })
        .collect::<Vec<_>>()
        .join(" ")
}

pub use super::val::Val;

impl rusqlite::ToSql for Val {
    fn to_sql(&self) -> rusqlite::Result<rusqlite::types::ToSqlOutput<'_>> {
        use rusqlite::types::{ToSqlOutput, Value, ValueRef};
        Ok(match self {
            Val::Null => ToSqlOutput::Owned(Value::Null),
            Val::Int(v) => ToSqlOutput::Owned(Value::Integer(*v)),
            Val::Real(v) => ToSqlOutput::Owned(Value::Real(*v)),
            Val::Text(s) => ToSqlOutput::Borrowed(ValueRef::Text(s.as_bytes())),
            Val::Bytes(b) => ToSqlOutput::Borrowed(ValueRef::Blob(b)),
            Val::Bool(b) => ToSqlOutput::Owned(Value::Integer(i64::from(*b))),
        })
    }
}

impl PgToSql for Val {
    fn to_sql(
        &self,
        ty: &Type,
        out: &mut bytes::BytesMut,
    ) -> Result<IsNull, Box<dyn std::error::Error + Sync + Send>> {
        /// The value's own encoding, after checking that the column's type takes it.
        fn typed<T: PgToSql>(
            v: &T,
            ty: &Type,
            out: &mut bytes::BytesMut,
        ) -> Result<IsNull, Box<dyn std::error::Error + Sync + Send>> {
            if T::accepts(ty) {
                v.to_sql(ty, out)
            } else {
                Err(format!("a {} value given for a {ty} parameter", std::any::type_name::<T>()).into())
            }
        }
        match self {
            Val::Null => Ok(IsNull::Yes),
            Val::Int(v) => typed(v, ty, out),
            Val::Real(v) => typed(v, ty, out),
            Val::Text(v) => typed(v, ty, out),
            Val::Bytes(v) => typed(v, ty, out),
            Val::Bool(v) => typed(v, ty, out),
        }
    }

    fn accepts(_: &Type) -> bool {
        true
    }

    to_sql_checked!();
}

/// An open connection, and its target for messages (password hidden).
pub struct Conn {
    link: Link,
    target: String,
    /// Opened to read ([`Access::Read`]): its transactions take no writer's lock, so a reader
    /// never waits for a writer nor makes one wait. SQLite: deferred, not immediate (in WAL mode
    /// a transaction reads one snapshot); PostgreSQL: `REPEATABLE READ, READ ONLY` (one snapshot
    /// for the whole transaction), without the ledger's advisory lock. Set once the open's
    /// migration and backfill, which write, are done.
    read_only: bool,
}

/// The engine's connection.
enum Link {
    /// SQLite.
    Sqlite(rusqlite::Connection),
    /// PostgreSQL, with the statements it has prepared.
    Postgres(Box<postgres::Client>, Statements),
}

/// A PostgreSQL connection's prepared statements by their text: a statement is parsed and
/// planned once per connection, and each later use is one round trip instead of two. The line's
/// statements are a fixed set; the cache is emptied should it ever pass [`Statements::MAX`].
#[derive(Default)]
pub struct Statements(std::collections::HashMap<String, postgres::Statement>);

impl Statements {
    const MAX: usize = 512;

    fn get(&mut self, t: &mut postgres::Transaction<'_>, sql: &str) -> Result<postgres::Statement, DbError> {
        if let Some(st) = self.0.get(sql) {
            return Ok(st.clone());
        }
        let st = t.prepare(sql).map_err(DbError::pg)?;
        if self.0.len() >= Self::MAX {
            self.0.clear();
        }
        self.0.insert(sql.to_string(), st.clone());
        Ok(st)
    }
}

/// How a database is opened.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Access {
    /// To store into: a SQLite file is created when missing; the database must take writes
    /// (checked here, before the caller does anything else) and is migrated.
    Write,
    /// To read: the SQLite file must exist; it is migrated when it can be written, else read as
    /// it is (a read-only file or mount), which must then be at this build's schema.
    Read,
}

/// A transaction of either engine.
pub enum Tx<'a> {
    /// SQLite (a writer's begun `IMMEDIATE`: the write lock is taken at the start).
    Sqlite(rusqlite::Transaction<'a>),
    /// PostgreSQL, with its connection's prepared statements.
    Postgres(postgres::Transaction<'a>, &'a mut Statements),
}

/// The newest schema version this build has (the migrations' last `V<n>`).
pub fn schema_version() -> i64 {
    embedded::sqlite::migrations::runner()
        .get_migrations()
        .iter()
        .map(|m| i64::from(m.version()))
        .max()
        .unwrap_or(0)
}

impl Conn {
    /// Connects. [`Access::Write`] brings the schema to this build's version; `after` runs under
    /// the migration's lock once the schema is current, with the schema version the database had
    /// before (`None`: a new database): the ledger's sealing of rows written before it existed,
    /// the derived rows' backfill, the writer's check of the chain's shape. [`Access::Read`]
    /// never writes: a database at another schema version is refused ([`DbError::NeedsMigration`]).
    pub fn open(
        target: &Target,
        access: Access,
        after: impl FnOnce(&mut Conn, Option<i64>) -> Result<(), DbError>,
    ) -> Result<Conn, DbError> {
        match target {
            Target::Sqlite(path) => open_sqlite(path, access, after),
            Target::Postgres(spec) => {
                let mut conn = connect_pg(spec, access)?;
                if access == Access::Read {
                    // A writer that is migrating holds the migration's lock: the reader waits for
                    // it (a shared hold, which writes nothing) rather than see a schema half
                    // migrated (two stations starting together on a new database).
                    conn.pg_locked_as(LockMode::Shared, |c| c.check_current())?;
                    return Ok(conn);
                }
                // Under an advisory lock, so that stations starting together migrate once.
                conn.pg_locked(|c| {
                    c.check_history()?;
                    let before = c.reading(latest_version)?;
                    let Link::Postgres(client, _) = &mut c.link else {
                        unreachable!("a PostgreSQL connection")
                    };
                    embedded::postgres::migrations::runner()
                        .run(client.as_mut())
                        .map_err(migration_failed)?;
                    after(c, before)
                })?;
                Ok(conn)
            }
        }
    }

    /// A reader's check: the database is at this build's schema. Read in one transaction that
    /// only reads.
    fn check_current(&mut self) -> Result<(), DbError> {
        let target = self.target.clone();
        self.check_history()?;
        let have = self.reading(latest_version)?;
        let want = schema_version();
        match have {
            Some(v) if v == want => Ok(()),
            Some(v) if v > want => Err(DbError::NeedsMigration {
                target,
                why: format!(
                    "it is at schema version {v}, newer than this build's {want}: use a later accelcal"
                ),
            }),
            None => Err(DbError::NotCreated { target }),
            Some(v) => Err(DbError::NeedsMigration {
                target,
                why: format!("it is at schema version {v}, this build reads version {want}"),
            }),
        }
    }

    /// The migration history checked ([`schema_history::damage`]) before anything trusts it.
    fn check_history(&mut self) -> Result<(), DbError> {
        match self.reading(schema_history::damage)? {
            None => Ok(()),
            Some(what) => {
                Err(DbError::MigrationHistory { target: self.target.clone(), what, repairable: true })
            }
        }
    }

    /// Runs `f` holding the migration's advisory lock (PostgreSQL).
    fn pg_locked(&mut self, f: impl FnOnce(&mut Conn) -> Result<(), DbError>) -> Result<(), DbError> {
        self.pg_locked_as(LockMode::Exclusive, f)
    }

    /// Runs `f` holding the migration's advisory lock, `exclusive` (a writer that may migrate) or
    /// `shared` (a reader, which waits for a migration under way and lets other readers in).
    fn pg_locked_as(
        &mut self,
        mode: LockMode,
        f: impl FnOnce(&mut Conn) -> Result<(), DbError>,
    ) -> Result<(), DbError> {
        let lock = |c: &mut Conn, sql: &str| -> Result<(), DbError> {
            let Link::Postgres(client, _) = &mut c.link else { unreachable!("a PostgreSQL connection") };
            client.execute(sql, &[&MIGRATION_LOCK]).map(drop).map_err(DbError::pg)
        };
        let (take, give) = match mode {
            LockMode::Shared => {
                ("SELECT pg_advisory_lock_shared($1)", "SELECT pg_advisory_unlock_shared($1)")
            }
            LockMode::Exclusive => ("SELECT pg_advisory_lock($1)", "SELECT pg_advisory_unlock($1)"),
        };
        lock(self, take)?;
        let r = f(self);
        lock(self, give)?;
        r
    }

    /// The schema versions applied, oldest first.
    pub fn applied_versions(&mut self) -> Result<Vec<i64>, DbError> {
        let rows = self.transaction(|tx| {
            tx.query("SELECT version FROM refinery_schema_history ORDER BY version", &[])
        })?;
        rows.iter().map(|r| r[0].int()).collect()
    }

    /// Runs `f` in one transaction: committed when it returns `Ok`, rolled back otherwise (and by
    /// the engine when the process dies first).
    pub fn transaction<T>(
        &mut self,
        f: impl FnOnce(&mut Tx<'_>) -> Result<T, DbError>,
    ) -> Result<T, DbError> {
        let target = self.target.clone();
        match self.transaction_here(f) {
            // The engine's message, with the database it came from.
            Err(DbError::Engine { cause }) if !cause.starts_with(&target) => {
                Err(DbError::Engine { cause: format!("{target}: {cause}") })
            }
            Err(e @ DbError::Schema { .. }) => Err(self.name_bad_cell(e)),
            r => r,
        }
    }

    /// A value that does not read as its type ([`DbError::Schema`]), named by table, row and
    /// column ([`DbError::BadCell`]) when a cell of SQLite's holds another type than its
    /// column's; any other failure as it is.
    pub fn name_bad_cell(&mut self, e: DbError) -> DbError {
        let DbError::Schema { what } = e else { return e };
        let was = std::mem::replace(&mut self.read_only, true);
        let cells = self.transaction_here(scan_cells).unwrap_or_default();
        self.read_only = was;
        match cells.split_first() {
            Some((first, more)) => DbError::BadCell {
                target: self.target.clone(),
                first: Box::new(first.clone()),
                more: more.len(),
            },
            None => DbError::Schema { what },
        }
    }

    /// Runs `f` in one transaction that only reads, as a reader's are (see `read_only`),
    /// whatever the connection was opened for: what every open asks (is there anything to seal
    /// or derive?) must not wait for a writer.
    pub fn reading<T>(&mut self, f: impl FnOnce(&mut Tx<'_>) -> Result<T, DbError>) -> Result<T, DbError> {
        let was = std::mem::replace(&mut self.read_only, true);
        let out = self.transaction(f);
        self.read_only = was;
        out
    }

    fn transaction_here<T>(
        &mut self,
        f: impl FnOnce(&mut Tx<'_>) -> Result<T, DbError>,
    ) -> Result<T, DbError> {
        let behavior = if self.read_only {
            rusqlite::TransactionBehavior::Deferred
        } else {
            rusqlite::TransactionBehavior::Immediate
        };
        match &mut self.link {
            Link::Sqlite(c) => {
                let tx = c.transaction_with_behavior(behavior).map_err(DbError::sqlite)?;
                let mut tx = Tx::Sqlite(tx);
                let out = f(&mut tx)?;
                match tx {
                    Tx::Sqlite(t) => t.commit().map_err(DbError::sqlite)?,
                    Tx::Postgres(..) => unreachable!("a SQLite connection gives SQLite transactions"),
                }
                Ok(out)
            }
            Link::Postgres(c, statements) => {
                let t = if self.read_only {
                    c.build_transaction()
                        .isolation_level(postgres::IsolationLevel::RepeatableRead)
                        .read_only(true)
                        .start()
                } else {
                    c.transaction()
                };
                let mut tx = Tx::Postgres(t.map_err(DbError::pg)?, statements);
                if !self.read_only {
                    // One writer at a time appends to the ledger (SQLite: `BEGIN IMMEDIATE` does it).
                    tx.execute("SELECT pg_advisory_xact_lock($1)", &[Val::Int(LEDGER_LOCK)])?;
                }
                let out = f(&mut tx)?;
                match tx {
                    Tx::Postgres(t, _) => t.commit().map_err(DbError::pg)?,
                    Tx::Sqlite(_) => unreachable!("a PostgreSQL connection gives PostgreSQL transactions"),
                }
                Ok(out)
            }
        }
    }

    /// The engine's name, for messages and tests.
    pub fn engine(&self) -> &'static str {
        match self.link {
            Link::Sqlite(_) => "sqlite",
            Link::Postgres(..) => "postgres",
        }
    }
}

/// Whether the migration history table (`refinery_schema_history`) is there.
pub(crate) fn history_exists(tx: &mut Tx<'_>) -> Result<bool, DbError> {
    let sql = match tx {
        Tx::Sqlite(_) => {
            "SELECT 1 FROM sqlite_master WHERE type = 'table' AND name = 'refinery_schema_history'"
        }
        Tx::Postgres(..) => {
            "SELECT 1 FROM pg_catalog.pg_tables WHERE tablename = 'refinery_schema_history' \
             AND schemaname = ANY (current_schemas(false))"
        }
    };
    Ok(!tx.query(sql, &[])?.is_empty())
}

/// The newest schema version applied (`None`: no accelcal schema, a new database). Read
/// without failing when the history table is not there.
fn latest_version(tx: &mut Tx<'_>) -> Result<Option<i64>, DbError> {
    if !history_exists(tx)? {
        return Ok(None);
    }
    let rows = tx.query("SELECT MAX(version) FROM refinery_schema_history", &[])?;
    match rows.first().map(|r| &r[0]) {
        None | Some(Val::Null) => Ok(None),
        Some(v) => v.int().map(Some),
    }
}

/// How the migration's advisory lock is held: by a writer that may migrate, or by a reader.
#[derive(Clone, Copy)]
enum LockMode {
    Exclusive,
    Shared,
}

/// Key of the PostgreSQL advisory lock held while migrating ("accelcal" in ASCII).
const MIGRATION_LOCK: i64 = 0x6163_6365_6c63_616c;
/// Key of the PostgreSQL advisory lock each writing transaction holds ("ledger\0\0"); a
/// reading one does not.
pub const LEDGER_LOCK: i64 = 0x6c65_6467_6572_0000;

fn migration_failed(e: refinery::Error) -> DbError {
    DbError::Migration { cause: e.to_string() }
}

/// Whether `path` (an existing file) and its directory take writes (SQLite writes its `-wal` and
/// `-shm` files beside the database). By access(2), never by opening the file: closing another
/// descriptor of a database drops every fcntl(2) lock this process's connections hold on it.
fn writable(path: &Path) -> bool {
    let dir = path.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new("."));
    let ok = |p: &Path| {
        std::ffi::CString::new(p.as_os_str().as_encoded_bytes())
            // SAFETY: access(2) reads the NUL-terminated path and nothing else.
            .map(|c| unsafe { libc::access(c.as_ptr(), libc::W_OK) } == 0)
            .unwrap_or(false)
    };
    ok(path) && ok(dir)
}

fn open_sqlite(
    path: &Path,
    access: Access,
    after: impl FnOnce(&mut Conn, Option<i64>) -> Result<(), DbError>,
) -> Result<Conn, DbError> {
    use rusqlite::OpenFlags;
    let shown = path.display().to_string();
    let failed = |e: rusqlite::Error| DbError::Unreachable { target: shown.clone(), cause: e.to_string() };
    let exists = path.exists();
    if access == Access::Read {
        if !exists {
            return Err(DbError::NoDatabase { path: path.to_path_buf() });
        }
        // A reader never writes the database: opened read-only (SQLite may create the `-wal`
        // and `-shm` files beside it, never the database's own pages). A read-only file or
        // mount is read as it is, without locks (nothing can change it).
        let flags =
            OpenFlags::SQLITE_OPEN_READ_ONLY | OpenFlags::SQLITE_OPEN_URI | OpenFlags::SQLITE_OPEN_NO_MUTEX;
        let c = if writable(path) {
            rusqlite::Connection::open_with_flags(path, flags)
        } else {
            rusqlite::Connection::open_with_flags(format!("file:{}?immutable=1", uri_path(path)), flags)
        }
        .map_err(failed)?;
        c.busy_timeout(WAIT).map_err(failed)?;
        let mut conn = Conn { link: Link::Sqlite(c), target: shown.clone(), read_only: true };
        conn.check_current()?;
        return Ok(conn);
    }
    if exists && !writable(path) {
        return Err(DbError::ReadOnly { path: path.to_path_buf() });
    }
    // Processes opening a new file at once set it up one after the other: the switch to WAL
    // (SQLite answers `database is locked` at once, without its busy handler, to a first open
    // that meets another's) and the migration (refinery reads the applied versions before its
    // transaction, so two first opens would both create the tables): an exclusive flock(2) on
    // the database's directory. Not on the database file itself: closing any other descriptor
    // of it would drop this process's fcntl(2) locks, SQLite's own.
    let dir = path.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new("."));
    let lock = std::fs::File::open(dir).map_err(|e| DbError::Unreachable {
        target: shown.clone(),
        cause: format!("opening its directory: {e}"),
    })?;
    lock.lock().map_err(|e| DbError::Unreachable {
        target: shown.clone(),
        cause: format!("locking its directory to migrate: {e}"),
    })?;
    let flags =
        OpenFlags::SQLITE_OPEN_READ_WRITE | OpenFlags::SQLITE_OPEN_CREATE | OpenFlags::SQLITE_OPEN_NO_MUTEX;
    let c = rusqlite::Connection::open_with_flags(path, flags).map_err(failed)?;
    if c.is_readonly(rusqlite::MAIN_DB).map_err(failed)? {
        return Err(DbError::ReadOnly { path: path.to_path_buf() });
    }
    c.busy_timeout(WAIT).map_err(failed)?;
    // WAL: readers do not block the writer; FULL sync: a committed row survives a power cut.
    c.pragma_update(None, "journal_mode", "WAL").map_err(failed)?;
    c.pragma_update(None, "synchronous", "FULL").map_err(failed)?;
    c.pragma_update(None, "foreign_keys", "ON").map_err(failed)?;
    let mut conn = Conn { link: Link::Sqlite(c), target: shown.clone(), read_only: false };
    conn.check_history()?;
    let before = conn.reading(latest_version)?;
    {
        let Link::Sqlite(c) = &mut conn.link else { unreachable!("a SQLite connection") };
        embedded::sqlite::migrations::runner().run(c).map_err(migration_failed)?;
    }
    after(&mut conn, before)?;
    drop(lock);
    Ok(conn)
}

/// A PostgreSQL connection, not yet checked or migrated (10 s to connect unless `spec` says).
fn connect_pg(spec: &str, access: Access) -> Result<Conn, DbError> {
    let mut config: postgres::Config = spec
        .parse()
        .map_err(|e: postgres::Error| DbError::BadTarget { spec: redact(spec), why: e.to_string() })?;
    if config.get_connect_timeout().is_none() {
        config.connect_timeout(WAIT);
    }
    let client = config
        .connect(postgres::NoTls)
        .map_err(|e| DbError::Unreachable { target: redact(spec), cause: pg_cause(&e) })?;
    Ok(Conn {
        link: Link::Postgres(Box::new(client), Statements::default()),
        target: redact(spec),
        read_only: access == Access::Read,
    })
}

/// `accelcal db migrate`'s first step on an existing database: its migration history recorded
/// again when it is damaged and the schema is exactly that of one of this build's versions
/// ([`schema_history::repair`]; on PostgreSQL under the migration's lock); what was done, or
/// `None` (nothing to do).
pub fn repair_schema_history(target: &Target) -> Result<Option<String>, DbError> {
    use rusqlite::OpenFlags;
    let path = match target {
        Target::Sqlite(path) => path,
        Target::Postgres(spec) => {
            let mut conn = connect_pg(spec, Access::Write)?;
            let shown = conn.target.clone();
            let mut done = None;
            conn.pg_locked(|c| {
                done = c.transaction(|tx| schema_history::repair(tx, &shown))?;
                Ok(())
            })?;
            return Ok(done);
        }
    };
    if !path.exists() {
        return Ok(None);
    }
    if !writable(path) {
        return Err(DbError::ReadOnly { path: path.to_path_buf() });
    }
    let shown = path.display().to_string();
    let failed = |e: rusqlite::Error| DbError::Unreachable { target: shown.clone(), cause: e.to_string() };
    let c = rusqlite::Connection::open_with_flags(
        path,
        OpenFlags::SQLITE_OPEN_READ_WRITE | OpenFlags::SQLITE_OPEN_NO_MUTEX,
    )
    .map_err(failed)?;
    c.busy_timeout(WAIT).map_err(failed)?;
    let mut conn = Conn { link: Link::Sqlite(c), target: shown.clone(), read_only: false };
    conn.transaction(|tx| schema_history::repair(tx, &shown))
}

/// A path for a `file:` URI: `%`, `?` and `#` percent-encoded.
fn uri_path(path: &Path) -> String {
    let mut out = String::new();
    for c in path.to_string_lossy().chars() {
        match c {
            '%' => out.push_str("%25"),
            '?' => out.push_str("%3f"),
            '#' => out.push_str("%23"),
            c => out.push(c),
        }
    }
    out
}

/// A PostgreSQL error in the server's own words (`database "x" does not exist`, `password
/// authentication failed for user "y"`), or the client's with its causes (`Connection refused`).
pub fn pg_cause(e: &postgres::Error) -> String {
    if let Some(d) = e.as_db_error() {
        let mut s = d.message().to_string();
        if let Some(detail) = d.detail() {
            s.push_str(&format!(" ({detail})"));
        }
        return s;
    }
    let mut s = e.to_string();
    let mut src = std::error::Error::source(e);
    while let Some(c) = src {
        let c_text = c.to_string();
        if !s.contains(&c_text) {
            s.push_str(&format!(": {c_text}"));
        }
        src = c.source();
    }
    s
}

impl Tx<'_> {
    /// Runs a statement that returns no rows; the number of rows it changed.
    pub fn execute(&mut self, sql: &str, params: &[Val]) -> Result<u64, DbError> {
        match self {
            Tx::Sqlite(t) => t
                .prepare_cached(sql)
                .and_then(|mut st| st.execute(rusqlite::params_from_iter(params.iter())))
                .map(|n| n as u64)
                .map_err(DbError::sqlite),
            Tx::Postgres(t, statements) => {
                let p: Vec<&(dyn PgToSql + Sync)> =
                    params.iter().map(|v| v as &(dyn PgToSql + Sync)).collect();
                let st = statements.get(t, sql)?;
                t.execute(&st, &p).map_err(DbError::pg)
            }
        }
    }

    /// Runs a query; its rows, each a vector of the selected columns.
    pub fn query(&mut self, sql: &str, params: &[Val]) -> Result<Vec<Vec<Val>>, DbError> {
        match self {
            Tx::Sqlite(t) => {
                let mut st = t.prepare_cached(sql).map_err(DbError::sqlite)?;
                let n = st.column_count();
                let mut rows =
                    st.query(rusqlite::params_from_iter(params.iter())).map_err(DbError::sqlite)?;
                let mut out = Vec::new();
                while let Some(r) = rows.next().map_err(DbError::sqlite)? {
                    out.push((0..n).map(|i| sqlite_val(r.get_ref(i))).collect::<Result<_, _>>()?);
                }
                Ok(out)
            }
            Tx::Postgres(t, statements) => {
                let p: Vec<&(dyn PgToSql + Sync)> =
                    params.iter().map(|v| v as &(dyn PgToSql + Sync)).collect();
                let st = statements.get(t, sql)?;
                let rows = t.query(&st, &p).map_err(DbError::pg)?;
                rows.iter().map(|r| (0..r.len()).map(|i| pg_val(r, i)).collect()).collect()
            }
        }
    }
}

fn sqlite_val(v: rusqlite::Result<rusqlite::types::ValueRef<'_>>) -> Result<Val, DbError> {
    use rusqlite::types::ValueRef;
    Ok(match v.map_err(DbError::sqlite)? {
        ValueRef::Null => Val::Null,
        ValueRef::Integer(i) => Val::Int(i),
        ValueRef::Real(f) => Val::Real(f),
        ValueRef::Text(t) => Val::Text(String::from_utf8_lossy(t).into_owned()),
        ValueRef::Blob(b) => Val::Bytes(b.to_vec()),
    })
}

fn pg_val(r: &postgres::Row, i: usize) -> Result<Val, DbError> {
    let ty = r.columns()[i].type_().clone();
    let get = |e: postgres::Error| DbError::pg(e);
    let v = if ty == Type::INT8 {
        r.try_get::<_, Option<i64>>(i).map_err(get)?.map(Val::Int)
    } else if ty == Type::INT4 {
        r.try_get::<_, Option<i32>>(i).map_err(get)?.map(|v| Val::Int(v.into()))
    } else if ty == Type::FLOAT8 {
        r.try_get::<_, Option<f64>>(i).map_err(get)?.map(Val::Real)
    } else if ty == Type::TEXT || ty == Type::VARCHAR || ty == Type::NAME {
        r.try_get::<_, Option<String>>(i).map_err(get)?.map(Val::Text)
    } else if ty == Type::BYTEA {
        r.try_get::<_, Option<Vec<u8>>>(i).map_err(get)?.map(Val::Bytes)
    } else if ty == Type::BOOL {
        r.try_get::<_, Option<bool>>(i).map_err(get)?.map(Val::Bool)
    } else {
        return Err(DbError::schema(format!("column {i} has type {ty}, which this build does not read")));
    };
    Ok(v.unwrap_or(Val::Null))
}

/// Text from a cell as a message shows it: control characters escaped (`\u{1b}`), nothing else.
fn shown(s: &str) -> String {
    s.chars().map(|c| if c.is_control() { c.escape_unicode().to_string() } else { c.to_string() }).collect()
}

/// The storage classes a declared type takes (SQLite's affinity rules for the types the schema
/// uses).
fn takes(declared: &str) -> &'static [&'static str] {
    let d = declared.to_ascii_uppercase();
    if d.contains("INT") || d.contains("BOOL") {
        &["integer"]
    } else if d.contains("CHAR") || d.contains("TEXT") || d.contains("CLOB") {
        &["text"]
    } else if d.contains("BLOB") || d.contains("BYTEA") || d.is_empty() {
        &["blob"]
    } else {
        // REAL, DOUBLE PRECISION, FLOAT: a whole number may be kept as an integer.
        &["real", "integer"]
    }
}

/// Every cell of every accelcal table (the calibration's, the ledger, the derived rows, the
/// migration history) that does not read as its declared type. Empty on PostgreSQL, whose
/// columns hold their type only.
pub fn scan_cells(tx: &mut Tx<'_>) -> Result<Vec<BadCell>, DbError> {
    if !matches!(tx, Tx::Sqlite(_)) {
        return Ok(Vec::new());
    }
    let tables: Vec<String> = tx
        .query(
            "SELECT name FROM sqlite_master WHERE type = 'table' AND name NOT LIKE 'sqlite\\_%' ESCAPE '\\' ORDER BY name",
            &[],
        )?
        .iter()
        .map(|r| r[0].text())
        .collect::<Result<_, _>>()?;
    let mut out = Vec::new();
    for t in tables {
        // name, type, notnull, pk (SQLite's table_info columns 1, 2, 3, 5).
        let info =
            tx.query(&format!("SELECT name, type, \"notnull\", pk FROM pragma_table_info('{t}')"), &[])?;
        let mut key: Vec<(i64, String)> = Vec::new();
        let mut cols: Vec<(String, String, bool)> = Vec::new();
        for r in &info {
            let name = r[0].text()?;
            let pk = r[3].int()?;
            if pk > 0 {
                key.push((pk, name.clone()));
            }
            cols.push((name, r[1].text()?, r[2].int()? != 0));
        }
        key.sort();
        let key_sql = if key.is_empty() {
            "'rowid ' || rowid".to_string()
        } else {
            key.iter()
                .map(|(_, k)| format!("'{k} = ' || quote(substr(CAST(\"{k}\" AS TEXT), 1, 40))"))
                .collect::<Vec<_>>()
                .join(" || ', ' || ")
        };
        for (c, declared, not_null) in cols {
            let mut allowed: Vec<&str> = takes(&declared).to_vec();
            if !not_null {
                allowed.push("null");
            }
            let list = allowed.iter().map(|a| format!("'{a}'")).collect::<Vec<_>>().join(", ");
            let rows = tx.query(
                &format!(
                    "SELECT {key_sql}, typeof(\"{c}\"), quote(substr(CAST(\"{c}\" AS TEXT), 1, 40)) FROM \"{t}\" \
                     WHERE typeof(\"{c}\") NOT IN ({list}) LIMIT 1000"
                ),
                &[],
            )?;
            for r in rows {
                let value = match &r[2] {
                    Val::Text(s) => shown(s),
                    v => format!("{v:?}"),
                };
                out.push(BadCell {
                    table: t.clone(),
                    row: shown(&r[0].text().unwrap_or_default()),
                    column: c.clone(),
                    declared: declared.clone(),
                    read: format!("{} {value}", r[1].text()?),
                });
            }
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A version-1 database (no ledger) opened by this build: migrated, and its rows sealed
    /// into the chain once, in the order they were written.
    #[test]
    fn a_version_1_database_is_sealed_into_the_chain_once() {
        use crate::{chain, Db, RunId, RunStart};
        let d = tempfile::tempdir().unwrap();
        let path = d.path().join("v1.sqlite");
        let mut c = rusqlite::Connection::open(&path).unwrap();
        embedded::sqlite::migrations::runner().set_target(refinery::Target::Version(1)).run(&mut c).unwrap();
        let s = RunStart {
            run_id: RunId::new(),
            device_id: "51454d552d422d4c34373545".into(),
            serial: "U-1".into(),
            station: "st".into(),
            head: "manual".into(),
            operator: "ana".into(),
            started_unix_s: 1_767_225_600,
            software_version: "0.1.0".into(),
            firmware_version: String::new(),
            g_m_s2: 9.80665,
            g_source: "--g".into(),
        };
        let id = s.run_id.to_string();
        c.execute(
            "INSERT INTO run VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, ?12)",
            rusqlite::params![
                id,
                s.device_id,
                s.serial,
                s.station,
                s.head,
                s.operator,
                s.started_unix_s,
                s.software_version,
                s.firmware_version,
                s.g_m_s2,
                s.g_source,
                chain::run_content(&s)
            ],
        )
        .unwrap();
        let fit = r#"{"channels":[]}"#;
        c.execute(
            "INSERT INTO fit VALUES (?1, ?2, 1767225700, ?3)",
            rusqlite::params![id, fit, crate::sha256_hex(fit.as_bytes())],
        )
        .unwrap();
        drop(c);
        let spec = path.display().to_string();
        let r = Db::open(&spec).unwrap().verify_chain().unwrap();
        assert!(r.mismatches.is_empty(), "{:?}", r.mismatches);
        assert_eq!((r.entries, r.rows, r.runs), (3, 3, 1), "two rows and the legacy-seal event");
        assert_eq!(r.events.len(), 1);
        let mut db = Db::open(&spec).unwrap();
        assert_eq!(db.verify_chain().unwrap().entries, 3, "sealed once");
        assert_eq!(db.schema_versions().unwrap(), vec![1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12]);
        db.verify_run(s.run_id).unwrap();
    }

    #[test]
    fn targets_are_told_apart_and_passwords_never_shown() {
        assert_eq!(Target::parse("cal.sqlite").unwrap(), Target::Sqlite("cal.sqlite".into()));
        let t = Target::parse("postgres://line:secret@db.local:5433/accelcal").unwrap();
        assert_eq!(t.display(), "postgres://line:***@db.local:5433/accelcal");
        let t = Target::parse("host=/tmp port=5433 user=line password=secret").unwrap();
        assert_eq!(t.display(), "host=/tmp port=5433 user=line password=***");
        assert!(matches!(Target::parse("  "), Err(DbError::BadTarget { .. })));
        assert!(matches!(Target::parse("postgres://h:notaport/db"), Err(DbError::BadTarget { .. })));
    }
}
