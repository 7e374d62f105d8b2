//! `accelcal serve --db URL [--bind IP:PORT]`: a read-only web view of the calibration database
//! for the line (issue 31).
//!
//! axum serves server-side HTML from askama templates (`host/templates/serve/`, every value
//! escaped by the template engine; the charts are SVG from plotters, which escapes its text).
//! There is no JavaScript and no write endpoint: every route is a GET (axum answers 405 to any
//! other method), and each request takes a reading connection from a pool of at most
//! [`CONNECTIONS`] (r2d2; checked with a `SELECT 1` as it is taken) on a blocking thread, and
//! gathers what its page shows with the same functions as `fleet`, `history` and `certificate`.
//! The pool bounds what a browser's reloads can take of a PostgreSQL server's connections, which
//! the stations writing need, and saves a connection's setup per page; a request that finds
//! every connection busy for [`WAIT`] is answered 503. A Content-Security-Policy without scripts goes with every answer, so a stored
//! certificate (whose HTML the view serves as issued) cannot run one either.

mod pages;
mod svg;

use std::io::Write;

use accelcal_core::error::environment;
use accelcal_db::Db;
use anyhow::Context;
use axum::extract::{Path, RawQuery, State};
use axum::http::{header, HeaderValue, StatusCode};
use axum::response::{Html, IntoResponse, Response};
use axum::routing::get;
use axum::Router;

use crate::cmd::store::reader_spec;
use crate::settings::reader::Serve;

/// Connections to the database the server keeps at most.
pub const CONNECTIONS: u32 = 4;

/// How long a request waits for a free connection before it is answered 503.
const WAIT: std::time::Duration = std::time::Duration::from_secs(10);

/// The pool's connections: readers of the database at `spec`.
struct Readers {
    spec: String,
}

impl r2d2::ManageConnection for Readers {
    type Connection = Db;
    type Error = accelcal_db::DbError;

    fn connect(&self) -> Result<Db, accelcal_db::DbError> {
        Db::open_existing(&self.spec)
    }

    fn is_valid(&self, db: &mut Db) -> Result<(), accelcal_db::DbError> {
        db.ping()
    }

    fn has_broken(&self, _: &mut Db) -> bool {
        false
    }
}

/// What every handler needs.
#[derive(Clone)]
struct App {
    /// The reading connections.
    pool: r2d2::Pool<Readers>,
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
}

/// Runs `accelcal serve` until Ctrl-C.
pub fn run(a: &Serve) -> anyhow::Result<()> {
    let spec = reader_spec(a.db.as_deref())?;
    // The database must be there before the server listens.
    let target = Db::open_existing(&spec)?.target();
    let pool = r2d2::Pool::builder()
        .max_size(CONNECTIONS)
        .min_idle(Some(1))
        .connection_timeout(WAIT)
        .build(Readers { spec })
        .with_context(|| format!("connecting to {target}"))?;
    let app = App { pool, target: target.clone(), due_days: a.due_days };
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .context("starting the web server's runtime")?;
    rt.block_on(async {
        let listener = tokio::net::TcpListener::bind(a.bind)
            .await
            .map_err(|e| environment(format!("listening on {}", a.bind), e))?;
        let addr = listener.local_addr().context("the listening address")?;
        println!("serving {target} read-only at http://{addr}/ (GET only; Ctrl-C stops)");
        std::io::stdout().flush().ok();
        axum::serve(listener, router(app))
            .with_graceful_shutdown(async {
                let _ = tokio::signal::ctrl_c().await;
            })
            .await
            .context("serving")
    })
}

fn router(app: App) -> Router {
    Router::new()
        .route("/", get(overview))
        .route("/fleet", get(fleet))
        .route("/fleet.csv", get(fleet_csv))
        .route("/charts", get(charts))
        .route("/unit/{key}", get(unit))
        .route("/run/{id}/certificate", get(certificate))
        .fallback(not_found)
        .layer(axum::middleware::map_response(secure))
        .with_state(app)
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
        let mut db = app.pool.get().map_err(|e| PageError {
            status: StatusCode::SERVICE_UNAVAILABLE,
            message: format!("no connection to the database within {} s: {e}", WAIT.as_secs()),
        })?;
        render(&mut db, &app)
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

async fn overview(State(app): State<App>) -> Response {
    page(app, |db, app| html(pages::overview(db, app)?)).await
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

async fn not_found(State(app): State<App>) -> Response {
    error_page(&app.target, PageError::not_found("no such page"))
}
