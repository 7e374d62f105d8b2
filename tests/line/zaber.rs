//! Issue 56, the Zaber head: `station --head zaber:…` against `accelcal emulate --head zaber`
//! (TCP) and `--head zaber-pty` (a pseudo-terminal, as a serial chain), and an injected fault
//! that ends the station with the environment's exit code, naming the axis, after which the same
//! command finishes the unit.

use super::*;

/// How many positions of the acquisition the journal keeps (each with its commanded and
/// read-back angles).
fn acquired_positions(dir: &Path) -> usize {
    let steps = json(&dir.join("station.json"))["steps"].as_array().unwrap().clone();
    steps.iter().find(|r| r["step"] == "acquire").and_then(|r| r["positions"].as_array()).map_or(0, Vec::len)
}

#[test]
fn the_station_calibrates_on_a_zaber_head_and_a_stall_ends_it_naming_the_axis() {
    let _one = one_bench();
    let dir = tempfile::tempdir().unwrap();
    let (truth, _) = unit(dir.path(), "u", 56, 10);
    // The 5th move since start (the acquisition's 5th position: no as-found verification runs
    // on a node without a record) stalls α.
    let em = Emulator::start(&truth, &["--head", "zaber", "--head-fault", "stall", "--head-fault-at", "5"]);
    assert!(em.head.starts_with("zaber:127.0.0.1:"), "{}", em.head);
    let a = dir.path().join("unit-a");
    let args = station_args(&em, "Z-1", &a, &[]);
    let out = accelcal(&args);
    let e = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(3), "{e}");
    assert!(
        e.contains(&format!(
            "head {}: alpha (device 1 axis 1) reports a fault: FS (stalled and stopped)",
            em.head
        )),
        "{e}"
    );
    // Nothing of that position is recorded: the campaign has 4 positions.
    let campaign = std::fs::read_to_string(a.join("campaign.csv")).unwrap_or_default();
    let positions = campaign.lines().filter(|l| l.starts_with("# head_at:")).count();
    assert_eq!(positions, 4, "{campaign}");
    // The same command again (the fault gone: it struck once) resumes and finishes the unit.
    let out = succeed(&args);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("station: unit Z-1 (device 51454d552d422d4c34373545) PASS"), "{text}");
    assert_eq!(acquired_positions(&a), 24);
    drop(em);

    // Over a pseudo-terminal, as a serial chain: the unit calibrated again (a fresh node, the
    // same device and serial) passes too.
    let em = Emulator::start(&truth, &["--head", "zaber-pty"]);
    assert!(em.head.starts_with("zaber:/dev/pts/"), "{}", em.head);
    let b = dir.path().join("unit-b");
    let out = succeed(&station_args(&em, "Z-1", &b, &[]));
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("station: unit Z-1 (device 51454d552d422d4c34373545) PASS"), "{text}");
    assert_eq!(acquired_positions(&b), 24);
}
