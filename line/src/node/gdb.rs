//! A client of the GDB remote serial protocol (RSP), for the node's flash through a GDB server:
//! Black Magic Probe, OpenOCD, or QEMU's gdbstub (`accelcal emulate` prints its address).
//!
//! Only what `flash --gdb` needs: read memory (`m`), write memory (`M`), program flash (`vFlashErase`,
//! `vFlashWrite`, `vFlashDone`, which probes with a flash driver implement; a stub that answers them
//! with an empty packet has none, and memory writes are used instead), and detach (`D`). Packets
//! are `$payload#checksum` with `+` acknowledgements (no-ack mode is not requested).
//!
//! (The crates.io RSP crates are servers (`gdbstub`) or an unmaintained parser; a client of five
//! packets is smaller than adapting either.)

use accelcal_core::error::{Classify, Kind};
use std::io::{BufReader, Read, Write};
use std::net::TcpStream;
use std::time::Duration;

/// Why a GDB server could not be used.
#[derive(Debug, thiserror::Error)]
pub enum GdbError {
    /// The connection failed or timed out.
    #[error("gdb server {addr}: {cause}")]
    Io {
        /// The server's address.
        addr: String,
        /// The cause.
        cause: std::io::Error,
    },
    /// The server answered an error code or something the protocol does not allow.
    #[error("gdb server {addr}: {what}")]
    Protocol {
        /// The server's address.
        addr: String,
        /// What went wrong.
        what: String,
    },
    /// The server closed the connection.
    #[error("gdb server {addr}: connection closed")]
    Closed {
        /// The server's address.
        addr: String,
    },
}

impl Classify for GdbError {
    fn kind(&self) -> Kind {
        Kind::Environment
    }
}

/// A connection to a GDB server.
pub struct GdbClient {
    addr: String,
    reader: BufReader<TcpStream>,
    writer: TcpStream,
}

/// The largest memory transfer per packet, bytes (hex doubles it; every server here accepts
/// packets of a few KiB, QEMU's up to 4 KiB).
const CHUNK: usize = 512;

fn checksum(payload: &[u8]) -> u8 {
    payload.iter().fold(0u8, |s, &b| s.wrapping_add(b))
}

/// Escapes binary data for `vFlashWrite` (`#`, `$`, `}` and `*` become `}` followed by the byte
/// xor 0x20).
fn escape(data: &[u8]) -> Vec<u8> {
    let mut out = Vec::with_capacity(data.len() + 8);
    for &b in data {
        if matches!(b, b'#' | b'$' | b'}' | b'*') {
            out.push(b'}');
            out.push(b ^ 0x20);
        } else {
            out.push(b);
        }
    }
    out
}

fn hex(data: &[u8]) -> String {
    data.iter().map(|b| format!("{b:02x}")).collect()
}

fn unhex(s: &[u8]) -> Option<Vec<u8>> {
    if !s.len().is_multiple_of(2) {
        return None;
    }
    s.chunks(2).map(|p| u8::from_str_radix(std::str::from_utf8(p).ok()?, 16).ok()).collect()
}

impl GdbClient {
    /// Connects to `addr` (`HOST:PORT`); each answer may take up to `timeout`.
    pub fn connect(addr: &str, timeout: Duration) -> Result<GdbClient, GdbError> {
        let io = |cause| GdbError::Io { addr: addr.to_string(), cause };
        let stream = TcpStream::connect(addr).map_err(io)?;
        stream.set_read_timeout(Some(timeout)).map_err(io)?;
        stream.set_nodelay(true).map_err(io)?;
        let writer = stream.try_clone().map_err(io)?;
        let mut c = GdbClient { addr: addr.to_string(), reader: BufReader::new(stream), writer };
        // Stop reason: also makes sure the target is halted and the server talks RSP. A server
        // halts the target on connection: one that then fails is asked to let it run.
        if let Err(e) = c.request(b"?") {
            let _ = c.detach();
            return Err(e);
        }
        Ok(c)
    }

    fn io(&self, cause: std::io::Error) -> GdbError {
        GdbError::Io { addr: self.addr.clone(), cause }
    }

    fn protocol(&self, what: impl Into<String>) -> GdbError {
        GdbError::Protocol { addr: self.addr.clone(), what: what.into() }
    }

    fn byte(&mut self) -> Result<u8, GdbError> {
        let mut b = [0u8];
        match self.reader.read(&mut b) {
            Ok(1) => Ok(b[0]),
            Ok(_) => Err(GdbError::Closed { addr: self.addr.clone() }),
            Err(e) => Err(self.io(e)),
        }
    }

    /// Sends a packet and returns the answer's payload (retransmitting on `-`).
    pub fn request(&mut self, payload: &[u8]) -> Result<Vec<u8>, GdbError> {
        let mut pkt = Vec::with_capacity(payload.len() + 4);
        pkt.push(b'$');
        pkt.extend_from_slice(payload);
        pkt.extend_from_slice(format!("#{:02x}", checksum(payload)).as_bytes());
        for _ in 0..3 {
            self.writer.write_all(&pkt).map_err(|e| self.io(e))?;
            match self.byte()? {
                b'+' => return self.answer(),
                b'-' => continue,
                // A server in no-ack mode or one that answers at once: the answer starts here.
                b'$' => return self.answer_body(),
                other => {
                    return Err(self.protocol(format!("expected an acknowledgement, got byte {other:#04x}")))
                }
            }
        }
        Err(self.protocol("the packet was refused three times (bad checksum on the line?)"))
    }

    fn answer(&mut self) -> Result<Vec<u8>, GdbError> {
        loop {
            if self.byte()? == b'$' {
                return self.answer_body();
            }
        }
    }

    fn answer_body(&mut self) -> Result<Vec<u8>, GdbError> {
        let mut body = Vec::new();
        loop {
            match self.byte()? {
                b'#' => break,
                b => body.push(b),
            }
        }
        let sum = [self.byte()?, self.byte()?];
        let ok = std::str::from_utf8(&sum).ok().and_then(|s| u8::from_str_radix(s, 16).ok())
            == Some(checksum(&body));
        self.writer.write_all(if ok { b"+" } else { b"-" }).map_err(|e| self.io(e))?;
        if !ok {
            return Err(self.protocol("answer with a bad checksum"));
        }
        Ok(body)
    }

    fn expect_ok(&mut self, payload: &[u8], what: &str) -> Result<(), GdbError> {
        let a = self.request(payload)?;
        if a == b"OK" {
            Ok(())
        } else {
            Err(self.protocol(format!("{what}: answered `{}`", accelcal_core::text::escape_peer(&a))))
        }
    }

    /// Reads `buf.len()` bytes at `addr`.
    pub fn read(&mut self, addr: u32, buf: &mut [u8]) -> Result<(), GdbError> {
        for (i, chunk) in buf.chunks_mut(CHUNK).enumerate() {
            let at = addr as usize + i * CHUNK;
            let a = self.request(format!("m{at:x},{:x}", chunk.len()).as_bytes())?;
            match unhex(&a) {
                Some(bytes) if bytes.len() == chunk.len() => chunk.copy_from_slice(&bytes),
                _ => {
                    return Err(self.protocol(format!(
                        "reading {} bytes at {at:#010x}: answered `{}`",
                        chunk.len(),
                        accelcal_core::text::escape_peer(&a)
                    )))
                }
            }
        }
        Ok(())
    }

    /// Writes `data` at `addr` with memory writes, in ascending chunks.
    pub fn write(&mut self, addr: u32, data: &[u8]) -> Result<(), GdbError> {
        for (i, chunk) in data.chunks(CHUNK).enumerate() {
            let at = addr as usize + i * CHUNK;
            let p = format!("M{at:x},{:x}:{}", chunk.len(), hex(chunk));
            self.expect_ok(p.as_bytes(), &format!("writing {} bytes at {at:#010x}", chunk.len()))?;
        }
        Ok(())
    }

    /// Erases and programs flash at `addr` through the server's flash driver; `Ok(false)` when
    /// the server has none (it answers `vFlashErase` with an empty packet), nothing written then.
    pub fn program_flash(&mut self, addr: u32, data: &[u8]) -> Result<bool, GdbError> {
        let a = self.request(format!("vFlashErase:{addr:x},{:x}", data.len()).as_bytes())?;
        if a.is_empty() {
            return Ok(false);
        }
        if a != b"OK" {
            return Err(self.protocol(format!(
                "vFlashErase at {addr:#010x}: answered `{}`",
                accelcal_core::text::escape_peer(&a)
            )));
        }
        for (i, chunk) in data.chunks(CHUNK).enumerate() {
            let at = addr as usize + i * CHUNK;
            let mut p = format!("vFlashWrite:{at:x}:").into_bytes();
            p.extend_from_slice(&escape(chunk));
            self.expect_ok(&p, &format!("vFlashWrite at {at:#010x}"))?;
        }
        self.expect_ok(b"vFlashDone", "vFlashDone")?;
        Ok(true)
    }

    /// Detaches: the target runs on.
    pub fn detach(mut self) -> Result<(), GdbError> {
        // Some servers close the connection instead of answering OK; both are a detach.
        match self.request(b"D") {
            Ok(_) | Err(GdbError::Protocol { .. } | GdbError::Closed { .. }) => Ok(()),
            Err(e) => Err(e),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::net::TcpListener;

    /// A tiny RSP server over a 64 KiB memory starting at 0x1000, without a flash driver.
    fn serve(listener: TcpListener) -> Vec<u8> {
        let (mut s, _) = listener.accept().unwrap();
        let mut mem = vec![0u8; 0x10000];
        let mut buf = Vec::new();
        let mut byte = [0u8];
        loop {
            if s.read(&mut byte).unwrap_or(0) == 0 {
                return mem;
            }
            match byte[0] {
                b'$' => buf.clear(),
                b'#' => {
                    let mut sum = [0u8; 2];
                    s.read_exact(&mut sum).unwrap();
                    s.write_all(b"+").unwrap();
                    let p = String::from_utf8(buf.clone()).unwrap();
                    let answer = if p == "?" {
                        "S05".to_string()
                    } else if p.starts_with("mdead0000,") {
                        // A hostile server: terminal escape sequences instead of memory.
                        "\x1b]0;pwned\x07\x1b[2J".into()
                    } else if let Some(r) = p.strip_prefix('m') {
                        let (a, n) = r.split_once(',').unwrap();
                        let (a, n) = (
                            usize::from_str_radix(a, 16).unwrap() - 0x1000,
                            usize::from_str_radix(n, 16).unwrap(),
                        );
                        if a + n > mem.len() {
                            "E14".into()
                        } else {
                            hex(&mem[a..a + n])
                        }
                    } else if let Some(r) = p.strip_prefix('M') {
                        let (head, data) = r.split_once(':').unwrap();
                        let a = usize::from_str_radix(head.split_once(',').unwrap().0, 16).unwrap() - 0x1000;
                        let d = unhex(data.as_bytes()).unwrap();
                        mem[a..a + d.len()].copy_from_slice(&d);
                        "OK".into()
                    } else if p == "D" {
                        "OK".into()
                    } else {
                        String::new()
                    };
                    let reply = format!("${answer}#{:02x}", checksum(answer.as_bytes()));
                    s.write_all(reply.as_bytes()).unwrap();
                    let mut ack = [0u8];
                    s.read_exact(&mut ack).unwrap();
                    if p == "D" {
                        return mem;
                    }
                }
                b => buf.push(b),
            }
        }
    }

    #[test]
    fn reads_writes_and_falls_back_without_a_flash_driver() {
        let l = TcpListener::bind("127.0.0.1:0").unwrap();
        let addr = l.local_addr().unwrap().to_string();
        let server = std::thread::spawn(move || serve(l));
        let mut c = GdbClient::connect(&addr, Duration::from_secs(5)).unwrap();
        let data: Vec<u8> = (0..1500u32).map(|i| (i * 7) as u8).collect();
        assert!(!c.program_flash(0x2000, &data).unwrap());
        c.write(0x2000, &data).unwrap();
        let mut back = vec![0u8; data.len()];
        c.read(0x2000, &mut back).unwrap();
        assert_eq!(back, data);
        let e = c.read(0x2_0000, &mut [0u8; 4]).unwrap_err().to_string();
        assert!(e.contains("answered `E14`"), "{e}");
        // What the server sends is shown escaped, never sent to the terminal.
        let e = c.read(0xdead_0000, &mut [0u8; 4]).unwrap_err().to_string();
        assert!(e.contains(r"answered `\x1b]0;pwned\x07\x1b[2J`"), "{e}");
        assert!(!e.contains('\u{1b}') && !e.contains('\u{7}'), "{e}");
        c.detach().unwrap();
        let mem = server.join().unwrap();
        assert_eq!(&mem[0x1000..0x1000 + 1500], &data[..]);
    }

    #[test]
    fn binary_escapes() {
        assert_eq!(escape(b"a#$}*b"), b"a}\x03}\x04}]}\x0ab".to_vec());
    }
}
