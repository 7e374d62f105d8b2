//! CLI tests on the `accelcal` binary: every command end to end on simulated files, the JSON
//! shapes the issues specify, bad input turned into exit code 2 with one line naming the file,
//! options that do not apply to their mode refused before any I/O, every command's help, and
//! snapshots of what users read (a certificate, a diagnosis JSON; `insta` snapshots under
//! `tests/snapshots/`). The examples of the README and the guide: `tests/docs.rs`.

use crate::common;

#[path = "cli/assets.rs"]
mod assets;
#[path = "cli/conformity.rs"]
mod conformity;
#[path = "cli/dcc.rs"]
mod dcc;
#[path = "cli/design.rs"]
mod design;
#[path = "cli/fleet_bench.rs"]
mod fleet_bench;
#[path = "cli/help.rs"]
mod help;
#[path = "cli/output.rs"]
mod output;
#[path = "cli/records.rs"]
mod records;
#[path = "cli/settings.rs"]
mod settings;
#[path = "cli/signature.rs"]
mod signature;
#[path = "cli/station_config.rs"]
mod station_config;
#[path = "cli/uncertainty.rs"]
mod uncertainty;
use std::path::{Path, PathBuf};
use std::process::Command;

use accelcal_shared::record::Record;
use common::{accelcal, bad, ok};
use serde_json::Value;

fn json(p: &Path) -> Value {
    serde_json::from_str(&std::fs::read_to_string(p).unwrap()).unwrap()
}

struct Dir(tempfile::TempDir);

impl Dir {
    fn new() -> Dir {
        Dir(tempfile::tempdir().unwrap())
    }
    fn p(&self, name: &str) -> PathBuf {
        self.0.path().join(name)
    }
    fn s(&self, name: &str) -> String {
        self.p(name).to_str().unwrap().to_string()
    }
}

fn simulate(d: &Dir, name: &str, extra: &[&str]) -> String {
    let mut args = vec!["simulate", "--out"];
    let out = d.s(name);
    args.push(&out);
    args.extend_from_slice(extra);
    ok(&args);
    out
}

#[test]
fn simulate_is_seeded_and_writes_truth() {
    let d = Dir::new();
    let a = simulate(&d, "a.csv", &["--seed", "5", "--samples", "3", "--json", &d.s("sum.json")]);
    let b = simulate(&d, "b.csv", &["--seed", "5", "--samples", "3"]);
    assert_eq!(std::fs::read(&a).unwrap(), std::fs::read(&b).unwrap());
    let truth = json(&d.p("a.truth.json"));
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        let mode = std::fs::metadata(&a).unwrap().permissions().mode() & 0o777;
        assert_eq!(mode, 0o644, "outputs are ordinary files");
    }
    assert_eq!(truth["channels"].as_array().unwrap().len(), 3);
    assert_eq!(json(&d.p("sum.json"))["positions"], 62);
    let head = std::fs::read_to_string(&a).unwrap();
    assert!(head.starts_with("# g_m_s2: 9.81\n# g_source: given\nt_s,alpha_deg,beta_deg,x,y,z\n"), "{head}");
    let block = simulate(&d, "blk.csv", &["--layout", "block:5", "--plan", "six", "--samples", "2"]);
    assert!(std::fs::read_to_string(block)
        .unwrap()
        .starts_with("# g_m_s2: 9.81\n# g_source: given\nt_s,alpha_deg,beta_deg,a1,a2,a3,a4,a5\n"));
}

#[test]
fn select_reports_table_1_and_json() {
    let d = Dir::new();
    let c = simulate(&d, "c.csv", &["--seed", "3"]);
    let out = ok(&["select", &c, "--json", &d.s("sel.json"), "--plot", &d.s("plots")]);
    assert!(out.contains("<- selected") && out.contains("unidentif."), "{out}");
    let j = json(&d.p("sel.json"));
    let chans = j["channels"].as_array().unwrap();
    assert_eq!(chans.len(), 3);
    for ch in chans {
        assert_eq!(ch["selected"]["terms"], serde_json::json!(["1", "ax", "ay", "az"]));
        assert_eq!(ch["selected"]["coefficients"].as_array().unwrap().len(), 4);
        assert!(ch["selected"]["criterion"].as_f64().unwrap() > 0.0);
        let cands = ch["candidates"].as_array().unwrap();
        assert_eq!(cands.len(), 11);
        assert_eq!(cands[10]["identifiable"], false);
        assert!(cands[10]["criterion"].is_null());
        assert_eq!(cands[3]["identifiable"], true);
    }
    assert!(std::fs::read_to_string(d.p("plots/criterion-x.svg")).unwrap().contains("<svg"));
    // The other criteria and splits run; a bad split is bad input.
    ok(&[
        "select",
        &c,
        "--criterion",
        "symmetric",
        "--split",
        "halves",
        "--basis",
        "quadratic",
        "--channels",
        "y",
    ]);
    ok(&["select", &c, "--criterion", "rss", "--split", "tail:0.25", "--tolerance", "0"]);
    let e = bad(&["select", &c, "--channels", "w"]);
    assert!(e.contains("no channel `w`"), "{e}");
}

/// Issue 22, item 2: on the six test-turn positions the alternate split leaves 3 positions to fit
/// on, too few for model 4, so the regularity criterion can only rank models without one of the
/// axes. `select` refuses that (nothing written) and points to the leave-one-out criterion, which
/// picks model 4 on every channel.
#[test]
fn select_on_six_positions_refuses_the_split_and_leave_one_out_picks_model_4() {
    let d = Dir::new();
    let c =
        simulate(&d, "six.csv", &["--plan", "six", "--samples", "100", "--seed", "5", "--codes", "signed16"]);
    let j = d.s("sel.json");
    let e = bad(&["select", &c, "--json", &j, "--plot", &d.s("plots")]);
    assert!(
        e.contains(&format!(
            "{c}: channel x: --split alternate leaves part A 3 of the 6 positions, too few to identify \
             1,ax,ay,az (4 terms: at least 4 positions in A, a campaign of at least 7 with this split)"
        )) && e.contains("--criterion loo"),
        "{e}"
    );
    assert!(!d.p("sel.json").exists() && !d.p("plots").exists());
    let out = ok(&["select", &c, "--criterion", "loo", "--json", &j]);
    assert!(out.contains("leave-one-out criterion"), "{out}");
    let sel = json(&d.p("sel.json"));
    assert_eq!(sel["criterion"], "loo");
    assert!(sel["split"].is_null(), "{sel}");
    for ch in sel["channels"].as_array().unwrap() {
        assert_eq!(ch["selected"]["terms"], serde_json::json!(["1", "ax", "ay", "az"]), "{ch}");
        // Model 4 on six positions: three times the dwell-mean residual, a few codes, not thousands.
        assert!(ch["selected"]["criterion"].as_f64().unwrap() < 50.0, "{ch}");
    }
    // The exhaustive bases work with it too.
    let out = ok(&["select", &c, "--criterion", "loo", "--basis", "cubic", "--channels", "z"]);
    assert!(out.contains("1,ax,ay,az ") && out.contains("<- selected"), "{out}");
}

#[test]
fn fit_lsq_and_test_turns_write_json_and_record() {
    let d = Dir::new();
    let c = simulate(&d, "c.csv", &["--seed", "4", "--noise", "0", "--ideal-adc", "--samples", "2"]);
    let truth = json(&d.p("c.truth.json"));
    ok(&[
        "fit",
        &c,
        "--json",
        &d.s("lsq.json"),
        "--record",
        &d.s("cal.rec"),
        "--device-id",
        "0102030405060708090a0b0c",
        "--created",
        "1800000000",
    ]);
    let j = json(&d.p("lsq.json"));
    let rec = Record::parse(&std::fs::read(d.p("cal.rec")).unwrap()).unwrap();
    assert_eq!(rec.device_id, [1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12]);
    assert_eq!(rec.created_unix_s, 1_800_000_000);
    for (i, ch) in j["channels"].as_array().unwrap().iter().enumerate() {
        assert_eq!(ch["terms"], serde_json::json!(["1", "ax", "ay", "az"]));
        let coef: Vec<f64> =
            ch["coefficients"].as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect();
        assert_eq!(ch["std_errors"].as_array().unwrap().len(), 4);
        assert_eq!(&rec.coefficients[i][..4], &coef[..]);
        let t = &truth["channels"][i];
        assert!((coef[0] - t["bias"].as_f64().unwrap()).abs() < 1e-6);
        assert!((coef[2] - t["k"][1].as_f64().unwrap()).abs() < 1e-8);
    }
    ok(&["fit", &c, "--method", "test-turns", "--json", &d.s("tt.json")]);
    let j = json(&d.p("tt.json"));
    let coef = j["channels"][2]["coefficients"].as_array().unwrap();
    assert!((coef[3].as_f64().unwrap() - truth["channels"][2]["k"][2].as_f64().unwrap()).abs() < 1e-8);
    // Other structures by LSQ; test turns refuse them.
    let out = ok(&["fit", &c, "--terms", "ax,ay,az,ax*ay"]);
    assert!(out.contains("ax*ay"));
    let e = bad(&["fit", &c, "--method", "test-turns", "--terms", "ax,ay,az,ax^2"]);
    assert!(e.contains("test turns determine model 4"), "{e}");
    let e = bad(&["fit", &c, "--terms", "ax,ay,az,ax^2,ay^2,az^2"]);
    assert!(e.contains("not identifiable") && e.contains("ax^2, ay^2, az^2"), "{e}");
    let e = bad(&["fit", &c, "--terms", "ax,bx"]);
    assert!(e.contains("unknown variable"), "{e}");
    let e = bad(&["fit", &c, "--device-id", "12", "--record", &d.s("r.rec")]);
    assert!(e.contains("24 hex digits"), "{e}");
    assert!(!d.p("r.rec").exists());
    let e = bad(&["fit", &c, "--device-id", "000000000000000000000001"]);
    assert!(e.contains("--device-id does not apply to fit without --record"), "{e}");
}

/// `--latitude`/`--height` set g to the normal gravity there, as every command with `--g` uses it.
#[test]
fn latitude_and_height_give_local_gravity() {
    let g = |args: &[&str]| -> f64 {
        let out = ok(&[&["plan", "--plan", "six"], args].concat());
        let at = out.find("g = ").unwrap() + 4;
        out[at..].split(' ').next().unwrap().parse().unwrap()
    };
    assert_eq!(g(&[]), 9.81);
    assert_eq!(g(&["--latitude", "45"]), accelcal_shared::normal_gravity(45.0, 0.0));
    assert!((g(&["--latitude", "45"]) - 9.80620).abs() < 5e-6);
    assert!(
        (g(&["--latitude", "45"]) - g(&["--latitude", "45", "--height", "1000"]) - 3.086e-3).abs() < 1e-12
    );
    assert_eq!(g(&["--latitude", "-45"]), g(&["--latitude", "45"]));
    // The campaign commands use it too: a fit with the local g differs from one with 9.81, and
    // the campaign simulated there states it, so a fit without --g uses it.
    let d = Dir::new();
    let c = simulate(&d, "c.csv", &["--seed", "4", "--samples", "2", "--latitude", "0"]);
    // (The coefficients, not the budget: the uncertainty of g follows where it came from.)
    let fit = |extra: &[&str]| {
        let out = ok(&[&["fit", c.as_str()], extra].concat());
        out.split("expanded uncertainty").next().unwrap().to_string()
    };
    let a = fit(&["--latitude", "0"]);
    let b = fit(&["--g", &accelcal_shared::normal_gravity(0.0, 0.0).to_string()]);
    assert_eq!(a, b);
    assert_ne!(a, fit(&["--g", "9.81"]));
    assert_eq!(a, fit(&[]));
}

/// Issue 24: `acquire`'s check that the head moved as the plan says
/// (`accelcal_line::acquire::MotionCheck`) accepts every position, in acquisition order, of the
/// real Xsens recording's holds (their angles from the calibrated gravity direction) and of
/// simulated campaigns with each effect, and refuses the unturned head's second position.
#[test]
fn the_motion_check_accepts_real_and_simulated_positions() {
    use accelcal_core::campaign::Campaign;
    use accelcal_line::acquire::MotionCheck;
    let check = |path: &Path, g: f64| -> Result<usize, String> {
        let c = Campaign::read(path).unwrap();
        let mut m = MotionCheck::new(g);
        for (k, d) in c.dwells().iter().enumerate() {
            let mean = [0, 1, 2].map(|ch| {
                c.channels[ch].codes[d.start..d.end].iter().sum::<f64>() / (d.end - d.start) as f64
            });
            m.check(d.accel(g), mean).map_err(|e| format!("{}: position {}: {e}", path.display(), k + 1))?;
            m.accept(d.accel(g), mean, k + 1);
        }
        Ok(c.dwells().len())
    };
    let d = Dir::new();
    let real = concat!(env!("CARGO_MANIFEST_DIR"), "/../tests/data/real/imu_tk_xsens_acc.txt.gz");
    ok(&["fit", real, "--method", "gravity-norm", "--g", "9.81744", "--campaign-out", &d.s("real.csv")]);
    assert_eq!(check(&d.p("real.csv"), 9.81744), Ok(38));
    let effects = [
        "bias_drift=rate:2",
        "nonlinearity=k2:50",
        "head_misalignment=rx_mrad:20,ry_mrad:-20",
        "hysteresis=h:50",
        "settling=gain:30,tau:0.4",
    ];
    for (seed, effect) in effects.iter().enumerate() {
        let name = format!("s{seed}.csv");
        let seed = seed.to_string();
        simulate(&d, &name, &["--seed", &seed, "--samples", "20", "--effect", effect]);
        assert_eq!(check(&d.p(&name), 9.81), Ok(62), "{effect}");
    }
    unturned(&d.p("u.csv"));
    let e = check(&d.p("u.csv"), 9.81).unwrap_err();
    assert!(e.contains("position 2: its mean codes moved"), "{e}");
}

#[test]
fn compare_gives_table_2_with_and_without_validation_campaign() {
    let d = Dir::new();
    let c = simulate(&d, "c.csv", &["--seed", "6"]);
    let v = simulate(&d, "v.csv", &["--seed", "6", "--plan", "random:30"]);
    let out = ok(&["compare", &c, "--json", &d.s("cmp.json"), "--plot", &d.s("plots")]);
    assert!(out.contains("mean LSQ"), "{out}");
    let j = json(&d.p("cmp.json"));
    assert_eq!(j["validation_positions"], 28);
    for ch in j["channels"].as_array().unwrap() {
        for m in ["lsq", "test_turns"] {
            let s = ch[m]["std_error"].as_f64().unwrap();
            // Noise 80 codes per sample at ~1670 codes per m/s² is ~0.048 m/s².
            assert!((0.035..0.065).contains(&s), "{m}: {s}");
            assert!(ch[m]["mean_error"].as_f64().unwrap().abs() < 0.01);
        }
    }
    assert!(d.p("plots/errors-lsq.svg").exists() && d.p("plots/errors-test-turns.svg").exists());
    ok(&["compare", &c, "--validate", &v, "--json", &d.s("cmp2.json")]);
    assert_eq!(json(&d.p("cmp2.json"))["validation_positions"], 30);
    // No test-turn positions in a random plan.
    let e = bad(&["compare", &v]);
    assert!(e.contains("test turns need"), "{e}");
}

#[test]
fn demo_writes_everything() {
    let d = Dir::new();
    let out = ok(&["demo", "--out", &d.s("demo")]);
    assert!(out.contains("Table 1") && out.contains("Table 2"));
    for f in [
        "campaign.csv",
        "truth.json",
        "select.json",
        "fit-lsq.json",
        "fit-test-turns.json",
        "compare.json",
        "calibration.rec",
        "criterion-x.svg",
        "errors-lsq.svg",
        "errors-test-turns.svg",
    ] {
        assert!(d.p("demo").join(f).exists(), "{f} missing");
    }
    let rec = Record::parse(&std::fs::read(d.p("demo/calibration.rec")).unwrap()).unwrap();
    assert!(rec.model4().is_some());
    let sel = json(&d.p("demo/select.json"));
    for ch in sel["channels"].as_array().unwrap() {
        assert_eq!(ch["selected"]["terms"], serde_json::json!(["1", "ax", "ay", "az"]));
    }
}

#[test]
fn bad_campaigns_exit_2_name_the_place_and_leave_no_output() {
    let d = Dir::new();
    // The bytes of each file, and what must follow its name on the error line.
    let cases: &[(&[u8], &str)] = &[
        (
            b"t_s,alpha_deg,beta_deg,x\n0,0,0,1\n1,0,zero,2\n",
            ":3:3: expected a number in `beta_deg`, found `zero`",
        ),
        (b"", ": empty file: expected a header row"),
        (b"t_s,alpha_deg,beta_deg,x\n", ": header only: no data rows"),
        (b"t_s,alpha_deg,x\n0,0,1\n", ": missing required column `beta_deg`"),
        (b"t_s,alpha_deg,beta_deg,x,x\n0,0,0,1,1\n", ":1:5: duplicate column `x`"),
        (b"t_s,alpha_deg,beta_deg,x\n0,0,0,1,5\n", ":2:5: expected 4 fields, found 5"),
        (b"t_s,alpha_deg,beta_deg,x\n1,0,0,1\n0.5,0,0,1\n", ":3:1: t_s must not decrease"),
        (b"t_s,alpha_deg,beta_deg,x\n0,inf,0,1\n", ":2:2: `alpha_deg` must be finite"),
        (b"\x00\x01\x02\xffbinary", ":1: not UTF-8 text (is this a binary file?)"),
    ];
    for (i, (text, want)) in cases.iter().enumerate() {
        let f = d.p(&format!("bad{i}.csv"));
        std::fs::write(&f, text).unwrap();
        let j = d.p(&format!("out{i}.json"));
        for cmd in ["select", "fit", "compare"] {
            let e = bad(&[cmd, f.to_str().unwrap(), "--json", j.to_str().unwrap()]);
            assert!(!want.is_empty() && e.contains(&format!("{}{want}", f.display())), "case {i} {cmd}: {e}");
            assert!(!j.exists(), "case {i}: partial output left behind");
        }
    }
    let e = bad(&["fit", d.s("missing.csv").as_str()]);
    assert!(e.contains("missing.csv") && e.contains("No such file"), "{e}");
    // Bad options are bad input too (clap adds a hint line after the error line).
    let out = accelcal(&["select", "x.csv", "--split", "tail:2"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr)
        .lines()
        .next()
        .unwrap()
        .contains("tail fraction must be a number in (0, 1)"));
    let e = bad(&["simulate", "--out", &d.s("x.csv"), "--effect", "wobble=a:1"]);
    assert!(e.contains("unknown effect"), "{e}");
    assert!(!d.p("x.csv").exists());
}

#[test]
fn real_recording_becomes_a_campaign_that_diagnose_reads() {
    let real = concat!(env!("CARGO_MANIFEST_DIR"), "/../tests/data/real/imu_tk_xsens_acc.txt.gz");
    let d = Dir::new();
    let camp = d.s("real.csv");
    let g = 9.81744;
    let fit = d.s("fit.json");
    let out = ok(&[
        "fit",
        real,
        "--method",
        "gravity-norm",
        "--g",
        "9.81744",
        "--campaign-out",
        &camp,
        "--json",
        &fit,
    ]);
    assert!(out.contains("38 holds as position dwells"), "{out}");
    let c = accelcal_core::campaign::Campaign::read(Path::new(&camp)).unwrap();
    let dwells = c.dwells();
    assert_eq!(dwells.len(), 38);
    // The calibration the fit wrote: a = T·((u − b)/s) (imu_tk model, no quadratic term).
    let j = json(Path::new(&fit));
    assert_eq!(j["structure"], "imu_tk (bias+scale+misalignment)");
    let num = |v: &Value| v.as_f64().unwrap();
    let ch = |i: usize, k: &str| num(&j["channels"][i][k]);
    let t: Vec<Vec<f64>> = j["misalignment"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| r.as_array().unwrap().iter().map(num).collect())
        .collect();
    // Every hold's angles reproduce its calibrated direction: on the first and the last hold,
    // |a| = g within 0.005 m/s² (2 codes; the fit's residual RMS is 0.001) and a points where the
    // hold's head angles say through the kinematics (to rounding: the angles are written in full).
    for (k, w) in [(0, &dwells[0]), (37, &dwells[37])] {
        let n = (w.end - w.start) as f64;
        let mean: Vec<f64> =
            (0..3).map(|i| c.channels[i].codes[w.start..w.end].iter().sum::<f64>() / n).collect();
        let v: Vec<f64> = (0..3).map(|i| (mean[i] - ch(i, "bias")) / ch(i, "scale")).collect();
        let a: Vec<f64> = (0..3).map(|r| (0..3).map(|i| t[r][i] * v[i]).sum()).collect();
        let norm = a.iter().map(|x| x * x).sum::<f64>().sqrt();
        assert!((norm - g).abs() < 0.005, "hold {k}: |a| = {norm} m/s², g = {g}");
        let want = accelcal_shared::gravity(w.alpha_deg, w.beta_deg, g);
        let cos = (0..3).map(|i| a[i] * want[i]).sum::<f64>() / (norm * g);
        assert!(cos > 1.0 - 1e-12, "hold {k}: a = {a:?} but the angles say {want:?}");
        if k == 0 {
            assert!(want[2] > 9.7, "the initial rest has z along +g: {want:?}");
        }
    }
    ok(&["diagnose", &camp, "--g", "9.81744", "--json", &d.s("diag.json")]);
    let j = json(&d.p("diag.json"));
    assert!(j["effects"].is_array());
    // The real data are not the simulation: a gap no library effect explains is reported as such.
    assert!(j["unexplained_rms"].as_f64().unwrap() > 0.1, "{j}");
}

#[test]
fn a_closed_pipe_ends_the_output_quietly() {
    let d = Dir::new();
    let c = simulate(&d, "c.csv", &["--samples", "2"]);
    let mut child = Command::new(env!("CARGO_BIN_EXE_accelcal"))
        .args(["select", &c, "--basis", "quadratic"])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    // Close the reading end before the tables are printed (like `| head` that has had enough).
    drop(child.stdout.take());
    let out = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!err.contains("panicked"), "{err}");
}

// ---------------------------------------------------------------------------------------------
// Snapshots of what users read (the demo's and a diagnosis's output: `tests/docs.rs`).

/// The text of an HTML page as a reader sees it, one table row or paragraph a line, cells
/// separated by ` | `; plots and style left out.
fn page_text(html: &str) -> String {
    let mut s = html.to_string();
    for (open, close) in
        [("<title>", "</title>"), ("<style>", "</style>"), ("<svg", "</svg>"), ("<script", "</script>")]
    {
        while let Some(a) = s.find(open) {
            let b = s[a..].find(close).map_or(s.len(), |b| a + b + close.len());
            s.replace_range(a..b, "");
        }
    }
    for (tag, with) in [
        ("</tr>", "\n"),
        ("</p>", "\n"),
        ("</h1>", "\n"),
        ("</div>", "\n"),
        ("</h2>", "\n"),
        ("</td>", " | "),
        ("</th>", " | "),
    ] {
        s = s.replace(tag, with);
    }
    let mut out = String::new();
    let mut in_tag = false;
    for c in s.chars() {
        match c {
            '<' => in_tag = true,
            '>' => in_tag = false,
            _ if !in_tag => out.push(c),
            _ => {}
        }
    }
    let out =
        out.replace("&mdash;", "—").replace("&plusmn;", "±").replace("&alpha;", "α").replace("&beta;", "β");
    let out = out
        .replace("&#39;", "'")
        .replace("&#60;", "<")
        .replace("&#62;", ">")
        .replace("&#34;", "\"")
        .replace("&#38;", "&")
        .replace("&amp;", "&")
        .replace("&lt;", "<")
        .replace("&gt;", ">")
        .replace("&quot;", "\"");
    // One line per row or paragraph, without the template's blank lines.
    out.lines().map(str::trim).filter(|l| !l.is_empty()).collect::<Vec<_>>().join("\n") + "\n"
}

/// Issue 24.4: the certificate of a simulated unit, verified (a verification document of the
/// record, as `verify --json` writes it): one g with its bound, per-axis tolerances, the
/// temperature of the verification. Issue 57: the same document as a PDF (every value read back
/// by `pdftotext`, the document attached), and GMDH next to the record's terms and Table 2 in the
/// technical report, not on the certificate.
#[test]
fn the_certificate_is_the_snapshot() {
    let d = Dir::new();
    let c = simulate(&d, "u42.csv", &["--seed", "42", "--samples", "20", "--serial", "U-42"]);
    let (rec, fit, cert) = (d.s("u42.rec"), d.s("u42-fit.json"), d.s("u42.html"));
    let (pdf, technical) = (d.s("u42.pdf"), d.s("u42-technical.html"));
    // Fit by `method`, verify (a document of the record) and certify: the report's stdout and the
    // page's text.
    let certify = |method: &str| {
        let id = "51454d552d422d4c34373545";
        ok(&[
            "fit",
            &c,
            "--method",
            method,
            "--record",
            &rec,
            "--device-id",
            id,
            "--created",
            "1800000000",
            "--json",
            &fit,
        ]);
        let crc = json(&d.p("u42-fit.json"))["record_crc"].as_str().unwrap().to_string();
        let verification = d.s("u42-verify.json");
        std::fs::write(&verification, verification_json(&crc, 9.81).to_string()).unwrap();
        let out = ok(&[
            "report",
            "--campaign",
            &c,
            "--record",
            &rec,
            "--fit",
            &fit,
            "--verify",
            &verification,
            "-o",
            &cert,
            "--pdf",
            &pdf,
            "--technical",
            &technical,
            "--customer",
            "ACME <Sensors> & Co",
            "--customer-address",
            "2 Road, Town",
            "--received",
            "2026-12-01",
            "--place",
            "line 2",
        ]);
        assert!(out.contains(&format!("certificate of unit U-42 (device {id}, record CRC {crc})")), "{out}");
        page_text(&std::fs::read_to_string(&cert).unwrap())
    };
    let text = certify("lsq");
    let v = json(&d.p("u42-fit.json"));
    assert_eq!(
        (v["serial"].as_str(), v["device_id"].as_str()),
        (Some("U-42"), Some("51454d552d422d4c34373545"))
    );
    let dir = d.0.path().to_str().unwrap();
    let dates = text.lines().find(|l| l.starts_with("Dates")).unwrap().to_string();
    let issued = &dates[dates.find("issued ").unwrap()..];
    let text = text
        .replace(dir, "DIR")
        .replace(issued, "issued (date) | ")
        .replace(&format!("accelcal {}", env!("CARGO_PKG_VERSION")), "accelcal (version)");
    assert_eq!(text.matches(" m/s² (").count(), 1, "one g: {text}");
    assert!(
        text.contains("g (local gravity) | 9.8100 ± 0.0058 m/s² (U, k = 2): the value the operator stated"),
        "{text}"
    );
    assert!(
        text.contains(
            "at 25.0 °C (the unit's own sensor, not a traceable thermometer; 24.9 to 25.1 °C over the positions)"
        ),
        "{text}"
    );
    insta::assert_snapshot!("certificate_text", text);
    // Engineering material is not on the certificate.
    for gone in ["GMDH selects", "Table 2", "Coefficients in force"] {
        assert!(!text.contains(gone), "{gone} on the certificate: {text}");
    }
    let tech = page_text(&std::fs::read_to_string(&technical).unwrap());
    for want in ["GMDH selects", "Table 2", "Coefficients in force", "U-42"] {
        assert!(tech.contains(want), "{want} not in the technical report: {tech}");
    }

    // The PDF: A4 pages numbered, a draft marked on each, and every value of the HTML page's
    // results table read back by pdftotext.
    let pages = crate::line::print::certificate_pdf(
        Path::new(&pdf),
        "Calibration certificate draft, not numbered — accelerometer triad U-42",
        &[
            "Results: expanded uncertainty U",
            "Uncertainty budget",
            "ACME <Sensors> & Co, 2 Road, Town",
            "line 2",
        ],
    );
    assert!(pages.iter().all(|p| p.contains("DRAFT — awaiting approval")), "{pages:?}");
    let pdf_text: String = pages.concat();
    let results = text.lines().skip_while(|l| !l.starts_with("channel | bias K0")).skip(1).take(3);
    for line in results {
        for cell in line.split('|').map(str::trim).filter(|c| c.contains('±')) {
            assert!(pdf_text.contains(cell), "{cell} not in the PDF: {pdf_text}");
        }
    }
    let size = Command::new("pdfinfo").arg(&pdf).output().expect("pdfinfo (poppler-utils)");
    let info = String::from_utf8_lossy(&size.stdout);
    assert!(info.contains("595.28 x 841.89 pts (A4)"), "{info}");
    let fonts = Command::new("pdffonts").arg(&pdf).output().expect("pdffonts (poppler-utils)");
    let fonts = String::from_utf8_lossy(&fonts.stdout);
    assert!(
        fonts.lines().skip(2).all(|l| l.contains(" yes yes ")),
        "every font embedded and subset: {fonts}"
    );

    // A fit that a later accelcal wrote is refused, as every reader of the fit JSON refuses it
    // (issue 58: `report` read it without the version check).
    let mut later = json(&d.p("u42-fit.json"));
    later["version"] = serde_json::json!(99);
    std::fs::write(d.p("later-fit.json"), later.to_string()).unwrap();
    let e = bad(&[
        "report",
        "--campaign",
        &c,
        "--record",
        &rec,
        "--fit",
        &d.s("later-fit.json"),
        "-o",
        &d.s("later.html"),
    ]);
    assert!(e.contains("version 99, written by a newer accelcal"), "{e}");
    assert!(!d.p("later.html").exists());

    // A test-turn record: Table 2 names it the record's method, LSQ the other one.
    let _ = certify("test-turns");
    let tech = page_text(&std::fs::read_to_string(&technical).unwrap());
    assert!(tech.contains("test turns (the record's method) and LSQ"), "{tech}");
    assert!(tech.contains("standard error of the test turns fit"), "{tech}");
}

/// Numbers rounded to 9 significant digits: the snapshot then holds every digit a reader could
/// care about without depending on the last bit of the platform's libm.
fn rounded(v: &Value) -> Value {
    match v {
        Value::Number(n) if n.is_f64() => {
            let x = n.as_f64().unwrap();
            serde_json::json!(format!("{x:.8e}").parse::<f64>().unwrap())
        }
        Value::Array(a) => Value::Array(a.iter().map(rounded).collect()),
        Value::Object(o) => Value::Object(o.iter().map(|(k, v)| (k.clone(), rounded(v))).collect()),
        _ => v.clone(),
    }
}

#[test]
fn diagnosis_json_is_pinned_and_deterministic() {
    let d = Dir::new();
    let c = simulate(&d, "c.csv", &["--seed", "42", "--effect", "settling=gain:30,tau:0.4"]);
    ok(&["diagnose", &c, "--json", &d.s("a.json")]);
    ok(&["diagnose", &c, "--json", &d.s("b.json")]);
    let (a, b) = (std::fs::read(d.p("a.json")).unwrap(), std::fs::read(d.p("b.json")).unwrap());
    assert_eq!(a, b, "the diagnosis of one campaign is the same twice, to the bit");
    // No field depends on the run (paths, times): nothing to redact.
    let text = String::from_utf8(a).unwrap();
    assert!(!text.contains(d.0.path().to_str().unwrap()), "the JSON names the temporary directory");
    let j = json(&d.p("a.json"));
    assert_eq!(j["effects"][0]["name"], "settling");
    insta::assert_snapshot!("diagnose_settling_json", serde_json::to_string_pretty(&rounded(&j)).unwrap());
}

// ---------------------------------------------------------------------------------------------
// Settings checked before any I/O.

/// A campaign of the six positions at which the head was never turned: every dwell reads the
/// same codes, give or take two.
fn unturned(path: &Path) {
    let mut text = String::from("t_s,alpha_deg,beta_deg,x,y,z\n");
    for (p, (a, b)) in accelcal_core::sim::Plan::six().positions.into_iter().enumerate() {
        for i in 0..20 {
            let n = ((p * 20 + i) * 7 % 5) as i64 - 2;
            text += &format!(
                "{},{a},{b},{},{},{}\n",
                (p * 20 + i) as f64 * 0.01,
                32000 + n,
                33000 - n,
                34000 + n
            );
        }
    }
    std::fs::write(path, text).unwrap();
}

/// A passing six-position `verify --json` document of the QEMU node running the record with CRC
/// `crc`, at `g`, at about 25 °C.
fn verification_json(crc: &str, g: f64) -> Value {
    let positions: Vec<Value> = [(0, 0), (180, 0), (90, 0), (-90, 0), (0, 90), (0, -90)]
        .iter()
        .enumerate()
        .map(|(k, (a, b))| {
            let e = [0.001 * k as f64 - 0.002, -0.0015 + 0.0005 * k as f64, 0.0008];
            serde_json::json!({
                "position": k + 1, "alpha_deg": a, "beta_deg": b, "expected_m_s2": [0.0, 0.0, g],
                "measured_m_s2": [0.0, 0.0, g], "error_m_s2": e, "sd_mean_m_s2": [0.001, 0.001, 0.001],
                "tolerance_m_s2": [0.0095, 0.0104, 0.0101], "lost": 0, "temp_c": 24.9 + 0.05 * k as f64,
                "out_of_range": false, "pass": true
            })
        })
        .collect();
    serde_json::json!({
        "device_id": "51454d552d422d4c34373545",
        "record": {"slot": 0, "sequence": 1, "created_unix_s": 1800000000u64, "crc": crc},
        "g_m_s2": g, "chamber_c": null,
        "tolerance_rule": "|error| <= 4·sqrt(σ_cal² + σ_mean²) per component: σ_cal from the fit's covariance matrix at the position's acceleration, σ_mean the standard error of the measured mean",
        "static_rule": "static", "positions": positions, "pass": true, "interrupted": false
    })
}
