//! `accelcal monitor`: shows a node's live stream from its serial port (the board's ST-LINK
//! virtual COM port, USART1).

use std::io::Write;

use anyhow::Context;
use std::time::Duration;

use accelcal_shared::wire::{self, Block, NodeMsg, RecordStatus, Status};

use super::link::{LinkError, Receiver};

/// The node's USART1 baud rate (`firmware/src/board/real.rs`).
pub const NODE_BAUD: u32 = accelcal_shared::contract::BAUD_REAL;

/// One line of text for a status report.
pub fn format_status(s: &Status) -> String {
    let record = match s.record {
        RecordStatus::InUse { slot, sequence, created_unix_s, crc } => {
            format!("record slot {slot} seq {sequence} created {created_unix_s} crc {crc:08x}")
        }
        RecordStatus::Missing(f) => format!("NO RECORD ({f}): output is UNCALIBRATED"),
    };
    let trigger = if s.trigger_mismatch { ", ADC TRIGGER MISMATCH (see the node's log)" } else { "" };
    format!(
        "status: protocol {}, {record}, output {}, rate {} Hz, sample sets {}, overruns {}, bad frames {}, last reset {}{trigger}",
        s.protocol,
        s.output.name(),
        s.rate_hz,
        s.sample_sets,
        s.overruns,
        s.bad_frames,
        s.reset_cause
    )
}

/// Lines of text for a block of samples: `seq ax ay az` (m/s²), `seq RAW x y z` (raw codes on
/// request) or `seq UNCALIBRATED x y z` (raw codes because the node has no record).
pub fn format_block(seq: u32, data: &Block) -> Vec<String> {
    match data {
        Block::Calibrated(v) => {
            v.iter().map(|a| format!("{seq} {:.5} {:.5} {:.5}", a[0], a[1], a[2])).collect()
        }
        Block::CalibratedFixed(v) => v
            .iter()
            .map(|a| {
                let f = |q: i32| q as f64 / accelcal_shared::contract::FIXED_SCALE;
                format!("{seq} {:.5} {:.5} {:.5}", f(a[0]), f(a[1]), f(a[2]))
            })
            .collect(),
        Block::Uncalibrated(v) => {
            v.iter().map(|c| format!("{seq} UNCALIBRATED {} {} {}", c[0], c[1], c[2])).collect()
        }
        Block::Raw(v) => v.iter().map(|c| format!("{seq} RAW {} {} {}", c[0], c[1], c[2])).collect(),
    }
}

/// Reads messages from `port` at `baud` and prints them to `out`, until `count` messages (all of
/// them when `None`) or an error. With `rate`, first asks the node to sample at `rate` Hz (checked
/// here against the protocol's range first); a refusal ends the command with the node's reason.
/// A port that stays silent for `silence` fails with what to check (the node reports its status
/// every second, so a running node is never silent that long).
pub fn monitor(
    port_name: &str,
    baud: u32,
    count: Option<u64>,
    rate: Option<u32>,
    silence: Duration,
    out: &mut impl Write,
) -> anyhow::Result<()> {
    if let Some(hz) = rate {
        wire::check_rate(hz).map_err(|r| crate::error::bad(format!("--rate-hz: {r}")))?;
    }
    let port = serialport::new(port_name, baud)
        .timeout(silence)
        .open()
        .map_err(|e| crate::error::bad(format!("{port_name}: cannot open serial port: {e}")))?;
    let rx: Receiver<Box<dyn std::io::Read + Send>> = match rate {
        Some(hz) => {
            // Through a session: the request is resent until the node answers (a pty that QEMU
            // has not started reading yet loses the first copy), and a refusal is an error. The
            // stream goes on from the session's receiver, so nothing it read past the answer is
            // lost.
            let tx = port.try_clone()?;
            let mut s = super::session::Session::from_streams(port_name, Box::new(tx), port, silence);
            let st = s.set_rate(hz)?;
            writeln!(out, "rate set: {}", format_status(&st))?;
            s.into_receiver()
        }
        // The port was opened on a running node: the first bytes may be the tail of a frame.
        None => Receiver::mid_stream(Box::new(port)),
    };
    monitor_stream(rx, port_name, baud, count, silence, out)
}

/// [`monitor`] on a receiver whose reads time out after `silence`.
pub fn monitor_stream(
    mut rx: Receiver<impl std::io::Read>,
    port_name: &str,
    baud: u32,
    count: Option<u64>,
    silence: Duration,
    out: &mut impl Write,
) -> anyhow::Result<()> {
    let mut seen = 0u64;
    // The node's sample counter expected for the next block's first set.
    let mut next_first: Option<u32> = None;
    while count.is_none_or(|c| seen < c) {
        match rx.recv() {
            Ok(Ok(NodeMsg::Status(s))) => writeln!(out, "{}", format_status(&s))?,
            Ok(Ok(NodeMsg::Samples { seq, first, data, .. })) => {
                if let Some(expected) = next_first {
                    let lost = first.wrapping_sub(expected);
                    if lost != 0 {
                        writeln!(out, "# gap: {lost} sample sets lost before block {seq}")?;
                    }
                }
                next_first = Some(first.wrapping_add(data.len() as u32));
                for line in format_block(seq, &data) {
                    writeln!(out, "{line}")?;
                }
            }
            Ok(Ok(NodeMsg::Replayed { seq, .. })) => writeln!(out, "# replay answer {seq}")?,
            Ok(Ok(NodeMsg::RateSet(s))) => writeln!(out, "rate set: {}", format_status(&s))?,
            Ok(Ok(NodeMsg::OutputSet(s))) => writeln!(out, "output set: {}", format_status(&s))?,
            Ok(Ok(NodeMsg::Info(i))) => writeln!(out, "# info: {i:?}")?,
            Ok(Ok(NodeMsg::Refused(r))) => anyhow::bail!("the node refused the request: {r}"),
            Ok(Err(e)) => writeln!(out, "# bad frame: {e}")?,
            Err(LinkError::Closed) => break,
            Err(LinkError::Io(e)) if e.kind() == std::io::ErrorKind::TimedOut => {
                return Err(LinkError::Io(e)).with_context(|| {
                    format!(
                        "{port_name}: no frame from the node in {} s (is the board powered and running the accelcal \
                         firmware, is this its ST-LINK virtual COM port, is the baud rate {baud} the node's?)",
                        silence.as_secs_f64()
                    )
                });
            }
            Err(e) => return Err(e.into()),
        }
        seen += 1;
    }
    Ok(())
}

#[cfg(test)]
mod silence_tests {
    use super::*;

    /// A stream that has nothing to say: every read times out.
    struct Silent;
    impl std::io::Read for Silent {
        fn read(&mut self, _: &mut [u8]) -> std::io::Result<usize> {
            Err(std::io::Error::new(std::io::ErrorKind::TimedOut, "timed out"))
        }
    }

    #[test]
    fn a_silent_port_fails_with_what_to_check() {
        let mut out = Vec::new();
        let e = monitor_stream(
            Receiver::mid_stream(Silent),
            "/dev/ttyACM0",
            921_600,
            None,
            Duration::from_secs(5),
            &mut out,
        )
        .unwrap_err();
        let msg = format!("{e:#}");
        assert!(msg.starts_with("/dev/ttyACM0: no frame from the node in 5 s"), "{msg}");
        assert!(msg.contains("baud rate 921600"), "{msg}");
        // A failure of the environment (exit code 1), not bad input.
        assert!(e.chain().any(|c| c.is::<LinkError>()), "{e:?}");
        assert!(out.is_empty());
    }
}
