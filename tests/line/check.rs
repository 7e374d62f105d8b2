//! Issue 31 item 2: the station's check standard. A known unit is checked at the start of a shift
//! (`station --check-standard SERIAL`: its as-found verification only); its mean error per axis
//! goes on the station's individuals chart. A check out of control ends with exit code 3 naming
//! the rule and the check, the station then refuses production (exit code 3), and a check in
//! control lets it calibrate again.

use super::*;
use accelcal_db::{Db, Outcome, Phase, RunId, RunStart};
use accelcal_line::verify::VerifyReport;

/// Earlier checks of `station`, stored through the database's normal path: each a run of the
/// check standard with an as-found verification whose every position has the error `m` (m/s²),
/// ended in control. `template` is a real verification of the unit (its device and positions).
fn seed_checks(db: &str, station: &str, serial: &str, template: &VerifyReport, means: &[[f64; 3]]) {
    let mut db = Db::open(db).unwrap();
    let t0 = accelcal_db::now_unix_s() - 86_400 * means.len() as i64;
    for (i, m) in means.iter().enumerate() {
        let run = RunId::new();
        let start = RunStart {
            run_id: run,
            device_id: template.device_id.clone(),
            serial: serial.into(),
            station: station.into(),
            head: "sim".into(),
            operator: "test".into(),
            started_unix_s: t0 + 86_400 * i as i64,
            software_version: "test".into(),
            firmware_version: String::new(),
            g_m_s2: template.g_m_s2,
            g_source: "--g".into(),
        };
        db.begin_run(&start, None).unwrap();
        let mut report = template.clone();
        for p in &mut report.positions {
            p.error_m_s2 = *m;
        }
        db.store_verification(run, Phase::AsFound, &report).unwrap();
        db.finish_run(run, Outcome::Pass, "check standard: in control").unwrap();
    }
}

#[test]
fn a_check_standard_out_of_control_stops_production_until_a_check_is_in_control() {
    let _one = one_bench();
    let dir = tempfile::tempdir().unwrap();
    let db = dir.path().join("line.sqlite").display().to_string();
    let (truth, _) = unit(dir.path(), "u", 31, 10);
    let station = ["--station", "line-1", "--db", &db];
    // The check standard is calibrated first: a record in force, and its fit stored.
    let first = dir.path().join("first");
    {
        let em = Emulator::start(&truth, &[]);
        succeed(&station_args(&em, "GOLD-1", &first, &station));
    }
    let record = first.join("record.rec");
    // Six earlier checks on the station at a mean x error of +0.05 ± 0.005 m/s² (y, z 0 ± 0.005):
    // x's limits about 0.023 to 0.077 m/s², which a check of the unit as it is (about 0) breaks.
    let template = VerifyReport::read(&first.join("as-left.json")).unwrap();
    let means: Vec<[f64; 3]> =
        (0..6).map(|i| if i % 2 == 0 { [0.055, 0.005, -0.005] } else { [0.045, -0.005, 0.005] }).collect();
    seed_checks(&db, "line-1", "GOLD-1", &template, &means);

    let em = Emulator::start(&truth, &["--record", s(&record)]);
    let check_args = |em: &Emulator, out: &Path| -> Vec<String> {
        let mut v: Vec<String> =
            station_args(em, "GOLD-1", out, &station).iter().map(|w| w.to_string()).collect();
        let at = v.iter().position(|w| w == "--serial").unwrap();
        v[at] = "--check-standard".into();
        v
    };
    let args = check_args(&em, &dir.path().join("check-1"));
    let out = accelcal(&args.iter().map(String::as_str).collect::<Vec<_>>());
    let (stdout, stderr) = (String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
    assert_eq!(out.status.code(), Some(3), "{stdout}\n{stderr}");
    assert!(
        stdout.contains("station: check standard GOLD-1 on line-1: OUT OF CONTROL (mean error x"),
        "{stdout}"
    );
    assert!(
        stderr.contains("station line-1: its check standard GOLD-1 is out of control (run ")
            && stderr.contains(": mean error x: rule 1 (a point beyond 3σ) at check 7 of 7"),
        "{stderr}"
    );

    // Production is refused, naming the check, before any node is touched.
    let k9 = dir.path().join("k9");
    let p = station_args(&em, "K-9", &k9, &station);
    let out = accelcal(&p);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(3), "{stderr}");
    assert!(
        stderr.contains("its check standard GOLD-1 is out of control") && stderr.contains("rule 1"),
        "{stderr}"
    );
    assert!(!k9.join("info.json").exists(), "a node was asked");
    em.stop();

    // The unit as the earlier checks saw it (x bias +0.05 m/s²): in control, and production
    // goes on.
    let mut t = json(&truth);
    let k = t["channels"][0]["k"][0].as_f64().unwrap();
    let bias = t["channels"][0]["bias"].as_f64().unwrap();
    t["channels"][0]["bias"] = serde_json::json!(bias + 0.05 * k);
    let moved = dir.path().join("moved.json");
    std::fs::write(&moved, t.to_string()).unwrap();
    let em = Emulator::start(&moved, &["--record", s(&record)]);
    let args = check_args(&em, &dir.path().join("check-2"));
    let out = succeed(&args.iter().map(String::as_str).collect::<Vec<_>>());
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(stdout.contains("station: check standard GOLD-1 on line-1: in control (8 checks)"), "{stdout}");
    let checks = Db::open(&db).unwrap().check_runs("line-1").unwrap();
    let outcomes: Vec<&str> = checks.iter().map(|c| c.outcome.as_deref().unwrap()).collect();
    assert_eq!(outcomes, ["pass", "pass", "pass", "pass", "pass", "pass", "rejected", "pass"]);
    // `fleet` shows the station's check standard, and counts the calibration, not the checks.
    let f = dir.path().join("fleet.json");
    let out = succeed(&["fleet", "--db", &db, "--since", "2000-01-01", "--json", s(&f)]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("  check standard of line-1: GOLD-1, 8 checks, IN CONTROL"), "{text}");
    let fleet = json(&f);
    assert_eq!(fleet["counts"]["runs"], 1, "{}", fleet["counts"]);
    assert_eq!(fleet["check_standards"][0]["state"], "in control");
    assert_eq!(fleet["check_standards"][0]["charts"][0]["points"].as_array().unwrap().len(), 8);
    // The option that does not apply is refused.
    let mut with_serial = args.clone();
    with_serial.extend(["--serial".into(), "X".into()]);
    let out = accelcal(&with_serial.iter().map(String::as_str).collect::<Vec<_>>());
    assert_eq!(out.status.code(), Some(2));
    assert!(
        String::from_utf8_lossy(&out.stderr).contains("--serial does not apply to station --check-standard")
    );
    em.stop();
}
