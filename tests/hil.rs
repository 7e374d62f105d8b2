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
use accelcal_shared::kinematics::gravity;
use accelcal_shared::record::Record;
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

    // 1. The node's arithmetic: within the stated f32 bound of the host's f64, every sample set.
    let mut worst = 0.0f64;
    for (row, (t, a)) in got.iter().enumerate() {
        assert_eq!(*t, camp.t_s[row]);
        let want = cal.apply([x[row], y[row], z[row]]);
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
