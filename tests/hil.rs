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

use crate::common;
use crate::support;

#[path = "hil/thermal.rs"]
mod thermal;
use std::path::{Path, PathBuf};
use std::process::Command;

use accelcal_core::campaign::Campaign;
use accelcal_line::node::hil::{replay_blocks, replay_with_temps, CampaignCodes, HilOptions, QemuNode};
use accelcal_line::node::monitor::format_status;
use accelcal_shared::contract::QEMU_DEVICE_ID;
use accelcal_shared::kinematics::gravity;
use accelcal_shared::record::{crc32, Record, RecordError};
use accelcal_shared::slots::{SlotImage, COMMIT_OFFSET, SLOT_MAGIC_V2, SLOT_SIZE};
use accelcal_shared::terms::{Structure, MODEL_4};
use accelcal_shared::wire::{
    record_error_code, Block, HostMsg, NodeMsg, RecordFault, RecordStatus, Refusal, ResetCause,
    DEFAULT_RATE_HZ, MAX_BLOCK, PROTOCOL_VERSION, RATE_MAX_HZ, RATE_MIN_HZ,
};
use accelcal_shared::G_STANDARD;
use common::{accelcal, bad, ok};
use support::{node_elf, record_bytes, thermal_model};

/// Hex of the QEMU node's device id, "QEMU-B-L475E" (`accelcal_shared::contract::QEMU_DEVICE_ID`).
const QEMU_ID_HEX: &str = "51454d552d422d4c34373545";

/// The fixed-point QEMU build (`cargo xtask firmware` builds it).
fn node_fixed_elf() -> PathBuf {
    node_elf(); // checks QEMU too
    support::firmware_elf(
        "ACCELCAL_NODE_QEMU_FIXED_ELF",
        "target/thumbv7em-none-eabihf/release/node-qemu-fixed",
        "cargo build --release --features board-qemu,fixed-point --bin node-qemu-fixed",
    )
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

/// Appends `row` to the campaign file `path`; returns its line number.
fn append_row(path: &Path, row: &str) -> usize {
    let mut text = std::fs::read_to_string(path).unwrap();
    text += row;
    text += "\n";
    std::fs::write(path, &text).unwrap();
    text.lines().count()
}

/// The last row of a campaign file, its fields.
fn last_row(path: &Path) -> Vec<String> {
    let text = std::fs::read_to_string(path).unwrap();
    text.lines().last().unwrap().split(',').map(String::from).collect()
}

/// `accelcal hil` streams: a campaign whose last row is bad is refused as bad input (exit 2, one
/// line naming the place, the output file never appears), although the rows before it went
/// through the node; so is a code the node cannot take deep in the file.
#[test]
fn hil_refuses_a_bad_row_at_the_end_of_a_campaign_and_leaves_no_output() {
    let elf = node_elf();
    let dir = tempfile::tempdir().unwrap();
    let camp = dir.path().join("campaign.csv");
    let rec = dir.path().join("node.rec");
    ok(&["simulate", "--out", s(&camp), "--seed", "11", "--samples", "10"]);
    ok(&["fit", s(&camp), "--record", s(&rec), "--device-id", QEMU_ID_HEX, "--created", "1800000000"]);
    let out_dir = dir.path().join("out");
    let out_path = out_dir.join("node.csv");
    let hil = || accelcal(&["hil", "--qemu", s(&elf), "--record", s(&rec), s(&camp), "--out", s(&out_path)]);
    let good = hil();
    assert!(good.status.success(), "{}", String::from_utf8_lossy(&good.stderr));
    std::fs::remove_file(&out_path).unwrap();

    let head = std::fs::read_to_string(&camp).unwrap();
    // The header row (after the `# g_m_s2:` comment that `simulate` writes).
    let header = head.lines().find(|l| !l.starts_with('#')).unwrap();
    let x = header.split(',').position(|h| h == "x").unwrap();
    for (value, want) in [
        ("oops", "{camp}:{line}:{col}: expected a number in `x`, found `oops`"),
        ("30000.5", "{camp}:{line}:{col}: channel x: code 30000.5 is not a whole number in 0..=65535"),
    ] {
        std::fs::write(&camp, &head).unwrap();
        let mut row = last_row(&camp);
        row[x] = value.into();
        let line = append_row(&camp, &row.join(","));
        let want = want
            .replace("{camp}", s(&camp))
            .replace("{line}", &line.to_string())
            .replace("{col}", &(x + 1).to_string());
        let out = hil();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{stderr}");
        assert_eq!(stderr.lines().count(), 1, "{stderr}");
        assert!(stderr.contains(&want), "expected `{want}` in: {stderr}");
        let left: Vec<_> = std::fs::read_dir(&out_dir).unwrap().flatten().map(|e| e.path()).collect();
        assert!(left.is_empty(), "output left behind: {left:?}");
    }
}

/// The replay streams: the node's answers to the first blocks are handed out before a bad row at
/// the end of the file is read, the replay then stops with that row's error, and each answer is
/// the host's f32 calibration of its rows.
#[test]
fn replay_hands_out_answers_before_the_end_of_the_campaign_is_read() {
    let dir = tempfile::tempdir().unwrap();
    let (camp, rec_path) = campaign_and_record(dir.path(), QEMU_ID_HEX);
    let record = std::fs::read(&rec_path).unwrap();
    let cal = Record::parse(&record).unwrap().model4().unwrap().invert().unwrap().to_f32();
    let all = Campaign::read(&camp).unwrap();
    let mut row = last_row(&camp);
    row[1] = "zero".into();
    let line = append_row(&camp, &row.join(","));
    let codes = CampaignCodes::open(&camp).unwrap().map(|b| b.map(|(c, rows)| (c, None, rows.t_s)));
    let mut answered = 0;
    let e = replay_blocks(&HilOptions::new(node_elf()), &record, codes, |t_s, accel, temp| {
        assert_eq!(temp, None);
        for (k, (t, a)) in t_s.iter().zip(accel).enumerate() {
            let i = answered + k;
            assert_eq!(*t, all.t_s[i]);
            let ch = |n: &str| all.channels[all.channel(n).unwrap()].codes[i] as u16;
            assert_eq!(*a, cal.apply([ch("x"), ch("y"), ch("z")]), "row {i}");
        }
        answered += accel.len();
        Ok(())
    })
    .unwrap_err();
    assert_eq!(
        format!("{e:#}"),
        format!(
            "reading the campaign: {}:{line}:2: expected a number in `alpha_deg`, found `zero`",
            s(&camp)
        )
    );
    assert!(answered > 0 && answered < all.len(), "{answered} of {} rows answered", all.len());
}

fn replay_msg(seq: u32, codes: &[[u16; 3]]) -> HostMsg {
    HostMsg::Replay { seq, codes: heapless::Vec::from_slice(codes).unwrap(), temp: None }
}

/// Without a valid record the node says so and returns raw codes flagged uncalibrated, unchanged.
#[test]
fn node_without_record_answers_uncalibrated() {
    let mut node = QemuNode::start(&HilOptions::new(node_elf()), None).unwrap();
    let status = node.status().unwrap();
    assert_eq!(status.record, RecordStatus::Missing(RecordFault::NoSlot));
    assert_eq!(status.protocol, PROTOCOL_VERSION);
    let codes = [[1, 2, 3], [65535, 0, 32768]];
    let answer = node.request(&replay_msg(5, &codes)).unwrap();
    let want = NodeMsg::Replayed {
        seq: 5,
        data: Block::Uncalibrated(heapless::Vec::from_slice(&codes).unwrap()),
        temp: None,
    };
    assert_eq!(answer, want);
}

/// The status carries the cause of the last reset: QEMU's RCC model reads RCC_CSR = 0x0C00_0600
/// after its reset (BORRSTF | PINRSTF, the chip's power-on value), which the node decodes as a
/// power-on; no ADC trigger mismatch is flagged (QEMU has no ADC to read back).
#[test]
fn node_reports_the_cause_of_its_last_reset() {
    let mut node = QemuNode::start(&HilOptions::new(node_elf()), None).unwrap();
    let status = node.status().unwrap();
    assert_eq!(status.reset_cause, ResetCause::PowerOn);
    assert!(!status.trigger_mismatch);
    assert!(
        format_status(&status).contains(", last reset PowerOn: power-on or brown-out reset"),
        "{status:?}"
    );
}

/// `SetRate` within the stated range is answered with the new status and stays in force; a rate
/// outside it is refused with the range, and the rate in force does not change.
#[test]
fn node_sets_its_sampling_rate_within_the_stated_range() {
    let mut node = QemuNode::start(&HilOptions::new(node_elf()), None).unwrap();
    assert_eq!(node.status().unwrap().rate_hz, DEFAULT_RATE_HZ);
    for hz in [250, RATE_MIN_HZ, RATE_MAX_HZ, 1234] {
        match node.request(&HostMsg::SetRate { hz }).unwrap() {
            NodeMsg::RateSet(s) => assert_eq!(s.rate_hz, hz),
            other => panic!("SetRate {hz}: {other:?}"),
        }
        assert_eq!(node.status().unwrap().rate_hz, hz);
    }
    for hz in [0, RATE_MIN_HZ - 1, RATE_MAX_HZ + 1, u32::MAX] {
        let answer = node.request(&HostMsg::SetRate { hz }).unwrap();
        let want = Refusal::RateOutOfRange { requested_hz: hz, min_hz: 100, max_hz: 4000 };
        assert_eq!(answer, NodeMsg::Refused(want));
        assert_eq!(node.status().unwrap().rate_hz, 1234, "a refused rate changed the rate");
    }
    // Still serving, nothing counted as a bad frame.
    let answer = node.request(&replay_msg(9, &[[1, 2, 3]])).unwrap();
    assert!(matches!(answer, NodeMsg::Replayed { seq: 9, .. }), "{answer:?}");
    assert_eq!(node.status().unwrap().bad_frames, 0);
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
    let bad = with_record(&page, &rec);

    let mut node = QemuNode::start(&HilOptions::new(node_elf()), Some(&bad)).unwrap();
    let status = node.status().unwrap();
    // 7 = RecordError::BadCrc (wire::record_error_code).
    assert_eq!(status.record, RecordStatus::Missing(RecordFault::BadRecord(7)));
    // A frame with an unknown message variant, then a good request. (Requests sent while the node
    // was still booting may have been heard in part, so count from the current value.)
    let before = node.status().unwrap().bad_frames;
    node.send_raw(&[0x00, 0x02, 0x63, 0x00]).unwrap();
    let answer = node.request(&replay_msg(1, &[[10, 20, 30]])).unwrap();
    assert!(matches!(answer, NodeMsg::Replayed { seq: 1, data: Block::Uncalibrated(_), .. }), "{answer:?}");
    assert_eq!(node.status().unwrap().bad_frames, before + 1);
}

/// `page` (a slot image of a record of the same length) holding `record` instead, with the slot's
/// CRC (and, in a version-2 slot, its copy in the commit double word) recomputed: an intact slot
/// whatever the record holds (`SlotImage::build` refuses records that do not parse).
fn with_record(page: &[u8; SLOT_SIZE], record: &[u8]) -> [u8; SLOT_SIZE] {
    let mut out = *page;
    assert_eq!(u16::from_le_bytes([page[8], page[9]]) as usize, record.len());
    out[16..16 + record.len()].copy_from_slice(record);
    let mut covered = out[4..12].to_vec();
    covered.extend_from_slice(record);
    let crc = crc32(&covered).to_le_bytes();
    out[12..16].copy_from_slice(&crc);
    if out[0..4] == SLOT_MAGIC_V2 {
        out[COMMIT_OFFSET + 4..].copy_from_slice(&crc);
    }
    out
}

/// Boots the node with `page` in slot 0, checks the status it reports and that it returns raw
/// codes flagged uncalibrated, unchanged; returns the status as `accelcal monitor` shows it.
fn node_runs_uncalibrated(page: &[u8; SLOT_SIZE], want: RecordFault) -> String {
    let mut node = QemuNode::start(&HilOptions::new(node_elf()), Some(page)).unwrap();
    let status = node.status().unwrap();
    assert_eq!(status.record, RecordStatus::Missing(want));
    let codes = [[100, 200, 300], [65535, 0, 32768]];
    let answer = node.request(&replay_msg(3, &codes)).unwrap();
    let raw = Block::Uncalibrated(heapless::Vec::from_slice(&codes).unwrap());
    assert_eq!(answer, NodeMsg::Replayed { seq: 3, data: raw, temp: None });
    format_status(&status)
}

/// A model-4 record for the QEMU node, with a plausible calibration.
fn qemu_model4_record() -> Record {
    let m = accelcal_shared::linear::Model4 {
        u0: [32100.5, 33012.25, 31877.75],
        k: [[1671.2, 8.5, -3.25], [-4.0, 1650.75, 6.5], [2.5, -7.75, 1689.0]],
    };
    Record::from_model4(QEMU_DEVICE_ID, 1_800_000_000, &m)
}

/// The node boots from a slot page of either format: version 2 (what `accelcal flash` and
/// `accelcal hil` write: commit double word at the page's end) and version 1 (written before
/// version 2, still read). Each time the status names the slot and sequence in force and the
/// node's answers are the shared crate's f32 calibration of the codes. An uncommitted version-2
/// page (all but its last double word programmed: a write cut before its commit) is no record.
/// (An unreadable double word, a flash ECC error, cannot be emulated: QEMU's flash has no ECC.)
#[test]
fn node_runs_a_version_2_slot_and_still_reads_a_version_1_slot() {
    let rec = qemu_model4_record();
    let bytes = record_bytes(&rec);
    let cal = rec.model4().unwrap().invert().unwrap().to_f32();
    let codes = [[32100, 33012, 31877], [40000, 30000, 20000], [0, 65535, 1]];
    let v2 = SlotImage::build(&bytes, 17).unwrap();
    let v1 = SlotImage::build_v1(&bytes, 16).unwrap();
    assert_eq!(&v2[..4], b"ASL2");
    assert_eq!(&v1[..4], b"ASL1");
    for (page, sequence) in [(v2, 17), (v1, 16)] {
        let mut node = QemuNode::start(&HilOptions::new(node_elf()), Some(&page)).unwrap();
        let status = node.status().unwrap();
        let crc = u32::from_le_bytes(bytes[bytes.len() - 4..].try_into().unwrap());
        assert_eq!(
            status.record,
            RecordStatus::InUse { slot: 0, sequence, created_unix_s: 1_800_000_000, crc }
        );
        let want: Vec<[f32; 3]> = codes.iter().map(|u| cal.apply(*u)).collect();
        let answer = node.request(&replay_msg(9, &codes)).unwrap();
        let want = NodeMsg::Replayed {
            seq: 9,
            data: Block::Calibrated(heapless::Vec::from_slice(&want).unwrap()),
            temp: None,
        };
        assert_eq!(answer, want, "slot format of sequence {sequence}");
    }
    let mut uncommitted = v2;
    uncommitted[COMMIT_OFFSET..].fill(0xff);
    node_runs_uncalibrated(&uncommitted, RecordFault::NoSlot);
}

/// A record of format version 3 (a future one) that is otherwise intact (its own CRC and the slot's recomputed,
/// so that only the version differs) is refused by the node, which says which check failed and
/// streams uncalibrated; `accelcal hil` refuses the file before booting the node, naming both
/// versions.
#[test]
fn node_refuses_a_record_of_another_format_version() {
    let v1 = record_bytes(&qemu_model4_record());
    let mut v2 = v1.clone();
    v2[4..6].copy_from_slice(&3u16.to_le_bytes());
    let n = v2.len();
    let crc = crc32(&v2[..n - 4]);
    v2[n - 4..].copy_from_slice(&crc.to_le_bytes());
    assert_eq!(Record::parse(&v2), Err(RecordError::UnsupportedVersion(3)));
    let good_page = SlotImage::build(&v1, 1).unwrap();
    let page = with_record(&good_page, &v2);
    // Only the version, the record's CRC and the slot's CRC differ from the version-1 slot.
    let differ: Vec<usize> = (0..SLOT_SIZE).filter(|&i| page[i] != good_page[i]).collect();
    let allowed = |i: usize| {
        i == 16 + 4 || (12..16).contains(&i) || (16 + n - 4..16 + n).contains(&i) || i >= COMMIT_OFFSET + 4
    };
    assert!(differ.contains(&(16 + 4)) && differ.iter().all(|&i| allowed(i)), "{differ:?}");

    let code = record_error_code(RecordError::UnsupportedVersion(3));
    let shown = node_runs_uncalibrated(&page, RecordFault::BadRecord(code));
    assert!(
        shown.contains(
            "NO RECORD (BadRecord(UnsupportedVersion): the record in force is invalid: its format \
             version is not 1 or 2, the ones the node reads): output is UNCALIBRATED"
        ),
        "{shown}"
    );

    let dir = tempfile::tempdir().unwrap();
    let (camp, _) = campaign_and_record(dir.path(), QEMU_ID_HEX);
    let rec = dir.path().join("v2.rec");
    std::fs::write(&rec, &v2).unwrap();
    let out_path = dir.path().join("node.csv");
    let out =
        accelcal(&["hil", "--qemu", s(&node_elf()), "--record", s(&rec), s(&camp), "--out", s(&out_path)]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert_eq!(
        stderr,
        format!(
            "error: {}: unsupported record format version 3 (this build reads versions 1 and 2)\n",
            s(&rec)
        )
    );
    assert!(!out_path.exists());
}

/// A valid record of another model (model 4 plus the quadratic term ax²) is refused: the node
/// reports `NotModel4` and streams uncalibrated, and `accelcal hil` names the reason.
#[test]
fn node_refuses_a_record_of_another_model() {
    let mut quad = qemu_model4_record();
    let ax2 = 4; // index of ax^2 in terms::BASIS
    quad.structure = Structure::from_mask(MODEL_4.mask() | 1 << ax2);
    for c in 0..3 {
        quad.coefficients[c][4] = 0.5; // ax^2 comes after 1, ax, ay, az
    }
    assert_eq!(quad.structure.to_string(), "1,ax,ay,az,ax^2");
    let bytes = record_bytes(&quad);
    assert!(Record::parse(&bytes).unwrap().model4().is_none());
    let shown = node_runs_uncalibrated(&SlotImage::build(&bytes, 1).unwrap(), RecordFault::NotModel4);
    assert!(shown.contains("NO RECORD (NotModel4: the node applies model 4"), "{shown}");

    // The same through the CLI. `accelcal fit` no longer writes such a record (the node's check
    // refuses it first), so the test writes the bytes itself.
    let dir = tempfile::tempdir().unwrap();
    let camp = dir.path().join("campaign.csv");
    let rec = dir.path().join("quad.rec");
    ok(&["simulate", "--out", s(&camp), "--seed", "11", "--samples", "10"]);
    let e =
        bad(&["fit", s(&camp), "--terms", "ax,ay,az,ax^2", "--record", s(&rec), "--device-id", QEMU_ID_HEX]);
    assert!(e.contains("a node would refuse this record: NotModel4"), "{e}");
    assert!(!rec.exists());
    std::fs::write(&rec, &bytes).unwrap();
    let out_path = dir.path().join("node.csv");
    let out =
        accelcal(&["hil", "--qemu", s(&node_elf()), "--record", s(&rec), s(&camp), "--out", s(&out_path)]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(
        stderr.contains(
            "the node did not accept the record: NotModel4: the node applies model 4 (terms 1,ax,ay,az) \
             for three channels only, the record holds another model (fit it with `--terms ax,ay,az`, the default)"
        ),
        "{stderr}"
    );
    assert!(!out_path.exists());
}

/// The fixed-point build computes exactly what the shared crate's fixed-point path computes on
/// the host, and stays within its stated bound of the f64 calibration.
#[test]
fn fixed_point_node_matches_host_fixed_arithmetic() {
    let elf = node_fixed_elf();
    let dir = tempfile::tempdir().unwrap();
    let (camp_path, rec_path) = campaign_and_record(dir.path(), QEMU_ID_HEX);
    let codes: Vec<[u16; 3]> =
        CampaignCodes::open(&camp_path).unwrap().flat_map(|b| b.unwrap().0).take(600).collect();
    let codes = &codes[..];
    let record = std::fs::read(&rec_path).unwrap();
    let run = accelcal_line::node::hil::replay(&HilOptions::new(elf), &record, codes).unwrap();
    let cal = Record::parse(&record).unwrap().model4().unwrap().invert().unwrap();
    let fixed = cal.to_fixed().unwrap();
    let bound = fixed.error_bound(&cal);
    assert_eq!(run.accel.len(), codes.len());
    for (row, (a, u)) in run.accel.iter().zip(codes).enumerate() {
        // The node sends m/s²·2¹⁶ as i32; `replay` converts exactly (|a| < 256 m/s²).
        let q = a.map(|v| (v as f64 * accelcal_shared::contract::FIXED_SCALE) as i32);
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
        .args(["monitor", "--port", pty, "--count", "4"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut mon = Kill(mon);
    // Each line with the time it arrived (monitor's stdout is line-buffered).
    let (tx, rx) = std::sync::mpsc::channel();
    let stdout = mon.0.stdout.take().unwrap();
    std::thread::spawn(move || {
        for line in BufReader::new(stdout).lines().map_while(Result::ok) {
            let _ = tx.send((std::time::Instant::now(), line));
        }
    });
    let t0 = std::time::Instant::now();
    while mon.0.try_wait().unwrap().is_none() {
        assert!(t0.elapsed() < std::time::Duration::from_secs(30), "monitor did not finish");
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
    let lines: Vec<(std::time::Instant, String)> = rx.iter().collect();
    assert_eq!(lines.len(), 4, "{lines:?}");
    for (_, l) in &lines {
        assert!(l.starts_with("status: protocol 4, NO RECORD (NoSlot: no record slot holds"), "{l}");
        assert!(l.contains(", rate 1000 Hz, ") && l.contains(", last reset PowerOn: "), "{l}");
    }
    // The node's 1 s status period is 1 s of the host's time: QEMU's time base is the host clock,
    // not a count of SysTick interrupts (QEMU loses those; counted, 3 periods took about 10.5 s).
    let three = lines[3].0 - lines[0].0;
    assert!((2.5..6.0).contains(&three.as_secs_f64()), "3 status periods took {three:?}, want about 3 s");

    // `--rate-hz` sets the node's rate first: the node answers with its new status. The request is
    // sent again every second until answered, and QEMU polls a reopened pty once a second: when
    // both copies reach the node, it answers both, and the stream shows the second answer too.
    let out = Command::new(env!("CARGO_BIN_EXE_accelcal"))
        .args(["monitor", "--port", pty, "--count", "3", "--rate-hz", "250"])
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(lines.len(), 4, "{text}");
    assert!(lines[0].starts_with("rate set: status: protocol 4, "), "{text}");
    for l in &lines {
        assert!(
            l.starts_with("rate set: status: protocol 4, ") || l.starts_with("status: protocol 4, "),
            "{text}"
        );
        assert!(l.contains(", rate 250 Hz, "), "{text}");
    }
    // A rate outside the range is refused before the port is opened, with the range (`--rate`,
    // the former name, still reaches the same option).
    let out = accelcal(&["monitor", "--port", pty, "--rate", "50"]);
    assert_eq!(out.status.code(), Some(2));
    assert_eq!(
        String::from_utf8_lossy(&out.stderr),
        "error: --rate-hz: RateOutOfRange: sampling rate 50 Hz refused, the node accepts 100..=4000 Hz\n"
    );
}
