//! `accelcal serve --db URL [--bind IP:PORT]`: a read-only web view of the calibration database
//! for the line (issue 31).
//!
//! axum serves server-side HTML from askama templates (`host/templates/serve/`, every value
//! escaped by the template engine; the charts are SVG from plotters, which escapes its text).
//! There is no JavaScript and no write endpoint: every route is a GET (axum answers 405 to any
//! other method), and each request takes a reading connection from a pool of at most
//! [`CONNECTIONS`] (r2d2; checked with a `SELECT 1` as it is taken) on a blocking thread, and
//! gathers what its page shows with the same functions as `fleet`, `history` and `certificate`;
//! the overview opens with what needs attention (`app::attention`), and every page carries the
//! search box ([`search`]).
//! The pool bounds what a browser's reloads can take of a PostgreSQL server's connections, which
//! the stations writing need, and saves a connection's setup per page; a request that finds
//! every connection busy for [`WAIT`] is answered 503. A Content-Security-Policy without scripts goes with every answer, so a stored
//! certificate (whose HTML the view serves as issued) cannot run one either.

pub mod auth;
pub mod escape;
mod links;
mod listen;
mod pages;
mod search;
mod svg;
mod ticks;

use std::io::Write;
use std::os::unix::fs::MetadataExt;
use std::path::PathBuf;
use std::sync::Arc;

use accelcal_core::error::{bad, environment};
use accelcal_db::{Db, DbError, Target};
use anyhow::Context;
use axum::extract::{Path, RawQuery, State};
use axum::http::{header, HeaderValue, StatusCode};
use axum::response::{Html, IntoResponse, Redirect, Response};
use axum::routing::get;
use axum::Router;

pub use listen::Limits;

use crate::cmd::store::reader_spec;
use crate::settings::reader::Serve;

/// Connections to the database the server keeps at most.
pub const CONNECTIONS: u32 = 4;

/// How long a request waits for a free connection before it is answered 503.
const WAIT: std::time::Duration = std::time::Duration::from_secs(10);

/// Descriptors the server needs besides its connections' (the database's files, the pool's
/// PostgreSQL sockets, the standard streams, the runtime's).
const OTHER_DESCRIPTORS: u64 = 64;

/// A SQLite file as a reading connection opened it: its device and inode. A connection whose
/// file is no longer at its path (removed, or replaced by another file) is not used again.
type FileId = (u64, u64);

/// The identity of the file at `path`, if there is one.
fn file_id(path: &std::path::Path) -> Option<FileId> {
    std::fs::metadata(path).ok().filter(|m| m.is_file()).map(|m| (m.dev(), m.ino()))
}

/// The pool's connections: readers of the database at `spec` (`Db::open_existing`: nothing is
/// created, migrated or written).
struct Readers {
    spec: String,
    /// The SQLite file, when it is one.
    file: Option<PathBuf>,
}

/// A pooled reading connection, and the SQLite file it reads.
struct Reader {
    db: Db,
    file: Option<FileId>,
}

/// Why the pool has no connection to give.
#[derive(Debug, thiserror::Error)]
enum ReaderError {
    #[error(transparent)]
    Db(#[from] DbError),
    /// The SQLite file changed under the connection (or while it was opened).
    #[error("{}: the database file was removed or replaced", .0.display())]
    Replaced(PathBuf),
}

impl r2d2::ManageConnection for Readers {
    type Connection = Reader;
    type Error = ReaderError;

    fn connect(&self) -> Result<Reader, ReaderError> {
        let Some(path) = &self.file else {
            return Ok(Reader { db: Db::open_existing(&self.spec)?.listing_unreadable(), file: None });
        };
        // The file's identity before and after the open: a file replaced meanwhile is not known
        // to be the one opened.
        let before = file_id(path);
        let db = Db::open_existing(&self.spec)?.listing_unreadable();
        match (before, file_id(path)) {
            (Some(a), Some(b)) if a == b => Ok(Reader { db, file: Some(a) }),
            _ => Err(ReaderError::Replaced(path.clone())),
        }
    }

    fn is_valid(&self, r: &mut Reader) -> Result<(), ReaderError> {
        if let (Some(path), Some(id)) = (&self.file, r.file) {
            if file_id(path) != Some(id) {
                return Err(ReaderError::Replaced(path.clone()));
            }
        }
        Ok(r.db.ping()?)
    }

    fn has_broken(&self, _: &mut Reader) -> bool {
        false
    }
}

/// What every handler needs.
#[derive(Clone)]
struct App {
    /// The reading connections.
    pool: r2d2::Pool<Readers>,
    /// The SQLite file, when it is one: checked before a connection is taken.
    file: Option<PathBuf>,
    /// Its name as the pages show it.
    target: String,
    /// The overview's horizon for units and assets due, days.
    due_days: u32,
}

/// Why a page cannot be shown: its status and a message for the reader.
#[derive(Debug)]
pub(crate) struct PageError {
    status: StatusCode,
    message: String,
}

impl PageError {
    fn bad(message: impl Into<String>) -> PageError {
        PageError { status: StatusCode::BAD_REQUEST, message: message.into() }
    }

    fn not_found(message: impl Into<String>) -> PageError {
        PageError { status: StatusCode::NOT_FOUND, message: message.into() }
    }

    fn internal(e: impl std::fmt::Display) -> PageError {
        PageError { status: StatusCode::INTERNAL_SERVER_ERROR, message: e.to_string() }
    }

    /// The rows asked for do not match their hash chain: 409, and nothing of them shown.
    fn tampered(e: impl std::fmt::Display) -> PageError {
        PageError { status: StatusCode::CONFLICT, message: e.to_string() }
    }

    /// The database failed: 503, for a reload to try again (not 404: the page may well exist).
    fn unavailable(e: impl std::fmt::Display) -> PageError {
        PageError { status: StatusCode::SERVICE_UNAVAILABLE, message: format!("the database failed: {e}") }
    }

    /// A failure of the functions `fleet` shares: the database's (503) or another (500).
    fn of(e: anyhow::Error) -> PageError {
        if e.chain().any(|c| c.downcast_ref::<DbError>().is_some()) {
            PageError::unavailable(crate::words::line(&e))
        } else {
            PageError::internal(crate::words::line(&e))
        }
    }
}

/// Raises the soft limit of open files to what `max_connections` need, or says why it cannot.
fn descriptors_for(max_connections: usize) -> anyhow::Result<()> {
    let need = max_connections as u64 + OTHER_DESCRIPTORS;
    let mut lim = libc::rlimit { rlim_cur: 0, rlim_max: 0 };
    // SAFETY: getrlimit writes the struct it is given.
    if unsafe { libc::getrlimit(libc::RLIMIT_NOFILE, &mut lim) } != 0 || lim.rlim_cur >= need {
        return Ok(());
    }
    if lim.rlim_max < need {
        return Err(bad(format!(
            "--max-connections {max_connections} needs {need} open files, and this process may open {} \
             (ulimit -n): give a smaller --max-connections",
            lim.rlim_max
        )));
    }
    let raised = libc::rlimit { rlim_cur: need, rlim_max: lim.rlim_max };
    // SAFETY: setrlimit reads the struct it is given; the soft limit stays under the hard one.
    if unsafe { libc::setrlimit(libc::RLIMIT_NOFILE, &raised) } != 0 {
        return Err(environment(
            format!("raising the open-file limit to {need} for --max-connections {max_connections}"),
            std::io::Error::last_os_error(),
        ));
    }
    Ok(())
}

/// Runs `accelcal serve` until Ctrl-C or SIGTERM.
pub fn run(a: &Serve) -> anyhow::Result<()> {
    descriptors_for(a.max_connections)?;
    let users = a.users.as_deref().map(auth::Users::read).transpose()?.map(Arc::new);
    let spec = reader_spec(a.db.as_deref())?;
    // The database must be there before the server listens.
    let first = Db::open_existing(&spec)?;
    let target = first.target();
    drop(first);
    let file = match Target::parse(&spec)? {
        Target::Sqlite(path) => Some(path),
        Target::Postgres(_) => None,
    };
    let pool = r2d2::Pool::builder()
        .max_size(CONNECTIONS)
        .min_idle(Some(1))
        .connection_timeout(WAIT)
        .build(Readers { spec, file: file.clone() })
        .with_context(|| format!("connecting to {target}"))?;
    let app = App { pool, file, target: target.clone(), due_days: a.due_days };
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .context("starting the web server's runtime")?;
    let served = rt.block_on(async {
        let listener = tokio::net::TcpListener::bind(a.bind)
            .await
            .map_err(|e| environment(format!("listening on {}", a.bind), e))?;
        let addr = listener.local_addr().context("the listening address")?;
        let login = if users.is_some() { "; HTTP Basic authentication" } else { "" };
        println!("serving {target} read-only at http://{addr}/ (GET only{login}; Ctrl-C stops)");
        std::io::stdout().flush().ok();
        let stop = stop_signal()?;
        let limits = Limits { header_timeout: a.header_timeout, max_connections: a.max_connections };
        listen::serve(listener, router(app.clone(), users), limits, stop).await;
        anyhow::Ok(())
    });
    // The database's connections are closed here, outside the runtime: the synchronous
    // PostgreSQL client runs a runtime of its own to close, which cannot start inside another.
    drop(rt);
    drop(app);
    served
}

/// Ctrl-C (SIGINT) or SIGTERM.
fn stop_signal() -> anyhow::Result<impl std::future::Future<Output = ()>> {
    use tokio::signal::unix::{signal, SignalKind};
    let mut int = signal(SignalKind::interrupt()).context("handling Ctrl-C")?;
    let mut term = signal(SignalKind::terminate()).context("handling SIGTERM")?;
    Ok(async move {
        tokio::select! {
            _ = int.recv() => {}
            _ = term.recv() => {}
        }
    })
}

fn router(app: App, users: Option<Arc<auth::Users>>) -> Router {
    let routes = Router::new()
        .route("/", get(overview))
        .route("/fleet", get(fleet))
        .route("/fleet.csv", get(fleet_csv))
        .route("/charts", get(charts))
        .route("/unit/{key}", get(unit))
        .route("/search", get(search))
        .route("/run/{id}", get(run_page))
        .route("/run/{id}/certificate", get(certificate))
        .route("/certificate/{number}", get(numbered))
        .fallback(not_found)
        .with_state(app);
    let routes = match users {
        Some(users) => routes.layer(axum::middleware::from_fn_with_state(users, auth::basic)),
        None => routes,
    };
    routes.layer(axum::middleware::map_response(secure))
}

/// No scripts, no frames, nothing fetched from elsewhere, on every answer.
async fn secure(mut r: Response) -> Response {
    let h = r.headers_mut();
    h.insert(
        header::CONTENT_SECURITY_POLICY,
        HeaderValue::from_static(
            "default-src 'none'; style-src 'unsafe-inline'; img-src 'self' data:; form-action 'self'",
        ),
    );
    h.insert(header::X_CONTENT_TYPE_OPTIONS, HeaderValue::from_static("nosniff"));
    h.insert(header::X_FRAME_OPTIONS, HeaderValue::from_static("DENY"));
    r
}

/// Gathers and renders a page on a blocking thread with the database open for reading.
async fn page<F>(app: App, render: F) -> Response
where
    F: FnOnce(&mut Db, &App) -> Result<Response, PageError> + Send + 'static,
{
    let target = app.target.clone();
    let done = tokio::task::spawn_blocking(move || {
        if let Some(path) = &app.file {
            if file_id(path).is_none() {
                return Err(PageError::unavailable(format!(
                    "{}: the database file is not there (removed, or being replaced)",
                    path.display()
                )));
            }
        }
        let mut r = app.pool.get().map_err(|e| PageError {
            status: StatusCode::SERVICE_UNAVAILABLE,
            message: format!("no connection to the database within {} s: {e}", WAIT.as_secs()),
        })?;
        // What an earlier page's reads set aside and did not show is not this page's.
        r.db.forget_unreadable();
        render(&mut r.db, &app)
    })
    .await;
    match done {
        Ok(Ok(r)) => r,
        Ok(Err(e)) => error_page(&target, e),
        Err(e) => error_page(&target, PageError::internal(e)),
    }
}

fn error_page(target: &str, e: PageError) -> Response {
    let body = pages::error(target, e.status, &e.message);
    (e.status, Html(body)).into_response()
}

fn html(s: String) -> Result<Response, PageError> {
    Ok(Html(s).into_response())
}

async fn overview(State(app): State<App>, RawQuery(q): RawQuery) -> Response {
    page(app, move |db, app| html(pages::overview(db, app, q.as_deref().unwrap_or(""))?)).await
}

async fn fleet(State(app): State<App>, RawQuery(q): RawQuery) -> Response {
    page(app, move |db, app| html(pages::fleet(db, app, q.as_deref().unwrap_or(""))?)).await
}

async fn fleet_csv(State(app): State<App>, RawQuery(q): RawQuery) -> Response {
    page(app, move |db, app| {
        let csv = pages::fleet_csv(db, app, q.as_deref().unwrap_or(""))?;
        Ok((
            [
                (header::CONTENT_TYPE, "text/csv; charset=utf-8"),
                (header::CONTENT_DISPOSITION, "attachment; filename=\"fleet.csv\""),
            ],
            csv,
        )
            .into_response())
    })
    .await
}

async fn charts(State(app): State<App>, RawQuery(q): RawQuery) -> Response {
    page(app, move |db, app| html(pages::charts(db, app, q.as_deref().unwrap_or(""))?)).await
}

async fn unit(State(app): State<App>, Path(key): Path<String>) -> Response {
    page(app, move |db, app| html(pages::unit(db, app, &key)?)).await
}

async fn certificate(State(app): State<App>, Path(id): Path<String>) -> Response {
    page(app, move |db, _| html(pages::certificate(db, &id)?)).await
}

async fn numbered(State(app): State<App>, Path(number): Path<String>) -> Response {
    page(app, move |db, _| html(pages::numbered(db, &number)?)).await
}

/// The query of the search box: `q`.
#[derive(serde::Deserialize)]
struct Search {
    #[serde(default)]
    q: String,
}

/// `/search?q=…`: a 303 to the page the search names, or the list of those it may name.
async fn search(State(app): State<App>, RawQuery(q): RawQuery) -> Response {
    page(app, move |db, app| {
        let s: Search = serde_urlencoded::from_str(q.as_deref().unwrap_or(""))
            .map_err(|e| PageError::bad(format!("the query `{}`: {e}", q.as_deref().unwrap_or(""))))?;
        match search::find(db, &app.target, &s.q)? {
            search::Found::Go(to) => Ok(Redirect::to(&to).into_response()),
            search::Found::Several(page) => html(page),
        }
    })
    .await
}

/// `/run/ID`: a 303 to the run's row on its unit's page.
async fn run_page(State(app): State<App>, Path(id): Path<String>) -> Response {
    page(app, move |db, _| {
        let run = accelcal_db::RunId::parse(&id).map_err(|e| PageError::bad(e.to_string()))?;
        Ok(Redirect::to(&search::run_row(db, run)?).into_response())
    })
    .await
}

async fn not_found(State(app): State<App>) -> Response {
    error_page(&app.target, PageError::not_found("no such page"))
}
