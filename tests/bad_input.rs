//! The bad-input corpus (`tests/data/bad/`, expectations in its `expected.txt`): every command
//! that reads a campaign or a record exits with code 2, prints one line naming the file and the
//! place, and leaves no output file behind. Also what the readers exclude with a warning, and that
//! a refusal after such warnings is still one line.

use crate::common;

use std::path::{Path, PathBuf};

use accelcal_shared::record::{Record, MAX_CHANNELS, MAX_RECORD_LEN};
use accelcal_shared::terms::MODEL_4;
use accelcal_shared::N_BASIS;
use common::{accelcal, bad};

fn corpus() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/data/bad")
}

/// The corpus table: (file, what must follow its name on the error line).
fn expected() -> Vec<(PathBuf, String)> {
    let text = std::fs::read_to_string(corpus().join("expected.txt")).unwrap();
    text.lines()
        .filter(|l| !l.starts_with('#') && !l.trim().is_empty())
        .map(|l| {
            let (file, want) = l.split_once('\t').unwrap_or_else(|| panic!("no tab in `{l}`"));
            (corpus().join(file), want.to_string())
        })
        .collect()
}

/// A directory for outputs that must stay empty.
fn out_dir() -> (tempfile::TempDir, PathBuf) {
    let d = tempfile::tempdir().unwrap();
    let out = d.path().join("out");
    (d, out)
}

fn assert_no_output(out: &Path, what: &str) {
    let left: Vec<_> =
        std::fs::read_dir(out).map(|r| r.flatten().map(|e| e.path()).collect()).unwrap_or_default();
    assert!(left.is_empty(), "{what}: output left behind: {left:?}");
}

/// A valid model-4 record for the commands that need one besides the campaign.
fn good_record(dir: &Path) -> PathBuf {
    let mut coefficients = [[0.0; N_BASIS]; MAX_CHANNELS];
    for (c, row) in coefficients.iter_mut().take(3).enumerate() {
        row[0] = 32768.0;
        row[1 + c] = 1650.0;
    }
    let rec = Record {
        device_id: *b"QEMU-B-L475E",
        created_unix_s: 1_800_000_000,
        structure: MODEL_4,
        n_channels: 3,
        coefficients,
        g_m_s2: None,
        thermal: None,
    };
    let mut buf = [0u8; MAX_RECORD_LEN];
    let n = rec.emit(&mut buf).unwrap();
    let p = dir.join("good.rec");
    std::fs::write(&p, &buf[..n]).unwrap();
    p
}

#[test]
fn every_bad_campaign_is_refused_by_every_command() {
    let (d, out) = out_dir();
    let elf = good_record(d.path()); // any existing file passes the ELF check before the campaign is read
    let rec = good_record(d.path());
    let good = d.path().join("good.csv");
    campaign(&good, &[(0.0, 0.0, 3), (180.0, 0.0, 3), (90.0, 0.0, 3), (-90.0, 0.0, 3)]);
    let good = good.to_str().unwrap();
    let [j, plots, cal, o] =
        ["out.json", "plots", "cal.rec", "o.csv"].map(|n| out.join(n).to_str().unwrap().to_string());
    let (j, plots, cal, o) = (j.as_str(), plots.as_str(), cal.as_str(), o.as_str());
    let (rec, elf) = (rec.to_str().unwrap(), elf.to_str().unwrap());
    let mut n = 0;
    for (file, want) in expected().iter().filter(|(f, _)| f.extension().is_some_and(|e| e == "csv")) {
        let f = file.to_str().unwrap();
        let runs: [Vec<&str>; 6] = [
            vec!["select", f, "--json", j, "--plot", plots],
            vec!["fit", f, "--json", j, "--record", cal, "--device-id", "51454d552d422d4c34373545"],
            vec!["compare", f, "--json", j, "--plot", plots],
            vec!["compare", good, "--validate", f, "--json", j],
            vec!["diagnose", f, "--json", j, "--plot", plots],
            vec!["hil", "--qemu", elf, "--record", rec, f, "--out", o],
        ];
        for args in &runs {
            let e = bad(args);
            let place = format!("{f}{want}");
            assert!(e.contains(&place), "{args:?}: expected `{place}` in: {e}");
            assert_no_output(&out, &format!("{args:?}"));
            n += 1;
        }
    }
    assert!(n >= 6 * 15, "the corpus has shrunk: {n} runs");
}

#[test]
fn every_bad_record_is_refused_before_any_device_is_needed() {
    let (d, out) = out_dir();
    let camp = corpus().join("short-row.csv"); // never read: the record comes first
    let mut cases: Vec<(PathBuf, String)> =
        expected().into_iter().filter(|(f, _)| f.extension().is_some_and(|e| e == "rec")).collect();
    // A record damaged after it was written: its CRC no longer matches.
    let good = std::fs::read(good_record(d.path())).unwrap();
    let mut flipped = good.clone();
    let last = flipped.len() - 1;
    flipped[last] ^= 0x55;
    let p = d.path().join("bad-crc.rec");
    std::fs::write(&p, &flipped).unwrap();
    cases.push((p, ": record CRC mismatch".into()));
    let p = d.path().join("truncated.rec");
    std::fs::write(&p, &good[..good.len() / 2]).unwrap();
    cases.push((p, ": record".into()));
    cases.push((d.path().join("missing.rec"), ": cannot read the record".into()));
    assert!(cases.len() >= 5);
    for (file, want) in &cases {
        let f = file.to_str().unwrap();
        let o = out.join("o.csv");
        for args in [
            vec![
                "hil",
                "--qemu",
                "no-such.elf",
                "--record",
                f,
                camp.to_str().unwrap(),
                "--out",
                o.to_str().unwrap(),
            ],
            vec!["flash", f, "--probe", "ffff:ffff"],
        ] {
            let e = bad(&args);
            assert!(e.contains(&format!("{f}{want}")), "{args:?}: expected `{f}{want}` in: {e}");
            assert_no_output(&out, &format!("{args:?}"));
        }
    }
}

/// Writes a campaign from `(alpha, beta, samples)` dwells: channels x, y, z read
/// `30000 + 200·a` codes for the acceleration `a` (m/s²) along their own axis (within the signed
/// and the unsigned 16-bit ranges), plus a within-dwell
/// step of one code per sample (a sensor with nothing else, so that `select` has a model to find).
fn campaign(path: &Path, dwells: &[(f64, f64, usize)]) {
    let mut s = String::from("t_s,alpha_deg,beta_deg,x,y,z\n");
    let mut t = 0.0;
    for &(a, b, n) in dwells {
        let acc = accelcal_shared::gravity(a, b, 9.81);
        let [x, y, z] = acc.map(|v| 30000 + (200.0 * v).round() as i64);
        for k in 0..n as i64 {
            s += &format!("{t},{a},{b},{},{},{}\n", x + k, y + k, z + k);
            t += 0.1;
        }
    }
    std::fs::write(path, s).unwrap();
}

#[test]
fn too_few_positions_are_refused_naming_the_file() {
    let (d, out) = out_dir();
    let c = d.path().join("three.csv");
    campaign(&c, &[(0.0, 0.0, 3), (90.0, 0.0, 3), (180.0, 0.0, 3)]);
    let c = c.to_str().unwrap();
    let j = out.join("j.json");
    let j = j.to_str().unwrap();
    let e = bad(&["fit", c, "--json", j]);
    assert!(
        e.contains(&format!(
            "{c}: channel `x`: 4 terms (1,ax,ay,az) need at least 4 positions, the plan has 3"
        )),
        "{e}"
    );
    // select refuses to pick a model without `ax` because the split leaves 2 positions to fit
    // 1,ax,az on (issue 22), and leave-one-out has too few positions too.
    let e = bad(&["select", c, "--channels", "x", "--json", j]);
    assert!(
        e.contains(&format!(
            "{c}: channel x: --split alternate leaves part A 2 of the 3 positions, too few to identify \
             1,ax,az (3 terms: at least 3 positions in A, a campaign of at least 5 with this split), so \
             the selection 1,az would drop its own axis term `ax`: use --criterion loo"
        )),
        "{e}"
    );
    let e = bad(&["select", c, "--channels", "x", "--criterion", "loo", "--json", j]);
    assert!(e.contains("leaving one of the 3 positions out leaves too few"), "{e}");
    for cmd in ["compare", "diagnose"] {
        let e = bad(&[cmd, c, "--json", j]);
        assert!(e.contains(c), "{cmd}: {e}");
    }
    assert_no_output(&out, "too few positions");
}

/// The six test-turn positions and two oblique ones.
const EIGHT_POSITIONS: [(f64, f64); 8] = [
    (0.0, 0.0),
    (180.0, 0.0),
    (90.0, 0.0),
    (-90.0, 0.0),
    (0.0, 90.0),
    (0.0, -90.0),
    (45.0, 30.0),
    (-45.0, -30.0),
];

/// Sets fields of a campaign file: (line, 0-based field, value).
fn set_fields(path: &Path, fields: &[(usize, usize, &str)]) {
    let mut lines: Vec<String> = std::fs::read_to_string(path).unwrap().lines().map(String::from).collect();
    for &(line, col, v) in fields {
        let mut f: Vec<&str> = lines[line - 1].split(',').collect();
        f[col] = v;
        lines[line - 1] = f.join(",");
    }
    std::fs::write(path, lines.join("\n") + "\n").unwrap();
}

#[test]
fn saturated_samples_are_excluded_with_one_warning_per_channel() {
    let d = tempfile::tempdir().unwrap();
    let c = d.path().join("sat.csv");
    campaign(&c, &EIGHT_POSITIONS.map(|(a, b)| (a, b, 4)));
    // Channel x saturates on lines 3 and 9, channel z reads 70000 on line 12.
    set_fields(&c, &[(3, 3, "65535"), (9, 3, "0"), (12, 5, "70000")]);
    let c = c.to_str().unwrap();
    for cmd in ["fit", "select", "compare"] {
        let out = accelcal(&[cmd, c]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{cmd}: {err}");
        let warnings: Vec<&str> = err.lines().filter(|l| l.starts_with("warning: ")).collect();
        assert_eq!(warnings.len(), 2, "{cmd}: {err}");
        assert!(
            warnings[0].contains(&format!("{c}:3:4: excluded 2 of 32 samples where channel `x`")),
            "{err}"
        );
        assert!(
            warnings[1].contains(&format!("{c}:12:6: excluded 1 of 32 samples where channel `z`")),
            "{err}"
        );
    }
}

#[test]
fn single_sample_dwells_are_accepted_with_a_warning() {
    let d = tempfile::tempdir().unwrap();
    let c = d.path().join("one.csv");
    campaign(&c, &EIGHT_POSITIONS.map(|(a, b)| (a, b, if a == 90.0 { 1 } else { 3 })));
    let c = c.to_str().unwrap();
    for method in ["lsq", "test-turns"] {
        let out = accelcal(&["fit", c, "--method", method, "--g", "9.81", "--g-u", "1e-5"]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{err}");
        assert_eq!(err.trim_end(), format!("warning: {c}:8: 1 dwell(s) with a single sample (first at this line): their scatter is unknown"));
        assert!(!String::from_utf8_lossy(&out.stdout).contains("NaN"));
    }
    // Every dwell a single sample: fits still run; the diagnosis, which needs the noise, refuses.
    campaign(Path::new(c), &EIGHT_POSITIONS.map(|(a, b)| (a, b, 1)));
    assert!(accelcal(&["fit", c]).status.success());
    let e = bad(&["diagnose", c]);
    assert!(e.contains(&format!("error: {c}: every dwell has a single sample")), "{e}");
    assert!(e.contains(&format!("(note: {c}:2: 8 dwell(s) with a single sample")), "{e}");
}

/// Samples excluded with a warning, then the campaign refused because of what is left: the user
/// gets one line, the error, which names the exclusion; when the command succeeds on the same file
/// the warnings print on their own lines.
#[test]
fn a_refusal_after_excluded_samples_is_one_line_naming_the_exclusion() {
    let d = tempfile::tempdir().unwrap();
    // Two samples per dwell, channel x saturated in the first of each: one sample left per dwell.
    let c = d.path().join("half.csv");
    campaign(&c, &EIGHT_POSITIONS.map(|(a, b)| (a, b, 2)));
    let saturated: Vec<(usize, usize, &str)> = (0..8).map(|k| (2 + 2 * k, 3, "65535")).collect();
    set_fields(&c, &saturated);
    let c = c.to_str().unwrap();
    let excluded = format!("{c}:2:4: excluded 8 of 16 samples where channel `x` is saturated");
    let single = format!("{c}:2: 8 dwell(s) with a single sample");
    let e = bad(&["diagnose", c]);
    assert!(e.starts_with(&format!("error: {c}: every dwell has a single sample")), "{e}");
    assert!(e.contains(&format!("(note: {excluded}")) && e.contains(&single), "{e}");
    let out = accelcal(&["fit", c, "--g", "9.81", "--g-u", "1e-5"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    let lines: Vec<&str> = err.lines().collect();
    assert_eq!(lines.len(), 2, "{err}");
    assert!(lines[0].starts_with(&format!("warning: {excluded}")), "{err}");
    assert!(lines[1].starts_with(&format!("warning: {single}")), "{err}");

    // Too few positions for the model, in a campaign that also had a sample excluded.
    let c = d.path().join("three.csv");
    campaign(&c, &[(0.0, 0.0, 3), (90.0, 0.0, 3), (180.0, 0.0, 3)]);
    set_fields(&c, &[(5, 5, "0")]);
    let c = c.to_str().unwrap();
    let e = bad(&["fit", c]);
    assert!(e.contains("need at least 4 positions, the plan has 3"), "{e}");
    let note = format!(
        "(note: {c}:5:6: excluded 1 of 9 samples where channel `z` is saturated (0 or 65535) or \
         outside the unsigned16 range (first at this line))"
    );
    for cmd in ["fit", "compare", "diagnose"] {
        let e = bad(&[cmd, c]);
        assert!(e.ends_with(&note), "{cmd}: {e}");
    }
}

/// `hil` replays codes to a node that samples a 16-bit unsigned ADC: a signed16 campaign, by its
/// comment line or by `--codes`, is refused before any node is started, and so is a `--codes`
/// that contradicts the file.
#[test]
fn hil_refuses_signed_codes_before_any_node_is_started() {
    let (d, out) = out_dir();
    let rec = good_record(d.path());
    let c = d.path().join("signed.csv");
    campaign(&c, &EIGHT_POSITIONS.map(|(a, b)| (a, b, 2)));
    let plain = std::fs::read_to_string(&c).unwrap();
    let commented = d.path().join("commented.csv");
    std::fs::write(&commented, format!("# codes: signed16\n{plain}")).unwrap();
    let (c, commented, rec) = (c.to_str().unwrap(), commented.to_str().unwrap(), rec.to_str().unwrap());
    let o = out.join("o.csv");
    let o = o.to_str().unwrap();
    // Any existing file passes the ELF check: nothing may get as far as starting QEMU.
    let hil = |campaign: &str, codes: &[&'static str]| {
        let mut args = vec!["hil", "--qemu", rec, "--record", rec, campaign, "--out", o];
        args.extend_from_slice(codes);
        bad(&args)
    };
    let refused = "signed16 codes cannot be replayed: the node samples a 16-bit unsigned ADC";
    for (campaign, codes) in
        [(commented, &[][..]), (c, &["--codes", "signed16"][..]), (commented, &["--codes", "signed16"])]
    {
        let e = hil(campaign, codes);
        assert!(e.contains(&format!("{campaign}: {refused}")), "{codes:?}: {e}");
    }
    let e = hil(commented, &["--codes", "unsigned16"]);
    assert!(e.contains(&format!("{commented}:1: `# codes: signed16` contradicts --codes unsigned16")), "{e}");
    assert_no_output(&out, "hil with signed codes");
}

/// A campaign that does not state its gravity, fitted without --g or --latitude: the 9.81 m/s²
/// fallback is announced once, as a note after the result, by each of the commands that need g;
/// a failure's one line does not carry it; --g silences it.
#[test]
fn the_gravity_fallback_is_announced_once() {
    let d = tempfile::tempdir().unwrap();
    let c = d.path().join("plain.csv");
    campaign(&c, &EIGHT_POSITIONS.map(|(a, b)| (a, b, 3)));
    let c = c.to_str().unwrap();
    let note = format!(
        "note: g = 9.81 m/s² assumed: {c} does not state its gravity (`# g_m_s2:`) and neither --g nor --latitude was given"
    );
    for cmd in [&["fit", c][..], &["select", c, "--basis", "linear"][..], &["compare", c][..]] {
        let out = accelcal(cmd);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{cmd:?}: {err}");
        assert_eq!(err.matches("g = 9.81 m/s² assumed").count(), 1, "{cmd:?}: {err}");
        assert_eq!(err.lines().last(), Some(note.as_str()), "{cmd:?}: {err}");
    }
    // A g typed is not assumed: it is taken as rounded, said once; with --g-u, nothing is said.
    let typed = accelcal(&["fit", c, "--g", "9.81"]);
    let err = String::from_utf8_lossy(&typed.stderr);
    assert_eq!(err.lines().collect::<Vec<_>>(), ["note: u(g) = 2.9e-3 m/s²: g = 9.81 m/s² as typed is taken as rounded, half a unit of its last digit (give --g-u with the standard uncertainty of the survey it came from)"], "{err}");
    let quiet = accelcal(&["fit", c, "--g", "9.81", "--g-u", "1e-5"]);
    assert!(String::from_utf8_lossy(&quiet.stderr).is_empty());
    let e = bad(&["fit", c, "--terms", "ax,ay,az,ax^2,ay^2,az^2,ax*ay,ax*az,ay*az"]);
    assert!(!e.contains("assumed"), "{e}");
    // A simulated campaign states its g.
    let sim = d.path().join("sim.csv");
    ok_quiet(&["simulate", "-o", sim.to_str().unwrap(), "--samples", "3", "--g", "9.8"]);
    assert!(std::fs::read_to_string(&sim).unwrap().starts_with("# g_m_s2: 9.8\n"));
    let out = accelcal(&["fit", sim.to_str().unwrap()]);
    assert!(out.status.success() && String::from_utf8_lossy(&out.stderr).is_empty());
}

fn ok_quiet(args: &[&str]) {
    let out = accelcal(args);
    assert!(out.status.success(), "{args:?}: {}", String::from_utf8_lossy(&out.stderr));
}
