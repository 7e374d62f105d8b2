//! `serve`'s connections: hyper's HTTP/1 server under the limits a hostile peer needs.
//!
//! - **Header-read and idle timeout** ([`Limits::header_timeout`]): hyper's own
//!   `header_read_timeout`, whose clock starts when the connection opens and again after each
//!   answer, so it bounds both a slow request header and an idle keep-alive connection.
//! - **A cap on connections** ([`Limits::max_connections`]): at the cap, a new connection takes
//!   the place of the oldest one that has no request in hand (it waits for its first request or
//!   its next one, which is what an idle flood is), the way a proxy drops its idle keep-alive
//!   connections when it runs short; when every connection is in the middle of a request, the
//!   new one is answered `503 Service Unavailable` with a short text and closed. The cap keeps
//!   the server's descriptors under the process's limit, so `accept` never fails for want of one
//!   (the cause of the hang of issue 55: 1,100 idle connections under `ulimit -n 1024`).
//! - **Shutdown** on Ctrl-C or SIGTERM: no new connection, each open one finishes its request and
//!   is closed, at most [`GRACE`] later the server returns.

use std::collections::VecDeque;
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use axum::Router;
use hyper::server::conn::http1;
use hyper_util::rt::{TokioIo, TokioTimer};
use hyper_util::service::TowerToHyperService;
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::{TcpListener, TcpStream};
use tokio::sync::{watch, Notify};
use tokio::task::JoinSet;

/// How long open connections are given to finish at shutdown.
pub const GRACE: Duration = Duration::from_secs(5);

/// The limits of every connection.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Limits {
    /// A request's header must be complete this long after the connection opened or after the
    /// previous answer; else the connection is closed.
    pub header_timeout: Duration,
    /// Connections open at once, at most.
    pub max_connections: usize,
}

/// The open connections, oldest first.
struct Slots {
    open: Mutex<VecDeque<Slot>>,
    next: AtomicU64,
    cap: usize,
}

/// One open connection as [`Slots`] knows it.
struct Slot {
    id: u64,
    /// Its requests being answered (0: it waits for one).
    busy: Arc<AtomicUsize>,
    /// Told when another connection takes its place.
    evict: Arc<Notify>,
}

/// A connection's place among the open ones, given back when dropped.
struct Ticket {
    id: u64,
    slots: Arc<Slots>,
    busy: Arc<AtomicUsize>,
    evict: Arc<Notify>,
}

impl Slots {
    fn new(cap: usize) -> Arc<Slots> {
        Arc::new(Slots { open: Mutex::new(VecDeque::new()), next: AtomicU64::new(0), cap })
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, VecDeque<Slot>> {
        self.open.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// A place for a new connection: a free one, or the oldest idle connection's (which is told
    /// to close); `None` when every connection is busy.
    fn admit(self: &Arc<Slots>) -> Option<Ticket> {
        let mut open = self.lock();
        if open.len() >= self.cap {
            let idle = open.iter().position(|s| s.busy.load(Ordering::SeqCst) == 0)?;
            if let Some(old) = open.remove(idle) {
                old.evict.notify_one();
            }
        }
        let id = self.next.fetch_add(1, Ordering::Relaxed);
        let (busy, evict) = (Arc::new(AtomicUsize::new(0)), Arc::new(Notify::new()));
        open.push_back(Slot { id, busy: busy.clone(), evict: evict.clone() });
        Some(Ticket { id, slots: self.clone(), busy, evict })
    }
}

impl Drop for Ticket {
    fn drop(&mut self) {
        let mut open = self.slots.lock();
        if let Some(i) = open.iter().position(|s| s.id == self.id) {
            open.remove(i);
        }
    }
}

/// A request being answered: the connection's count, back down when dropped.
struct InHand(Arc<AtomicUsize>);

impl InHand {
    fn take(busy: &Arc<AtomicUsize>) -> InHand {
        busy.fetch_add(1, Ordering::SeqCst);
        InHand(busy.clone())
    }
}

impl Drop for InHand {
    fn drop(&mut self) {
        self.0.fetch_sub(1, Ordering::SeqCst);
    }
}

/// What a connection past the cap is told.
fn unavailable(cap: usize) -> String {
    let body = format!(
        "503 Service Unavailable: all {cap} connections of this server are answering requests; try again shortly\n"
    );
    format!(
        "HTTP/1.1 503 Service Unavailable\r\ncontent-type: text/plain; charset=utf-8\r\n\
         content-length: {}\r\nretry-after: 5\r\nconnection: close\r\n\r\n{body}",
        body.len()
    )
}

/// Answers 503 and closes, without waiting on the peer for more than a second. What the peer
/// sends meanwhile (its request) is read and dropped, so that the close does not reset the
/// connection before the peer has read the answer.
async fn refuse(mut stream: TcpStream, cap: usize) {
    let _ = tokio::time::timeout(Duration::from_secs(1), async {
        stream.write_all(unavailable(cap).as_bytes()).await?;
        stream.shutdown().await?;
        let mut sink = [0u8; 1024];
        while stream.read(&mut sink).await? > 0 {}
        std::io::Result::Ok(())
    })
    .await;
}

/// Serves `app` on `listener` under `limits` until `stop` completes, then lets the open
/// connections finish (at most [`GRACE`]).
pub async fn serve(
    listener: TcpListener,
    app: Router,
    limits: Limits,
    stop: impl std::future::Future<Output = ()>,
) {
    let slots = Slots::new(limits.max_connections.max(1));
    let mut http = http1::Builder::new();
    http.timer(TokioTimer::new()).header_read_timeout(limits.header_timeout).keep_alive(true);
    let (closing, closed) = watch::channel(false);
    let mut tasks = JoinSet::new();
    tokio::pin!(stop);
    loop {
        let stream = tokio::select! {
            () = &mut stop => break,
            accepted = listener.accept() => match accepted {
                Ok((stream, _)) => stream,
                Err(e) => {
                    // Out of descriptors (another process's, or a limit below the cap): wait for
                    // some to close rather than spin; a peer that went away: the next one.
                    if matches!(e.raw_os_error(), Some(libc::EMFILE | libc::ENFILE | libc::ENOBUFS | libc::ENOMEM)) {
                        tokio::time::sleep(Duration::from_millis(50)).await;
                    }
                    continue;
                }
            },
        };
        while tasks.try_join_next().is_some() {}
        let Some(ticket) = slots.admit() else {
            tasks.spawn(refuse(stream, slots.cap));
            continue;
        };
        let _ = stream.set_nodelay(true);
        let tower = TowerToHyperService::new(app.clone());
        let busy = ticket.busy.clone();
        let service = hyper::service::service_fn(move |request| {
            let in_hand = InHand::take(&busy);
            let answer = hyper::service::Service::call(&tower, request);
            async move {
                let r = answer.await;
                drop(in_hand);
                r
            }
        });
        let connection = http.serve_connection(TokioIo::new(stream), service);
        let mut closed = closed.clone();
        tasks.spawn(async move {
            tokio::pin!(connection);
            tokio::select! {
                _ = connection.as_mut() => {}
                () = ticket.evict.notified() => {}
                () = async { let _ = closed.wait_for(|c| *c).await; } => {
                    connection.as_mut().graceful_shutdown();
                    let _ = tokio::time::timeout(GRACE, connection).await;
                }
            }
            drop(ticket);
        });
    }
    drop(listener);
    let _ = closing.send(true);
    let _ = tokio::time::timeout(GRACE + Duration::from_secs(1), async {
        while tasks.join_next().await.is_some() {}
    })
    .await;
    tasks.abort_all();
}

#[cfg(test)]
mod tests {
    use super::*;
    use axum::routing::get;
    use std::io::{Read, Write};

    /// A server on 127.0.0.1 with `app` under `limits`, on its own runtime; stopped when the
    /// returned sender is dropped.
    fn start(app: Router, limits: Limits) -> (std::net::SocketAddr, tokio::sync::oneshot::Sender<()>) {
        let (stop_tx, stop_rx) = tokio::sync::oneshot::channel::<()>();
        let (addr_tx, addr_rx) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            let rt =
                tokio::runtime::Builder::new_multi_thread().worker_threads(2).enable_all().build().unwrap();
            rt.block_on(async move {
                let listener = TcpListener::bind("127.0.0.1:0").await.unwrap();
                addr_tx.send(listener.local_addr().unwrap()).unwrap();
                serve(listener, app, limits, async {
                    let _ = stop_rx.await;
                })
                .await;
            });
        });
        (addr_rx.recv().unwrap(), stop_tx)
    }

    fn get_path(addr: std::net::SocketAddr, path: &str) -> String {
        let mut s = std::net::TcpStream::connect(addr).unwrap();
        s.set_read_timeout(Some(Duration::from_secs(5))).unwrap();
        let _ = write!(s, "GET {path} HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n");
        let mut out = String::new();
        let _ = s.read_to_string(&mut out);
        out
    }

    #[test]
    fn a_connection_past_a_cap_of_busy_ones_is_answered_503() {
        // `/slow` holds its request until the test lets it go: two connections busy at a cap of 2.
        let release = Arc::new(Notify::new());
        let r = release.clone();
        let app = Router::new().route("/", get(|| async { "ok" })).route(
            "/slow",
            get(move || {
                let r = r.clone();
                async move {
                    r.notified().await;
                    "slow"
                }
            }),
        );
        let (addr, _stop) =
            start(app, Limits { header_timeout: Duration::from_secs(10), max_connections: 2 });
        let slow: Vec<_> = (0..2).map(|_| std::thread::spawn(move || get_path(addr, "/slow"))).collect();
        std::thread::sleep(Duration::from_millis(300));
        let refused = get_path(addr, "/");
        assert!(refused.starts_with("HTTP/1.1 503 Service Unavailable\r\n"), "{refused}");
        assert!(refused.contains("content-type: text/plain"), "{refused}");
        assert!(
            refused.ends_with("all 2 connections of this server are answering requests; try again shortly\n")
        );
        release.notify_waiters();
        for s in slow {
            assert!(s.join().unwrap().starts_with("HTTP/1.1 200 OK"));
        }
        assert!(get_path(addr, "/").starts_with("HTTP/1.1 200 OK"));
    }

    #[test]
    fn an_idle_connection_makes_room_and_times_out() {
        let app = Router::new().route("/", get(|| async { "ok" }));
        let (addr, _stop) =
            start(app, Limits { header_timeout: Duration::from_millis(500), max_connections: 2 });
        // Two idle connections fill the cap; a request takes the oldest one's place.
        let mut idle: Vec<_> = (0..2).map(|_| std::net::TcpStream::connect(addr).unwrap()).collect();
        std::thread::sleep(Duration::from_millis(100));
        assert!(get_path(addr, "/").starts_with("HTTP/1.1 200 OK"));
        let mut buf = [0u8; 64];
        idle[0].set_read_timeout(Some(Duration::from_secs(5))).unwrap();
        assert_eq!(idle[0].read(&mut buf).unwrap_or(0), 0, "the oldest idle connection was closed");
        // The other one is closed by the header timeout, half a second after it opened.
        let t = std::time::Instant::now();
        idle[1].set_read_timeout(Some(Duration::from_secs(5))).unwrap();
        let n = idle[1].read(&mut buf).unwrap_or(0);
        assert!(n == 0 || String::from_utf8_lossy(&buf[..n]).starts_with("HTTP/1.1 408"), "{n}");
        assert!(t.elapsed() < Duration::from_secs(2), "{:?}", t.elapsed());
    }
}
