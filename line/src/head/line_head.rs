//! A head that speaks the line protocol of [`super::protocol`]: [`LineHead`] drives the emulated
//! head at `sim:HOST:PORT` over TCP, and an adapter (`exec:COMMAND`, [`super::exec`]) over its
//! standard input and output. Both are a [`Link`]; the head is greeted (`HELLO`) before anything
//! else, and one that speaks another protocol version is refused.

use super::link::Link;
use super::protocol::{Reply, Request, VERSION};
use super::{Angles, HeadError, Positioner, Target};
use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use std::time::Duration;

/// A head on the line protocol.
pub struct LineHead {
    spec: String,
    ident: String,
    link: Link,
    stop: Option<Arc<AtomicBool>>,
}

impl LineHead {
    /// Connects to the emulated head at `addr` (`HOST:PORT`) and greets it; every request, a move
    /// included, must be answered within `timeout` (> 0).
    pub fn connect(addr: &str, timeout: Duration) -> Result<LineHead, HeadError> {
        LineHead::greet(format!("sim:{addr}"), Link::tcp(addr, timeout)?)
    }

    /// Greets the head at the end of `link` (`HELLO`), named `spec` in the campaign and the
    /// journal: it must speak this build's protocol version.
    pub fn greet(spec: String, mut link: Link) -> Result<LineHead, HeadError> {
        match link.request(Request::Hello)? {
            Reply::Hello { version: VERSION, ident } => Ok(LineHead { spec, ident, link, stop: None }),
            Reply::Hello { version, .. } => Err(HeadError::Protocol {
                addr: link.name().to_string(),
                message: format!(
                    "speaks head protocol version {version}; this build speaks version {VERSION} \
                     (the guide's \"Connecting a dividing head\" page lists what changed)"
                ),
            }),
            other => Err(link_unexpected(&link, "HELLO", &other)),
        }
    }

    /// Stops the head at once when `stop` is set during a move (Ctrl-C): the move ends where the
    /// head stopped.
    pub fn stop_on(mut self, stop: Arc<AtomicBool>) -> LineHead {
        self.stop = Some(stop);
        self
    }

    /// What the head said it is in its `HELLO` (escaped).
    pub fn ident(&self) -> &str {
        &self.ident
    }

    /// Sends one request and reads its reply; `ERR` replies are errors.
    pub fn request(&mut self, req: Request) -> Result<Reply, HeadError> {
        self.link.request(req)
    }

    fn unexpected(&self, after: &str, got: &Reply) -> HeadError {
        link_unexpected(&self.link, after, got)
    }

    fn angles(&self, after: &str, got: Reply) -> Result<Angles, HeadError> {
        match got {
            Reply::Ok { alpha_deg, beta_deg } => Ok(Angles { alpha_deg, beta_deg }),
            other => Err(self.unexpected(after, &other)),
        }
    }

    /// Sets the rig's thermal chamber to `temp_c` (°C); returns the setpoint it confirmed.
    pub fn set_chamber(&mut self, temp_c: f64) -> Result<f64, HeadError> {
        match self.request(Request::Chamber { temp_c })? {
            Reply::Temp { setpoint_c } => Ok(setpoint_c),
            other => Err(self.unexpected("CHAMBER", &other)),
        }
    }

    /// Turns the head to `(alpha_deg, beta_deg)` and returns when it stands there, with the
    /// angles it reports. When the stop flag ([`LineHead::stop_on`]) is set meanwhile, the head
    /// is stopped and the angles it stopped at are returned.
    pub fn move_to(&mut self, alpha_deg: f64, beta_deg: f64) -> Result<Angles, HeadError> {
        let req = Request::Move { alpha_deg, beta_deg };
        let reply = match self.stop.clone() {
            Some(stop) => match self.link.request_or_stop(req, &stop)? {
                (_, Some(stopped)) => return self.angles("STOP", stopped),
                (moved, None) => moved,
            },
            None => self.link.request(req)?,
        };
        self.angles("MOVE", reply)
    }
}

fn link_unexpected(link: &Link, after: &str, got: &Reply) -> HeadError {
    HeadError::Protocol {
        addr: link.name().to_string(),
        message: format!("unexpected reply `{}` to {after}", got.line()),
    }
}

/// A head on the line protocol as a [`Positioner`]: homes, moves, stops, never retries.
impl Positioner for LineHead {
    fn describe(&self) -> String {
        self.spec.clone()
    }
    fn home(&mut self) -> anyhow::Result<()> {
        let reply = self.request(Request::Home)?;
        self.angles("HOME", reply)?;
        Ok(())
    }
    fn set(&mut self, t: &Target) -> anyhow::Result<Angles> {
        Ok(self.move_to(t.angles.alpha_deg, t.angles.beta_deg)?)
    }
    fn read_back(&mut self) -> anyhow::Result<Angles> {
        match self.request(Request::Where)? {
            Reply::At { alpha_deg, beta_deg, .. } => Ok(Angles { alpha_deg, beta_deg }),
            other => Err(self.unexpected("WHERE", &other).into()),
        }
    }
    fn stop(&mut self) -> anyhow::Result<()> {
        let reply = self.request(Request::Stop)?;
        self.angles("STOP", reply)?;
        Ok(())
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
    use std::io::{BufRead, BufReader, Write};
    use std::time::Instant;

    /// Answers the greeting of the client on `s` as this build's emulated head does.
    fn greet(s: &mut std::net::TcpStream) {
        let mut line = String::new();
        BufReader::new(s.try_clone().unwrap()).read_line(&mut line).unwrap();
        assert_eq!(line, "HELLO\n");
        writeln!(s, "HELLO {VERSION} test head").unwrap();
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
                greet(&mut s);
                let mut line = String::new();
                BufReader::new(s.try_clone().unwrap()).read_line(&mut line).unwrap();
                s.write_all(reply).unwrap();
            }
        });
        for want in wants {
            let mut head = LineHead::connect(&addr, Duration::from_secs(5)).unwrap();
            assert_eq!(head.ident(), "test head");
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
                greet(&mut s);
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
            let mut head = LineHead::connect(&addr, timeout).unwrap();
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

    /// Ctrl-C during a move: the client sends `STOP` while the `MOVE` waits, and returns the
    /// angles where the head stopped once both replies are in; a head that speaks another version
    /// is refused at the greeting.
    #[test]
    fn a_stop_during_a_move_is_sent_and_both_replies_are_read() {
        let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
        let addr = listener.local_addr().unwrap().to_string();
        let server = std::thread::spawn(move || {
            let (mut s, _) = listener.accept().unwrap();
            greet(&mut s);
            let mut r = BufReader::new(s.try_clone().unwrap());
            let mut line = String::new();
            r.read_line(&mut line).unwrap();
            assert_eq!(line, "MOVE 90 0\n");
            line.clear();
            r.read_line(&mut line).unwrap();
            assert_eq!(line, "STOP\n");
            s.write_all(b"OK 12.5 0\nOK 12.5 0\n").unwrap();
            line.clear();
            r.read_line(&mut line).unwrap();
            assert_eq!(line, "WHERE\n");
            s.write_all(b"AT 12.5 0 STILL\n").unwrap();
            let (mut s, _) = listener.accept().unwrap();
            let mut line = String::new();
            BufReader::new(s.try_clone().unwrap()).read_line(&mut line).unwrap();
            s.write_all(b"HELLO 3 a later head\n").unwrap();
        });
        let stop = Arc::new(AtomicBool::new(false));
        let mut head = LineHead::connect(&addr, Duration::from_secs(5)).unwrap().stop_on(stop.clone());
        let flag = stop.clone();
        std::thread::spawn(move || {
            std::thread::sleep(Duration::from_millis(100));
            flag.store(true, std::sync::atomic::Ordering::Relaxed);
        });
        assert_eq!(head.move_to(90.0, 0.0).unwrap(), Angles { alpha_deg: 12.5, beta_deg: 0.0 });
        assert_eq!(head.read_back().unwrap(), Angles { alpha_deg: 12.5, beta_deg: 0.0 });
        let e = LineHead::connect(&addr, Duration::from_secs(5)).err().unwrap().to_string();
        assert!(e.contains("speaks head protocol version 3; this build speaks version 2"), "{e}");
        server.join().unwrap();
    }
}
