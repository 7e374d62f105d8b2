//! Campaigns as real users have them: signed 16-bit codes (a digital MEMS, stated by `--codes
//! signed16` or a `# codes: signed16` line) and gzipped files, through every command that reads
//! campaigns. A signed campaign is the unsigned one less 32768, so every result must be the same
//! but for the bias, shifted by exactly that; a gzipped campaign must give the same JSON as the
//! plain one.

use crate::common;

use std::io::Write;
use std::path::{Path, PathBuf};

use common::{accelcal, bad};
use serde_json::Value;

/// Runs a command that must succeed; returns its stderr (the readers' warnings).
fn ok(args: &[&str]) -> String {
    String::from_utf8_lossy(&common::succeed(args).stderr).into_owned()
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// The same simulated block (head plan, so that `compare` has positions besides the test-turn
/// ones and `diagnose` enough of them) written in unsigned and in signed codes, at a g other than
/// the 9.81 m/s² fallback (the campaigns state it in their `# g_m_s2:` line).
struct Pair {
    dir: tempfile::TempDir,
    unsigned: PathBuf,
    signed: PathBuf,
}

fn pair() -> Pair {
    let dir = tempfile::tempdir().unwrap();
    let (unsigned, signed) = (dir.path().join("u.csv"), dir.path().join("s.csv"));
    for (out, codes) in [(&unsigned, "unsigned16"), (&signed, "signed16")] {
        ok(&["simulate", "-o", s(out), "--samples", "12", "--seed", "31", "--codes", codes, "--g", "9.7803"]);
    }
    Pair { dir, unsigned, signed }
}

impl Pair {
    fn path(&self, name: &str) -> PathBuf {
        self.dir.path().join(name)
    }

    /// Runs `cmd` on `campaign` with `extra` arguments and returns its JSON.
    fn json(&self, cmd: &str, campaign: &Path, extra: &[&str]) -> Value {
        let j = self.path(&format!("{cmd}.json"));
        let mut args = vec![cmd, s(campaign), "--json", s(&j)];
        args.extend_from_slice(extra);
        ok(&args);
        serde_json::from_str(&std::fs::read_to_string(&j).unwrap()).unwrap()
    }
}

/// The rows of a campaign file: (text of the non-code fields, codes), comments left out.
fn rows(path: &Path) -> Vec<(String, Vec<f64>)> {
    std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .filter(|l| !l.starts_with('#'))
        .skip(1)
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            (f[..3].join(","), f[3..].iter().map(|v| v.parse().unwrap()).collect())
        })
        .collect()
}

/// The fields that differ between two runs or two files of the same results: `select`'s measured
/// run time, and the fit's hash of the campaign file it read.
const TIMINGS: [&str; 3] = ["search_seconds", "models_per_second", "campaign_sha256"];

/// Replaces the run-time and file-identity fields of a JSON document by null.
fn without_timings(v: &mut Value) {
    match v {
        Value::Object(m) => {
            for (k, x) in m.iter_mut() {
                if TIMINGS.contains(&k.as_str()) {
                    *x = Value::Null;
                } else {
                    without_timings(x);
                }
            }
        }
        Value::Array(a) => a.iter_mut().for_each(without_timings),
        _ => {}
    }
}

/// Shifts the intercept of every model (an object with `terms` starting with `1` and
/// `coefficients`) by `by` codes.
fn shift_intercepts(v: &mut Value, by: f64) {
    match v {
        Value::Object(m) => {
            let intercept = m.get("terms").and_then(|t| t.get(0)).is_some_and(|t| t == "1");
            if let (true, Some(Value::Array(c))) = (intercept, m.get_mut("coefficients")) {
                c[0] = serde_json::json!(c[0].as_f64().unwrap() + by);
            }
            m.values_mut().for_each(|x| shift_intercepts(x, by));
        }
        Value::Array(a) => a.iter_mut().for_each(|x| shift_intercepts(x, by)),
        _ => {}
    }
}

/// Asserts that two JSON documents are equal, numbers to 1e-9 relative (the codes differ by
/// 32768, so sums of them round differently in the last bits).
fn assert_close(a: &Value, b: &Value, at: &str) {
    match (a, b) {
        (Value::Number(x), Value::Number(y)) => {
            let (x, y) = (x.as_f64().unwrap(), y.as_f64().unwrap());
            // The diagnosis's period is the maximum of a periodogram, refined by a search: where
            // the peak is flat (no significant period), a last-bit change of the residuals moves
            // its location by about the square root of that change, so its fields agree to 1e-6.
            let rel = if at.contains(".period.") { 1e-6 } else { 1e-9 };
            assert!((x - y).abs() <= rel * x.abs().max(y.abs()).max(1.0), "{at}: {x} != {y}");
        }
        (Value::Object(x), Value::Object(y)) => {
            assert_eq!(x.keys().collect::<Vec<_>>(), y.keys().collect::<Vec<_>>(), "{at}");
            for (k, v) in x {
                assert_close(v, &y[k], &format!("{at}.{k}"));
            }
        }
        (Value::Array(x), Value::Array(y)) => {
            assert_eq!(x.len(), y.len(), "{at}");
            for (i, (v, w)) in x.iter().zip(y).enumerate() {
                assert_close(v, w, &format!("{at}[{i}]"));
            }
        }
        _ => assert_eq!(a, b, "{at}"),
    }
}

#[test]
fn simulate_writes_signed_codes_as_the_unsigned_ones_less_32768() {
    let p = pair();
    let text = std::fs::read_to_string(&p.signed).unwrap();
    assert!(
        text.starts_with(
            "# g_m_s2: 9.7803\n# g_source: given\n# codes: signed16\nt_s,alpha_deg,beta_deg,x,y,z\n"
        ),
        "{}",
        &text[..80]
    );
    let (u, sg) = (rows(&p.unsigned), rows(&p.signed));
    assert_eq!(u.len(), 62 * 12);
    assert_eq!(u.len(), sg.len());
    let mut negative = 0;
    for ((ku, cu), (ks, cs)) in u.iter().zip(&sg) {
        assert_eq!(ku, ks);
        for (a, b) in cu.iter().zip(cs) {
            assert_eq!(*b, a - 32768.0);
            negative += usize::from(*b < 0.0);
        }
    }
    // The campaign is really signed: about half its codes are below zero.
    assert!(negative > u.len(), "{negative} negative codes");
}

/// The case: signed codes, given by the comment line or by `--codes signed16`, work in
/// `select`, `fit`, `compare` and `diagnose`, and give the unsigned campaign's results with the
/// bias shifted by exactly 32768 codes.
#[test]
fn signed_campaigns_give_the_unsigned_results_with_the_bias_shifted_by_32768() {
    let p = pair();
    // The same signed campaign without its comment line: the range comes from --codes.
    let bare = p.path("bare.csv");
    let text = std::fs::read_to_string(&p.signed).unwrap();
    std::fs::write(&bare, text.replacen("# codes: signed16\n", "", 1)).unwrap();
    let signed16 = ["--codes", "signed16"];
    for cmd in ["select", "fit", "compare", "diagnose"] {
        let mut want = p.json(cmd, &p.unsigned, &[]);
        without_timings(&mut want);
        shift_intercepts(&mut want, -32768.0);
        for (campaign, extra) in [(&p.signed, &[][..]), (&p.signed, &signed16[..]), (&bare, &signed16[..])] {
            let mut got = p.json(cmd, campaign, extra);
            without_timings(&mut got);
            assert_close(&got, &want, &format!("{cmd} {} {extra:?}", campaign.display()));
        }
        // Without the range, the bare file's negative codes are outside unsigned16.
        let e = bad(&[cmd, s(&bare)]);
        assert!(e.contains("outside the unsigned16 range"), "{e}");
    }
    // The fit's bias really moved (shift_intercepts found the models).
    let (u, sg) = (p.json("fit", &p.unsigned, &[]), p.json("fit", &p.signed, &[]));
    for (cu, cs) in u["channels"].as_array().unwrap().iter().zip(sg["channels"].as_array().unwrap()) {
        let (bu, bs) = (cu["coefficients"][0].as_f64().unwrap(), cs["coefficients"][0].as_f64().unwrap());
        assert!((bu - bs - 32768.0).abs() < 1e-6, "{bu} {bs}");
        assert_eq!(cu["terms"], cs["terms"]);
    }
}

#[test]
fn a_codes_flag_that_contradicts_the_comment_line_is_refused_naming_both() {
    let p = pair();
    let f = s(&p.signed);
    let (rec, out) = (p.path("r.rec"), p.path("o.csv"));
    std::fs::write(&rec, b"not read").unwrap();
    // Line 3: `simulate` writes its `# g_m_s2:` and `# g_source:` lines first.
    let want = format!("{f}:3: `# codes: signed16` contradicts --codes unsigned16");
    for args in [
        vec!["select", f, "--codes", "unsigned16"],
        vec!["fit", f, "--codes", "unsigned16"],
        vec!["compare", f, "--codes", "unsigned16"],
        vec!["compare", s(&p.unsigned), "--validate", f, "--codes", "unsigned16"],
        vec!["diagnose", f, "--codes", "unsigned16"],
    ] {
        let e = bad(&args);
        assert!(e.contains(&want), "{args:?}: {e}");
    }
    // A validation campaign in the other range is refused: the fits do not apply to its codes.
    let e = bad(&["compare", f, "--validate", s(&p.unsigned)]);
    assert!(e.contains("the validation campaign's codes are unsigned16, the campaign's signed16"), "{e}");
    // The unsigned file has no comment line: --codes signed16 is its range, and its codes near
    // 65535 are outside it.
    let e = bad(&["fit", s(&p.unsigned), "--codes", "signed16"]);
    assert!(e.contains("outside the signed16 range"), "{e}");
    // gravity-norm reads a recording, not a campaign.
    let e = bad(&["fit", s(&p.signed), "--method", "gravity-norm", "--codes", "signed16"]);
    assert!(e.contains("--codes does not apply to fit --method gravity-norm"), "{e}");
    // clap refuses an unknown range (with its usage note, on more than one line).
    let run = accelcal(&["fit", s(&p.signed), "--codes", "signed8"]);
    let e = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(2), "{e}");
    assert!(e.contains("unknown code range `signed8` (expected unsigned16 or signed16)"), "{e}");
    assert!(!out.exists());
}

#[test]
fn saturated_signed_codes_are_excluded_with_a_warning() {
    let p = pair();
    let text = std::fs::read_to_string(&p.signed).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    // Rows 3 and 40 (file lines 5 and 42) saturate channel y low and high.
    let (sat, kept) = (p.path("sat.csv"), p.path("kept.csv"));
    let mut with = String::new();
    let mut without = String::new();
    for (i, l) in lines.iter().enumerate() {
        let mut f: Vec<String> = l.split(',').map(String::from).collect();
        match i + 1 {
            5 => f[4] = "-32768".into(),
            42 => f[4] = "32767".into(),
            _ => without += &format!("{l}\n"),
        }
        with += &format!("{}\n", f.join(","));
    }
    std::fs::write(&sat, with).unwrap();
    std::fs::write(&kept, without).unwrap();
    let warning = format!(
        "warning: {}:5:5: excluded 2 of 744 samples where channel `y` is saturated (-32768 or 32767) or outside the signed16 range (first at this line)",
        s(&sat)
    );
    for cmd in ["fit", "compare", "diagnose"] {
        let j = p.path("sat.json");
        let err = ok(&[cmd, s(&sat), "--json", s(&j)]);
        assert_eq!(err.lines().collect::<Vec<_>>(), vec![warning.as_str()], "{cmd}");
        // The fit's `campaign_sha256` names the file it read (the two files differ by the two
        // rows): everything else is the same.
        let results = |j: &Path| {
            let mut v: serde_json::Value = serde_json::from_slice(&std::fs::read(j).unwrap()).unwrap();
            v.as_object_mut().unwrap().remove("campaign_sha256");
            v
        };
        let excluded = results(&j);
        ok(&[cmd, s(&kept), "--json", s(&j)]);
        assert_eq!(excluded, results(&j), "{cmd}: excluded rows must count as absent");
    }
}

fn gzip(from: &Path, to: &Path) {
    let mut enc = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
    enc.write_all(&std::fs::read(from).unwrap()).unwrap();
    std::fs::write(to, enc.finish().unwrap()).unwrap();
}

#[test]
fn gzipped_campaigns_give_the_json_of_the_plain_ones() {
    let p = pair();
    for plain in [&p.unsigned, &p.signed] {
        let gz = plain.with_extension("csv.gz");
        gzip(plain, &gz);
        for cmd in ["fit", "select", "compare", "diagnose"] {
            let (a, b) = (p.path("a.json"), p.path("b.json"));
            let plain_err = ok(&[cmd, s(plain), "--json", s(&a)]);
            let gz_err = ok(&[cmd, s(&gz), "--json", s(&b)]);
            // The gzipped copy's `# g_m_s2:` line is read: no fallback to 9.81 announced.
            assert!(!gz_err.contains("assumed"), "{cmd} {}: {gz_err}", gz.display());
            assert_eq!(plain_err, gz_err.replace(s(&gz), s(plain)), "{cmd} {}", gz.display());
            let (a, b) = (std::fs::read_to_string(&a).unwrap(), std::fs::read_to_string(&b).unwrap());
            if cmd == "select" {
                // Byte-identical but for the measured search times.
                let strip = |t: &str| {
                    let mut v: Value = serde_json::from_str(t).unwrap();
                    without_timings(&mut v);
                    v
                };
                assert_eq!(strip(&a), strip(&b), "{cmd} {}", gz.display());
            } else {
                assert_eq!(a, b, "{cmd} {}", gz.display());
            }
        }
    }
}

#[test]
fn a_truncated_gzip_campaign_is_refused_in_one_line_naming_the_file() {
    let p = pair();
    let gz = p.path("c.csv.gz");
    gzip(&p.unsigned, &gz);
    let bytes = std::fs::read(&gz).unwrap();
    std::fs::write(&gz, &bytes[..bytes.len() / 2]).unwrap();
    let f = s(&gz);
    for cmd in ["select", "fit", "compare", "diagnose"] {
        let e = bad(&[cmd, f]);
        assert!(e.contains(&format!("{f}: truncated gzip stream")), "{cmd}: {e}");
    }
}
