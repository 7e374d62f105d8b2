//! The emulated node's serial port: a pseudo-terminal this process owns, bridged to the unix
//! socket of QEMU's USART1 chardev.
//!
//! QEMU's own `-chardev pty` notices a program opening the terminal only on a timer, once a
//! second (`char-pty.c`: `pty_chr_rearm_timer(chr, 1000)` while no one has it open), and until
//! then neither reads the host's bytes nor sends the node's. Every step of a station opens the
//! port anew, so each request waited 0 to 1 s for nothing (its request sent once and answered
//! up to a second later; the figures are on the guide's measurements page). The bridge polls the terminal
//! every [`IDLE_POLL`] instead; it keeps the behaviour of QEMU's pty otherwise: what the node
//! sends while no program has the terminal open is dropped, and a program that opens it but does
//! not read holds the node's output back (the node's transmitter waits, as on QEMU's pty).

use std::fs::File;
use std::io::{self, Read, Write};
use std::os::fd::{AsRawFd, FromRawFd, OwnedFd, RawFd};
use std::os::unix::net::UnixStream;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::Duration;

/// How often a terminal that no program holds open is looked at again, and the longest a
/// thread waits before it checks the stop flag.
const IDLE_POLL: Duration = Duration::from_millis(5);

/// A pseudo-terminal in raw mode: its controlling side (kept here) and the path of the terminal
/// programs open.
pub struct Pty {
    master: OwnedFd,
    /// `/dev/pts/N`.
    pub path: PathBuf,
}

fn last_os_error(what: &str) -> io::Error {
    let e = io::Error::last_os_error();
    io::Error::new(e.kind(), format!("{what}: {e}"))
}

impl Pty {
    /// Opens a new pseudo-terminal, sets its terminal side raw (no echo, no line editing: bytes
    /// pass as they are) and closes that side, as QEMU's pty chardev does.
    pub fn open() -> io::Result<Pty> {
        let (mut master, mut slave): (libc::c_int, libc::c_int) = (-1, -1);
        // SAFETY: openpty writes two descriptors into the given ints; the name, termios and
        // window size arguments may be null.
        let r = unsafe {
            libc::openpty(&mut master, &mut slave, std::ptr::null_mut(), std::ptr::null(), std::ptr::null())
        };
        if r != 0 {
            return Err(last_os_error("openpty"));
        }
        // SAFETY: both descriptors were just opened by openpty and are owned here alone.
        let (master, slave) = unsafe { (OwnedFd::from_raw_fd(master), OwnedFd::from_raw_fd(slave)) };
        // SAFETY: a zeroed termios is a valid buffer for tcgetattr to fill.
        let mut t: libc::termios = unsafe { std::mem::zeroed() };
        // SAFETY: `slave` is an open terminal descriptor and `t` a valid termios.
        if unsafe { libc::tcgetattr(slave.as_raw_fd(), &mut t) } != 0 {
            return Err(last_os_error("tcgetattr"));
        }
        // SAFETY: cfmakeraw only edits the struct it is given.
        unsafe { libc::cfmakeraw(&mut t) };
        // SAFETY: as for tcgetattr.
        if unsafe { libc::tcsetattr(slave.as_raw_fd(), libc::TCSANOW, &t) } != 0 {
            return Err(last_os_error("tcsetattr"));
        }
        let mut name = [0 as libc::c_char; 128];
        // SAFETY: ptsname_r writes a NUL-terminated name of at most `name.len()` bytes.
        if unsafe { libc::ptsname_r(master.as_raw_fd(), name.as_mut_ptr(), name.len()) } != 0 {
            return Err(last_os_error("ptsname_r"));
        }
        // SAFETY: ptsname_r succeeded, so `name` holds a NUL-terminated string.
        let path = unsafe { std::ffi::CStr::from_ptr(name.as_ptr()) };
        let path = PathBuf::from(path.to_string_lossy().into_owned());
        set_nonblocking(master.as_raw_fd())?;
        drop(slave);
        Ok(Pty { master, path })
    }

    /// Carries bytes between the terminal and `node` (QEMU's USART1 socket) in two threads until
    /// `stop` is set or either end fails; returns the threads.
    pub fn bridge(self, node: UnixStream, stop: &Arc<AtomicBool>) -> io::Result<[JoinHandle<()>; 2]> {
        let to_node = node.try_clone()?;
        let mut from_node = node;
        from_node.set_read_timeout(Some(IDLE_POLL * 20))?;
        let master = Arc::new(File::from(self.master));
        let (m, s) = (master.clone(), stop.clone());
        let down = std::thread::spawn(move || {
            let _ = node_to_terminal(&mut from_node, &m, &s);
        });
        let s = stop.clone();
        let up = std::thread::spawn(move || {
            let _ = terminal_to_node(&master, to_node, &s);
        });
        Ok([down, up])
    }
}

fn set_nonblocking(fd: RawFd) -> io::Result<()> {
    // SAFETY: F_GETFL/F_SETFL on a descriptor this module owns.
    let flags = unsafe { libc::fcntl(fd, libc::F_GETFL) };
    if flags < 0 || unsafe { libc::fcntl(fd, libc::F_SETFL, flags | libc::O_NONBLOCK) } < 0 {
        return Err(last_os_error("fcntl O_NONBLOCK"));
    }
    Ok(())
}

/// Waits up to `timeout` for `events` on `fd`; returns the events that occurred (0: none).
fn poll(fd: RawFd, events: libc::c_short, timeout: Duration) -> io::Result<libc::c_short> {
    let mut p = libc::pollfd { fd, events, revents: 0 };
    // SAFETY: one valid pollfd.
    let r = unsafe { libc::poll(&mut p, 1, timeout.as_millis() as libc::c_int) };
    if r < 0 {
        let e = io::Error::last_os_error();
        return if e.kind() == io::ErrorKind::Interrupted { Ok(0) } else { Err(e) };
    }
    Ok(p.revents)
}

/// Whether a program holds the terminal open (the controlling side reports a hang-up when none
/// does).
fn held_open(master: &File) -> io::Result<bool> {
    Ok(poll(master.as_raw_fd(), libc::POLLOUT, Duration::ZERO)? & libc::POLLHUP == 0)
}

/// The node's bytes to the terminal, or dropped while no program has it open.
fn node_to_terminal(node: &mut UnixStream, master: &File, stop: &AtomicBool) -> io::Result<()> {
    let mut buf = [0u8; 4096];
    while !stop.load(Ordering::Relaxed) {
        let n = match node.read(&mut buf) {
            Ok(0) => return Ok(()),
            Ok(n) => n,
            Err(e) if matches!(e.kind(), io::ErrorKind::WouldBlock | io::ErrorKind::TimedOut) => continue,
            Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
            Err(e) => return Err(e),
        };
        let mut rest = &buf[..n];
        while !rest.is_empty() && !stop.load(Ordering::Relaxed) {
            if !held_open(master)? {
                break;
            }
            match (&*master).write(rest) {
                Ok(k) => rest = &rest[k..],
                // The program does not read: the node waits (its socket fills, its
                // transmitter holds), as on QEMU's pty.
                Err(e) if e.kind() == io::ErrorKind::WouldBlock => {
                    poll(master.as_raw_fd(), libc::POLLOUT, IDLE_POLL)?;
                }
                Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                // Closed between the check and the write.
                Err(e) if e.raw_os_error() == Some(libc::EIO) => break,
                Err(e) => return Err(e),
            }
        }
    }
    Ok(())
}

/// The program's bytes to the node.
fn terminal_to_node(master: &File, mut node: UnixStream, stop: &AtomicBool) -> io::Result<()> {
    let mut buf = [0u8; 4096];
    while !stop.load(Ordering::Relaxed) {
        let ev = poll(master.as_raw_fd(), libc::POLLIN, IDLE_POLL * 20)?;
        if ev & libc::POLLHUP != 0 && ev & libc::POLLIN == 0 {
            // No program has the terminal open: look again shortly.
            std::thread::sleep(IDLE_POLL);
            continue;
        }
        if ev & libc::POLLIN == 0 {
            continue;
        }
        match (&*master).read(&mut buf) {
            Ok(0) => {}
            Ok(n) => node.write_all(&buf[..n])?,
            Err(e) if matches!(e.kind(), io::ErrorKind::WouldBlock | io::ErrorKind::Interrupted) => {}
            Err(e) if e.raw_os_error() == Some(libc::EIO) => std::thread::sleep(IDLE_POLL),
            Err(e) => return Err(e),
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Bytes pass both ways unchanged (raw mode: no echo, no CR/LF translation), and what the
    /// node sends while the terminal is closed is dropped, as QEMU's pty does.
    #[test]
    fn the_bridge_carries_bytes_both_ways_and_drops_them_while_closed() {
        let pty = Pty::open().unwrap();
        let path = pty.path.clone();
        let (node, mut qemu) = UnixStream::pair().unwrap();
        let stop = Arc::new(AtomicBool::new(false));
        let threads = pty.bridge(node, &stop).unwrap();
        // Closed: dropped.
        qemu.write_all(b"lost\n").unwrap();
        std::thread::sleep(Duration::from_millis(100));
        let mut term = std::fs::OpenOptions::new().read(true).write(true).open(&path).unwrap();
        std::thread::sleep(Duration::from_millis(50));
        let sent: Vec<u8> = (0..=255u8).collect();
        qemu.write_all(&sent).unwrap();
        let mut got = vec![0u8; sent.len()];
        term.read_exact(&mut got).unwrap();
        assert_eq!(got, sent, "node to program");
        term.write_all(&[0, 2, 3, 0, b'\r', b'\n', 3]).unwrap();
        let mut back = [0u8; 7];
        qemu.set_read_timeout(Some(Duration::from_secs(5))).unwrap();
        qemu.read_exact(&mut back).unwrap();
        assert_eq!(back, [0, 2, 3, 0, b'\r', b'\n', 3], "program to node");
        stop.store(true, Ordering::Relaxed);
        drop(term);
        for t in threads {
            t.join().unwrap();
        }
    }
}
