//! Opening the node's serial port, which serialport takes exclusively (`TIOCEXCL` and an
//! exclusive `flock(2)`). A process killed with the port open holds that lock until the kernel
//! has torn it down, which is not done when its parent has already been reaped: a station killed
//! mid-unit and run again at once could meet its own dying step ("Unable to acquire exclusive
//! lock on serial port"). So a port held by another process is tried again for [`LOCK_WAIT`],
//! and a port still held then is refused naming the processes that hold it (from `/proc`).

use std::path::Path;
use std::time::{Duration, Instant};

/// How long an open waits for another process to let go of the port.
pub const LOCK_WAIT: Duration = Duration::from_secs(5);

/// Opens `port` at `baud` with reads timing out every `poll`, waiting up to `wait` while another
/// process holds it.
pub fn open(
    port: &str,
    baud: u32,
    poll: Duration,
    wait: Duration,
) -> Result<Box<dyn serialport::SerialPort>, serialport::Error> {
    let deadline = Instant::now() + wait;
    loop {
        match serialport::new(port, baud).timeout(poll).open() {
            Ok(p) => return Ok(p),
            Err(e) if held(&e) && Instant::now() < deadline => std::thread::sleep(Duration::from_millis(50)),
            Err(e) if held(&e) => {
                let who = holders(Path::new(port));
                let named = if who.is_empty() {
                    "no process that this user can see holds it".to_string()
                } else {
                    format!("held by {}", who.join(", "))
                };
                return Err(serialport::Error::new(
                    e.kind,
                    format!("{} after waiting {} s: {named}", e.description, wait.as_secs_f64()),
                ));
            }
            Err(e) => return Err(e),
        }
    }
}

/// Whether the open failed because another open file holds the port: the exclusive flock
/// (`EWOULDBLOCK`) or `TIOCEXCL` (`EBUSY`).
fn held(e: &serialport::Error) -> bool {
    let d = e.description.to_ascii_lowercase();
    d.contains("exclusive lock") || d.contains("resource busy") || d.contains("would block")
}

/// The processes with `port` open: `pid NAME (command line)`, read from `/proc/*/fd`.
pub fn holders(port: &Path) -> Vec<String> {
    let Ok(target) = std::fs::canonicalize(port) else { return Vec::new() };
    let Ok(procs) = std::fs::read_dir("/proc") else { return Vec::new() };
    let mut out = Vec::new();
    for p in procs.flatten() {
        let Some(pid) = p.file_name().to_str().and_then(|s| s.parse::<u32>().ok()) else { continue };
        let Ok(fds) = std::fs::read_dir(p.path().join("fd")) else { continue };
        if fds.flatten().any(|fd| std::fs::read_link(fd.path()).is_ok_and(|l| l == target)) {
            let cmd = std::fs::read(p.path().join("cmdline"))
                .map(|b| {
                    let words: Vec<String> = b
                        .split(|&c| c == 0)
                        .filter(|w| !w.is_empty())
                        .map(accelcal_core::text::escape_peer)
                        .collect();
                    words.join(" ")
                })
                .unwrap_or_default();
            out.push(format!("pid {pid} ({cmd})"));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A pseudo-terminal pair; the follower's path is a port to open.
    fn pty() -> (std::fs::File, String) {
        let (mut leader, mut follower) = (0, 0);
        // SAFETY: openpty writes the two descriptors; no name, termios or window size is passed.
        let r = unsafe {
            libc::openpty(
                &mut leader,
                &mut follower,
                std::ptr::null_mut(),
                std::ptr::null(),
                std::ptr::null(),
            )
        };
        assert_eq!(r, 0, "openpty");
        let name = std::fs::read_link(format!("/proc/self/fd/{follower}")).unwrap().display().to_string();
        // SAFETY: both descriptors were just opened and are owned here alone.
        unsafe { libc::close(follower) };
        (unsafe { std::os::fd::FromRawFd::from_raw_fd(leader) }, name)
    }

    #[test]
    fn a_port_held_past_the_wait_names_its_holder() {
        let (_leader, port) = pty();
        let first = open(&port, 115_200, Duration::from_millis(10), Duration::ZERO).unwrap();
        let t = Instant::now();
        let e = open(&port, 115_200, Duration::from_millis(10), Duration::from_millis(300)).err().unwrap();
        assert!(t.elapsed() >= Duration::from_millis(300), "it waited");
        let me = format!("pid {} (", std::process::id());
        assert!(e.description.contains("after waiting 0.3 s: held by") && e.description.contains(&me), "{e}");
        drop(first);
    }

    #[test]
    fn a_port_let_go_within_the_wait_is_opened() {
        let (_leader, port) = pty();
        let first = open(&port, 115_200, Duration::from_millis(10), Duration::ZERO).unwrap();
        let holder = std::thread::spawn(move || {
            std::thread::sleep(Duration::from_millis(200));
            drop(first);
        });
        open(&port, 115_200, Duration::from_millis(10), Duration::from_secs(5)).unwrap();
        holder.join().unwrap();
    }
}
