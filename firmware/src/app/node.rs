//! The node's async loops: serving host requests, streaming live samples, reporting status and
//! sending frames. Each runs forever in its own task and talks to the others through [`OUTBOX`].

use core::sync::atomic::{AtomicU32, Ordering};

use accelcal_shared::wire::{
    self, Codes, FrameDecoder, FrameError, HostMsg, NodeMsg, RecordStatus, Status, MAX_BLOCK, MAX_FRAME,
    PROTOCOL_VERSION,
};
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::channel::Channel;
use embassy_time::{Duration, Timer};

use super::calib::Calibration;
use super::ports::{LinkRx, LinkTx, SampleSource};

/// Messages waiting for the link transmitter.
pub static OUTBOX: Channel<CriticalSectionRawMutex, NodeMsg, 4> = Channel::new();

/// Counters reported in [`Status`].
pub struct Stats {
    /// Sample sets lost (acquisition overruns and blocks dropped because the link was busy).
    pub overruns: AtomicU32,
    /// Sample sets acquired.
    pub sample_sets: AtomicU32,
    /// Host frames that did not decode.
    pub bad_frames: AtomicU32,
}

/// The node's counters since boot.
pub static STATS: Stats =
    Stats { overruns: AtomicU32::new(0), sample_sets: AtomicU32::new(0), bad_frames: AtomicU32::new(0) };

/// Interval of the unsolicited status reports.
pub const STATUS_PERIOD: Duration = Duration::from_secs(1);

/// What every task needs to know about the node: its calibration and configuration.
#[derive(Clone, Copy, Debug)]
pub struct Node {
    /// The calibration applied to every sample set.
    pub cal: Calibration,
    /// What the status reports about the record.
    pub record: RecordStatus,
    /// Live sampling rate per channel, Hz (0 when samples only arrive over the link).
    pub rate_hz: u32,
}

impl Node {
    /// The current status report.
    pub fn status(&self) -> Status {
        Status {
            protocol: PROTOCOL_VERSION,
            record: self.record,
            overruns: STATS.overruns.load(Ordering::Relaxed),
            sample_sets: STATS.sample_sets.load(Ordering::Relaxed),
            rate_hz: self.rate_hz,
            bad_frames: STATS.bad_frames.load(Ordering::Relaxed),
        }
    }

    async fn handle(&self, msg: Result<HostMsg, FrameError>) {
        match msg {
            Ok(HostMsg::GetStatus) => OUTBOX.send(NodeMsg::Status(self.status())).await,
            Ok(HostMsg::Replay { seq, codes }) => {
                let data = self.cal.apply_block(&codes);
                OUTBOX.send(NodeMsg::Replayed { seq, data }).await;
            }
            Err(e) => {
                STATS.bad_frames.fetch_add(1, Ordering::Relaxed);
                defmt::warn!("bad host frame: {}", defmt::Display2Format(&e));
            }
        }
    }
}

/// Decodes host frames from `rx` and answers them, forever.
pub async fn serve_link(mut rx: impl LinkRx, node: Node) -> ! {
    let mut decoder = FrameDecoder::<MAX_FRAME>::new();
    let mut buf = [0u8; 32];
    loop {
        let n = rx.read(&mut buf).await;
        for &b in &buf[..n] {
            let mut got = None;
            decoder.push(&[b], |m| got = Some(m));
            if let Some(m) = got {
                node.handle(m).await;
            }
        }
    }
}

/// Encodes and sends every message put into [`OUTBOX`], forever.
pub async fn transmit(mut tx: impl LinkTx) -> ! {
    let mut buf = [0u8; MAX_FRAME];
    loop {
        let msg = OUTBOX.receive().await;
        match wire::encode(&msg, &mut buf) {
            Ok(frame) => tx.write_all(frame).await,
            // Unreachable with the message sizes of `wire` (tested there); never send a partial frame.
            Err(e) => defmt::error!("frame encode failed: {}", defmt::Display2Format(&e)),
        }
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

/// Reads live sample sets, calibrates them and queues them for the link, forever. Sets that the
/// source lost, or that the link could not take in time, are counted as overruns.
pub async fn stream_samples(mut source: impl SampleSource, node: Node) -> ! {
    let mut codes: [Codes; MAX_BLOCK] = [[0; 3]; MAX_BLOCK];
    let mut seq: u32 = 0;
    loop {
        match source.read_block(&mut codes).await {
            Ok(n) => {
                STATS.sample_sets.fetch_add(n as u32, Ordering::Relaxed);
                let data = node.cal.apply_block(&codes[..n]);
                if OUTBOX.try_send(NodeMsg::Samples { seq, data }).is_err() {
                    STATS.overruns.fetch_add(n as u32, Ordering::Relaxed);
                }
                seq = seq.wrapping_add(1);
            }
            Err(o) => {
                STATS.overruns.fetch_add(o.lost, Ordering::Relaxed);
                defmt::warn!("sampling overrun: {=u32} sample sets lost", o.lost);
            }
        }
    }
}
