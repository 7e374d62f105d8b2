//! The host end of the node link: frames [`HostMsg`]s out and decodes [`NodeMsg`]s in, over any
//! byte stream (a QEMU socket, a serial port).

use std::io::{self, Read, Write};

use crate::error::{Classify, Kind};
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

/// Encodes one message as a frame.
pub fn frame(msg: &HostMsg) -> Result<Vec<u8>, LinkError> {
    let mut buf = [0u8; MAX_FRAME];
    Ok(wire::encode(msg, &mut buf).map_err(LinkError::Encode)?.to_vec())
}

/// Reads node messages from a byte stream.
pub struct Receiver<R> {
    inner: R,
    decoder: Box<FrameDecoder<MAX_FRAME>>,
    pending: std::collections::VecDeque<Result<NodeMsg, FrameError>>,
    /// Bytes are dropped up to and including the next frame delimiter (a stream joined mid-frame).
    skip_to_delimiter: bool,
}

impl<R: Read> Receiver<R> {
    /// Wraps a byte stream that starts at a frame boundary (a node's link from its boot on).
    pub fn new(inner: R) -> Self {
        Receiver {
            inner,
            decoder: Box::new(FrameDecoder::new()),
            pending: Default::default(),
            skip_to_delimiter: false,
        }
    }

    /// Wraps a byte stream joined while the node was already sending (a serial port opened on a
    /// running node, or a stream another reader has read from): the bytes before the first frame
    /// delimiter are the tail of a frame and are dropped, not reported as a bad frame. A joiner at
    /// a frame boundary loses one whole frame that way.
    pub fn mid_stream(inner: R) -> Self {
        Receiver { skip_to_delimiter: true, ..Receiver::new(inner) }
    }

    /// The next frame: a message, or why the frame was bad (the caller decides whether that is
    /// fatal). Blocks until one arrives or the stream's read timeout expires.
    pub fn recv(&mut self) -> Result<Result<NodeMsg, FrameError>, LinkError> {
        let mut buf = [0u8; 512];
        loop {
            if let Some(m) = self.pending.pop_front() {
                return Ok(m);
            }
            let n = self.inner.read(&mut buf)?;
            if n == 0 {
                return Err(LinkError::Closed);
            }
            let mut bytes = &buf[..n];
            if self.skip_to_delimiter {
                match bytes.iter().position(|&b| b == 0) {
                    Some(end) => {
                        bytes = &bytes[end + 1..];
                        self.skip_to_delimiter = false;
                    }
                    None => continue,
                }
            }
            let pending = &mut self.pending;
            self.decoder.push(bytes, |m| pending.push_back(m));
        }
    }
}

/// Sends one message (with a leading zero, which resynchronises the node's decoder after noise).
pub fn send(w: &mut impl Write, msg: &HostMsg) -> Result<(), LinkError> {
    let mut bytes = vec![0u8];
    bytes.extend_from_slice(&frame(msg)?);
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
mod tests {
    use super::*;
    use accelcal_shared::wire::{Block, MAX_BLOCK};

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
        std::iter::from_fn(|| rx.recv().ok()).collect()
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
    fn a_stream_joined_at_a_boundary_loses_one_frame() {
        let mut bytes = samples_frame();
        bytes.extend_from_slice(&samples_frame());
        assert_eq!(all(Receiver::mid_stream(Chunks(bytes, 0))).len(), 1);
    }
}
