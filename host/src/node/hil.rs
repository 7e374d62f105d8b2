//! Hardware in the loop on QEMU: boot the node's QEMU build with a calibration record in its
//! flash, replay raw code sets through its link, and collect what the node computed.
//!
//! QEMU runs `-M b-l475e-iot01a` with USART1 on a unix-socket chardev that this process connects
//! to, the record loaded as slot 0's page image by QEMU's generic loader (`-device
//! loader,file=...,addr=0x080FF000`; the loader refuses raw files larger than the machine's RAM
//! size, which is 0 on this board unless `-m` is given), and semihosting on for the node's defmt
//! output (kept in a file next to the socket, for diagnosis).

use std::io::Write;
use std::os::unix::net::UnixStream;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use accelcal_shared::record::Record;
use accelcal_shared::slots::SlotImage;
use accelcal_shared::wire::{Block, Codes, HostMsg, NodeMsg, RecordStatus, Status, MAX_BLOCK};

use super::link::{self, LinkError, Receiver};
use super::RECORD_SLOTS;

/// How to run the node in QEMU.
#[derive(Clone, Debug)]
pub struct HilOptions {
    /// The QEMU executable.
    pub qemu: PathBuf,
    /// The node's QEMU build (ELF).
    pub elf: PathBuf,
    /// How long the node may stay silent before the run fails.
    pub timeout: Duration,
    /// Keeps QEMU's main loop busy so that the link is read at full speed (see
    /// [`SPIN_CHARDEV`]); costs one host core while QEMU runs.
    pub spin_main_loop: bool,
}

/// A second serial port (USART2, which the node never enables) reading `/dev/zero`.
///
/// QEMU's stm32l4x5 USART model takes one byte at a time (`can_receive` is 1 only while RXNE is
/// clear) and does not call `qemu_chr_fe_accept_input()` when the guest reads RDR, so the link's
/// socket is polled again only at the main loop's next iteration, which otherwise waits for a
/// timer (the node's 1 kHz SysTick) or another event: about 7 kB/s, 820 sample sets/s. A chardev
/// that is always readable makes the main loop iterate without pause; the model drops what it
/// reads, because USART2's receiver is off.
pub const SPIN_CHARDEV: [&str; 4] =
    ["-chardev", "file,id=spin,path=/dev/null,input-path=/dev/zero", "-serial", "chardev:spin"];

impl HilOptions {
    /// Defaults: `qemu-system-arm` from `PATH`, 20 s timeout, QEMU's main loop not kept busy.
    pub fn new(elf: impl Into<PathBuf>) -> Self {
        HilOptions {
            qemu: "qemu-system-arm".into(),
            elf: elf.into(),
            timeout: Duration::from_secs(20),
            spin_main_loop: false,
        }
    }
}

/// What a replay returned.
#[derive(Clone, Debug)]
pub struct HilRun {
    /// The node's calibrated acceleration for each replayed code set, m/s².
    pub accel: Vec<[f32; 3]>,
    /// The node's status after the replay.
    pub status: Status,
}

/// Why a replay failed.
#[derive(Debug, thiserror::Error)]
pub enum HilError {
    /// The record bytes are not a valid record.
    #[error("invalid calibration record: {0}")]
    Record(accelcal_shared::slots::SlotError),
    /// QEMU could not be started.
    #[error("cannot start {qemu}: {source} (install QEMU >= 9 with `bash scripts/setup-qemu.sh`)")]
    Spawn {
        /// The executable.
        qemu: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// QEMU ended before the replay finished.
    #[error("qemu exited ({status}): {stderr}")]
    QemuExited {
        /// Exit status.
        status: std::process::ExitStatus,
        /// What it printed on stderr (the node's panic message goes there).
        stderr: String,
    },
    /// The node did not answer in time.
    #[error("the node did not answer within {0:?}")]
    Timeout(Duration),
    /// The link failed.
    #[error(transparent)]
    Link(#[from] LinkError),
    /// The node runs without the record.
    #[error("the node did not accept the record: {0}{hint}", hint = rejection_hint(*.0))]
    Rejected(accelcal_shared::wire::RecordFault),
    /// The node answered something it should not have.
    #[error("unexpected answer from the node: {0}")]
    Protocol(String),
    /// Local file trouble (temporary directory).
    #[error("{0}")]
    Io(#[from] std::io::Error),
}

fn hex(b: &[u8]) -> String {
    b.iter().map(|x| format!("{x:02x}")).collect()
}

/// What to do about a record the QEMU node refused, where there is something to say.
fn rejection_hint(fault: accelcal_shared::wire::RecordFault) -> String {
    use accelcal_shared::wire::RecordFault;
    match fault {
        RecordFault::WrongDevice => {
            format!(" (a record for the QEMU node needs device id {})", hex(&super::QEMU_DEVICE_ID))
        }
        RecordFault::NotModel4 => " (fit it with `--terms ax,ay,az`, the default)".into(),
        _ => String::new(),
    }
}

/// A QEMU process running the node's QEMU build, with its link connected; killed when dropped.
pub struct QemuNode {
    child: Child,
    stderr_path: PathBuf,
    _dir: tempfile::TempDir,
    stream: UnixStream,
    rx: Receiver<UnixStream>,
    timeout: Duration,
}

impl QemuNode {
    /// Boots the node with `slot0` (a slot page image, see [`SlotImage::build`]) loaded into
    /// record slot 0, or with both slots blank (QEMU's flash reads as zeros), and connects to its
    /// link.
    pub fn start(opts: &HilOptions, slot0: Option<&[u8]>) -> Result<QemuNode, HilError> {
        let dir = tempfile::Builder::new().prefix("accelcal-hil").tempdir()?;
        let slot_path = dir.path().join("slot0.bin");
        let sock = dir.path().join("link.sock");
        let stderr_path = dir.path().join("qemu.stderr");
        let mut cmd = Command::new(&opts.qemu);
        cmd.args(["-M", "b-l475e-iot01a", "-m", "1M", "-display", "none", "-monitor", "none"])
            .args(["-semihosting-config", "enable=on,target=native"])
            .arg("-chardev")
            .arg(format!("socket,id=link,path={},server=on,wait=on", sock.display()))
            .args(["-serial", "chardev:link"]);
        if opts.spin_main_loop {
            cmd.args(SPIN_CHARDEV);
        }
        if let Some(page) = slot0 {
            std::fs::write(&slot_path, page)?;
            cmd.arg("-device").arg(format!(
                "loader,file={},addr={:#x}",
                slot_path.display(),
                RECORD_SLOTS[0]
            ));
        }
        cmd.arg("-kernel")
            .arg(&opts.elf)
            .stdin(Stdio::null())
            .stdout(std::fs::File::create(dir.path().join("defmt.bin"))?)
            .stderr(std::fs::File::create(&stderr_path)?);
        let mut child = cmd.spawn().map_err(|source| HilError::Spawn { qemu: opts.qemu.clone(), source })?;
        let t0 = Instant::now();
        let stream = loop {
            if let Ok(s) = UnixStream::connect(&sock) {
                break s;
            }
            if let Some(status) = child.try_wait()? {
                let stderr = std::fs::read_to_string(&stderr_path).unwrap_or_default();
                return Err(HilError::QemuExited { status, stderr });
            }
            if t0.elapsed() > opts.timeout {
                let _ = child.kill();
                return Err(HilError::Timeout(opts.timeout));
            }
            std::thread::sleep(Duration::from_millis(20));
        };
        stream.set_read_timeout(Some(Duration::from_millis(200)))?;
        let rx = Receiver::new(stream.try_clone()?);
        let mut node = QemuNode { child, stderr_path, _dir: dir, stream, rx, timeout: opts.timeout };
        node.wait_boot_status()?;
        Ok(node)
    }

    /// Waits for the status report the node sends at boot, once its link is up (QEMU starts the
    /// guest only once this process has connected, so the report cannot be missed). Nothing is
    /// sent before it: bytes sent before the node enables its receiver would be lost in part.
    fn wait_boot_status(&mut self) -> Result<Status, HilError> {
        self.next_status()
    }

    /// Asks the node for its status and returns the next status report.
    pub fn status(&mut self) -> Result<Status, HilError> {
        let mut tx = self.stream.try_clone()?;
        link::send(&mut tx, &HostMsg::GetStatus)?;
        self.next_status()
    }

    /// The next status report the node sends (other messages are passed over), within the timeout.
    fn next_status(&mut self) -> Result<Status, HilError> {
        let t0 = Instant::now();
        loop {
            match self.rx.recv() {
                Ok(Ok(NodeMsg::Status(s))) => return Ok(s),
                Ok(_) => {}
                Err(e) if is_timeout(&e) => {}
                Err(e) => return Err(self.explain(e)),
            }
            if t0.elapsed() > self.timeout {
                return Err(HilError::Timeout(self.timeout));
            }
        }
    }

    /// Sends raw bytes on the link (for tests of the node's frame handling).
    pub fn send_raw(&mut self, bytes: &[u8]) -> Result<(), HilError> {
        self.stream.write_all(bytes)?;
        Ok(())
    }

    /// Sends `msg` and returns the node's next message that is not a periodic status report.
    pub fn request(&mut self, msg: &HostMsg) -> Result<NodeMsg, HilError> {
        let mut tx = self.stream.try_clone()?;
        link::send(&mut tx, msg)?;
        self.next_answer()
    }

    /// The next message that is not a status report.
    fn next_answer(&mut self) -> Result<NodeMsg, HilError> {
        let mut last = Instant::now();
        loop {
            match self.rx.recv() {
                Ok(Ok(NodeMsg::Status(_))) => last = Instant::now(),
                Ok(Ok(m)) => return Ok(m),
                Ok(Err(e)) => return Err(HilError::Protocol(format!("bad frame from the node: {e}"))),
                Err(e) if is_timeout(&e) => {
                    if last.elapsed() > self.timeout {
                        return Err(HilError::Timeout(self.timeout));
                    }
                }
                Err(e) => return Err(self.explain(e)),
            }
        }
    }

    /// Turns a link error into the more telling "QEMU exited" when QEMU is gone.
    fn explain(&mut self, e: LinkError) -> HilError {
        std::thread::sleep(Duration::from_millis(100));
        match self.child.try_wait() {
            Ok(Some(status)) => HilError::QemuExited {
                status,
                stderr: std::fs::read_to_string(&self.stderr_path).unwrap_or_default(),
            },
            _ => HilError::Link(e),
        }
    }
}

impl Drop for QemuNode {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

fn is_timeout(e: &LinkError) -> bool {
    matches!(e, LinkError::Io(io) if matches!(io.kind(), std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut))
}

/// Boots the QEMU node with `record` (the bytes of a record file) in slot 0, replays `codes`
/// through it in blocks of [`MAX_BLOCK`], and returns the node's answers in order.
pub fn replay(opts: &HilOptions, record: &[u8], codes: &[Codes]) -> Result<HilRun, HilError> {
    let rec =
        Record::parse(record).map_err(|e| HilError::Record(accelcal_shared::slots::SlotError::Record(e)))?;
    let page = SlotImage::build(&record[..rec.len()], 1).map_err(HilError::Record)?;
    let mut node = QemuNode::start(opts, Some(&page))?;
    let status = node.status()?;
    if let RecordStatus::Missing(fault) = status.record {
        return Err(HilError::Rejected(fault));
    }

    // A writer thread sends every request; QEMU's chardev applies back-pressure, so the node
    // takes them at its own pace while this thread collects the answers.
    let mut tx = node.stream.try_clone()?;
    let blocks: Vec<Vec<Codes>> = codes.chunks(MAX_BLOCK).map(|c| c.to_vec()).collect();
    let writer = std::thread::spawn(move || -> Result<(), LinkError> {
        let mut out = Vec::new();
        for (seq, block) in blocks.into_iter().enumerate() {
            let codes = heapless::Vec::from_slice(&block).expect("chunks of MAX_BLOCK");
            out.extend_from_slice(&link::frame(&HostMsg::Replay { seq: seq as u32, codes })?);
        }
        tx.write_all(&out)?;
        tx.flush()?;
        Ok(())
    });

    let mut accel = Vec::with_capacity(codes.len());
    while accel.len() < codes.len() {
        let NodeMsg::Replayed { seq, data } = node.next_answer()? else {
            continue;
        };
        let want = accel.len() / MAX_BLOCK;
        if seq as usize != want {
            return Err(HilError::Protocol(format!("answer {seq} where {want} was due")));
        }
        let expected = (codes.len() - accel.len()).min(MAX_BLOCK);
        match data {
            Block::Calibrated(v) if v.len() == expected => accel.extend_from_slice(&v),
            // Fixed point: m/s²·2¹⁶ as i32; exact in f32 for |a| < 256 m/s².
            Block::CalibratedFixed(v) if v.len() == expected => {
                accel.extend(v.iter().map(|a| a.map(|q| (q as f64 / 65536.0) as f32)))
            }
            Block::Uncalibrated(_) => {
                return Err(HilError::Protocol("the node answered uncalibrated codes".into()))
            }
            other => {
                return Err(HilError::Protocol(format!(
                    "answer {seq} has {} sets, {expected} were sent",
                    other.len()
                )))
            }
        }
    }
    match writer.join() {
        Ok(r) => r?,
        Err(_) => return Err(HilError::Protocol("writer thread panicked".into())),
    }
    let status = node.status()?;
    Ok(HilRun { accel, status })
}

/// The raw code sets of a campaign's channels `x`, `y`, `z`, as the node's ADC would deliver
/// them: every code must be a whole number in 0..=65535.
pub fn campaign_codes(c: &crate::campaign::Campaign, path: &Path) -> anyhow::Result<Vec<Codes>> {
    let ch = |name: &str| {
        c.channels.iter().find(|ch| ch.name == name).ok_or_else(|| {
            crate::error::bad(format!(
                "{}: no channel `{name}` (the node replays a triad with channels x, y, z)",
                path.display()
            ))
        })
    };
    let (x, y, z) = (ch("x")?, ch("y")?, ch("z")?);
    let mut out = Vec::with_capacity(c.t_s.len());
    for row in 0..c.t_s.len() {
        let mut set = [0u16; 3];
        for (k, chan) in [x, y, z].into_iter().enumerate() {
            let v = chan.codes[row];
            if !(0.0..=65535.0).contains(&v) || v.fract() != 0.0 {
                return Err(crate::error::bad(format!(
                    "{}: row {} channel {}: code {v} is not a whole number in 0..=65535 (simulate without --ideal-adc)",
                    path.display(),
                    row + 1,
                    chan.name
                )));
            }
            set[k] = v as u16;
        }
        out.push(set);
    }
    Ok(out)
}

/// Writes the node's answers as CSV `t_s,ax,ay,az` (m/s²; f32 values printed exactly).
pub fn write_csv(path: &Path, t_s: &[f64], accel: &[[f32; 3]]) -> std::io::Result<()> {
    let mut w = std::io::BufWriter::new(std::fs::File::create(path)?);
    writeln!(w, "t_s,ax,ay,az")?;
    for (t, a) in t_s.iter().zip(accel) {
        writeln!(w, "{t},{},{},{}", a[0], a[1], a[2])?;
    }
    w.flush()
}
