//! Load test of the node in QEMU: 100,000 sample sets replayed through the link as fast as the
//! node takes them; every answer must arrive, in order, with the right number of sets and the same
//! f32 values as the host's f32 path, and the node's final status must show no overrun and no bad
//! frame. Prints the replay rate (sample sets per second of wall time).
//!
//! It runs alone among the emulated benches (`support::one_bench`, and nextest's test group
//! `bench`). Needs `qemu-system-arm` and the QEMU build, like `hil.rs` (`cargo xtask test`).

use crate::support;

use std::time::Instant;

use accelcal_line::node::hil::{replay, HilOptions};
use accelcal_shared::linear::Model4;
use accelcal_shared::record::Record;
use accelcal_shared::wire::MAX_BLOCK;
use support::{node_elf, record_bytes};

/// The number of sample sets; `ACCELCAL_LOAD_SETS` overrides it.
const SETS: usize = 100_000;

fn sets() -> usize {
    std::env::var("ACCELCAL_LOAD_SETS").map_or(SETS, |v| v.parse().expect("ACCELCAL_LOAD_SETS: a number"))
}

/// A model-4 record for the QEMU board's device id.
fn record(m: &Model4) -> Vec<u8> {
    record_bytes(&Record::from_model4(accelcal_shared::contract::QEMU_DEVICE_ID, 1_800_000_000, m))
}

/// Deterministic code sets over the whole 16-bit range (xorshift), so no two blocks are alike.
fn codes(n: usize) -> Vec<[u16; 3]> {
    let mut s = 0x9E37_79B9_7F4A_7C15u64;
    (0..n)
        .map(|_| {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            [s as u16, (s >> 16) as u16, (s >> 32) as u16]
        })
        .collect()
}

#[test]
fn node_replays_100000_sets_in_order_without_overruns() {
    let _bench = support::one_bench();
    let m = Model4 {
        u0: [32100.5, 33012.25, 31877.75],
        k: [[1671.2, 8.5, -3.25], [-4.0, 1650.75, 6.5], [2.5, -7.75, 1689.0]],
    };
    let host = m.invert().unwrap().to_f32();
    let n = sets();
    let codes = codes(n);
    let t0 = Instant::now();
    // `replay` fails unless every answer comes back in order (`seq`) with as many sets as were sent.
    let opts = HilOptions {
        // The QEMU board's 20 µs SysTick keeps QEMU's main loop taking bytes; the spinning
        // chardev on top of it only competes with the vCPU thread (measurements.md has the times).
        spin_main_loop: std::env::var_os("ACCELCAL_LOAD_SPIN").is_some(),
        ..HilOptions::new(node_elf())
    };
    let run = replay(&opts, &record(&m), &codes).unwrap();
    let secs = t0.elapsed().as_secs_f64();
    assert_eq!(run.accel.len(), n);
    for (i, (a, u)) in run.accel.iter().zip(&codes).enumerate() {
        assert_eq!(*a, host.apply(*u), "set {i}: node and host f32 differ (lost or reordered set?)");
    }
    assert_eq!(run.status.overruns, 0, "{:?}", run.status);
    assert_eq!(run.status.bad_frames, 0, "{:?}", run.status);
    println!(
        "replayed {n} sample sets ({} requests of {MAX_BLOCK}) through the QEMU node in {secs:.1} s \
         (boot included) = {:.0} sets/s; final status {:?}",
        n.div_ceil(MAX_BLOCK),
        n as f64 / secs,
        run.status
    );
}
