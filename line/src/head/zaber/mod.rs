//! A Zaber motorised head (`zaber:/dev/ttyUSB0` or `zaber:HOST:PORT`): two rotary axes, α (the
//! spindle) and β (the tilt), each a device and axis on one chain, driven over Zaber's ASCII
//! protocol ([`codec`]; sections of Zaber's *ASCII Protocol Manual* are cited there and below).
//!
//! - **Connection.** A serial port at 115 200 Bd, 8 data bits, no parity, 1 stop bit, no flow
//!   control (*Quick Start § Connecting*: the ASCII protocol's defaults), or a TCP socket (a
//!   controller's Ethernet port, or `accelcal emulate --head zaber`).
//! - **Scale.** Degrees to microsteps by [`ZaberAxes::deg_per_step`] (the stage's datasheet:
//!   *Physical Units*, a rotary stage's microstep size), rounded to the nearest microstep.
//! - **Homing** ([`Positioner::home`], once before the first move): `warnings clear` on each
//!   axis (*Command Reference § warnings*) lists its flags; an axis with `WH` (not homed) or `WR`
//!   (no reference position) gets `home` (*§ home*), and both are polled until `IDLE`.
//! - **Moves.** `move abs N` to both axes at once (*§ move*), then an empty command polls each
//!   axis (*Message Format § Commands*: no command, the status only) until both are `IDLE`,
//!   then `get pos` (*§ get*, setting `pos`) reads the angles back.
//! - **Faults.** Every reply is checked: its device and axis must be the ones addressed (a
//!   reply from another is refused), `RJ` is [`HeadError::Rejected`], a fault flag (*Warning
//!   Flags*: every `F…`, and `WL`, a limit sensor that stopped the move) is
//!   [`HeadError::Fault`], and so is `WH`/`WR` after homing; no reply within the head's timeout
//!   is [`HeadError::Timeout`]. Info (`#`) and alert (`!`) messages are skipped.
//! - **Stop.** `stop` to both axes (*§ stop*); a move under way when the stop flag is set is
//!   stopped and its read-back returned.

pub mod codec;

use std::io::{Read, Write};
use std::net::TcpStream;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use accelcal_core::text::escape_peer;
use codec::{parse_message, Address, Flag, Message, Reply, Severity, Status};

use super::{Angles, HeadError, Positioner, Target};

/// The two axes of a Zaber head and the scale of both.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ZaberAxes {
    /// α, the spindle (`--zaber-alpha`, `head_zaber_alpha`).
    pub alpha: Address,
    /// β, the tilt (`--zaber-beta`, `head_zaber_beta`).
    pub beta: Address,
    /// Degrees per microstep of both stages (`--zaber-deg-per-step`, `head_zaber_deg_per_step`).
    pub deg_per_step: f64,
}

impl ZaberAxes {
    /// The default scale, 0.000234375° (0.84375″) per microstep: 0.03° per full step at 128
    /// microsteps, a 1.8° motor through a 60:1 worm gear.
    pub const DEG_PER_STEP: f64 = 0.000_234_375;

    /// Checks the axes and the scale: two distinct axes, and a scale that is a finite number of
    /// degrees in (0, 1).
    pub fn check(&self) -> Result<(), String> {
        if self.alpha == self.beta {
            return Err(format!("alpha and beta are the same axis {}: each needs its own", self.alpha));
        }
        let d = self.deg_per_step;
        if !(d.is_finite() && d > 0.0 && d < 1.0) {
            return Err(format!("degrees per microstep must be a finite number in (0, 1), got {d}"));
        }
        Ok(())
    }

    /// The axis in words: `alpha (device 1 axis 1)`.
    pub fn name(&self, axis: Address) -> String {
        let which = if axis == self.alpha { "alpha" } else { "beta" };
        format!("{which} (device {} axis {})", axis.device, axis.axis)
    }
}

impl Default for ZaberAxes {
    /// α at device 1 axis 1, β at device 2 axis 1, [`ZaberAxes::DEG_PER_STEP`].
    fn default() -> ZaberAxes {
        ZaberAxes {
            alpha: Address { device: 1, axis: 1 },
            beta: Address { device: 2, axis: 1 },
            deg_per_step: ZaberAxes::DEG_PER_STEP,
        }
    }
}

/// Where a Zaber chain is reached.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum ZaberPort {
    /// A serial port (`/dev/ttyUSB0`, `/dev/pts/3`).
    Serial(String),
    /// A TCP address, `HOST:PORT`.
    Tcp(String),
}

impl std::fmt::Display for ZaberPort {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ZaberPort::Serial(p) | ZaberPort::Tcp(p) => f.write_str(p),
        }
    }
}

impl ZaberPort {
    /// `PORT` of `zaber:PORT`: a path (beginning with `/`) is a serial port, `HOST:PORT` a TCP
    /// address.
    pub fn parse(s: &str) -> Option<ZaberPort> {
        if s.starts_with('/') && s.len() > 1 {
            return Some(ZaberPort::Serial(s.to_string()));
        }
        s.rsplit_once(':')
            .is_some_and(|(h, p)| !h.is_empty() && p.parse::<u16>().is_ok())
            .then(|| ZaberPort::Tcp(s.to_string()))
    }
}

/// The baud rate of Zaber's ASCII protocol (*Quick Start § Connecting*).
pub const BAUD: u32 = 115_200;

/// How often reads time out to look at the deadline and the stop flag, and how often a move is
/// polled.
const POLL: Duration = Duration::from_millis(20);

/// The longest line a device may send, bytes.
const MAX_LINE: usize = 256;

trait Stream: Read + Write + Send {}
impl<T: Read + Write + Send> Stream for T {}

/// A connected Zaber head.
pub struct ZaberHead {
    spec: String,
    stream: Box<dyn Stream>,
    pending: Vec<u8>,
    axes: ZaberAxes,
    timeout: Duration,
    stop: Arc<AtomicBool>,
    identity: String,
}

/// One command to one axis (axis 0: its device).
struct Cmd<'a> {
    to: Address,
    text: &'a str,
}

impl ZaberHead {
    /// Connects to the chain at `port`, checks `axes`, and asks each device for its identity
    /// (`get device.id`, *Command Reference § get*). Every exchange must be answered within
    /// `timeout`, a move included.
    pub fn connect(
        port: &ZaberPort,
        axes: ZaberAxes,
        timeout: Duration,
        stop: Arc<AtomicBool>,
    ) -> Result<ZaberHead, HeadError> {
        let spec = format!("zaber:{port}");
        axes.check().map_err(|message| HeadError::Protocol { addr: spec.clone(), message })?;
        let io = |cause| HeadError::Io { addr: spec.clone(), cause };
        let stream: Box<dyn Stream> = match port {
            ZaberPort::Tcp(addr) => {
                let s = TcpStream::connect(addr).map_err(io)?;
                s.set_nodelay(true).map_err(io)?;
                s.set_read_timeout(Some(POLL)).map_err(io)?;
                Box::new(s)
            }
            ZaberPort::Serial(path) => {
                let p = crate::node::port::open(path, BAUD, POLL, crate::node::port::LOCK_WAIT)
                    .map_err(|e| io(e.into()))?;
                Box::new(p)
            }
        };
        let mut head =
            ZaberHead { spec, stream, pending: Vec::new(), axes, timeout, stop, identity: String::new() };
        let mut ids = Vec::new();
        for a in [axes.alpha, axes.beta] {
            let dev = Address { device: a.device, axis: 0 };
            let r = head.exchange(&[Cmd { to: dev, text: "get device.id" }])?.remove(0);
            ids.push(format!("{} {a} device.id {}", if a == axes.alpha { "alpha" } else { "beta" }, r.data));
        }
        head.identity = format!("{}; {} deg/step", ids.join(", "), axes.deg_per_step);
        Ok(head)
    }

    fn name(&self, a: Address) -> String {
        if a.axis == 0 {
            format!("device {}", a.device)
        } else {
            self.axes.name(a)
        }
    }

    /// Reads one line (without its end) by `deadline`, or None at the deadline.
    fn read_line(&mut self, deadline: Instant) -> Result<Option<Vec<u8>>, HeadError> {
        let mut buf = [0u8; 256];
        loop {
            if let Some(i) = self.pending.iter().position(|&b| b == b'\n') {
                let line: Vec<u8> = self.pending.drain(..=i).collect();
                return Ok(Some(line));
            }
            if self.pending.len() > MAX_LINE {
                return Err(HeadError::Protocol {
                    addr: self.spec.clone(),
                    message: format!("a line longer than {MAX_LINE} bytes without a line end"),
                });
            }
            if Instant::now() >= deadline {
                return Ok(None);
            }
            match self.stream.read(&mut buf) {
                Ok(0) => {
                    return Err(HeadError::Protocol {
                        addr: self.spec.clone(),
                        message: "connection closed".into(),
                    })
                }
                Ok(n) => self.pending.extend_from_slice(&buf[..n]),
                Err(e) if crate::node::read_again(&e) => {}
                Err(cause) => return Err(HeadError::Io { addr: self.spec.clone(), cause }),
            }
        }
    }

    /// Sends `cmds` at once and returns their replies in the same order, each checked: from the
    /// device and axis addressed, `OK`. Info messages and alerts are skipped.
    fn exchange(&mut self, cmds: &[Cmd<'_>]) -> Result<Vec<Reply>, HeadError> {
        let lines: String = cmds.iter().map(|c| codec::command(c.to.device, c.to.axis, c.text)).collect();
        let request = || lines.trim_end().replace('\n', "; ");
        self.stream
            .write_all(lines.as_bytes())
            .and_then(|_| self.stream.flush())
            .map_err(|cause| HeadError::Io { addr: self.spec.clone(), cause })?;
        let deadline = Instant::now() + self.timeout;
        let mut got: Vec<Option<Reply>> = vec![None; cmds.len()];
        let mut refused = None;
        while got.iter().any(Option::is_none) {
            let Some(line) = self.read_line(deadline)? else {
                return Err(HeadError::Timeout {
                    addr: self.spec.clone(),
                    request: request(),
                    secs: self.timeout.as_secs_f64(),
                });
            };
            if line.trim_ascii().is_empty() {
                continue;
            }
            let msg = parse_message(&line)
                .map_err(|m| HeadError::Protocol { addr: self.spec.clone(), message: m })?;
            let Message::Reply(r) = msg else { continue };
            let at = Address { device: r.device, axis: r.axis };
            let Some(i) = cmds.iter().enumerate().position(|(i, c)| c.to == at && got[i].is_none()) else {
                return Err(HeadError::Protocol {
                    addr: self.spec.clone(),
                    message: format!(
                        "a reply from device {} axis {} (`{}`), which was not asked (sent `{}`)",
                        r.device,
                        r.axis,
                        escape_peer(line.trim_ascii()),
                        request()
                    ),
                });
            };
            if r.flag == Flag::Rejected && refused.is_none() {
                let flag =
                    r.warning.map(|w| format!(", flag {}", codec::warning_words(w))).unwrap_or_default();
                refused = Some(HeadError::Rejected {
                    addr: self.spec.clone(),
                    axis: self.name(at),
                    command: cmds[i].text.to_string(),
                    said: format!("{}{flag}", escape_peer(line.trim_ascii())),
                });
            }
            got[i] = Some(r);
        }
        // Every reply is read before a refusal is reported: none is left to answer a later
        // command.
        if let Some(e) = refused {
            return Err(e);
        }
        Ok(got.into_iter().flatten().collect())
    }

    /// The fault a reply's warning flag shows, if any (`not_homed_too`: `WH`/`WR` are faults too).
    fn fault(&self, at: Address, r: &Reply, not_homed_too: bool) -> Result<(), HeadError> {
        let Some(w) = r.warning else { return Ok(()) };
        let fault = match codec::warning(w).0 {
            Severity::Fault => true,
            Severity::NotHomed => not_homed_too,
            Severity::Benign => false,
        };
        if fault {
            return Err(HeadError::Fault {
                addr: self.spec.clone(),
                axis: self.name(at),
                fault: format!("{} (`{}`)", codec::warning_words(w), r.line(false).trim_end()),
            });
        }
        Ok(())
    }

    fn both(&self) -> [Address; 2] {
        [self.axes.alpha, self.axes.beta]
    }

    /// Polls both axes until both are `IDLE` (Ok(true)), the stop flag is set (Ok(false), the
    /// axes not stopped yet), or the head's timeout passes.
    fn wait_idle(&mut self, what: &str, not_homed_too: bool) -> Result<bool, HeadError> {
        let deadline = Instant::now() + self.timeout;
        let [a, b] = self.both();
        loop {
            if self.stop.load(Ordering::Relaxed) {
                return Ok(false);
            }
            let r = self.exchange(&[Cmd { to: a, text: "" }, Cmd { to: b, text: "" }])?;
            self.fault(a, &r[0], not_homed_too)?;
            self.fault(b, &r[1], not_homed_too)?;
            if r.iter().all(|r| r.status == Status::Idle) {
                return Ok(true);
            }
            if Instant::now() >= deadline {
                return Err(HeadError::Timeout {
                    addr: self.spec.clone(),
                    request: format!("{what} (still BUSY)"),
                    secs: self.timeout.as_secs_f64(),
                });
            }
            std::thread::sleep(POLL);
        }
    }

    /// Sends `stop` to both axes (*Command Reference § stop*).
    pub fn stop_axes(&mut self) -> Result<(), HeadError> {
        let [a, b] = self.both();
        self.exchange(&[Cmd { to: a, text: "stop" }, Cmd { to: b, text: "stop" }])?;
        Ok(())
    }

    /// The positions both axes report, microsteps converted to degrees.
    pub fn angles(&mut self) -> Result<Angles, HeadError> {
        let [a, b] = self.both();
        let r = self.exchange(&[Cmd { to: a, text: "get pos" }, Cmd { to: b, text: "get pos" }])?;
        let mut deg = [0.0; 2];
        for (i, (at, r)) in [(a, &r[0]), (b, &r[1])].into_iter().enumerate() {
            let steps = r.data.parse::<i64>().map_err(|_| HeadError::Protocol {
                addr: self.spec.clone(),
                message: format!(
                    "{}: `get pos` answered `{}`, not a whole number of microsteps",
                    self.name(at),
                    escape_peer(r.data.as_bytes())
                ),
            })?;
            deg[i] = steps as f64 * self.axes.deg_per_step;
        }
        Ok(Angles { alpha_deg: deg[0], beta_deg: deg[1] })
    }

    /// `deg` in microsteps, refused beyond what a position setting holds (a signed 32-bit value).
    fn steps(&self, at: Address, deg: f64) -> Result<i64, HeadError> {
        let s = (deg / self.axes.deg_per_step).round();
        if !(s.is_finite() && s.abs() <= i32::MAX as f64) {
            return Err(HeadError::Protocol {
                addr: self.spec.clone(),
                message: format!("{}: {deg} deg is beyond the stage's position range", self.name(at)),
            });
        }
        Ok(s as i64)
    }

    /// Moves both axes to `angles` and waits until both are `IDLE` without a fault; returns the
    /// angles read back (also when a stop cut the move short, after stopping both axes).
    pub fn move_to(&mut self, angles: Angles) -> Result<Angles, HeadError> {
        let [a, b] = self.both();
        let sa = self.steps(a, angles.alpha_deg)?;
        let sb = self.steps(b, angles.beta_deg)?;
        let (ca, cb) = (format!("move abs {sa}"), format!("move abs {sb}"));
        let r = self.exchange(&[Cmd { to: a, text: &ca }, Cmd { to: b, text: &cb }])?;
        self.fault(a, &r[0], true)?;
        self.fault(b, &r[1], true)?;
        if !self.wait_idle(&format!("{ca} to {}, {cb} to {}", self.name(a), self.name(b)), true)? {
            self.stop_axes()?;
        }
        self.angles()
    }
}

impl Positioner for ZaberHead {
    fn describe(&self) -> String {
        format!("{} ({})", self.spec, self.identity)
    }

    fn home(&mut self) -> anyhow::Result<()> {
        let mut needs = Vec::new();
        for at in self.both() {
            // `warnings clear` answers the flags it clears: `NN F1 F2 …` (*Command Reference §
            // warnings*). Faults left over from an earlier run are cleared; one that persists
            // shows again in the first poll.
            let r = self.exchange(&[Cmd { to: at, text: "warnings clear" }])?.remove(0);
            let homed = !r.data.split_ascii_whitespace().skip(1).any(|f| f == "WH" || f == "WR")
                && !r.warning.is_some_and(|w| codec::warning(w).0 == Severity::NotHomed);
            if !homed {
                needs.push(at);
            }
        }
        if needs.is_empty() {
            return Ok(());
        }
        let cmds: Vec<Cmd<'_>> = needs.iter().map(|&to| Cmd { to, text: "home" }).collect();
        let r = self.exchange(&cmds)?;
        for (at, r) in needs.iter().zip(&r) {
            self.fault(*at, r, false)?;
        }
        if !self.wait_idle("home", false)? {
            self.stop_axes()?;
            return Ok(());
        }
        // Homed now: `WH` left over is a fault.
        self.wait_idle("home", true)?;
        Ok(())
    }

    fn set(&mut self, target: &Target) -> anyhow::Result<Angles> {
        Ok(self.move_to(target.angles)?)
    }

    fn read_back(&mut self) -> anyhow::Result<Angles> {
        Ok(self.angles()?)
    }

    fn stop(&mut self) -> anyhow::Result<()> {
        Ok(self.stop_axes()?)
    }
}

#[cfg(test)]
mod tests;
