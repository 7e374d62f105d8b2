//! The host end of the node link: frames [`HostMsg`]s out and decodes [`NodeMsg`]s in, over any
//! byte stream (a QEMU socket, a serial port).

use std::io::{self, Read, Write};

use accelcal_shared::wire::{self, FrameDecoder, FrameError, HostMsg, NodeMsg, MAX_FRAME};

/// Why a message could not be exchanged.
#[derive(Debug, thiserror::Error)]
pub enum LinkError {
    /// The byte stream failed (including read timeouts).
    #[error("node link i/o: {0}")]
    Io(#[from] io::Error),
    /// The stream ended.
    #[error("node link closed")]
    Closed,
    /// A message could not be encoded.
    #[error("cannot encode message: {0}")]
    Encode(FrameError),
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
}

impl<R: Read> Receiver<R> {
    /// Wraps a byte stream.
    pub fn new(inner: R) -> Self {
        Receiver { inner, decoder: Box::new(FrameDecoder::new()), pending: Default::default() }
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
            let pending = &mut self.pending;
            self.decoder.push(&buf[..n], |m| pending.push_back(m));
        }
    }
}

/// Sends one message (with a leading zero, which resynchronises the node's decoder after noise).
pub fn send(w: &mut impl Write, msg: &HostMsg) -> Result<(), LinkError> {
    let mut bytes = vec![0u8];
    bytes.extend_from_slice(&frame(msg)?);
    w.write_all(&bytes)?;
    w.flush()?;
    Ok(())
}
