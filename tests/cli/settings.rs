//! Settings checked before any I/O: options that do not apply to their mode are refused with
//! nothing written, and bad values name the option.

use super::*;

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
        "fit C --method test-turns --head-angle-u 3",
        "--head-angle-u does not apply to fit --method test-turns (it enters the uncertainty budget of an lsq fit of model 4)",
    ),
    (
        "fit C --terms ax,ay,az,ax^2 --head-orthogonality-u 3",
        "--head-orthogonality-u does not apply to fit --terms ax,ay,az,ax^2 (the uncertainty budget is made for model 4, --terms ax,ay,az)",
    ),
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
    ("monitor --port P --timeout-s 0", "--timeout-s must be a positive number of seconds up to 86400 (a day), got 0"),
    ("info --port P --timeout-s 0", "--timeout-s must be a positive number of seconds up to 86400 (a day), got 0"),
    (
        "hil --qemu R --record V --out o.csv C --timeout-s 0",
        "--timeout-s must be a positive number of seconds up to 86400 (a day), got 0",
    ),
    ("acquire --port P --head manual --out a.csv --rate-hz 50", "--rate-hz: RateOutOfRange"),
    // Issue 28: an emulated head's replies are bounded by --head-timeout-s (it was a fixed 120 s).
    ("acquire --port P --head sim:h:1 --out a.csv --head-timeout-s 0", "--head-timeout-s must be a positive number of seconds up to 86400 (a day), got 0"),
    ("verify --port P --head sim:h:1 --head-timeout-s inf", "--head-timeout-s must be a positive number of seconds up to 86400 (a day), got inf"),
    (
        "acquire --port P --head manual --out a.csv --head-timeout-s 10",
        "--head-timeout-s does not apply to --head manual (the operator turns the head, and their word is the read-back)",
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
        "2 --port, 1 --out: give --out once per --port, in the same order",
    ),
    (
        "acquire --port P --port Q --head manual --out a.csv --out b.csv --serial S",
        "2 --port, 1 --serial: give --serial once per --port, in the same order (or not at all)",
    ),
    ("acquire --port P --port P --head manual --out a.csv --out b.csv", "--port P is given twice (ports 1 and 2)"),
    ("acquire --port P --port Q --head manual --out a.csv --out a.csv", "--out and --out name the same path"),
    (
        "emulate --qemu R --unit C --unit V --seed 1",
        "2 --unit, 1 --seed: give --seed once per --unit, in the same order (or not at all)",
    ),
    (
        "emulate --qemu R --unit C --unit V --record a.rec --record b.rec --record c.rec",
        "2 --unit, 3 --record: give --record once per --unit",
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
    (
        "report --campaign C --record rc.rec --fit fc.json --verify vc.json -o o.html --laboratory-country CH",
        "--laboratory-country needs --laboratory (it is the laboratory's country)",
    ),
    (
        "report --campaign C --record rc.rec --fit fc.json --verify vc.json -o o.html --laboratory L --laboratory-country Swiss",
        "--laboratory-country \"Swiss\" is not an ISO 3166-1 alpha-2 code (two capital letters, e.g. DE)",
    ),
    (
        "station --head manual --port P --out u --serial S --thermometer-asset T-1",
        "--thermometer-asset needs --ambient-c: the certificate states the environment's temperature as read on it",
    ),
    (
        "station --head manual --port P --out u --serial S --ambient-c 22",
        "--ambient-c needs --thermometer-asset: a reading is traceable through the registered thermometer it was read on",
    ),
    (
        "report --campaign C --record rc.rec --fit fc.json --verify vc.json -o o.html --ambient-c 22",
        "--ambient-c needs --db and --run-id: the thermometer it was read on is the run's",
    ),
    (
        "station --head manual --port P --out u --serial S --g-u 1e-6",
        "--g-u needs --g: it is the standard uncertainty of the g typed there",
    ),
    (
        "station --head manual --port P --out u --serial S --gravity-asset G-1 --latitude 50",
        "--gravity-asset and --latitude both give gravity: give one of them",
    ),
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
        "--head-timeout-s does not apply to --head manual (the operator turns the head, and their word is the read-back)",
    ),
    (
        r"station --port P --head manual --serial S-1 --out u1 --relabel a\tb",
        r#"--relabel: "a\tb" holds a control character (U+0009)"#,
    ),
    // Issue 59: a designed plan states its dwell; the station takes it, and refuses a
    // --samples or --rate-hz that contradicts it, naming both values.
    (
        "station --port P --head manual --serial S-1 --out u1 --plan designed.csv --samples 400",
        "--samples 400 contradicts the plan designed.csv (designed with `# samples: 800`): give 800, or leave it out",
    ),
    (
        "station --port P --head manual --serial S-1 --out u1 --plan designed.csv --rate-hz 100",
        "--rate-hz 100 contradicts the plan designed.csv (designed with `# rate_hz: 500`): give 500, or leave it out",
    ),
    (
        "station --port P --head manual --serial S-1 --out u1 --plan fractional.csv",
        "the plan fractional.csv's `# rate_hz: 12.5` is not a rate the node takes: not a whole number of Hz",
    ),
    (
        "station --port P --head manual --serial S-1 --out u1 --plan twice.csv",
        "twice.csv:2: a second `# samples:` line (the first is line 1)",
    ),
];

/// The plan files of the table: one designed (800 sample sets at 500 Hz), one whose rate no
/// node takes, one that states its samples twice.
const PLANS: &[(&str, &str)] = &[
    ("designed.csv", "# designed by accelcal plan --design 8\n# samples: 800\n# rate_hz: 500\nalpha_deg,beta_deg\n0,0\n90,0\n"),
    ("fractional.csv", "# samples: 800\n# rate_hz: 12.5\nalpha_deg,beta_deg\n0,0\n"),
    ("twice.csv", "# samples: 800\n# samples: 400\nalpha_deg,beta_deg\n0,0\n"),
];

/// An acquired campaign's header (`A` of the table): 200 sets per position at 500 Hz, g 9.81.
const ACQUIRED_HEADER: &str =
    "# acquired_by: accelcal 0.1.0 acquire\n# device_id: 51454d552d422d4c34373545\n\
    # g_m_s2: 9.81\n# plan: six (6 positions)\n# samples: 200\n# rate_hz: 500\n# codes: unsigned16\n\
    t_s,alpha_deg,beta_deg,x,y,z\n";

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

/// Issue 55: identifiers with a zero-width character or a bidi control (two units that would
/// display the same) are refused before anything is done: exit code 2, one line naming the option
/// and the character as U+XXXX, nothing written; the station's settings file likewise.
#[test]
fn an_identifier_with_a_format_character_is_refused() {
    let d = Dir::new();
    let out = d.s("c.csv");
    let db = d.s("cal.sqlite");
    let cases: [(Vec<&str>, &str); 4] = [
        (vec!["simulate", "--out", &out, "--samples", "4", "--serial", "SN\u{200b}1"], "--serial"),
        (
            vec![
                "station",
                "--port",
                "P",
                "--head",
                "manual",
                "--serial",
                "S-1",
                "--out",
                &out,
                "--operator",
                "ana\u{202e}",
            ],
            "--operator",
        ),
        (
            vec![
                "station",
                "--port",
                "P",
                "--head",
                "manual",
                "--serial",
                "S-1",
                "--out",
                &out,
                "--customer",
                "\u{feff}ACME",
            ],
            "--customer",
        ),
        (
            vec![
                "asset",
                "add",
                "HEAD\u{2066}-1",
                "--kind",
                "thermometer",
                "--certificate",
                "C-1",
                "--due",
                "2099-01-01",
                "--db",
                &db,
            ],
            "ID",
        ),
    ];
    for (args, option) in cases {
        let e = bad(&args);
        assert!(e.starts_with(&format!("error: {option}: ")), "{args:?}: {e}");
        assert!(e.contains("holds the invisible format character U+"), "{e}");
        assert!(!e.contains(['\u{200b}', '\u{202e}', '\u{feff}', '\u{2066}']), "{e:?}");
        assert_eq!(std::fs::read_dir(d.0.path()).unwrap().count(), 0, "{args:?}: a file was written");
    }
    let e = bad(&["simulate", "--out", &out, "--serial", "SN\u{200b}1"]);
    assert!(
        e.contains(r#"--serial: "SN\u{200b}1" holds the invisible format character U+200B at character 3"#),
        "{e}"
    );
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
    for (name, text) in PLANS {
        std::fs::write(d.p(name), text).unwrap();
    }
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

/// A number outside its option's range is refused by the option's value parser as the command
/// line is parsed (`host/src/cli/range.rs`): one line naming the option and the value, exit code
/// 2, whichever command takes the option; a number that does not parse the same way, shown
/// escaped.
#[test]
fn a_number_out_of_its_range_is_one_line_naming_the_option() {
    let cases: &[(&[&str], &str)] = &[
        (
            &["info", "--port", "P", "--timeout-s", "0"],
            "error: --timeout-s must be a positive number of seconds up to 86400 (a day), got 0",
        ),
        // Issue 55: a duration is at most a day; 1e20 s panicked building the timeout.
        (
            &["info", "--port", "P", "--timeout-s", "1e20"],
            "error: --timeout-s must be a positive number of seconds up to 86400 (a day), got 1e20",
        ),
        (
            &["monitor", "--port", "P", "--timeout-s", "86400.5"],
            "error: --timeout-s must be a positive number of seconds up to 86400 (a day), got 86400.5",
        ),
        (
            &["simulate", "--out", "a.csv", "--chamber", "20", "--soak-s", "1e300"],
            "error: --soak-s must be a number of seconds from 0 to 86400 (a day), got 1e300",
        ),
        (
            &["emulate", "--qemu", "R", "--unit", "u", "--head-speed", "0"],
            "error: --head-speed must be a positive number of degrees per second, got 0",
        ),
        (&["simulate", "--out", "a.csv", "--samples", "0"], "error: --samples must be at least 1, got 0"),
        (&["select", "C", "--width", "0"], "error: --width must be at least 1, got 0"),
        (
            &["select", "C", "--t-ref", "300"],
            "error: --t-ref must be a temperature in -100..=200 °C, got 300",
        ),
        (
            &["fit", "R", "--method", "gravity-norm", "--window-s", "0"],
            "error: --window-s must be a positive number of seconds up to 86400 (a day), got 0",
        ),
        (
            &["history", "U-1", "--db", "cal.sqlite", "--coverage", "0"],
            "error: --coverage must be a positive number, got 0",
        ),
        (&["plan", "--design", "12", "--noise=-1"], "error: --noise must be a finite number ≥ 0, got -1"),
        (
            &["monitor", "--port", "P", "--timeout-s", "1\u{1b}[2J"],
            "error: --timeout-s `1\\u{1b}[2J`: invalid float literal",
        ),
    ];
    for (args, want) in cases {
        let out = common::accelcal(args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        assert_eq!(err.trim_end(), *want, "{args:?}");
    }
}

/// Issue 55: a command that appends to an existing database refuses a SQLite file that is not
/// there instead of creating an empty one: exit code 2, one line naming the file, and the file
/// still missing afterwards.
#[test]
fn a_missing_database_is_refused_by_commands_that_append_to_one() {
    let d = Dir::new();
    let db = d.s("missing.sqlite");
    let run = "7c9e6679-7425-40de-944b-e07fc1f90ae7";
    let cases: [(Vec<&str>, &str); 3] = [
        (vec!["void", run, "--reason", "x", "--db", &db], "void"),
        (vec!["flash", "x.rec", "--db", &db, "--run-id", run, "--gdb", "127.0.0.1:1"], "flash --db"),
        (
            vec![
                "report",
                "--campaign",
                "C",
                "--record",
                "x.rec",
                "--fit",
                "f.json",
                "--out",
                "c.html",
                "--db",
                &db,
                "--run-id",
                run,
            ],
            "report --db",
        ),
    ];
    for (args, command) in cases {
        let e = bad(&args);
        assert_eq!(
            e,
            format!("error: {db}: no such database: {command} appends to an existing database, it does not create one"),
            "{args:?}"
        );
        assert!(!d.p("missing.sqlite").exists(), "{args:?} created the database");
    }
}
