//! Hardware-in-the-loop tests: the node firmware's QEMU build, judged by its binary link protocol.
//!
//! Simulate a triad campaign, fit model 4 and write a record with the `accelcal` binary, replay
//! the campaign through the node in QEMU (`accelcal hil`), and check the node's f32 output against
//! the host's f64 calibration (per axis within `LinearCal::f32_error_bound`) and against the true
//! acceleration from the dividing head's angles.
//!
//! Needs `qemu-system-arm` (>= 9) and the QEMU build of the firmware; `cargo xtask test` provides
//! both. The ELF is taken from `ACCELCAL_NODE_QEMU_ELF`, else from the firmware's release target
//! directory. A missing prerequisite fails the test with the command that provides it.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use accelcal::campaign::Campaign;
use accelcal::node::hil::{HilOptions, QemuNode};
use accelcal_shared::kinematics::gravity;
use accelcal_shared::record::Record;
use accelcal_shared::slots::{SlotImage, SLOT_SIZE};
use accelcal_shared::wire::{Block, HostMsg, NodeMsg, RecordFault, RecordStatus};
use accelcal_shared::G_STANDARD;

/// Hex of the QEMU node's device id, "QEMU-B-L475E".
const QEMU_ID_HEX: &str = "51454d552d422d4c34373545";

fn node_elf() -> PathBuf {
    let elf = std::env::var_os("ACCELCAL_NODE_QEMU_ELF").map(PathBuf::from).unwrap_or_else(|| {
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../firmware/target/thumbv7em-none-eabihf/release/node-qemu")
    });
    assert!(
        elf.is_file(),
        "{} is missing: build it with `cargo xtask test` (or `cd firmware && cargo build --release \
         --features board-qemu --bin node-qemu`)",
        elf.display()
    );
    let qemu_ok = Command::new("qemu-system-arm")
        .args(["-M", "help"])
        .output()
        .is_ok_and(|o| String::from_utf8_lossy(&o.stdout).contains("b-l475e-iot01a"));
    assert!(
        qemu_ok,
        "qemu-system-arm with the b-l475e-iot01a machine is missing: run `bash scripts/setup-qemu.sh`"
    );
    elf
}

/// The fixed-point QEMU build (`cargo xtask test` builds it into firmware/target/fixed-point).
fn node_fixed_elf() -> PathBuf {
    let elf = std::env::var_os("ACCELCAL_NODE_QEMU_FIXED_ELF").map(PathBuf::from).unwrap_or_else(|| {
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../firmware/target/fixed-point/thumbv7em-none-eabihf/release/node-qemu")
    });
    assert!(
        elf.is_file(),
        "{} is missing: build it with `cargo xtask test` (or `cd firmware && cargo build --release \
         --features board-qemu,fixed-point --bin node-qemu --target-dir target/fixed-point`)",
        elf.display()
    );
    node_elf(); // checks QEMU too
    elf
}

fn accelcal(args: &[&str]) -> Output {
    let out = Command::new(env!("CARGO_BIN_EXE_accelcal")).args(args).output().expect("run accelcal");
    out
}

fn ok(args: &[&str]) -> String {
    let out = accelcal(args);
    assert!(
        out.status.success(),
        "accelcal {args:?} failed: {}\n{}",
        String::from_utf8_lossy(&out.stderr),
        String::from_utf8_lossy(&out.stdout)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// Simulated triad campaign and its LSQ model-4 record for the device id `id_hex`.
fn campaign_and_record(dir: &Path, id_hex: &str) -> (PathBuf, PathBuf) {
    let camp = dir.join("campaign.csv");
    let rec = dir.join("node.rec");
    ok(&["simulate", "--out", s(&camp), "--seed", "11", "--samples", "100"]);
    ok(&["fit", s(&camp), "--record", s(&rec), "--device-id", id_hex, "--created", "1800000000"]);
    (camp, rec)
}

fn read_out(path: &Path) -> Vec<(f64, [f64; 3])> {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some("t_s,ax,ay,az"));
    lines
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            assert_eq!(f.len(), 4, "{l}");
            // The node's f32 values, exactly as printed.
            let a = |i: usize| f[i].parse::<f32>().unwrap() as f64;
            (f[0].parse().unwrap(), [a(1), a(2), a(3)])
        })
        .collect()
}

#[test]
fn node_in_qemu_matches_host_calibration_and_truth() {
    let elf = node_elf();
    let dir = tempfile::tempdir().unwrap();
    let (camp_path, rec_path) = campaign_and_record(dir.path(), QEMU_ID_HEX);
    let out_path = dir.path().join("node.csv");
    let stdout =
        ok(&["hil", "--qemu", s(&elf), "--record", s(&rec_path), s(&camp_path), "--out", s(&out_path)]);
    assert!(stdout.contains("record slot 0 seq 1 created 1800000000"), "{stdout}");
    assert!(stdout.contains("bad frames 0"), "{stdout}");

    let camp = Campaign::read(&camp_path).unwrap();
    let rec = Record::parse(&std::fs::read(&rec_path).unwrap()).unwrap();
    let cal = rec.model4().expect("model 4 record").invert().unwrap();
    let bound = cal.f32_error_bound();
    let got = read_out(&out_path);
    assert_eq!(got.len(), camp.t_s.len());
    let ch = |n: &str| &camp.channels.iter().find(|c| c.name == n).unwrap().codes;
    let (x, y, z) = (ch("x"), ch("y"), ch("z"));

    // 1. The node's arithmetic: within the stated f32 bound of the host's f64, every sample set,
    // and bit for bit what the shared crate's f32 path computes on the host (IEEE single, same
    // operations; the M4F's VMLA rounds like a multiply then an add).
    let f32cal = cal.to_f32();
    let mut worst = 0.0f64;
    for (row, (t, a)) in got.iter().enumerate() {
        assert_eq!(*t, camp.t_s[row]);
        let want = cal.apply([x[row], y[row], z[row]]);
        let host_f32 = f32cal.apply([x[row] as u16, y[row] as u16, z[row] as u16]);
        assert_eq!(a.map(|v| v as f32), host_f32, "row {row}: node and host f32 differ");
        for i in 0..3 {
            let e = (a[i] - want[i]).abs();
            assert!(
                e <= bound[i],
                "row {row} axis {i}: node {} host {} (|e| {e} > {})",
                a[i],
                want[i],
                bound[i]
            );
            worst = worst.max(e / bound[i]);
        }
    }
    // The comparison is not vacuous: the node does round (f32), and the bound is tight enough
    // that a wrong coefficient or a lost offset would break it (bound < 1e-4 m/s²).
    assert!(worst > 0.0, "node output identical to f64: suspicious");
    assert!(bound.iter().all(|&b| b < 1e-4), "{bound:?}");

    // 2. Against the truth: per position (dwell), the node's mean acceleration is within 0.03 m/s²
    // of gravity at the commanded angles. The simulator's noise is 80 codes ≈ 0.048 m/s² per
    // sample; the mean of 100 samples has σ ≈ 0.0048 m/s², so the bound is about 6σ (the fit's
    // own error, from the same noise, is smaller still).
    let mut start = 0;
    let mut positions = 0;
    while start < got.len() {
        let mut end = start;
        while end < got.len()
            && camp.alpha_deg[end] == camp.alpha_deg[start]
            && camp.beta_deg[end] == camp.beta_deg[start]
        {
            end += 1;
        }
        let truth = gravity(camp.alpha_deg[start], camp.beta_deg[start], G_STANDARD);
        for i in 0..3 {
            let mean = got[start..end].iter().map(|(_, a)| a[i]).sum::<f64>() / (end - start) as f64;
            assert!(
                (mean - truth[i]).abs() < 0.03,
                "position at row {start} axis {i}: node mean {mean}, truth {}",
                truth[i]
            );
        }
        positions += 1;
        start = end;
    }
    assert!(positions >= 60, "{positions}");
}

#[test]
fn node_refuses_a_record_for_another_device() {
    let elf = node_elf();
    let dir = tempfile::tempdir().unwrap();
    let (camp, rec) = campaign_and_record(dir.path(), "0102030405060708090a0b0c");
    let out_path = dir.path().join("node.csv");
    let out = accelcal(&["hil", "--qemu", s(&elf), "--record", s(&rec), s(&camp), "--out", s(&out_path)]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("did not accept the record: WrongDevice"), "{stderr}");
    assert!(!out_path.exists());
}

#[test]
fn hil_names_a_missing_channel_and_exits_2() {
    let elf = node_elf();
    let dir = tempfile::tempdir().unwrap();
    let camp = dir.path().join("block.csv");
    ok(&["simulate", "--out", s(&camp), "--layout", "block:3", "--samples", "2"]);
    let (_, rec) = campaign_and_record(dir.path(), QEMU_ID_HEX);
    let out = accelcal(&[
        "hil",
        "--qemu",
        s(&elf),
        "--record",
        s(&rec),
        s(&camp),
        "--out",
        s(&dir.path().join("o.csv")),
    ]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("block.csv: no channel `x`"), "{stderr}");
}

fn replay_msg(seq: u32, codes: &[[u16; 3]]) -> HostMsg {
    HostMsg::Replay { seq, codes: heapless::Vec::from_slice(codes).unwrap() }
}

/// Without a valid record the node says so and returns raw codes flagged uncalibrated, unchanged.
#[test]
fn node_without_record_answers_uncalibrated() {
    let mut node = QemuNode::start(&HilOptions::new(node_elf()), None).unwrap();
    let status = node.status().unwrap();
    assert_eq!(status.record, RecordStatus::Missing(RecordFault::NoSlot));
    assert_eq!(status.protocol, 1);
    let codes = [[1, 2, 3], [65535, 0, 32768]];
    let answer = node.request(&replay_msg(5, &codes)).unwrap();
    let want =
        NodeMsg::Replayed { seq: 5, data: Block::Uncalibrated(heapless::Vec::from_slice(&codes).unwrap()) };
    assert_eq!(answer, want);
}

/// A slot that is intact but holds a record whose own CRC fails is refused with that reason; a
/// malformed host frame is counted, and the node keeps serving.
#[test]
fn node_refuses_a_corrupt_record_and_survives_garbage() {
    let dir = tempfile::tempdir().unwrap();
    let (_, rec_path) = campaign_and_record(dir.path(), QEMU_ID_HEX);
    let mut rec = std::fs::read(&rec_path).unwrap();
    let page = SlotImage::build(&rec, 1).unwrap();
    // Flip a coefficient bit and rebuild only the slot's CRC: the slot is intact, the record not.
    rec[40] ^= 0x01;
    let mut bad = page;
    bad[16..16 + rec.len()].copy_from_slice(&rec);
    let mut hdr_and_rec = bad[4..12].to_vec();
    hdr_and_rec.extend_from_slice(&rec);
    bad[12..16].copy_from_slice(&accelcal_shared::record::crc32(&hdr_and_rec).to_le_bytes());
    assert_eq!(bad.len(), SLOT_SIZE);

    let mut node = QemuNode::start(&HilOptions::new(node_elf()), Some(&bad)).unwrap();
    let status = node.status().unwrap();
    // 7 = RecordError::BadCrc (wire::record_error_code).
    assert_eq!(status.record, RecordStatus::Missing(RecordFault::BadRecord(7)));
    // A frame with an unknown message variant, then a good request. (Requests sent while the node
    // was still booting may have been heard in part, so count from the current value.)
    let before = node.status().unwrap().bad_frames;
    node.send_raw(&[0x00, 0x02, 0x63, 0x00]).unwrap();
    let answer = node.request(&replay_msg(1, &[[10, 20, 30]])).unwrap();
    assert!(matches!(answer, NodeMsg::Replayed { seq: 1, data: Block::Uncalibrated(_) }), "{answer:?}");
    assert_eq!(node.status().unwrap().bad_frames, before + 1);
}

/// The fixed-point build computes exactly what the shared crate's fixed-point path computes on
/// the host, and stays within its stated bound of the f64 calibration.
#[test]
fn fixed_point_node_matches_host_fixed_arithmetic() {
    let elf = node_fixed_elf();
    let dir = tempfile::tempdir().unwrap();
    let (camp_path, rec_path) = campaign_and_record(dir.path(), QEMU_ID_HEX);
    let camp = Campaign::read(&camp_path).unwrap();
    let codes = accelcal::node::hil::campaign_codes(&camp, &camp_path).unwrap();
    let codes = &codes[..600];
    let record = std::fs::read(&rec_path).unwrap();
    let run = accelcal::node::hil::replay(&HilOptions::new(elf), &record, codes).unwrap();
    let cal = Record::parse(&record).unwrap().model4().unwrap().invert().unwrap();
    let fixed = cal.to_fixed().unwrap();
    let bound = fixed.error_bound(&cal);
    assert_eq!(run.accel.len(), codes.len());
    for (row, (a, u)) in run.accel.iter().zip(codes).enumerate() {
        // The node sends m/s²·2¹⁶ as i32; `replay` converts exactly (|a| < 256 m/s²).
        let q = a.map(|v| (v as f64 * 65536.0) as i32);
        assert_eq!(q, fixed.apply(*u), "row {row}");
        let want = cal.apply(u.map(f64::from));
        for i in 0..3 {
            assert!((a[i] as f64 - want[i]).abs() <= bound[i], "row {row} axis {i}");
        }
    }
}

/// `accelcal monitor` reads the node's stream through a serial port: QEMU exposes USART1 as a
/// pseudo-terminal, the node reports its status every second.
#[test]
fn monitor_shows_the_status_stream_of_a_node_on_a_serial_port() {
    use std::io::{BufRead, BufReader};
    use std::process::Stdio;
    let elf = node_elf();
    let mut qemu = Command::new("qemu-system-arm")
        .args(["-M", "b-l475e-iot01a", "-display", "none", "-monitor", "none", "-serial", "pty"])
        .args(["-semihosting-config", "enable=on,target=native", "-kernel"])
        .arg(&elf)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    struct Kill(std::process::Child);
    impl Drop for Kill {
        fn drop(&mut self) {
            let _ = self.0.kill();
            let _ = self.0.wait();
        }
    }
    // QEMU names the pseudo-terminal on stdout ("char device redirected to /dev/pts/3 (label
    // serial0)"); the node's defmt bytes follow and are drained.
    let stdout = qemu.stdout.take().unwrap();
    let _qemu = Kill(qemu);
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let mut r = BufReader::new(stdout);
        let mut line = String::new();
        let _ = r.read_line(&mut line);
        let _ = tx.send(line);
        let _ = std::io::copy(&mut r, &mut std::io::sink());
    });
    let line = rx.recv_timeout(std::time::Duration::from_secs(10)).expect("qemu names its pty");
    let pty = line.split_whitespace().find(|w| w.starts_with("/dev/")).unwrap_or_else(|| panic!("{line}"));
    let mon = Command::new(env!("CARGO_BIN_EXE_accelcal"))
        .args(["monitor", "--port", pty, "--count", "2"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut mon = Kill(mon);
    let t0 = std::time::Instant::now();
    while mon.0.try_wait().unwrap().is_none() {
        assert!(t0.elapsed() < std::time::Duration::from_secs(30), "monitor did not finish");
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
    let mut out = String::new();
    std::io::Read::read_to_string(mon.0.stdout.as_mut().unwrap(), &mut out).unwrap();
    let lines: Vec<&str> = out.lines().collect();
    assert_eq!(lines.len(), 2, "{out}");
    for l in lines {
        assert!(l.starts_with("status: protocol 1, NO RECORD (NoSlot): output is UNCALIBRATED"), "{l}");
    }
}
