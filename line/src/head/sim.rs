//! The emulated head's client: [`SimHead`] drives a head at `sim:HOST:PORT` over the line protocol
//! of [`super::protocol`].

use super::protocol::{Reply, Request};
use super::{Angles, HeadError, Positioner, Target};
use accelcal_core::text::escape_peer;
use std::io::{BufRead, BufReader, Write};
use std::net::TcpStream;
use std::time::{Duration, Instant};

/// The longest reply line a head may send, bytes (the protocol's are a few dozen).
const MAX_REPLY: usize = 1024;

/// A connection to an emulated head.
pub struct SimHead {
    addr: String,
    reader: BufReader<TcpStream>,
    writer: TcpStream,
    timeout: Duration,
}

impl SimHead {
    /// Connects to the head at `addr` (`HOST:PORT`); every request, a move included, must be
    /// answered within `timeout` (> 0).
    pub fn connect(addr: &str, timeout: Duration) -> Result<SimHead, HeadError> {
        let io = |cause| HeadError::Io { addr: addr.to_string(), cause };
        let stream = TcpStream::connect(addr).map_err(io)?;
        stream.set_nodelay(true).map_err(io)?;
        let writer = stream.try_clone().map_err(io)?;
        Ok(SimHead { addr: addr.to_string(), reader: BufReader::new(stream), writer, timeout })
    }

    /// Sends one request and reads its reply; `ERR` replies are errors. The reply must be
    /// complete within the head's timeout, an absolute deadline checked on every read whatever
    /// the head sends (a reply that trickles in byte by byte, or never ends its line).
    pub fn request(&mut self, req: Request) -> Result<Reply, HeadError> {
        let addr = self.addr.clone();
        let io = |cause| HeadError::Io { addr: addr.clone(), cause };
        writeln!(self.writer, "{}", req.line()).map_err(io)?;
        let deadline = Instant::now() + self.timeout;
        let mut line = Vec::new();
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            if left.is_zero() {
                return Err(HeadError::Timeout {
                    addr,
                    request: req.line(),
                    secs: self.timeout.as_secs_f64(),
                });
            }
            self.reader.get_ref().set_read_timeout(Some(left)).map_err(io)?;
            let got = match self.reader.fill_buf() {
                Ok(got) => got,
                Err(e) if crate::node::read_again(&e) => continue,
                Err(e) => return Err(io(e)),
            };
            if got.is_empty() {
                return Err(HeadError::Protocol { addr, message: "connection closed".into() });
            }
            let (take, end) = match got.iter().position(|&b| b == b'\n') {
                Some(i) => (i + 1, true),
                None => (got.len(), false),
            };
            line.extend_from_slice(&got[..take]);
            self.reader.consume(take);
            if end {
                break;
            }
            if line.len() > MAX_REPLY {
                return Err(HeadError::Protocol {
                    addr,
                    message: format!("a reply longer than {MAX_REPLY} bytes without a line end"),
                });
            }
        }
        let Ok(text) = std::str::from_utf8(&line) else {
            return Err(HeadError::Protocol {
                addr,
                message: format!("a reply that is not UTF-8 text: `{}`", escape_peer(line.trim_ascii())),
            });
        };
        match Reply::parse(text) {
            Ok(Reply::Err(message)) => {
                Err(HeadError::Protocol { addr, message: format!("refused: {message}") })
            }
            Ok(r) => Ok(r),
            Err(message) => Err(HeadError::Protocol { addr, message }),
        }
    }

    /// Sets the rig's thermal chamber to `temp_c` (°C); returns the setpoint it confirmed.
    pub fn set_chamber(&mut self, temp_c: f64) -> Result<f64, HeadError> {
        match self.request(Request::Chamber { temp_c })? {
            Reply::Temp { setpoint_c } => Ok(setpoint_c),
            other => Err(HeadError::Protocol {
                addr: self.addr.clone(),
                message: format!("expected TEMP after CHAMBER, got `{}`", other.line()),
            }),
        }
    }

    /// Turns the head to `(alpha_deg, beta_deg)` and returns when it stands there, with the
    /// angles it reports.
    pub fn move_to(&mut self, alpha_deg: f64, beta_deg: f64) -> Result<Angles, HeadError> {
        match self.request(Request::Move { alpha_deg, beta_deg })? {
            Reply::Ok { alpha_deg, beta_deg } => Ok(Angles { alpha_deg, beta_deg }),
            other => Err(HeadError::Protocol {
                addr: self.addr.clone(),
                message: format!("expected OK after MOVE, got `{}`", other.line()),
            }),
        }
    }
}

/// The emulated head as a [`Positioner`]: moves and never retries.
impl Positioner for SimHead {
    fn describe(&self) -> String {
        format!("sim:{}", self.addr)
    }
    fn set(&mut self, t: &Target) -> anyhow::Result<Angles> {
        Ok(self.move_to(t.angles.alpha_deg, t.angles.beta_deg)?)
    }
    fn read_back(&mut self) -> anyhow::Result<Angles> {
        match self.request(Request::Where)? {
            Reply::At { alpha_deg, beta_deg, .. } => Ok(Angles { alpha_deg, beta_deg }),
            other => Err(HeadError::Protocol {
                addr: self.addr.clone(),
                message: format!("expected AT after WHERE, got `{}`", other.line()),
            }
            .into()),
        }
    }
    fn chamber(&mut self, setpoint_c: f64) -> anyhow::Result<()> {
        self.set_chamber(setpoint_c)?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use accelcal_core::error::{Classify, Kind};

    /// A hostile head: its replies (a terminal title and a screen clear, an `ERR` with a bidi
    /// override, bytes that are not UTF-8) are shown escaped in the error, never sent raw to the
    /// operator's terminal (issue 55).
    #[test]
    fn a_head_s_reply_is_shown_escaped() {
        let replies: [&[u8]; 3] =
            [b"\x1b]0;pwned\x07\x1b[2J\n", "ERR no\u{202e}gnirts\x1b[31m\n".as_bytes(), b"OK \xff\x1b[2J\n"];
        let wants = [
            r"unexpected reply `\x1b]0;pwned\x07\x1b[2J` from the head",
            r"refused: no\u{202e}gnirts\x1b[31m",
            r"a reply that is not UTF-8 text: `OK \xff\x1b[2J`",
        ];
        let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
        let addr = listener.local_addr().unwrap().to_string();
        let server = std::thread::spawn(move || {
            for reply in replies {
                let (mut s, _) = listener.accept().unwrap();
                let mut line = String::new();
                BufReader::new(s.try_clone().unwrap()).read_line(&mut line).unwrap();
                s.write_all(reply).unwrap();
            }
        });
        for want in wants {
            let mut head = SimHead::connect(&addr, Duration::from_secs(5)).unwrap();
            let e = head.move_to(30.0, -90.0).unwrap_err().to_string();
            assert_eq!(e, format!("head {addr}: {want}"));
            assert!(!e.contains(['\u{1b}', '\u{7}', '\u{202e}']), "{e}");
        }
        server.join().unwrap();
    }

    /// A head that takes the connection and never answers, and one whose reply trickles in a byte
    /// at a time and never ends its line: a move fails after the head's timeout, naming it.
    #[test]
    fn a_frozen_head_fails_after_its_timeout() {
        for trickle in [false, true] {
            let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
            let addr = listener.local_addr().unwrap().to_string();
            let server = std::thread::spawn(move || {
                // Reads the request and waits until the client goes (or 3 s), answering nothing
                // or an endless "OOO…".
                let (mut s, _) = listener.accept().unwrap();
                s.set_read_timeout(Some(Duration::from_millis(20))).unwrap();
                let t0 = Instant::now();
                while t0.elapsed() < Duration::from_secs(3) {
                    if trickle && s.write_all(b"O").is_err() {
                        break;
                    }
                    if let Ok(0) = std::io::Read::read(&mut s, &mut [0u8; 64]) {
                        break;
                    }
                }
            });
            let timeout = Duration::from_millis(300);
            let mut head = SimHead::connect(&addr, timeout).unwrap();
            let t0 = Instant::now();
            let e = head.move_to(30.0, -90.0).unwrap_err();
            let took = t0.elapsed();
            assert!(took >= timeout && took < timeout + Duration::from_millis(200), "{took:?}");
            assert!(matches!(e, HeadError::Timeout { .. }), "{e:?}");
            let msg = e.to_string();
            assert!(
                msg.starts_with(&format!("head {addr}: no reply to `MOVE 30 -90` within 0.3 s")),
                "{msg}"
            );
            assert_eq!(e.kind(), Kind::Environment);
            drop(head);
            server.join().unwrap();
        }
    }
}
