//! Values several commands' settings share, and the station's steps with them: the run a command
//! stores into, how `flash` reaches the MCU, who issues a certificate.

use accelcal_db::RunId;

use crate::cli::{Issuer as IssuerArgs, RunArgs};

/// The database a command stores its piece in (`--db`, as given), the run (`--run-id`, parsed)
/// and the relabel a run begun now stores (`--relabel`, its reason).
#[derive(Clone, Debug, PartialEq)]
pub struct RunStore {
    pub spec: String,
    pub run: Option<RunId>,
    pub relabel: Option<String>,
    /// `--anchor-log`.
    pub anchor_log: Option<std::path::PathBuf>,
}

impl RunStore {
    /// From `--db`, `--run-id` and `--relabel` (`None` without `--db`).
    pub fn of(a: &RunArgs) -> anyhow::Result<Option<RunStore>> {
        let Some(spec) = &a.db else { return Ok(None) };
        let run = a.run_id.as_deref().map(RunId::parse).transpose()?;
        Ok(Some(RunStore {
            spec: spec.clone(),
            run,
            relabel: a.relabel.clone(),
            anchor_log: a.anchor_log.clone(),
        }))
    }

    /// [`RunStore::of`] for a command that stores into a run the database already holds
    /// (`flash --db`, `report --db`): a missing SQLite file is refused ([`existing_db`]).
    pub fn existing(a: &RunArgs, command: &str) -> anyhow::Result<Option<RunStore>> {
        let store = RunStore::of(a)?;
        if let Some(s) = &store {
            existing_db(&s.spec, command)?;
        }
        Ok(store)
    }
}

/// Refuses a SQLite database file that does not exist, for a command that appends to a database
/// that must already hold its run (`void`, `flash --db`, `report --db`): opening it for writing
/// would create an empty one. Checked as the command line is settled, before any I/O; a
/// PostgreSQL server is the server's to answer. (The readers open with `Db::open_existing`,
/// which refuses a missing file itself; `fit`, `verify`, `station` and `asset add` may begin a
/// database.)
pub fn existing_db(spec: &str, command: &str) -> anyhow::Result<()> {
    if let accelcal_db::Target::Sqlite(path) = accelcal_db::Target::parse(spec)? {
        if !path.exists() {
            return Err(accelcal_core::error::bad(format!(
                "{}: no such database: {command} appends to an existing database, it does not create one",
                path.display()
            )));
        }
    }
    Ok(())
}

/// How `flash` reaches the MCU.
#[derive(Clone, Debug, PartialEq)]
pub enum FlashRoute {
    /// A GDB server (QEMU's gdbstub), `HOST:PORT`.
    Gdb(String),
    /// A debug probe: the chip's name, and the probe when several are connected.
    Probe { chip: String, probe: Option<String> },
}

/// Who issues the certificate and for whom (each optional).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Issuer {
    pub laboratory: Option<String>,
    pub laboratory_address: Option<String>,
    pub laboratory_country: Option<String>,
    /// `--ambient-c`: the environment read on the run's thermometer, °C.
    pub ambient_c: Option<f64>,
    pub customer: Option<String>,
    pub customer_address: Option<String>,
    pub received: Option<String>,
    pub place: Option<String>,
    pub authorised_by: Option<String>,
    /// `--interval-days`: the laboratory's decided interval.
    pub interval_days: Option<f64>,
    /// `--min-interval-days`: the floor.
    pub min_interval_days: Option<f64>,
}

impl Issuer {
    /// The recalibration rule a certificate states: the default one, with the floor and the
    /// laboratory's decided interval given.
    pub fn recal_rule(&self) -> accelcal_db::history::RecalRule {
        let mut rule = accelcal_db::history::DEFAULT_RULE;
        if let Some(m) = self.min_interval_days {
            rule.min_interval_days = m;
        }
        rule.decided_interval_days = self.interval_days;
        rule
    }

    /// From `--laboratory`, `--laboratory-address`, `--customer` and `--authorised-by`.
    pub fn of(a: &IssuerArgs) -> Issuer {
        Issuer {
            laboratory: a.laboratory.clone(),
            laboratory_address: a.laboratory_address.clone(),
            laboratory_country: a.laboratory_country.clone(),
            ambient_c: a.ambient_c,
            customer: a.customer.clone(),
            customer_address: a.customer_address.clone(),
            received: a.received.clone(),
            place: a.place.clone(),
            authorised_by: a.authorised_by.clone(),
            interval_days: a.interval_days,
            min_interval_days: a.min_interval_days,
        }
    }
}
