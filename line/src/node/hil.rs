//! Hardware in the loop on QEMU: boot the node with a calibration record in its flash, replay raw
//! code sets through its link, and collect what the node computed.
//!
//! QEMU is run by [`super::qemu`] with USART1 on a unix-socket chardev that this process connects
//! to, the record as slot 0's page image, and USART2 (the live front end) on `null`, so the node's
//! sampler sees nothing and only the replay answers and status reports come back.
//!
//! A record with thermal terms is replayed with each set's temperature (the campaign's `temp_c`,
//! as f32): the first request of a run restarts the node's replay tracker
//! ([`accelcal_shared::wire::ReplayTemp`]), so the node's output is the shared f32 path
//! ([`accelcal_shared::thermal::ThermalTracker::apply_block`]) fed the run's sets in order, which
//! the host reproduces bit for bit.

use std::io::{Read, Write};
use std::os::unix::net::UnixStream;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use accelcal_shared::record::Record;
use accelcal_shared::slots::SlotImage;
use accelcal_shared::wire::{
    self, Block, BlockTemp, Codes, HostMsg, NodeMsg, RecordStatus, ReplayTemp, Status, MAX_BLOCK,
};

use anyhow::Context;

use super::link::{self, LinkError, Receiver};
use super::qemu::{Link, LinkChannel, Qemu, QemuError, QemuOptions};
use accelcal_core::campaign::{CodeRange, Row};
use accelcal_core::error::bad;
use accelcal_core::error::{Classify, Kind};
use accelcal_core::input::Input;
use accelcal_core::reduce::DwellRows;

pub use super::qemu::SPIN_CHARDEV;

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

    /// The QEMU run of a replay: link on a socket, no front end, `slot0` in record slot 0 (slot 1
    /// blank, reading zeros).
    pub fn qemu_options(&self, slot0: Option<&[u8]>) -> QemuOptions {
        QemuOptions {
            qemu: self.qemu.clone(),
            spin_main_loop: self.spin_main_loop,
            timeout: self.timeout,
            slots: [slot0.map(<[u8]>::to_vec), None],
            ..QemuOptions::new(&self.elf)
        }
    }
}

/// What a replay returned.
#[derive(Clone, Debug)]
pub struct HilRun {
    /// The node's calibrated acceleration for each replayed code set, m/s².
    pub accel: Vec<[f32; 3]>,
    /// The temperature report of each replayed block (of [`MAX_BLOCK`] sets), when the sets were
    /// sent with temperatures.
    pub temp: Vec<Option<BlockTemp>>,
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
    #[error("cannot start {qemu}: {cause} (install QEMU >= 9 with `bash scripts/setup-qemu.sh`)")]
    Spawn {
        /// The executable.
        qemu: PathBuf,
        /// The cause.
        cause: std::io::Error,
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
    /// QEMU was asked for something it cannot run.
    #[error(transparent)]
    Qemu(QemuError),
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
    #[error(transparent)]
    Io(#[from] std::io::Error),
}

impl Classify for HilError {
    fn kind(&self) -> Kind {
        match self {
            // The record given, refused before QEMU starts.
            HilError::Record(_) => Kind::BadInput,
            HilError::Link(e) => e.kind(),
            HilError::Qemu(e) => e.kind(),
            HilError::Spawn { .. }
            | HilError::QemuExited { .. }
            | HilError::Timeout(_)
            | HilError::Rejected(_)
            | HilError::Protocol(_)
            | HilError::Io(_) => Kind::Environment,
        }
    }
}

impl From<QemuError> for HilError {
    fn from(e: QemuError) -> Self {
        match e {
            QemuError::Spawn { qemu, cause } => HilError::Spawn { qemu, cause },
            QemuError::Exited { status, stderr } => HilError::QemuExited { status, stderr },
            QemuError::Timeout(t) => HilError::Timeout(t),
            QemuError::Io(e) => HilError::Io(e),
            e @ QemuError::SlotSize { .. } => HilError::Qemu(e),
        }
    }
}

/// What to do about a record the QEMU node refused, where there is something to say.
fn rejection_hint(fault: accelcal_shared::wire::RecordFault) -> String {
    use accelcal_shared::wire::RecordFault;
    match fault {
        RecordFault::WrongDevice => {
            format!(
                " (a record for the QEMU node needs device id {})",
                super::session::device_id_hex(&super::QEMU_DEVICE_ID)
            )
        }
        RecordFault::NotModel4 => " (fit it with `--terms ax,ay,az`, the default)".into(),
        RecordFault::NoTempInput => {
            " (the QEMU board has only the front end's temperature channel: a thermal record for it names the input `front-end`)"
                .into()
        }
        _ => String::new(),
    }
}

/// A QEMU process running the node's QEMU build, with its link connected; killed when dropped.
pub struct QemuNode {
    qemu: Qemu,
    stream: UnixStream,
    rx: Receiver<UnixStream>,
    timeout: Duration,
}

impl QemuNode {
    /// Boots the node with `slot0` (a slot page image, see [`SlotImage::build`]) loaded into
    /// record slot 0, or with both slots blank (QEMU's flash reads as zeros), and connects to its
    /// link.
    pub fn start(opts: &HilOptions, slot0: Option<&[u8]>) -> Result<QemuNode, HilError> {
        QemuNode::launch(&opts.qemu_options(slot0))
    }

    /// Boots the node as `opts` says (the link must be [`LinkChannel::Socket`]), connects to its
    /// link and waits for its boot status; the front-end socket, if any, is left in the returned
    /// node's [`QemuNode::qemu`]. `opts.timeout` also bounds every wait for an answer.
    pub fn launch(opts: &QemuOptions) -> Result<QemuNode, HilError> {
        if opts.link != LinkChannel::Socket {
            return Err(HilError::Protocol("a QemuNode talks over a socket link".into()));
        }
        let mut qemu = Qemu::start(opts)?;
        let Some(Link::Socket(stream)) = qemu.take_link() else {
            return Err(HilError::Protocol("QEMU's link is not a connected socket".into()));
        };
        stream.set_read_timeout(Some(Duration::from_millis(200)))?;
        let rx = Receiver::new(stream.try_clone()?);
        let mut node = QemuNode { qemu, stream, rx, timeout: opts.timeout };
        node.wait_boot_status()?;
        Ok(node)
    }

    /// The QEMU process (its front-end socket, its files).
    pub fn qemu(&mut self) -> &mut Qemu {
        &mut self.qemu
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
        let deadline = Instant::now() + self.timeout;
        loop {
            match self.rx.recv(deadline) {
                Ok(Ok(NodeMsg::Status(s))) => return Ok(s),
                Ok(_) => {}
                Err(LinkError::Deadline) => return Err(HilError::Timeout(self.timeout)),
                Err(e) => return Err(self.explain(e)),
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

    /// The next message that is not a status report; each status report (the node is alive and
    /// working through the requests) gives it another timeout.
    fn next_answer(&mut self) -> Result<NodeMsg, HilError> {
        let mut deadline = Instant::now() + self.timeout;
        loop {
            match self.rx.recv(deadline) {
                Ok(Ok(NodeMsg::Status(_))) => deadline = Instant::now() + self.timeout,
                Ok(Ok(m)) => return Ok(m),
                Ok(Err(e)) => return Err(HilError::Protocol(format!("bad frame from the node: {e}"))),
                Err(LinkError::Deadline) => return Err(HilError::Timeout(self.timeout)),
                Err(e) => return Err(self.explain(e)),
            }
        }
    }

    /// Turns a link error into the more telling "QEMU exited" when QEMU is gone.
    fn explain(&mut self, e: LinkError) -> HilError {
        std::thread::sleep(Duration::from_millis(100));
        match self.qemu.exited() {
            Some(e) => e.into(),
            None => HilError::Link(e),
        }
    }
}

/// Code sets to replay: one request's worth.
pub type CodeBlock = heapless::Vec<Codes, MAX_BLOCK>;
/// The temperatures of a block's sets, °C.
pub type TempBlock = heapless::Vec<f32, MAX_BLOCK>;

/// How many requests may wait for their answer: the protocol's bound
/// ([`wire::MAX_REQUESTS_IN_FLIGHT`], 9), which the real node's receive ring is sized for. In
/// QEMU it keeps the node's input (the socket, read one byte at a time) from running dry, and the
/// requests (at most `wire::MAX_REQUEST_FRAME`, 221 bytes each) fit the socket's buffer, so sending never waits for the node
/// and one thread does both.
const IN_FLIGHT: usize = wire::MAX_REQUESTS_IN_FLIGHT;

/// Boots the QEMU node with `record` (the bytes of a record file) in slot 0, replays `codes`
/// through it in blocks of [`MAX_BLOCK`], and returns the node's answers in order.
pub fn replay(opts: &HilOptions, record: &[u8], codes: &[Codes]) -> Result<HilRun, HilError> {
    replay_with_temps(opts, record, codes, None)
}

/// [`replay`] with each set's temperature `temp_c` (°C, as many as `codes`) when given: what a
/// record with thermal terms needs.
pub fn replay_with_temps(
    opts: &HilOptions,
    record: &[u8],
    codes: &[Codes],
    temp_c: Option<&[f32]>,
) -> Result<HilRun, HilError> {
    if temp_c.is_some_and(|t| t.len() != codes.len()) {
        return Err(HilError::Protocol("one temperature per code set is needed".into()));
    }
    let mut accel = Vec::with_capacity(codes.len());
    let mut temp = Vec::new();
    let blocks = codes.chunks(MAX_BLOCK).enumerate().map(|(k, c)| {
        let t = temp_c.map(|t| {
            TempBlock::from_slice(&t[k * MAX_BLOCK..k * MAX_BLOCK + c.len()]).expect("chunks of MAX_BLOCK")
        });
        Ok::<_, HilError>((CodeBlock::from_slice(c).expect("chunks of MAX_BLOCK"), t, ()))
    });
    let status = replay_blocks(opts, record, blocks, |(), a, t| {
        accel.extend_from_slice(a);
        temp.push(t);
        Ok(())
    })?;
    Ok(HilRun { accel, temp, status })
}

/// Boots the QEMU node with `record` (the bytes of a record file) in slot 0 and replays the blocks
/// `blocks` yields, each with its sets' temperatures (or `None`) and a tag of the caller's, as they
/// come: at most `IN_FLIGHT` (9) requests wait for their answer, so memory does not grow with the
/// blocks. The first block with temperatures restarts the node's replay tracker. Each answer,
/// checked (in order, as many sets as were sent, calibrated), goes to `answered` with its block's
/// tag and temperature report. Returns the node's status after the last answer; the first error
/// of `blocks`, of `answered` or of the node ends the replay, and the node is shut down.
pub fn replay_blocks<T, E: From<HilError>>(
    opts: &HilOptions,
    record: &[u8],
    blocks: impl IntoIterator<Item = Result<(CodeBlock, Option<TempBlock>, T), E>>,
    mut answered: impl FnMut(T, &[[f32; 3]], Option<BlockTemp>) -> Result<(), E>,
) -> Result<Status, E> {
    let rec =
        Record::parse(record).map_err(|e| HilError::Record(accelcal_shared::slots::SlotError::Record(e)))?;
    let page = SlotImage::build(&record[..rec.len()], 1).map_err(HilError::Record)?;
    let mut node = QemuNode::start(opts, Some(&page))?;
    let status = node.status()?;
    if let RecordStatus::Missing(fault) = status.record {
        return Err(HilError::Rejected(fault).into());
    }

    let mut blocks = blocks.into_iter().fuse();
    // (seq, sets sent, tag) of the requests waiting for their answer, oldest first.
    let mut waiting = std::collections::VecDeque::with_capacity(IN_FLIGHT);
    let mut seq = 0u32;
    let mut restart = true;
    let mut accel = Vec::with_capacity(MAX_BLOCK);
    loop {
        while waiting.len() < IN_FLIGHT {
            let Some(block) = blocks.next() else { break };
            let (codes, temp_c, tag) = block?;
            let sent = codes.len();
            let temp = temp_c.map(|temp_c| ReplayTemp { restart: std::mem::take(&mut restart), temp_c });
            node.send_raw(&link::frame(&HostMsg::Replay { seq, codes, temp }).map_err(HilError::from)?)?;
            waiting.push_back((seq, sent, tag));
            seq = seq.wrapping_add(1);
        }
        let Some((want, sent, tag)) = waiting.pop_front() else { break };
        let temp = node.next_block(want, sent, &mut accel)?;
        answered(tag, &accel, temp)?;
    }
    Ok(node.status()?)
}

impl QemuNode {
    /// Waits for the answer to request `want`, which carried `sent` code sets, puts the node's
    /// calibrated acceleration into `accel` and returns the block's temperature report.
    fn next_block(
        &mut self,
        want: u32,
        sent: usize,
        accel: &mut Vec<[f32; 3]>,
    ) -> Result<Option<BlockTemp>, HilError> {
        let (seq, data, temp) = loop {
            if let NodeMsg::Replayed { seq, data, temp } = self.next_answer()? {
                break (seq, data, temp);
            }
        };
        if seq != want {
            return Err(HilError::Protocol(format!("answer {seq} where {want} was due")));
        }
        accel.clear();
        match data {
            Block::Calibrated(v) if v.len() == sent => accel.extend_from_slice(&v),
            // Fixed point: m/s²·2¹⁶ as i32; exact in f32 for |a| < 256 m/s².
            Block::CalibratedFixed(v) if v.len() == sent => accel.extend(
                v.iter().map(|a| a.map(|q| (q as f64 / accelcal_shared::contract::FIXED_SCALE) as f32)),
            ),
            Block::Uncalibrated(_) => {
                return Err(HilError::Protocol("the node answered uncalibrated codes".into()))
            }
            other => {
                return Err(HilError::Protocol(format!(
                    "answer {seq} has {} sets, {sent} were sent",
                    other.len()
                )))
            }
        }
        Ok(temp)
    }
}

/// The times of a block's rows, s.
pub type TimeBlock = heapless::Vec<f64, MAX_BLOCK>;

/// What a block's rows say besides their codes.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RowsBlock {
    /// The rows' times, s.
    pub t_s: TimeBlock,
    /// The rows' temperatures (`temp_c`, as f32, the node's precision), when the campaign has
    /// them.
    pub temp_c: Option<TempBlock>,
}

/// A campaign's channels `x`, `y`, `z` as the code sets the node's ADC would deliver (every code a
/// whole number in 0..=65535), with the rows' times, a block of [`MAX_BLOCK`] rows at a time: read
/// with every check of the campaign reader (`DwellRows`), keeping one block, so that a campaign
/// of any length is replayed in bounded memory.
///
/// [`CampaignCodes::new`] reads the header and the first block, then checks the channels and the
/// code range: a file that is bad in its first rows is refused with the message every command
/// gives it, and a file whose trouble shows there is refused before any node is started.
///
/// Only `unsigned16` campaigns can be replayed: the node samples a 16-bit unsigned ADC and its
/// link carries such codes. A `signed16` campaign (a digital MEMS) is refused: shifting its
/// codes by 32768 would feed the node codes its record was not fitted on.
pub struct CampaignCodes<R: Read> {
    /// `None` once the end of the file is checked.
    rows: Option<DwellRows<R>>,
    path: PathBuf,
    /// The current row.
    row: Row,
    /// Indices of x, y, z among the channels.
    xyz: [usize; 3],
    /// File columns (1-based) of x, y, z, for error messages.
    xyz_columns: [usize; 3],
    /// The first block, read before the channels were checked.
    first: Option<(CodeBlock, RowsBlock)>,
    /// Whether the file has a `temp_c` column.
    has_temp: bool,
    warnings: Vec<String>,
}

impl CampaignCodes<Input> {
    /// Opens a campaign file, plain or gzip (see [`CampaignCodes::new`]).
    pub fn open(path: &Path) -> anyhow::Result<Self> {
        CampaignCodes::open_with(path, None)
    }

    /// [`CampaignCodes::open`] with the code range the user declared, which the file's
    /// `# codes:` line must not contradict.
    pub fn open_with(path: &Path, declared: Option<CodeRange>) -> anyhow::Result<Self> {
        CampaignCodes::from_rows(DwellRows::open(path, declared).context(READING)?, path)
    }
}

/// The context of the campaign reader's errors.
const READING: &str = "reading the campaign";

impl<R: Read> CampaignCodes<R> {
    /// Reads the header and the first block, and checks the channels; `path` names the reader in
    /// errors.
    pub fn new(reader: R, path: &Path) -> anyhow::Result<Self> {
        CampaignCodes::from_rows(DwellRows::new(reader, path, None).context(READING)?, path)
    }

    fn from_rows(rows: DwellRows<R>, path: &Path) -> anyhow::Result<Self> {
        let names = rows.channel_names();
        let columns = rows.channel_columns();
        let codes = rows.codes();
        let has_temp = rows.has_temp();
        let mut c = CampaignCodes {
            rows: Some(rows),
            path: path.to_owned(),
            row: Row::default(),
            xyz: [0; 3],
            xyz_columns: [0; 3],
            first: None,
            has_temp,
            warnings: Vec::new(),
        };
        let mut first = Vec::with_capacity(MAX_BLOCK);
        while first.len() < MAX_BLOCK && c.advance()? {
            first.push(c.row.clone());
        }
        for (k, name) in ["x", "y", "z"].into_iter().enumerate() {
            c.xyz[k] = names.iter().position(|n| n == name).ok_or_else(|| {
                bad(format!(
                    "{}: no channel `{name}` (the node replays a triad with channels x, y, z)",
                    path.display()
                ))
            })?;
            c.xyz_columns[k] = columns[c.xyz[k]];
        }
        if codes != CodeRange::Unsigned16 {
            return Err(bad(format!(
                "{}: {codes} codes cannot be replayed: the node samples a 16-bit unsigned ADC and its link carries unsigned16 codes",
                path.display()
            )));
        }
        let mut block = c.empty_block();
        for row in first {
            c.row = row;
            c.push_row(&mut block)?;
        }
        c.first = Some(block);
        Ok(c)
    }

    /// Reads the next row into `self.row`; `false` at the end of the file, which is then checked.
    fn advance(&mut self) -> anyhow::Result<bool> {
        let Some(rows) = self.rows.as_mut() else { return Ok(false) };
        match rows.next_row().context(READING)? {
            Some((_, row)) => {
                self.row.clone_from(row);
                Ok(true)
            }
            None => {
                self.warnings = self.rows.take().expect("not at the end").finish().context(READING)?;
                Ok(false)
            }
        }
    }

    /// Whether the campaign has a `temp_c` column.
    pub fn has_temp(&self) -> bool {
        self.has_temp
    }

    fn empty_block(&self) -> (CodeBlock, RowsBlock) {
        (CodeBlock::new(), RowsBlock { t_s: TimeBlock::new(), temp_c: self.has_temp.then(TempBlock::new) })
    }

    /// Adds the current row to `block`, checking its codes.
    fn push_row(&mut self, (codes, rows): &mut (CodeBlock, RowsBlock)) -> anyhow::Result<()> {
        let mut set = [0u16; 3];
        for (k, (&col, name)) in self.xyz.iter().zip(["x", "y", "z"]).enumerate() {
            let v = self.row.codes[col];
            let (lo, hi) = CodeRange::Unsigned16.rails();
            if !(lo..=hi).contains(&v) || v.fract() != 0.0 {
                return Err(bad(format!(
                    "{}:{}:{}: channel {name}: code {v} is not a whole number in 0..=65535 (simulate without --ideal-adc)",
                    self.path.display(),
                    self.row.line,
                    self.xyz_columns[k],
                )));
            }
            set[k] = v as u16;
        }
        // All have room: blocks are filled to MAX_BLOCK and no further.
        let _ = codes.push(set);
        let _ = rows.t_s.push(self.row.t);
        if let Some(t) = rows.temp_c.as_mut() {
            // The campaign reader gives every row of a file with `temp_c` its value.
            let _ = t.push(self.row.temp.map_or(f32::NAN, |v| v as f32));
        }
        Ok(())
    }

    /// The next block of code sets and their times; `None` after the last.
    fn next_block(&mut self) -> anyhow::Result<Option<(CodeBlock, RowsBlock)>> {
        if let Some(first) = self.first.take() {
            return Ok((!first.0.is_empty()).then_some(first));
        }
        let mut block = self.empty_block();
        while !block.0.is_full() && self.advance()? {
            self.push_row(&mut block)?;
        }
        Ok((!block.0.is_empty()).then_some(block))
    }

    /// The campaign reader's warnings (excluded samples, single-sample dwells), once the last
    /// block has been read.
    pub fn warnings(&self) -> &[String] {
        &self.warnings
    }
}

impl<R: Read> Iterator for CampaignCodes<R> {
    type Item = anyhow::Result<(CodeBlock, RowsBlock)>;

    fn next(&mut self) -> Option<Self::Item> {
        self.next_block().transpose()
    }
}

/// The header of the CSV that `accelcal hil` writes.
pub const CSV_HEADER: &str = "t_s,ax,ay,az";
/// The header of the CSV that `accelcal hil` writes for a record with thermal terms: each row
/// also carries its block's [`BlockTemp`], the filtered temperature the calibration was evaluated
/// at (°C) and whether a set of the block was calibrated outside the record's range (0 or 1).
pub const CSV_HEADER_THERMAL: &str = "t_s,ax,ay,az,applied_c,out_of_range";

/// Writes the node's answers for rows at times `t_s` as CSV rows `t_s,ax,ay,az` (m/s²; f32
/// values printed exactly) under [`CSV_HEADER`], with the block's `applied_c,out_of_range`
/// (empty when the node reported none) when `temp` is given (under [`CSV_HEADER_THERMAL`]).
pub fn write_rows(
    w: &mut impl Write,
    t_s: &[f64],
    accel: &[[f32; 3]],
    temp: Option<Option<BlockTemp>>,
) -> std::io::Result<()> {
    let tail = match temp {
        None => String::new(),
        Some(None) => ",,".into(),
        Some(Some(b)) => format!(
            ",{},{}",
            b.applied_c.map(|v| v.to_string()).unwrap_or_default(),
            u8::from(b.out_of_range)
        ),
    };
    for (t, a) in t_s.iter().zip(accel) {
        writeln!(w, "{t},{},{},{}{tail}", a[0], a[1], a[2])?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use accelcal_core::campaign::Campaign;

    fn blocks(text: &str) -> anyhow::Result<Vec<(CodeBlock, RowsBlock)>> {
        CampaignCodes::new(text.as_bytes(), Path::new("c.csv"))?.collect()
    }

    /// A triad campaign of `n` rows over two dwells, with a saturated row.
    fn triad(n: usize) -> String {
        let mut s = String::from("t_s,alpha_deg,beta_deg,temp_c,x,z,y\n");
        for i in 0..n {
            let x = if i == 7 { 65535 } else { 30000 + i };
            s += &format!("{},{},0,25,{x},{},{}\n", i as f64 * 0.1, 90 * (i / 20), 31000 + 2 * i, 32000 + i);
        }
        s
    }

    #[test]
    fn blocks_hold_the_rows_the_campaign_reader_keeps() {
        let text = triad(45);
        let c = Campaign::from_reader(text.as_bytes(), Path::new("c.csv")).unwrap();
        let mut codes = CampaignCodes::new(text.as_bytes(), Path::new("c.csv")).unwrap();
        let got: Vec<_> = codes.by_ref().collect::<anyhow::Result<_>>().unwrap();
        assert_eq!(got.iter().map(|(c, _)| c.len()).collect::<Vec<_>>(), vec![16, 16, 12]);
        let t: Vec<f64> = got.iter().flat_map(|(_, r)| r.t_s.clone()).collect();
        let temp: Vec<f32> = got.iter().flat_map(|(_, r)| r.temp_c.clone().unwrap()).collect();
        assert_eq!(temp, vec![25.0; t.len()]);
        assert!(codes.has_temp());
        let sets: Vec<Codes> = got.iter().flat_map(|(c, _)| c.clone()).collect();
        assert_eq!(t, c.t_s);
        let ch = |n: &str| &c.channels[c.channel(n).unwrap()].codes;
        for (i, set) in sets.iter().enumerate() {
            assert_eq!(set.map(f64::from), [ch("x")[i], ch("y")[i], ch("z")[i]], "row {i}");
        }
        assert_eq!(codes.warnings(), c.warnings);
        assert_eq!(codes.warnings().len(), 1);
    }

    #[test]
    fn gzip_campaigns_give_the_same_blocks_and_signed_ones_are_refused() {
        use std::io::Write as _;
        let dir = tempfile::tempdir().unwrap();
        let (plain, gz) = (dir.path().join("c.csv"), dir.path().join("c.csv.gz"));
        let text = triad(45);
        std::fs::write(&plain, &text).unwrap();
        let mut enc = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
        enc.write_all(text.as_bytes()).unwrap();
        std::fs::write(&gz, enc.finish().unwrap()).unwrap();
        let read = |p: &Path| -> Vec<(CodeBlock, RowsBlock)> {
            CampaignCodes::open(p).unwrap().collect::<anyhow::Result<_>>().unwrap()
        };
        assert_eq!(read(&gz), read(&plain));
        let e = CampaignCodes::open_with(&plain, Some(CodeRange::Signed16)).err().unwrap();
        assert!(e.is::<accelcal_core::error::BadInput>(), "{e:?}");
        assert!(e.to_string().contains("signed16 codes cannot be replayed"), "{e}");
        std::fs::write(&plain, format!("# codes: signed16\n{text}")).unwrap();
        let e = CampaignCodes::open(&plain).err().unwrap();
        assert!(e.to_string().contains("signed16 codes cannot be replayed"), "{e}");
    }

    #[test]
    fn rows_are_checked_as_they_are_read() {
        // In the first block: the file is refused when opened, before the channels are checked.
        let e = CampaignCodes::new(
            "t_s,alpha_deg,beta_deg,x\n0,0,0,1\n1,0,zero,2\n".as_bytes(),
            Path::new("c.csv"),
        );
        assert_eq!(
            format!("{:#}", e.err().unwrap()),
            "reading the campaign: c.csv:3:3: expected a number in `beta_deg`, found `zero`"
        );
        let e = CampaignCodes::new("t_s,alpha_deg,beta_deg,x,y\n0,0,0,1,2\n".as_bytes(), Path::new("c.csv"));
        // Without `temp_c` the blocks carry no temperatures.
        let plain = blocks("t_s,alpha_deg,beta_deg,x,y,z\n0,0,0,1,2,3\n0.1,0,0,1,2,3\n").unwrap();
        assert_eq!(plain[0].1.temp_c, None);
        assert!(format!("{}", e.err().unwrap()).starts_with("c.csv: no channel `z`"));
        // After the first block: the blocks before it come first.
        let mut bad = triad(40);
        bad += "4,90,0,25,30000,31000,oops\n";
        let mut codes = CampaignCodes::new(bad.as_bytes(), Path::new("c.csv")).unwrap();
        assert!(codes.next().unwrap().is_ok());
        assert!(codes.next().unwrap().is_ok());
        let e = codes.next().unwrap().unwrap_err();
        assert_eq!(
            format!("{e:#}"),
            "reading the campaign: c.csv:42:7: expected a number in `y`, found `oops`"
        );
        let mut frac = triad(40);
        frac += "4,90,0,25,30000.5,31000,32000\n";
        let e = blocks(&frac).unwrap_err();
        assert!(e.is::<accelcal_core::error::BadInput>(), "{e:?}");
        assert_eq!(
            e.to_string(),
            "c.csv:42:5: channel x: code 30000.5 is not a whole number in 0..=65535 (simulate without --ideal-adc)"
        );
    }
}
