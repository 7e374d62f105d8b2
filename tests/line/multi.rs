//! Issue 23: several nodes on one head. `emulate` with two units (two QEMU nodes, two front ends
//! reading one emulated head), `acquire` with two ports: each campaign carries its node's id and
//! recovers its own unit, so a swapped or shared stream fails; `--resume` continues each campaign
//! from its own complete positions; a record carries its node's id and only that node takes it.

use super::*;
use crate::support::station_line::{station_line, Unit};

/// The `# key: value` of a campaign's header.
fn header_value(campaign: &Path, key: &str) -> String {
    let text = std::fs::read_to_string(campaign).unwrap();
    let prefix = format!("# {key}: ");
    let line = text.lines().find(|l| l.starts_with(&prefix));
    line.unwrap_or_else(|| panic!("no `{prefix}` in {}", campaign.display()))[prefix.len()..].to_string()
}

/// Keeps the header, the first `positions` positions of `samples` rows of a campaign and five rows
/// of the next, plus half a row (as a crash leaves it). The body's comment lines (each position's
/// `# head_at:` line) are kept and not counted as rows.
fn cut_after(campaign: &Path, positions: usize, samples: usize) {
    let text = std::fs::read_to_string(campaign).unwrap();
    let header = text.lines().take_while(|l| l.starts_with('#')).count() + 1;
    let want = positions * samples + 5;
    let mut data = 0;
    let mut keep: Vec<&str> = Vec::new();
    let mut lines = text.lines();
    for l in lines.by_ref() {
        if keep.len() >= header && !l.starts_with('#') {
            if data == want {
                std::fs::write(campaign, format!("{}\n{}", keep.join("\n"), &l[..l.len() / 2])).unwrap();
                return;
            }
            data += 1;
        }
        keep.push(l);
    }
    panic!("{} has fewer than {want} rows", campaign.display());
}

#[test]
fn two_nodes_on_one_head_each_record_their_own_unit() {
    let _one = one_bench();
    let dir = tempfile::tempdir().unwrap();
    let (t1, _) = unit(dir.path(), "u1", 5, 10);
    let (t2, _) = unit(dir.path(), "u2", 6, 10);
    let em = Emulator::start_units(&[&t1, &t2], &[]);
    let ids: Vec<&str> = em.nodes.iter().map(|n| n.2.as_str()).collect();
    // The first node keeps the fixed QEMU id ("QEMU-B-L475E"), the second is "QEMU-NODE-02".
    assert_eq!(ids, ["51454d552d422d4c34373545", "51454d552d4e4f44452d3032"]);
    assert_eq!(em.nodes[0].0, em.port);
    let (p1, p2) = (em.nodes[0].0.as_str(), em.nodes[1].0.as_str());
    let info = dir.path().join("info.json");
    ok(&["info", "--port", p2, "--json", s(&info)]);
    assert_eq!(json(&info)["device_id"], ids[1]);
    let (a, b) = (dir.path().join("a.csv"), dir.path().join("b.csv"));
    let samples = "200";
    let mut args = vec!["acquire", "--head", &em.head, "--plan", "six", "--samples", samples, "--g", "9.81"];
    args.extend_from_slice(&["--port", p1, "--port", p2, "--out", s(&a), "--out", s(&b)]);
    args.extend_from_slice(&["--serial", "S1", "--serial", "S2"]);
    let out = succeed(&args);
    let stdout = String::from_utf8_lossy(&out.stdout);
    for (id, c) in [(ids[0], &a), (ids[1], &b)] {
        assert!(
            stdout.contains(&format!("6 positions of device {id} written to {}", c.display())),
            "{stdout}"
        );
    }
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains(&format!("{p2}: position 6/6")), "{err}");
    for (c, id, serial) in [(&a, ids[0], "S1"), (&b, ids[1], "S2")] {
        assert_eq!(dwells(c).len(), 6, "{}", c.display());
        assert!(dwells(c).iter().all(|d| d.2 == 200), "{:?}", dwells(c));
        assert_eq!(header_value(c, "device_id"), id);
        assert_eq!(header_value(c, "serial"), serial);
    }
    // The second campaign cut after three positions: `--resume` with both ports records its
    // last three, and nothing into the complete first one.
    let whole_a = std::fs::read_to_string(&a).unwrap();
    cut_after(&b, 3, 200);
    args.push("--resume");
    let out = succeed(&args);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains(&format!("{p2}: resume: 3 complete positions kept, 5 rows of an unfinished")),
        "{err}"
    );
    assert!(
        err.contains(&format!("{p2}: position 4/6")) && !err.contains(&format!("{p1}: position")),
        "{err}"
    );
    assert_eq!(std::fs::read_to_string(&a).unwrap(), whole_a);
    assert_eq!(dwells(&b).len(), 6);
    assert!(dwells(&b).iter().all(|d| d.2 == 200), "{:?}", dwells(&b));
    // Each campaign recovers its own unit; the two units differ far beyond the fits' uncertainty.
    let (f1, f2) = (fit(&a, &dir.path().join("fa.json"), &[]), fit(&b, &dir.path().join("fb.json"), &[]));
    let (u1, u2) = (json(&t1), json(&t2));
    let own = [worst_z(&f1, &u1), worst_z(&f2, &u2)];
    let swapped = [worst_z(&f1, &u2), worst_z(&f2, &u1)];
    assert!(own.iter().all(|&z| z < 5.0), "own units: {own:?}");
    assert!(swapped.iter().all(|&z| z > 20.0), "swapped units: {swapped:?}");
    // A record fitted from each campaign carries its node's id (from the header): node 2 refuses
    // node 1's before anything is written and runs its own.
    let (ra, rb) = (dir.path().join("a.rec"), dir.path().join("b.rec"));
    fit(&a, &dir.path().join("fa-rec.json"), &["--record", s(&ra)]);
    fit(&b, &dir.path().join("fb-rec.json"), &["--record", s(&rb)]);
    let g2 = em.nodes[1].1.as_str();
    let e = common::bad(&["flash", s(&ra), "--gdb", g2, "--port", p2]);
    let want = format!("the record is for device {}, the connected MCU is {}", ids[0], ids[1]);
    assert!(e.contains(&want), "{e}");
    let out = ok(&["flash", s(&rb), "--gdb", g2, "--port", p2]);
    assert!(out.contains(&format!("confirmed over {p2}")), "{out}");
    assert_eq!(em.stop(), Some(0));
}

/// The station with two nodes on one head: one campaign over both, each unit's line to its own
/// certificate and its own run in the database.
#[test]
fn the_station_calibrates_two_nodes_on_one_head() {
    let _one = one_bench();
    let dir = tempfile::tempdir().unwrap();
    let (t1, _) = unit(dir.path(), "u1", 7, 10);
    let (t2, _) = unit(dir.path(), "u2", 8, 10);
    let em = Emulator::start_units(&[&t1, &t2], &[]);
    let outs = [dir.path().join("M-1"), dir.path().join("M-2")];
    let units: Vec<Unit> = em
        .nodes
        .iter()
        .enumerate()
        .map(|(i, n)| Unit { port: &n.0, gdb: &n.1, serial: ["M-1", "M-2"][i], out: s(&outs[i]) })
        .collect();
    let args = station_line(&em.head, &units);
    let out = succeed(&args);
    let text = String::from_utf8_lossy(&out.stdout);
    let err = String::from_utf8_lossy(&out.stderr);
    // One acquisition for both.
    assert_eq!(err.matches("step 3/8 acquire: accelcal acquire").count(), 1, "{err}");
    for (i, n) in em.nodes.iter().enumerate() {
        let serial = ["M-1", "M-2"][i];
        assert!(text.contains(&format!("station: unit {serial} (device {}) PASS", n.2)), "{text}");
        assert_eq!(header_value(&outs[i].join("campaign.csv"), "device_id"), n.2);
        let crc = json(&outs[i].join("as-left.json"))["record"]["crc"].as_str().unwrap().to_string();
        let info = dir.path().join(format!("info-{i}.json"));
        ok(&["info", "--port", &n.0, "--json", s(&info)]);
        assert_eq!(json(&info)["record"]["crc"].as_str(), Some(crc.as_str()), "{serial}");
    }
    // Two lanes: M-2 is flashed while the head verifies M-1 (one after the other, M-2's flash
    // would end after M-1's certificate). The journal's times are whole seconds; the as-left
    // verification takes about 5.
    let finished = |dir: &Path, step: &str| {
        let j = json(&dir.join("station.json"));
        let r = j["steps"].as_array().unwrap().iter().find(|r| r["step"] == step).cloned();
        r.and_then(|r| r["finished"].as_str().map(str::to_string)).unwrap_or_else(|| panic!("{step}: {j}"))
    };
    let (flash_2, as_left_1) = (finished(&outs[1], "flash"), finished(&outs[0], "as-left"));
    assert!(flash_2 < as_left_1, "M-2 flashed at {flash_2}, M-1 verified at {as_left_1}");
    let db = dir.path().join("calibration.sqlite");
    for (i, n) in em.nodes.iter().enumerate() {
        let h = String::from_utf8_lossy(&succeed(&["history", &n.2, "--db", s(&db)]).stdout).to_string();
        assert!(h.contains(&format!("({}): 1 run, 1 calibration", ["M-1", "M-2"][i])), "{h}");
    }
}
