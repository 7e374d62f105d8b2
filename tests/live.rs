//! The QEMU node's live stream: the test is the emulated analog front end, writing
//! `accelcal_shared::frontend` frames into the node's USART2 (paced by the wall clock) and reading
//! the node's `FeCtl` messages back, while it talks to the node over the link (USART1). The node's
//! `Samples` blocks must number every set (`first`), carry the fed codes (raw) or the shared f32
//! model-4 calibration of them (bit-exact), and count every lost set in both the status and the
//! jumps of `first`; every block carries the front end's temperature, and with a thermal record
//! the temperature its calibration was evaluated at (bit-exact with the shared tracker).
//!
//! QEMU runs one at a time here (a lock): each keeps its main loop busy (one host core) so that
//! 1 kHz of sets gets through. Needs `qemu-system-arm` and the QEMU build, like `hil.rs`.

use crate::support;

use std::io::{Read, Write};
use std::os::unix::net::UnixStream;
use std::sync::mpsc;
use std::sync::MutexGuard;
use std::time::{Duration, Instant};

use accelcal_line::node::link::{self, Receiver};
use accelcal_line::node::qemu::{BlankSlot, Link, LinkChannel, Qemu, QemuOptions};
use accelcal_shared::contract::QEMU_DEVICE_ID;
use accelcal_shared::frontend::{FeCtl, FeSet, FE_MAX_FRAME};
use accelcal_shared::linear::{LinearCalF32, Model4};
use accelcal_shared::record::Record;
use accelcal_shared::slots::SlotImage;
use accelcal_shared::wire::{
    self, Block, BlockTemp, Codes, FrameDecoder, HostMsg, Info, NodeMsg, Output, RecordStatus, ResetCause,
    Status, MAX_BLOCK, PROTOCOL_VERSION,
};
use support::{node_elf, record_bytes, thermal_model};

/// The fed sets' temperature (0.01 °C), from the set's index: a ramp of 0.1 °C per set from
/// 20 °C, wrapping every 400 sets (so a thermal record's tracker follows a changing temperature).
fn temp_cc_of(index: u32) -> i16 {
    2000 + 10 * (index % 400) as i16
}

/// The fed sets' codes, from the set's index: distinct, over most of the 16-bit range.
fn codes_of(index: u32) -> Codes {
    let i = index.wrapping_mul(2_654_435_761);
    [(i >> 16) as u16, (i >> 8) as u16 ^ 0x5a5a, 1000u16.wrapping_add(index as u16 * 7)]
}

fn model() -> Model4 {
    Model4 {
        u0: [32100.5, 33012.25, 31877.75],
        k: [[1671.2, 8.5, -3.25], [-4.0, 1650.75, 6.5], [2.5, -7.75, 1689.0]],
    }
}

/// A model-4 record for the QEMU node's device id, as `tests/hil.rs` builds them.
fn record() -> Vec<u8> {
    record_bytes(&Record::from_model4(QEMU_DEVICE_ID, 1_800_000_000, &model()))
}

/// The node in QEMU with the test as its front end.
struct Bench {
    _qemu: Qemu,
    /// The link, sending half.
    link: UnixStream,
    /// What the node sent on the link, read by a thread as it comes (QEMU stalls when the link's
    /// socket is full).
    msgs: mpsc::Receiver<NodeMsg>,
    fe: UnixStream,
    /// What the node sent the front end.
    ctl: mpsc::Receiver<FeCtl>,
    _lock: MutexGuard<'static, ()>,
}

impl Bench {
    fn start(record: Option<&[u8]>) -> Bench {
        let lock = support::one_bench();
        let slot0 = record.map(|r| SlotImage::build(r, 1).unwrap().to_vec());
        let opts = QemuOptions {
            frontend: true,
            spin_main_loop: false,
            slots: [slot0, None],
            ..QemuOptions::new(node_elf())
        };
        let mut qemu = Qemu::start(&opts).unwrap();
        let fe = qemu.take_frontend().expect("front-end socket");
        let Some(Link::Socket(link)) = qemu.take_link() else { panic!("a socket link") };
        let mut rx = Receiver::new(link.try_clone().unwrap());
        let (tx, msgs) = mpsc::channel();
        std::thread::spawn(move || {
            // Until the link closes (the test's own timeouts bound its waits).
            let end = Instant::now() + Duration::from_secs(24 * 3600);
            while let Ok(m) = rx.recv(end) {
                if tx.send(m.expect("a NodeMsg frame from the node")).is_err() {
                    break;
                }
            }
        });
        let mut fe_rx = fe.try_clone().unwrap();
        let (tx, ctl) = mpsc::channel();
        std::thread::spawn(move || {
            let mut d = FrameDecoder::<FE_MAX_FRAME>::new();
            let mut buf = [0u8; 64];
            while let Ok(n @ 1..) = fe_rx.read(&mut buf) {
                d.push(&buf[..n], |m: Result<FeCtl, _>| {
                    let _ = tx.send(m.expect("a FeCtl frame from the node"));
                });
            }
        });
        let mut bench = Bench { _qemu: qemu, link, msgs, fe, ctl, _lock: lock };
        assert!(matches!(bench.recv(), Some(NodeMsg::Status(_))), "the boot status comes first");
        bench
    }

    /// The node's next message, within 1 s.
    fn recv(&mut self) -> Option<NodeMsg> {
        self.msgs.recv_timeout(Duration::from_secs(1)).ok()
    }

    /// Feeds the sets of `indices` (codes from [`codes_of`]), one per millisecond of wall time
    /// (1 kHz) or, with `paced` false, as fast as the socket takes them.
    fn feed(&mut self, indices: impl IntoIterator<Item = u32>, paced: bool) {
        let t0 = Instant::now();
        let mut buf = [0u8; FE_MAX_FRAME];
        for (k, i) in indices.into_iter().enumerate() {
            if paced {
                let due = t0 + Duration::from_micros(1000 * k as u64);
                if let Some(wait) = due.checked_duration_since(Instant::now()) {
                    std::thread::sleep(wait);
                }
            }
            let set = FeSet { index: i as u16, codes: codes_of(i), temp_cc: temp_cc_of(i) };
            self.fe.write_all(wire::encode(&set, &mut buf).unwrap()).unwrap();
        }
    }

    /// Sends `msg` and returns the first answer of kind `pick` (Samples are kept in `blocks`).
    fn ask<T>(
        &mut self,
        msg: &HostMsg,
        blocks: &mut Vec<(u32, Block)>,
        pick: impl Fn(NodeMsg) -> Option<T>,
    ) -> T {
        link::send(&mut self.link, msg).unwrap();
        let t0 = Instant::now();
        loop {
            assert!(t0.elapsed() < Duration::from_secs(10), "no answer to {msg:?}");
            match self.recv() {
                Some(NodeMsg::Samples { first, data, .. }) => blocks.push((first, data)),
                Some(m) => {
                    if let Some(t) = pick(m) {
                        return t;
                    }
                }
                None => {}
            }
        }
    }

    /// Collects `Samples` until `sets` sets are in `blocks` (or 10 s have passed).
    fn collect(&mut self, blocks: &mut Vec<(u32, Block)>, sets: usize) {
        let t0 = Instant::now();
        while blocks.iter().map(|(_, b)| b.len()).sum::<usize>() < sets {
            assert!(t0.elapsed() < Duration::from_secs(10), "{} blocks only", blocks.len());
            if let Some(NodeMsg::Samples { first, data, .. }) = self.recv() {
                blocks.push((first, data));
            }
        }
    }

    /// Collects `Samples` with their temperature reports until `sets` sets are in `blocks` (or
    /// 10 s have passed).
    fn collect_temp(&mut self, blocks: &mut Vec<(u32, Block, Option<BlockTemp>)>, sets: usize) {
        let t0 = Instant::now();
        while blocks.iter().map(|(_, b, _)| b.len()).sum::<usize>() < sets {
            assert!(t0.elapsed() < Duration::from_secs(10), "{} blocks only", blocks.len());
            if let Some(NodeMsg::Samples { first, data, temp, .. }) = self.recv() {
                blocks.push((first, data, temp));
            }
        }
    }

    fn status(&mut self, blocks: &mut Vec<(u32, Block)>) -> Status {
        self.ask(&HostMsg::GetStatus, blocks, |m| if let NodeMsg::Status(s) = m { Some(s) } else { None })
    }

    fn set_output(&mut self, output: Output, blocks: &mut Vec<(u32, Block)>) -> Status {
        self.ask(&HostMsg::SetOutput(output), blocks, |m| {
            if let NodeMsg::OutputSet(s) = m {
                Some(s)
            } else {
                None
            }
        })
    }

    /// The next message to the front end, within 5 s.
    fn next_ctl(&self) -> FeCtl {
        self.ctl.recv_timeout(Duration::from_secs(5)).expect("a FeCtl from the node")
    }
}

/// Checks that raw `blocks` carry the codes of the sets their `first` numbers.
fn assert_raw_codes(blocks: &[(u32, Block)]) {
    for (first, b) in blocks {
        let Block::Raw(v) = b else { panic!("block {first} is not raw: {b:?}") };
        for (k, c) in v.iter().enumerate() {
            assert_eq!(*c, codes_of(first + k as u32), "set {}", first + k as u32);
        }
    }
}

/// Checks that `blocks` follow each other without a jump from set `from`, and returns the next.
fn assert_contiguous(blocks: &[(u32, Block)], from: u32) -> u32 {
    let mut next = from;
    for (first, b) in blocks {
        assert_eq!(*first, next, "a jump in `first`");
        next += b.len() as u32;
    }
    next
}

/// (a), (b): sets fed at 1 kHz come back numbered without gaps, as the fed codes in raw output and
/// as the shared f32 calibration of them in calibrated output, and each switch is acknowledged.
#[test]
fn live_sets_come_back_raw_or_calibrated_and_numbered() {
    let mut bench = Bench::start(Some(&record()));
    assert_eq!(bench.next_ctl(), FeCtl::Rate { hz: 1000 });
    let host: LinearCalF32 = model().invert().unwrap().to_f32();
    let mut blocks = Vec::new();

    let s = bench.set_output(Output::Raw, &mut blocks);
    assert_eq!(s.output, Output::Raw);
    bench.feed(0..320, true);
    bench.collect(&mut blocks, 320);
    assert_eq!(blocks.len(), 20);
    assert!(blocks.iter().all(|(_, b)| b.len() == MAX_BLOCK));
    assert_raw_codes(&blocks);
    let next = assert_contiguous(&blocks, 0);

    let s = bench.set_output(Output::Calibrated, &mut blocks);
    assert_eq!(s.output, Output::Calibrated);
    let mut cal = Vec::new();
    bench.feed(320..640, true);
    bench.collect(&mut cal, 320);
    assert_eq!(assert_contiguous(&cal, next), 640);
    for (first, b) in &cal {
        let Block::Calibrated(v) = b else { panic!("block {first} is not calibrated: {b:?}") };
        for (k, a) in v.iter().enumerate() {
            let u = codes_of(first + k as u32);
            assert_eq!(*a, host.apply(u), "set {}: node and host f32 differ", first + k as u32);
        }
    }

    let mut raw = Vec::new();
    assert_eq!(bench.set_output(Output::Raw, &mut raw).output, Output::Raw);
    bench.feed(640..672, true);
    bench.collect(&mut raw, 32);
    assert_raw_codes(&raw);
    assert_eq!(assert_contiguous(&raw, 640), 672);
    let s = bench.status(&mut raw);
    assert_eq!((s.overruns, s.sample_sets, s.bad_frames), (0, 672, 0), "{s:?}");
}

/// (c): who the node is.
#[test]
fn node_tells_who_it_is() {
    let rec = record();
    let mut bench = Bench::start(Some(&rec));
    let info: Info =
        bench.ask(
            &HostMsg::GetInfo,
            &mut Vec::new(),
            |m| if let NodeMsg::Info(i) = m { Some(i) } else { None },
        );
    assert_eq!(&info.device_id, b"QEMU-B-L475E");
    assert_eq!(info.firmware, firmware_version());
    assert_eq!(info.protocol, PROTOCOL_VERSION);
    let crc = u32::from_le_bytes(rec[rec.len() - 4..].try_into().unwrap());
    assert_eq!(info.record, RecordStatus::InUse { slot: 0, sequence: 1, created_unix_s: 1_800_000_000, crc });
    assert_eq!((info.rate_hz, info.overruns, info.output), (1000, 0, Output::Calibrated));
    assert_eq!(info.reset_cause, ResetCause::PowerOn);
}

/// The firmware crate's version, from `firmware/Cargo.toml`.
fn firmware_version() -> [u16; 3] {
    let toml =
        std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../firmware/Cargo.toml")).unwrap();
    let line = toml.lines().find(|l| l.starts_with("version = ")).expect("a package version");
    let v: Vec<u16> = line
        .trim_start_matches("version = ")
        .trim_matches('"')
        .split('.')
        .map(|n| n.parse().unwrap())
        .collect();
    [v[0], v[1], v[2]]
}

/// Sums the jumps of `first` in `blocks` (from set 0), checks every set's codes (raw output), and
/// returns (sets lost by the jumps, sets delivered).
fn jumps_and_sets(blocks: &[(u32, Block)]) -> (u32, u32) {
    assert_raw_codes(blocks);
    let (mut next, mut lost, mut sets) = (0u32, 0u32, 0u32);
    for (first, b) in blocks {
        assert!(*first >= next, "`first` went back: {first} after {next}");
        lost += first - next;
        sets += b.len() as u32;
        next = first + b.len() as u32;
    }
    (lost, sets)
}

/// (d): a front end that skips 100 indices causes 100 overruns that the status and the jump of
/// `first` both report; after a flood, the status's overruns still equal the jumps of `first` and
/// every set fed is delivered, counted lost, or in the last partial block. Every set delivered
/// carries the codes of the index it is numbered with, so none was lost silently.
#[test]
fn lost_sets_are_counted_in_the_status_and_in_first() {
    let mut bench = Bench::start(None);
    assert_eq!(bench.next_ctl(), FeCtl::Rate { hz: 1000 });
    let mut blocks = Vec::new();
    bench.set_output(Output::Raw, &mut blocks);
    // A gap of 100 after set 63.
    bench.feed((0..64).chain(164..228), true);
    bench.collect(&mut blocks, 128);
    let s = bench.status(&mut blocks);
    assert_eq!(jumps_and_sets(&blocks), (100, 128));
    assert_eq!((s.overruns, s.sample_sets), (100, 128), "{s:?}");
    let firsts: Vec<u32> = blocks.iter().map(|(f, _)| *f).collect();
    assert_eq!(firsts, [0, 16, 32, 48, 164, 180, 196, 212]);

    // A flood: 4000 sets as fast as the socket takes them, then 64 paced ones so that a loss at
    // the end of the flood is attached to a set that follows. QEMU hands the bytes to USART2 one at
    // a time as the guest takes them, so whether the ring overflows depends on the host's speed
    // (this machine: 4000 sets in 1.6 s, none lost); what must hold either way is the accounting.
    bench.feed(228..4228, false);
    bench.feed(4228..4292, true);
    let s = settle(&mut bench, &mut blocks, 4292);
    println!("the flood of 4000 sets lost {} of them", s.overruns - 100);
}

/// Asks for the status until every set of the `fed` ones is delivered, counted lost or in the
/// ring's last partial block (at most 10 s), then checks that the status's overruns equal the
/// jumps of `first` in `blocks`, and that every set is accounted for.
fn settle(bench: &mut Bench, blocks: &mut Vec<(u32, Block)>, fed: u32) -> Status {
    let t0 = Instant::now();
    let s = loop {
        let s = bench.status(blocks);
        if fed.saturating_sub(s.sample_sets + s.overruns) < MAX_BLOCK as u32
            || t0.elapsed() > Duration::from_secs(10)
        {
            break s;
        }
        std::thread::sleep(Duration::from_millis(100));
    };
    let (lost, sets) = jumps_and_sets(blocks);
    assert_eq!(s.overruns, lost, "status and `first` disagree: {s:?}");
    assert_eq!(s.sample_sets, sets, "{s:?}");
    let (last_first, last) = blocks.last().unwrap();
    assert_eq!(last_first + last.len() as u32, sets + lost);
    assert!(
        sets + lost <= fed && fed - (sets + lost) < MAX_BLOCK as u32,
        "{fed} fed, {sets} delivered, {lost} lost"
    );
    s
}

/// (e): the node tells the front end its rate at boot and after every accepted change.
#[test]
fn node_tells_the_front_end_its_rate() {
    let mut bench = Bench::start(None);
    assert_eq!(bench.next_ctl(), FeCtl::Rate { hz: 1000 });
    let mut blocks = Vec::new();
    let s = bench.ask(&HostMsg::SetRate { hz: 250 }, &mut blocks, |m| {
        if let NodeMsg::RateSet(s) = m {
            Some(s)
        } else {
            None
        }
    });
    assert_eq!(s.rate_hz, 250);
    assert_eq!(bench.next_ctl(), FeCtl::Rate { hz: 250 });
    let refused = bench.ask(&HostMsg::SetRate { hz: 50 }, &mut blocks, |m| {
        if let NodeMsg::Refused(r) = m {
            Some(r)
        } else {
            None
        }
    });
    assert!(matches!(refused, wire::Refusal::RateOutOfRange { requested_hz: 50, .. }));
    let s = bench.ask(&HostMsg::SetRate { hz: 4000 }, &mut blocks, |m| {
        if let NodeMsg::RateSet(s) = m {
            Some(s)
        } else {
            None
        }
    });
    assert_eq!(s.rate_hz, 4000);
    // The refused rate sent nothing: the next message is the accepted one.
    assert_eq!(bench.next_ctl(), FeCtl::Rate { hz: 4000 });
}

/// The link on a pseudo-terminal (what `accelcal emulate` offers to serial-port programs): QEMU
/// names it, the node answers on it; a record in slot 1 next to an erased slot 0 is in force; the
/// gdbstub answers on its port.
#[test]
fn qemu_offers_the_link_on_a_pty_and_a_gdbstub() {
    let _lock = support::one_bench();
    let port = std::net::TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port();
    let page = SlotImage::build(&record(), 3).unwrap().to_vec();
    let opts = QemuOptions {
        link: LinkChannel::Pty,
        gdb_port: Some(port),
        slots: [None, Some(page)],
        blank: BlankSlot::Erased,
        ..QemuOptions::new(node_elf())
    };
    let mut qemu = Qemu::start(&opts).unwrap();
    let Some(Link::Pty(path)) = qemu.take_link() else { panic!("a pty link") };
    let pty = std::fs::OpenOptions::new().read(true).write(true).open(&path).unwrap();
    let (tx, msgs) = mpsc::channel();
    let mut rx = Receiver::new(pty.try_clone().unwrap());
    std::thread::spawn(move || {
        let end = Instant::now() + Duration::from_secs(24 * 3600);
        while let Ok(m) = rx.recv(end) {
            if tx.send(m).is_err() {
                break;
            }
        }
    });
    let mut w = pty;
    let t0 = Instant::now();
    let info = loop {
        assert!(t0.elapsed() < Duration::from_secs(10), "no Info on {}", path.display());
        link::send(&mut w, &HostMsg::GetInfo).unwrap();
        if let Ok(Ok(NodeMsg::Info(i))) = msgs.recv_timeout(Duration::from_millis(500)) {
            break i;
        }
    };
    assert_eq!(&info.device_id, b"QEMU-B-L475E");
    assert!(matches!(info.record, RecordStatus::InUse { slot: 1, sequence: 3, .. }), "{:?}", info.record);

    let mut gdb = std::net::TcpStream::connect(("127.0.0.1", port)).unwrap();
    gdb.set_read_timeout(Some(Duration::from_secs(5))).unwrap();
    // `?` (why the target stopped), checksum 0x3f.
    gdb.write_all(b"$?#3f").unwrap();
    let mut reply = Vec::new();
    let mut buf = [0u8; 64];
    while !reply.contains(&b'#') {
        let n = gdb.read(&mut buf).unwrap();
        assert!(n > 0, "gdbstub closed");
        reply.extend_from_slice(&buf[..n]);
    }
    let reply = String::from_utf8_lossy(&reply);
    assert!(reply.starts_with("+$T") || reply.starts_with("+$S"), "{reply}");
}

/// Every live block carries the front end's temperature: with a model-4 record its mean only;
/// with a thermal record, in calibrated output, also the filtered temperature the calibration was
/// evaluated at, and the calibrated sets are, bit for bit, the shared f32 path (`ThermalTracker`
/// fed every set since boot, `apply_block`); in raw output the mean only.
#[test]
fn live_blocks_carry_the_front_ends_temperature() {
    use accelcal_shared::thermal::{block_mean, ThermalTracker};
    let temps = |first: u32, n: usize| -> Vec<f32> {
        (first..first + n as u32)
            .map(|i| FeSet { index: 0, codes: [0; 3], temp_cc: temp_cc_of(i) }.temp_c())
            .collect()
    };
    // Model 4: the mean, no applied temperature.
    {
        let mut bench = Bench::start(Some(&record()));
        assert_eq!(bench.next_ctl(), FeCtl::Rate { hz: 1000 });
        bench.feed(0..64, true);
        let mut blocks = Vec::new();
        bench.collect_temp(&mut blocks, 64);
        for (first, b, temp) in &blocks {
            let t = temps(*first, b.len());
            assert_eq!(
                *temp,
                Some(BlockTemp { mean_c: block_mean(&t).unwrap(), applied_c: None, out_of_range: false })
            );
        }
    }
    // A thermal record.
    let model = thermal_model();
    let rec = record_bytes(&model.to_record(QEMU_DEVICE_ID, 1_800_000_000, 9.81));
    let mut bench = Bench::start(Some(&rec));
    assert_eq!(bench.next_ctl(), FeCtl::Rate { hz: 1000 });
    let f = model.to_f32();
    let mut host = ThermalTracker::new(f, f.at(25.0).unwrap());
    bench.feed(0..320, true);
    let mut blocks = Vec::new();
    bench.collect_temp(&mut blocks, 320);
    let mut next = 0;
    for (first, b, temp) in &blocks {
        assert_eq!(*first, next, "a jump in `first`");
        let Block::Calibrated(v) = b else { panic!("block {first} is not calibrated: {b:?}") };
        let t = temps(*first, v.len());
        let codes: Vec<Codes> = (*first..*first + v.len() as u32).map(codes_of).collect();
        let mut out = vec![[0.0f32; 3]; v.len()];
        let flag = host.apply_block(&codes, &t, &mut out);
        assert_eq!(
            v.iter().map(|a| a.map(f32::to_bits)).collect::<Vec<_>>(),
            out.iter().map(|a| a.map(f32::to_bits)).collect::<Vec<_>>(),
            "block {first}"
        );
        let want = ThermalTracker::block_temp(&t, Some((&host, flag)));
        assert_eq!(*temp, want, "block {first}");
        assert!(want.unwrap().applied_c.is_some());
        next += v.len() as u32;
    }
    // Raw output: the mean only.
    let mut ignored = Vec::new();
    assert_eq!(bench.set_output(Output::Raw, &mut ignored).output, Output::Raw);
    assert!(ignored.is_empty(), "{ignored:?}");
    bench.feed(320..352, true);
    let mut raw = Vec::new();
    bench.collect_temp(&mut raw, 32);
    for (first, b, temp) in &raw {
        assert!(matches!(b, Block::Raw(_)), "{b:?}");
        let t = temps(*first, b.len());
        assert_eq!(temp.unwrap().mean_c, block_mean(&t).unwrap());
        assert_eq!(temp.unwrap().applied_c, None);
    }
}
