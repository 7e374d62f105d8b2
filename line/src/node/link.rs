//! The host end of the node link: frames [`HostMsg`]s out and decodes [`NodeMsg`]s in, over any
//! byte stream (a QEMU socket, a serial port).
//!
//! [`Receiver::recv`] takes an absolute deadline, checked on every read whatever the peer sends
//! (a line held low, noise without a delimiter), and [`Traffic`] counts what came, for the
//! timeout's message. [`Receiver::mid_stream`] drops the tail of a frame a late reader joins:
//! every session's port is joined that way, and since the node puts a zero in front of each frame
//! (`wire::encode_sync`), a join at a frame boundary loses nothing.

use std::io::{self, Read, Write};
use std::time::Instant;

use accelcal_core::error::{Classify, Kind};
use accelcal_shared::wire::{self, FrameDecoder, FrameError, HostMsg, NodeMsg, MAX_FRAME};

/// Why a message could not be exchanged.
#[derive(Debug, thiserror::Error)]
pub enum LinkError {
    /// The byte stream failed (including read timeouts). The cause is in the message, not a
    /// `source` (a chain of causes would print it twice).
    #[error("node link i/o: {0}")]
    Io(io::Error),
    /// The stream ended.
    #[error("node link closed")]
    Closed,
    /// A message could not be encoded.
    #[error("cannot encode message: {0}")]
    Encode(FrameError),
    /// The deadline given to [`Receiver::recv`] passed before a frame was complete (the caller
    /// says what it waited for, with the receiver's [`Traffic`]).
    #[error("node link: no frame before the deadline")]
    Deadline,
}

impl From<io::Error> for LinkError {
    fn from(e: io::Error) -> LinkError {
        LinkError::Io(e)
    }
}

impl Classify for LinkError {
    fn kind(&self) -> Kind {
        Kind::Environment
    }
}

/// Encodes one message as a frame with its leading zero ([`wire::encode_sync`]).
pub fn frame(msg: &HostMsg) -> Result<Vec<u8>, LinkError> {
    let mut buf = [0u8; MAX_FRAME];
    Ok(wire::encode_sync(msg, &mut buf).map_err(LinkError::Encode)?.to_vec())
}

/// What a [`Receiver`] has read: bytes, how many of them were `0x00` (the frame delimiter), and
/// the frames they made, good and bad. A wait that timed out says what came meanwhile
/// ([`Traffic::since`]): nothing, bytes that made no frame (a line held low reads as endless
/// `0x00`, empty frames the decoder skips; noise without a `0x00` is one frame that never ends),
/// bad frames only, or messages that were not the awaited one.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Traffic {
    /// Bytes read (those dropped before the first delimiter of a stream joined mid-frame too).
    pub bytes: u64,
    /// Of them, `0x00` bytes.
    pub zeros: u64,
    /// Frames that decoded to a message.
    pub frames: u64,
    /// Frames that did not (too long, or malformed).
    pub bad_frames: u64,
}

impl Traffic {
    /// What came after `earlier` (a snapshot of the same receiver).
    pub fn since(self, earlier: Traffic) -> Traffic {
        Traffic {
            bytes: self.bytes.saturating_sub(earlier.bytes),
            zeros: self.zeros.saturating_sub(earlier.zeros),
            frames: self.frames.saturating_sub(earlier.frames),
            bad_frames: self.bad_frames.saturating_sub(earlier.bad_frames),
        }
    }
}

impl std::fmt::Display for Traffic {
    /// "it sent …", with what to check.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let Traffic { bytes, zeros, frames, bad_frames } = *self;
        if bytes == 0 {
            return f.write_str(
                "it sent nothing (is the board powered and running the accelcal firmware, and is this its link port?)",
            );
        }
        if frames > 0 {
            return write!(f, "it sent {frames} other messages and {bad_frames} bad frames ({bytes} bytes)");
        }
        if bad_frames > 0 {
            return write!(
                f,
                "it sent {bytes} bytes in {bad_frames} bad frames and no good one (is the baud rate the node's?)"
            );
        }
        let why = if zeros == bytes {
            "all 0x00: a line held low reads as 0x00 bytes"
        } else if zeros == 0 {
            "with no 0x00 frame delimiter: one frame that never ends, from noise or a wrong baud rate"
        } else {
            "a line held low sends 0x00 bytes; noise, a frame that never ends"
        };
        write!(f, "it sent {bytes} bytes of which none made a frame ({why})")
    }
}

/// Reads node messages from a byte stream.
pub struct Receiver<R> {
    inner: R,
    decoder: Box<FrameDecoder<MAX_FRAME>>,
    pending: std::collections::VecDeque<Result<NodeMsg, FrameError>>,
    /// Bytes are dropped up to and including the next frame delimiter (a stream joined mid-frame).
    skip_to_delimiter: bool,
    traffic: Traffic,
}

impl<R: Read> Receiver<R> {
    /// Wraps a byte stream that starts at a frame boundary (a node's link from its boot on).
    pub fn new(inner: R) -> Self {
        Receiver {
            inner,
            decoder: Box::new(FrameDecoder::new()),
            pending: Default::default(),
            skip_to_delimiter: false,
            traffic: Traffic::default(),
        }
    }

    /// Wraps a byte stream joined while the node was already sending (a serial port opened on a
    /// running node, or a stream another reader has read from): the bytes before the first frame
    /// delimiter are the tail of a frame and are dropped, not reported as a bad frame. The node
    /// puts a zero in front of every frame ([`wire::encode_sync`]), so a joiner at a frame
    /// boundary drops only that zero; from a sender without leading zeros it would lose one
    /// whole frame.
    pub fn mid_stream(inner: R) -> Self {
        Receiver { skip_to_delimiter: true, ..Receiver::new(inner) }
    }

    /// What it has read so far.
    pub fn traffic(&self) -> Traffic {
        self.traffic
    }

    /// The next frame: a message, or why the frame was bad (the caller decides whether that is
    /// fatal), or [`LinkError::Deadline`] once `deadline` has passed. The deadline is checked
    /// before every read, whatever the stream delivers: a stream that keeps sending bytes that
    /// never complete a frame (endless `0x00`, empty frames the decoder skips, or endless bytes
    /// without a delimiter) cannot hold the caller past it. A read that times out (the stream's
    /// own read timeout, which bounds how far past the deadline a silent stream may block) is
    /// read again; a read cut by a signal is returned as [`LinkError::Io`] (`Interrupted`), so
    /// that the caller can check a stop flag.
    pub fn recv(&mut self, deadline: Instant) -> Result<Result<NodeMsg, FrameError>, LinkError> {
        let mut buf = [0u8; 512];
        loop {
            if let Some(m) = self.pending.pop_front() {
                return Ok(m);
            }
            if Instant::now() >= deadline {
                return Err(LinkError::Deadline);
            }
            let n = match self.inner.read(&mut buf) {
                Ok(0) => return Err(LinkError::Closed),
                Ok(n) => n,
                Err(e) if matches!(e.kind(), io::ErrorKind::TimedOut | io::ErrorKind::WouldBlock) => continue,
                Err(e) => return Err(e.into()),
            };
            let mut bytes = &buf[..n];
            self.traffic.bytes += n as u64;
            self.traffic.zeros += bytes.iter().filter(|&&b| b == 0).count() as u64;
            if self.skip_to_delimiter {
                match bytes.iter().position(|&b| b == 0) {
                    Some(end) => {
                        bytes = &bytes[end + 1..];
                        self.skip_to_delimiter = false;
                    }
                    None => continue,
                }
            }
            let (pending, traffic) = (&mut self.pending, &mut self.traffic);
            self.decoder.push(bytes, |m: Result<NodeMsg, FrameError>| {
                match m {
                    Ok(_) => traffic.frames += 1,
                    Err(_) => traffic.bad_frames += 1,
                }
                pending.push_back(m)
            });
        }
    }
}

/// Sends one message (with a leading zero, which resynchronises the node's decoder after noise).
pub fn send(w: &mut impl Write, msg: &HostMsg) -> Result<(), LinkError> {
    let bytes = frame(msg)?;
    // `write_all` retries a write cut by a signal (EINTR); the flush (a serial port's `tcdrain`)
    // is retried here, so that a Ctrl-C never fails a request.
    w.write_all(&bytes)?;
    loop {
        match w.flush() {
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
            r => return Ok(r?),
        }
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use accelcal_shared::wire::{Block, MAX_BLOCK};
    use std::time::Duration;

    /// A block of raw codes, as a node streams them.
    fn samples() -> NodeMsg {
        let codes = (0..MAX_BLOCK as u16).map(|i| [32_768 + i, 1000 * i, 65_535 - i]).collect();
        NodeMsg::Samples { seq: 41, first: 656, data: Block::Raw(codes), temp: None }
    }

    fn samples_frame() -> Vec<u8> {
        let mut buf = [0u8; MAX_FRAME];
        wire::encode(&samples(), &mut buf).unwrap().to_vec()
    }

    /// The tail of a frame, then two whole frames, read a few bytes at a time.
    fn joined_mid_frame() -> Vec<u8> {
        let f = samples_frame();
        let mut bytes = f[f.len() / 2..].to_vec();
        bytes.extend_from_slice(&f);
        bytes.extend_from_slice(&f);
        bytes
    }

    /// Reads `bytes` in chunks of 7 (a serial port hands out what has arrived).
    struct Chunks(Vec<u8>, usize);
    impl Read for Chunks {
        fn read(&mut self, out: &mut [u8]) -> io::Result<usize> {
            let n = (self.0.len() - self.1).min(7).min(out.len());
            out[..n].copy_from_slice(&self.0[self.1..self.1 + n]);
            self.1 += n;
            Ok(n)
        }
    }

    fn all<R: Read>(mut rx: Receiver<R>) -> Vec<Result<NodeMsg, FrameError>> {
        let deadline = Instant::now() + Duration::from_secs(60);
        std::iter::from_fn(|| rx.recv(deadline).ok()).collect()
    }

    #[test]
    fn a_stream_joined_mid_frame_starts_at_the_next_frame() {
        let got = all(Receiver::mid_stream(Chunks(joined_mid_frame(), 0)));
        let want = samples();
        assert_eq!(got.len(), 2, "{got:?}");
        assert!(got.iter().all(|m| m.as_ref() == Ok(&want)), "{got:?}");
        // Read as a stream from its start, the tail is a bad frame.
        let got = all(Receiver::new(Chunks(joined_mid_frame(), 0)));
        assert_eq!(got.len(), 3, "{got:?}");
        assert!(got[0].is_err() && got[1..].iter().all(|m| m.as_ref() == Ok(&want)), "{got:?}");
    }

    #[test]
    fn a_stream_joined_at_a_boundary_loses_one_frame_unless_frames_lead_with_a_zero() {
        let mut bytes = samples_frame();
        bytes.extend_from_slice(&samples_frame());
        assert_eq!(all(Receiver::mid_stream(Chunks(bytes, 0))).len(), 1);
        // As the node sends them: each frame after a zero.
        let mut buf = [0u8; MAX_FRAME];
        let synced = wire::encode_sync(&samples(), &mut buf).unwrap().to_vec();
        let got = all(Receiver::mid_stream(Chunks([synced.clone(), synced].concat(), 0)));
        assert_eq!(got, vec![Ok(samples()), Ok(samples())]);
    }

    /// A peer that never stops sending `pattern` over and over, a few bytes per read, each read
    /// answered at once (no read timeout ever fires); after 5 s it closes the stream, so that a
    /// receiver that ignores its deadline ends with `Closed` rather than hanging the test.
    pub(crate) struct Endless {
        pattern: Vec<u8>,
        at: usize,
        until: Instant,
    }
    impl Endless {
        pub(crate) fn new(pattern: &[u8]) -> Endless {
            Endless { pattern: pattern.to_vec(), at: 0, until: Instant::now() + Duration::from_secs(5) }
        }
    }
    impl Read for Endless {
        fn read(&mut self, out: &mut [u8]) -> io::Result<usize> {
            if Instant::now() > self.until {
                return Ok(0);
            }
            let n = out.len().min(5);
            for b in &mut out[..n] {
                *b = self.pattern[self.at];
                self.at = (self.at + 1) % self.pattern.len();
            }
            std::thread::sleep(Duration::from_micros(50));
            Ok(n)
        }
    }

    /// The deadline holds whatever the peer sends: endless `0x00` (a UART line held low: endless
    /// empty frames) and endless `0x41` (one frame that never ends, too long for any buffer).
    #[test]
    fn the_deadline_holds_while_bytes_keep_arriving() {
        for (byte, why) in [(0x00, "all 0x00: a line held low"), (0x41, "with no 0x00 frame delimiter")] {
            for mid_stream in [false, true] {
                let endless = Endless::new(&[byte]);
                let mut rx = if mid_stream { Receiver::mid_stream(endless) } else { Receiver::new(endless) };
                let t0 = Instant::now();
                let got = rx.recv(t0 + Duration::from_millis(200));
                let took = t0.elapsed();
                assert!(matches!(got, Err(LinkError::Deadline)), "{byte:#04x}: {got:?} after {took:?}");
                assert!(took < Duration::from_millis(400), "{byte:#04x}: returned after {took:?}");
                let heard = rx.traffic();
                assert!(heard.bytes > 100 && heard.frames == 0 && heard.bad_frames == 0, "{heard:?}");
                let text = heard.to_string();
                assert!(text.contains("bytes of which none made a frame") && text.contains(why), "{text}");
            }
        }
    }
}
