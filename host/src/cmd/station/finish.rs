//! The end of a unit's line: the steps after the campaign, and a unit that passed run again.

use super::*;

impl Station<'_> {
    /// The unit's steps after the campaign; its run ends `pass`.
    pub(super) fn after_acquire(&mut self) -> anyhow::Result<()> {
        self.prepare()?;
        self.conclude()
    }

    /// The steps after the campaign that do not use the head: select, fit, flash.
    pub(super) fn prepare(&mut self) -> anyhow::Result<()> {
        self.select()?;
        self.fit()?;
        self.flash()
    }

    /// The as-left verification (on the head), the certificate, and the run's end `pass`.
    pub(super) fn conclude(&mut self) -> anyhow::Result<()> {
        self.as_left()?;
        self.certificate()?;
        let run = self.run_id()?;
        self.db.finish_run(run, Outcome::Pass, PASS_REASON)?;
        crash_point("db:end");
        outln!(
            "station: unit {} (device {}) PASS{}; certificate {}; journal {}; run {run} stored in {}{}",
            self.u.serial,
            self.journal.device_id.as_deref().unwrap_or("?"),
            self.as_found_words()?,
            self.p(CERTIFICATE),
            self.p(JOURNAL),
            self.db.target(),
            self.transit_words()?
        )?;
        Ok(())
    }

    /// What the station's last line says of the sets the campaign lost in transit (the acquire
    /// step's lines say each position's): `; 12,043 of 124,000 sample sets lost in transit; every
    /// position kept at least 400`. Nothing when the campaign states no rate to count them by.
    fn transit_words(&self) -> anyhow::Result<String> {
        let transit = accelcal_core::campaign::transit::Transit::of_file(&self.path(CAMPAIGN))
            .with_context(|| self.p(CAMPAIGN))?;
        Ok(transit.map(|t| format!("; {}", t.words())).unwrap_or_default())
    }

    /// What the station's last line says of the as-found result when it did not pass: out of
    /// tolerance (a conditional fail or a fail under the specification), not shown to conform
    /// (a conditional pass), or failed against the consistency bound (no specification).
    fn as_found_words(&self) -> anyhow::Result<String> {
        if !self.path(AS_FOUND).is_file() {
            return Ok(String::new());
        }
        let v = VerifyReport::read(&self.path(AS_FOUND))?;
        let failed = v.positions.iter().filter(|p| !p.pass).count();
        // The parameters the rule did not accept, after the positions.
        let params = v
            .failure()
            .filter(|f| !f.parameters.is_empty())
            .map(|f| format!("; {}", f.parameters.join(", ")))
            .unwrap_or_default();
        Ok(match v.decision {
            Some(d) if d.out_of_tolerance() => format!(
                " as left, but AS FOUND OUT OF TOLERANCE ({}: {failed} of {} positions not accepted{params})",
                d.name(),
                v.positions.len()
            ),
            Some(d) if !d.accepted() => format!(
                " as left; as found a {} ({failed} of {} positions within the limit but not by the guard band{params})",
                d.name().to_uppercase(),
                v.positions.len()
            ),
            None if failed > 0 => format!(
                " as left; as found FAIL {failed}/{} against the consistency bound (no --spec: not a tolerance decision)",
                v.positions.len()
            ),
            _ => String::new(),
        })
    }

    /// A unit that passed, run again: its files must still be as the steps wrote them, and the
    /// node must still run the record the run certified.
    pub(super) fn passed_before(&mut self) -> anyhow::Result<()> {
        let run = self.run_id()?;
        if let Some(rec) = self.db.progress(run)?.record {
            if !self.runs_record(rec.crc32()) {
                return Err(StationError::RecordReplaced {
                    serial: self.u.serial.clone(),
                    node: self.in_force_words(),
                    certified: format!("{:08x}", rec.crc32()),
                    run_id: run.to_string(),
                }
                .into());
            }
        }
        // `report --db` ended the run before the station journalled its step (a crash between
        // the two): the certificate on disk is the stored one, journalled now.
        if self.journal.done(self.dir, Step::Certificate)?.is_none() {
            let on_disk = std::fs::read(self.path(CERTIFICATE)).ok().map(|b| accelcal_db::sha256_hex(&b));
            if on_disk.is_some() && on_disk == self.db.certificate_sha256(run)? {
                self.finish(
                    Step::Certificate,
                    None,
                    "written (stored, and the run ended, before the stop)".into(),
                    &[CERTIFICATE],
                )?;
            }
        }
        for step in Step::ALL.into_iter().skip(1) {
            if !self.done(step)? {
                return Err(bad(format!(
                    "run {} ended pass in {}, but {} has no step {}: the journal does not match the database",
                    self.run_id()?,
                    self.db.target(),
                    self.p(JOURNAL),
                    step.name()
                )));
            }
        }
        outln!(
            "station: unit {} (device {}) PASS, finished before (run {} in {}); nothing to do",
            self.u.serial,
            self.journal.device_id.as_deref().unwrap_or("?"),
            self.run_id()?,
            self.db.target()
        )?;
        Ok(())
    }
}
