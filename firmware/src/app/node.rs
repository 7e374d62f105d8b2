//! The node's async loops: serving host requests, streaming live samples, reporting status and
//! sending frames. Each runs forever in its own task and talks to the others through [`OUTBOX`].

use core::sync::atomic::{AtomicBool, AtomicU32, Ordering};

use accelcal_shared::wire::{
    self, Codes, FrameDecoder, FrameError, HostMsg, NodeMsg, RecordStatus, ResetCause, Status, MAX_BLOCK,
    MAX_FRAME, PROTOCOL_VERSION,
};
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::channel::Channel;
use embassy_time::{Duration, Timer};

use super::calib::Calibration;
use super::ports::{LinkRx, LinkTx, SampleClock, SampleSource};

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
    /// Sampling rate per channel in force, Hz (changed by [`HostMsg::SetRate`]).
    pub rate_hz: AtomicU32,
    /// The last read-back of the sampling trigger configuration did not match.
    pub trigger_mismatch: AtomicBool,
}

/// The node's counters since boot, and the state that [`HostMsg::SetRate`] changes.
pub static STATS: Stats = Stats {
    overruns: AtomicU32::new(0),
    sample_sets: AtomicU32::new(0),
    bad_frames: AtomicU32::new(0),
    rate_hz: AtomicU32::new(0),
    trigger_mismatch: AtomicBool::new(false),
};

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
}

impl Node {
    /// The node's state at boot: records the sampling clock's rate and reads its trigger
    /// configuration back (a mismatch is logged and flagged in every status).
    pub fn new(
        cal: Calibration,
        record: RecordStatus,
        reset_cause: ResetCause,
        clock: &impl SampleClock,
    ) -> Node {
        defmt::info!("last reset: {}", defmt::Display2Format(&reset_cause));
        STATS.rate_hz.store(clock.rate_hz(), Ordering::Relaxed);
        note_trigger_check(clock.trigger_ok());
        Node { cal, record, reset_cause }
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
        }
    }

    async fn handle(&self, msg: Result<HostMsg, FrameError>, clock: &mut impl SampleClock) {
        match msg {
            Ok(HostMsg::GetStatus) => OUTBOX.send(NodeMsg::Status(self.status())).await,
            Ok(HostMsg::Replay { seq, codes }) => {
                let data = self.cal.apply_block(&codes);
                OUTBOX.send(NodeMsg::Replayed { seq, data }).await;
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
                    defmt::warn!("request refused: {}", defmt::Display2Format(&refusal));
                    OUTBOX.send(NodeMsg::Refused(refusal)).await;
                }
            },
            Err(e) => {
                STATS.bad_frames.fetch_add(1, Ordering::Relaxed);
                defmt::warn!("bad host frame: {}", defmt::Display2Format(&e));
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
    loop {
        let n = rx.read(&mut buf).await;
        for &b in &buf[..n] {
            let mut got = None;
            decoder.push(&[b], |m| got = Some(m));
            if let Some(m) = got {
                node.handle(m, &mut clock).await;
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
