//! The transport of the head protocol ([`super::protocol`]): request lines out, reply lines in,
//! each reply within the head's timeout. One [`Link`] for every transport: a TCP connection
//! (`sim:HOST:PORT`) or an adapter's standard input and output (`exec:COMMAND`).
//!
//! A reader thread cuts what the head sends into lines (at most [`MAX_REPLY`] bytes each) and hands
//! them over a channel, so a reply is awaited the same way whatever carries it, with an absolute
//! deadline whatever the head sends (a reply that trickles in byte by byte, or never ends its line).
//!
//! Invariants:
//! - Every request gets exactly one reply, in order; a `STOP` sent while a request waits (Ctrl-C
//!   during a move) is one more request, whose reply is read before the link is used again.
//! - Dropping the link ends its reader thread: the TCP connection is shut down; an adapter's
//!   standard input is closed, it is given [`EXEC_GRACE`] to exit, then killed and reaped.

use std::io::{Read, Write};
use std::net::TcpStream;
use std::process::Child;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{Receiver, RecvTimeoutError, Sender};
use std::time::{Duration, Instant};

use super::protocol::{Reply, Request};
use super::HeadError;
use accelcal_core::text::escape_peer;

/// The longest reply line a head may send, bytes (the protocol's are a few dozen).
pub const MAX_REPLY: usize = 1024;

/// How often a wait for a reply looks at the stop flag.
const POLL: Duration = Duration::from_millis(20);

/// How long an adapter may take to exit once its standard input is closed, before it is killed.
pub const EXEC_GRACE: Duration = Duration::from_secs(1);

/// What the reader thread hands over.
enum Line {
    /// One line, its end included.
    Text(Vec<u8>),
    /// More than [`MAX_REPLY`] bytes without a line end.
    TooLong,
    /// The head closed the connection (or the adapter its output).
    Closed,
    /// Reading failed.
    Failed(std::io::Error),
}

/// What the link holds open besides its two directions.
enum Peer {
    Tcp(TcpStream),
    /// The adapter, and the thread that forwards its standard error.
    Child(Child, Option<std::thread::JoinHandle<()>>),
}

/// A head's line protocol over one transport.
pub struct Link {
    name: String,
    writer: Option<Box<dyn Write + Send>>,
    lines: Receiver<Line>,
    timeout: Duration,
    peer: Peer,
}

/// Cuts `from` into lines for `to` until it ends, fails or the receiver goes.
fn pump(mut from: impl Read, to: Sender<Line>) {
    let mut line = Vec::new();
    let mut buf = [0u8; 512];
    loop {
        let n = match from.read(&mut buf) {
            Ok(0) => {
                let _ = to.send(Line::Closed);
                return;
            }
            Ok(n) => n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
            Err(e) => {
                let _ = to.send(Line::Failed(e));
                return;
            }
        };
        for &b in &buf[..n] {
            line.push(b);
            let sent = if b == b'\n' {
                to.send(Line::Text(std::mem::take(&mut line)))
            } else if line.len() > MAX_REPLY {
                // What follows up to the next line end belongs to the refused line: the link is
                // not used again (the request fails), so the thread ends here.
                let _ = to.send(Line::TooLong);
                return;
            } else {
                Ok(())
            };
            if sent.is_err() {
                return;
            }
        }
    }
}

impl Link {
    /// Connects to a head at `addr` (`HOST:PORT`); every reply must come within `timeout`.
    pub fn tcp(addr: &str, timeout: Duration) -> Result<Link, HeadError> {
        let io = |cause| HeadError::Io { addr: addr.to_string(), cause };
        let stream = TcpStream::connect(addr).map_err(io)?;
        stream.set_nodelay(true).map_err(io)?;
        let reader = stream.try_clone().map_err(io)?;
        let writer = stream.try_clone().map_err(io)?;
        let (tx, rx) = std::sync::mpsc::channel();
        std::thread::spawn(move || pump(reader, tx));
        Ok(Link {
            name: addr.to_string(),
            writer: Some(Box::new(writer)),
            lines: rx,
            timeout,
            peer: Peer::Tcp(stream),
        })
    }

    /// A link over a child's standard input (`stdin`) and output (`stdout`), named `name` in
    /// errors; the child is stopped when the link is dropped, and then `forwarder` (the thread
    /// that copies its standard error) is given the same grace to pass on its last lines.
    pub fn child(
        name: &str,
        mut child: Child,
        forwarder: Option<std::thread::JoinHandle<()>>,
        timeout: Duration,
    ) -> Result<Link, HeadError> {
        let (Some(stdin), Some(stdout)) = (child.stdin.take(), child.stdout.take()) else {
            let _ = child.kill();
            let _ = child.wait();
            return Err(HeadError::Protocol {
                addr: name.to_string(),
                message: "the adapter's standard input and output are not pipes".into(),
            });
        };
        let (tx, rx) = std::sync::mpsc::channel();
        std::thread::spawn(move || pump(stdout, tx));
        Ok(Link {
            name: name.to_string(),
            writer: Some(Box::new(stdin)),
            lines: rx,
            timeout,
            peer: Peer::Child(child, forwarder),
        })
    }

    /// The head's name in errors.
    pub fn name(&self) -> &str {
        &self.name
    }

    fn io(&self, cause: std::io::Error) -> HeadError {
        HeadError::Io { addr: self.name.clone(), cause }
    }

    fn protocol(&self, message: String) -> HeadError {
        HeadError::Protocol { addr: self.name.clone(), message }
    }

    fn send(&mut self, req: Request) -> Result<(), HeadError> {
        let line = format!("{}\n", req.line());
        let w = self.writer.as_mut().expect("the writer is taken only on drop");
        let sent = w.write_all(line.as_bytes()).and_then(|()| w.flush());
        sent.map_err(|e| self.io(e))
    }

    /// Waits for the reply to `req` until the head's timeout; when `stop` is given and gets set
    /// meanwhile, sends `STOP` once (and says so in the second value).
    fn receive(&mut self, req: Request, stop: Option<&AtomicBool>) -> Result<(Reply, bool), HeadError> {
        let mut deadline = Instant::now() + self.timeout;
        let mut stopping = false;
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            if left.is_zero() {
                let request = if stopping { Request::Stop.line() } else { req.line() };
                return Err(HeadError::Timeout {
                    addr: self.name.clone(),
                    request,
                    secs: self.timeout.as_secs_f64(),
                });
            }
            let watch = stop.filter(|_| !stopping);
            let wait = if watch.is_some() { left.min(POLL) } else { left };
            match self.lines.recv_timeout(wait) {
                Ok(line) => return Ok((self.reply(line)?, stopping)),
                Err(RecvTimeoutError::Timeout) => {
                    if watch.is_some_and(|s| s.load(Ordering::Relaxed)) {
                        self.send(Request::Stop)?;
                        stopping = true;
                        // The head stops at once: the move's reply and the stop's are due within
                        // a timeout from now.
                        deadline = Instant::now() + self.timeout;
                    }
                }
                Err(RecvTimeoutError::Disconnected) => {
                    return Err(self.protocol("connection closed".into()));
                }
            }
        }
    }

    /// One reply line, parsed; `ERR` replies are errors. What the head sent is shown escaped.
    fn reply(&self, line: Line) -> Result<Reply, HeadError> {
        let line = match line {
            Line::Text(l) => l,
            Line::TooLong => {
                return Err(
                    self.protocol(format!("a reply longer than {MAX_REPLY} bytes without a line end"))
                );
            }
            Line::Closed => return Err(self.protocol("connection closed".into())),
            Line::Failed(e) => return Err(self.io(e)),
        };
        let Ok(text) = std::str::from_utf8(&line) else {
            return Err(self
                .protocol(format!("a reply that is not UTF-8 text: `{}`", escape_peer(line.trim_ascii()))));
        };
        match Reply::parse(text) {
            Ok(Reply::Err(message)) => Err(self.protocol(format!("refused: {message}"))),
            Ok(r) => Ok(r),
            Err(message) => Err(self.protocol(message)),
        }
    }

    /// Sends one request and reads its reply; `ERR` replies are errors. The reply must be complete
    /// within the head's timeout.
    pub fn request(&mut self, req: Request) -> Result<Reply, HeadError> {
        self.send(req)?;
        Ok(self.receive(req, None)?.0)
    }

    /// As [`Link::request`], and when `stop` is set while the reply is awaited (Ctrl-C during a
    /// move), sends `STOP`: the head stops where it is and answers `req` with that position, then
    /// the `STOP`, whose reply is read (and returned second) before this returns.
    pub fn request_or_stop(
        &mut self,
        req: Request,
        stop: &AtomicBool,
    ) -> Result<(Reply, Option<Reply>), HeadError> {
        self.send(req)?;
        let (reply, stopping) = self.receive(req, Some(stop))?;
        if !stopping {
            return Ok((reply, None));
        }
        let (stopped, _) = self.receive(Request::Stop, None)?;
        Ok((reply, Some(stopped)))
    }
}

impl Drop for Link {
    fn drop(&mut self) {
        // Closing the writer is the adapter's signal to exit; a TCP head sees its connection end.
        drop(self.writer.take());
        match &mut self.peer {
            Peer::Tcp(s) => {
                let _ = s.shutdown(std::net::Shutdown::Both);
            }
            Peer::Child(c, forwarder) => {
                let t0 = Instant::now();
                while t0.elapsed() < EXEC_GRACE && !matches!(c.try_wait(), Ok(Some(_))) {
                    std::thread::sleep(Duration::from_millis(10));
                }
                if !matches!(c.try_wait(), Ok(Some(_))) {
                    let _ = c.kill();
                    let _ = c.wait();
                }
                // The adapter's last diagnostics reach the operator before the command goes on
                // (or ends with the adapter's error); a grandchild holding the pipe open is not
                // waited for beyond the grace.
                if let Some(f) = forwarder.take() {
                    let t0 = Instant::now();
                    while t0.elapsed() < EXEC_GRACE && !f.is_finished() {
                        std::thread::sleep(Duration::from_millis(5));
                    }
                    if f.is_finished() {
                        let _ = f.join();
                    }
                }
            }
        }
    }
}
