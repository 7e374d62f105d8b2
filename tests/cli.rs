//! CLI tests on the `accelcal` binary: every command end to end on simulated files, the JSON
//! shapes the issues specify, bad input turned into exit code 2 with one line naming the file,
//! options that do not apply to their mode refused before any I/O, every command's help, and
//! snapshots of what users read (a certificate, a diagnosis JSON; `insta` snapshots under
//! `tests/snapshots/`). The examples of the README and the guide: `tests/docs.rs`.

mod common;

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

/// The subcommands, from the command tree the binary prints (`help` excluded).
fn commands() -> Vec<String> {
    /// The subcommands listed under `Commands:` in a help text.
    fn listed(help: &str) -> Vec<String> {
        help.lines()
            .skip_while(|l| *l != "Commands:")
            .skip(1)
            .take_while(|l| !l.trim().is_empty())
            .map(|l| l.split_whitespace().next().unwrap().to_string())
            .filter(|c| c != "help")
            .collect()
    }
    let top = ok(&["--help"]);
    let mut list = Vec::new();
    // A command with subcommands (`record`) stands for its subcommands (`record show`).
    for cmd in listed(&top) {
        let subs = listed(&ok(&[&cmd, "--help"]));
        if subs.is_empty() {
            list.push(cmd);
        } else {
            list.extend(subs.iter().map(|s| format!("{cmd} {s}")));
        }
    }
    assert!(list.len() >= 10, "the command tree has shrunk: {list:?}\n{top}");
    assert!(list.iter().any(|c| c == "record show"), "{list:?}");
    list
}

/// One entry of a help text: its first line (flags and value name, or `<ARG>`) and the whole
/// text of the entry (description, possible values, default).
struct Entry {
    head: String,
    text: String,
}

impl Entry {
    /// The long flag (`--min-hold-s`), or the positional `<CAMPAIGN>`.
    fn name(&self) -> &str {
        self.head.split([' ', ',', '=']).find(|w| w.starts_with("--") || w.starts_with('<')).unwrap()
    }
    /// The value clap prints as `[default: X]`, if any.
    fn default(&self) -> Option<&str> {
        let at = self.text.rfind("[default: ")?;
        Some(self.text[at + 10..].split(']').next().unwrap())
    }
}

/// The entries of the Arguments and Options sections (any heading) of a help text.
fn entries(help: &str) -> Vec<Entry> {
    let mut out: Vec<Entry> = Vec::new();
    let mut in_section = false;
    for line in help.lines() {
        let t = line.trim_start();
        if !line.starts_with(' ') && !line.is_empty() {
            // A heading: `Arguments:`, `Options:`, `Gravity-norm options (...):`; or `Usage:`.
            in_section = line.ends_with(':') && !line.starts_with("Usage");
            continue;
        }
        if !in_section || t.is_empty() {
            continue;
        }
        let indent = line.len() - t.len();
        let starts = indent <= 6
            && (t.starts_with("--") || t.starts_with('<') || t.starts_with('-') && !t.starts_with("- "));
        if starts {
            let head = t.split("  ").next().unwrap().to_string();
            out.push(Entry { head, text: t.to_string() });
        } else if let Some(e) = out.last_mut() {
            e.text.push(' ');
            e.text.push_str(t);
        }
    }
    out
}

/// Options that take a physical quantity and the unit their help must state.
const UNITS: &[(&str, &str)] = &[
    ("--g", "m/s²"),
    ("--rate-hz", "Hz"),
    ("--move-s", ", s"),
    ("--noise", "ADC codes"),
    ("--bias-sd", "codes"),
    ("--misalign-sd", "rad"),
    ("--temp-profile", "°C"),
    ("--t-ref", "°C"),
    ("--thermal-lag-s", "seconds"),
    ("--chamber", "°C"),
    ("--soak-s", "Seconds"),
    ("--tolerance", "codes"),
    ("--select-tolerance", "ADC codes"),
    ("--tolerance-m-s2", "m/s²"),
    ("--max-interval-days", "days"),
    ("--tolerance", "m/s²"),
    ("--min-hold-s", "seconds"),
    ("--window-s", "seconds"),
    ("--threshold", "codes²"),
    ("--created", "seconds since the Unix epoch"),
    ("--timeout-s", "Seconds"),
    ("--head-timeout-s", "Seconds"),
    ("--baud", "Baud rate"),
    ("--magnitude", "in units of the per-position noise"),
    ("--latitude", "degrees"),
    ("--height", ", m "),
    ("--head-speed", "degrees per second"),
    ("--settle-timeout-s", "Seconds"),
    ("--static-z", "standard errors"),
];

/// Numeric options without a physical unit (counts, seeds, ratios).
const DIMENSIONLESS: &[&str] = &[
    "--first-node",
    "--seed",
    "--samples",
    "--scale-sd", // relative
    "--coverage", // a multiple of the standard uncertainty
    "--width",
    "--max-terms",
    "--threads",
    "--top",
    "--count",
    "--campaigns",
    "--rate-factor",
    "--gdb-port",
    "--head-port",
    "--static-window",
];

#[test]
fn every_command_has_help_naming_its_options_units_and_defaults_once() {
    let mut seen = std::collections::BTreeSet::new();
    for cmd in commands() {
        let words: Vec<&str> = cmd.split(' ').collect();
        let long = ok(&[&words[..], &["--help"]].concat());
        let short = ok(&[&words[..], &["-h"]].concat());
        let usage =
            long.lines().find(|l| l.starts_with("Usage: ")).unwrap_or_else(|| panic!("{cmd}: {long}"));
        assert!(usage.starts_with(&format!("Usage: accelcal {cmd} ")), "{cmd}: {usage}");
        let (le, se) = (entries(&long), entries(&short));
        let names: Vec<&str> = le.iter().map(Entry::name).collect();
        // Both helps list the same options, help and version among them, each with its text.
        assert_eq!(names, se.iter().map(Entry::name).collect::<Vec<_>>(), "{cmd}: -h and --help differ");
        assert!(names.contains(&"--help") && names.contains(&"--version"), "{cmd}: {names:?}");
        assert!(names.len() > 2, "{cmd} lists no options of its own: {names:?}");
        // Whatever the usage line requires (positionals, required options) is documented.
        for w in usage.split_whitespace().skip(3) {
            let w = w.trim_matches(|c| c == '[' || c == ']');
            if w.starts_with("--") || w.starts_with('<') {
                let documented = names.contains(&w) || le.iter().any(|e| e.head.contains(w));
                assert!(documented, "{cmd}: `{w}` of the usage line is not documented");
            }
        }
        for e in le.iter().chain(&se) {
            let name = e.name();
            let desc = e.text[e.head.len()..].trim();
            assert!(!desc.is_empty(), "{cmd} {name}: no description");
            // Each default printed once: clap's `[default: X]`, or the text's own, not both.
            let defaults = e.text.to_lowercase().matches("default").count();
            assert!(defaults <= 1, "{cmd} {name} states its default {defaults} times: {}", e.text);
            // A physical quantity states its unit.
            let units: Vec<&str> = UNITS.iter().filter(|(n, _)| *n == name).map(|(_, u)| *u).collect();
            if !units.is_empty() {
                // An option name may mean different quantities in different commands (--tolerance:
                // codes in select, m/s² in verify): one of its units must be stated.
                assert!(
                    units.iter().any(|u| e.text.contains(u)),
                    "{cmd} {name}: no unit of {units:?} in: {}",
                    e.text
                );
                seen.insert(name.to_string());
            } else {
                let numeric = e.default().is_some_and(|d| d.parse::<f64>().is_ok())
                    && !e.head.ends_with("<HEX>")
                    || ["<N>", "<K>", "_S>", "_HZ>"].iter().any(|v| e.head.ends_with(v));
                assert!(
                    !numeric || DIMENSIONLESS.contains(&name),
                    "{cmd} {name} takes a number: add it to UNITS (with the unit its help states) \
                     or to DIMENSIONLESS: {}",
                    e.text
                );
            }
        }
    }
    // The unit table names options that exist.
    let missing: Vec<_> = UNITS.iter().filter(|(n, _)| !seen.contains(*n)).collect();
    assert!(missing.is_empty(), "no command has {missing:?}");
    assert!(ok(&["select", "--help"]).contains("tail:FRACTION"));
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
    assert!(head.starts_with("# g_m_s2: 9.81\nt_s,alpha_deg,beta_deg,x,y,z\n"));
    let block = simulate(&d, "blk.csv", &["--layout", "block:5", "--plan", "six", "--samples", "2"]);
    assert!(std::fs::read_to_string(block)
        .unwrap()
        .starts_with("# g_m_s2: 9.81\nt_s,alpha_deg,beta_deg,a1,a2,a3,a4,a5\n"));
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
    let a = ok(&["fit", &c, "--latitude", "0"]);
    let b = ok(&["fit", &c, "--g", &accelcal_shared::normal_gravity(0.0, 0.0).to_string()]);
    assert_eq!(a, b);
    assert_ne!(a, ok(&["fit", &c, "--g", "9.81"]));
    assert_eq!(a, ok(&["fit", &c]));
}

/// `record show` prints every field of a record as `fit` wrote it, and the node's verdict; bad
/// bytes are bad input naming the file.
#[test]
fn record_show_prints_what_fit_wrote() {
    let d = Dir::new();
    let c = simulate(&d, "c.csv", &["--seed", "4", "--samples", "2"]);
    let id = "0102030405060708090a0b0c";
    ok(&["fit", &c, "--record", &d.s("r.rec"), "--device-id", id, "--created", "1800000000"]);
    let bytes = std::fs::read(d.p("r.rec")).unwrap();
    let rec = Record::parse(&bytes).unwrap();
    let out = ok(&["record", "show", &d.s("r.rec"), "--json", &d.s("r.json")]);
    let crc = u32::from_le_bytes(bytes[bytes.len() - 4..].try_into().unwrap());
    assert!(
        out.starts_with(&format!(
            "record {}: 156 bytes, format version 2, CRC-32 {crc:#010x}\n",
            d.s("r.rec")
        )),
        "{out}"
    );
    assert!(out.contains(&format!("device id: {id}\n")), "{out}");
    assert!(out.contains("created: 1800000000 (2027-01-15T08:00:00Z)\n"), "{out}");
    assert!(out.contains("terms: 1,ax,ay,az\n"), "{out}");
    assert!(out.contains("g: 9.81 m/s² (the gravity the fit used)\n"), "{out}");
    assert!(out.contains("node: accepts it"), "{out}");
    let j = json(&d.p("r.json"));
    assert_eq!(j["device_id"], id);
    assert_eq!(j["node_accepts"], true);
    assert_eq!(j["refusal"], Value::Null);
    assert_eq!(j["g_m_s2"], 9.81);
    assert_eq!(j["thermal"], Value::Null);
    for c in 0..3 {
        let row: Vec<f64> =
            j["coefficients"][c].as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect();
        // (serde_json's reader may be one ulp off; the printed text is exact.)
        assert!(
            row.iter().zip(&rec.coefficients[c]).all(|(a, b)| (a - b).abs() <= 1e-15 * b.abs()),
            "channel {c}"
        );
        let line = out.lines().find(|l| l.starts_with(&format!("channel {c}: "))).unwrap();
        let printed: Vec<f64> =
            line.split(": ").nth(1).unwrap().split(' ').map(|v| v.parse().unwrap()).collect();
        assert_eq!(printed, rec.coefficients[c][..4], "channel {c}: printed in full precision");
    }
    std::fs::write(d.p("bad.rec"), &bytes[..40]).unwrap();
    let e = bad(&["record", "show", &d.s("bad.rec")]);
    assert_eq!(e.trim_end(), format!("error: {}: record is truncated", d.s("bad.rec")));
    let e = bad(&["record", "show", &d.s("r.rec"), "--json", &d.s("r.rec")]);
    assert!(e.contains("is the input FILE: refusing to overwrite it"), "{e}");
}

/// A record that a node would refuse is refused by `fit --record` and by `flash` with the node's
/// reason, exit code 2, one line, and nothing is written.
#[test]
fn records_a_node_would_refuse_are_not_written_nor_flashed() {
    let d = Dir::new();
    let c = simulate(&d, "c.csv", &["--seed", "4", "--samples", "2"]);
    let (rec, j) = (d.s("r.rec"), d.s("r.json"));
    let id = "51454d552d422d4c34373545";
    let e = bad(&["fit", &c, "--terms", "ax,ay,az,ax*ay", "--record", &rec, "--device-id", id, "--json", &j]);
    assert_eq!(e.lines().count(), 1, "{e}");
    assert!(
        e.contains(&format!("{rec}: a node would refuse this record: NotModel4: the node applies model 4")),
        "{e}"
    );
    let zero = "000000000000000000000000";
    let e = bad(&["fit", &c, "--record", &rec, "--device-id", zero, "--json", &j]);
    assert!(e.contains(&format!("{rec}: a node would refuse this record: WrongDevice: ")), "{e}");
    assert!(e.contains("all zeros"), "{e}");
    let e = bad(&["fit", &c, "--record", &rec]);
    assert!(e.contains("fit --record needs --device-id HEX"), "{e}");
    assert!(!d.p("r.rec").exists() && !d.p("r.json").exists());
    // flash refuses a record no node accepts before it looks for a probe.
    ok(&["fit", &c, "--record", &d.s("good.rec"), "--device-id", id]);
    let mut r = Record::parse(&std::fs::read(d.p("good.rec")).unwrap()).unwrap();
    r.device_id = [0; 12];
    let mut buf = [0u8; accelcal_shared::record::MAX_RECORD_LEN];
    let n = r.emit(&mut buf).unwrap();
    std::fs::write(d.p("zero.rec"), &buf[..n]).unwrap();
    // record show says the same, and exits 0: it only reports.
    let out = ok(&["record", "show", &d.s("zero.rec"), "--json", &d.s("zero.json")]);
    assert!(out.contains("device id: 000000000000000000000000\n"), "{out}");
    assert!(out.contains("node: a node would refuse this record: WrongDevice: "), "{out}");
    let j = json(&d.p("zero.json"));
    assert_eq!(j["node_accepts"], false);
    assert!(j["refusal"].as_str().unwrap().contains("all zeros"), "{j}");
    let e = bad(&["flash", &d.s("zero.rec"), "--probe", "ffff:ffff"]);
    assert_eq!(e.lines().count(), 1, "{e}");
    assert!(
        e.contains(&format!("{}: a node would refuse this record: WrongDevice: ", d.s("zero.rec"))),
        "{e}"
    );
}

/// Issue 24: a record whose sensitivities no unit has (here one of −0.8 codes/(m/s²), as the
/// unturned head's campaign gave) is refused by `fit --record` (see the table of refused command
/// lines) and `flash`, and `record show` says so although a node would accept it.
#[test]
fn implausible_records_are_refused_and_record_show_says_why() {
    let d = Dir::new();
    let c = simulate(&d, "c.csv", &["--seed", "4", "--samples", "2"]);
    ok(&["fit", &c, "--record", &d.s("good.rec"), "--device-id", "51454d552d422d4c34373545"]);
    let mut r = Record::parse(&std::fs::read(d.p("good.rec")).unwrap()).unwrap();
    r.coefficients[1][2] = -0.8;
    let mut buf = [0u8; accelcal_shared::record::MAX_RECORD_LEN];
    let n = r.emit(&mut buf).unwrap();
    std::fs::write(d.p("flat.rec"), &buf[..n]).unwrap();
    let why = "implausible sensitivity: channel 1's coefficient of ay is -0.8000 codes/(m/s²), a unit's is positive \
               and 3.34 to 3340 codes/(m/s²) at g = 9.81 m/s²";
    let out = ok(&["record", "show", &d.s("flat.rec"), "--json", &d.s("flat.json")]);
    assert!(out.contains(&format!("node: would accept it, but accelcal refuses it: {why}")), "{out}");
    let j = json(&d.p("flat.json"));
    assert_eq!(j["node_accepts"], true);
    assert!(j["refusal"].as_str().unwrap().starts_with(why), "{j}");
    let e = bad(&["flash", &d.s("flat.rec"), "--probe", "ffff:ffff"]);
    assert!(e.contains(&format!("{}: {why}", d.s("flat.rec"))), "{e}");
}

/// Issue 24: `acquire`'s check that the head moved as the plan says
/// (`accelcal_core::acquire::MotionCheck`) accepts every position, in acquisition order, of the
/// real Xsens recording's holds (their angles from the calibrated gravity direction) and of
/// simulated campaigns with each effect, and refuses the unturned head's second position.
#[test]
fn the_motion_check_accepts_real_and_simulated_positions() {
    use accelcal_core::acquire::MotionCheck;
    use accelcal_core::campaign::Campaign;
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
    for (open, close) in [("<title>", "</title>"), ("<style>", "</style>"), ("<svg", "</svg>")] {
        while let Some(a) = s.find(open) {
            let b = s[a..].find(close).map_or(s.len(), |b| a + b + close.len());
            s.replace_range(a..b, "");
        }
    }
    for (tag, with) in [
        ("</tr>", "\n"),
        ("</p>", "\n"),
        ("</h1>", "\n"),
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
    out.replace("&amp;", "&").replace("&lt;", "<").replace("&gt;", ">").replace("&quot;", "\"")
}

/// Issue 24.4: the certificate of a simulated unit, verified (a verification document of the
/// record, as `verify --json` writes it): one g with its bound, per-axis tolerances, the
/// temperature of the verification, GMDH next to the record's terms, Table 2 for information.
#[test]
fn the_certificate_is_the_snapshot() {
    let d = Dir::new();
    let c = simulate(&d, "u42.csv", &["--seed", "42", "--samples", "20", "--serial", "U-42"]);
    let (rec, fit, cert) = (d.s("u42.rec"), d.s("u42-fit.json"), d.s("u42.html"));
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
    let issued = text.lines().find(|l| l.starts_with("Issued")).unwrap().to_string();
    let text = text.replace(dir, "DIR").replace(&issued, "Issued | (date) by accelcal (version) | ");
    assert_eq!(text.matches(" m/s² (").count(), 1, "one g: {text}");
    assert!(text.contains("g (local gravity) | 9.810 ± 0.005 m/s²"), "{text}");
    assert!(text.contains("at 25.0 °C (the node's sensor, 24.9 to 25.1 °C over the positions)"), "{text}");
    insta::assert_snapshot!("certificate_text", text);

    // A test-turn record: Table 2 names it the record's method, LSQ the other one.
    let text = certify("test-turns");
    assert!(text.contains("test turns (the record's method) and LSQ"), "{text}");
    assert!(text.contains("standard error of the test turns fit"), "{text}");
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

/// Every file under `dir` with its bytes.
fn files(dir: &Path) -> std::collections::BTreeMap<PathBuf, Vec<u8>> {
    let mut out = std::collections::BTreeMap::new();
    let mut todo = vec![dir.to_path_buf()];
    while let Some(d) = todo.pop() {
        for e in std::fs::read_dir(&d).unwrap().flatten() {
            let p = e.path();
            if p.is_dir() {
                out.insert(p.clone(), Vec::new());
                todo.push(p);
            } else {
                out.insert(p.clone(), std::fs::read(&p).unwrap());
            }
        }
    }
    out
}

/// Command lines (`C` a campaign, `V` a second one, `D` the campaign `C` with a `# device_id:
/// 51454d552d422d4c34373545` line, `R` a raw recording; `rc.rec`/`fc.json` the record and fit JSON
/// of `C`, `rv.rec`/`fv.json` those of `V`, `old.json` a fit JSON without the unit's identity,
/// `vc.json` a verification of `rc.rec`, `vx.json` one of another record, `vg.json` one of `rc.rec`
/// at another g; other names outputs in the same directory) that are refused, and what the one
/// error line must say.
const REFUSED: &[(&str, &str)] = &[
    (
        "fit C --run-id 7c9e6679-7425-40de-944b-e07fc1f90ae7",
        "--run-id does not apply to a command without --db (it names the run stored into)",
    ),
    (
        "fit R --method gravity-norm --db cal.sqlite",
        "--db does not apply to fit --method gravity-norm (it stores the campaign's lsq or test-turns fit)",
    ),
    ("flash x.rec --db cal.sqlite --gdb 127.0.0.1:1", "flash --db needs --run-id"),
    (
        "station --port /dev/pts/7 --port /dev/pts/8 --head manual --serial S-1 --out u1 --out u2",
        "2 --port, 1 --serial: give --serial once per --port, in the same order",
    ),
    (
        "station --port /dev/pts/7 --port /dev/pts/8 --head manual --serial S-1 --serial S-2 --out u1 --out u2 --gdb 127.0.0.1:1",
        "2 --port, 1 --gdb: give --gdb once per --port, in the same order (or not at all)",
    ),
    (
        "station --port /dev/pts/7 --port /dev/pts/7 --head manual --serial S-1 --serial S-2 --out u1 --out u2",
        "--port /dev/pts/7 is given twice: one unit per node",
    ),
    (
        "report --campaign C --record x.rec --fit f.json --out c.html --db cal.sqlite",
        "report --db needs --run-id",
    ),
    ("fit R --method gravity-norm --record x.rec", "fit --record needs --device-id HEX"),
    (
        "fit R --method gravity-norm --device-id 00112233445566778899aabb",
        "--device-id does not apply to fit without --record",
    ),
    ("fit R --method gravity-norm --created 1800000000", "--created does not apply to fit without --record"),
    ("fit R --method gravity-norm --terms ax,ay", "--terms does not apply to fit --method gravity-norm"),
    ("fit R --method gravity-norm --campaign-out R", "--campaign-out R is the input CAMPAIGN"),
    ("fit C --plot d", "--plot does not apply to fit --method lsq"),
    ("fit C --campaign-out x.csv", "--campaign-out does not apply to fit --method lsq"),
    ("fit C --threshold 5", "--threshold does not apply to fit --method lsq"),
    ("fit C --method test-turns --window-s 2", "--window-s does not apply to fit --method test-turns"),
    ("fit C --method test-turns --structure auto", "--structure does not apply to fit --method test-turns"),
    ("fit C --device-id 00112233445566778899aabb", "--device-id does not apply to fit without --record"),
    ("fit C --created 1800000000", "--created does not apply to fit without --record"),
    ("fit C --record r.rec", "fit --record needs --device-id HEX"),
    (
        "fit C --record C --device-id 00112233445566778899aabb",
        "--record C is the input CAMPAIGN: refusing to overwrite it",
    ),
    ("fit C --json C", "--json C is the input CAMPAIGN: refusing to overwrite it"),
    (
        "fit C --json o.json --record o.json --device-id 00112233445566778899aabb",
        "--json and --record name the same path",
    ),
    ("compare C --json C", "--json C is the input CAMPAIGN: refusing to overwrite it"),
    ("compare C --validate V --json V", "--json V is the input --validate"),
    ("compare C --plot C", "--plot C is the input CAMPAIGN"),
    ("select C --width 4", "--width does not apply to select --algorithm combi"),
    ("select C --top 3", "--top does not apply to select without --json"),
    ("select C --json C", "--json C is the input CAMPAIGN"),
    ("select C --criterion loo --split halves", "--split does not apply to select --criterion loo"),
    ("diagnose C --json C", "--json C is the input CAMPAIGN"),
    ("simulate --out a.csv --truth a.csv", "--out and --truth name the same path"),
    ("simulate --out a.csv --json a.csv", "--out and --json name the same path"),
    ("hil --qemu R --record V --out C C", "--out C is the input CAMPAIGN"),
    ("fit C --g 9.8 --latitude 45", "--g and --latitude both give gravity: give one of them"),
    ("select C --height 300", "--height needs --latitude"),
    ("plan --latitude 91", "--latitude must be in -90..=90 degrees, got 91"),
    ("simulate --out a.csv --latitude 45 --height inf", "--height must be within ±100000 m"),
    (
        "verify --port P --head manual --coverage 5 --tolerance 0.01",
        "--coverage does not apply to verify --tolerance (it derives the tolerance; --tolerance sets it)",
    ),
    ("verify --port P --head manual --tolerance 0", "--tolerance must be a positive number of m/s², got 0"),
    ("verify --port P --head manual --fit F --tolerance 0.01", "--fit does not apply to verify --tolerance"),
    ("verify --port P --head manual --coverage 0.5", "--coverage must be a number >= 1, got 0.5"),
    ("fit C --t-ref 20", "--t-ref does not apply to --terms ax,ay,az: it is the reference of the terms in t"),
    ("fit R --method gravity-norm --t-ref 20", "--t-ref does not apply to fit --method gravity-norm"),
    ("select C --t-ref 20", "--t-ref does not apply to a --basis without terms in t"),
    ("simulate --out a.csv --soak-s 10", "--soak-s does not apply to simulate without --chamber"),
    (
        "simulate --out a.csv --thermal-lag-s 10",
        "--thermal-lag-s does not apply to simulate without --chamber",
    ),
    (
        "simulate --out a.csv --chamber 200",
        "--chamber: each setpoint must be a temperature in -60..=150 °C, got 200",
    ),
    ("monitor --port P --timeout-s 0", "--timeout-s must be a positive number of seconds, got 0"),
    ("info --port P --timeout-s 0", "--timeout-s must be a positive number of seconds, got 0"),
    (
        "hil --qemu R --record V --out o.csv C --timeout-s 0",
        "--timeout-s must be a positive number of seconds, got 0",
    ),
    ("acquire --port P --head manual --out a.csv --rate-hz 50", "--rate-hz: RateOutOfRange"),
    // Issue 28: an emulated head's replies are bounded by --head-timeout-s (it was a fixed 120 s).
    ("acquire --port P --head sim:h:1 --out a.csv --head-timeout-s 0", "--head-timeout-s must be a positive number of seconds, got 0"),
    ("verify --port P --head sim:h:1 --head-timeout-s inf", "--head-timeout-s must be a positive number of seconds, got inf"),
    (
        "acquire --port P --head manual --out a.csv --head-timeout-s 10",
        "--head-timeout-s does not apply to --head manual (the operator turns the head)",
    ),
    ("verify --port P --head manual --head-timeout-s 10", "--head-timeout-s does not apply to --head manual"),
    ("monitor --port P --rate 50", "--rate-hz: RateOutOfRange"),
    // Issue 24: `--resume` continues with the campaign's samples, rate and g (`A`, as `acquire`
    // wrote it: 200 sets, 500 Hz, 9.81 m/s²), before the node is opened (`P` is no port).
    (
        "acquire --port P --head manual --plan six -o A --resume --samples 300",
        "--samples 300 contradicts A's `# samples: 200`: --resume continues with the campaign's settings",
    ),
    (
        "acquire --port P --head manual --plan six -o A --resume --rate-hz 1000",
        "--rate-hz 1000 contradicts A's `# rate_hz: 500`",
    ),
    (
        "acquire --port P --head manual --plan six -o A --resume --g 9.8",
        "--g 9.8 contradicts A's `# g_m_s2: 9.81`",
    ),
    (
        "acquire --port P --head manual --plan six -o C --resume",
        "not a campaign written by `accelcal acquire`",
    ),
    // Issue 23: several nodes on one head, each option per node once per `--port`/`--unit`.
    (
        "acquire --port P --port Q --head manual --out a.csv",
        "--out is given once for 2 --port options: give it once per --port (in the same order)",
    ),
    (
        "acquire --port P --port Q --head manual --out a.csv --out b.csv --serial S",
        "--serial is given once for 2 --port options: give it once per --port (in the same order), or not at all",
    ),
    ("acquire --port P --port P --head manual --out a.csv --out b.csv", "--port P is given twice (ports 1 and 2)"),
    ("acquire --port P --port Q --head manual --out a.csv --out a.csv", "--out and --out name the same path"),
    (
        "emulate --qemu R --unit C --unit V --seed 1",
        "--seed is given once for 2 --unit options: give it once per --unit (in the same order), or not at all",
    ),
    (
        "emulate --qemu R --unit C --unit V --record a.rec --record b.rec --record c.rec",
        "--record is given 3 times for 2 --unit options",
    ),
    // Issue 24: the record of a head that was never turned (`U`: six positions, one reading).
    (
        "fit U --record u.rec --device-id 51454d552d422d4c34373545",
        "implausible sensitivity: channel 0's coefficient of ax is",
    ),
    // Issue 24.2: files of different units, or that cannot say whose they are.
    (
        "fit D --record r.rec --device-id 00112233445566778899aabb",
        "--device-id 00112233445566778899aabb contradicts D's `# device_id: 51454d552d422d4c34373545`: not the same unit",
    ),
    (
        "report --campaign C --record rv.rec --fit fc.json -o o.html",
        "fc.json has record CRC CRC_C but rv.rec has CRC_V: not the record of this fit",
    ),
    (
        "report --campaign V --record rc.rec --fit fc.json -o o.html",
        "fc.json has campaign SHA-256 SHA_C but V has SHA_V: not the campaign of this fit",
    ),
    (
        "report --campaign D --record rv.rec --fit fv.json -o o.html",
        "D has device id 51454d552d422d4c34373545 but rv.rec has 00112233445566778899aabb: not the same unit",
    ),
    (
        "report --campaign C --record rc.rec --fit old.json -o o.html",
        "old.json: the fit JSON does not say whose fit it is",
    ),
    (
        "report --campaign C --record rc.rec --fit fc.json --g 9.8 -o o.html",
        "fc.json has g 9.81 m/s² but --g has 9.8 m/s²: the certificate states one g",
    ),
    (
        "report --campaign C --record rc.rec --fit fc.json --verify vx.json -o o.html",
        "vx.json has record CRC 00000000 but rc.rec has CRC_C: the node did not run this record when it was verified",
    ),
    (
        "report --campaign C --record rc.rec --fit fc.json --verify vg.json -o o.html",
        "vg.json has g 9.8 m/s² but fc.json has 9.81 m/s²: the certificate states one g",
    ),
    ("report --campaign C --record rc.rec --fit fc.json --verify vc.json -o fc.json", "fc.json is the input --fit: refusing to overwrite it"),
    ("history U-1 --db cal.sqlite --tolerance-m-s2 0", "--tolerance-m-s2 must be a positive number, got 0"),
    (
        "history U-1 --db cal.sqlite --max-interval-days 0",
        "--max-interval-days must be a positive number, got 0",
    ),
    ("history U-1 --db cal.sqlite --json cal.sqlite", "cal.sqlite is the database: refusing to overwrite it"),
    // Issue 28.4: a value that is not one line of text would add lines to the files it is written
    // into (`\n`, `\r`, `\t`, `\xHH` in a word stand for those characters); the message shows it
    // escaped.
    (
        r"acquire --port P --head manual --out a.csv --serial A\n#\x20device_id:\x20000000000000000000000000",
        r#"--serial: "A\n# device_id: 000000000000000000000000" holds a control character (U+000A) at character 2"#,
    ),
    (
        r"simulate --out a.csv --serial A\n#\x20g_m_s2:\x209",
        r#"--serial: "A\n# g_m_s2: 9" holds a control character (U+000A) at character 2"#,
    ),
    (
        r"simulate --out a.csv --serial \x20U-1",
        r#"--serial: " U-1" begins or ends with white space, which a campaign's `# key: value` line does not keep"#,
    ),
    (
        r"station --port P --head manual --serial S\r1 --out u1",
        r#"--serial: "S\r1" holds a control character (U+000D) at character 2"#,
    ),
    (
        r"station --port P --head manual --serial S-1 --out u1 --operator Bob\x1b[2J",
        r#"--operator: "Bob\u{1b}[2J" holds a control character (U+001B) at character 4"#,
    ),
    (
        r"station --port P --head manual --serial S-1 --out u1 --station line\t2",
        r#"--station: "line\t2" holds a control character (U+0009) at character 5"#,
    ),
    (
        r"station --port P --head sim:a\x1bb:1 --serial S-1 --out u1",
        r#"--head: "sim:a\u{1b}b:1" holds a control character (U+001B) at character 6"#,
    ),
    (
        r"acquire --port P --head manual --out a.csv --plan six\n#\x20g_m_s2:\x209",
        r#"--plan: "six\n# g_m_s2: 9" holds a control character (U+000A) at character 4"#,
    ),
    (r"simulate --out a\nb.csv", r#"\nb.csv" holds a control character (U+000A) at character"#),
    (r"history U\x7f1 --db cal.sqlite", r#"SERIAL|DEVICE: "U\u{7f}1" holds a control character (U+007F) at character 2"#),
    // Issue 28: the line's mistakes.
    (
        "history U-1 --db postgress://line@dbhost/accelcal",
        "`postgress://` is not a database this build opens: PostgreSQL is postgres:// or postgresql://",
    ),
    (
        "history U-1 --db cal.sqlite --max-interval-days 1e18",
        "--max-interval-days 1000000000000000000 is not an interval: give a positive number of days, at most 36525",
    ),
    ("flash x.rec --relabel swapped --gdb 127.0.0.1:1", "--relabel does not apply to a command without --db"),
    (
        "flash x.rec --db cal.sqlite --run-id 7c9e6679-7425-40de-944b-e07fc1f90ae7 --relabel swapped --gdb 127.0.0.1:1",
        "--relabel does not apply to flash (it begins no run",
    ),
    ("void 12345 --reason mislabelled --db cal.sqlite", "the run id cannot be stored"),
    (r"void 7c9e6679-7425-40de-944b-e07fc1f90ae7 --reason \x20 --db cal.sqlite", "--reason is empty"),
    (
        r"void 7c9e6679-7425-40de-944b-e07fc1f90ae7 --reason a\nb --db cal.sqlite",
        r#"--reason: "a\nb" holds a control character (U+000A)"#,
    ),
    (
        "station --port P --head manual --serial S-1 --out u1 --head-timeout-s 5",
        "--head-timeout-s does not apply to --head manual (the operator turns the head)",
    ),
    (
        r"station --port P --head manual --serial S-1 --out u1 --relabel a\tb",
        r#"--relabel: "a\tb" holds a control character (U+0009)"#,
    ),
];

/// An acquired campaign's header (`A` of the table): 200 sets per position at 500 Hz, g 9.81.
const ACQUIRED_HEADER: &str =
    "# acquired_by: accelcal 0.1.0 acquire\n# device_id: 51454d552d422d4c34373545\n\
    # g_m_s2: 9.81\n# plan: six (6 positions)\n# samples: 200\n# rate_hz: 500\n# codes: unsigned16\n\
    t_s,alpha_deg,beta_deg,x,y,z\n";

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

/// Command lines in which every option applies: they run, and write what they are asked to.
const ACCEPTED: &[(&str, &[&str])] = &[
    ("fit C --record r.rec --device-id 00112233445566778899aabb --created 1800000000", &["r.rec"]),
    ("fit C --method test-turns --json t.json", &["t.json"]),
    (
        "fit R --method gravity-norm --threshold 1000 --window-s 1 --min-hold-s 2 --structure imu-tk \
         --format imu-tk --plot p --campaign-out rc.csv --json g.json",
        &["p/gravity-residuals.svg", "rc.csv", "g.json"],
    ),
    ("select C --algorithm multi --width 4 --basis quadratic", &[]),
    ("select C --json s.json --top 3", &["s.json"]),
    ("select C --criterion loo --basis linear --json l.json", &["l.json"]),
    ("compare C --validate V --json c.json", &["c.json"]),
    ("diagnose C --json dj.json", &["dj.json"]),
    ("simulate --out a.csv --truth b.json --json a.json --samples 2", &["a.csv", "b.json", "a.json"]),
    ("fit D --record d.rec --json d.json", &["d.rec", "d.json"]),
    ("fit D --record d2.rec --device-id 51454d552d422d4c34373545", &["d2.rec"]),
    ("report --campaign C --record rc.rec --fit fc.json --verify vc.json -o o.html", &["o.html"]),
];

/// Makes the table's files of units (`D`, `rc.rec`, `fc.json`, `rv.rec`, `fv.json`, `old.json`,
/// `vc.json`, `vx.json`, `vg.json`) from `C` and `V`; returns what the expected lines' `CRC_C`,
/// `CRC_V`, `SHA_C` and `SHA_V` stand for.
fn unit_files(d: &Dir) -> Vec<(&'static str, String)> {
    let text = std::fs::read_to_string(d.p("C")).unwrap();
    std::fs::write(d.p("D"), format!("# device_id: 51454d552d422d4c34373545\n{text}")).unwrap();
    let created = ["--created", "1800000000", "--g", "9.81"];
    for (c, id, n) in [("C", "51454d552d422d4c34373545", "c"), ("V", "00112233445566778899aabb", "v")] {
        let (rec, fit) = (d.s(&format!("r{n}.rec")), d.s(&format!("f{n}.json")));
        let campaign = d.s(c);
        let mut args = vec!["fit", &campaign, "--record", &rec, "--device-id", id, "--json", &fit];
        args.extend_from_slice(&created);
        ok(&args);
    }
    let mut old = json(&d.p("fc.json"));
    for k in ["device_id", "serial", "g_m_s2", "campaign_sha256", "record_crc"] {
        old.as_object_mut().unwrap().remove(k);
    }
    std::fs::write(d.p("old.json"), old.to_string()).unwrap();
    let crc = |n: &str| json(&d.p(n))["record_crc"].as_str().unwrap().to_string();
    for (name, crc, g) in [
        ("vc.json", crc("fc.json"), 9.81),
        ("vx.json", "00000000".into(), 9.81),
        ("vg.json", crc("fc.json"), 9.8),
    ] {
        std::fs::write(d.p(name), verification_json(&crc, g).to_string()).unwrap();
    }
    vec![
        ("CRC_C", crc("fc.json")),
        ("CRC_V", crc("fv.json")),
        ("SHA_C", json(&d.p("fc.json"))["campaign_sha256"].as_str().unwrap().to_string()),
        ("SHA_V", json(&d.p("fv.json"))["campaign_sha256"].as_str().unwrap().to_string()),
    ]
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

/// The arguments of a table line, run in `d`: `C`, `V`, `R` and output names become paths there;
/// `\n`, `\r`, `\t` and `\xHH` in a word become the characters they stand for.
fn table_args(d: &Dir, line: &str) -> Vec<String> {
    let is_path = |w: &str| {
        ["C", "V", "D", "R", "A", "U", "d", "p"].contains(&w) || w.contains('.') && w.parse::<f64>().is_err()
    };
    line.split_whitespace().map(|w| unescape(&if is_path(w) { d.s(w) } else { w.to_string() })).collect()
}

/// `w` with `\n`, `\r`, `\t` and `\xHH` replaced by the characters they stand for.
fn unescape(w: &str) -> String {
    let mut out = String::new();
    let mut rest = w;
    while let Some(at) = rest.find('\\') {
        out.push_str(&rest[..at]);
        let (c, len) = match rest.as_bytes().get(at + 1) {
            Some(b'n') => ('\n', 2),
            Some(b'r') => ('\r', 2),
            Some(b't') => ('\t', 2),
            Some(b'x') => (char::from(u8::from_str_radix(&rest[at + 2..at + 4], 16).unwrap()), 4),
            _ => ('\\', 1),
        };
        out.push(c);
        rest = &rest[at + len..];
    }
    out + rest
}

/// `simulate --serial $'A\n# g_m_s2: 9.0'` (issue 28.4: the campaign would say g = 9.0 and `fit`
/// use it) is refused before anything is simulated: exit code 2, one line showing the value
/// escaped, no campaign and no truth file; the serial alone is accepted and read back as given.
#[test]
fn a_serial_that_would_forge_a_header_line_is_refused_and_nothing_is_written() {
    let d = Dir::new();
    let out = d.s("c.csv");
    for hostile in ["A\n# g_m_s2: 9.0", "A\r\n# device_id: 000000000000000000000000", "A\u{1b}[2J"] {
        let e = bad(&["simulate", "--out", &out, "--samples", "4", "--serial", hostile]);
        assert!(
            e.starts_with(&format!("error: --serial: {hostile:?} holds a control character (U+00")),
            "{e}"
        );
        assert!(!e.contains('\u{1b}'), "the escape sequence reached the terminal: {e:?}");
        assert_eq!(std::fs::read_dir(d.0.path()).unwrap().count(), 0, "{hostile:?}: a file was written");
    }
    ok(&["simulate", "--out", &out, "--samples", "4", "--serial", "A # g_m_s2: 9.0"]);
    let header = accelcal_core::campaign::header(&d.p("c.csv")).unwrap();
    let get =
        |k: &str| header.iter().filter(|(key, _)| key == k).map(|(_, v)| v.as_str()).collect::<Vec<_>>();
    assert_eq!((get("serial"), get("g_m_s2")), (vec!["A # g_m_s2: 9.0"], vec!["9.81"]));
}

#[test]
fn options_that_do_not_apply_and_outputs_that_are_inputs_are_refused_before_any_io() {
    let d = Dir::new();
    simulate(&d, "C", &["--seed", "3", "--samples", "16"]);
    simulate(&d, "V", &["--seed", "4", "--samples", "16", "--plan", "random:20"]);
    std::fs::copy(
        concat!(env!("CARGO_MANIFEST_DIR"), "/../tests/data/real/imu_tk_xsens_acc.txt.gz"),
        d.p("R"),
    )
    .unwrap();
    std::fs::write(d.p("A"), ACQUIRED_HEADER).unwrap();
    unturned(&d.p("U"));
    let subs = unit_files(&d);
    for (line, want) in REFUSED {
        let args = table_args(&d, line);
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let before = files(d.0.path());
        let e = bad(&args);
        // The files of the line, named in the expected message, become their paths there too.
        let mut want = format!(" {want}");
        for (w, path) in line.split_whitespace().zip(table_args(&d, line)) {
            if w != path {
                want = want.replace(&format!(" {w} "), &format!(" {path} "));
                want = want.replace(&format!(" {w}'s "), &format!(" {path}'s "));
            }
        }
        for (k, v) in &subs {
            want = want.replace(k, v);
        }
        let want = want.trim_start();
        assert!(e.contains(want), "`{line}`: expected `{want}` in: {e}");
        assert!(files(d.0.path()) == before, "`{line}`: a file was written or changed");
    }
    for (line, outputs) in ACCEPTED {
        let args = table_args(&d, line);
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        ok(&args);
        for o in *outputs {
            assert!(d.p(o).is_file(), "`{line}` did not write {o}");
        }
    }
}

/// A campaign that states its g (`# g_m_s2:`, as `acquire` writes it) is fitted at that g unless
/// --g or --latitude says otherwise.
#[test]
fn a_campaign_s_stated_g_is_used() {
    let d = Dir::new();
    // `simulate` states its g: strip the line for a campaign that does not.
    let sim = simulate(&d, "sim.csv", &["--seed", "3", "--samples", "5", "--g", "9.7803"]);
    let text = std::fs::read_to_string(&sim).unwrap();
    let plain = d.s("plain.csv");
    std::fs::write(&plain, text.strip_prefix("# g_m_s2: 9.7803\n").unwrap()).unwrap();
    let stated = d.s("stated.csv");
    std::fs::write(&stated, &text).unwrap();
    let fit = |campaign: &str, extra: &[&str], out: &str| {
        let mut args = vec!["fit", campaign, "--json", out];
        args.extend_from_slice(extra);
        ok(&args);
        json(Path::new(out))["channels"][0]["coefficients"][1].as_f64().unwrap()
    };
    let k_stated = fit(&stated, &[], &d.s("a.json"));
    let k_given = fit(&plain, &["--g", "9.7803"], &d.s("b.json"));
    let k_default = fit(&plain, &[], &d.s("c.json"));
    let k_override = fit(&stated, &["--g", "9.81"], &d.s("d.json"));
    assert_eq!(k_stated, k_given);
    assert_eq!(k_default, k_override);
    assert!((k_stated / k_default - 9.81 / 9.7803).abs() < 1e-9);
}

/// A failure of the environment is not bad input: `emulate` on a busy head port exits 1 (not 2),
/// with the OS error once, before QEMU is started (the ELF here is not even one).
#[test]
fn a_busy_port_is_the_environment_and_its_os_error_is_printed_once() {
    let d = Dir::new();
    let campaign = d.s("u.csv");
    let truth = d.s("u.json");
    common::succeed(&["simulate", "-o", &campaign, "--truth", &truth, "--samples", "5", "--seed", "3"]);
    let elf = d.s("not-an-elf");
    std::fs::write(&elf, b"x").unwrap();
    let busy = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let port = busy.local_addr().unwrap().port().to_string();
    let out = common::accelcal(&["emulate", "--qemu", &elf, "--unit", &truth, "--head-port", &port]);
    let err = String::from_utf8_lossy(&out.stderr).to_string();
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert_eq!(err.trim_end().lines().count(), 1, "{err}");
    assert!(err.starts_with(&format!("error: head server on 127.0.0.1:{port}: ")), "{err}");
    let cause = err.rsplit(": ").next().unwrap().trim_end();
    assert!(cause.contains("os error"), "{err}");
    assert_eq!(err.matches(cause).count(), 1, "the OS error printed once: {err}");
}
