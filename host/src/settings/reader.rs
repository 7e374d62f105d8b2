//! The settings of the commands that read the calibration database for the line (`fleet`,
//! `certificate`): their command line checked and resolved into plain values before anything is
//! opened. The commands take these values, never clap's structs (issue 29's `Settings`, for
//! these commands so far).

use std::path::PathBuf;

use accelcal_core::error::bad;
use accelcal_db::asset::{today_utc, Date};
use accelcal_db::{RunId, Target};
use anyhow::Context;

use crate::cli::{CertificateArgs, FleetArgs};
use crate::cmd::store::reader_spec;

/// The period `fleet` shows when `--since` is not given: the 30 days before `--until`.
const THIRTY_DAYS: std::time::Duration = std::time::Duration::from_secs(30 * 86_400);

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
    let since = match a.since {
        Some(s) => s,
        None => until.checked_sub(THIRTY_DAYS).context("--until is too early")?,
    };
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

/// `accelcal certificate`, settled.
#[derive(Clone, Debug, PartialEq)]
pub struct Certificate {
    /// `--db` as given.
    pub db: Option<String>,
    /// The run whose certificate is printed again.
    pub run: RunId,
    /// `--out`: not the database.
    pub out: PathBuf,
}

/// `certificate`'s settings from its command line.
pub fn certificate(a: &CertificateArgs) -> anyhow::Result<Certificate> {
    let run = RunId::parse(&a.run_id)?;
    not_the_db(a.reader.db.as_deref(), &a.out, "--out")?;
    Ok(Certificate { db: a.reader.db.clone(), run, out: a.out.clone() })
}

/// The day `fleet`'s `--until` defaults to: today, UTC.
pub fn today() -> Date {
    today_utc()
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
}
