//! The emulated head as a Zaber chain (`accelcal emulate --head zaber`): Zaber's ASCII protocol
//! (`crate::head::zaber::codec`; sections of Zaber's *ASCII Protocol Manual* cited there) served
//! over TCP, or over a pseudo-terminal (`--head zaber-pty`) as a serial chain is, for the one
//! [`Head`] the front ends read.
//!
//! The stage ([`ZaberStage`]): two rotary axes, α and β, at the addresses of [`ZaberAxes`]
//! (device 1 axis 1 and device 2 axis 1 by default), positions in microsteps of
//! `deg_per_step`. What it answers:
//!
//! | command (to an axis) | reply data, and what happens |
//! |---|---|
//! | (none: a poll) | `0`; `BUSY` while the head moves |
//! | `home` | `0`; the axis is homed (`WH` goes) and heads for 0 |
//! | `move abs N` | `0`; the axis heads for N microsteps (joining a move under way: [`Head::move_axis`]) |
//! | `stop` | `0`; the head stops where it is, and stands there ([`Head::stop`]) |
//! | `get pos` | the position, microsteps |
//! | `get device.id` (also to axis 0) | `0` (an emulated stage) |
//! | `warnings`, `warnings clear` | `NN F1 F2 …`, the axis's flags (then cleared, `WH` kept until homed) |
//!
//! Anything else is answered `RJ … BADCOMMAND`; an axis that is not α or β `RJ … BADAXIS`; a
//! device that is neither α's nor β's, or a line that is not a command, is not answered (no such
//! device on the chain). Every reply's warning field is the axis's fault flag, else `WH` while
//! it is not homed (both start so), else `--`. A command with a checksum is answered with one
//! (*Message Format § Checksums*).
//!
//! Both axes move as the head does: together, at its speed (one [`Head`] move per position).
//!
//! Faults ([`HeadFault`]) strike the N-th `move` to α since start: `reject` answers it `RJ IDLE
//! -- BADDATA`; `not-homed` makes α lose its reference and answers `RJ IDLE WH BADDATA`;
//! `silent` answers nothing and does not move; `stall` and `limit` stop the head half-way with
//! `FS` or `WL` on α (kept until `warnings clear`); `off=ARCSEC` lands α that far from the
//! target, and `get pos` says so.

use std::io::{Read, Write};
use std::net::TcpListener;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};

use super::fault::{FaultCounter, FaultKind, HeadFault};
use super::head::{Head, HeadServerError, HeadServerStats, MAX_LINE, POLL};
use crate::head::zaber::codec::{parse_command, Address, Flag, Reply, Status};
use crate::head::zaber::ZaberAxes;

#[derive(Debug, Default)]
struct Axes {
    homed: [bool; 2],
    flag: [Option<[u8; 2]>; 2],
    /// A stall or limit to come: when (bench clock, s), which axis, its flag.
    stall: Option<(f64, usize, [u8; 2])>,
}

/// The emulated Zaber chain over a [`Head`].
pub struct ZaberStage {
    head: Arc<Head>,
    axes: ZaberAxes,
    faults: FaultCounter,
    state: Mutex<Axes>,
}

impl ZaberStage {
    /// Both axes not homed, `fault` to strike once.
    pub fn new(head: Arc<Head>, axes: ZaberAxes, fault: Option<HeadFault>) -> ZaberStage {
        ZaberStage { head, axes, faults: FaultCounter::new(fault), state: Mutex::new(Axes::default()) }
    }

    fn state(&self) -> MutexGuard<'_, Axes> {
        self.state.lock().unwrap_or_else(|e| e.into_inner())
    }

    fn index(&self, a: Address) -> Option<usize> {
        [self.axes.alpha, self.axes.beta].iter().position(|&x| x == a)
    }

    /// The reply to one command line, with its line end; None when none is due.
    pub fn answer(&self, line: &[u8]) -> Option<String> {
        let cmd = parse_command(line).ok()?;
        let checksum = line.contains(&b':');
        let ours = [self.axes.alpha.device, self.axes.beta.device];
        if !ours.contains(&cmd.device) {
            return None;
        }
        let words: Vec<&str> = cmd.text.split_ascii_whitespace().collect();
        let reply = |axis: u8, flag: Flag, warning: Option<[u8; 2]>, data: String| {
            let status = if self.head.pose().moving.is_some() { Status::Busy } else { Status::Idle };
            Some(Reply { device: cmd.device, axis, id: cmd.id, flag, status, warning, data }.line(checksum))
        };
        self.apply_stall();
        let at = Address { device: cmd.device, axis: cmd.axis };
        let Some(i) = self.index(at) else {
            return match (cmd.axis, words.as_slice()) {
                (0, ["get", "device.id"]) => reply(0, Flag::Ok, None, "0".into()),
                (0, _) => reply(0, Flag::Rejected, None, "BADCOMMAND".into()),
                _ => reply(cmd.axis, Flag::Rejected, None, "BADAXIS".into()),
            };
        };
        let warning = |s: &Axes| s.flag[i].or((!s.homed[i]).then_some(*b"WH"));
        let ok = |data: String| {
            let w = warning(&self.state());
            reply(cmd.axis, Flag::Ok, w, data)
        };
        let steps = |deg: f64| ((deg / self.axes.deg_per_step).round() as i64).to_string();
        match words.as_slice() {
            [] => ok("0".into()),
            ["home"] => {
                self.state().homed[i] = true;
                let p = self.head.pose();
                let at = if i == 0 { p.stand.0 } else { p.stand.1 };
                if p.moving.is_some() || at != 0.0 {
                    let _ = self.head.move_axis(i, 0.0);
                }
                ok("0".into())
            }
            ["move", "abs", n] => {
                let Ok(n) = n.parse::<i64>() else {
                    return reply(cmd.axis, Flag::Rejected, warning(&self.state()), "BADDATA".into());
                };
                let fault = if i == 0 { self.faults.next_move() } else { None };
                let mut deg = n as f64 * self.axes.deg_per_step;
                match fault {
                    Some(FaultKind::Silent) => return None,
                    Some(FaultKind::Reject) => {
                        return reply(cmd.axis, Flag::Rejected, warning(&self.state()), "BADDATA".into())
                    }
                    Some(FaultKind::NotHomed) => self.state().homed[i] = false,
                    Some(FaultKind::Off(arcsec)) => deg += arcsec / 3600.0,
                    _ => {}
                }
                if !self.state().homed[i] {
                    return reply(cmd.axis, Flag::Rejected, warning(&self.state()), "BADDATA".into());
                }
                let t0 = self.head.clock().now_s();
                let end = match self.head.move_axis(i, deg) {
                    Ok(end) => end,
                    Err(_) => {
                        return reply(cmd.axis, Flag::Rejected, warning(&self.state()), "BADDATA".into())
                    }
                };
                if let Some(FaultKind::Stall | FaultKind::Limit) = fault {
                    let flag = if fault == Some(FaultKind::Stall) { *b"FS" } else { *b"WL" };
                    self.state().stall = Some((t0 + 0.5 * (end - t0), i, flag));
                }
                ok("0".into())
            }
            ["stop"] => {
                self.head.stop();
                self.state().stall = None;
                ok("0".into())
            }
            ["get", "pos"] => {
                let p = self.head.pose();
                ok(steps(if i == 0 { p.alpha_deg } else { p.beta_deg }))
            }
            ["get", "device.id"] => ok("0".into()),
            ["warnings"] | ["warnings", "clear"] => {
                let mut s = self.state();
                let flags: Vec<String> = [s.flag[i], (!s.homed[i]).then_some(*b"WH")]
                    .into_iter()
                    .flatten()
                    .map(|f| String::from_utf8_lossy(&f).into_owned())
                    .collect();
                let w = warning(&s);
                if words.len() == 2 {
                    s.flag[i] = None;
                }
                drop(s);
                let data =
                    std::iter::once(format!("{:02}", flags.len())).chain(flags).collect::<Vec<_>>().join(" ");
                reply(cmd.axis, Flag::Ok, w, data)
            }
            _ => reply(cmd.axis, Flag::Rejected, warning(&self.state()), "BADCOMMAND".into()),
        }
    }

    /// A stall or limit due by now stops the head where it was then and raises its flag.
    fn apply_stall(&self) {
        let mut s = self.state();
        let Some((t, i, flag)) = s.stall else { return };
        if self.head.clock().now_s() < t {
            return;
        }
        self.head.stop_at(t);
        s.flag[i] = Some(flag);
        s.stall = None;
    }
}

/// Serves the stage on one byte stream (a TCP connection, or the pseudo-terminal's bridge) until
/// it ends or `stop` is set; reads must time out (every [`POLL`] or so).
pub fn serve_stream<S: Read + Write>(
    mut stream: S,
    stage: &ZaberStage,
    stop: &AtomicBool,
    stats: &mut HeadServerStats,
) -> std::io::Result<()> {
    let mut pending: Vec<u8> = Vec::new();
    let mut buf = [0u8; 256];
    while !stop.load(Ordering::Relaxed) {
        let n = match stream.read(&mut buf) {
            Ok(0) => return Ok(()),
            Ok(n) => n,
            Err(e) if crate::node::read_again(&e) => continue,
            Err(e) => return Err(e),
        };
        pending.extend_from_slice(&buf[..n]);
        // *Message Format § Commands*: a command ends at a line feed or a carriage return.
        while let Some(i) = pending.iter().position(|&b| b == b'\n' || b == b'\r') {
            let line: Vec<u8> = pending.drain(..=i).collect();
            if line.trim_ascii().is_empty() {
                continue;
            }
            stats.requests += 1;
            if let Some(r) = stage.answer(&line) {
                if line.windows(9).any(|w| w == b"move abs ") && r.contains(" OK ") {
                    stats.moves += 1;
                }
                stream.write_all(r.as_bytes())?;
            }
        }
        if pending.len() > MAX_LINE {
            // No device takes such a line: dropped unanswered.
            pending.clear();
        }
    }
    Ok(())
}

/// Serves the stage on `listener` (127.0.0.1), one connection at a time, until `stop` is set.
pub fn serve_zaber(
    listener: TcpListener,
    stage: &ZaberStage,
    stop: &AtomicBool,
) -> Result<HeadServerStats, HeadServerError> {
    super::head::accept_one_at_a_time(listener, stop, |stream, stats| {
        stream.set_nonblocking(false)?;
        stream.set_read_timeout(Some(POLL))?;
        stream.set_nodelay(true)?;
        serve_stream(stream, stage, stop, stats)
    })
}

/// Serves the stage on a pseudo-terminal of its own, as a serial chain is reached; returns the
/// terminal's path (`/dev/pts/N`) and the threads (which return when `stop` is set).
pub fn spawn_zaber_pty(
    stage: Arc<ZaberStage>,
    stop: &Arc<AtomicBool>,
) -> std::io::Result<(String, Vec<std::thread::JoinHandle<()>>)> {
    let pty = super::pty::Pty::open()?;
    let path = pty.path.display().to_string();
    let (ours, theirs) = std::os::unix::net::UnixStream::pair()?;
    ours.set_read_timeout(Some(POLL))?;
    let mut threads: Vec<_> = pty.bridge(theirs, stop)?.into();
    let s = stop.clone();
    threads.push(std::thread::spawn(move || {
        let _ = serve_stream(ours, &stage, &s, &mut HeadServerStats::default());
    }));
    Ok((path, threads))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::emulate::head::{Clock, Motion};

    fn stage(fault: Option<HeadFault>) -> ZaberStage {
        let head =
            Arc::new(Head::new(Clock::start(), Motion { speed_deg_s: 900.0, overhead_s: 0.01 }, (0.0, 0.0)));
        ZaberStage::new(head, ZaberAxes::default(), fault)
    }

    #[test]
    fn the_stage_answers_in_zaber_s_format() {
        let s = stage(None);
        let a = |l: &str| s.answer(l.as_bytes());
        assert_eq!(a("/1 1\n").unwrap(), "@01 1 OK IDLE WH 0\r\n");
        assert_eq!(a("/1 1 move abs 100\n").unwrap(), "@01 1 RJ IDLE WH BADDATA\r\n");
        assert_eq!(a("/2 1 warnings\n").unwrap(), "@02 1 OK IDLE WH 01 WH\r\n");
        assert_eq!(a("/1 0 get device.id\n").unwrap(), "@01 0 OK IDLE -- 0\r\n");
        assert_eq!(a("/1 1 home\n").unwrap(), "@01 1 OK IDLE -- 0\r\n");
        assert_eq!(a("/1 3 get pos\n").unwrap(), "@01 3 RJ IDLE -- BADAXIS\r\n");
        assert_eq!(a("/1 1 jump\n").unwrap(), "@01 1 RJ IDLE -- BADCOMMAND\r\n");
        assert_eq!(a("/1 1 7 get pos\n").unwrap(), "@01 1 7 OK IDLE -- 0\r\n");
        assert_eq!(a("/9 1 get pos\n"), None);
        assert_eq!(a("hello\n"), None);
        // A command with a checksum is answered with one.
        let body = "1 1 get pos";
        let c = format!("/{body}:{:02X}\n", crate::head::zaber::codec::checksum(body.as_bytes()));
        let r = a(&c).unwrap();
        assert!(r.starts_with("@01 1 OK IDLE -- 0:"), "{r}");
    }
}
