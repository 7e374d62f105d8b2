//! The settings of the commands on the calibration database (`fleet`, `certificate`, `history`,
//! `void`, `db verify`, `serve`, `bench-fleet`): their command line checked and resolved into
//! plain values before anything is opened.

use std::path::PathBuf;

use accelcal_core::error::bad;
use accelcal_db::asset::Date;
use accelcal_db::{RunId, Target};
use anyhow::Context;

use accelcal_db::history::RecalRule;

use crate::cli::{
    BenchFleetArgs, CertificateArgs, DbVerifyArgs, FleetArgs, HistoryArgs, ServeArgs, ServeUserAddArgs,
    VoidArgs,
};
use crate::cmd::store::reader_spec;

/// The period `fleet` and `serve`'s pages show when its start is not given: the 30 days before
/// its end.
pub const DEFAULT_PERIOD: std::time::Duration = std::time::Duration::from_secs(30 * 86_400);

/// The period's first day: `since` when given, else [`DEFAULT_PERIOD`] before `until`; `None`
/// when `until` is too early to count back from.
pub fn period_start(since: Option<Date>, until: Date) -> Option<Date> {
    since.or_else(|| until.checked_sub(DEFAULT_PERIOD).ok())
}

/// `accelcal fleet`, settled.
#[derive(Clone, Debug, PartialEq)]
pub struct Fleet {
    /// `--db` as given (`None`: `ACCELCAL_DB`, else the station's file here).
    pub db: Option<String>,
    /// The period's first day and last day (UTC, both included): `--since` defaults to 30 days
    /// before `--until`, `--until` to today.
    pub since: Date,
    pub until: Date,
    /// The filters given (`--station`, `--head-asset`, `--serial-prefix`, `--operator`).
    pub station: Option<String>,
    pub head_asset: Option<String>,
    pub serial_prefix: Option<String>,
    pub operator: Option<String>,
    /// `--due-days`: the units and assets due up to this many days after the period.
    pub due_days: u32,
    /// `--json`, `--csv`: distinct files, neither of them the database.
    pub json: Option<PathBuf>,
    pub csv: Option<PathBuf>,
}

/// `fleet`'s settings from its command line, `today` the day `--until` defaults to.
pub fn fleet(a: &FleetArgs, today: Date) -> anyhow::Result<Fleet> {
    let until = a.until.unwrap_or(today);
    let since = period_start(a.since, until).context("--until is too early")?;
    if since > until {
        return Err(bad(format!("--since {since} is after --until {until}: the period is empty")));
    }
    if let (Some(j), Some(c)) = (&a.json, &a.csv) {
        if j == c {
            return Err(bad(format!("--json and --csv are the same file {}", j.display())));
        }
    }
    for (what, out) in [("--json", &a.json), ("--csv", &a.csv)] {
        if let Some(out) = out {
            not_the_db(a.reader.db.as_deref(), out, what)?;
        }
    }
    Ok(Fleet {
        db: a.reader.db.clone(),
        since,
        until,
        station: a.station.clone(),
        head_asset: a.head_asset.clone(),
        serial_prefix: a.serial_prefix.clone(),
        operator: a.operator.clone(),
        due_days: a.due_days,
        json: a.json.clone(),
        csv: a.csv.clone(),
    })
}

/// Which certificate: its run, or its number.
#[derive(Clone, Debug, PartialEq)]
pub enum Which {
    /// The run's (a UUID).
    Run(RunId),
    /// The certificate numbered so (`2026-000017`).
    Number(String),
    /// The run whose id begins so (at least 8 hex digits, lower case; the database says which,
    /// or that several do).
    RunPrefix(String),
}

/// `accelcal certificate`, settled.
#[derive(Clone, Debug, PartialEq)]
pub struct Certificate {
    /// `--db` as given.
    pub db: Option<String>,
    /// The certificate printed again.
    pub which: Which,
    /// `--out`: the HTML page; not the database.
    pub out: Option<PathBuf>,
    /// `--pdf`: the PDF; not the database.
    pub pdf: Option<PathBuf>,
    /// `--dcc`: the DCC XML; not the database.
    pub dcc: Option<PathBuf>,
}

/// Whether `s` is written as the beginning of a run id: 8 to 35 of its characters (hex digits
/// and dashes where the UUID has them).
pub(crate) fn is_run_prefix(s: &str) -> bool {
    const DASHES: [usize; 4] = [8, 13, 18, 23];
    (8..36).contains(&s.len())
        && s.char_indices().all(|(i, c)| if DASHES.contains(&i) { c == '-' } else { c.is_ascii_hexdigit() })
}

/// `certificate`'s settings from its command line: a run id or a certificate number
/// (`YYYY-NNNNNN`), and at least one of `--out` and `--pdf`, neither the database.
pub fn certificate(a: &CertificateArgs) -> anyhow::Result<Certificate> {
    let given = a.certificate.as_deref().ok_or_else(|| bad("certificate needs NUMBER|RUN_ID"))?;
    let which = match accelcal_db::certificate::is_number(given) {
        true => Which::Number(given.to_string()),
        false => match RunId::parse(given) {
            Ok(run) => Which::Run(run),
            Err(_) if is_run_prefix(given) => Which::RunPrefix(given.to_ascii_lowercase()),
            Err(e) => {
                return Err(bad(format!(
                    "{given:?} is neither a certificate number (YYYY-NNNNNN, as printed) nor a run id or the \
                     beginning of one (8 or more of its hex digits): {e}"
                )))
            }
        },
    };
    if a.out.is_none() && a.pdf.is_none() && a.dcc.is_none() {
        return Err(bad("certificate needs --out FILE (the HTML page), --pdf FILE or --dcc FILE"));
    }
    let outs = [("--out", &a.out), ("--pdf", &a.pdf), ("--dcc", &a.dcc)];
    for (what, out) in outs {
        if let Some(out) = out {
            not_the_db(a.reader.db.as_deref(), out, what)?;
        }
    }
    for (i, (w1, o1)) in outs.iter().enumerate() {
        for (w2, o2) in &outs[i + 1..] {
            if let (Some(o1), Some(o2)) = (o1, o2) {
                if o1 == o2 {
                    return Err(bad(format!("{w1} and {w2} name the same file, {}", o1.display())));
                }
            }
        }
    }
    Ok(Certificate {
        db: a.reader.db.clone(),
        which,
        out: a.out.clone(),
        pdf: a.pdf.clone(),
        dcc: a.dcc.clone(),
    })
}

/// `accelcal history`, settled.
#[derive(Clone, Debug, PartialEq)]
pub struct History {
    /// `--db` as given.
    pub db: Option<String>,
    /// The unit: its serial or device id, not empty.
    pub unit: String,
    /// When a unit is due again (`--tolerance-m-s2`, `--coverage`, `--max-interval-days`).
    pub rule: RecalRule,
    /// `--json`: not the database.
    pub json: Option<PathBuf>,
}

/// `history`'s settings from its command line.
pub fn history(a: &HistoryArgs) -> anyhow::Result<History> {
    if a.max_interval_days > 36_525.0 {
        return Err(bad(format!(
            "--max-interval-days {} is not an interval: give a positive number of days, at most 36525 (a century)",
            a.max_interval_days
        )));
    }
    if a.min_interval_days > a.max_interval_days {
        return Err(bad(format!(
            "--min-interval-days {} is longer than --max-interval-days {}: the floor is at most the longest interval",
            a.min_interval_days, a.max_interval_days
        )));
    }
    if a.unit.trim().is_empty() {
        return Err(bad("SERIAL|DEVICE is empty"));
    }
    if let Some(j) = &a.json {
        not_the_db(a.db.as_deref(), j, "--json")?;
    }
    Ok(History {
        db: a.db.clone(),
        unit: a.unit.clone(),
        rule: RecalRule {
            tolerance_m_s2: a.tolerance_m_s2,
            coverage: a.coverage,
            max_interval_days: a.max_interval_days,
            min_interval_days: a.min_interval_days,
            decided_interval_days: None,
        },
        json: a.json.clone(),
    })
}

/// `accelcal void`, settled.
#[derive(Clone, Debug, PartialEq)]
pub struct Void {
    /// `--db` as given.
    pub db: Option<String>,
    /// The run voided.
    pub run: RunId,
    /// `--reason`, trimmed, not empty.
    pub reason: String,
    /// `--operator` (`None`: the user's name).
    pub operator: Option<String>,
    /// `--anchor-log`.
    pub anchor_log: Option<PathBuf>,
}

/// `void`'s settings from its command line.
pub fn void(a: &VoidArgs) -> anyhow::Result<Void> {
    let run = RunId::parse(&a.run_id)?;
    let reason = a.reason.trim();
    if reason.is_empty() {
        return Err(bad("--reason is empty: say why the run is voided (it is stored with it)"));
    }
    if let Some(spec) = crate::cmd::store::named_db(a.reader.db.as_deref()) {
        super::values::existing_db(&spec, "void")?;
    }
    Ok(Void {
        db: a.reader.db.clone(),
        run,
        reason: reason.to_string(),
        operator: a.operator.clone(),
        anchor_log: a.anchor_log.clone(),
    })
}

/// `accelcal certificate verify`, settled.
#[derive(Clone, Debug, PartialEq)]
pub struct CertificateVerify {
    /// The PDF or DCC file.
    pub file: PathBuf,
    /// `--db`: the database to check it against, as given.
    pub db: Option<String>,
}

/// `accelcal db verify`, settled.
#[derive(Clone, Debug, PartialEq)]
pub struct DbVerify {
    /// `--db` as given.
    pub db: Option<String>,
    /// `--json`.
    pub json: Option<PathBuf>,
    /// `--anchors`.
    pub anchors: Vec<PathBuf>,
}

/// `db verify`'s settings from its command line.
pub fn db_verify(a: &DbVerifyArgs) -> DbVerify {
    DbVerify { db: a.reader.db.clone(), json: a.json.clone(), anchors: a.anchors.clone() }
}

/// `accelcal serve`, settled.
#[derive(Clone, Debug, PartialEq)]
pub struct Serve {
    /// `--db` as given.
    pub db: Option<String>,
    /// `--bind`: where the server listens (beyond loopback only with `users`).
    pub bind: std::net::SocketAddr,
    /// `--due-days`, as `fleet`'s.
    pub due_days: u32,
    /// `--users`: HTTP Basic authentication against this file of argon2 hashes.
    pub users: Option<PathBuf>,
    /// `--header-timeout-s`: a request's header must be complete this long after the connection
    /// opened or after its previous answer.
    pub header_timeout: std::time::Duration,
    /// `--max-connections`.
    pub max_connections: usize,
}

/// `serve`'s settings from its command line: a bind beyond loopback (`0.0.0.0`, `::`, any
/// address but 127.0.0.0/8 and ::1) needs `--users`.
pub fn serve(a: &ServeArgs) -> anyhow::Result<Serve> {
    if a.users.is_none() && !a.bind.ip().to_canonical().is_loopback() {
        return Err(bad(format!(
            "--bind {} is beyond this machine and the view would have no login: give --users FILE \
             (written by `accelcal serve-user add NAME --file FILE`), or bind 127.0.0.1 behind a reverse proxy",
            a.bind
        )));
    }
    Ok(Serve {
        db: a.reader.db.clone(),
        bind: a.bind,
        due_days: a.due_days,
        users: a.users.clone(),
        header_timeout: std::time::Duration::from_secs(a.header_timeout_s.into()),
        max_connections: a.max_connections as usize,
    })
}

/// `accelcal serve-user add`, settled.
#[derive(Clone, Debug, PartialEq)]
pub struct AddUser {
    /// The user's name (plain text without `:`: [`refused_name`]).
    pub name: String,
    /// `--file`: the users file, written or updated.
    pub file: PathBuf,
    /// `--password-file`: the password is its first line; else it is asked on the terminal.
    pub password_file: Option<PathBuf>,
}

/// `serve-user add`'s settings from its command line.
pub fn add_user(a: &ServeUserAddArgs) -> anyhow::Result<AddUser> {
    if let Some(why) = refused_name(&a.name) {
        return Err(bad(why));
    }
    if a.password_file.as_ref() == Some(&a.file) {
        return Err(bad(format!("--password-file and --file are the same file {}", a.file.display())));
    }
    Ok(AddUser { name: a.name.clone(), file: a.file.clone(), password_file: a.password_file.clone() })
}

/// `accelcal bench-fleet`, settled.
#[derive(Clone, Debug, PartialEq)]
pub struct BenchFleet {
    /// `--db`: the database timed (and filled first when it holds no run).
    pub db: String,
    /// `--units`, `--runs` (at least one run per unit), `--seed`: the line generated.
    pub units: u32,
    pub runs: u32,
    pub seed: u64,
    /// `--month` (`YYYY-MM`) and its first and last days (`YYYY-MM-DD`): the period timed.
    pub month: String,
    pub first_day: String,
    pub last_day: String,
    /// `--writers`: connections that write the line at once.
    pub writers: u32,
    /// `--repeat`: times each command and page is timed.
    pub repeat: u32,
}

/// `bench-fleet`'s settings from its command line.
pub fn bench_fleet(a: &BenchFleetArgs) -> anyhow::Result<BenchFleet> {
    if a.runs < a.units {
        return Err(bad(format!(
            "--runs {} is fewer than --units {}: every unit has a run",
            a.runs, a.units
        )));
    }
    let first = accelcal_db::asset::parse_date(&format!("{}-01", a.month))
        .map_err(|e| bad(format!("--month {}: {e}", a.month)))?;
    Ok(BenchFleet {
        db: a.db.clone(),
        units: a.units,
        runs: a.runs,
        seed: a.seed,
        month: a.month.clone(),
        first_day: first.to_string(),
        last_day: first.last_of_month().to_string(),
        writers: a.writers,
        repeat: a.repeat,
    })
}

/// An output file that would overwrite the database (a SQLite file) is refused.
fn not_the_db(db: Option<&str>, out: &std::path::Path, what: &str) -> anyhow::Result<()> {
    if let Ok(spec) = reader_spec(db) {
        if let Ok(Target::Sqlite(f)) = Target::parse(&spec) {
            if f == out {
                return Err(bad(format!(
                    "{what} {} is the database: refusing to overwrite it",
                    out.display()
                )));
            }
        }
    }
    Ok(())
}

/// Why a user's name (`serve-user add`, a `--users` file) cannot be one: `None` when it can.
/// Here, with the settings, so that the command line is checked before any I/O and `serve`'s
/// users file is read by the same rule.
pub fn refused_name(name: &str) -> Option<String> {
    if name.is_empty() {
        return Some("a user's name cannot be empty".into());
    }
    if let Some(c) = name.chars().find(|&c| {
        c.is_control() || accelcal_core::text::is_format(c) || matches!(c, '\u{2028}' | '\u{2029}')
    }) {
        return Some(format!(
            "the user name {name:?} holds a control or format character (U+{:04X}): a name is plain text",
            u32::from(c)
        ));
    }
    if name.contains(':') {
        return Some(format!(
            "the user name {name:?} holds a `:`, which HTTP Basic authentication cannot send"
        ));
    }
    if name.trim() != name {
        return Some(format!("the user name {name:?} begins or ends with white space"));
    }
    None
}

#[cfg(test)]
mod tests {
    use clap::Parser;

    use super::*;
    use crate::cli::{Cli, Command};

    fn settled(line: &[&str]) -> anyhow::Result<Fleet> {
        let cli = Cli::try_parse_from(line).expect("parses");
        let Command::Fleet(a) = cli.command else { panic!("not fleet") };
        fleet(&a, "2026-12-06".parse().expect("a date"))
    }

    #[test]
    fn fleet_s_period_defaults_to_the_30_days_before_today_and_is_checked() {
        let s = settled(&["accelcal", "fleet", "--db", "x.sqlite"]).expect("settles");
        assert_eq!((s.since.to_string(), s.until.to_string()), ("2026-11-06".into(), "2026-12-06".into()));
        assert_eq!(s.due_days, 30);
        let s =
            settled(&["accelcal", "fleet", "--db", "x.sqlite", "--until", "2026-06-30", "--station", "st-1"])
                .expect("settles");
        assert_eq!((s.since.to_string(), s.station.as_deref()), ("2026-05-31".into(), Some("st-1")));
        let e =
            settled(&["accelcal", "fleet", "--since", "2026-07-01", "--until", "2026-06-30"]).unwrap_err();
        assert_eq!(e.to_string(), "--since 2026-07-01 is after --until 2026-06-30: the period is empty");
    }

    #[test]
    fn fleet_s_outputs_are_distinct_files_and_not_the_database() {
        let e = settled(&["accelcal", "fleet", "--json", "a", "--csv", "a"]).unwrap_err();
        assert_eq!(e.to_string(), "--json and --csv are the same file a");
        let e = settled(&["accelcal", "fleet", "--db", "c.sqlite", "--csv", "c.sqlite"]).unwrap_err();
        assert_eq!(e.to_string(), "--csv c.sqlite is the database: refusing to overwrite it");
    }

    #[test]
    fn bench_fleet_s_month_runs_from_its_first_day_to_its_last() {
        let month = |m: &str| -> anyhow::Result<(String, String)> {
            let cli =
                Cli::try_parse_from(["accelcal", "bench-fleet", "--db", "x", "--month", m]).expect("parses");
            let Command::BenchFleet(a) = cli.command else { panic!("not bench-fleet") };
            bench_fleet(&a).map(|s| (s.first_day, s.last_day))
        };
        assert_eq!(month("2026-06").expect("a month"), ("2026-06-01".into(), "2026-06-30".into()));
        assert_eq!(month("2024-02").expect("a month"), ("2024-02-01".into(), "2024-02-29".into()));
        assert_eq!(month("2026-12").expect("a month"), ("2026-12-01".into(), "2026-12-31".into()));
        assert!(month("2026-13").unwrap_err().to_string().starts_with("--month 2026-13: "));
    }
}
