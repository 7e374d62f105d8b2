//! Fuzz target: the link's frame decoder ([`FrameDecoder`]) with both message types.
//!
//! Properties checked on every input, for `HostMsg` (what the node decodes) and `NodeMsg` (what the
//! host decodes):
//! - `push` returns (never panics), and yields exactly one result per non-empty `0x00`-terminated
//!   run of bytes, in order;
//! - a run longer than the decoder's limit ([`MAX_FRAME`]) is `TooLong`, never a message, and a
//!   run within the limit is never `TooLong`;
//! - every decoded message encodes again into at most [`MAX_FRAME`] bytes, and that frame decodes
//!   to a message with the same encoding; a decoded `HostMsg` re-encodes within
//!   [`MAX_REQUEST_FRAME`] (with a leading zero), the bound the node's receive ring is sized by;
//! - feeding the same bytes in random pieces gives the same results as feeding them at once;
//! - resynchronisation: after the input, a `0x00` and a valid frame decode to that frame's message.

use core::fmt::Debug;

use accelcal_shared::wire::{
    self, Block, FrameDecoder, FrameError, HostMsg, NodeMsg, RecordFault, RecordStatus, Refusal, ResetCause,
    Status, MAX_BLOCK, MAX_FRAME, MAX_REQUEST_FRAME,
};
use serde::de::DeserializeOwned;
use serde::Serialize;

use crate::rng::Rng;
use crate::Target;

/// The frame target and its tally of decoder results.
#[derive(Default)]
pub struct FrameTarget {
    ok: u64,
    malformed: u64,
    too_long: u64,
    /// The input is being decoded as `HostMsg` (requests must fit `MAX_REQUEST_FRAME`).
    host_pass: bool,
}

/// One decoder result, the message replaced by its canonical frame.
type Event = Result<Vec<u8>, FrameError>;

fn encode<T: Serialize>(msg: &T) -> Result<Vec<u8>, String> {
    let mut buf = [0u8; MAX_FRAME];
    wire::encode(msg, &mut buf).map(|f| f.to_vec()).map_err(|e| format!("re-encoding a decoded message: {e}"))
}

fn decode_events<T: DeserializeOwned + Serialize>(
    dec: &mut FrameDecoder<MAX_FRAME>,
    chunks: &[&[u8]],
) -> Result<Vec<Event>, String> {
    let mut msgs: Vec<Result<T, FrameError>> = Vec::new();
    for c in chunks {
        dec.push(c, |m: Result<T, FrameError>| msgs.push(m));
    }
    msgs.into_iter()
        .map(|m| match m {
            Ok(m) => encode(&m).map(Ok),
            Err(e) => Ok(Err(e)),
        })
        .collect()
}

/// Lengths of the non-empty, terminated runs of non-zero bytes: one decoder result each.
fn runs(input: &[u8]) -> Vec<usize> {
    let mut out = Vec::new();
    let mut run = 0;
    for &b in input {
        if b != 0 {
            run += 1;
        } else if run > 0 {
            out.push(run);
            run = 0;
        }
    }
    out
}

fn host_sentinel() -> HostMsg {
    HostMsg::Replay { seq: 0xC0FFEE, codes: heapless::Vec::from_slice(&[[1, 0, 65535]]).unwrap(), temp: None }
}

fn node_sentinel() -> NodeMsg {
    NodeMsg::Replayed {
        seq: 0xC0FFEE,
        data: Block::Uncalibrated(heapless::Vec::from_slice(&[[7, 0, 9]]).unwrap()),
        temp: None,
    }
}

impl FrameTarget {
    fn check_as<T>(&mut self, input: &[u8], rng: &mut Rng, sentinel: &T) -> Result<(), String>
    where
        T: DeserializeOwned + Serialize + PartialEq + Debug,
    {
        let mut dec = FrameDecoder::<MAX_FRAME>::new();
        let events = decode_events::<T>(&mut dec, &[input])?;
        let runs = runs(input);
        if events.len() != runs.len() {
            return Err(format!("{} results for {} terminated frames", events.len(), runs.len()));
        }
        for (k, (e, &len)) in events.iter().zip(&runs).enumerate() {
            match e {
                Err(FrameError::TooLong) if len <= MAX_FRAME => {
                    return Err(format!("frame {k} of {len} bytes reported too long"))
                }
                Ok(_) | Err(FrameError::Malformed) if len > MAX_FRAME => {
                    return Err(format!("frame {k} of {len} bytes (limit {MAX_FRAME}) was not refused"))
                }
                Ok(frame) if self.host_pass && frame.len() + 1 > MAX_REQUEST_FRAME => {
                    return Err(format!(
                    "frame {k}: a host request of {} bytes (leading zero included) exceeds MAX_REQUEST_FRAME",
                    frame.len() + 1
                ))
                }
                Ok(frame) => {
                    let again = decode_events::<T>(&mut FrameDecoder::new(), &[frame])?;
                    if again.as_slice() != [Ok(frame.clone())] {
                        return Err(format!(
                            "frame {k}: its message re-encodes to a frame that decodes to {again:?}"
                        ));
                    }
                    self.ok += 1;
                }
                Err(FrameError::Malformed) => self.malformed += 1,
                Err(FrameError::TooLong) => self.too_long += 1,
            }
        }
        let mut chunks = Vec::new();
        let mut rest = input;
        while !rest.is_empty() {
            let n = 1 + rng.below(rest.len().min(64));
            chunks.push(&rest[..n]);
            rest = &rest[n..];
        }
        let pieces = decode_events::<T>(&mut FrameDecoder::new(), &chunks)?;
        if pieces != events {
            return Err(format!("fed in {} pieces the bytes decode differently", chunks.len()));
        }
        let mut tail = vec![0u8];
        tail.extend_from_slice(&encode(sentinel)?);
        let mut after: Vec<Result<T, FrameError>> = Vec::new();
        dec.push(&tail, |m| after.push(m));
        match after.last() {
            Some(Ok(m)) if m == sentinel && after.len() <= 2 => Ok(()),
            _ => Err(format!("no resynchronisation: after the input, 0x00 and a valid frame gave {after:?}")),
        }
    }
}

impl Target for FrameTarget {
    fn name(&self) -> &'static str {
        "frame"
    }

    fn seeds(&self) -> Vec<Vec<u8>> {
        let codes: heapless::Vec<[u16; 3], MAX_BLOCK> =
            (0..MAX_BLOCK as u16).map(|i| [i * 4099, 65535 - i, 0x8000 | i]).collect();
        let status = Status {
            protocol: wire::PROTOCOL_VERSION,
            record: RecordStatus::InUse {
                slot: 1,
                sequence: 7,
                created_unix_s: 1_800_000_000,
                crc: 0xdead_beef,
            },
            overruns: 3,
            sample_sets: u32::MAX,
            rate_hz: 1000,
            bad_frames: 128,
            reset_cause: ResetCause::IndependentWatchdog,
            trigger_mismatch: true,
            output: wire::Output::Calibrated,
        };
        let f32s = (0..MAX_BLOCK).map(|i| [i as f32 * 0.5, -9.81, f32::MAX]).collect();
        let fixed = (0..MAX_BLOCK as i32).map(|i| [i << 16, -i, i32::MIN]).collect();
        let frames = [
            encode(&HostMsg::GetStatus),
            encode(&HostMsg::Replay { seq: 300, codes: codes.clone(), temp: None }),
            encode(&HostMsg::Replay {
                seq: 301,
                codes: codes.clone(),
                temp: Some(wire::ReplayTemp {
                    restart: true,
                    temp_c: (0..codes.len()).map(|i| i as f32 - 10.5).collect(),
                }),
            }),
            encode(&host_sentinel()),
            encode(&NodeMsg::Status(status)),
            encode(&NodeMsg::Status(Status {
                record: RecordStatus::Missing(RecordFault::BadRecord(7)),
                ..status
            })),
            encode(&NodeMsg::Samples {
                seq: u32::MAX,
                first: 1 << 20,
                data: Block::Calibrated(f32s),
                temp: Some(accelcal_shared::wire::BlockTemp {
                    mean_c: -40.0,
                    applied_c: Some(f32::MAX),
                    out_of_range: true,
                }),
            }),
            encode(&NodeMsg::Samples {
                seq: 9,
                first: u32::MAX,
                data: Block::Raw(codes.clone()),
                temp: None,
            }),
            encode(&HostMsg::GetInfo),
            encode(&HostMsg::SetOutput(wire::Output::Raw)),
            encode(&NodeMsg::OutputSet(Status { output: wire::Output::Raw, ..status })),
            encode(&NodeMsg::Info(wire::Info {
                device_id: *b"QEMU-B-L475E",
                firmware: [0, 1, 0],
                protocol: wire::PROTOCOL_VERSION,
                record: status.record,
                rate_hz: 1000,
                overruns: 5,
                reset_cause: ResetCause::PowerOn,
                output: wire::Output::Calibrated,
            })),
            encode(&NodeMsg::Replayed { seq: 1, data: Block::CalibratedFixed(fixed), temp: None }),
            encode(&NodeMsg::Replayed {
                seq: 2,
                data: Block::Uncalibrated(codes),
                temp: Some(wire::BlockTemp { mean_c: 25.0, applied_c: None, out_of_range: false }),
            }),
            encode(&HostMsg::SetRate { hz: 4000 }),
            encode(&HostMsg::SetRate { hz: u32::MAX }),
            encode(&NodeMsg::RateSet(Status { rate_hz: 250, reset_cause: ResetCause::Pin, ..status })),
            encode(&NodeMsg::Refused(Refusal::RateOutOfRange {
                requested_hz: 50,
                min_hz: 100,
                max_hz: 4000,
            })),
        ];
        let frames: Vec<Vec<u8>> =
            frames.into_iter().map(|f| f.expect("seed messages fit a frame")).collect();
        let mut seeds = frames.clone();
        // Streams of several frames, as the link carries them.
        for (i, f) in frames.iter().enumerate() {
            let mut s = f.clone();
            s.extend_from_slice(&frames[(i + 3) % frames.len()]);
            s.extend_from_slice(&frames[(i + 5) % frames.len()]);
            seeds.push(s);
        }
        seeds
    }

    fn fix_up(&self, _rng: &mut Rng, _data: &mut Vec<u8>) {}

    fn check(&mut self, input: &[u8], rng: &mut Rng) -> Result<(), String> {
        self.host_pass = true;
        let host = self.check_as::<HostMsg>(input, rng, &host_sentinel());
        self.host_pass = false;
        host?;
        self.check_as::<NodeMsg>(input, rng, &node_sentinel())
    }

    fn summary(&self) -> String {
        format!(
            "frames decoded {} (re-encoding checked), malformed {}, too long {}",
            self.ok, self.malformed, self.too_long
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn seeds_decode_and_garbage_is_survived() {
        let mut t = FrameTarget::default();
        let mut rng = Rng::new(0);
        for s in t.seeds() {
            t.check(&s, &mut rng).unwrap();
        }
        // Node messages read as host messages are malformed (or happen to decode); none is lost.
        assert!(t.ok >= 8, "{}", t.summary());
        let mut garbage = vec![0x11u8; MAX_FRAME + 5];
        garbage.extend_from_slice(&[0x00, 0x05, 0x09, 0x00, 0x42]);
        t.check(&garbage, &mut rng).unwrap();
        assert!(t.too_long >= 2, "{}", t.summary());
    }

    #[test]
    fn a_frame_at_the_limit_is_not_too_long() {
        assert_eq!(runs(&[1, 2, 0, 0, 3, 0, 4]), vec![2, 1]);
        let mut t = FrameTarget::default();
        let mut input = vec![0x01u8; MAX_FRAME];
        input.push(0);
        t.check(&input, &mut Rng::new(1)).unwrap();
        assert_eq!((t.too_long, t.malformed + t.ok), (0, 2));
    }
}
