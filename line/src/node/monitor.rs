//! `accelcal monitor`: shows a node's live stream from its serial port (the board's ST-LINK
//! virtual COM port, USART1).
//!
//! `--rate-hz` sends `SetRate` first; `--count N` counts messages, not bad frames; no message for
//! `--timeout-s` fails, whatever else came. A freshly opened port is joined mid-stream.

use std::io::Write;

use std::time::{Duration, Instant};

use accelcal_shared::wire::{self, Block, NodeMsg, RecordStatus, Status};

use super::link::{LinkError, Receiver};
use super::session::SessionError;

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
/// them when `None`) or an error. Only messages count toward `count`: a frame that does not
/// decode is shown (`# bad frame: …`) and not counted. With `rate`, first asks the node to sample
/// at `rate` Hz (checked here against the protocol's range first); a refusal ends the command
/// with the node's reason. When no message comes for `silence` (the node reports its status
/// every second, so a running node never goes that long without one), whatever else arrives —
/// nothing, bytes that make no frame (a line held low), bad frames —, the command fails
/// ([`SessionError::Timeout`], saying what came); so does a link that closes before `count`
/// messages.
pub fn monitor(
    port_name: &str,
    baud: u32,
    count: Option<u64>,
    rate: Option<u32>,
    silence: Duration,
    out: &mut impl Write,
) -> anyhow::Result<()> {
    if let Some(hz) = rate {
        wire::check_rate(hz).map_err(|r| accelcal_core::error::bad(format!("--rate-hz: {r}")))?;
    }
    // Reads time out every POLL: the receiver checks its deadline between them.
    let port = super::port::open(port_name, baud, super::session::POLL, super::port::LOCK_WAIT)
        .map_err(|e| accelcal_core::error::bad(format!("{port_name}: cannot open serial port: {e}")))?;
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

/// [`monitor`] on a receiver (whose reads should time out now and then, so that a silent stream
/// does not block long past the deadline).
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
    // The next message is due by `deadline`; `heard`: the link's traffic when the wait began.
    let (mut deadline, mut heard) = (Instant::now() + silence, rx.traffic());
    while count.is_none_or(|c| seen < c) {
        let msg = match rx.recv(deadline) {
            Ok(Ok(m)) => m,
            Ok(Err(e)) => {
                writeln!(out, "# bad frame: {e}")?;
                continue;
            }
            Err(LinkError::Closed) => match count {
                None => break,
                Some(c) => {
                    return Err(anyhow::Error::new(LinkError::Closed)
                        .context(format!("{port_name}: after {seen} of {c} messages")))
                }
            },
            Err(LinkError::Deadline) => {
                return Err(SessionError::Timeout {
                    port: format!("{port_name} at {baud} baud"),
                    what: "message",
                    secs: silence.as_secs_f64(),
                    heard: rx.traffic().since(heard),
                }
                .into())
            }
            Err(e) => return Err(e.into()),
        };
        match msg {
            NodeMsg::Status(s) => writeln!(out, "{}", format_status(&s))?,
            NodeMsg::Samples { seq, first, data, .. } => {
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
            NodeMsg::Replayed { seq, .. } => writeln!(out, "# replay answer {seq}")?,
            NodeMsg::RateSet(s) => writeln!(out, "rate set: {}", format_status(&s))?,
            NodeMsg::OutputSet(s) => writeln!(out, "output set: {}", format_status(&s))?,
            NodeMsg::Info(i) => writeln!(out, "# info: {i:?}")?,
            NodeMsg::Refused(r) => anyhow::bail!("the node refused the request: {r}"),
        }
        seen += 1;
        (deadline, heard) = (Instant::now() + silence, rx.traffic());
    }
    Ok(())
}

#[cfg(test)]
mod silence_tests {
    use super::*;
    use crate::node::link::tests::Endless;
    use accelcal_shared::wire::MAX_FRAME;

    /// A stream that has nothing to say: every read times out.
    struct Silent;
    impl std::io::Read for Silent {
        fn read(&mut self, _: &mut [u8]) -> std::io::Result<usize> {
            std::thread::sleep(Duration::from_millis(1));
            Err(std::io::Error::new(std::io::ErrorKind::TimedOut, "timed out"))
        }
    }

    fn run(rx: Receiver<impl std::io::Read>, count: Option<u64>) -> (anyhow::Result<()>, String, Duration) {
        let mut out = Vec::new();
        let t0 = Instant::now();
        let r = monitor_stream(rx, "/dev/ttyACM0", 921_600, count, Duration::from_millis(300), &mut out);
        (r, String::from_utf8(out).unwrap(), t0.elapsed())
    }

    #[test]
    fn a_silent_port_fails_with_what_to_check() {
        let (r, out, _) = run(Receiver::mid_stream(Silent), None);
        let e = r.unwrap_err();
        let msg = format!("{e:#}");
        assert!(
            msg.starts_with(
                "/dev/ttyACM0 at 921600 baud: no message from the node within 0.3 s: it sent nothing"
            ),
            "{msg}"
        );
        assert!(msg.contains("is this its link port?"), "{msg}");
        // A failure of the environment (exit code 1), not bad input.
        assert!(e.chain().any(|c| c.is::<SessionError>()), "{e:?}");
        assert!(out.is_empty());
    }

    /// Bad frames are shown and not counted: `--count 3` over a stream of nothing but bad frames
    /// fails after the timeout (it used to succeed after three of them), and so does a line held
    /// low, whose endless 0x00 bytes make no frame at all.
    #[test]
    fn bad_frames_do_not_count_and_do_not_stop_the_deadline() {
        for (pattern, heard) in
            [(&[0x01, 0x00][..], "bad frames and no good one"), (&[0x00][..], "all 0x00: a line held low")]
        {
            let (r, out, took) = run(Receiver::new(Endless::new(pattern)), Some(3));
            let msg = format!("{:#}", r.unwrap_err());
            assert!(
                msg.starts_with("/dev/ttyACM0 at 921600 baud: no message from the node within 0.3 s"),
                "{msg}"
            );
            assert!(msg.contains(heard), "{msg}");
            assert!(took < Duration::from_millis(500), "{took:?}");
            assert!(out.lines().all(|l| l == "# bad frame: malformed frame"), "{out}");
        }
    }

    /// Messages between bad frames: `--count 2` ends after the second message.
    #[test]
    fn only_messages_count() {
        let mut buf = [0u8; MAX_FRAME];
        let answer = NodeMsg::Replayed { seq: 5, data: Block::Raw(Default::default()), temp: None };
        let mut pattern = vec![0x01, 0x00];
        pattern.extend_from_slice(wire::encode(&answer, &mut buf).unwrap());
        let (r, out, _) = run(Receiver::new(Endless::new(&pattern)), Some(2));
        r.unwrap();
        assert_eq!(out, "# bad frame: malformed frame\n# replay answer 5\n# bad frame: malformed frame\n# replay answer 5\n");
    }
}
