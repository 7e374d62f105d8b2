//! `station --check-standard SERIAL`: the station checked with a known unit (its as-found
//! verification against the record in force, nothing recalibrated), the check put on the
//! station's chart ([`accelcal_db::check`]), and production refused while the latest check is out
//! of control.

use accelcal_db::check::{check_charts, judge, mean_errors, why_out_of_control, CheckRun, Judgement};

use super::*;

/// Refuses production on `station` while its latest check is out of control (exit code 3); a
/// station without checks, or without a database yet, is not refused.
pub(super) fn refuse_out_of_control(db_spec: &str, station: &str) -> anyhow::Result<()> {
    let mut db = match Db::open_existing(db_spec) {
        Err(DbError::NoDatabase { .. } | DbError::NotCreated { .. }) => return Ok(()),
        r => r?,
    };
    let checks = db.check_runs(station)?;
    let Some(last) = checks.last() else { return Ok(()) };
    if last.outcome.as_deref() != Some("rejected") {
        return Ok(());
    }
    Err(StationError::OutOfControl {
        station: station.to_string(),
        serial: last.serial.clone(),
        why: format!("run {}: {}", last.run_id, why_out_of_control(&last.reason)),
    }
    .into())
}

impl Station<'_> {
    /// The check: info, the as-found verification (stored), then the run ended in control
    /// (`pass`) or out of control (`rejected`, exit code 3), its reason saying which rule broke
    /// at which check.
    pub(super) fn check_standard(&mut self, station: &str) -> anyhow::Result<()> {
        let serial = self.u.serial.clone();
        let info = self.info()?;
        if self.ended {
            outln!(
                "station: check standard {serial}: finished before (run {} in {}); nothing to do",
                self.run_id()?,
                self.db.target()
            )?;
            return Ok(());
        }
        if info.record.is_none() {
            return Err(bad(format!(
                "the check standard {serial} has no record in force: calibrate it with a production run first"
            )));
        }
        self.as_found(&info)?;
        let run = self.run_id()?;
        let report = VerifyReport::read(&self.path(AS_FOUND))?;
        let mean = mean_errors(&report);
        let mut checks = self.db.check_runs(station)?;
        checks.retain(|c| c.run_id != run.to_string());
        checks.push(CheckRun {
            run_id: run.to_string(),
            serial: serial.clone(),
            started_unix_s: self.journal.started_unix_s.unwrap_or_default(),
            outcome: None,
            reason: String::new(),
            mean_error_m_s2: mean,
        });
        let n = checks.len();
        let judgement = judge(&check_charts(&checks));
        let values = mean
            .map(|m| format!("mean error x {:+.5}, y {:+.5}, z {:+.5} m/s²", m[0], m[1], m[2]))
            .unwrap_or_else(|| "no position measured".into());
        let outcome =
            if let Judgement::OutOfControl(_) = judgement { Outcome::Rejected } else { Outcome::Pass };
        self.db.finish_run(run, outcome, &judgement.reason(n))?;
        crash_point("db:end");
        if let Judgement::OutOfControl(why) = judgement {
            outln!("station: check standard {serial} on {station}: OUT OF CONTROL ({values})")?;
            return Err(StationError::OutOfControl {
                station: station.to_string(),
                serial,
                why: format!("run {run}: {why}"),
            }
            .into());
        }
        let state = judgement.words(n);
        outln!(
            "station: check standard {serial} on {station}: {state} ({values}); run {run} in {}",
            self.db.target()
        )?;
        Ok(())
    }
}
