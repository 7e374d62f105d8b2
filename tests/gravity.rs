//! Integration tests of the gravity-norm calibration: simulated hand-placed sessions with a known truth,
//! the command-line front end, and the real imu_tk Xsens recording.

use std::path::{Path, PathBuf};

use accelcal_core::gravity::fit::GravityStructure;
use accelcal_core::gravity::holds::DetectorConfig;
use accelcal_core::gravity::sim::{simulate, SessionConfig};
use accelcal_core::gravity::{calibrate, calibrate_path, StructureChoice};

/// Tolerances of parameter recovery on a simulated session like the real file (noise 3.3 codes,
/// 414 codes per m/s², 38 holds of 4–11 s): bias in codes, scale relative, angles in radians.
const BIAS_TOL: f64 = 1.0;
const SCALE_REL_TOL: f64 = 2e-4;
const ANGLE_TOL: f64 = 5e-4;

#[test]
fn recovers_the_truth_of_simulated_sessions() {
    for seed in 1..=4 {
        let cfg = SessionConfig { seed, ..SessionConfig::default() };
        let s = simulate(&cfg);
        let rec = &s.recording;
        let cal = calibrate(
            &rec.t,
            &rec.codes,
            cfg.g,
            &DetectorConfig::default(),
            StructureChoice::Fixed(GravityStructure::ImuTk),
        )
        .unwrap();
        let det = &cal.detection;
        // Every true static interval is found once, and every detected hold lies inside a true one.
        assert_eq!(det.holds.len(), s.holds.len(), "seed {seed}: rejected {:?}", det.rejected);
        for (h, &(ts, te)) in det.holds.iter().zip(&s.holds) {
            assert!(
                h.start >= ts && h.end <= te,
                "seed {seed}: hold {}..{} outside {ts}..{te}",
                h.start,
                h.end
            );
        }
        let (m, se, t) = (&cal.fit.model, &cal.fit.std_err, &cfg.truth);
        for i in 0..3 {
            let db = m.bias[i] - t.bias[i];
            let ds = m.scale[i] / t.scale[i] - 1.0;
            let da = m.alpha[i] - t.alpha[i];
            assert!(db.abs() < BIAS_TOL, "seed {seed} bias[{i}] error {db}");
            assert!(ds.abs() < SCALE_REL_TOL, "seed {seed} scale[{i}] rel. error {ds}");
            assert!(da.abs() < ANGLE_TOL, "seed {seed} alpha[{i}] error {da}");
            // The stated uncertainties cover the actual errors.
            assert!(db.abs() < 4.0 * se.bias[i], "seed {seed} bias[{i}] error {db} vs σ {}", se.bias[i]);
            assert!((m.scale[i] - t.scale[i]).abs() < 4.0 * se.scale[i], "seed {seed} scale[{i}]");
            assert!(da.abs() < 4.0 * se.alpha[i], "seed {seed} alpha[{i}] error {da} vs σ {}", se.alpha[i]);
        }
        // Hold means carry ~3.3/sqrt(600) codes of noise, i.e. a few 1e-4 m/s².
        assert!(cal.fit.rms < 1e-3, "seed {seed}: rms {}", cal.fit.rms);
        assert_eq!(cal.selected, Some(GravityStructure::ImuTk), "seed {seed}: {:?}", cal.scores);
    }
}

#[test]
fn a_shorter_minimum_hold_and_noisier_sensor_still_calibrate() {
    let cfg = SessionConfig {
        seed: 7,
        holds: 16,
        hold_s: (2.5, 4.0),
        noise_codes: 10.0,
        ..SessionConfig::default()
    };
    let s = simulate(&cfg);
    let rec = &s.recording;
    let det_cfg = DetectorConfig { min_hold_s: 1.0, ..DetectorConfig::default() };
    let cal = calibrate(&rec.t, &rec.codes, cfg.g, &det_cfg, StructureChoice::Fixed(GravityStructure::ImuTk))
        .unwrap();
    assert_eq!(cal.detection.holds.len(), 17, "{:?}", cal.detection.rejected);
    for i in 0..3 {
        assert!((cal.fit.model.bias[i] - cfg.truth.bias[i]).abs() < 5.0);
        assert!((cal.fit.model.scale[i] / cfg.truth.scale[i] - 1.0).abs() < 1e-3);
        assert!((cal.fit.model.alpha[i] - cfg.truth.alpha[i]).abs() < 2e-3);
    }
}

#[test]
fn gmdh_selects_the_quadratic_term_when_the_sensor_has_one() {
    let mut cfg = SessionConfig { seed: 3, ..SessionConfig::default() };
    cfg.truth.quad = [2e-3, -1.5e-3, 1e-3];
    let s = simulate(&cfg);
    let rec = &s.recording;
    let cal =
        calibrate(&rec.t, &rec.codes, cfg.g, &DetectorConfig::default(), StructureChoice::Auto).unwrap();
    assert_eq!(cal.selected, Some(GravityStructure::ImuTkQuadratic), "{:?}", cal.scores);
    assert_eq!(cal.fit.structure, GravityStructure::ImuTkQuadratic);
    for i in 0..3 {
        assert!((cal.fit.model.quad[i] - cfg.truth.quad[i]).abs() < 1e-4, "{:?}", cal.fit.model.quad);
    }
}

/// Runs the binary; returns (exit code, stdout, stderr).
fn accelcal(args: &[&str]) -> (Option<i32>, String, String) {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_accelcal")).args(args).output().unwrap();
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// The core's gravity-norm pipeline on a file, with the binary's defaults (imu_tk structure).
fn calibrate_file(
    path: &Path,
    g: f64,
    threshold: Option<f64>,
) -> (accelcal_core::gravity::imutk::Recording, accelcal_core::gravity::Calibration) {
    let det = DetectorConfig { threshold, ..DetectorConfig::default() };
    calibrate_path(path, g, &det, StructureChoice::Fixed(GravityStructure::ImuTk)).unwrap()
}

#[test]
fn cli_writes_json_in_the_issue_shape_and_plots() {
    let dir = tempfile::tempdir().unwrap();
    let cfg = SessionConfig { seed: 11, holds: 20, ..SessionConfig::default() };
    let (data, truth) = simulate(&cfg).write(dir.path(), "session").unwrap();
    assert!(truth.exists());
    let json = dir.path().join("cal.json");
    let plots = dir.path().join("plots");
    let (code, _, err) = accelcal(&[
        "fit",
        data.to_str().unwrap(),
        "--method",
        "gravity-norm",
        "--g",
        "9.81744",
        "--json",
        json.to_str().unwrap(),
        "--plot",
        plots.to_str().unwrap(),
    ]);
    assert_eq!(code, Some(0), "{err}");
    let v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let ch = v["channels"].as_array().unwrap();
    assert_eq!(ch.len(), 3);
    for (i, name) in ["x", "y", "z"].iter().enumerate() {
        assert_eq!(ch[i]["channel"], *name);
        let keys: Vec<&String> = ch[i].as_object().unwrap().keys().collect();
        assert_eq!(keys, ["bias", "channel", "scale"]);
        assert!((ch[i]["bias"].as_f64().unwrap() - cfg.truth.bias[i]).abs() < 2.0);
        assert!((ch[i]["scale"].as_f64().unwrap() / cfg.truth.scale[i] - 1.0).abs() < 1e-3);
    }
    let t = v["misalignment"].as_array().unwrap();
    assert_eq!(t.len(), 3);
    assert!(t.iter().all(|row| row.as_array().unwrap().len() == 3));
    assert_eq!(t[0][0], 1.0);
    assert!((t[1][2].as_f64().unwrap() + cfg.truth.alpha[2]).abs() < 1e-3, "T[1][2] = -alpha_zx");
    assert_eq!(v["holds"], 21);
    assert!(v["residual_rms"].as_f64().unwrap() < 1e-3);
    for file in ["gravity-residuals.svg", "gravity-detector.svg"] {
        let svg = std::fs::read_to_string(plots.join(file)).unwrap();
        assert!(svg.starts_with("<svg") && svg.contains("</svg>"), "{file}");
    }
}

#[test]
fn cli_reports_bad_input_with_file_and_line() {
    let dir = tempfile::tempdir().unwrap();
    let bad = dir.path().join("bad.txt");
    std::fs::write(&bad, "0 1 2 3\n0.01 1 2 oops\n").unwrap();
    let (code, _, msg) = accelcal(&["fit", bad.to_str().unwrap(), "--method", "gravity-norm"]);
    assert_eq!(code, Some(2), "{msg}");
    assert!(msg.contains("bad.txt:2:10: expected a number, found `oops`"), "{msg}");
    assert_eq!(msg.lines().count(), 1, "{msg}");
}

fn real_file() -> PathBuf {
    std::env::var_os("ACCELCAL_REAL_ACC").map(PathBuf::from).unwrap_or_else(|| {
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../tests/data/real/imu_tk_xsens_acc.txt.gz")
    })
}

#[test]
fn real_xsens_recording_calibrates_to_a_millimetre_per_second_squared() {
    let (rec, cal) = calibrate_file(&real_file(), 9.81744, None);
    assert_eq!(rec.len(), 51175);
    // About 38 hand-placed holds plus the initial rest.
    let n = cal.detection.holds.len();
    assert!((34..=42).contains(&n), "{n} holds");
    let first = &cal.detection.holds[0];
    assert!(
        first.t_start < 1.0 && first.t_end > 45.0,
        "initial rest {:.1}..{:.1}",
        first.t_start,
        first.t_end
    );
    // Measured: 0.00098 m/s² (see README-gravity.md); the issue asks for well below 0.05.
    assert!(cal.fit.rms < 0.002, "rms {}", cal.fit.rms);
    assert!(cal.fit.residuals.iter().all(|r| r.abs() < 0.005));
    // Without misalignment the fit is 30 times worse: the angles are real.
    let bs = cal.scores.iter().find(|s| s.structure == GravityStructure::BiasScale).unwrap();
    assert!(bs.fit_rms > 10.0 * cal.fit.rms, "{:?}", cal.scores);
    for i in 0..3 {
        assert!((cal.fit.model.scale[i] - 413.0).abs() < 5.0, "{:?}", cal.fit.model.scale);
        assert!((cal.fit.model.bias[i] - 33000.0).abs() < 1000.0, "{:?}", cal.fit.model.bias);
    }
}

#[test]
fn accelcal_fit_method_gravity_norm_runs_on_the_real_file() {
    let dir = tempfile::tempdir().unwrap();
    let json = dir.path().join("real.json");
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_accelcal"))
        .args(["fit", real_file().to_str().unwrap(), "--method", "gravity-norm", "--g", "9.81744"])
        .arg("--json")
        .arg(&json)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{stdout}\n{}", String::from_utf8_lossy(&out.stderr));
    assert!(stdout.contains("holds: 38 kept, 1 rejected"), "{stdout}");
    let v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    for key in ["channels", "misalignment", "holds", "residual_rms"] {
        assert!(v.get(key).is_some(), "missing {key}");
    }
    // The core's defaults that the other tests of the real file use are the binary's.
    let (_, cal) = calibrate_file(&real_file(), 9.81744, None);
    for i in 0..3 {
        let (b, s) =
            (v["channels"][i]["bias"].as_f64().unwrap(), v["channels"][i]["scale"].as_f64().unwrap());
        assert!(
            (b - cal.fit.model.bias[i]).abs() < 1e-9 * b.abs(),
            "bias[{i}]: {b} vs {}",
            cal.fit.model.bias[i]
        );
        assert!(
            (s - cal.fit.model.scale[i]).abs() < 1e-9 * s,
            "scale[{i}]: {s} vs {}",
            cal.fit.model.scale[i]
        );
    }
    assert_eq!(v["holds"], cal.detection.holds.len());
    // A malformed recording is bad input: exit code 2, message with file, line and column.
    let bad = dir.path().join("bad.txt");
    std::fs::write(&bad, "0 1 2 3\n0.01 1 2\n").unwrap();
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_accelcal"))
        .args(["fit", bad.to_str().unwrap(), "--method", "gravity-norm"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("bad.txt:2:1: expected 4 fields"));
}

#[test]
fn real_recording_result_does_not_hinge_on_the_threshold() {
    let base = calibrate_file(&real_file(), 9.81744, None).1;
    // From 2x to 30x the noise floor (about 30 codes²) the holds change but the calibration does not.
    for th in ["60", "1000"] {
        let cal = calibrate_file(&real_file(), 9.81744, Some(th.parse().unwrap())).1;
        assert!(cal.fit.rms < 0.002, "threshold {th}: rms {}", cal.fit.rms);
        for i in 0..3 {
            let ds = cal.fit.model.scale[i] - base.fit.model.scale[i];
            let db = cal.fit.model.bias[i] - base.fit.model.bias[i];
            assert!(ds.abs() < 2.0 * base.fit.std_err.scale[i], "threshold {th}: scale[{i}] moved {ds}");
            assert!(db.abs() < 2.0 * base.fit.std_err.bias[i], "threshold {th}: bias[{i}] moved {db}");
        }
    }
}

/// `fit --method gravity-norm --record` writes the equivalent model-4 record: the node's
/// calibration of that record (shared::linear, the f64 reference) gives the gravity-norm model's
/// acceleration at every hold to 1e-9 relative. The quadratic structure is refused, nothing
/// written.
#[test]
fn cli_writes_the_equivalent_model4_record() {
    use accelcal_core::gravity::fit::TriadModel;
    use accelcal_shared::record::Record;
    let dir = tempfile::tempdir().unwrap();
    let cfg = SessionConfig { seed: 12, holds: 20, ..SessionConfig::default() };
    let (data, _) = simulate(&cfg).write(dir.path(), "session").unwrap();
    let (json, rec) = (dir.path().join("cal.json"), dir.path().join("cal.rec"));
    let id = "51454d552d422d4c34373545";
    let (code, out, err) = accelcal(&[
        "fit",
        data.to_str().unwrap(),
        "--method",
        "gravity-norm",
        "--structure",
        "imu-tk",
        "--g",
        "9.81744",
        "--json",
        json.to_str().unwrap(),
        "--record",
        rec.to_str().unwrap(),
        "--device-id",
        id,
        "--created",
        "1800000000",
    ]);
    assert_eq!(code, Some(0), "{err}");
    assert!(
        out.contains("record: ") && out.contains("(156 bytes, model 4 from imu_tk (bias+scale+misalignment)"),
        "{out}"
    );
    let record = Record::parse(&std::fs::read(&rec).unwrap()).unwrap();
    assert_eq!(accelcal_shared::boot::gate(&record), Ok(()));
    assert_eq!(record.created_unix_s, 1_800_000_000);
    let cal = record.model4().unwrap().invert().unwrap();
    let j: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    // The JSON names its unit as `fit --method lsq`'s does (issue 24): device, g, the recording's
    // hash, the record's CRC (the one `record show` prints).
    let bytes = std::fs::read(&rec).unwrap();
    let crc = format!("{:08x}", accelcal_shared::record::crc32(&bytes[..bytes.len() - 4]));
    let sha = accelcal_db::sha256_hex(&std::fs::read(&data).unwrap());
    assert_eq!(
        (&j["device_id"], &j["serial"], &j["g_m_s2"], &j["campaign_sha256"], &j["record_crc"]),
        (
            &serde_json::json!(id),
            &serde_json::Value::Null,
            &serde_json::json!(9.81744),
            &serde_json::json!(sha),
            &serde_json::json!(crc)
        )
    );
    let f = |v: &serde_json::Value| v.as_f64().unwrap();
    let model = TriadModel {
        bias: std::array::from_fn(|i| f(&j["channels"][i]["bias"])),
        scale: std::array::from_fn(|i| f(&j["channels"][i]["scale"])),
        alpha: std::array::from_fn(|i| f(&j["alpha"][i])),
        quad: [0.0; 3],
    };
    let holds = j["per_hold"].as_array().unwrap();
    assert!(holds.len() >= 15, "{}", holds.len());
    let mut worst = 0.0f64;
    for h in holds {
        let u: [f64; 3] = std::array::from_fn(|i| f(&h["mean"][i]));
        let (want, got) = (model.apply(u), cal.apply(u));
        let norm = want.iter().map(|v| v * v).sum::<f64>().sqrt();
        for i in 0..3 {
            worst = worst.max((got[i] - want[i]).abs() / norm);
        }
    }
    assert!(worst < 1e-9, "worst relative difference {worst:e}");

    let quad = dir.path().join("quad.rec");
    let (code, out, err) = accelcal(&[
        "fit",
        data.to_str().unwrap(),
        "--method",
        "gravity-norm",
        "--structure",
        "quadratic",
        "--record",
        quad.to_str().unwrap(),
        "--device-id",
        id,
    ]);
    assert_eq!(code, Some(2), "{err}");
    assert!(out.is_empty(), "{out}");
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(
        err.contains(&format!(
            "{}: the imu_tk + per-axis quadratic structure is not model 4",
            quad.display()
        )),
        "{err}"
    );
    assert!(!quad.exists());
}

/// A recording made by hand, as issue 59 met them: 5 s of rest with z up, then for each of `dirs`
/// 2 s of movement and a hold of `hold_s` seconds, at 100 Hz with about 3 codes of noise, from the
/// default session's sensor.
fn by_hand(dirs: &[[f64; 3]], hold_s: f64) -> accelcal_core::gravity::imutk::Recording {
    let cfg = SessionConfig::default();
    let raw = |d: [f64; 3]| {
        let n = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        cfg.truth.raw_from_specific_force(d.map(|x| x / n * cfg.g)).unwrap()
    };
    let mut state = 0x2545_f491_4f6c_dd1d_u64;
    let mut noise = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64 * 10.0 - 5.0
    };
    let mut rec = accelcal_core::gravity::imutk::Recording::default();
    let push = |c: [f64; 3], rec: &mut accelcal_core::gravity::imutk::Recording| {
        rec.t.push(rec.t.len() as f64 * 0.01);
        rec.codes.push(c);
    };
    let mut at = raw([0.0, 0.0, 1.0]);
    for _ in 0..500 {
        push(at.map(|c| c + noise()), &mut rec);
    }
    for d in dirs {
        let to = raw(*d);
        for k in 0..200 {
            let f = k as f64 / 200.0;
            let bump = 800.0 * (std::f64::consts::PI * f).sin();
            push(std::array::from_fn(|i| at[i] + (to[i] - at[i]) * f + bump + noise()), &mut rec);
        }
        at = to;
        for _ in 0..(hold_s * 100.0) as usize {
            push(at.map(|c| c + noise()), &mut rec);
        }
    }
    rec
}

fn write_by_hand(dir: &Path, dirs: &[[f64; 3]], hold_s: f64) -> PathBuf {
    let path = dir.join("by-hand.txt");
    let rec = by_hand(dirs, hold_s);
    accelcal_core::gravity::imutk::write(&rec, std::fs::File::create(&path).unwrap()).unwrap();
    path
}

/// `accelcal fit FILE --method gravity-norm --g 9.81744` (the default session's g) with `more`.
fn gravity_fit(file: &Path, more: &[&str]) -> (Option<i32>, String, String) {
    let mut args = vec!["fit", file.to_str().unwrap(), "--method", "gravity-norm", "--g", "9.81744"];
    args.extend(more);
    accelcal(&args)
}

/// Twelve directions: the six faces and six diagonals.
const SPREAD: [[f64; 3]; 12] = [
    [1.0, 0.0, 0.0],
    [-1.0, 0.0, 0.0],
    [0.0, 1.0, 0.0],
    [0.0, -1.0, 0.0],
    [0.0, 0.0, -1.0],
    [0.0, 0.0, 1.0],
    [1.0, 1.0, 0.0],
    [-1.0, 0.0, 1.0],
    [0.0, -1.0, -1.0],
    [1.0, 0.0, -1.0],
    [0.0, 1.0, 1.0],
    [-1.0, -1.0, 0.0],
];

/// Issue 59: holds of a 2.7 s protocol are 1.7 s after the detector's window, under the 2 s
/// minimum: the refusal says what the detector kept and dropped, and names the `--min-hold-s`
/// that keeps them, which then calibrates.
#[test]
fn short_holds_are_named_with_the_option_that_keeps_them() {
    let dir = tempfile::tempdir().unwrap();
    let file = write_by_hand(dir.path(), &SPREAD, 2.7);
    let (code, _, err) = gravity_fit(&file, &[]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("the detector: 1 holds kept; 12 dropped: 12 too short ("), "{err}");
    let at = err.find("--min-hold-s ").expect("the option named") + "--min-hold-s ".len();
    let keep = err[at..].split_whitespace().next().unwrap().to_string();
    assert!(err.contains(&format!("--min-hold-s {keep} keeps them")), "{err}");
    let (code, out, err) = gravity_fit(&file, &["--min-hold-s", &keep]);
    assert_eq!(code, Some(0), "{err}");
    assert!(out.contains("holds: 13 kept, 0 rejected"), "{out}");
}

/// Issue 59: with too few holds to withhold half, `--structure auto` selects nothing; it fits the
/// simplest structure and says so (never the richest in silence).
#[test]
fn auto_with_too_few_holds_fits_the_simplest_and_says_so() {
    let dir = tempfile::tempdir().unwrap();
    let file = write_by_hand(dir.path(), &SPREAD[..9], 5.0);
    let json = dir.path().join("fit.json");
    let (code, out, err) = gravity_fit(&file, &["--structure", "auto", "--json", json.to_str().unwrap()]);
    assert_eq!(code, Some(0), "{err}");
    assert!(out.contains("holds: 10 kept"), "{out}");
    assert!(out.contains("--structure auto could not select"), "{out}");
    assert!(out.contains("fitted bias+scale, the simplest (6 parameters)"), "{out}");
    let j: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert_eq!(j["selected_structure"], serde_json::Value::Null);
    assert_eq!(j["structure_fallback"], true);
    assert_eq!(j["structure"], "bias+scale");
}

/// Issue 59: no hold with y near ±g (every hold tilts y by about 0.37 g): a warning names the
/// axis with its scale's standard error; the well-excited axes get none.
#[test]
fn a_weakly_excited_axis_is_named_with_its_standard_error() {
    let dir = tempfile::tempdir().unwrap();
    let dirs: Vec<[f64; 3]> = (0..12)
        .map(|k| {
            let a = k as f64 * std::f64::consts::PI / 6.0;
            [a.cos(), if k % 2 == 0 { 0.4 } else { -0.4 }, a.sin()]
        })
        .collect();
    let file = write_by_hand(dir.path(), &dirs, 5.0);
    let json = dir.path().join("fit.json");
    let (code, _, err) = gravity_fit(&file, &["--structure", "bias-scale", "--json", json.to_str().unwrap()]);
    assert_eq!(code, Some(0), "{err}");
    assert!(err.contains("warning: no hold has axis y within 30° of ±g (the largest |a_y| is 0.3"), "{err}");
    assert!(err.contains("codes/(m/s²) is weakly identified"), "{err}");
    assert!(!err.contains("axis x") && !err.contains("axis z"), "{err}");
    let j: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert_eq!(j["weak_axes"].as_array().unwrap().len(), 1, "{j}");
    assert_eq!(j["weak_axes"][0]["axis"], "y");
    assert!(j["weak_axes"][0]["scale_std_err"].as_f64().unwrap() > 0.0);
}
