//! The node's async loops: serving host requests, streaming live samples, reporting status and
//! sending frames. Each runs forever in its own task and talks to the others through [`OUTBOX`].
//!
//! Live samples leave the node as [`NodeMsg::Samples`] blocks whose `first` is the node's sample
//! counter: it counts every set the sampler produced since boot, the ones the source lost
//! ([`Overrun`](super::ports::Overrun)) and the ones in blocks the [`OUTBOX`] could not take
//! included, so a jump of `first` between consecutive blocks equals the sets counted in
//! [`Stats::overruns`] meanwhile. [`HostMsg::SetOutput`] switches the stream between calibrated
//! blocks and [`Block::Raw`] codes.
//!
//! Every live block carries its temperature ([`BlockTemp`]): both boards read one (the QEMU board
//! the front end's channel with each set, the real board the MCU's sensor once per block). With
//! a thermal record the live stream keeps one tracker for its life, fed every set's temperature
//! in order (in raw output too); the replay path keeps another, restarted by the host
//! ([`accelcal_shared::wire::ReplayTemp`]), so that a replay is reproducible on the host.

use core::sync::atomic::{AtomicBool, AtomicU32, Ordering};

use accelcal_shared::wire::{
    self, Block, BlockTemp, Codes, FrameDecoder, FrameError, HostMsg, Info, NodeMsg, Output, RecordStatus,
    ResetCause, Status, MAX_BLOCK, MAX_FRAME, PROTOCOL_VERSION,
};
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::channel::Channel;
use embassy_time::{Duration, Timer};
use heapless::Vec;

use super::calib::{Applier, Calibration};
use super::ports::{LinkRx, LinkTx, SampleClock, SampleSource};
use super::progress::{self, SAMPLED, SENT};

/// Messages waiting for the link transmitter.
pub static OUTBOX: Channel<CriticalSectionRawMutex, NodeMsg, OUTBOX_DEPTH> = Channel::new();
/// How many messages [`OUTBOX`] holds.
const OUTBOX_DEPTH: usize = 4;
/// Of them, the slots the live stream leaves free, for answers and status reports. Those wait
/// for room (`send`), where a live block that finds no room is dropped and counted
/// (`try_send`). Without the reserve, when the link is slower than the stream the woken waiter
/// races the sampler for each slot the transmitter frees, and an answer can lose every race
/// (the host gives up on it); with it, an answer waits behind at most `OUTBOX_DEPTH - 1`
/// frames however saturated the link.
const RESERVED_FOR_ANSWERS: usize = 1;

/// Counters reported in [`Status`].
pub struct Stats {
    /// Sample sets lost (acquisition overruns and blocks dropped because the link was busy).
    pub overruns: AtomicU32,
    /// Sample sets acquired.
    pub sample_sets: AtomicU32,
    /// Host frames that did not decode.
    pub bad_frames: AtomicU32,
    /// Sampling rate per channel in force, Hz (changed by [`HostMsg::SetRate`]).
    pub rate_hz: AtomicU32,
    /// The last read-back of the sampling trigger configuration did not match.
    pub trigger_mismatch: AtomicBool,
    /// Live samples leave as raw codes ([`Output::Raw`]) instead of calibrated
    /// ([`Output::Calibrated`], the mode at boot); changed by [`HostMsg::SetOutput`].
    pub raw_output: AtomicBool,
}

/// The node's counters since boot, and the state that [`HostMsg::SetRate`] changes.
pub static STATS: Stats = Stats {
    overruns: AtomicU32::new(0),
    sample_sets: AtomicU32::new(0),
    bad_frames: AtomicU32::new(0),
    rate_hz: AtomicU32::new(0),
    trigger_mismatch: AtomicBool::new(false),
    raw_output: AtomicBool::new(false),
};

impl Stats {
    /// What the node streams now.
    pub fn output(&self) -> Output {
        if self.raw_output.load(Ordering::Relaxed) {
            Output::Raw
        } else {
            Output::Calibrated
        }
    }
}

/// The firmware's version, major, minor, patch: this crate's Cargo package version, parsed at
/// compile time.
pub const FIRMWARE_VERSION: [u16; 3] = [
    parse_u16(env!("CARGO_PKG_VERSION_MAJOR")),
    parse_u16(env!("CARGO_PKG_VERSION_MINOR")),
    parse_u16(env!("CARGO_PKG_VERSION_PATCH")),
];

/// A decimal number of at most 65535, in a const context (a bad version fails the build).
const fn parse_u16(s: &str) -> u16 {
    let b = s.as_bytes();
    assert!(!b.is_empty(), "empty version number");
    let mut v: u32 = 0;
    let mut i = 0;
    while i < b.len() {
        assert!(b[i].is_ascii_digit(), "version number is not decimal");
        v = v * 10 + (b[i] - b'0') as u32;
        assert!(v <= u16::MAX as u32, "version number above 65535");
        i += 1;
    }
    v as u16
}

/// Interval of the unsolicited status reports.
pub const STATUS_PERIOD: Duration = Duration::from_secs(1);

/// What every task needs to know about the node: its calibration and what it found at boot.
#[derive(Clone, Copy, Debug)]
pub struct Node {
    /// The calibration applied to every sample set.
    pub cal: Calibration,
    /// What the status reports about the record.
    pub record: RecordStatus,
    /// Why the node last reset.
    pub reset_cause: ResetCause,
    /// The id a record must carry (the MCU's unique id; the QEMU board's fixed id).
    pub device_id: [u8; 12],
}

impl Node {
    /// The node's state at boot: records the sampling clock's rate and reads its trigger
    /// configuration back (a mismatch is logged and flagged in every status).
    pub fn new(
        cal: Calibration,
        record: RecordStatus,
        reset_cause: ResetCause,
        device_id: [u8; 12],
        clock: &impl SampleClock,
    ) -> Node {
        defmt::info!("last reset: {}", reset_cause);
        STATS.rate_hz.store(clock.rate_hz(), Ordering::Relaxed);
        note_trigger_check(clock.trigger_ok());
        Node { cal, record, reset_cause, device_id }
    }

    /// Who the node is ([`HostMsg::GetInfo`]).
    pub fn info(&self) -> Info {
        Info {
            device_id: self.device_id,
            firmware: FIRMWARE_VERSION,
            protocol: PROTOCOL_VERSION,
            record: self.record,
            rate_hz: STATS.rate_hz.load(Ordering::Relaxed),
            overruns: STATS.overruns.load(Ordering::Relaxed),
            reset_cause: self.reset_cause,
            output: STATS.output(),
        }
    }

    /// The current status report.
    pub fn status(&self) -> Status {
        Status {
            protocol: PROTOCOL_VERSION,
            record: self.record,
            overruns: STATS.overruns.load(Ordering::Relaxed),
            sample_sets: STATS.sample_sets.load(Ordering::Relaxed),
            rate_hz: STATS.rate_hz.load(Ordering::Relaxed),
            bad_frames: STATS.bad_frames.load(Ordering::Relaxed),
            reset_cause: self.reset_cause,
            trigger_mismatch: STATS.trigger_mismatch.load(Ordering::Relaxed),
            output: STATS.output(),
        }
    }

    /// The output block of a live block of `codes` with their temperatures `temp_c`, in the
    /// output mode now in force, calibrated by the live stream's `applier`, and the block's
    /// temperature report. In raw output a thermal record's tracker is still fed the
    /// temperatures, so its filter is current when calibrated output resumes.
    fn live_block(applier: &mut Applier, codes: &[Codes], temp_c: &[f32]) -> (Block, Option<BlockTemp>) {
        match STATS.output() {
            Output::Calibrated => applier.apply_block(codes, temp_c),
            Output::Raw => {
                let n = codes.len().min(temp_c.len()).min(MAX_BLOCK);
                (Block::Raw(Vec::from_slice(&codes[..n]).unwrap_or_default()), applier.track(&temp_c[..n]))
            }
        }
    }

    /// Answers one host frame. `replay` is the replay path's applier: a thermal record's tracker
    /// of the current replay run, started afresh by a request with temperatures and `restart`
    /// (or the first with temperatures).
    async fn handle(
        &self,
        msg: Result<HostMsg, FrameError>,
        clock: &mut impl SampleClock,
        replay: &mut Option<Applier>,
    ) {
        match msg {
            Ok(HostMsg::GetStatus) => OUTBOX.send(NodeMsg::Status(self.status())).await,
            Ok(HostMsg::Replay { seq, codes, temp: None }) => {
                let data = self.cal.apply_block(&codes);
                OUTBOX.send(NodeMsg::Replayed { seq, data, temp: None }).await;
            }
            Ok(HostMsg::Replay { seq, codes, temp: Some(t) }) => {
                if t.restart {
                    *replay = None;
                }
                let applier = replay.get_or_insert_with(|| self.cal.applier());
                let (data, temp) = applier.apply_block(&codes, &t.temp_c);
                OUTBOX.send(NodeMsg::Replayed { seq, data, temp }).await;
            }
            Ok(HostMsg::GetInfo) => OUTBOX.send(NodeMsg::Info(self.info())).await,
            Ok(HostMsg::SetOutput(output)) => {
                STATS.raw_output.store(output == Output::Raw, Ordering::Relaxed);
                defmt::info!("live output set to {=str}", output.name());
                OUTBOX.send(NodeMsg::OutputSet(self.status())).await;
            }
            Ok(HostMsg::SetRate { hz }) => match wire::check_rate(hz) {
                Ok(()) => {
                    let ok = clock.set_rate(hz);
                    STATS.rate_hz.store(clock.rate_hz(), Ordering::Relaxed);
                    note_trigger_check(ok);
                    defmt::info!("sampling rate set to {=u32} Hz", hz);
                    OUTBOX.send(NodeMsg::RateSet(self.status())).await;
                }
                Err(refusal) => {
                    defmt::warn!("request refused: {}", refusal);
                    OUTBOX.send(NodeMsg::Refused(refusal)).await;
                }
            },
            Err(e) => {
                STATS.bad_frames.fetch_add(1, Ordering::Relaxed);
                defmt::warn!("bad host frame: {}", e);
            }
        }
    }
}

/// Records the result of a read-back of the trigger configuration for the status, and logs a
/// mismatch.
fn note_trigger_check(ok: bool) {
    if !ok {
        defmt::error!("ADC trigger configuration does not read back as programmed: flagged in the status");
    }
    STATS.trigger_mismatch.store(!ok, Ordering::Relaxed);
}

/// Decodes host frames from `rx` and answers them (changing the sampling rate through `clock`),
/// forever.
pub async fn serve_link(mut rx: impl LinkRx, mut clock: impl SampleClock, node: Node) -> ! {
    let mut decoder = FrameDecoder::<MAX_FRAME>::new();
    let mut buf = [0u8; 32];
    let mut replay = None;
    loop {
        let n = rx.read(&mut buf).await;
        for &b in &buf[..n] {
            let mut got = None;
            decoder.push(&[b], |m| got = Some(m));
            if let Some(m) = got {
                node.handle(m, &mut clock, &mut replay).await;
            }
        }
    }
}

/// Encodes and sends every message put into [`OUTBOX`], forever.
pub async fn transmit(mut tx: impl LinkTx) -> ! {
    let mut buf = [0u8; MAX_FRAME];
    loop {
        let msg = OUTBOX.receive().await;
        // A zero in front of each frame: a host that opens its port while a frame is on the line
        // drops the bytes up to the first zero, so it never loses more than that frame's tail.
        match wire::encode_sync(&msg, &mut buf) {
            Ok(frame) => tx.write_all(frame).await,
            // Unreachable with the message sizes of `wire` (tested there); never send a partial frame.
            Err(e) => defmt::error!("frame encode failed: {}", e),
        }
        progress::bump(&SENT);
    }
}

/// Announces the node with a status report at boot (the link is up by then, so a host that
/// waits for it never talks to a receiver that is not yet listening), then reports every
/// [`STATUS_PERIOD`], forever.
pub async fn report_status(node: Node) -> ! {
    loop {
        OUTBOX.send(NodeMsg::Status(node.status())).await;
        Timer::after(STATUS_PERIOD).await;
    }
}

/// Reads live sample sets, calibrates them (or not, in [`Output::Raw`]) and queues them for the
/// link, forever. Sets that the source lost, or that the link could not take in time, are counted
/// as overruns and advance the sample counter (`first`) all the same.
pub async fn stream_samples(mut source: impl SampleSource, node: Node) -> ! {
    let mut codes: [Codes; MAX_BLOCK] = [[0; 3]; MAX_BLOCK];
    let mut temp_c = [0.0f32; MAX_BLOCK];
    let mut applier = node.cal.applier();
    let mut seq: u32 = 0;
    // The node's sample counter: the number of the next set the sampler produces.
    let mut next: u32 = 0;
    loop {
        let block = source.read_block(&mut codes, &mut temp_c).await;
        progress::bump(&SAMPLED);
        match block {
            Ok(n) => {
                let first = next;
                next = next.wrapping_add(n as u32);
                STATS.sample_sets.fetch_add(n as u32, Ordering::Relaxed);
                let (data, temp) = Node::live_block(&mut applier, &codes[..n], &temp_c[..n]);
                let room = OUTBOX.free_capacity() > RESERVED_FOR_ANSWERS;
                if !room || OUTBOX.try_send(NodeMsg::Samples { seq, first, data, temp }).is_err() {
                    STATS.overruns.fetch_add(n as u32, Ordering::Relaxed);
                }
                seq = seq.wrapping_add(1);
            }
            Err(o) => {
                next = next.wrapping_add(o.lost);
                STATS.overruns.fetch_add(o.lost, Ordering::Relaxed);
                defmt::warn!("sampling overrun: {=u32} sample sets lost", o.lost);
            }
        }
    }
}
