//! What the database tests share (`tests/db.rs` on SQLite, `tests/db_pg.rs` on a PostgreSQL
//! server): runs built from literal pieces, and the scenarios both engines must pass.
#![allow(dead_code)]

use std::io::{BufRead, BufReader};
use std::process::{Command, Stdio};

mod check;
pub mod fleet;
pub mod recall;
pub mod release;
pub mod serve;
pub mod tamper;

#[allow(unused_imports)] // not every test binary that includes dbkit runs it
pub use check::check_runs_are_the_station_s_checks;

use accelcal_db::{Asset, AssetKind, Db, DbError, Outcome, Phase, RunId, RunStart, Stored};
use accelcal_line::verify::{PositionCheck, VerifyReport};
use accelcal_shared::record::{Record, MAX_CHANNELS, MAX_RECORD_LEN};
use accelcal_shared::terms::MODEL_4;
use accelcal_shared::N_BASIS;

/// The QEMU node's device id, as hex.
pub const DEVICE: &str = "51454d552d422d4c34373545";
/// 2026-01-01T00:00:00Z.
pub const T0: i64 = 1_767_225_600;
pub const DAY: i64 = 86_400;
pub const G: f64 = 9.80665;

/// A unit's model 4: `[channel][1, ax, ay, az]`, codes and codes per m/s².
pub type Coefs = [[f64; 4]; 3];

/// A unit whose x bias grows by `bias_step` codes per calibration.
pub fn coefs(bias_step: f64, i: usize) -> Coefs {
    let mut c = [[0.0; 4]; 3];
    for (ch, row) in c.iter_mut().enumerate() {
        row[0] = 32768.0 + 10.0 * ch as f64;
        row[1 + ch] = 1670.0;
        row[1 + (ch + 1) % 3] = 3.0;
    }
    c[0][0] += bias_step * i as f64;
    c
}

pub fn start(run_id: RunId, device: &str, serial: &str, station: &str, t: i64) -> RunStart {
    RunStart {
        run_id,
        device_id: device.into(),
        serial: serial.into(),
        station: station.into(),
        head: "sim:127.0.0.1:7001".into(),
        operator: "ana".into(),
        started_unix_s: t,
        software_version: "0.1.0".into(),
        firmware_version: "0.4.0".into(),
        g_m_s2: G,
        g_source: "--g".into(),
    }
}

/// `fit --json` of model 4 with a diagonal covariance (σ 0.5 code on the bias, 0.02 on the
/// sensitivities).
pub fn fit_json(c: &Coefs) -> String {
    let chans: Vec<serde_json::Value> = ["x", "y", "z"]
        .iter()
        .enumerate()
        .map(|(i, name)| {
            let var = [0.25, 4e-4, 4e-4, 4e-4];
            let cov: Vec<Vec<f64>> =
                (0..4).map(|r| (0..4).map(|k| if r == k { var[r] } else { 0.0 }).collect()).collect();
            serde_json::json!({
                "channel": name,
                "terms": ["1", "ax", "ay", "az"],
                "coefficients": c[i],
                "std_errors": var.iter().map(|v: &f64| v.sqrt()).collect::<Vec<_>>(),
                "covariance": cov,
                "condition": 1.5,
                "rms_codes": 0.4,
            })
        })
        .collect();
    serde_json::json!({"method": "lsq", "channels": chans}).to_string()
}

/// The record of `c` for `device` (hex).
pub fn record(device: &str, c: &Coefs) -> Vec<u8> {
    let mut id = [0u8; 12];
    for (i, b) in id.iter_mut().enumerate() {
        *b = u8::from_str_radix(&device[2 * i..2 * i + 2], 16).unwrap();
    }
    let mut coefficients = [[0.0; N_BASIS]; MAX_CHANNELS];
    for ch in 0..3 {
        coefficients[ch][..4].copy_from_slice(&c[ch]);
    }
    let rec = Record {
        device_id: id,
        created_unix_s: 1_800_000_000,
        structure: MODEL_4,
        n_channels: 3,
        coefficients,
        g_m_s2: Some(G),
        thermal: None,
    };
    let mut buf = [0u8; MAX_RECORD_LEN];
    let n = rec.emit(&mut buf).unwrap();
    buf[..n].to_vec()
}

/// A six-position verification whose largest error is `max_err` m/s².
pub fn verification(device: &str, max_err: f64, tol: f64) -> VerifyReport {
    let positions = (1..=6)
        .map(|p| {
            let e = max_err * p as f64 / 6.0;
            PositionCheck {
                position: p,
                alpha_deg: 90.0 * p as f64,
                beta_deg: 0.0,
                read_back_alpha_deg: Some(90.0 * p as f64),
                read_back_beta_deg: Some(0.0),
                expected_m_s2: [0.0, 0.0, G],
                measured_m_s2: [e, 0.0, G],
                error_m_s2: [e, 0.0, 0.0],
                sd_mean_m_s2: [1e-4; 3],
                tolerance_m_s2: [tol; 3],
                lost: 0,
                temp_c: None,
                out_of_range: false,
                pass: e.abs() <= tol,
                u_expanded_m_s2: None,
                decisions: None,
            }
        })
        .collect::<Vec<_>>();
    VerifyReport {
        version: accelcal_core::document::VERIFY_VERSION,
        device_id: device.into(),
        record: serde_json::json!({"slot": 0, "sequence": 1, "created_unix_s": 1_800_000_000, "crc": "00000000"}),
        g_m_s2: G,
        chamber_c: None,
        tolerance_rule: format!("|error| <= {tol} m/s² on every component (--tolerance)"),
        static_rule: "static".into(),
        pass: positions.iter().all(|p| p.pass),
        positions,
        interrupted: false,
        fit: None,
        specification: None,
        decision: None,
        parameters: None,
    }
}

/// A campaign file of `rows` rows.
pub fn campaign(rows: usize) -> Vec<u8> {
    let mut s = String::from("# device_id: 51454d552d422d4c34373545\nposition,alpha_deg,beta_deg,x,y,z\n");
    for r in 0..rows {
        s.push_str(&format!("{},{},0,{},{},{}\n", r / 100 + 1, 90 * (r / 100), 32768 + r % 7, 32770, 34400));
    }
    s.into_bytes()
}

/// One whole calibration run, as a station stores it.
pub fn calibrate(db: &mut Db, s: &RunStart, c: &Coefs, as_found: Option<f64>) -> RunId {
    let run = s.run_id;
    db.begin_run(s, None).unwrap();
    if let Some(e) = as_found {
        db.store_verification(run, Phase::AsFound, &verification(&s.device_id, e, 0.05)).unwrap();
    }
    db.store_campaign(run, &campaign(600)).unwrap();
    db.store_fit(run, &fit_json(c)).unwrap();
    let rec = db.store_record(run, &record(&s.device_id, c)).unwrap();
    db.record_flashed(&rec).unwrap();
    db.store_verification(run, Phase::AsLeft, &verification(&s.device_id, 0.002, 0.05)).unwrap();
    db.store_certificate(run, "<html>certificate</html>").unwrap();
    db.finish_run(run, Outcome::Pass, "verified").unwrap();
    run
}

/// Every piece stored once, each stored again is a no-op, a different one is refused, and a
/// finished run takes nothing more.
pub fn pieces_are_stored_once(spec: &str) {
    let mut db = Db::open(spec).unwrap();
    let s = start(RunId::new(), DEVICE, "SN-0001", "st-1", T0);
    let c = coefs(0.0, 0);
    let run = s.run_id;
    assert_eq!(db.begin_run(&s, None).unwrap(), Stored::New);
    assert_eq!(db.begin_run(&s, None).unwrap(), Stored::Already);
    let other = RunStart { station: "st-2".into(), ..s.clone() };
    assert!(matches!(db.begin_run(&other, None), Err(DbError::Conflict { .. })));
    assert_eq!(db.store_campaign(run, &campaign(300)).unwrap(), Stored::New);
    assert_eq!(db.store_campaign(run, &campaign(300)).unwrap(), Stored::Already);
    let e = db.store_campaign(run, &campaign(301)).unwrap_err();
    assert!(e.to_string().contains("it holds another campaign already"), "{e}");
    assert_eq!(db.store_fit(run, &fit_json(&c)).unwrap(), Stored::New);
    let foreign = db.store_record(run, &record("00112233445566778899aabb", &c)).unwrap_err();
    assert!(
        foreign.to_string().contains(
            "the record's device id 00112233445566778899aabb is not the run's 51454d552d422d4c34373545"
        ),
        "{foreign}"
    );
    let e = db.store_record(run, b"not a record").unwrap_err();
    assert!(matches!(e, DbError::BadPiece { piece: "record", .. }), "{e}");
    let rec = db.store_record(run, &record(DEVICE, &c)).unwrap();
    assert_eq!(rec.bytes(), &record(DEVICE, &c)[..]);
    let p = db.progress(run).unwrap();
    assert!(p.campaign && p.fit && !p.flashed && p.record == Some(rec.clone()) && p.outcome.is_none());
    db.record_flashed(&rec).unwrap();
    let e = db.store_verification(run, Phase::AsLeft, &verification("00112233445566778899aabb", 0.001, 0.05));
    assert!(matches!(e, Err(DbError::Mismatch { .. })), "{e:?}");
    db.store_verification(run, Phase::AsLeft, &verification(DEVICE, 0.001, 0.05)).unwrap();
    db.finish_run(run, Outcome::Pass, "verified").unwrap();
    assert_eq!(db.finish_run(run, Outcome::Pass, "verified").unwrap(), Stored::Already);
    let e = db.store_certificate(run, "<html/>").unwrap_err();
    assert!(e.to_string().contains("the run is finished (pass): its certificate cannot be stored"), "{e}");
    let e = db.store_fit(RunId::new(), &fit_json(&c)).unwrap_err();
    assert!(matches!(e, DbError::NoRun { .. }), "{e}");
    let p = db.progress(run).unwrap();
    assert!(p.flashed && p.as_left && !p.as_found && !p.certificate && p.outcome == Some(Outcome::Pass));
    assert_eq!(db.schema_versions().unwrap(), vec![1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12]);
    // Opening again migrates nothing.
    drop(db);
    assert_eq!(
        Db::open(spec).unwrap().schema_versions().unwrap(),
        vec![1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12]
    );
}

/// The environment variable that turns a test process into the writer that is killed.
pub const CHILD_ENV: &str = "ACCELCAL_TEST_DB_WRITER";

/// In the child process: begins the run, stores the campaign and the fit, says so on stdout
/// after each, and waits to be killed.
pub fn writer_child() -> bool {
    let Ok(arg) = std::env::var(CHILD_ENV) else { return false };
    let (spec, run) = arg.split_once('\t').unwrap();
    let run = RunId::parse(run).unwrap();
    let mut db = Db::open(spec).unwrap();
    let c = coefs(0.0, 0);
    db.begin_run(&start(run, DEVICE, "SN-0009", "st-1", T0), None).unwrap();
    println!("begun");
    db.store_campaign(run, &campaign(20_000)).unwrap();
    println!("campaign");
    db.store_fit(run, &fit_json(&c)).unwrap();
    println!("fit");
    loop {
        std::thread::sleep(std::time::Duration::from_secs(1));
    }
}

/// A writer killed (SIGKILL) after storing its fit; the run resumed under its id holds every
/// piece once. `test` is the name of the calling test and `module` its `module_path!()`: the
/// child runs that test again, named by its path in the test binary (`db::…`).
pub fn killed_writer_resumes(spec: &str, module: &str, test: &str) -> RunId {
    Db::open(spec).unwrap();
    let run = RunId::new();
    let path = match module.split_once("::") {
        Some((_crate, inside)) => format!("{inside}::{test}"),
        None => test.to_string(),
    };
    let mut child = Command::new(std::env::current_exe().unwrap())
        .args(["--exact", &path, "--nocapture", "--test-threads", "1"])
        .env(CHILD_ENV, format!("{spec}\t{run}"))
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    let mut lines = BufReader::new(child.stdout.take().unwrap()).lines();
    loop {
        let l = lines.next().expect("the writer ended before storing its fit").unwrap();
        if l == "fit" {
            break;
        }
    }
    child.kill().unwrap(); // SIGKILL
    let status = child.wait().unwrap();
    assert!(!status.success());
    let mut db = Db::open(spec).unwrap();
    let p = db.progress(run).unwrap();
    assert!(p.campaign && p.fit && p.record.is_none() && p.outcome.is_none(), "{p:?}");
    // The station resumes: what is stored is skipped or stored again identically.
    let c = coefs(0.0, 0);
    assert_eq!(db.begin_run(&p.start, None).unwrap(), Stored::Already);
    assert_eq!(db.store_campaign(run, &campaign(20_000)).unwrap(), Stored::Already);
    assert_eq!(db.store_fit(run, &fit_json(&c)).unwrap(), Stored::Already);
    let rec = db.store_record(run, &record(DEVICE, &c)).unwrap();
    db.record_flashed(&rec).unwrap();
    db.store_verification(run, Phase::AsLeft, &verification(DEVICE, 0.002, 0.05)).unwrap();
    db.finish_run(run, Outcome::Pass, "verified").unwrap();
    let runs = db.unit_runs("SN-0009").unwrap();
    assert_eq!(runs.len(), 1);
    assert!(runs[0].fit_json.is_some() && runs[0].campaign_sha256.is_some() && runs[0].end.is_some());
    run
}

/// Two stations writing at once, `n` units each: every run whole, none lost.
pub fn two_writers_lose_nothing(spec: &str, n: usize) {
    Db::open(spec).unwrap();
    let writers: Vec<_> = (0..2)
        .map(|w| {
            let spec = spec.to_string();
            std::thread::spawn(move || {
                let mut db = Db::open(&spec).unwrap();
                for u in 0..n {
                    let device = format!("{:012x}{:012x}", 0xabc000 + w, u);
                    let s =
                        start(RunId::new(), &device, &format!("W{w}-{u}"), &format!("st-{w}"), T0 + u as i64);
                    calibrate(&mut db, &s, &coefs(1.0, u), Some(0.01));
                }
            })
        })
        .collect();
    for w in writers {
        w.join().unwrap();
    }
    let mut db = Db::open(spec).unwrap();
    for w in 0..2 {
        for u in 0..n {
            let runs = db.unit_runs(&format!("W{w}-{u}")).unwrap();
            assert_eq!(runs.len(), 1, "W{w}-{u}");
            let r = &runs[0];
            assert!(
                r.fit_json.is_some()
                    && r.record_crc32.is_some()
                    && r.flashed_unix_s.is_some()
                    && r.as_found.is_some()
                    && r.as_left.is_some()
                    && r.end.is_some(),
                "W{w}-{u}: {r:?}"
            );
        }
    }
}

/// Runs `accelcal` and returns (exit code, stdout, stderr).
pub fn accelcal(args: &[&str]) -> (Option<i32>, String, String) {
    let out =
        Command::new(env!("CARGO_BIN_EXE_accelcal")).args(args).env_remove("ACCELCAL_DB").output().unwrap();
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// A running cluster, stopped and removed on drop.
pub struct Cluster {
    dir: tempfile::TempDir,
    /// Its URL, for `--db`.
    pub url: String,
}

fn script() -> std::path::PathBuf {
    std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../scripts/postgres-cluster.sh")
}

impl Cluster {
    /// Starts a throwaway cluster (`scripts/postgres-cluster.sh start`).
    pub fn start() -> Cluster {
        let dir = tempfile::Builder::new().prefix("accelcal-pg").tempdir().unwrap();
        let out =
            std::process::Command::new("bash").arg(script()).arg("start").arg(dir.path()).output().unwrap();
        assert!(
            out.status.success(),
            "starting a PostgreSQL cluster failed (is the server installed? scripts/setup-postgres.sh): {}",
            String::from_utf8_lossy(&out.stderr)
        );
        let url = String::from_utf8(out.stdout).unwrap().trim().to_string();
        Cluster { dir, url }
    }
}

impl Drop for Cluster {
    fn drop(&mut self) {
        let _ = std::process::Command::new("bash").arg(script()).arg("stop").arg(self.dir.path()).status();
    }
}

/// Another device of the line.
pub const DEVICE_2: &str = "0123456789abcdef01234567";

/// Issue 28 item 5: a serial tied to another device, or a device tied to another serial, is
/// refused; `relabel` moves the serial (a row with the reason) and `history` follows it; a voided
/// run is listed but counts neither as a calibration nor as a label.
pub fn labels_and_voids(spec: &str) {
    use accelcal_db::{LabelClash, Relabel};
    let mut db = Db::open(spec).unwrap();
    let a = calibrate(&mut db, &start(RunId::new(), DEVICE, "U-0045", "st-1", T0), &coefs(0.0, 0), None);
    calibrate(&mut db, &start(RunId::new(), DEVICE_2, "U-0044", "st-1", T0 + 10), &coefs(0.0, 0), None);
    // Device 1 (U-0045) brought in under U-0044's label: refused, nothing begun.
    let mislabel = start(RunId::new(), DEVICE, "U-0044", "st-1", T0 + DAY);
    let e = db.begin_run(&mislabel, None).unwrap_err();
    assert!(matches!(&e, DbError::Label(c) if matches!(**c, LabelClash::SerialOfAnother { .. })), "{e}");
    let msg = e.to_string();
    assert!(
        msg.contains(&format!("serial U-0044 is device {DEVICE_2}")) && msg.contains("--relabel REASON"),
        "{msg}"
    );
    assert!(matches!(db.progress(mislabel.run_id), Err(DbError::NoRun { .. })));
    // A serial no device carries, on device 1: refused too (the device is U-0045).
    let e = db.begin_run(&start(RunId::new(), DEVICE, "U-0099", "st-1", T0 + DAY), None).unwrap_err();
    assert!(e.to_string().contains(&format!("device {DEVICE} is unit U-0045 in the database")), "{e}");
    // A relabel where nothing clashes is refused.
    let r = Relabel { reason: "the label was swapped with U-0044's".into(), operator: "ana".into() };
    let e = db.begin_run(&start(RunId::new(), DEVICE, "U-0045", "st-1", T0 + DAY), Some(&r)).unwrap_err();
    assert!(matches!(&e, DbError::Label(c) if matches!(**c, LabelClash::NothingToRelabel { .. })), "{e}");
    // On purpose: device 1 becomes U-0044, device 2 loses the serial.
    let moved = start(RunId::new(), DEVICE, "U-0044", "st-1", T0 + 2 * DAY);
    assert_eq!(db.begin_run(&moved, Some(&r)).unwrap(), Stored::New);
    assert_eq!(db.begin_run(&moved, Some(&r)).unwrap(), Stored::Already, "a resumed run");
    let l = db.label_of(DEVICE).unwrap().unwrap();
    assert_eq!(l.serial, "U-0044");
    assert_eq!(db.label_of(DEVICE_2).unwrap().unwrap().serial, "");
    let runs = db.unit_runs("U-0044").unwrap();
    assert_eq!(runs[0].start.device_id, DEVICE, "history follows the relabel");
    assert_eq!(db.unit_runs("U-0045").unwrap()[0].start.device_id, DEVICE, "the old serial too");
    // Void: listed as voided, not a calibration; again with the same reason a no-op; another refused.
    assert_eq!(db.void_run(a, "measured on a head out of true", "ana").unwrap(), Stored::New);
    assert_eq!(db.void_run(a, "measured on a head out of true", "ana").unwrap(), Stored::Already);
    assert!(matches!(db.void_run(a, "another reason", "ana"), Err(DbError::Conflict { .. })));
    let runs = db.unit_runs(DEVICE).unwrap();
    let voided = runs.iter().find(|r| r.start.run_id == a).unwrap();
    assert_eq!(voided.voided.as_ref().unwrap().0, "measured on a head out of true");
    let h = accelcal_db::history::history(&runs, accelcal_db::history::DEFAULT_RULE);
    assert_eq!(h.recalibration.calibrations, 0, "the voided run is no calibration");
    // A voided run takes nothing more.
    assert!(matches!(db.store_certificate(moved.run_id, "x"), Ok(Stored::New)));
    db.void_run(moved.run_id, "mislabelled", "ana").unwrap();
    let e = db.store_fit(moved.run_id, &fit_json(&coefs(0.0, 0))).unwrap_err();
    assert!(e.to_string().contains("the run is voided (mislabelled)"), "{e}");
    // Everything written is on the chain.
    let r = db.verify_chain().unwrap();
    assert!(r.mismatches.is_empty(), "{:?}", r.mismatches);
    assert!(r.entries >= 20 && r.runs == 3, "{r:?}");
}

/// Issue 28 item 9: a row changed behind accelcal's back (`tamper` runs SQL on the database
/// with the triggers out of the way) is found by `db verify`, named, and stops `flash --db`.
pub fn a_changed_row_breaks_the_chain(spec: &str, postgres: bool, tamper: &dyn Fn(&str)) {
    let mut db = Db::open(spec).unwrap();
    let s = start(RunId::new(), DEVICE, "SN-7", "st-1", T0);
    let run = s.run_id;
    db.begin_run(&s, None).unwrap();
    db.store_campaign(run, &campaign(60)).unwrap();
    db.store_fit(run, &fit_json(&coefs(0.0, 0))).unwrap();
    let rec = record(DEVICE, &coefs(0.0, 0));
    db.store_record(run, &rec).unwrap();
    let other =
        calibrate(&mut db, &start(RunId::new(), DEVICE_2, "SN-8", "st-1", T0 + 5), &coefs(0.0, 1), None);
    assert_eq!(db.verify_run(run).unwrap().seq, 4, "{run}");
    let (code, out, err) = accelcal(&["db", "verify", "--db", spec]);
    assert_eq!(code, Some(0), "{out}{err}");
    assert!(out.contains("every row matches its hash chain"), "{out}");
    // Another unit's record forged into the run, its CRC and hash made to match.
    let forged = record(DEVICE, &coefs(0.0, 3));
    let crc = u32::from_le_bytes(forged[forged.len() - 4..].try_into().unwrap());
    let hex: String = forged.iter().map(|b| format!("{b:02x}")).collect();
    tamper(&format!(
        "{} cal_record (run_id, bytes, crc32, stored_unix_s, content_sha256) VALUES ('{run}', {}, {crc}, {T0}, '{}')",
        if postgres { "DELETE FROM cal_record WHERE run_id = '".to_string() + &run.to_string() + "'; INSERT INTO" } else { "REPLACE INTO".into() },
        if postgres { format!("'\\x{hex}'::bytea") } else { format!("X'{hex}'") },
        accelcal_db::sha256_hex(&forged)
    ));
    let (code, out, err) = accelcal(&["db", "verify", "--db", spec]);
    assert_eq!(code, Some(1), "{out}{err}");
    assert!(
        out.contains(&format!(
            "the first row that does not match is the cal_record row of run {run} (ledger entry 4)"
        )),
        "{out}"
    );
    assert!(err.contains("does not match its hash chain") && err.lines().count() == 1, "{err}");
    // The forged record is never flashed.
    let d = tempfile::tempdir().unwrap();
    let f = d.path().join("forged.rec");
    std::fs::write(&f, &forged).unwrap();
    let (code, _, err) = accelcal(&[
        "flash",
        f.to_str().unwrap(),
        "--db",
        spec,
        "--run-id",
        &run.to_string(),
        "--gdb",
        "127.0.0.1:1",
    ]);
    assert_eq!(code, Some(2), "{err}");
    assert!(
        err.contains(&format!(
            "run {run}: the database's rows do not match their hash chain: the cal_record row"
        )),
        "{err}"
    );
    // The other run is untouched and still usable.
    db.verify_run(other).unwrap();
}

/// Issue 28 item 11: writers racing to begin and store into one run id: one writes each row, the
/// others find it there (`Already`), none fails.
pub fn writers_racing_on_one_run(spec: &str) {
    let s = start(RunId::new(), DEVICE, "SN-R", "st-1", T0);
    let results: Vec<(Stored, Stored)> = std::thread::scope(|scope| {
        let handles: Vec<_> = (0..8)
            .map(|_| {
                let s = s.clone();
                scope.spawn(move || {
                    let mut db = Db::open(spec).unwrap();
                    let begun = db.begin_run(&s, None).unwrap();
                    let fit = db.store_fit(s.run_id, &fit_json(&coefs(0.0, 0))).unwrap();
                    (begun, fit)
                })
            })
            .collect();
        handles.into_iter().map(|h| h.join().unwrap()).collect()
    });
    for pick in [|r: &(Stored, Stored)| r.0, |r: &(Stored, Stored)| r.1] {
        assert_eq!(results.iter().map(pick).filter(|s| *s == Stored::New).count(), 1, "{results:?}");
    }
    let r = Db::open(spec).unwrap().verify_chain().unwrap();
    assert!(r.mismatches.is_empty() && r.entries == 2, "{r:?}");
}

/// A head asset's certificate.
pub fn head_asset(id: &str, certificate: &str, due: &str, angle_u: f64, registered: i64) -> Asset {
    Asset {
        asset_id: id.into(),
        kind: AssetKind::Head,
        certificate: certificate.into(),
        due_date: accelcal_db::asset::parse_date(due).unwrap(),
        angle_u_arcsec: angle_u,
        orthogonality_u_arcsec: 2.0 * angle_u,
        operator: "ana".into(),
        registered_unix_s: registered,
        value: None,
    }
}

fn date(s: &str) -> accelcal_db::asset::Date {
    accelcal_db::asset::parse_date(s).unwrap()
}

fn asset_refusal(e: DbError) -> String {
    match e {
        DbError::Asset(a) => a.to_string(),
        other => panic!("not an asset refusal: {other}"),
    }
}

/// Assets: a certificate registered once (again: a no-op; changed: refused), a recalibration's
/// new certificate in force, an overdue, unknown or other-kind asset refused, one head per run,
/// and `affected` naming the runs since a date; the hash chain covers it all.
pub fn assets_register_and_trace(spec: &str) {
    let mut db = Db::open(spec).unwrap();
    assert_eq!(
        db.add_asset(&head_asset("HEAD-1", "DKD-17-001", "2026-03-31", 3.0, T0)).unwrap(),
        Stored::New
    );
    let recal = head_asset("HEAD-1", "DKD-17-002", "2027-03-31", 2.5, T0 + 80 * DAY);
    assert_eq!(db.add_asset(&recal).unwrap(), Stored::New);
    assert_eq!(db.add_asset(&recal).unwrap(), Stored::Already, "the same certificate again");
    let changed = head_asset("HEAD-1", "DKD-17-002", "2028-03-31", 2.5, T0 + 90 * DAY);
    let e = asset_refusal(db.add_asset(&changed).unwrap_err());
    assert!(e.contains("registered already with other statements"), "{e}");
    let mut thermo = head_asset("HEAD-1", "T-1", "2027-01-01", 0.0, T0);
    thermo.kind = AssetKind::Thermometer;
    thermo.orthogonality_u_arcsec = 0.0;
    let e = asset_refusal(db.add_asset(&thermo).unwrap_err());
    assert!(e.contains("registered as a head, not a thermometer"), "{e}");
    thermo.asset_id = "PT100-7".into();
    assert_eq!(db.add_asset(&thermo).unwrap(), Stored::New);
    let mut stated = thermo.clone();
    stated.angle_u_arcsec = 1.0;
    stated.certificate = "T-2".into();
    let e = asset_refusal(db.add_asset(&stated).unwrap_err());
    assert!(e.contains("a thermometer states no angle uncertainty"), "{e}");
    let e = asset_refusal(db.add_asset(&head_asset("HEAD 1", "C", "2027-01-01", 1.0, T0)).unwrap_err());
    assert!(e.contains("letters, digits"), "{e}");

    let listed = db.assets().unwrap();
    let ids: Vec<(&str, &str)> =
        listed.iter().map(|a| (a.asset_id.as_str(), a.certificate.as_str())).collect();
    assert_eq!(ids, [("HEAD-1", "DKD-17-002"), ("PT100-7", "T-1")], "the certificate in force of each");
    assert_eq!(db.asset_certificates("HEAD-1").unwrap().len(), 2);

    let in_force = db.asset_in_force("HEAD-1", AssetKind::Head, date("2027-03-31")).unwrap();
    assert_eq!((in_force.certificate.as_str(), in_force.angle_u_arcsec), ("DKD-17-002", 2.5));
    for (id, kind, day, want) in [
        (
            "HEAD-1",
            AssetKind::Head,
            "2027-04-01",
            "is overdue: its certificate DKD-17-002 was due 2027-03-31",
        ),
        ("HEAD-9", AssetKind::Head, "2026-06-01", "asset `HEAD-9` is not registered"),
        ("PT100-7", AssetKind::Head, "2026-06-01", "asset `PT100-7` is a thermometer, not a head"),
    ] {
        let e = db.asset_in_force(id, kind, date(day)).unwrap_err();
        assert_eq!(accelcal_core::error::Classify::kind(&e), accelcal_core::error::Kind::Environment, "{e}");
        let e = asset_refusal(e);
        assert!(e.contains(want), "{e}");
    }

    // Two runs with the head (under each certificate), one without.
    let old = start(RunId::new(), DEVICE, "SN-0100", "st-1", T0 + 10 * DAY);
    db.begin_run(&old, None).unwrap();
    let first = db.asset_certificates("HEAD-1").unwrap().remove(0);
    assert_eq!(db.store_run_asset(old.run_id, &first).unwrap(), Stored::New);
    calibrate(&mut db, &old, &coefs(0.0, 0), None);
    let new = start(RunId::new(), DEVICE_2, "SN-0101", "st-2", T0 + 100 * DAY);
    db.begin_run(&new, None).unwrap();
    assert_eq!(db.store_run_asset(new.run_id, &in_force).unwrap(), Stored::New);
    assert_eq!(db.store_run_asset(new.run_id, &in_force).unwrap(), Stored::Already);
    let e = db.store_run_asset(new.run_id, &first).unwrap_err().to_string();
    assert!(e.contains("holds another head asset already"), "{e}");
    assert_eq!(db.store_run_asset(new.run_id, &thermo).unwrap(), Stored::New, "one asset per kind");
    let without = start(RunId::new(), "00112233445566778899aabb", "SN-0102", "st-1", T0 + 120 * DAY);
    calibrate(&mut db, &without, &coefs(0.0, 0), None);
    let e = db.store_run_asset(without.run_id, &in_force).unwrap_err().to_string();
    assert!(e.contains("the run is finished"), "{e}");

    let all = db.affected("HEAD-1", 0).unwrap();
    let got: Vec<(String, &str, bool, Option<Outcome>)> =
        all.iter().map(|r| (r.run_id.clone(), r.certificate.as_str(), r.certified, r.outcome)).collect();
    assert_eq!(
        got,
        [
            (old.run_id.to_string(), "DKD-17-001", true, Some(Outcome::Pass)),
            (new.run_id.to_string(), "DKD-17-002", false, None),
        ]
    );
    assert_eq!(all[1].serial, "SN-0101");
    let since = db.affected("HEAD-1", T0 + 50 * DAY).unwrap();
    assert_eq!(since.iter().map(|r| r.run_id.clone()).collect::<Vec<_>>(), [new.run_id.to_string()]);
    assert!(db.affected("HEAD-1", T0 + 400 * DAY).unwrap().is_empty());
    assert!(asset_refusal(db.affected("HEAD-9", 0).unwrap_err()).contains("not registered"));
    let kinds: Vec<AssetKind> = db.run_assets(new.run_id).unwrap().into_iter().map(|(k, _, _)| k).collect();
    assert_eq!(kinds, [AssetKind::Head, AssetKind::Thermometer]);

    let report = db.verify_chain().unwrap();
    assert!(report.mismatches.is_empty(), "{:?}", report.mismatches);
    db.verify_run(new.run_id).unwrap();
}

/// Every table's columns, as the engine reports them, are the chain's (each row's digest takes
/// every column, in order).
pub fn columns_are_the_chain_s(columns_of: &mut dyn FnMut(&str) -> Vec<String>) {
    for t in accelcal_db::chain::TABLES.iter() {
        assert_eq!(columns_of(t.name), t.columns, "table {}", t.name);
    }
}

/// The tables whose rows the engines' triggers keep (each holds a row after [`with_head_asset`]).
pub const APPEND_ONLY: [&str; 10] = [
    "run",
    "campaign",
    "fit",
    "cal_record",
    "flash",
    "verification",
    "certificate",
    "run_end",
    "asset",
    "run_asset",
];

/// One whole run calibrated with a registered head.
pub fn with_head_asset(db: &mut Db) -> RunId {
    let head = head_asset("HEAD-1", "DKD-17-001", "2099-12-31", 3.0, T0);
    db.add_asset(&head).unwrap();
    let s = start(RunId::new(), DEVICE, "SN-1", "st-1", T0);
    db.begin_run(&s, None).unwrap();
    db.store_run_asset(s.run_id, &head).unwrap();
    calibrate(db, &s, &coefs(0.0, 0), Some(0.01))
}

/// Certificate numbers (ISO/IEC 17025 §7.8.2.1): one per run, the same when the certificate is
/// printed again, the next one for the next run, never given twice: not for a voided run's
/// (refused, and its number stays used), nor for a finished run. Each is in the hash chain.
pub fn certificate_numbers_are_never_reused(spec: &str) {
    let mut db = Db::open(spec).unwrap();
    let year = accelcal_db::asset::today_utc().year();
    let begun = |db: &mut Db, serial: &str, t: i64| {
        let s = start(RunId::new(), DEVICE, serial, "st-1", t);
        db.begin_run(&s, None).unwrap();
        s.run_id
    };
    let a = begun(&mut db, "SN-C1", T0);
    let first = db.certificate_number(a).unwrap();
    assert_eq!((first.sequence, first.number.clone()), (1, format!("{year}-000001")));
    assert_eq!(db.certificate_number(a).unwrap(), first, "the same run, the same number");
    let b = begun(&mut db, "SN-C1", T0 + DAY);
    let second = db.certificate_number(b).unwrap();
    assert_eq!(second.number, format!("{year}-000002"));
    db.void_run(b, "the head was found out of true", "qa").unwrap();
    let e = db.certificate_number(b).unwrap_err().to_string();
    assert!(
        e.contains("the run is voided (the head was found out of true): its certificate cannot be numbered"),
        "{e}"
    );
    let c = begun(&mut db, "SN-C1", T0 + 2 * DAY);
    assert_eq!(
        db.certificate_number(c).unwrap().number,
        format!("{year}-000003"),
        "a voided run's number stays used"
    );
    db.finish_run(c, Outcome::Rejected, "selection beyond model 4").unwrap();
    let d = begun(&mut db, "SN-C1", T0 + 3 * DAY);
    db.finish_run(d, Outcome::Rejected, "selection beyond model 4").unwrap();
    let e = db.certificate_number(d).unwrap_err().to_string();
    assert!(e.contains("the run is finished (rejected): its certificate cannot be numbered"), "{e}");
    assert!(matches!(db.certificate_number(RunId::new()), Err(DbError::NoRun { .. })));
    let r = db.verify_chain().unwrap();
    assert!(r.mismatches.is_empty(), "{:?}", r.mismatches);
}

/// Schema 5: the recalibration date a certificate states is stored with its number, and printing
/// it again states the date first stored, whatever the drift says by then; a run numbered without
/// a date keeps none. The view `verification_decision` gives each verification's decision and
/// rule as columns (`decisions` runs `SELECT run_id, decision, rule FROM verification_decision`
/// on the engine). Every row is in the hash chain.
pub fn recalibration_dates_and_decisions_are_stored(
    spec: &str,
    decisions: &mut dyn FnMut() -> Vec<(String, Option<String>, Option<String>)>,
) {
    use accelcal_core::conformity::Decision;
    use accelcal_db::RecalibrationDue;
    let mut db = Db::open(spec).unwrap();
    let begun = |db: &mut Db, serial: &str, t: i64| {
        let s = start(RunId::new(), DEVICE, serial, "st-1", t);
        db.begin_run(&s, None).unwrap();
        s.run_id
    };
    let a = begun(&mut db, "SN-D1", T0);
    let due = RecalibrationDue { due_unix_s: T0 + 365 * DAY, basis: "the maximum interval".into() };
    let (n, stored) = db.certificate_number_with_due(a, &due).unwrap();
    assert_eq!(stored.as_ref(), Some(&due));
    let later = RecalibrationDue { due_unix_s: T0 + 100 * DAY, basis: "the drift of x's bias".into() };
    assert_eq!(db.certificate_number_with_due(a, &later).unwrap(), (n.clone(), Some(due.clone())));
    assert_eq!(db.certificate_number(a).unwrap(), n);
    let b = begun(&mut db, "SN-D1", T0 + DAY);
    let nb = db.certificate_number(b).unwrap();
    assert_eq!(db.certificate_number_with_due(b, &later).unwrap(), (nb, None));

    let found = decided_as_found(DEVICE, Decision::ConditionalFail);
    db.store_verification(a, Phase::AsFound, &found).unwrap();
    db.store_verification(b, Phase::AsFound, &verification(DEVICE, 0.001, 0.05)).unwrap();
    let mut rows = decisions();
    rows.sort();
    let mut want = vec![
        (a.to_string(), Some("conditional fail".to_string()), Some("guard-band".to_string())),
        (b.to_string(), None, None),
    ];
    want.sort();
    assert_eq!(rows, want);
    let r = db.verify_chain().unwrap();
    assert!(r.mismatches.is_empty(), "{:?}", r.mismatches);
}

/// An as-found verification with an error of 0.09 m/s², decided `decision` by the guard-band rule
/// against T = 0.05 m/s².
pub fn decided_as_found(device: &str, decision: accelcal_core::conformity::Decision) -> VerifyReport {
    use accelcal_core::conformity::{RuleKind, Specification};
    let mut found = verification(device, 0.09, 0.05);
    found.specification = Some(Specification {
        unit_type: "MS9002.D".into(),
        acceleration_error_m_s2: 0.05,
        rule: RuleKind::GuardBand,
        guard_band_m_s2: None,
        bias_mg: None,
        scale_factor_ppm: None,
        misalignment_urad: None,
    });
    found.decision = Some(decision);
    found
}

/// A reader (`fleet`, `serve`, `history`: a database opened to read) does not wait for a
/// writer. `hold` takes the writers' lock as a station's store does and keeps it
/// until the guard it returns is dropped (SQLite: `BEGIN IMMEDIATE`; PostgreSQL: the ledger's
/// advisory lock); meanwhile the period's fleet, read on two connections at once as `fleet`
/// reads it, is counted well within the writers' 10 s wait.
pub fn a_reader_does_not_wait_for_a_writer<G>(spec: &str, hold: impl FnOnce() -> G) {
    use accelcal_db::fleet::Filter;
    let mut db = Db::open(spec).unwrap();
    let s = start(RunId::parse("00000000000000000000000000000a11").unwrap(), DEVICE, "SN-R1", "st-1", T0);
    calibrate(&mut db, &s, &coefs(0.0, 0), None);
    drop(db);
    let filter = Filter { since_unix_s: T0 - DAY, until_unix_s: T0 + DAY, ..Filter::default() };
    let guard = hold();
    let t = std::time::Instant::now();
    let (tx, rx) = std::sync::mpsc::channel();
    let spec2 = spec.to_string();
    std::thread::spawn(move || {
        let read = || -> Result<(i64, usize), DbError> {
            let mut reader = Db::open_existing(&spec2)?;
            let mut again = reader.open_again()?;
            Ok((reader.fleet_counts(&filter)?.passed, again.fleet_runs(&filter)?.len()))
        };
        let _ = tx.send(read());
    });
    let read = rx.recv_timeout(std::time::Duration::from_secs(5));
    drop(guard);
    let read = read.expect("the reader waited for the writer's lock (no answer in 5 s)");
    assert_eq!(read.unwrap(), (1, 1));
    assert!(t.elapsed() < std::time::Duration::from_secs(5), "{:?}", t.elapsed());
}
