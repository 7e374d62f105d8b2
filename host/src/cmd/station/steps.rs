//! A unit's steps on the head: as found, the campaign's storing, select, fit, flash, as left and
//! the certificate, each run as the command of that name and journalled.

use super::*;

impl Station<'_> {
    /// Step `as-found`: the record in force, verified before anything changes. Its failure is
    /// the as-found result, not the station's.
    pub(super) fn as_found(&mut self, info: &InfoDoc) -> anyhow::Result<()> {
        self.as_found_step(info)?;
        if self.path(AS_FOUND).is_file() {
            let run = self.run_id()?;
            let path = self.path(AS_FOUND);
            crate::cmd::store::verification(&mut self.db, run, Phase::AsFound, &path)?;
            crash_point("db:as-found");
        }
        Ok(())
    }

    pub(super) fn as_found_step(&mut self, info: &InfoDoc) -> anyhow::Result<()> {
        if self.done(Step::AsFound)? {
            return Ok(());
        }
        if info.record.is_none() {
            return self.finish(Step::AsFound, None, "skipped: no record in force".into(), &[]);
        }
        let _ = std::fs::remove_file(self.path(AS_FOUND));
        let fit = match &self.a.as_found_fit {
            Some(p) => Some(p.clone()),
            None => self.stored_fit_of(info)?,
        };
        let cmd = self.verify_cmd(AS_FOUND, fit);
        self.run(Step::AsFound, &cmd)?;
        let outcome = match self.verdict(AS_FOUND)? {
            (v, verdict) if v.decision.is_some() => {
                format!(
                    "{} ({} positions, decision rule {})",
                    v.decision.map_or("", |d| d.name()).to_uppercase(),
                    v.positions.len(),
                    v.specification.as_ref().map_or("", |s| s.rule.name())
                ) + &verdict.err().map(|f| format!(": {f}")).unwrap_or_default()
            }
            (_, Ok(n)) => format!("PASS ({n} positions)"),
            (_, Err(f)) => format!("FAIL ({f})"),
        };
        self.finish(Step::AsFound, Some(&cmd), outcome, &[AS_FOUND])
    }

    /// The fit of the record in force, from the database (written to the unit's directory for
    /// the as-found verification's tolerance), when a run stored it.
    pub(super) fn stored_fit_of(&mut self, info: &InfoDoc) -> anyhow::Result<Option<PathBuf>> {
        let (Some(device), Some(crc)) =
            (self.journal.device_id.clone(), info.record.as_ref().map(|r| r.crc.as_str()))
        else {
            return Ok(None);
        };
        let Ok(crc) = u32::from_str_radix(crc, 16) else { return Ok(None) };
        let Some(json) = self.db.fit_of_record(&device, crc)? else {
            errln!(
                "station: {}the record in force (CRC {crc:08x}) is not in {}: the as-found tolerance comes from the measured scatter alone",
                self.tag,
                self.db.target()
            );
            return Ok(None);
        };
        let path = self.path(AS_FOUND_FIT);
        accelcal_core::output::write_atomic(&path, json.as_bytes())?;
        errln!(
            "station: {}the fit of the record in force (CRC {crc:08x}) from {}: {}",
            self.tag,
            self.db.target(),
            path.display()
        );
        Ok(Some(path))
    }

    /// Stores the campaign of the finished step `acquire`.
    pub(super) fn store_campaign(&mut self) -> anyhow::Result<()> {
        let bytes = std::fs::read(self.path(CAMPAIGN)).with_context(|| self.p(CAMPAIGN))?;
        self.db.store_campaign(self.run_id()?, &bytes)?;
        crash_point("db:campaign");
        Ok(())
    }

    pub(super) fn select(&mut self) -> anyhow::Result<()> {
        if self.done(Step::Select)? {
            return Ok(());
        }
        let cmd = StepCommand::Select {
            campaign: self.path(CAMPAIGN),
            json: self.path(SELECT),
            tolerance: self.a.select_tolerance,
            criterion: self.a.criterion,
        };
        if let Exit::Failed = self.run(Step::Select, &cmd)? {
            return Err(anyhow::anyhow!("step select failed (its error is above)"));
        }
        let text = std::fs::read_to_string(self.path(SELECT)).with_context(|| self.p(SELECT))?;
        let doc = accelcal_core::document::SelectDoc::parse(&text).with_context(|| self.p(SELECT))?;
        // Not journalled when rejected: the run ends rejected.
        if let Err(e) = deployable(&doc) {
            return Err(self.reject(e.into()));
        }
        self.finish(Step::Select, Some(&cmd), "model 4 deployable on every channel".into(), &[SELECT])
    }

    pub(super) fn fit(&mut self) -> anyhow::Result<()> {
        self.fit_step()?;
        let fit = std::fs::read_to_string(self.path(FIT)).with_context(|| self.p(FIT))?;
        let record = std::fs::read(self.path(RECORD)).with_context(|| self.p(RECORD))?;
        let run = self.run_id()?;
        self.db.store_fit(run, &fit)?;
        crash_point("db:fit");
        self.db.store_record(run, &record)?;
        crash_point("db:record");
        Ok(())
    }

    pub(super) fn fit_step(&mut self) -> anyhow::Result<()> {
        if self.done(Step::Fit)? {
            return Ok(());
        }
        let device = self.journal.device_id.clone().context("no device id: step info has not run")?;
        let cmd = StepCommand::Fit {
            campaign: self.path(CAMPAIGN),
            record: self.path(RECORD),
            json: self.path(FIT),
            device_id: device,
            head_u: self.head_u(),
            tempco: self.a.tempco,
        };
        if let Exit::Failed = self.run(Step::Fit, &cmd)? {
            return Err(anyhow::anyhow!("step fit failed (its error is above)"));
        }
        self.finish(Step::Fit, Some(&cmd), "record written".into(), &[FIT, RECORD])
    }

    pub(super) fn flash(&mut self) -> anyhow::Result<()> {
        if self.done(Step::Flash)? {
            return Ok(());
        }
        // Flashed and noted before a stop, and the node runs it: nothing to write again.
        let p = self.db.progress(self.run_id()?)?;
        if let (true, Some(rec)) = (p.flashed, &p.record) {
            if self.runs_record(rec.crc32()) {
                return self.finish(
                    Step::Flash,
                    None,
                    "the node runs the new record (flashed before the stop)".into(),
                    &[],
                );
            }
        }
        // Given the database, the flash step writes the record the run stored (step fit stored
        // it; a file that is not it is refused) and notes the flash there.
        let route = match &self.u.gdb {
            Some(g) => FlashRoute::Gdb(g.clone()),
            None => FlashRoute::Probe { chip: self.a.chip.clone(), probe: self.u.probe.clone() },
        };
        let cmd = StepCommand::Flash {
            record: self.path(RECORD),
            db: self.db_run()?,
            route,
            port: self.u.port.clone(),
            baud: self.a.baud,
        };
        if let Exit::Failed = self.run(Step::Flash, &cmd)? {
            // What the node runs is what the step said (a cut write keeps the old record; a
            // confirmed write whose note failed runs the new one).
            return Err(anyhow::anyhow!("step flash failed (its error above says what the node runs)"));
        }
        self.finish(Step::Flash, Some(&cmd), "the node runs the new record".into(), &[])
    }

    /// Step `as-left`; its failure rejects the unit. Journalled first, pass or fail, then
    /// stored: a crash between the two stores it on the next run (never a second measurement).
    pub(super) fn as_left(&mut self) -> anyhow::Result<()> {
        if !self.done(Step::AsLeft)? {
            let _ = std::fs::remove_file(self.path(AS_LEFT));
            let cmd = self.verify_cmd(AS_LEFT, Some(self.path(FIT)));
            self.run(Step::AsLeft, &cmd)?;
            let outcome = match self.verdict(AS_LEFT)?.1 {
                Ok(n) => format!("PASS ({n} positions)"),
                Err(f) => format!("FAIL ({f})"),
            };
            self.finish(Step::AsLeft, Some(&cmd), outcome, &[AS_LEFT])?;
        }
        let (report, verdict) = self.verdict(AS_LEFT)?;
        let run = self.run_id()?;
        self.db.store_verification(run, Phase::AsLeft, &report)?;
        crash_point("db:as-left");
        match verdict {
            Ok(_) => Ok(()),
            Err(f) => Err(self.reject(anyhow::Error::new(f).context("as-left verification"))),
        }
    }

    pub(super) fn certificate(&mut self) -> anyhow::Result<()> {
        if self.done(Step::Certificate)? {
            return Ok(());
        }
        let run = self.run_id()?;
        if self.db.progress(run)?.certificate {
            // Stored by the report step before a crash (it writes the file first).
            return self.finish(
                Step::Certificate,
                None,
                "written (stored before the stop)".into(),
                &[CERTIFICATE],
            );
        }
        let cmd = StepCommand::Report {
            campaign: self.path(CAMPAIGN),
            record: self.path(RECORD),
            fit: self.path(FIT),
            verify: self.path(AS_LEFT),
            out: self.path(CERTIFICATE),
            pdf: self.path(CERTIFICATE_PDF),
            as_found: Some(self.path(AS_FOUND)).filter(|p| p.is_file()),
            issuer: self.a.issuer.clone(),
            db: self.db_run()?,
        };
        if let Exit::Failed = self.run(Step::Certificate, &cmd)? {
            return Err(anyhow::anyhow!("step certificate failed (its error is above)"));
        }
        self.finish(Step::Certificate, Some(&cmd), "written".into(), &[CERTIFICATE, CERTIFICATE_PDF])
    }
}
