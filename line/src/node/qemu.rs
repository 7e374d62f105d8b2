//! Running the node's QEMU build (`-M b-l475e-iot01a`) as a child process: the one place that
//! knows QEMU's command line, for `accelcal hil` (replay, [`super::hil`]) and the emulated bench
//! (live samples from an emulated analog front end).
//!
//! The machine's serial ports, in order: serial0 = USART1, the host link ([`LinkChannel`]: a
//! unix-socket chardev this process connects to, or a pseudo-terminal whose path QEMU names);
//! serial1 = USART2, the front end (a unix-socket chardev the caller connects to, or `null` in
//! replay, so the node's sampler sees nothing); serial2 = USART3, which the node never enables,
//! optionally [`SPIN_CHARDEV`]. Record slots, and the device id of a node that must not report
//! the fixed QEMU id (at `accelcal_shared::contract::QEMU_ID_ADDR`, in SRAM2), are loaded with
//! QEMU's generic loader (`-device loader,file=...,addr=...`; the loader refuses raw files larger
//! than the machine's RAM size, which is 0 on this board unless `-m` is given, hence `-m 1M`). Semihosting is on for the node's
//! defmt output, which goes to a file next to the sockets, for diagnosis. An optional gdbstub
//! listens on `127.0.0.1:PORT`. The process is killed when [`Qemu`] is dropped.

use std::io::Read;
use std::os::unix::net::UnixStream;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::time::{Duration, Instant};

use accelcal_shared::contract::{qemu_id_block, QEMU_ID_ADDR};
use accelcal_shared::slots::SLOT_SIZE;

use super::RECORD_SLOTS;
use accelcal_core::error::{Classify, Kind};

/// A serial port on USART3, which the node never enables, reading `/dev/zero`.
///
/// QEMU's stm32l4x5 USART model takes one byte at a time (`can_receive` is 1 only while RXNE is
/// clear) and does not call `qemu_chr_fe_accept_input()` when the guest reads RDR, so a socket
/// is polled again only at the main loop's next iteration, which otherwise waits for a timer (the
/// node's 1 kHz SysTick) or another event: about 7 kB/s, 820 sample sets/s. A chardev that is
/// always readable makes the main loop iterate without pause; the model drops what it reads,
/// because USART3's receiver is off. It must come after USART1 and USART2 (`-serial` order).
pub const SPIN_CHARDEV: [&str; 4] =
    ["-chardev", "file,id=spin,path=/dev/null,input-path=/dev/zero", "-serial", "chardev:spin"];

/// What carries the host link (USART1).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LinkChannel {
    /// A unix socket QEMU listens on (`server=on,wait=on`: the guest starts once this process has
    /// connected), connected by [`Qemu::start`].
    Socket,
    /// A pseudo-terminal (`-chardev pty`), for programs that open a serial port; QEMU names it on
    /// its standard output ("char device redirected to /dev/pts/N (label link)"). The guest starts
    /// at once (unless a front end is awaited): what the node sends before the terminal is opened
    /// is lost.
    Pty,
}

/// What a record slot holds when no image is given for it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BlankSlot {
    /// Nothing is loaded: QEMU's flash reads zeros there (an empty slot to the node, like erased
    /// flash).
    Zeros,
    /// An erased page (`0xFF`) is loaded, as on the real chip.
    Erased,
}

/// How to run the node in QEMU.
#[derive(Clone, Debug)]
pub struct QemuOptions {
    /// The QEMU executable.
    pub qemu: PathBuf,
    /// The node's QEMU build (ELF).
    pub elf: PathBuf,
    /// What carries the host link.
    pub link: LinkChannel,
    /// Put USART2 on a unix socket that the caller connects to ([`Qemu::frontend`]) and feeds
    /// `accelcal_shared::frontend` frames; otherwise USART2 is `null` (replay).
    pub frontend: bool,
    /// Open QEMU's gdbstub on `127.0.0.1:PORT`.
    pub gdb_port: Option<u16>,
    /// Slot page images (see `SlotImage::build`) for record slots 0 and 1.
    pub slots: [Option<Vec<u8>>; 2],
    /// What a slot without an image holds.
    pub blank: BlankSlot,
    /// The device id the node reports, loaded at `contract::QEMU_ID_ADDR` (SRAM2) as
    /// `contract::qemu_id_block`; `None`: nothing is loaded and the node reports
    /// `contract::QEMU_DEVICE_ID`.
    pub device_id: Option<[u8; 12]>,
    /// Keep QEMU's main loop busy ([`SPIN_CHARDEV`] on USART3) so that the link and the front end
    /// are read at full speed; costs one host core while QEMU runs.
    pub spin_main_loop: bool,
    /// How long QEMU may take to open its sockets or name its pty.
    pub timeout: Duration,
}

impl QemuOptions {
    /// Defaults: `qemu-system-arm` from `PATH`, link on a socket, no front end (USART2 `null`), no
    /// gdbstub, blank slots reading zeros, main loop not kept busy, 20 s timeout.
    pub fn new(elf: impl Into<PathBuf>) -> Self {
        QemuOptions {
            qemu: "qemu-system-arm".into(),
            elf: elf.into(),
            link: LinkChannel::Socket,
            frontend: false,
            gdb_port: None,
            slots: [None, None],
            blank: BlankSlot::Zeros,
            device_id: None,
            spin_main_loop: false,
            timeout: Duration::from_secs(20),
        }
    }
}

/// Why QEMU could not be run.
#[derive(Debug, thiserror::Error)]
pub enum QemuError {
    /// QEMU could not be started.
    #[error("cannot start {qemu}: {cause} (install QEMU >= 9 with `bash scripts/setup-qemu.sh`)")]
    Spawn {
        /// The executable.
        qemu: PathBuf,
        /// The cause.
        cause: std::io::Error,
    },
    /// QEMU ended.
    #[error("qemu exited ({status}): {stderr}")]
    Exited {
        /// Exit status.
        status: ExitStatus,
        /// What it printed on stderr (the node's panic message goes there).
        stderr: String,
    },
    /// QEMU did not open its sockets or name its pty in time.
    #[error("qemu did not get ready within {0:?}")]
    Timeout(Duration),
    /// A slot image is not one page.
    #[error("slot {slot} image has {len} bytes, a slot page has {SLOT_SIZE}")]
    SlotSize {
        /// The slot.
        slot: usize,
        /// Its image's length.
        len: usize,
    },
    /// Local file or socket trouble.
    #[error(transparent)]
    Io(#[from] std::io::Error),
}

impl Classify for QemuError {
    fn kind(&self) -> Kind {
        Kind::Environment
    }
}

/// The host link of a running node.
#[derive(Debug)]
pub enum Link {
    /// The connected socket.
    Socket(UnixStream),
    /// The pseudo-terminal's path, for the caller to open.
    Pty(PathBuf),
}

/// A QEMU process running the node's QEMU build; killed when dropped.
pub struct Qemu {
    child: Child,
    stderr_path: PathBuf,
    dir: tempfile::TempDir,
    link: Option<Link>,
    frontend: Option<UnixStream>,
}

impl Qemu {
    /// Starts QEMU and connects what [`QemuOptions`] asks for: the link socket (or reads the pty's
    /// path), then the front-end socket. With sockets QEMU starts the guest only once both are
    /// connected, so nothing the node sends at boot is missed.
    pub fn start(opts: &QemuOptions) -> Result<Qemu, QemuError> {
        let dir = tempfile::Builder::new().prefix("accelcal-qemu").tempdir()?;
        let link_sock = dir.path().join("link.sock");
        let fe_sock = dir.path().join("frontend.sock");
        let stdout_path = dir.path().join("defmt.bin");
        let stderr_path = dir.path().join("qemu.stderr");
        let mut cmd = Command::new(&opts.qemu);
        cmd.args(["-M", "b-l475e-iot01a", "-m", "1M", "-display", "none", "-monitor", "none"])
            .args(["-semihosting-config", "enable=on,target=native"])
            .arg("-chardev");
        match opts.link {
            LinkChannel::Socket => {
                cmd.arg(format!("socket,id=link,path={},server=on,wait=on", link_sock.display()))
            }
            LinkChannel::Pty => cmd.arg("pty,id=link"),
        };
        cmd.args(["-serial", "chardev:link"]);
        if opts.frontend {
            cmd.arg("-chardev")
                .arg(format!("socket,id=fe,path={},server=on,wait=on", fe_sock.display()))
                .args(["-serial", "chardev:fe"]);
        } else {
            cmd.args(["-serial", "null"]);
        }
        if opts.spin_main_loop {
            cmd.args(SPIN_CHARDEV);
        }
        if let Some(port) = opts.gdb_port {
            cmd.arg("-gdb").arg(format!("tcp:127.0.0.1:{port}"));
        }
        for (slot, image) in opts.slots.iter().enumerate() {
            let page = match (image, opts.blank) {
                (Some(image), _) if image.len() != SLOT_SIZE => {
                    return Err(QemuError::SlotSize { slot, len: image.len() })
                }
                (Some(image), _) => image.clone(),
                (None, BlankSlot::Erased) => vec![0xff; SLOT_SIZE],
                (None, BlankSlot::Zeros) => continue,
            };
            let path = dir.path().join(format!("slot{slot}.bin"));
            std::fs::write(&path, page)?;
            cmd.arg("-device").arg(format!("loader,file={},addr={:#x}", path.display(), RECORD_SLOTS[slot]));
        }
        if let Some(id) = opts.device_id {
            let path = dir.path().join("device-id.bin");
            std::fs::write(&path, qemu_id_block(id))?;
            cmd.arg("-device").arg(format!("loader,file={},addr={QEMU_ID_ADDR:#x}", path.display()));
        }
        cmd.arg("-kernel")
            .arg(&opts.elf)
            .stdin(Stdio::null())
            .stdout(std::fs::File::create(&stdout_path)?)
            .stderr(std::fs::File::create(&stderr_path)?);
        let child = cmd.spawn().map_err(|cause| QemuError::Spawn { qemu: opts.qemu.clone(), cause })?;
        let mut q = Qemu { child, stderr_path, dir, link: None, frontend: None };
        let t0 = Instant::now();
        q.link = Some(match opts.link {
            LinkChannel::Socket => Link::Socket(q.connect(&link_sock, t0, opts.timeout)?),
            LinkChannel::Pty => Link::Pty(q.pty_path(&stdout_path, t0, opts.timeout)?),
        });
        if opts.frontend {
            q.frontend = Some(q.connect(&fe_sock, t0, opts.timeout)?);
        }
        Ok(q)
    }

    /// Connects to the socket QEMU listens on at `path`, retrying until QEMU has created it.
    fn connect(&mut self, path: &Path, t0: Instant, timeout: Duration) -> Result<UnixStream, QemuError> {
        loop {
            if let Ok(s) = UnixStream::connect(path) {
                return Ok(s);
            }
            self.wait_a_little(t0, timeout)?;
        }
    }

    /// The pseudo-terminal QEMU names on its standard output ("char device redirected to
    /// /dev/pts/N (label link)", printed before the guest starts, so before any defmt byte).
    fn pty_path(&mut self, stdout: &Path, t0: Instant, timeout: Duration) -> Result<PathBuf, QemuError> {
        loop {
            let mut text = Vec::new();
            std::fs::File::open(stdout)?.take(4096).read_to_end(&mut text)?;
            if let Some(path) = parse_pty_line(&String::from_utf8_lossy(&text), "link") {
                return Ok(path);
            }
            self.wait_a_little(t0, timeout)?;
        }
    }

    /// Fails if QEMU has exited or `timeout` has passed since `t0`; else sleeps 20 ms.
    fn wait_a_little(&mut self, t0: Instant, timeout: Duration) -> Result<(), QemuError> {
        if let Some(e) = self.exited() {
            return Err(e);
        }
        if t0.elapsed() > timeout {
            return Err(QemuError::Timeout(timeout));
        }
        std::thread::sleep(Duration::from_millis(20));
        Ok(())
    }

    /// The host link: the connected socket or the pty's path. `None` once taken.
    pub fn take_link(&mut self) -> Option<Link> {
        self.link.take()
    }

    /// The connected front-end socket (USART2), when [`QemuOptions::frontend`] asked for one.
    /// `None` once taken.
    pub fn take_frontend(&mut self) -> Option<UnixStream> {
        self.frontend.take()
    }

    /// `Some` with the exit status and QEMU's stderr once QEMU has ended.
    pub fn exited(&mut self) -> Option<QemuError> {
        match self.child.try_wait() {
            Ok(Some(status)) => Some(QemuError::Exited {
                status,
                // The node's own words (its panic message): shown escaped, on the error's line.
                stderr: accelcal_core::text::escape_peer(
                    std::fs::read(&self.stderr_path).unwrap_or_default().trim_ascii(),
                ),
            }),
            _ => None,
        }
    }

    /// The directory of QEMU's files (sockets, slot images, `defmt.bin` with the node's defmt
    /// output, `qemu.stderr`); removed when QEMU is dropped.
    pub fn dir(&self) -> &Path {
        self.dir.path()
    }
}

impl Drop for Qemu {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// The pty path in QEMU's "char device redirected to PATH (label LABEL)" line for `label`.
fn parse_pty_line(text: &str, label: &str) -> Option<PathBuf> {
    let tail = format!(" (label {label})");
    text.lines().find_map(|l| {
        let rest = l.strip_prefix("char device redirected to ")?;
        Some(PathBuf::from(rest.strip_suffix(&tail)?))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_pty_line_is_found_by_label() {
        let text = "char device redirected to /dev/pts/3 (label other)\nchar device redirected to /dev/pts/7 (label link)\n\u{1}junk";
        assert_eq!(parse_pty_line(text, "link"), Some(PathBuf::from("/dev/pts/7")));
        assert_eq!(parse_pty_line("nothing\n", "link"), None);
    }
}
