//! Every command's help: each option named once, a physical quantity with its unit, a default
//! stated at most once.

use super::*;

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
    ("--head-angle-u", "arcsec"),
    ("--head-orthogonality-u", "arcsec"),
    ("--angle-u", "arcsec"),
    ("--orthogonality-u", "arcsec"),
    ("--due", "UTC"),
    ("--since", "UTC"),
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
    ("--min-interval-days", "days"),
    ("--interval-days", "days"),
    ("--head-u", "arcsec"),
    ("--due-days", "days"),
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
    ("--header-timeout-s", "Seconds"),
    ("--static-z", "standard errors"),
    ("--head-tolerance-arcsec", "arcsec"),
    ("--settle-s", "Seconds"),
    ("--zaber-deg-per-step", "Degrees per microstep"),
];

/// Numeric options without a physical unit (counts, seeds, ratios).
const DIMENSIONLESS: &[&str] = &[
    "--first-node",
    "--head-fault-at", // the N-th move
    "--seed",
    "--samples",
    "--verify-samples",
    "--scale-sd", // relative
    "--coverage", // a multiple of the standard uncertainty
    "--width",
    "--max-terms",
    "--threads",
    "--top",
    "--count",
    "--campaigns",
    "--fleets",
    "--change-at", // a unit's place in the fleet
    "--units",
    "--after", // units
    "--orientations",
    "--rate-factor",
    "--gdb-port",
    "--head-port",
    "--static-window",
    "--runs",
    "--writers",
    "--repeat",
    "--max-connections",
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
