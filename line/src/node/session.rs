//! A conversation with a running node over its link (a serial port: the real board's ST-LINK
//! virtual COM port, or the pty of `accelcal emulate`): who it is ([`HostMsg::GetInfo`]), its
//! output mode and sampling rate, and its live sample blocks. Used by `info`, `acquire` and the
//! commands after them.
//!
//! The node sends status reports every second and live blocks all the time; a request's answer is
//! found among them by its kind. Every wait is bounded by the session's `answer` timeout, an
//! absolute deadline checked on every read whatever the node sends (bytes that make no frame, bad
//! frames, other messages), so a node that does not answer is an error that says what came
//! instead and what to check, never a hang.

use std::io::{self, Read, Write};
use std::time::{Duration, Instant};

use accelcal_shared::wire::{self, Block, HostMsg, Info, NodeMsg, Output, Status};

use super::link::{self, LinkError, Receiver, Traffic};
use accelcal_core::error::{Classify, Kind};

/// Why a conversation with the node failed (a failure of the environment: exit code 1).
#[derive(Debug, thiserror::Error)]
pub enum SessionError {
    /// The port could not be opened.
    #[error("{port}: cannot open the node's serial port: {cause}")]
    Open {
        /// The port.
        port: String,
        /// The cause.
        cause: serialport::Error,
    },
    /// The link failed.
    #[error("{port}: {cause}")]
    Link {
        /// The port.
        port: String,
        /// The cause.
        cause: LinkError,
    },
    /// No answer in time: what was awaited, for how long, and what the node sent meanwhile.
    #[error("{port}: no {what} from the node within {secs} s: {heard}")]
    Timeout {
        /// The port.
        port: String,
        /// What was awaited.
        what: &'static str,
        /// The timeout, s.
        secs: f64,
        /// What the link delivered during the wait.
        heard: Traffic,
    },
    /// The node refused a request.
    #[error("{port}: the node refused the request: {refusal}")]
    Refused {
        /// The port.
        port: String,
        /// Its reason.
        refusal: wire::Refusal,
    },
    /// The node speaks another protocol version.
    #[error("{port}: the node speaks link protocol {node}, this tool {host}: flash a matching firmware")]
    Protocol {
        /// The port.
        port: String,
        /// The node's version.
        node: u8,
        /// This tool's.
        host: u8,
    },
}

impl Classify for SessionError {
    fn kind(&self) -> Kind {
        Kind::Environment
    }
}

/// How often a blocking read gives control back (to check a stop flag or a deadline): the serial
/// port's read timeout, and the longest [`Session::poll`] waits.
pub const POLL: Duration = Duration::from_millis(100);
/// How long a request waits for its answer before it is sent again.
const RESEND: Duration = Duration::from_millis(1000);

/// An open link to a node.
pub struct Session {
    port: String,
    tx: Box<dyn Write + Send>,
    rx: Receiver<Box<dyn Read + Send>>,
    answer: Duration,
}

/// A bounded wait: what it awaits, when it ends, and the link's traffic when it began.
struct Wait {
    what: &'static str,
    deadline: Instant,
    heard: Traffic,
}

/// A wait for live sample blocks ([`Session::block_wait`]).
pub struct BlockWait(Wait);

/// A block of live samples: the node's sample counter of its first set, and the sets.
#[derive(Clone, Debug, PartialEq)]
pub struct Samples {
    /// Block number since boot.
    pub seq: u32,
    /// Sample counter of the first set (lost sets included).
    pub first: u32,
    /// The sets.
    pub data: Block,
    /// The block's temperature, when the node reads one.
    pub temp: Option<wire::BlockTemp>,
}

impl Session {
    /// Opens the serial port `port` at `baud` (a pty ignores the baud rate); requests wait up to
    /// `answer` for their reply.
    pub fn open(port: &str, baud: u32, answer: Duration) -> Result<Session, SessionError> {
        let open = |cause| SessionError::Open { port: port.to_string(), cause };
        let p = super::port::open(port, baud, POLL, super::port::LOCK_WAIT).map_err(open)?;
        let tx = p.try_clone().map_err(open)?;
        Ok(Session::from_streams(port, Box::new(tx), Box::new(p), answer))
    }

    /// A session over any pair of byte streams (tests); reads must time out every [`POLL`] or so.
    ///
    /// The stream is taken as joined mid-frame ([`Receiver::mid_stream`]), as every port is: the
    /// node was sending before the port was opened, and the emulator's terminal hands over the
    /// node's bytes from wherever they are when a program opens it. The tail of a frame, read as a
    /// frame, can decode to another message; the first bad frame once did, as a refusal.
    pub fn from_streams(
        port: &str,
        tx: Box<dyn Write + Send>,
        rx: Box<dyn Read + Send>,
        answer: Duration,
    ) -> Session {
        Session { port: port.to_string(), tx, rx: Receiver::mid_stream(rx), answer }
    }

    /// The receiving half, with whatever it has read past the last answer: a reader that goes on
    /// from here misses nothing the node sent.
    pub fn into_receiver(self) -> Receiver<Box<dyn Read + Send>> {
        self.rx
    }

    /// The port's name, for messages.
    pub fn port(&self) -> &str {
        &self.port
    }

    fn link(&self, cause: LinkError) -> SessionError {
        SessionError::Link { port: self.port.clone(), cause }
    }

    /// Sends a request.
    pub fn send(&mut self, msg: &HostMsg) -> Result<(), SessionError> {
        link::send(&mut self.tx, msg).map_err(|e| self.link(e))
    }

    /// The next message, or `None` when none arrived within the poll interval ([`POLL`], or less
    /// up to `until`), however many bytes came. Frames that do not decode are skipped (the
    /// node's stream resynchronises at the next frame). A read cut by a signal (EINTR: the
    /// serial port waits in `ppoll`, which a signal always interrupts, e.g. the Ctrl-C that sets
    /// a caller's stop flag) is `None` too: the caller checks its flag and polls again, and the
    /// receiver keeps the bytes it already had.
    fn poll_until(&mut self, until: Instant) -> Result<Option<NodeMsg>, SessionError> {
        match self.rx.recv(until.min(Instant::now() + POLL)) {
            Ok(Ok(m)) => Ok(Some(m)),
            Ok(Err(_)) | Err(LinkError::Deadline) => Ok(None),
            Err(LinkError::Io(e)) if e.kind() == io::ErrorKind::Interrupted => Ok(None),
            Err(e) => Err(self.link(e)),
        }
    }

    /// The next message, or `None` when none arrived within [`POLL`] (see `poll_until`).
    pub fn poll(&mut self) -> Result<Option<NodeMsg>, SessionError> {
        self.poll_until(Instant::now() + POLL)
    }

    /// A wait for `what` that ends `answer` from now.
    fn wait(&self, what: &'static str) -> Wait {
        Wait { what, deadline: Instant::now() + self.answer, heard: self.rx.traffic() }
    }

    /// The timeout error of `w`, with what the link delivered since it began.
    fn timed_out(&self, w: &Wait) -> SessionError {
        SessionError::Timeout {
            port: self.port.clone(),
            what: w.what,
            secs: self.answer.as_secs_f64(),
            heard: self.rx.traffic().since(w.heard),
        }
    }

    /// Sends `request` (when given) and waits for the first message that `pick` accepts, up to the
    /// answer timeout, sending the request again every [`RESEND`] (every request of the protocol
    /// may be repeated: a node that was not yet listening, or a pty not yet read by QEMU, loses
    /// the first copy); a refusal of a `SetRate` is an error. `what` names the awaited answer in
    /// the timeout's message.
    fn await_msg<T>(
        &mut self,
        request: Option<&HostMsg>,
        what: &'static str,
        mut pick: impl FnMut(NodeMsg) -> Option<T>,
    ) -> Result<T, SessionError> {
        let wait = self.wait(what);
        let mut next_send = Instant::now();
        while Instant::now() < wait.deadline {
            if let Some(r) = request {
                if Instant::now() >= next_send {
                    self.send(r)?;
                    next_send = Instant::now() + RESEND;
                }
            }
            match self.poll_until(wait.deadline)? {
                // Only a rate is ever refused: a refusal while waiting for another answer is not
                // this request's (the node sends none unasked) and is not taken for one.
                Some(NodeMsg::Refused(refusal)) if matches!(request, Some(HostMsg::SetRate { .. })) => {
                    return Err(SessionError::Refused { port: self.port.clone(), refusal })
                }
                Some(m) => {
                    if let Some(t) = pick(m) {
                        return Ok(t);
                    }
                }
                None => {}
            }
        }
        Err(self.timed_out(&wait))
    }

    fn check_protocol(&self, node: u8) -> Result<(), SessionError> {
        if node == wire::PROTOCOL_VERSION {
            Ok(())
        } else {
            Err(SessionError::Protocol { port: self.port.clone(), node, host: wire::PROTOCOL_VERSION })
        }
    }

    /// Who the node is.
    pub fn info(&mut self) -> Result<Info, SessionError> {
        let info = self.await_msg(Some(&HostMsg::GetInfo), "answer to GetInfo", |m| match m {
            NodeMsg::Info(i) => Some(i),
            _ => None,
        })?;
        self.check_protocol(info.protocol)?;
        Ok(info)
    }

    /// The node's status (the first status report that arrives: the answer, or a periodic report
    /// still in the port's buffer).
    pub fn status(&mut self) -> Result<Status, SessionError> {
        let s = self.await_msg(Some(&HostMsg::GetStatus), "status report", |m| match m {
            NodeMsg::Status(s) => Some(s),
            _ => None,
        })?;
        self.check_protocol(s.protocol)?;
        Ok(s)
    }

    /// Switches live streaming to `output`; returns the node's status after the switch.
    pub fn set_output(&mut self, output: Output) -> Result<Status, SessionError> {
        self.await_msg(Some(&HostMsg::SetOutput(output)), "answer to SetOutput", |m| match m {
            NodeMsg::OutputSet(s) => Some(s),
            _ => None,
        })
    }

    /// Sets the sampling rate, Hz; returns the node's status after the change.
    pub fn set_rate(&mut self, hz: u32) -> Result<Status, SessionError> {
        self.await_msg(Some(&HostMsg::SetRate { hz }), "answer to SetRate", |m| match m {
            NodeMsg::RateSet(s) => Some(s),
            _ => None,
        })
    }

    /// Starts a wait for live sample blocks ([`Session::poll_samples`]): each block must come
    /// within the answer timeout of the wait's start or of the block before it.
    pub fn block_wait(&self) -> BlockWait {
        BlockWait(self.wait("live sample block"))
    }

    /// The next message if it is a block of live samples; `None` when nothing arrived within the
    /// poll interval or the message was another one (a caller loops, checking its own deadline
    /// too). A block restarts `wait`; once it has passed without one, whatever else the node
    /// sent, the wait times out ([`SessionError::Timeout`]).
    pub fn poll_samples(&mut self, wait: &mut BlockWait) -> Result<Option<Samples>, SessionError> {
        match self.poll_until(wait.0.deadline)? {
            Some(NodeMsg::Samples { seq, first, data, temp }) => {
                *wait = self.block_wait();
                Ok(Some(Samples { seq, first, data, temp }))
            }
            _ if Instant::now() >= wait.0.deadline => Err(self.timed_out(&wait.0)),
            _ => Ok(None),
        }
    }

    /// Discards every block produced before this call: asks who the node is and drops what comes
    /// before the answer (the node's link sends in order, and `Info` is sent only on request,
    /// unlike the periodic status reports, so an old report still in the port's buffer cannot be
    /// taken for the answer).
    pub fn flush_stream(&mut self) -> Result<(), SessionError> {
        self.info().map(|_| ())
    }
}

/// The record in force as JSON, as `info --json` and `verify --json` write it: `{"slot",
/// "sequence", "created_unix_s", "crc"}` (CRC as 8 hex digits), or null when there is none.
pub fn record_json(r: accelcal_shared::wire::RecordStatus) -> serde_json::Value {
    serde_json::to_value(accelcal_core::document::RecordInForceDoc::of(r))
        .expect("a record in force serialises")
}

/// A device id as `fit --device-id` takes it: 24 lower-case hex digits.
pub fn device_id_hex(id: &[u8; 12]) -> String {
    id.iter().map(|b| format!("{b:02x}")).collect()
}

/// A firmware version `[major, minor, patch]` as `major.minor.patch`.
pub fn firmware_version(v: [u16; 3]) -> String {
    format!("{}.{}.{}", v[0], v[1], v[2])
}

#[cfg(test)]
mod tests {
    use super::*;
    use accelcal_shared::wire::{RecordStatus, ResetCause, MAX_FRAME};
    use std::collections::VecDeque;
    use std::sync::{Arc, Mutex};

    /// A scripted node: bytes queued to be read, reads time out when empty.
    #[derive(Clone, Default)]
    struct Script(Arc<Mutex<VecDeque<u8>>>);
    impl Read for Script {
        fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
            let mut q = self.0.lock().unwrap();
            if q.is_empty() {
                // A read timeout blocks a while first (a short one: the receiver reads again).
                drop(q);
                std::thread::sleep(Duration::from_millis(1));
                return Err(io::Error::new(io::ErrorKind::TimedOut, "timed out"));
            }
            let n = buf.len().min(q.len());
            for b in buf.iter_mut().take(n) {
                *b = q.pop_front().unwrap();
            }
            Ok(n)
        }
    }

    /// A node message framed as the node sends it (a zero in front).
    fn frame(m: &NodeMsg) -> Vec<u8> {
        let mut buf = [0u8; MAX_FRAME];
        wire::encode_sync(m, &mut buf).unwrap().to_vec()
    }

    fn info(protocol: u8) -> Info {
        Info {
            device_id: *b"QEMU-B-L475E",
            firmware: [0, 1, 0],
            protocol,
            record: RecordStatus::InUse { slot: 0, sequence: 1, created_unix_s: 2, crc: 3 },
            rate_hz: 1000,
            overruns: 0,
            reset_cause: ResetCause::PowerOn,
            output: Output::Calibrated,
        }
    }

    /// A status report of a node whose record was created at `created_unix_s`.
    fn status(created_unix_s: u64) -> Status {
        Status {
            protocol: wire::PROTOCOL_VERSION,
            record: RecordStatus::InUse { slot: 0, sequence: 1, created_unix_s, crc: 3 },
            overruns: 0,
            sample_sets: 0,
            rate_hz: 1000,
            bad_frames: 0,
            reset_cause: ResetCause::PowerOn,
            trigger_mismatch: false,
            output: Output::Calibrated,
        }
    }

    fn session(msgs: &[NodeMsg]) -> (Session, Arc<Mutex<Vec<u8>>>) {
        let script = Script::default();
        for m in msgs {
            script.0.lock().unwrap().extend(frame(m));
        }
        #[derive(Clone)]
        struct Sink(Arc<Mutex<Vec<u8>>>);
        impl Write for Sink {
            fn write(&mut self, b: &[u8]) -> io::Result<usize> {
                self.0.lock().unwrap().extend_from_slice(b);
                Ok(b.len())
            }
            fn flush(&mut self) -> io::Result<()> {
                Ok(())
            }
        }
        let sent = Arc::new(Mutex::new(Vec::new()));
        let s = Session::from_streams(
            "test",
            Box::new(Sink(sent.clone())),
            Box::new(script),
            Duration::from_millis(300),
        );
        (s, sent)
    }

    #[test]
    fn info_is_found_among_other_messages() {
        let block = NodeMsg::Samples { seq: 0, first: 0, data: Block::Raw(Default::default()), temp: None };
        let (mut s, sent) = session(&[block, NodeMsg::Info(info(wire::PROTOCOL_VERSION))]);
        assert_eq!(s.info().unwrap(), info(wire::PROTOCOL_VERSION));
        // A leading zero, then GetInfo (variant 3), once: the answer came at once.
        assert_eq!(*sent.lock().unwrap(), vec![0x00, 0x02, 0x03, 0x00]);
        assert_eq!(device_id_hex(b"QEMU-B-L475E"), "51454d552d422d4c34373545");
        assert_eq!(firmware_version([0, 1, 12]), "0.1.12");
    }

    /// A port opened while the node was sending a status report: the report's tail, which
    /// without its first byte begins like a refusal, is dropped, and the answer is read.
    #[test]
    fn a_port_opened_mid_frame_reads_the_next_frame_not_the_tail() {
        let status = status(1_796_525_864);
        for cut in 1..frame(&NodeMsg::Status(status)).len() - 1 {
            let (mut s, _) = session(&[]);
            let script = {
                let mut bytes = frame(&NodeMsg::Status(status))[cut..].to_vec();
                bytes.extend(frame(&NodeMsg::Info(info(wire::PROTOCOL_VERSION))));
                bytes
            };
            s.rx = Receiver::mid_stream(Box::new(Script(Arc::new(Mutex::new(script.into())))));
            assert_eq!(s.info().unwrap(), info(wire::PROTOCOL_VERSION), "joined {cut} bytes into the status");
        }
    }

    /// A refusal answers a `SetRate` only: while another answer is awaited it is passed over.
    #[test]
    fn a_refusal_fails_only_the_request_it_can_answer() {
        let refused =
            NodeMsg::Refused(wire::Refusal::RateOutOfRange { requested_hz: 0, min_hz: 1, max_hz: 2 });
        let (mut s, _) = session(&[refused.clone(), NodeMsg::Info(info(wire::PROTOCOL_VERSION))]);
        assert_eq!(s.info().unwrap(), info(wire::PROTOCOL_VERSION));
        let (mut s, _) = session(&[refused]);
        let e = s.set_rate(50).unwrap_err();
        assert!(matches!(e, SessionError::Refused { .. }), "{e}");
    }

    /// A read cut by a signal (Ctrl-C while the serial port waits) is no message yet, never an
    /// error, and loses nothing (issue 24: `acquire` ended with exit 1 "Interrupted system call").
    #[test]
    fn a_read_cut_by_a_signal_is_no_message_yet() {
        struct Cut(bool, Script);
        impl Read for Cut {
            fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
                if !std::mem::replace(&mut self.0, true) {
                    return Err(io::Error::from(io::ErrorKind::Interrupted));
                }
                self.1.read(buf)
            }
        }
        let script = Script::default();
        script.0.lock().unwrap().extend(frame(&NodeMsg::Info(info(wire::PROTOCOL_VERSION))));
        let mut s = Session::from_streams(
            "test",
            Box::new(io::sink()),
            Box::new(Cut(false, script)),
            Duration::from_millis(300),
        );
        assert_eq!(s.poll().unwrap(), None);
        assert_eq!(s.poll().unwrap(), Some(NodeMsg::Info(info(wire::PROTOCOL_VERSION))));
    }

    #[test]
    fn silence_and_other_protocols_are_errors_that_say_so() {
        let (mut s, _) = session(&[]);
        let e = s.info().unwrap_err().to_string();
        assert!(e.starts_with("test: no answer to GetInfo from the node within 0.3 s"), "{e}");
        let (mut s, _) = session(&[NodeMsg::Info(info(2))]);
        let e = s.info().unwrap_err().to_string();
        assert!(e.contains("protocol 2"), "{e}");
    }

    /// A node whose line is held low (endless 0x00) or that sends endless bytes without a
    /// delimiter, each read answered at once: `info` fails after its answer timeout, saying what
    /// came, and so does a wait for live blocks.
    #[test]
    fn bytes_that_make_no_frame_time_out_and_say_so() {
        use crate::node::link::tests::Endless;
        let answer = Duration::from_millis(300);
        for (byte, why) in [(0x00, "all 0x00: a line held low"), (0x41, "with no 0x00 frame delimiter")] {
            let mut s =
                Session::from_streams("test", Box::new(io::sink()), Box::new(Endless::new(&[byte])), answer);
            let t0 = Instant::now();
            let e = s.info().unwrap_err();
            let took = t0.elapsed();
            assert!(took < answer + Duration::from_millis(200), "{byte:#04x}: {took:?}");
            assert!(matches!(e, SessionError::Timeout { .. }), "{e:?}");
            let msg = e.to_string();
            assert!(
                msg.starts_with("test: no answer to GetInfo from the node within 0.3 s: it sent "),
                "{msg}"
            );
            assert!(msg.contains("bytes of which none made a frame") && msg.contains(why), "{msg}");
            assert_eq!(e.kind(), Kind::Environment);
            let mut wait = s.block_wait();
            let t0 = Instant::now();
            let e = loop {
                match s.poll_samples(&mut wait) {
                    Ok(_) => assert!(t0.elapsed() < Duration::from_secs(2), "{byte:#04x}: no timeout"),
                    Err(e) => break e.to_string(),
                }
            };
            assert!(t0.elapsed() < answer + Duration::from_millis(200), "{byte:#04x}: {:?}", t0.elapsed());
            assert!(e.starts_with("test: no live sample block from the node within 0.3 s: it sent "), "{e}");
        }
    }

    /// Status reports keep coming, but no block: a wait for blocks times out all the same, and a
    /// block restarts it.
    #[test]
    fn a_wait_for_blocks_ends_whatever_else_comes() {
        use std::sync::atomic::{AtomicBool, Ordering};
        let status = frame(&NodeMsg::Status(status(2)));
        let script = Script::default();
        let block = NodeMsg::Samples { seq: 1, first: 0, data: Block::Raw(Default::default()), temp: None };
        script.0.lock().unwrap().extend(frame(&block));
        let answer = Duration::from_millis(300);
        let mut s = Session::from_streams("test", Box::new(io::sink()), Box::new(script.clone()), answer);
        let stop = Arc::new(AtomicBool::new(false));
        let feeder = {
            let (feed, stop) = (script.0.clone(), stop.clone());
            std::thread::spawn(move || {
                while !stop.load(Ordering::Relaxed) {
                    feed.lock().unwrap().extend(&status);
                    std::thread::sleep(Duration::from_millis(20));
                }
            })
        };
        let mut wait = s.block_wait();
        let t0 = Instant::now();
        let mut blocks = 0;
        let e = loop {
            match s.poll_samples(&mut wait) {
                Ok(b) => blocks += usize::from(b.is_some()),
                Err(e) => break e.to_string(),
            }
            assert!(t0.elapsed() < Duration::from_secs(2), "no timeout");
        };
        let took = t0.elapsed();
        stop.store(true, Ordering::Relaxed);
        feeder.join().unwrap();
        assert_eq!(blocks, 1);
        assert!(took < answer + Duration::from_millis(200), "{took:?}");
        assert!(e.starts_with("test: no live sample block from the node within 0.3 s: it sent "), "{e}");
        assert!(e.contains("other messages and 0 bad frames"), "{e}");
    }
}
