//! Unit tests of `wire`.

use super::*;

fn decode_all<T: for<'de> Deserialize<'de>>(bytes: &[u8]) -> std::vec::Vec<Result<T, FrameError>> {
    let mut d = FrameDecoder::<MAX_FRAME>::new();
    let mut out = std::vec::Vec::new();
    d.push(bytes, |m| out.push(m));
    out
}

fn codes(v: &[Codes]) -> Vec<Codes, MAX_BLOCK> {
    Vec::from_slice(v).unwrap()
}

#[test]
fn get_status_literal_bytes() {
    // postcard: variant 0 → [0x00]; COBS: [0x01, 0x01]; terminator 0x00.
    let mut buf = [0u8; MAX_FRAME];
    assert_eq!(encode(&HostMsg::GetStatus, &mut buf).unwrap(), &[0x01, 0x01, 0x00]);
    assert_eq!(decode_all::<HostMsg>(&[0x01, 0x01, 0x00]), vec![Ok(HostMsg::GetStatus)]);
}

#[test]
fn replay_literal_bytes() {
    // Replay = variant 1, seq 300 = varint [0xac, 0x02], 2 sets, u16 varints:
    // 1 → [0x01], 2 → [0x02], 0x8000 → [0x80, 0x80, 0x02], then 0, 65535 → [0xff, 0xff, 0x03], 7.
    let raw: &[u8] =
        &[0x01, 0xac, 0x02, 0x02, 0x01, 0x02, 0x80, 0x80, 0x02, 0x00, 0xff, 0xff, 0x03, 0x07, 0x00];
    let msg = HostMsg::Replay { seq: 300, codes: codes(&[[1, 2, 0x8000], [0, 65535, 7]]), temp: None };
    assert_eq!(postcard::to_slice(&msg, &mut [0u8; 64]).unwrap(), raw);
    // (then `None` temperatures: [0x00])
    // COBS: the zeros at offsets 9 and 14 split the body into 9 + 4 + 0 non-zero bytes.
    let framed: &[u8] = &[
        0x0a, 0x01, 0xac, 0x02, 0x02, 0x01, 0x02, 0x80, 0x80, 0x02, 0x05, 0xff, 0xff, 0x03, 0x07, 0x01, 0x00,
    ];
    let mut buf = [0u8; MAX_FRAME];
    assert_eq!(encode(&msg, &mut buf).unwrap(), framed);
    assert_eq!(decode_all::<HostMsg>(framed), vec![Ok(msg)]);
    // With temperatures: Some = [0x01], restart = [0x01], 1 temperature, f32 LE 25.5.
    let temp = ReplayTemp { restart: true, temp_c: Vec::from_slice(&[25.5]).unwrap() };
    let msg = HostMsg::Replay { seq: 1, codes: codes(&[[1, 2, 3]]), temp: Some(temp) };
    let raw: &[u8] = &[0x01, 0x01, 0x01, 0x01, 0x02, 0x03, 0x01, 0x01, 0x01, 0x00, 0x00, 0xcc, 0x41];
    assert_eq!(postcard::to_slice(&msg, &mut [0u8; 64]).unwrap(), raw);
    let frame = encode(&msg, &mut buf).unwrap().to_vec();
    assert_eq!(decode_all::<HostMsg>(&frame), vec![Ok(msg)]);
}

#[test]
fn replayed_answer_literal_bytes() {
    // Replayed = variant 2, seq 5, Calibrated = variant 0, 1 set of f32 LE: 1.0, -2.5, 0.0.
    // Then the temperature: None = [0x00].
    let msg = NodeMsg::Replayed {
        seq: 5,
        data: Block::Calibrated(Vec::from_slice(&[[1.0, -2.5, 0.0]]).unwrap()),
        temp: None,
    };
    let raw: &[u8] = &[
        0x02, 0x05, 0x00, 0x01, 0x00, 0x00, 0x80, 0x3f, 0x00, 0x00, 0x20, 0xc0, 0x00, 0x00, 0x00, 0x00, 0x00,
    ];
    assert_eq!(postcard::to_slice(&msg, &mut [0u8; 64]).unwrap(), raw);
    let mut buf = [0u8; MAX_FRAME];
    let frame = encode(&msg, &mut buf).unwrap().to_vec();
    assert_eq!(decode_all::<NodeMsg>(&frame), vec![Ok(msg)]);
}

#[test]
fn status_round_trip_and_largest_message_fits() {
    let st = NodeMsg::Status(Status {
        protocol: PROTOCOL_VERSION,
        record: RecordStatus::InUse { slot: 1, sequence: u32::MAX, created_unix_s: u64::MAX, crc: u32::MAX },
        overruns: u32::MAX,
        sample_sets: u32::MAX,
        rate_hz: 1000,
        bad_frames: 3,
        reset_cause: ResetCause::IndependentWatchdog,
        trigger_mismatch: true,
        output: Output::Raw,
    });
    let big = NodeMsg::Samples {
        seq: u32::MAX,
        first: u32::MAX,
        data: Block::Calibrated(Vec::from_slice(&[[f32::MAX; 3]; MAX_BLOCK]).unwrap()),
        temp: Some(BlockTemp { mean_c: f32::MAX, applied_c: Some(f32::MAX), out_of_range: true }),
    };
    let info = NodeMsg::Info(Info {
        device_id: [0xff; 12],
        firmware: [u16::MAX; 3],
        protocol: PROTOCOL_VERSION,
        record: RecordStatus::InUse { slot: 1, sequence: u32::MAX, created_unix_s: u64::MAX, crc: u32::MAX },
        rate_hz: u32::MAX,
        overruns: u32::MAX,
        reset_cause: ResetCause::Pin,
        output: Output::Calibrated,
    });
    let mut buf = [0u8; MAX_FRAME];
    assert_eq!(encode_sync(&big, &mut buf).unwrap().len(), MAX_NODE_FRAME, "the largest node message");
    for m in [st, big, info] {
        let frame = encode_sync(&m, &mut buf).unwrap().to_vec();
        assert!(frame.len() <= MAX_NODE_FRAME);
        assert_eq!(decode_all::<NodeMsg>(&frame), vec![Ok(m)]);
    }
}

#[test]
fn set_rate_and_its_answers_literal_bytes() {
    // SetRate = variant 2, hz 4000 = varint [0xa0, 0x1f].
    let mut buf = [0u8; MAX_FRAME];
    assert_eq!(
        postcard::to_slice(&HostMsg::SetRate { hz: 4000 }, &mut [0u8; 8]).unwrap(),
        &[0x02, 0xa0, 0x1f]
    );
    let framed: &[u8] = &[0x04, 0x02, 0xa0, 0x1f, 0x00];
    assert_eq!(encode(&HostMsg::SetRate { hz: 4000 }, &mut buf).unwrap(), framed);
    // Refused = variant 4, RateOutOfRange = variant 0, 50, 100, 4000.
    let refused = NodeMsg::Refused(Refusal::RateOutOfRange { requested_hz: 50, min_hz: 100, max_hz: 4000 });
    assert_eq!(postcard::to_slice(&refused, &mut [0u8; 16]).unwrap(), &[0x04, 0x00, 50, 100, 0xa0, 0x1f]);
    // RateSet = variant 3 followed by the status; the status ends with the reset cause
    // (PowerOn = variant 7) and the mismatch flag.
    let status = Status {
        protocol: PROTOCOL_VERSION,
        record: RecordStatus::Missing(RecordFault::NoSlot),
        overruns: 0,
        sample_sets: 0,
        rate_hz: 250,
        bad_frames: 0,
        reset_cause: ResetCause::PowerOn,
        trigger_mismatch: false,
        output: Output::Calibrated,
    };
    let raw: &[u8] = &[0x03, PROTOCOL_VERSION, 0x01, 0x00, 0, 0, 0xfa, 0x01, 0, 0x07, 0x00, 0x00];
    assert_eq!(postcard::to_slice(&NodeMsg::RateSet(status), &mut [0u8; 32]).unwrap(), raw);
    let frame = encode(&NodeMsg::RateSet(status), &mut buf).unwrap().to_vec();
    assert_eq!(decode_all::<NodeMsg>(&frame), vec![Ok(NodeMsg::RateSet(status))]);
}

#[test]
fn info_and_output_literal_bytes() {
    // GetInfo = variant 3; SetOutput = variant 4 with Raw = variant 1.
    let mut buf = [0u8; MAX_FRAME];
    assert_eq!(encode(&HostMsg::GetInfo, &mut buf).unwrap(), &[0x02, 0x03, 0x00]);
    assert_eq!(encode(&HostMsg::SetOutput(Output::Raw), &mut buf).unwrap(), &[0x03, 0x04, 0x01, 0x00]);
    // Samples = variant 1, seq 2, first 300 = [0xac, 0x02], Raw = block variant 3, one set.
    // No temperature: Option None = 0x00.
    let msg = NodeMsg::Samples { seq: 2, first: 300, data: Block::Raw(codes(&[[1, 2, 3]])), temp: None };
    assert_eq!(
        postcard::to_slice(&msg, &mut [0u8; 32]).unwrap(),
        &[0x01, 0x02, 0xac, 0x02, 0x03, 0x01, 0x01, 0x02, 0x03, 0x00]
    );
}

#[test]
fn rates_are_checked_against_the_stated_range() {
    assert_eq!(check_rate(RATE_MIN_HZ), Ok(()));
    assert_eq!(check_rate(RATE_MAX_HZ), Ok(()));
    assert_eq!(check_rate(DEFAULT_RATE_HZ), Ok(()));
    for hz in [0, RATE_MIN_HZ - 1, RATE_MAX_HZ + 1, u32::MAX] {
        let e = check_rate(hz).unwrap_err();
        assert_eq!(e, Refusal::RateOutOfRange { requested_hz: hz, min_hz: 100, max_hz: 4000 });
    }
    assert_eq!(
        std::format!("{}", check_rate(5000).unwrap_err()),
        "RateOutOfRange: sampling rate 5000 Hz refused, the node accepts 100..=4000 Hz"
    );
}

#[test]
fn every_request_fits_max_request_frame_and_the_ring_holds_the_requests_in_flight() {
    let mut buf = [0u8; MAX_FRAME];
    let temp =
        || Some(ReplayTemp { restart: true, temp_c: Vec::from_slice(&[f32::MAX; MAX_BLOCK]).unwrap() });
    let largest = HostMsg::Replay { seq: u32::MAX, codes: codes(&[[65535; 3]; MAX_BLOCK]), temp: temp() };
    for m in [
        largest,
        HostMsg::GetStatus,
        HostMsg::SetRate { hz: u32::MAX },
        HostMsg::GetInfo,
        HostMsg::SetOutput(Output::Raw),
    ] {
        let n = encode_sync(&m, &mut buf).unwrap().len();
        assert!(n <= MAX_REQUEST_FRAME, "{m:?}: {n} bytes");
    }
    let n = encode_sync(
        &HostMsg::Replay { seq: u32::MAX, codes: codes(&[[65535; 3]; MAX_BLOCK]), temp: temp() },
        &mut buf,
    )
    .unwrap()
    .len();
    assert_eq!(n, MAX_REQUEST_FRAME, "the bound is tight");
    assert_eq!(MAX_REQUESTS_IN_FLIGHT, 9);
}

#[test]
fn reset_cause_from_rcc_csr() {
    // RCC_CSR reset value after a power-on (RM0351 §6.4.29): BORRSTF | PINRSTF | MSISRANGE 6.
    assert_eq!(ResetCause::from_rcc_csr(0x0C00_0600), ResetCause::PowerOn);
    let bit = |b: u32| 1u32 << b;
    let pin = bit(26);
    assert_eq!(ResetCause::from_rcc_csr(pin), ResetCause::Pin);
    assert_eq!(ResetCause::from_rcc_csr(bit(28) | pin), ResetCause::Software);
    assert_eq!(ResetCause::from_rcc_csr(bit(29) | pin), ResetCause::IndependentWatchdog);
    assert_eq!(ResetCause::from_rcc_csr(bit(30) | pin), ResetCause::WindowWatchdog);
    assert_eq!(ResetCause::from_rcc_csr(bit(31) | pin), ResetCause::LowPower);
    assert_eq!(ResetCause::from_rcc_csr(bit(24) | pin), ResetCause::Firewall);
    assert_eq!(ResetCause::from_rcc_csr(bit(25) | pin), ResetCause::OptionByte);
    // Bits below 24 (oscillator settings, RMVF) are not reset flags.
    assert_eq!(ResetCause::from_rcc_csr(0x00FF_FFFF), ResetCause::Unknown);
    assert_eq!(ResetCause::from_rcc_csr(0), ResetCause::Unknown);
    // A watchdog reset while the power-on flags were never cleared is still the watchdog's.
    assert_eq!(ResetCause::from_rcc_csr(0x0C00_0600 | bit(29)), ResetCause::IndependentWatchdog);
    assert_eq!(
        std::format!("{}", ResetCause::IndependentWatchdog),
        "IndependentWatchdog: the watchdog was not fed in time"
    );
}

#[test]
fn garbage_is_reported_and_the_decoder_resynchronises() {
    let mut bytes = vec![0x05, 0x09, 0x00]; // COBS says 4 more bytes, only 1 follows
    bytes.extend_from_slice(&[0x02, 0x63, 0x00]); // variant 99: unknown
    bytes.extend_from_slice(&[0x00, 0x00]); // empty frames: skipped
    bytes.extend_from_slice(&[0x11; MAX_FRAME + 10]); // too long
    bytes.push(0x00);
    bytes.extend_from_slice(&[0x01, 0x01, 0x00]); // GetStatus
    let got = decode_all::<HostMsg>(&bytes);
    assert_eq!(
        got,
        vec![
            Err(FrameError::Malformed),
            Err(FrameError::Malformed),
            Err(FrameError::TooLong),
            Ok(HostMsg::GetStatus)
        ]
    );
}

#[test]
fn frames_split_across_pushes_decode() {
    let msg = HostMsg::Replay { seq: 9, codes: codes(&[[10, 20, 30]; 16]), temp: None };
    let mut buf = [0u8; MAX_FRAME];
    let frame = encode(&msg, &mut buf).unwrap().to_vec();
    let mut d = FrameDecoder::<MAX_FRAME>::new();
    let mut out = std::vec::Vec::new();
    for chunk in frame.chunks(3) {
        d.push(chunk, |m: Result<HostMsg, _>| out.push(m));
    }
    assert_eq!(out, vec![Ok(msg)]);
}

#[test]
fn replay_with_more_than_max_block_sets_is_malformed() {
    // Variant 1, seq 0, 17 sets of [1, 1, 1]: heapless refuses the 17th.
    let mut raw = vec![0x01, 0x00, 17];
    raw.extend(std::iter::repeat_n(0x01, 17 * 3));
    let mut framed = vec![0u8; 128];
    let n = cobs_encode(&raw, &mut framed);
    framed.truncate(n);
    framed.push(0);
    assert_eq!(decode_all::<HostMsg>(&framed), vec![Err(FrameError::Malformed)]);
}

/// Plain COBS encoder for the tests (no zero in the input in this use).
fn cobs_encode(src: &[u8], dst: &mut [u8]) -> usize {
    let mut out = 1;
    let mut code_at = 0;
    let mut code = 1u8;
    for &b in src {
        if b == 0 || code == 0xff {
            dst[code_at] = code;
            code_at = out;
            out += 1;
            code = 1;
            if b == 0 {
                continue;
            }
        }
        dst[out] = b;
        out += 1;
        code += 1;
    }
    dst[code_at] = code;
    out
}

#[test]
fn record_faults_are_named_in_words() {
    use crate::record::RecordError as E;
    let errors = [
        E::Truncated,
        E::BadMagic,
        E::UnsupportedVersion(3),
        E::BadLength,
        E::BadChannelCount,
        E::BadTerms,
        E::BadCrc,
        E::NonFinite,
        E::BufferTooSmall,
        E::BadThermal,
    ];
    // Every code's name is its error's variant name.
    for e in errors {
        let debug = std::format!("{e:?}");
        let name = record_error_name(record_error_code(e)).unwrap();
        assert_eq!(debug.split('(').next().unwrap(), name);
    }
    assert_eq!(record_error_name(0), None);
    assert_eq!(record_error_name(11), None);
    let shown = |f: RecordFault| std::format!("{f}");
    assert_eq!(
        shown(RecordFault::BadRecord(record_error_code(E::UnsupportedVersion(3)))),
        "BadRecord(UnsupportedVersion): the record in force is invalid: its format version is not \
         1 or 2, the ones the node reads"
    );
    assert_eq!(
        shown(RecordFault::BadRecord(200)),
        "BadRecord(200): the record in force is invalid (reason code unknown to this host)"
    );
    assert!(shown(RecordFault::NotModel4).starts_with("NotModel4: the node applies model 4"));
    assert!(shown(RecordFault::WrongDevice).starts_with("WrongDevice: "));
}

#[test]
fn random_bytes_never_panic() {
    let mut s = 0x2545_F491_4F6C_DD1Du64;
    let mut d = FrameDecoder::<MAX_FRAME>::new();
    let mut frames = 0;
    for _ in 0..20_000 {
        let mut chunk = [0u8; 64];
        for b in &mut chunk {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            // Zeros about one byte in 16, so many short frames form.
            *b = if s & 0xf == 0 { 0 } else { (s >> 32) as u8 };
        }
        d.push(&chunk, |_: Result<NodeMsg, _>| frames += 1);
        d.push(&chunk, |_: Result<HostMsg, _>| frames += 1);
    }
    assert!(frames > 10_000);
}

/// A node's status frame that lost its first byte (a port opened mid-frame, or a byte lost on the
/// line) is the bytes 04 00 00 01 …: the start of a `Refused(RateOutOfRange { 0, 1, created })`,
/// with the rest of the status left over. It once reached a station's verification as the
/// node's refusal (max_hz = the record's creation time). Left-over bytes make it malformed.
#[test]
fn a_frame_that_lost_its_first_byte_is_malformed_not_another_message() {
    let status = Status {
        protocol: PROTOCOL_VERSION,
        record: RecordStatus::InUse { slot: 0, sequence: 1, created_unix_s: 1_796_525_864, crc: 0xdead_beef },
        overruns: 0,
        sample_sets: 12_000,
        rate_hz: 1000,
        bad_frames: 0,
        reset_cause: ResetCause::PowerOn,
        trigger_mismatch: false,
        output: Output::Calibrated,
    };
    let mut buf = [0u8; MAX_FRAME];
    let frame = encode_sync(&NodeMsg::Status(status), &mut buf).unwrap().to_vec();
    assert_eq!(&frame[..3], &[0x00, 0x01, 0x02], "a leading zero, then the COBS code of the variant's 0x00");
    let shifted = &frame[2..];
    // What the old decoder (postcard's `from_bytes_cobs`, left-over bytes ignored) made of it.
    let mut body = shifted[..shifted.len() - 1].to_vec();
    let old: NodeMsg = postcard::from_bytes_cobs(&mut body).unwrap();
    assert_eq!(
        old,
        NodeMsg::Refused(Refusal::RateOutOfRange { requested_hz: 0, min_hz: 1, max_hz: 1_796_525_864 })
    );
    assert_eq!(decode_all::<NodeMsg>(shifted), vec![Err(FrameError::Malformed)]);
    // The whole frame, read from its leading zero or from its body, is the status.
    assert_eq!(decode_all::<NodeMsg>(&frame), vec![Ok(NodeMsg::Status(status))]);
    assert_eq!(decode_all::<NodeMsg>(&frame[1..]), vec![Ok(NodeMsg::Status(status))]);
}

/// Any message with a byte appended inside its frame is malformed: exactly one message per frame.
#[test]
fn a_frame_with_bytes_after_its_message_is_malformed() {
    let mut body = postcard::to_slice(&HostMsg::SetRate { hz: 4000 }, &mut [0u8; 8]).unwrap().to_vec();
    body.push(0x00);
    let mut framed = [0u8; 16];
    let n = cobs::encode(&body, &mut framed);
    let mut frame = framed[..n].to_vec();
    frame.push(0);
    assert_eq!(decode_all::<HostMsg>(&frame), vec![Err(FrameError::Malformed)]);
}
