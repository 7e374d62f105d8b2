//! The dividing head: which head a command drives (`--head manual|sim:ADDR`) and the control
//! protocol of an emulated head (`accelcal emulate` serves it, `acquire` and `verify` drive it),
//! defined once for both ends.
//!
//! The protocol is one ASCII line per request and per reply over TCP (`sim:HOST:PORT`):
//!
//! | request | reply |
//! |---|---|
//! | `MOVE <alpha_deg> <beta_deg>` | `OK <alpha_deg> <beta_deg>` once the head stands still at the new angles |
//! | `WHERE` | `AT <alpha_deg> <beta_deg> STILL` or `AT … MOVING` (the angles it is passing) |
//! | `CHAMBER <temp_c>` | `TEMP <setpoint_c>`: the rig's thermal chamber now heads for this temperature (°C, −60..=150) |
//! | `TEMP` | `TEMP <setpoint_c>`: the chamber's setpoint |
//!
//! Any request the head cannot carry out is answered `ERR <reason>`. Angles are degrees in the
//! paper's convention (α about the spindle, β the tilt; `accelcal_shared::kinematics`).

use accelcal_core::error::{Classify, Kind};
use accelcal_core::text::escape_peer;
use std::io::{BufRead, BufReader, Write};
use std::net::TcpStream;
use std::time::{Duration, Instant};

/// Which head a command drives.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum HeadSpec {
    /// An operator turns the head by hand; the command shows the angles and waits for Enter.
    Manual,
    /// An emulated head at this TCP address (`HOST:PORT`), as `accelcal emulate` prints it.
    Sim(String),
}

impl std::str::FromStr for HeadSpec {
    type Err = String;
    fn from_str(s: &str) -> Result<HeadSpec, String> {
        if s == "manual" {
            return Ok(HeadSpec::Manual);
        }
        match s.strip_prefix("sim:") {
            Some(addr)
                if addr.rsplit_once(':').is_some_and(|(h, p)| !h.is_empty() && p.parse::<u16>().is_ok()) =>
            {
                Ok(HeadSpec::Sim(addr.to_string()))
            }
            _ => Err(format!(
                "`{s}`: expected `manual` or `sim:HOST:PORT` (the `head` that `accelcal emulate` prints)"
            )),
        }
    }
}

impl std::fmt::Display for HeadSpec {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            HeadSpec::Manual => f.write_str("manual"),
            HeadSpec::Sim(a) => write!(f, "sim:{a}"),
        }
    }
}

/// A request to a head.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Request {
    /// Turn to these angles, degrees.
    Move {
        /// α, degrees.
        alpha_deg: f64,
        /// β, degrees.
        beta_deg: f64,
    },
    /// Where is the head now?
    Where,
    /// Set the thermal chamber to this temperature, °C.
    Chamber {
        /// Setpoint, °C.
        temp_c: f64,
    },
    /// What is the chamber's setpoint?
    Temp,
}

/// The chamber setpoints the protocol accepts, °C.
pub const CHAMBER_RANGE_C: std::ops::RangeInclusive<f64> = -60.0..=150.0;

/// A head's reply.
#[derive(Clone, Debug, PartialEq)]
pub enum Reply {
    /// The move is done: the head stands at these angles.
    Ok {
        /// α, degrees.
        alpha_deg: f64,
        /// β, degrees.
        beta_deg: f64,
    },
    /// The head's angles now, and whether it is moving.
    At {
        /// α, degrees.
        alpha_deg: f64,
        /// β, degrees.
        beta_deg: f64,
        /// True while a move is under way.
        moving: bool,
    },
    /// The chamber's setpoint, °C.
    Temp {
        /// Setpoint, °C.
        setpoint_c: f64,
    },
    /// The request was refused.
    Err(String),
}

fn angles<'a>(mut words: impl Iterator<Item = &'a str>, what: &str) -> Result<(f64, f64), String> {
    let mut num = |name: &str| -> Result<f64, String> {
        words
            .next()
            .and_then(|w| w.parse::<f64>().ok())
            .filter(|v| v.is_finite())
            .ok_or_else(|| format!("{what}: expected {name} in degrees, a finite number"))
    };
    Ok((num("alpha")?, num("beta")?))
}

impl Request {
    /// The request's line, without the newline.
    pub fn line(&self) -> String {
        match *self {
            Request::Move { alpha_deg, beta_deg } => format!("MOVE {alpha_deg} {beta_deg}"),
            Request::Where => "WHERE".into(),
            Request::Chamber { temp_c } => format!("CHAMBER {temp_c}"),
            Request::Temp => "TEMP".into(),
        }
    }

    /// Parses a request line (surrounding white space ignored).
    pub fn parse(line: &str) -> Result<Request, String> {
        let mut words = line.split_whitespace();
        match words.next() {
            Some("MOVE") => {
                let (alpha_deg, beta_deg) = angles(words, "MOVE")?;
                Ok(Request::Move { alpha_deg, beta_deg })
            }
            Some("WHERE") => Ok(Request::Where),
            Some("TEMP") => Ok(Request::Temp),
            Some("CHAMBER") => match words.next().and_then(|w| w.parse::<f64>().ok()) {
                Some(temp_c) if CHAMBER_RANGE_C.contains(&temp_c) => Ok(Request::Chamber { temp_c }),
                _ => Err("CHAMBER: expected a temperature in -60..=150 °C".into()),
            },
            _ => Err(format!(
                "unknown request `{}` (expected MOVE <alpha> <beta>, WHERE, CHAMBER <temp_c> or TEMP)",
                escape_peer(line.trim().as_bytes())
            )),
        }
    }
}

impl Reply {
    /// The reply's line, without the newline.
    pub fn line(&self) -> String {
        match self {
            Reply::Ok { alpha_deg, beta_deg } => format!("OK {alpha_deg} {beta_deg}"),
            Reply::At { alpha_deg, beta_deg, moving } => {
                format!("AT {alpha_deg} {beta_deg} {}", if *moving { "MOVING" } else { "STILL" })
            }
            Reply::Temp { setpoint_c } => format!("TEMP {setpoint_c}"),
            Reply::Err(m) => format!("ERR {}", m.replace('\n', " ")),
        }
    }

    /// Parses a reply line. What the head sent is shown escaped in a refusal's words and in an
    /// `ERR`'s message ([`escape_peer`]): a reply cannot send escape sequences to the terminal.
    pub fn parse(line: &str) -> Result<Reply, String> {
        let line = line.trim();
        if let Some(m) = line.strip_prefix("ERR") {
            return Ok(Reply::Err(escape_peer(m.trim().as_bytes())));
        }
        let shown = escape_peer(line.as_bytes());
        let mut words = line.split_whitespace();
        match words.next() {
            Some("OK") => {
                let (alpha_deg, beta_deg) = angles(words, "OK")?;
                Ok(Reply::Ok { alpha_deg, beta_deg })
            }
            Some("TEMP") => {
                match words.next().and_then(|w| w.parse::<f64>().ok()).filter(|v| v.is_finite()) {
                    Some(setpoint_c) => Ok(Reply::Temp { setpoint_c }),
                    None => Err(format!("`{shown}`: expected TEMP <setpoint_c>")),
                }
            }
            Some("AT") => {
                let rest: Vec<&str> = words.collect();
                let moving = match rest.get(2) {
                    Some(&"MOVING") => true,
                    Some(&"STILL") => false,
                    _ => return Err(format!("`{shown}`: expected AT <alpha> <beta> MOVING|STILL")),
                };
                let (alpha_deg, beta_deg) = angles(rest.into_iter(), "AT")?;
                Ok(Reply::At { alpha_deg, beta_deg, moving })
            }
            _ => Err(format!("unexpected reply `{shown}` from the head")),
        }
    }
}

/// Why the emulated head could not be driven.
#[derive(Debug, thiserror::Error)]
pub enum HeadError {
    /// The connection failed or timed out.
    #[error("head {addr}: {cause}")]
    Io {
        /// The head's address.
        addr: String,
        /// The cause.
        cause: std::io::Error,
    },
    /// No reply within the head's timeout (a move is answered once the head stands still).
    #[error(
        "head {addr}: no reply to `{request}` within {secs} s (is the head stuck, or does a move take longer? \
         --head-timeout-s sets the wait)"
    )]
    Timeout {
        /// The head's address.
        addr: String,
        /// The request's line.
        request: String,
        /// The timeout, s.
        secs: f64,
    },
    /// The head answered something else than the protocol allows, or refused.
    #[error("head {addr}: {message}")]
    Protocol {
        /// The head's address.
        addr: String,
        /// What went wrong.
        message: String,
    },
}

impl Classify for HeadError {
    fn kind(&self) -> Kind {
        Kind::Environment
    }
}

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
                Err(e) if super::read_again(&e) => continue,
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

    /// Turns the head to `(alpha_deg, beta_deg)` and returns when it stands there.
    pub fn move_to(&mut self, alpha_deg: f64, beta_deg: f64) -> Result<(), HeadError> {
        match self.request(Request::Move { alpha_deg, beta_deg })? {
            Reply::Ok { .. } => Ok(()),
            other => Err(HeadError::Protocol {
                addr: self.addr.clone(),
                message: format!("expected OK after MOVE, got `{}`", other.line()),
            }),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lines_round_trip() {
        for r in [
            Request::Move { alpha_deg: 30.0, beta_deg: -90.0 },
            Request::Where,
            Request::Chamber { temp_c: -10.5 },
            Request::Temp,
        ] {
            assert_eq!(Request::parse(&r.line()), Ok(r));
        }
        for r in [
            Reply::Ok { alpha_deg: 0.0, beta_deg: 60.5 },
            Reply::At { alpha_deg: 12.25, beta_deg: -3.0, moving: true },
            Reply::At { alpha_deg: 0.0, beta_deg: 0.0, moving: false },
            Reply::Err("no such angle".into()),
            Reply::Temp { setpoint_c: 50.0 },
        ] {
            assert_eq!(Reply::parse(&r.line()), Ok(r));
        }
        assert!(Request::parse("MOVE 1 nan").is_err());
        assert!(Request::parse("JUMP").is_err());
        assert!(Request::parse("CHAMBER 400").is_err() && Request::parse("CHAMBER").is_err());
        assert!(Reply::parse("AT 1 2").is_err());
    }

    #[test]
    fn head_specs() {
        assert_eq!("manual".parse::<HeadSpec>(), Ok(HeadSpec::Manual));
        assert_eq!("sim:127.0.0.1:4000".parse::<HeadSpec>(), Ok(HeadSpec::Sim("127.0.0.1:4000".into())));
        assert!("sim:nowhere".parse::<HeadSpec>().is_err());
        assert!("auto".parse::<HeadSpec>().is_err());
    }

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
