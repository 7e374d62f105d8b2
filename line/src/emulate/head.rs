//! The emulated dividing head: its state and motion model ([`HeadState`], [`Motion`]), the state
//! shared with the front end ([`Head`]), and a TCP server of the head protocol of
//! [`crate::head::protocol`] ([`serve_head`]).
//!
//! Motion model: both axes start together and turn at `speed_deg_s` (the larger angle difference
//! sets the time), plus a fixed `overhead_s` for starting and stopping, so a move lasts
//! `overhead_s + max(|Δα|, |Δβ|)/speed_deg_s`. During it the angles go linearly in time from the
//! start to the target. A move to the angles the head stands at still takes `overhead_s` and counts
//! as a move.
//!
//! Invariants:
//! - The state is a pure function of its stored moves and a time `t` (seconds since the bench's
//!   [`Clock`] epoch): [`HeadState::pose`] never changes it, so the server and the front end, each
//!   in its thread, see the same head at the same instant.
//! - `moves_completed` counts moves whose end time has passed; it is the front end's position
//!   index.
//! - A move is refused (`ERR`) while another is under way, and angles must be finite (the
//!   protocol's parser refuses the rest); a refused request never changes the state.
//! - The server serves one connection at a time, in order of arrival; a connection's I/O error
//!   ends that connection only. It returns when the stop flag is set (checked at least every
//!   [`POLL`]).

use std::io::{Read, Write};
use std::net::{SocketAddr, TcpListener, TcpStream};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::{Duration, Instant};

use super::fault::{FaultCounter, FaultKind};
use crate::head::protocol::{Reply, Request};
use accelcal_core::error::{Classify, Kind};

/// How often blocking loops look at their stop flag.
pub const POLL: Duration = Duration::from_millis(20);

/// Longest request line the server accepts, bytes.
pub const MAX_LINE: usize = 256;

/// The bench's clock: seconds since an epoch, shared by the head and the front end.
#[derive(Clone, Copy, Debug)]
pub struct Clock {
    epoch: Instant,
}

impl Clock {
    /// A clock starting now.
    pub fn start() -> Clock {
        Clock { epoch: Instant::now() }
    }

    /// Seconds since the epoch.
    pub fn now_s(&self) -> f64 {
        self.epoch.elapsed().as_secs_f64()
    }

    /// The instant `t_s` seconds after the epoch.
    pub fn instant(&self, t_s: f64) -> Instant {
        self.epoch + Duration::from_secs_f64(t_s.max(0.0))
    }
}

/// The head's motion model.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Motion {
    /// Angular speed of both axes, degrees per second (> 0).
    pub speed_deg_s: f64,
    /// Time added to every move for starting and stopping, s (≥ 0).
    pub overhead_s: f64,
}

impl Default for Motion {
    /// 60 °/s and 0.1 s.
    fn default() -> Motion {
        Motion { speed_deg_s: 60.0, overhead_s: 0.1 }
    }
}

impl Motion {
    /// Duration of a move from `from` to `to` (degrees), s.
    pub fn duration_s(&self, from: (f64, f64), to: (f64, f64)) -> f64 {
        let d = (to.0 - from.0).abs().max((to.1 - from.1).abs());
        self.overhead_s + d / self.speed_deg_s
    }

    /// Checks the model's numbers.
    pub fn check(&self) -> Result<(), String> {
        if !(self.speed_deg_s.is_finite() && self.speed_deg_s > 0.0) {
            return Err(format!("head speed must be a finite number > 0 °/s, got {}", self.speed_deg_s));
        }
        if !(self.overhead_s.is_finite() && self.overhead_s >= 0.0) {
            return Err(format!(
                "head move overhead must be a finite number >= 0 s, got {}",
                self.overhead_s
            ));
        }
        Ok(())
    }
}

/// A move: from, to, start and end time.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Move {
    from: (f64, f64),
    to: (f64, f64),
    start_s: f64,
    end_s: f64,
}

/// The head's state: the last standing position, the one before, and the move under way.
#[derive(Clone, Debug, PartialEq)]
pub struct HeadState {
    motion: Motion,
    stand: (f64, f64),
    prev_stand: Option<(f64, f64)>,
    stopped_at_s: f64,
    moves: usize,
    current: Option<Move>,
}

/// The head at one instant, as the front end and the protocol see it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HeadPose {
    /// α now, degrees (interpolated while moving).
    pub alpha_deg: f64,
    /// β now, degrees.
    pub beta_deg: f64,
    /// Moves completed (the position index).
    pub moves_completed: usize,
    /// Angles of the standing position reached by the last completed move (the initial angles
    /// before any).
    pub stand: (f64, f64),
    /// Angles of the standing position before that one (None before the first move ends).
    pub prev_stand: Option<(f64, f64)>,
    /// When the head last stopped (0, the epoch, before any move), s.
    pub stopped_at_s: f64,
    /// The move under way: its target angles and the fraction done, in [0, 1).
    pub moving: Option<((f64, f64), f64)>,
}

impl HeadState {
    /// A head standing at `angles` (degrees) since the epoch, no move done.
    pub fn new(motion: Motion, angles: (f64, f64)) -> HeadState {
        HeadState { motion, stand: angles, prev_stand: None, stopped_at_s: 0.0, moves: 0, current: None }
    }

    /// The motion model.
    pub fn motion(&self) -> Motion {
        self.motion
    }

    /// The head at time `t_s`.
    pub fn pose(&self, t_s: f64) -> HeadPose {
        let standing = |stand: (f64, f64), prev_stand, stopped_at_s, moves_completed| HeadPose {
            alpha_deg: stand.0,
            beta_deg: stand.1,
            moves_completed,
            stand,
            prev_stand,
            stopped_at_s,
            moving: None,
        };
        match self.current {
            None => standing(self.stand, self.prev_stand, self.stopped_at_s, self.moves),
            Some(m) if t_s >= m.end_s => standing(m.to, Some(m.from), m.end_s, self.moves + 1),
            Some(m) => {
                let f = ((t_s - m.start_s) / (m.end_s - m.start_s)).clamp(0.0, 1.0);
                let f = if f.is_finite() { f } else { 0.0 };
                HeadPose {
                    alpha_deg: m.from.0 + f * (m.to.0 - m.from.0),
                    beta_deg: m.from.1 + f * (m.to.1 - m.from.1),
                    moves_completed: self.moves,
                    stand: self.stand,
                    prev_stand: self.prev_stand,
                    stopped_at_s: self.stopped_at_s,
                    moving: Some((m.to, f)),
                }
            }
        }
    }

    /// Starts a move to `to` (degrees) at `t_s`; returns when it ends, s. Refused while a move
    /// is under way or for non-finite angles (the state is then unchanged).
    pub fn start_move(&mut self, t_s: f64, to: (f64, f64)) -> Result<f64, String> {
        if !(to.0.is_finite() && to.1.is_finite()) {
            return Err(format!("angles must be finite, got {} {}", to.0, to.1));
        }
        let now = self.pose(t_s);
        if now.moving.is_some() {
            return Err("the head is moving".into());
        }
        let end_s = t_s + self.motion.duration_s(now.stand, to);
        *self = HeadState {
            motion: self.motion,
            stand: now.stand,
            prev_stand: now.prev_stand,
            stopped_at_s: now.stopped_at_s,
            moves: now.moves_completed,
            current: Some(Move { from: now.stand, to, start_s: t_s, end_s }),
        };
        Ok(end_s)
    }

    /// Sets axis `axis` (0: α, 1: β) heading for `to` (degrees) at `t_s`, the other axis keeping
    /// its target, as a stage takes a new `move` while it moves (Zaber's ASCII protocol): while a
    /// move is under way, it is turned towards the new angles from where it started, its start
    /// kept, and counts once; otherwise a move starts. Returns when it ends, s.
    pub fn move_axis(&mut self, t_s: f64, axis: usize, to: f64) -> Result<f64, String> {
        if !to.is_finite() {
            return Err(format!("angle must be finite, got {to}"));
        }
        let now = self.pose(t_s);
        let Some((mut target, _)) = now.moving else {
            let mut target = now.stand;
            if axis == 0 {
                target.0 = to
            } else {
                target.1 = to
            }
            return self.start_move(t_s, target);
        };
        if axis == 0 {
            target.0 = to
        } else {
            target.1 = to
        }
        let Some(m) = self.current.as_mut() else { return Err("no move under way".into()) };
        // Never ends before now: the head does not jump to a move's end.
        let end_s = (m.start_s + self.motion.duration_s(m.from, target)).max(t_s);
        *m = Move { to: target, end_s, ..*m };
        Ok(end_s)
    }

    /// Stops the move under way at `t_s` where the head is then: it stands there, and the move
    /// counts as done (the front end's next position). Standing, nothing changes.
    pub fn stop(&mut self, t_s: f64) {
        let now = self.pose(t_s);
        let Some(m) = self.current else { return };
        if now.moving.is_none() {
            return;
        }
        *self = HeadState {
            motion: self.motion,
            stand: (now.alpha_deg, now.beta_deg),
            prev_stand: Some(m.from),
            stopped_at_s: t_s,
            moves: self.moves + 1,
            current: None,
        };
    }
}

/// The sensor's temperature on the emulated bench: it follows the chamber's setpoint as a first
/// order lag with time constant `tau_s` (the thermal lag between chamber and sensor).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SensorTemp {
    /// Chamber setpoint, °C.
    pub chamber_c: f64,
    /// Sensor temperature at `at_s`, °C.
    pub sensor_c: f64,
    /// Time of `sensor_c` on the bench clock, s.
    pub at_s: f64,
    /// Thermal time constant, s.
    pub tau_s: f64,
}

impl SensorTemp {
    /// A sensor soaked at `temp_c` with time constant `tau_s`.
    pub fn soaked(temp_c: f64, tau_s: f64) -> SensorTemp {
        SensorTemp { chamber_c: temp_c, sensor_c: temp_c, at_s: 0.0, tau_s }
    }

    /// The sensor temperature at `t_s` (not before the last call's time).
    pub fn at(&mut self, t_s: f64) -> f64 {
        // The same lag as `simulate --thermal`'s.
        self.sensor_c =
            accelcal_core::sim::lag(self.sensor_c, self.chamber_c, (t_s - self.at_s).max(0.0), self.tau_s);
        self.at_s = self.at_s.max(t_s);
        self.sensor_c
    }

    /// Changes the chamber setpoint at `t_s`.
    pub fn set_chamber(&mut self, t_s: f64, chamber_c: f64) {
        self.at(t_s);
        self.chamber_c = chamber_c;
    }
}

/// The rig shared between the server and the front end (put it in an `Arc`): the head and the
/// thermal chamber around it.
#[derive(Debug)]
pub struct Head {
    clock: Clock,
    state: Mutex<HeadState>,
    chamber: Mutex<SensorTemp>,
}

impl Head {
    /// A head on `clock` standing at `angles`, the sensor soaked at 25 °C with no thermal lag.
    pub fn new(clock: Clock, motion: Motion, angles: (f64, f64)) -> Head {
        Head::with_chamber(clock, motion, angles, SensorTemp::soaked(25.0, 0.0))
    }

    /// A head in a thermal chamber whose sensor starts as `sensor` says.
    pub fn with_chamber(clock: Clock, motion: Motion, angles: (f64, f64), sensor: SensorTemp) -> Head {
        Head { clock, state: Mutex::new(HeadState::new(motion, angles)), chamber: Mutex::new(sensor) }
    }

    fn chamber(&self) -> MutexGuard<'_, SensorTemp> {
        self.chamber.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// The sensor's temperature at `t_s` on the bench clock, °C.
    pub fn sensor_temp_at(&self, t_s: f64) -> f64 {
        self.chamber().at(t_s)
    }

    /// Sets the chamber to `temp_c` now.
    pub fn set_chamber(&self, temp_c: f64) {
        let t = self.clock.now_s();
        self.chamber().set_chamber(t, temp_c);
    }

    /// The chamber's setpoint, °C.
    pub fn chamber_setpoint(&self) -> f64 {
        self.chamber().chamber_c
    }

    /// The bench clock.
    pub fn clock(&self) -> Clock {
        self.clock
    }

    fn state(&self) -> MutexGuard<'_, HeadState> {
        // The state is replaced whole under the lock, so a poisoned lock still holds a valid one.
        self.state.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// The head at `t_s` on the bench clock.
    pub fn pose_at(&self, t_s: f64) -> HeadPose {
        self.state().pose(t_s)
    }

    /// The head now.
    pub fn pose(&self) -> HeadPose {
        self.pose_at(self.clock.now_s())
    }

    /// Starts a move now; returns its end time on the bench clock, s.
    pub fn start_move(&self, to: (f64, f64)) -> Result<f64, String> {
        let t = self.clock.now_s();
        self.state().start_move(t, to)
    }

    /// Sets one axis heading for `to` now ([`HeadState::move_axis`]); returns the move's end
    /// time on the bench clock, s.
    pub fn move_axis(&self, axis: usize, to: f64) -> Result<f64, String> {
        let t = self.clock.now_s();
        self.state().move_axis(t, axis, to)
    }

    /// Stops the head now where it is ([`HeadState::stop`]).
    pub fn stop(&self) {
        self.stop_at(self.clock.now_s())
    }

    /// Stops the head where it was at `t_s` on the bench clock (not after now; a move that
    /// ended before `t_s` is not undone).
    pub fn stop_at(&self, t_s: f64) {
        self.state().stop(t_s)
    }
}

/// Why the head server stopped.
#[derive(Debug, thiserror::Error)]
pub enum HeadServerError {
    /// The listening socket failed.
    #[error("head server on {addr}: {cause}")]
    Listen {
        /// The address.
        addr: String,
        /// The cause.
        cause: std::io::Error,
    },
}

impl Classify for HeadServerError {
    fn kind(&self) -> Kind {
        Kind::Environment
    }
}

/// Binds the head's listener on 127.0.0.1 at `port` (0: a free port; its address is
/// `listener.local_addr()`).
pub fn bind_head(port: u16) -> Result<TcpListener, HeadServerError> {
    let addr = format!("127.0.0.1:{port}");
    TcpListener::bind(&addr).map_err(|cause| HeadServerError::Listen { addr, cause })
}

/// What the server did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct HeadServerStats {
    /// Connections served.
    pub connections: u64,
    /// Requests answered (refusals included).
    pub requests: u64,
    /// Moves completed for clients.
    pub moves: u64,
}

/// Serves the head protocol on `listener`, one connection at a time, until `stop` is set;
/// `faults` strikes one `MOVE` where it says (`reject`: `ERR`; `silent`: no reply, no motion;
/// `off=ARCSEC`: α lands that far off, and `OK` says so; the other kinds are not injected here).
pub fn serve_head(
    listener: TcpListener,
    head: &Head,
    faults: &FaultCounter,
    stop: &AtomicBool,
) -> Result<HeadServerStats, HeadServerError> {
    accept_one_at_a_time(listener, stop, |stream, stats| serve_connection(stream, head, faults, stop, stats))
}

/// Accepts connections on `listener` until `stop` is set and hands each to `serve`, one at a
/// time in order of arrival (checked at least every [`POLL`]); a connection's failure ends that
/// connection only. The emulated head's servers (this protocol's, and the Zaber dialect's) share
/// it.
pub fn accept_one_at_a_time(
    listener: TcpListener,
    stop: &AtomicBool,
    mut serve: impl FnMut(TcpStream, &mut HeadServerStats) -> std::io::Result<()>,
) -> Result<HeadServerStats, HeadServerError> {
    let addr = listener.local_addr().map(|a| a.to_string()).unwrap_or_default();
    let err = |cause| HeadServerError::Listen { addr: addr.clone(), cause };
    listener.set_nonblocking(true).map_err(err)?;
    let mut stats = HeadServerStats::default();
    while !stop.load(Ordering::Relaxed) {
        match listener.accept() {
            Ok((stream, _)) => {
                stats.connections += 1;
                let _ = serve(stream, &mut stats);
            }
            Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => std::thread::sleep(POLL / 4),
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) if e.kind() == std::io::ErrorKind::ConnectionAborted => {}
            Err(e) => return Err(err(e)),
        }
    }
    Ok(stats)
}

/// The reply to one request line; a `MOVE` blocks until the head has arrived, or until
/// `stop_requested` says a `STOP` came in meanwhile (the head then stops where it is and the
/// `MOVE` is answered with those angles; the `STOP` is answered next, as the protocol says).
/// None: no reply (`stop` was set, or the fault `silent` struck).
pub fn answer(
    line: &str,
    head: &Head,
    faults: &FaultCounter,
    stop: &AtomicBool,
    stop_requested: &mut dyn FnMut() -> bool,
) -> Option<Reply> {
    Some(match Request::parse(line) {
        Err(e) => Reply::Err(e),
        Ok(Request::Hello) => Reply::Hello {
            version: crate::head::protocol::VERSION,
            ident: format!("accelcal emulated head {}", env!("CARGO_PKG_VERSION")),
        },
        // The emulated head's axes need no homing: it answers where it stands.
        Ok(Request::Home | Request::Stop) => {
            let p = head.pose();
            Reply::Ok { alpha_deg: p.alpha_deg, beta_deg: p.beta_deg }
        }
        Ok(Request::Where) => {
            let p = head.pose();
            Reply::At { alpha_deg: p.alpha_deg, beta_deg: p.beta_deg, moving: p.moving.is_some() }
        }
        Ok(Request::Chamber { temp_c }) => {
            head.set_chamber(temp_c);
            Reply::Temp { setpoint_c: head.chamber_setpoint() }
        }
        Ok(Request::Temp) => Reply::Temp { setpoint_c: head.chamber_setpoint() },
        Ok(Request::Move { alpha_deg, beta_deg }) => match faults.next_move() {
            Some(FaultKind::Silent) => return None,
            Some(FaultKind::Reject) => Reply::Err("the head refuses the move (injected fault)".into()),
            fault => {
                let off = if let Some(FaultKind::Off(arcsec)) = fault { arcsec / 3600.0 } else { 0.0 };
                move_and_wait(head, (alpha_deg + off, beta_deg), stop, stop_requested)?
            }
        },
    })
}

/// Moves the head to `to` and waits until it stands there, or stops it when `stop_requested`
/// (None if `stop` is set meanwhile).
fn move_and_wait(
    head: &Head,
    to: (f64, f64),
    stop: &AtomicBool,
    stop_requested: &mut dyn FnMut() -> bool,
) -> Option<Reply> {
    Some(match head.start_move(to) {
        Err(e) => Reply::Err(e),
        Ok(end_s) => {
            let clock = head.clock();
            let end = clock.instant(end_s);
            loop {
                let now = Instant::now();
                if now >= end && head.pose().moving.is_none() {
                    break;
                }
                if stop.load(Ordering::Relaxed) {
                    return None;
                }
                if stop_requested() {
                    head.stop();
                    break;
                }
                std::thread::sleep(end.saturating_duration_since(now).clamp(Duration::from_millis(1), POLL));
            }
            let p = head.pose();
            Reply::Ok { alpha_deg: p.alpha_deg, beta_deg: p.beta_deg }
        }
    })
}

fn serve_connection(
    mut stream: TcpStream,
    head: &Head,
    faults: &FaultCounter,
    stop: &AtomicBool,
    stats: &mut HeadServerStats,
) -> std::io::Result<()> {
    stream.set_nonblocking(false)?;
    stream.set_read_timeout(Some(POLL))?;
    stream.set_nodelay(true)?;
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
        while let Some(i) = pending.iter().position(|&b| b == b'\n') {
            let line: Vec<u8> = pending.drain(..=i).collect();
            // During a move, what the client sends is read on: a `STOP` line among it stops the
            // head (it stays in `pending`, to be answered after the move).
            let mut stop_requested = || {
                let mut more = [0u8; 256];
                if let Ok(n @ 1..) = stream.read(&mut more) {
                    pending.extend_from_slice(&more[..n]);
                }
                pending.split(|&b| b == b'\n').rev().skip(1).any(|l| l.trim_ascii() == b"STOP")
            };
            let reply = match std::str::from_utf8(&line) {
                Ok(l) if l.trim().is_empty() => continue,
                Ok(l) => answer(l, head, faults, stop, &mut stop_requested),
                Err(_) => Some(Reply::Err("request is not UTF-8".into())),
            };
            let Some(reply) = reply else {
                if stop.load(Ordering::Relaxed) {
                    return Ok(());
                }
                stats.requests += 1;
                continue;
            };
            if matches!(reply, Reply::Ok { .. }) {
                stats.moves += 1;
            }
            stats.requests += 1;
            writeln!(stream, "{}", reply.line())?;
        }
        if pending.len() > MAX_LINE {
            stats.requests += 1;
            writeln!(stream, "{}", Reply::Err(format!("request longer than {MAX_LINE} bytes")).line())?;
            return Ok(());
        }
    }
    Ok(())
}

/// Starts the head server in a thread; returns its address and the thread (which returns when
/// `stop` is set).
pub fn spawn_head_server(
    listener: TcpListener,
    head: Arc<Head>,
    faults: Arc<FaultCounter>,
    stop: Arc<AtomicBool>,
) -> Result<(SocketAddr, std::thread::JoinHandle<Result<HeadServerStats, HeadServerError>>), HeadServerError>
{
    let addr =
        listener.local_addr().map_err(|cause| HeadServerError::Listen { addr: "127.0.0.1".into(), cause })?;
    let h = std::thread::spawn(move || serve_head(listener, &head, &faults, &stop));
    Ok((addr, h))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::head::LineHead;
    use std::io::{BufRead, BufReader};

    #[test]
    fn moves_take_the_stated_time_and_interpolate_the_angles() {
        let m = Motion::default();
        assert_eq!(m.duration_s((0.0, 0.0), (90.0, -30.0)), 0.1 + 1.5);
        assert_eq!(m.duration_s((10.0, 0.0), (10.0, 0.0)), 0.1);
        let mut h = HeadState::new(m, (0.0, 0.0));
        let p0 = h.pose(0.7);
        assert_eq!((p0.moves_completed, p0.stand, p0.prev_stand, p0.moving), (0, (0.0, 0.0), None, None));
        let end = h.start_move(1.0, (90.0, -30.0)).unwrap();
        assert_eq!(end, 2.6);
        let mid = h.pose(1.8);
        assert_eq!((mid.alpha_deg, mid.beta_deg, mid.moves_completed), (45.0, -15.0, 0));
        assert_eq!(mid.moving, Some(((90.0, -30.0), 0.5)));
        let before = h.clone();
        assert_eq!(h.start_move(2.0, (0.0, 0.0)), Err("the head is moving".into()));
        assert_eq!(h, before);
        let done = h.pose(2.6);
        assert_eq!((done.alpha_deg, done.beta_deg, done.moving), (90.0, -30.0, None));
        assert_eq!((done.moves_completed, done.prev_stand, done.stopped_at_s), (1, Some((0.0, 0.0)), 2.6));
        // The next move starts from where the last one ended and counts on.
        let end = h.start_move(3.0, (90.0, 30.0)).unwrap();
        assert!((end - 4.1).abs() < 1e-12);
        let p = h.pose(5.0);
        assert_eq!((p.moves_completed, p.stand, p.prev_stand), (2, (90.0, 30.0), Some((90.0, -30.0))));
        assert!(h.start_move(6.0, (f64::NAN, 0.0)).is_err());
        assert!(Motion { speed_deg_s: 0.0, overhead_s: 0.1 }.check().is_err());
        assert!(Motion { speed_deg_s: 10.0, overhead_s: -1.0 }.check().is_err());
        assert!(Motion::default().check().is_ok());
    }

    #[test]
    fn one_axis_moves_join_the_move_under_way_and_a_stop_stands_where_it_is() {
        let m = Motion { speed_deg_s: 10.0, overhead_s: 0.0 };
        let mut h = HeadState::new(m, (0.0, 0.0));
        assert_eq!(h.move_axis(1.0, 0, 20.0), Ok(3.0));
        // β joins the move α started: one move, its end set by the larger angle.
        assert_eq!(h.move_axis(1.0, 1, -40.0), Ok(5.0));
        let mid = h.pose(3.0);
        assert_eq!((mid.alpha_deg, mid.beta_deg, mid.moves_completed), (10.0, -20.0, 0));
        h.stop(3.0);
        let p = h.pose(10.0);
        assert_eq!((p.alpha_deg, p.beta_deg, p.moving), (10.0, -20.0, None));
        assert_eq!((p.moves_completed, p.prev_stand, p.stopped_at_s), (1, Some((0.0, 0.0)), 3.0));
        // Standing, a stop changes nothing; the next move starts from the stopped pose.
        let before = h.clone();
        h.stop(11.0);
        assert_eq!(h, before);
        assert_eq!(h.move_axis(12.0, 1, -20.0), Ok(12.0));
        assert_eq!(h.pose(12.0).moves_completed, 2);
        assert!(h.move_axis(13.0, 0, f64::INFINITY).is_err());
    }

    /// `--head-fault` on the line protocol: `reject` is an `ERR`, `silent` no reply (the client
    /// times out), `off=` lands α off and `OK` says so; each strikes the move it names only.
    #[test]
    fn the_line_protocol_s_head_injects_reject_silent_and_off() {
        use crate::emulate::fault::HeadFault;
        for (kind, want) in [
            (FaultKind::Reject, "refused: the head refuses the move (injected fault)"),
            (FaultKind::Silent, "no reply to `MOVE 20 0` within 0.3 s"),
            (FaultKind::Off(36.0), ""),
        ] {
            let head = Arc::new(Head::new(
                Clock::start(),
                Motion { speed_deg_s: 900.0, overhead_s: 0.01 },
                (0.0, 0.0),
            ));
            let stop = Arc::new(AtomicBool::new(false));
            let faults = Arc::new(FaultCounter::new(Some(HeadFault { kind, at_move: 2 })));
            let (addr, server) =
                spawn_head_server(bind_head(0).unwrap(), head, faults, stop.clone()).unwrap();
            let mut c = LineHead::connect(&addr.to_string(), Duration::from_millis(300)).unwrap();
            assert_eq!(c.move_to(10.0, 0.0).unwrap(), crate::head::Angles { alpha_deg: 10.0, beta_deg: 0.0 });
            match c.move_to(20.0, 0.0) {
                Ok(got) => {
                    assert_eq!(want, "");
                    assert!((got.alpha_deg - 20.01).abs() < 1e-9, "{got:?}");
                }
                Err(e) => assert!(e.to_string().contains(want), "{kind}: {e}"),
            }
            // The next move meets no fault (on a new connection: the server serves one at a time).
            drop(c);
            let mut c = LineHead::connect(&addr.to_string(), Duration::from_secs(5)).unwrap();
            assert_eq!(c.move_to(30.0, 0.0).unwrap(), crate::head::Angles { alpha_deg: 30.0, beta_deg: 0.0 });
            stop.store(true, Ordering::Relaxed);
            drop(c);
            server.join().unwrap().unwrap();
        }
    }

    fn raw(addr: &str, line: &str) -> String {
        let mut s = TcpStream::connect(addr).unwrap();
        s.set_read_timeout(Some(Duration::from_secs(5))).unwrap();
        s.write_all(line.as_bytes()).unwrap();
        let mut reply = String::new();
        BufReader::new(s).read_line(&mut reply).unwrap();
        reply
    }

    #[test]
    fn the_server_answers_the_head_protocol_over_tcp() {
        let head =
            Arc::new(Head::new(Clock::start(), Motion { speed_deg_s: 900.0, overhead_s: 0.05 }, (0.0, 0.0)));
        let stop = Arc::new(AtomicBool::new(false));
        let faults = Arc::new(FaultCounter::new(None));
        let (addr, server) =
            spawn_head_server(bind_head(0).unwrap(), head.clone(), faults, stop.clone()).unwrap();
        let addr = addr.to_string();
        let mut client = LineHead::connect(&addr, Duration::from_secs(5)).unwrap();
        let t0 = Instant::now();
        client.move_to(90.0, -45.0).unwrap();
        let took = t0.elapsed().as_secs_f64();
        assert!((0.15..1.0).contains(&took), "{took}");
        assert_eq!(
            client.request(Request::Where).unwrap(),
            Reply::At { alpha_deg: 90.0, beta_deg: -45.0, moving: false }
        );
        // A move under way (started by someone else): WHERE sees it, MOVE is refused.
        // (0.75 s, so that the two requests below fall within it even on a loaded machine.)
        head.start_move((720.0, 45.0)).unwrap();
        match client.request(Request::Where).unwrap() {
            Reply::At { alpha_deg, moving: true, .. } => assert!((90.0..=720.0).contains(&alpha_deg)),
            r => panic!("{r:?}"),
        }
        let e = client.move_to(1.0, 2.0).unwrap_err().to_string();
        assert!(e.contains("refused: the head is moving"), "{e}");
        drop(client);
        // Connections are served one after the other; bad requests get ERR.
        assert!(raw(&addr, "JUMP\n").starts_with("ERR unknown request `JUMP`"));
        assert!(raw(&addr, "MOVE 1 nan\n").starts_with("ERR MOVE: expected beta"));
        assert!(raw(&addr, &"X".repeat(MAX_LINE + 10)).starts_with("ERR request longer than"));
        let t = Instant::now();
        while head.pose().moving.is_some() && t.elapsed() < Duration::from_secs(5) {
            std::thread::sleep(Duration::from_millis(10));
        }
        assert_eq!(head.pose().moves_completed, 2);
        stop.store(true, Ordering::Relaxed);
        let stats = server.join().unwrap().unwrap();
        assert_eq!(stats.connections, 4);
        assert_eq!(stats.moves, 1);
        // HELLO, MOVE, WHERE, WHERE, MOVE refused, then the three bad requests.
        assert_eq!(stats.requests, 8);
    }

    /// Ctrl-C during a move (issue 56): the client sends `STOP` while its `MOVE` waits; the head
    /// stops where it is, answers the `MOVE` and the `STOP` with those angles, and stands still
    /// there (`WHERE` says `STILL`).
    #[test]
    fn a_stop_during_a_move_stops_the_head_where_it_is() {
        let head =
            Arc::new(Head::new(Clock::start(), Motion { speed_deg_s: 90.0, overhead_s: 0.0 }, (0.0, 0.0)));
        let stop = Arc::new(AtomicBool::new(false));
        let faults = Arc::new(FaultCounter::new(None));
        let (addr, server) =
            spawn_head_server(bind_head(0).unwrap(), head.clone(), faults, stop.clone()).unwrap();
        let ctrl_c = Arc::new(AtomicBool::new(false));
        let mut client =
            LineHead::connect(&addr.to_string(), Duration::from_secs(5)).unwrap().stop_on(ctrl_c.clone());
        let flag = ctrl_c.clone();
        let press = std::thread::spawn(move || {
            std::thread::sleep(Duration::from_millis(300));
            flag.store(true, Ordering::Relaxed);
        });
        let t0 = Instant::now();
        let at = client.move_to(90.0, 0.0).unwrap();
        assert!(t0.elapsed() < Duration::from_millis(800), "{:?}", t0.elapsed());
        assert!((5.0..60.0).contains(&at.alpha_deg), "{at:?}");
        std::thread::sleep(Duration::from_millis(100));
        let p = head.pose();
        assert!(p.moving.is_none() && (p.alpha_deg - at.alpha_deg).abs() < 1e-9, "{p:?} {at:?}");
        assert_eq!(
            client.request(Request::Where).unwrap(),
            Reply::At { alpha_deg: at.alpha_deg, beta_deg: 0.0, moving: false }
        );
        press.join().unwrap();
        drop(client);
        stop.store(true, Ordering::Relaxed);
        server.join().unwrap().unwrap();
    }
}
