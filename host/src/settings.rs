//! Settings: the parsed command line checked as a whole before any file is opened.
//!
//! clap checks each option alone (its type, its range of values). What it cannot see is checked
//! here, from the flags and from which options the user really gave (clap's value source, so that
//! a default never counts as given):
//! - an option that does not apply to the chosen mode is refused, naming the option and the mode
//!   it belongs to (`fit --method gravity-norm --terms ax,ay` would otherwise fit what it
//!   always fits and say nothing);
//! - an output path equal to an input path, or to another output, is refused (`fit c.csv --record
//!   c.csv` would overwrite the campaign).
//!
//! - a value that is not one line of text (a control character, a line separator:
//!   [`accelcal_core::text::single_line`]) is refused, whatever the option ([`check_text`]): the
//!   values end up in files (a campaign's header, the station's journal of command lines, the
//!   certificate) and in the database, and one would otherwise add lines of its own there.
//!
//! Every error here is bad input (exit code 2) and names the option.

use std::path::{Path, PathBuf};

use accelcal_core::error::bad;
use clap::parser::ValueSource;
use clap::ArgMatches;

use crate::cli::{Algorithm, Command, CriterionArg, FitArgs, MethodArg, RecordCommand};

pub mod asset;
pub mod campaign;
pub mod gravity;
pub mod line;
pub mod reader;
pub mod release;
pub mod settled;
pub mod station;
mod station_config;
pub mod values;

pub use station_config::apply as apply_config;

/// The options the user gave for one subcommand: explicitly on the command line, or (`station
/// --config`) in its settings file.
pub struct Given<'a> {
    matches: &'a ArgMatches,
    /// The options the settings file gave: clap id, the file's key, and `FILE:LINE:COL`.
    config: Vec<(&'static str, String, String)>,
}

impl<'a> Given<'a> {
    /// The given options of the subcommand in `matches` (the top-level matches).
    pub fn of(matches: &'a ArgMatches) -> Option<Given<'a>> {
        matches.subcommand().map(|(_, sub)| Given { matches: sub, config: Vec::new() })
    }

    /// Whether the option with clap id `id` (the field name) was given on the command line.
    fn on_command_line(&self, id: &str) -> bool {
        matches!(self.matches.try_get_raw(id), Ok(Some(_)))
            && self.matches.value_source(id) == Some(ValueSource::CommandLine)
    }

    /// Whether the option with clap id `id` was given, on the command line or in the settings
    /// file.
    fn has(&self, id: &str) -> bool {
        self.on_command_line(id) || self.config.iter().any(|(k, _, _)| *k == id)
    }

    /// How a message names the option `id`: its flag, or the settings file's key and line when
    /// the value came from there.
    fn name(&self, id: &str) -> String {
        match self.config.iter().find(|(k, _, _)| *k == id) {
            Some((_, key, at)) if !self.on_command_line(id) => format!("`{key}` ({at})"),
            _ => flag(id),
        }
    }

    /// How a message names the option `id` set to `value`: `--head manual`, or `head =
    /// "manual"` and the settings file's line.
    fn setting(&self, id: &str, value: &str) -> String {
        match self.config.iter().find(|(k, _, _)| *k == id) {
            Some((_, key, at)) if !self.on_command_line(id) => format!("`{key} = {value:?}` ({at})"),
            _ => format!("{} {value}", flag(id)),
        }
    }

    /// Refuses each of `ids` that was given: it does not apply to `mode`.
    fn refuse(&self, ids: &[&str], mode: &str, hint: &str) -> anyhow::Result<()> {
        for id in ids {
            if self.has(id) {
                return Err(bad(format!("{} does not apply to {mode}{hint}", self.name(id))));
            }
        }
        Ok(())
    }
}

/// Refuses a value of the command line that is not one line of text
/// ([`accelcal_core::text::single_line`]), naming its option (or, for an argument, its value
/// name) and showing it escaped; a `--serial`, which a campaign's `# serial:` line holds, must also
/// read back from there as given ([`accelcal_core::text::header_value`]: no white space at
/// either end).
///
/// Every option of every command is checked, not only those known to reach a file or the
/// database today: the station journals each step's whole command line, and a value that is
/// refused costs nothing while one let through can forge a header line. This is done here and
/// not by clap value parsers because clap's message for a refused value prints the value raw
/// (its line feeds and escape sequences reach the terminal) over several lines, where the rule
/// is one line and exit code 2.
pub fn check_text(matches: &ArgMatches, command: &Command) -> anyhow::Result<()> {
    use accelcal_core::text::{header_value, single_line};
    use clap::CommandFactory;
    let root = crate::cli::Cli::command();
    let (mut cmd, mut m) = (&root, matches);
    while let Some((name, sub)) = m.subcommand() {
        let Some(c) = cmd.find_subcommand(name) else { break };
        (cmd, m) = (c, sub);
        for arg in cmd.get_arguments() {
            let Ok(Some(values)) = m.try_get_raw(arg.get_id().as_str()) else { continue };
            let field = match (arg.get_long(), arg.get_value_names().and_then(|v| v.first())) {
                (Some(long), _) => format!("--{long}"),
                (None, Some(name)) => name.to_string(),
                (None, None) => arg.get_id().to_string(),
            };
            for v in values {
                single_line(&field, &v.to_string_lossy())?;
            }
        }
    }
    let serials: &[String] = match command {
        Command::Simulate(a) => a.serial.as_slice(),
        Command::Acquire(a) => &a.serial,
        Command::Station(a) => &a.serials,
        _ => &[],
    };
    for s in serials {
        header_value("--serial", s)?;
    }
    if let Command::Station(a) = command {
        if let Some(s) = &a.check_standard {
            header_value("--check-standard", s)?;
        }
    }
    Ok(())
}

/// `--run-id` goes with `--db`; `flash` and `report` store into an existing run, so they need it;
/// `fit --method gravity-norm` writes no record and no campaign fit.
fn check_run(command: &Command, given: &Given) -> anyhow::Result<()> {
    let (run, name) = match command {
        Command::Fit(a) => (&a.run, "fit"),
        Command::Verify(a) => (&a.run, "verify"),
        Command::Flash(a) => (&a.run, "flash"),
        Command::Report(a) => (&a.run, "report"),
        _ => return Ok(()),
    };
    if run.db.is_none() {
        given.refuse(&["relabel"], "a command without --db", " (it is stored with the run begun)")?;
        given.refuse(
            &["head_asset"],
            "a command without --db",
            " (the asset is read from the database's register; without one, give --head-angle-u and --head-orthogonality-u)",
        )?;
        given.refuse(
            &["gravity_asset"],
            "a command without --db",
            " (the survey is read from the database's register; without one, give --g and --g-u)",
        )?;
        return given.refuse(&["run_id"], "a command without --db", " (it names the run stored into)");
    }
    if let Command::Flash(_) | Command::Report(_) = command {
        given.refuse(
            &["relabel"],
            name,
            " (it begins no run: relabel where the run begins, `fit --db`, `verify --db` or `station`)",
        )?;
    }
    if let Some(id) = &run.run_id {
        accelcal_db::RunId::parse(id)?;
    }
    match command {
        Command::Fit(a) if a.method == crate::cli::MethodArg::GravityNorm => given.refuse(
            &["db"],
            "fit --method gravity-norm",
            " (it stores the campaign's lsq or test-turns fit)",
        ),
        Command::Flash(a) if a.cut_after.is_some() => {
            given.refuse(&["db"], "flash --cut-after", " (a fault injection writes no record to keep)")
        }
        Command::Flash(_) | Command::Report(_) if run.run_id.is_none() => Err(bad(format!(
            "{name} --db needs --run-id: the run whose record it writes (begun by `fit --db` or `station`)"
        ))),
        _ => Ok(()),
    }
}

/// The long flag of a clap id (`device_id` -> `--device-id`).
fn flag(id: &str) -> String {
    format!("--{}", id.replace('_', "-"))
}

/// Checks a parsed command line before anything is read or written.
pub fn check(command: &Command, given: &Given) -> anyhow::Result<()> {
    check_run(command, given)?;
    match command {
        Command::Fit(a) => check_fit(a, given),
        Command::Select(a) => {
            if a.algorithm != Algorithm::Multi {
                given.refuse(
                    &["width"],
                    "select --algorithm combi",
                    " (it sets the beam of --algorithm multi)",
                )?;
            }
            if a.criterion == CriterionArg::Loo {
                given.refuse(
                    &["split"],
                    "select --criterion loo",
                    " (leave-one-out fits on all the positions but one: there is no split)",
                )?;
            }
            if a.thermal.t_ref.is_some() && !accelcal_shared::Basis::from(a.basis).is_thermal() {
                return Err(bad(
                    "--t-ref does not apply to a --basis without terms in t (it applies to linear-thermal and quadratic-thermal)",
                ));
            }
            if a.common.json.is_none() {
                given.refuse(
                    &["top"],
                    "select without --json",
                    " (it limits the candidates listed in the JSON)",
                )?;
            }
            distinct(
                &[("CAMPAIGN", &a.campaign)],
                &[("--json", a.common.json.as_deref()), ("--plot", a.plot.as_deref())],
            )
        }
        Command::Compare(a) => {
            let mut inputs = vec![("CAMPAIGN", a.campaign.as_path())];
            if let Some(v) = &a.validate {
                inputs.push(("--validate", v));
            }
            distinct(&inputs, &[("--json", a.common.json.as_deref()), ("--plot", a.plot.as_deref())])
        }
        Command::Diagnose(a) => distinct(
            &[("CAMPAIGN", &a.campaign)],
            &[("--json", a.common.json.as_deref()), ("--plot", a.plot.as_deref())],
        ),
        Command::Simulate(a) => {
            if a.chamber.is_empty() {
                given.refuse(
                    &["soak_s", "thermal_lag_s"],
                    "simulate without --chamber",
                    " (they shape a thermal campaign)",
                )?;
            }
            distinct(
                &[],
                &[("--out", Some(&a.out)), ("--truth", a.truth.as_deref()), ("--json", a.json.as_deref())],
            )
        }
        Command::Hil(a) => distinct(
            &[("CAMPAIGN", &a.campaign), ("--record", &a.record), ("--qemu", &a.elf)],
            &[("--out", Some(&a.out))],
        ),
        Command::Record(RecordCommand::Show(a)) => {
            distinct(&[("FILE", &a.file)], &[("--json", a.json.as_deref())])
        }
        Command::Acquire(a) => {
            let ports = a.port.len();
            once_each("--out", a.out.len(), ports, "--port", false)?;
            once_each("--serial", a.serial.len(), ports, "--port", true)?;
            if let Some((i, p)) = a.port.iter().enumerate().find(|(i, p)| a.port[..*i].contains(p)) {
                return Err(bad(format!(
                    "--port {p} is given twice (ports {} and {})",
                    a.port.iter().position(|q| q == p).unwrap() + 1,
                    i + 1
                )));
            }
            let outs: Vec<(&str, Option<&Path>)> =
                a.out.iter().map(|o| ("--out", Some(o.as_path()))).collect();
            distinct(&[], &outs)?;
            if let Some(out) = a.out.iter().find(|o| !a.resume && o.exists()) {
                return Err(bad(format!(
                    "--out {} exists: continue it with --resume, or choose another file",
                    out.display()
                )));
            }
            refuse_head_timeout(given, &a.head)?;
            check_zaber(given, &a.head.to_string(), &a.zaber, "--head")
        }
        Command::Info(a) => distinct(&[], &[("--json", a.json.as_deref())]),
        Command::Verify(a) => {
            if a.tolerance.is_some() {
                given.refuse(
                    &["fit", "coverage"],
                    "verify --tolerance",
                    " (it derives the tolerance; --tolerance sets it)",
                )?;
            }
            refuse_head_timeout(given, &a.head)?;
            check_zaber(given, &a.head.to_string(), &a.zaber, "--head")?;
            let fit: Vec<(&str, &Path)> = a.fit.iter().map(|p| ("--fit", p.as_path())).collect();
            distinct(&fit, &[("--json", a.json.as_deref())])
        }
        Command::Emulate(a) => {
            match (a.head_fault, a.head_fault_at) {
                (Some(_), None) => {
                    return Err(bad("--head-fault needs --head-fault-at N: the move it strikes"))
                }
                (None, Some(_)) => {
                    return Err(bad("--head-fault-at needs --head-fault KIND: the fault it injects"))
                }
                (Some(k), Some(_))
                    if a.head_dialect == crate::cli::HeadDialectArg::Sim && !k.applies_to_sim() =>
                {
                    return Err(bad(format!(
                        "--head-fault {k} does not apply to --head sim (its line protocol has no motor \
                         warnings; it takes reject, silent and off=ARCSEC; --head zaber takes them all)"
                    )))
                }
                _ => {}
            }
            if a.head_dialect == crate::cli::HeadDialectArg::ZaberPty {
                given.refuse(
                    &["head_port"],
                    "--head zaber-pty",
                    " (its head is a pseudo-terminal, not a TCP port)",
                )?;
            }
            let units = a.unit.len();
            once_each("--seed", a.seed.len(), units, "--unit", true)?;
            once_each("--record", a.record.len(), units, "--unit", true)
        }
        Command::Report(a) => {
            if let Some(g) = a.g {
                crate::resolved::check_g(g)?;
            }
            check_issuer(&a.issuer)?;
            if a.issuer.ambient_c.is_some() && a.run.db.is_none() {
                return Err(bad(
                    "--ambient-c needs --db and --run-id: the thermometer it was read on is the run's, read from the \
                     register",
                ));
            }
            if a.issuer.authorised_by.is_some() && a.run.db.is_some() {
                return Err(bad(format!("--authorised-by does not apply with --db: {AWAITS_APPROVAL}")));
            }
            let mut inputs = vec![
                ("--campaign", a.campaign.as_path()),
                ("--record", a.record.as_path()),
                ("--fit", a.fit.as_path()),
            ];
            if let Some(v) = &a.verify {
                inputs.push(("--verify", v));
            }
            distinct(&inputs, &[("--out", Some(&a.out))])
        }
        Command::Flash(a) => {
            if a.gdb.is_some() {
                given.refuse(&["chip", "probe"], "flash --gdb", " (they select a probe-rs probe)")?;
            } else {
                given.refuse(
                    &["cut_after"],
                    "flash without --gdb",
                    " (it cuts a write through a GDB server)",
                )?;
            }
            if a.port.is_none() {
                given.refuse(&["baud"], "flash without --port", "")?;
            }
            Ok(())
        }
        Command::Station(a) => {
            if let Some(head) = &a.head {
                check_zaber(given, head, &a.zaber, &given.setting("head", head))?;
            }
            if a.head.as_deref() == Some("manual") {
                let head = given.setting("head", "manual");
                given.refuse(
                    &["head_timeout_s", "head_tolerance_arcsec"],
                    &head,
                    " (the operator turns the head, and their word is the read-back)",
                )?;
            }
            if !a.gdb.is_empty() {
                let gdb = if given.on_command_line("gdb") {
                    "station --gdb".to_string()
                } else {
                    given.name("gdb")
                };
                given.refuse(&["chip", "probe"], &gdb, " (they select a probe-rs probe)")?;
            }
            let n = a.ports.len();
            // The nodes come from --port, or from the settings file's [[node]] tables.
            let port = if given.on_command_line("ports") { "--port" } else { "[[node]]" };
            if let Some(s) = &a.check_standard {
                let hint = " (the check standard is the unit, with the record in force)";
                if given.has("serials") {
                    return Err(bad(format!("--serial does not apply to station --check-standard{hint}")));
                }
                given.refuse(&["relabel"], "station --check-standard", hint)?;
                if n != 1 {
                    return Err(bad(format!(
                        "station --check-standard {s} checks one unit: give one {port}, not {n}"
                    )));
                }
            }
            if a.check_standard.is_none() {
                once_each("--serial", a.serials.len(), n, port, false)?;
            }
            once_each("--out", a.outs.len(), n, port, false)?;
            once_each("--gdb", a.gdb.len(), n, port, true)?;
            if n > 1 || a.probe.len() > 1 {
                once_each("--probe", a.probe.len(), n, port, true)?;
            }
            // A settings file's serials come after `check_text`: checked here as the command
            // line's are there.
            for s in &a.serials {
                accelcal_core::text::header_value("--serial", s)?;
                if s.is_empty() {
                    return Err(bad("--serial must not be empty"));
                }
            }
            let dup = |v: Vec<String>, option: &str| -> anyhow::Result<()> {
                let mut sorted = v.clone();
                sorted.sort();
                match sorted.windows(2).find(|w| w[0] == w[1]) {
                    Some(w) => Err(bad(format!("{option} {} is given twice: one unit per node", w[0]))),
                    None => Ok(()),
                }
            };
            dup(a.ports.clone(), "--port")?;
            dup(a.serials.clone(), "--serial")?;
            dup(a.outs.iter().map(|p| resolve(p).display().to_string()).collect(), "--out")?;
            if a.coverage.is_some() && a.spec.is_some() {
                return Err(bad(format!(
                    "{} and {} do not go together: the specification's decision rule decides, not a coverage factor",
                    given.name("coverage"),
                    given.name("spec")
                )));
            }
            check_issuer(&a.issuer)?;
            match (a.thermometer_asset.is_some(), a.issuer.ambient_c.is_some()) {
                (true, false) => {
                    return Err(bad(format!(
                        "{} needs --ambient-c: the certificate states the environment's temperature as read on it",
                        given.name("thermometer_asset")
                    )))
                }
                (false, true) => {
                    return Err(bad(
                        "--ambient-c needs --thermometer-asset: a reading is traceable through the registered \
                         thermometer it was read on",
                    ))
                }
                _ => {}
            }
            if a.issuer.authorised_by.is_some() {
                return Err(bad(format!(
                    "{} does not apply to the station, which stores every run in a database: {AWAITS_APPROVAL}",
                    given.name("authorised_by")
                )));
            }
            if let Some(out) = a.outs.iter().find(|o| o.is_file()) {
                return Err(bad(format!(
                    "--out {} is a file: the station needs a directory for the unit",
                    out.display()
                )));
            }
            Ok(())
        }
        // Their numbers are checked by their value parsers (`cli::range`).
        Command::Output(_) | Command::Monitor(_) => Ok(()),
        Command::BenchDiagnose(_)
        | Command::BenchSignature(_)
        | Command::UncertaintyCheck(_)
        | Command::Demo(_) => Ok(()),
        Command::Db(_) => Ok(()),
        // Checked as they are settled (`settled::settle`).
        Command::Fleet(_)
        | Command::Certificate(_)
        | Command::History(_)
        | Command::Void(_)
        | Command::Asset(_)
        | Command::Affected(_)
        | Command::Serve(_)
        | Command::ServeUser(_)
        | Command::Signer(_)
        | Command::Approve(_)
        | Command::Reject(_)
        | Command::Amend(_)
        | Command::BenchFleet(_)
        | Command::Plan(_) => Ok(()),
    }
}

/// An option given per node (`--out` per `--port`, `--seed` per `--unit`, `--serial` per
/// `[[node]]`): `given` times for `n` of `per` must be once each (in the same order), or, when
/// `optional`, not at all.
fn once_each(option: &str, given: usize, n: usize, per: &str, optional: bool) -> anyhow::Result<()> {
    if given == n || (optional && given == 0) {
        return Ok(());
    }
    let or_not = if optional { " (or not at all)" } else { "" };
    Err(bad(format!("{n} {per}, {given} {option}: give {option} once per {per}, in the same order{or_not}")))
}

/// `--head-timeout-s` is for an emulated head only.
fn refuse_head_timeout(given: &Given, head: &accelcal_line::head::HeadSpec) -> anyhow::Result<()> {
    if *head == accelcal_line::head::HeadSpec::Manual {
        given.refuse(
            &["head_timeout_s", "head_tolerance_arcsec"],
            "--head manual",
            " (the operator turns the head, and their word is the read-back)",
        )?;
    }
    Ok(())
}

/// A Zaber head's options apply to `--head zaber:…` only (`head` names the head for the
/// message), and its two axes must differ.
fn check_zaber(given: &Given, head: &str, z: &crate::cli::ZaberArgs, named: &str) -> anyhow::Result<()> {
    if !head.starts_with("zaber:") {
        let named = if named == "--head" { format!("--head {head}") } else { named.to_string() };
        return given.refuse(
            &crate::cli::ZaberArgs::IDS,
            &named,
            " (they set a Zaber head's axes and scale)",
        );
    }
    z.axes().check().map_err(|e| bad(format!("--zaber-alpha/--zaber-beta: {e}")))
}

/// Why a stated authoriser is refused with a database.
const AWAITS_APPROVAL: &str =
    "there a certificate awaits approval by a registered signer's key (`accelcal signer add`, \
     `accelcal approve`), and a name typed in the settings authorises nothing";

/// `--laboratory-address` and `--laboratory-country` go with `--laboratory`; a country is
/// ISO 3166-1's two capital letters.
fn check_issuer(i: &crate::cli::Issuer) -> anyhow::Result<()> {
    if i.laboratory_address.is_some() && i.laboratory.is_none() {
        return Err(bad("--laboratory-address needs --laboratory (the address is printed after its name)"));
    }
    if let Some(t) = i.ambient_c {
        if !(t.is_finite() && (-50.0..=100.0).contains(&t)) {
            return Err(bad(format!("--ambient-c must be from -50 to 100 °C, got {t}")));
        }
    }
    if let Some(c) = &i.laboratory_country {
        if i.laboratory.is_none() {
            return Err(bad("--laboratory-country needs --laboratory (it is the laboratory's country)"));
        }
        if !(c.len() == 2 && c.bytes().all(|b| b.is_ascii_uppercase())) {
            return Err(bad(format!(
                "--laboratory-country {c:?} is not an ISO 3166-1 alpha-2 code (two capital letters, e.g. DE)"
            )));
        }
    }
    if i.customer_address.is_some() && i.customer.is_none() {
        return Err(bad("--customer-address needs --customer (the address is printed after its name)"));
    }
    if let Some(d) = &i.received {
        accelcal_db::asset::parse_date(d)
            .map_err(|e| bad(format!("--received {d:?}: {e} (the day the item was received, YYYY-MM-DD)")))?;
    }
    Ok(())
}

/// The options of `fit` that state the budget's references: the head's uncertainties, the unit
/// type's temperature coefficients (lsq, model 4).
const HEAD_U: [&str; 6] = [
    "head_angle_u",
    "head_orthogonality_u",
    "head_asset",
    "bias_tempco_u",
    "scale_tempco_u",
    "thermometer_u",
];

/// The options of `fit` that belong to one method only.
const GRAVITY_ONLY: [&str; 7] =
    ["format", "plot", "min_hold_s", "threshold", "window_s", "structure", "campaign_out"];

fn check_fit(a: &FitArgs, given: &Given) -> anyhow::Result<()> {
    match a.method {
        MethodArg::GravityNorm => {
            given.refuse(
                &["terms"],
                "fit --method gravity-norm",
                " (it applies to --method lsq and test-turns, which fit a campaign; gravity-norm picks --structure)",
            )?;
            given.refuse(
                &HEAD_U,
                "fit --method gravity-norm",
                " (it enters the uncertainty budget of an lsq fit of model 4)",
            )?
        }
        MethodArg::TestTurns => {
            given.refuse(
                &HEAD_U,
                "fit --method test-turns",
                " (it enters the uncertainty budget of an lsq fit of model 4)",
            )?;
            given.refuse(
                &GRAVITY_ONLY,
                "fit --method test-turns",
                " (it applies to --method gravity-norm)",
            )?;
        }
        MethodArg::Lsq => {
            if accelcal_core::lsq::parse_terms(&a.terms).is_ok_and(|s| s != accelcal_shared::terms::MODEL_4) {
                given.refuse(
                    &HEAD_U,
                    &format!("fit --terms {}", a.terms),
                    " (the uncertainty budget is made for model 4, --terms ax,ay,az)",
                )?;
            }
            given.refuse(&GRAVITY_ONLY, "fit --method lsq", " (it applies to --method gravity-norm)")?;
        }
    }
    if a.thermal.t_ref.is_some() {
        if a.method == MethodArg::GravityNorm {
            return Err(bad(
                "--t-ref does not apply to fit --method gravity-norm (its model has no terms in t)",
            ));
        }
        // An unparsable --terms is reported where it is parsed.
        if accelcal_core::lsq::parse_terms(&a.terms).is_ok_and(|s| !s.is_thermal()) {
            return Err(bad(format!(
                "--t-ref does not apply to --terms {}: it is the reference of the terms in t (t, t^2, ax*t, ...), and the model has none",
                a.terms
            )));
        }
    }
    if a.record.is_none() {
        given.refuse(
            &["device_id", "created"],
            "fit without --record",
            " (it is written into the record)",
        )?;
    } else if a.device_id.is_none() && a.method == MethodArg::GravityNorm {
        // A campaign's `# device_id:` line gives it otherwise (checked once the file is read).
        return Err(bad(
            "fit --record needs --device-id HEX, the MCU's 96-bit unique id: a node accepts only a record made for it",
        ));
    }
    distinct(
        &[("CAMPAIGN", &a.campaign)],
        &[
            ("--json", a.common.json.as_deref()),
            ("--record", a.record.as_deref()),
            ("--campaign-out", a.gravity.campaign_out.as_deref()),
            ("--plot", a.gravity.plot.as_deref()),
        ],
    )
}

/// Refuses an output that is an input, or two outputs that are the same path.
fn distinct(inputs: &[(&str, &Path)], outputs: &[(&str, Option<&Path>)]) -> anyhow::Result<()> {
    let outs: Vec<(&str, PathBuf)> =
        outputs.iter().filter_map(|(n, p)| p.map(|p| (*n, resolve(p)))).collect();
    for (on, op) in &outs {
        for (inn, ip) in inputs {
            if *op == resolve(ip) {
                return Err(bad(format!(
                    "{on} {} is the input {inn}: refusing to overwrite it",
                    ip.display()
                )));
            }
        }
    }
    for (i, (an, ap)) in outs.iter().enumerate() {
        if let Some((bn, _)) = outs[i + 1..].iter().find(|(_, bp)| bp == ap) {
            return Err(bad(format!("{an} and {bn} name the same path {}", ap.display())));
        }
    }
    Ok(())
}

/// A path made absolute and resolved as far as it exists (symbolic links, `..`), so that two
/// spellings of one file compare equal; no file is opened.
fn resolve(p: &Path) -> PathBuf {
    if let Ok(c) = p.canonicalize() {
        return c;
    }
    let abs = std::path::absolute(p).unwrap_or_else(|_| p.to_path_buf());
    match (abs.parent().and_then(|d| d.canonicalize().ok()), abs.file_name()) {
        (Some(dir), Some(name)) => dir.join(name),
        _ => abs,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn two_spellings_of_one_file_are_the_same_output() {
        let d = tempfile::tempdir().unwrap();
        let c = d.path().join("c.csv");
        std::fs::write(&c, "x").unwrap();
        let other = d.path().join("sub/../c.csv");
        std::fs::create_dir(d.path().join("sub")).unwrap();
        let e = distinct(&[("CAMPAIGN", &c)], &[("--json", Some(&other))]).unwrap_err();
        assert!(e.to_string().contains("--json") && e.to_string().contains("refusing to overwrite"), "{e}");
        let new = d.path().join("new.json");
        assert!(distinct(
            &[("CAMPAIGN", &c)],
            &[("--json", Some(&new)), ("--record", Some(&d.path().join("r.rec")))]
        )
        .is_ok());
        let e = distinct(&[], &[("--json", Some(&new)), ("--record", Some(&new))]).unwrap_err();
        assert!(e.to_string().contains("--json and --record name the same path"), "{e}");
    }

    #[test]
    fn flags_are_spelled_as_on_the_command_line() {
        assert_eq!(flag("device_id"), "--device-id");
        assert_eq!(flag("plot"), "--plot");
    }
}
