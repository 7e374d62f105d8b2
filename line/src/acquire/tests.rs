//! Unit tests of `acquire`.

use super::*;
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};

fn noisy(rng: &mut rand_chacha::ChaCha8Rng, mean: [f64; 3], sd: f64) -> [f64; 3] {
    let n = Normal::new(0.0, sd).unwrap();
    mean.map(|m| (m + n.sample(rng)).round())
}

#[test]
fn a_settling_stream_becomes_static_only_after_it_settles() {
    let rule = StaticRule::default();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
    let mut det = SettleDetector::new(rule);
    // An exponential approach of 2000 codes with tau = 100 sets, noise 20 codes.
    let mut at = None;
    for i in 0..3000 {
        let off = 2000.0 * (-(i as f64) / 100.0).exp();
        if det.push(noisy(&mut rng, [32768.0 + off, 30000.0, 40000.0 - off], 20.0)) {
            at = Some(i);
            break;
        }
    }
    let at = at.expect("settles");
    // Static means the remaining offset is within a few standard errors of a window mean
    // (20/sqrt(64) = 2.5 codes): after about tau·ln(2000/7.5) = 560 sets.
    assert!((450..1200).contains(&at), "static after {at} sets");
    // A quiet, quantised stream (every code equal) is static after two windows.
    let mut det = SettleDetector::new(rule);
    let n = (0..200).position(|_| det.push([100.0, 200.0, 300.0])).unwrap();
    assert_eq!(n + 1, 2 * rule.window);
    // A stream that keeps moving never is.
    let mut det = SettleDetector::new(rule);
    assert!(!(0..5000).any(|i| det.push([(1000 + i) as f64, 2000.0, 3000.0])));
    assert!(det.last_z > 10.0);
    assert!(rule.describe().contains("64 sets"));
}

/// A node found at another rate and output before a position (it reset) is set back, with a
/// note each; `t_s` continues after the last row when its sample counter restarted.
#[test]
fn a_node_that_reset_is_set_back_and_t_s_keeps_increasing() {
    use accelcal_shared::wire::{self, Info, NodeMsg, RecordStatus, ResetCause, Status};
    use std::collections::VecDeque;
    use std::io::{self, Read};
    struct Queue(VecDeque<u8>);
    impl Read for Queue {
        fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
            if self.0.is_empty() {
                return Err(io::Error::from(io::ErrorKind::TimedOut));
            }
            let n = buf.len().min(self.0.len());
            for b in buf.iter_mut().take(n) {
                *b = self.0.pop_front().unwrap();
            }
            Ok(n)
        }
    }
    struct Notes(Vec<String>);
    impl Progress for Notes {
        fn position_done(&mut self, _: &PositionReport, _: usize, _: usize, _: Duration) {}
        fn resumed(&mut self, _: usize, _: usize) {}
        fn started(&mut self, _: usize, _: usize, _: &StaticRule) {}
        fn note(&mut self, line: &str) {
            self.0.push(line.to_string());
        }
    }
    let record = RecordStatus::InUse { slot: 0, sequence: 1, created_unix_s: 2, crc: 3 };
    let info = Info {
        device_id: *b"QEMU-B-L475E",
        firmware: [0, 1, 0],
        protocol: wire::PROTOCOL_VERSION,
        record,
        rate_hz: 1000,
        overruns: 0,
        reset_cause: ResetCause::PowerOn,
        output: Output::Calibrated,
    };
    let status = Status {
        protocol: wire::PROTOCOL_VERSION,
        record,
        overruns: 0,
        sample_sets: 0,
        rate_hz: 500,
        bad_frames: 0,
        reset_cause: ResetCause::PowerOn,
        trigger_mismatch: false,
        output: Output::Raw,
    };
    let mut bytes = VecDeque::new();
    for m in [NodeMsg::Info(info), NodeMsg::RateSet(status), NodeMsg::OutputSet(status)] {
        let mut buf = [0u8; wire::MAX_FRAME];
        bytes.extend(wire::encode_sync(&m, &mut buf).unwrap());
    }
    let mut node = Session::from_streams(
        "test",
        Box::new(io::sink()),
        Box::new(Queue(bytes)),
        Duration::from_millis(300),
    );
    let mut notes = Notes(Vec::new());
    ensure_node(&mut node, 500, &mut notes).unwrap();
    assert_eq!(
        notes.0,
        [
            "the node streams at 1000 Hz, the campaign's rate is 500 Hz (did it reset? last reset: PowerOn: \
             power-on or brown-out reset): set back to 500 Hz",
            "the node streams calibrated output (did it reset?): set back to raw",
        ]
    );
    // The counter restarted at 40 after rows up to 12.5 s: the next rows follow the last one.
    let mut clock = Clock { offset: 0.0, last: 12.5 };
    clock.start(40, 500);
    assert!((clock.t(40, 500) - 12.502).abs() < 1e-9 && (clock.t(41, 500) - 12.504).abs() < 1e-9);
    // A counter that went on is kept as it is.
    let mut clock = Clock { offset: 0.0, last: 12.5 };
    clock.start(7000, 500);
    assert!((clock.t(7000, 500) - 14.0).abs() < 1e-12);
}
