//! `station --config station.toml` (issue 30, item 6): the line's settings in one file, refused
//! with the file's line when wrong, before anything is touched, and overridden by the command
//! line. That a file's settings reach every step: `tests/line/station.rs`.

use super::*;

/// A settings file for one node at a port that does not exist, with `extra` lines after the
/// top-level keys.
fn config(dir: &Dir, name: &str, extra: &str) -> PathBuf {
    let text = format!(
        "# The station of line 1.\nstation = \"line-1\"\nhead = \"manual\"\nplan = \"six\"\n{extra}\n[laboratory]\nname = \"Example Calibration Laboratory\"\naddress = \"1 Sample Street, Neuchâtel\"\n\n[[node]]\nport = \"{}\"\n",
        dir.p("no-such-port").display()
    );
    let p = dir.p(name);
    std::fs::write(&p, text).unwrap();
    p
}

/// Each refusal names the file, the key's line and column, and what is wrong; nothing is
/// created (the unit's directory stays missing).
#[test]
fn a_wrong_settings_file_is_refused_with_its_line_and_nothing_is_done() {
    let d = Dir::new();
    let cases: &[(&str, &str)] = &[
        ("plann = \"head\"", "station.toml:5:1: unknown field `plann`, expected one of"),
        ("samples = \"many\"", "station.toml:5:11: invalid type: string \"many\", expected usize"),
        ("samples = 1", "`samples` (station.toml:5:11) must be at least 2 sets per position, got 1"),
        (
            "head_timeout_s = 30",
            "`head_timeout_s` (station.toml:5:18) does not apply to `head = \"manual\"` (station.toml:3:8) (the operator turns the head, and their word is the read-back)",
        ),
        (
            "head_tolerance_arcsec = 5",
            "`head_tolerance_arcsec` (station.toml:5:25) does not apply to `head = \"manual\"` (station.toml:3:8) (the operator turns the head, and their word is the read-back)",
        ),
        (
            "head_zaber_alpha = \"1/1\"",
            "`head_zaber_alpha` (station.toml:5:20) does not apply to `head = \"manual\"` (station.toml:3:8) (they set a Zaber head's axes and scale)",
        ),
        (
            "head_zaber_beta = \"2/0\"",
            "`head_zaber_beta` (station.toml:5:19): `2/0`: expected DEVICE/AXIS, a device 1..=99 and an axis 1..=9 (as `1/1`)",
        ),
        (
            "head_zaber_deg_per_step = 0",
            "`head_zaber_deg_per_step` (station.toml:5:27) must be a number of degrees per microstep in (0, 1), got 0",
        ),
        ("settle_s = -1", "`settle_s` (station.toml:5:12) must be a number of seconds from 0 to 86400 (a day), got -1"),
        ("operator = \"Bob\\u001b[2J\"", "station.toml:5:12: operator: \"Bob\\u{1b}[2J\" holds a control character (U+001B)"),
        ("g = 9.8\nlatitude = 46.99", "station.toml:5:5: g and latitude (at 6:12) both give gravity: keep one of them"),
        ("height = 400", "station.toml:5:10: height needs latitude (it corrects the normal gravity there)"),
        (
            "gravity_asset = \"G-1\"\ng = 9.81",
            "station.toml:5:17: gravity_asset and g (at 6:5) both give gravity: keep one of them",
        ),
        ("g_u = 1e-6", "station.toml:5:7: g_u needs g: it is the standard uncertainty of that g"),
        ("rate_hz = 5", "`rate_hz` (station.toml:5:11): "),
        ("plan = \"six\"", "station.toml:5:1: duplicate key"),
        ("spec = \"a\\nb.toml\"", "station.toml:5:8: spec: \"a\\nb.toml\" holds a control character (U+000A)"),
        // Issue 55: a duration is at most a day (a larger one overflowed the timeout's Duration).
        (
            "timeout_s = 1e300",
            "`timeout_s` (station.toml:5:13) must be a positive number of seconds up to 86400 (a day), got 1e300",
        ),
        // Issue 55: an identifier with a bidi control is refused like a control character.
        (
            "operator = \"ana\\u202e\"",
            "station.toml:5:12: operator: \"ana\\u{202e}\" holds the invisible format character U+202E",
        ),
        ("bias_tempco_u = -0.1", "station.toml:5:17: bias_tempco_u must be a finite number ≥ 0, got -0.1"),
        // Issue 59: the verifications' own length and the selection's criterion.
        ("verify_samples = 1", "`verify_samples` (station.toml:5:18) must be at least 2 sets per position, got 1"),
        ("criterion = \"best\"", "`criterion` (station.toml:5:13): `best`: expected regularity, symmetric, rss or loo"),
        ("min_interval_days = -3", "`min_interval_days` (station.toml:5:21)"),
        // Issue 57: a station's certificate is approved by a signer, not by a name in a file.
        (
            "authorised_by = \"A. Reviewer\"",
            "`authorised_by` (station.toml:5:17) does not apply to the station, which stores every run in a database",
        ),
        (
            "bias_tempco_u = 0.1\nscale_tempco_u = 50",
            "station.toml: bias_tempco_u, scale_tempco_u and thermometer_u go together",
        ),
        ("[[node]]\nport = \"b\"\ngdb = \"127.0.0.1:3333\"", "station.toml:5:1: 1 of 2 [[node]] give gdb: give it for every node or for none"),
    ];
    for (extra, want) in cases {
        let c = config(&d, "station.toml", extra);
        let unit = d.p("unit");
        let e = bad(&[
            "station",
            "--config",
            c.to_str().unwrap(),
            "--serial",
            "S-1",
            "--out",
            unit.to_str().unwrap(),
        ]);
        let e = e.replace(&format!("{}/", d.0.path().display()), "");
        assert!(e.starts_with(&format!("error: {want}")), "{extra}:\n{e}\nwant: {want}");
        assert!(!unit.exists(), "{extra}: nothing done");
    }
    // Without a file, the nodes and the head are options of their own.
    let e = bad(&["station", "--serial", "S-1", "--out", "u"]);
    assert_eq!(e, "error: station needs --port and --head, or a --config file that gives them");
    let e =
        bad(&["station", "--config", d.p("missing.toml").to_str().unwrap(), "--serial", "S-1", "--out", "u"]);
    assert!(e.contains("missing.toml: cannot read: No such file"), "{e}");
}

/// An option on the command line overrides its key: the file's bad `samples` is not read once
/// `--samples` is given, and `--head sim:…` lifts the refusal of the file's `head_timeout_s`
/// (which a manual head has not). `--port` replaces the file's nodes, so their count no longer
/// has to match the `--serial`s. Relative paths are the file's: its `spec` is found beside it
/// from any working directory, and named there in the errors.
#[test]
fn the_command_line_overrides_the_file_and_its_paths_are_its_own() {
    let d = Dir::new();
    let c = config(&d, "station.toml", "samples = 1\nhead_timeout_s = 30\nspec = \"ms9002.toml\"");
    let c = c.to_str().unwrap();
    let unit = d.p("unit");
    let u = unit.to_str().unwrap();
    let e = bad(&["station", "--config", c, "--serial", "S-1", "--out", u, "--samples", "200"]);
    assert!(e.contains("`head_timeout_s` (") && e.contains("does not apply to `head = \"manual\"`"), "{e}");
    let with_head = ["--samples", "200", "--head", "sim:127.0.0.1:9", "--coverage", "5"];
    let mut args = vec!["station", "--config", c, "--serial", "S-1", "--out", u];
    args.extend(with_head);
    let e = bad(&args);
    let spec_at = format!("`spec` ({c}:");
    assert!(e.starts_with("error: --coverage and ") && e.contains(&spec_at), "{e}");
    // Without --coverage, the file's spec is read from beside the file, not from the working
    // directory (the test's), and refused there: it does not exist.
    args.truncate(args.len() - 2);
    let out = accelcal(&args);
    let e = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{e}");
    assert!(e.contains(&format!("{}: cannot read", d.p("ms9002.toml").display())), "{e}");
    assert!(
        e.contains("station: settings ") && e.contains("the command line overrides head, samples"),
        "{e}"
    );
    assert!(!unit.exists(), "nothing done");
    // --port replaces the file's one node: two --serial and two --out now match.
    let mut args =
        vec!["station", "--config", c, "--port", "P1", "--port", "P2", "--serial", "S-1", "--out", u];
    args.extend(&with_head[..4]);
    let e = bad(&args);
    assert_eq!(e, "error: 2 --port, 1 --serial: give --serial once per --port, in the same order");
}

/// Issue 59: a designed plan file states its dwell (`# samples:`, `# rate_hz:`) and the station
/// takes it; the file's `samples` or `rate_hz` that contradicts it is refused naming the key and
/// both values, before anything is done; values equal to the plan's are fine.
#[test]
fn a_designed_plan_s_dwell_is_the_station_s_and_a_key_that_contradicts_it_is_refused() {
    let d = Dir::new();
    let plan = d.p("designed.csv");
    std::fs::write(&plan, "# samples: 800\n# rate_hz: 500\nalpha_deg,beta_deg\n0,0\n90,0\n").unwrap();
    let (p, unit) = (plan.to_str().unwrap(), d.p("unit"));
    let u = unit.to_str().unwrap();
    for (extra, want) in [
        (
            "samples = 400",
            "`samples` (station.toml:5:11) 400 contradicts the plan PLAN (designed with `# samples: 800`)",
        ),
        (
            "rate_hz = 100",
            "`rate_hz` (station.toml:5:11) 100 contradicts the plan PLAN (designed with `# rate_hz: 500`)",
        ),
    ] {
        let c = config(&d, "station.toml", extra);
        let e =
            bad(&["station", "--config", c.to_str().unwrap(), "--plan", p, "--serial", "S-1", "--out", u]);
        let e = e.replace(&format!("{}/", d.0.path().display()), "");
        let want = want.replace("PLAN", p);
        assert!(
            e.starts_with(&format!("error: {}", want.replace(&format!("{}/", d.0.path().display()), ""))),
            "{extra}:\n{e}"
        );
        assert!(!unit.exists(), "{extra}: nothing done");
    }
    // Equal to the plan's: taken, and said; the station then goes on to its node, which is not there.
    let c = config(&d, "station.toml", "samples = 800\nrate_hz = 500");
    let out =
        accelcal(&["station", "--config", c.to_str().unwrap(), "--plan", p, "--serial", "S-1", "--out", u]);
    let e = String::from_utf8_lossy(&out.stderr);
    assert_ne!(out.status.code(), Some(2), "{e}");
    assert!(
        e.contains(&format!("station: plan {p}: 800 sample sets per position at 500 Hz, from its header")),
        "{e}"
    );
}

/// The guide's example file (`docs/src/line/station.md`) is accepted whole: the station gets as
/// far as the register, where its head asset is not (exit code 3, nothing done).
#[test]
fn the_guides_settings_file_is_accepted() {
    let page =
        std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../docs/src/line/station.md")).unwrap();
    let section = &page[page.find("## The settings file").expect("the guide's section")..];
    let start = section.find("```toml\n").expect("a toml block") + "```toml\n".len();
    let example = &section[start..start + section[start..].find("```").unwrap()];
    let d = Dir::new();
    std::fs::write(d.p("station.toml"), example).unwrap();
    let (c, unit, db) = (d.p("station.toml"), d.p("u0042"), d.p("calibration.sqlite"));
    let args =
        ["station", "--config", c.to_str().unwrap(), "--serial", "U-0042", "--out", unit.to_str().unwrap()];
    let out = accelcal(&[&args[..], &["--db", db.to_str().unwrap()]].concat());
    let e = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(3), "{e}");
    assert!(
        e.contains(&format!(
            "station: settings {} (station, customer, customer_address, place, min_interval_days, laboratory.name, laboratory.address, laboratory.country, head, head_asset, node.port, node.probe, plan, samples, rate_hz, latitude, height, spec)",
            c.display()
        )),
        "{e}"
    );
    assert!(e.contains("asset `HEAD-01`"), "{e}");
    assert!(!unit.exists() && !db.exists(), "nothing done");
}
