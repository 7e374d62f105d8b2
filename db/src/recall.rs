//! Recalls (issue 59): a reference found out of tolerance at its own recalibration, the runs it
//! calibrated while it was, and what became of each unit.
//!
//! - **The finding** ([`FoundBad`], table `asset_found_bad`, schema 12; `accelcal asset
//!   found-bad`): asset ID, used under its certificate N, was out of tolerance when it was
//!   recalibrated, so every run that used it under N and began on or after a day (`since`) is in
//!   doubt. One per certificate of an asset, refused with nothing stored for an unknown asset or
//!   certificate, a day after today, an empty reason, or a certificate found bad already. A global
//!   row of the chain (`run_id` '' in the ledger), as the asset's own register rows are.
//! - **The runs it affects** ([`Db::recall`], `accelcal affected ID`): each with its unit (serial,
//!   device), the unit's certificate in force for the run (the newest amendment's number, else
//!   the first; where it stands), the customer, and what became of it ([`RecallState`]):
//!   *recalibrated* when a later calibration of the same unit passed on another reference of the
//!   kind (another certificate of the asset, or another asset: a later run with no reference of
//!   the kind linked does not count, it may have used the bad one), *dismissed* when the unit was
//!   reviewed and needs no recall ([`Dismissal`], table `recall_dismissal`, chained too; `affected
//!   ID --dismiss SERIAL --reason TEXT`), *voided*, else *open*. The finding is kind-agnostic: it
//!   reads `run_asset`, so a thermometer or a gravity value linked to runs is traced as a head is.
//! - **What is still open** ([`Db::recalls`]): every finding with its runs, for `fleet` and
//!   `serve`, which show a unit until it is recalibrated or dismissed ([`Recall::units`]).
//!
//! **The customer** is not a column of the database: it is read where the certificate states it,
//! in the document the unit's certificate in force carries (its stored HTML page, which the chain
//! covers: [`accelcal_core::certificate::Certificate::of_page`], `facts.customer`, the name). The
//! station's settings (`customer` in `station.toml`, `--customer`) reach the database only
//! there. A page without a document (written before issue 57, or stored without one) names no
//! customer ([`Db::customers`] fills them in; the listings of the whole line leave them out).
//!
//! The finding's and the dismissals' rows are checked against their chain before they are used
//! ([`chain::verify_recall`]): `affected` refuses an asset whose recall rows do not match, and
//! [`Db::recalls`] marks its findings tampered and takes no dismissal of it as said.

use serde::Serialize;

use super::asset::{start_of_day_unix_s, today_utc, AssetError, AssetKind, Date};
use super::content::{dismissal_content, found_bad_content};
use super::engine::{Tx, Val};
use super::piece::insert_row;
use super::signer::CertificateState;
use super::{chain, now_unix_s, sha256_hex, Db, DbError, Outcome};

/// A reference found out of tolerance at its own recalibration ([`Db::record_found_bad`]).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct FoundBad {
    /// The asset.
    pub asset_id: String,
    /// What it is.
    pub kind: AssetKind,
    /// Its own certificate, under which it was used while out of tolerance.
    pub certificate: String,
    /// The first day (UTC) whose runs under that certificate are affected.
    pub since: Date,
    /// Why (what its recalibration found).
    pub reason: String,
    /// Who recorded it.
    pub operator: String,
    /// When, seconds since the Unix epoch.
    pub recorded_unix_s: i64,
}

/// A unit whose affected runs were reviewed and need no recall ([`Db::dismiss`]).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Dismissal {
    /// The finding's asset.
    pub asset_id: String,
    /// The finding's certificate.
    pub certificate: String,
    /// The unit's device id.
    pub device_id: String,
    /// Its serial (as its affected run has it).
    pub serial: String,
    /// Why no recall is needed.
    pub reason: String,
    /// Who decided it.
    pub operator: String,
    /// When, seconds since the Unix epoch.
    pub dismissed_unix_s: i64,
}

/// A dismissal as an affected run shows it.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Dismissed {
    /// Why no recall is needed.
    pub reason: String,
    /// Who decided it.
    pub operator: String,
    /// When, seconds since the Unix epoch.
    pub dismissed_unix_s: i64,
}

/// A later calibration of the unit that passed on another reference of the kind.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Recalibration {
    /// Its run.
    pub run_id: String,
    /// When it started, seconds since the Unix epoch.
    pub started_unix_s: i64,
    /// The reference it used.
    pub asset_id: String,
    /// That reference's certificate.
    pub certificate: String,
}

/// What became of a run a finding affects.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum RecallState {
    /// Nothing yet: the unit is to be recalled, or the run dismissed.
    Open,
    /// A later calibration of the unit passed on another reference.
    Recalibrated,
    /// Reviewed: no recall needed.
    Dismissed,
    /// The run was voided: it counts nowhere.
    Voided,
}

impl RecallState {
    /// In words, as listed.
    pub fn words(self) -> &'static str {
        match self {
            RecallState::Open => "open",
            RecallState::Recalibrated => "recalibrated",
            RecallState::Dismissed => "dismissed",
            RecallState::Voided => "voided",
        }
    }
}

/// A run calibrated with an asset: what [`Db::affected`] and [`Db::recall`] list.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct AffectedRun {
    /// The run.
    pub run_id: String,
    /// The unit's device id.
    pub device_id: String,
    /// The unit's serial number.
    pub serial: String,
    /// The station that ran it.
    pub station: String,
    /// When the run started, seconds since the Unix epoch.
    pub started_unix_s: i64,
    /// The asset's certificate in force for the run.
    pub certificate: String,
    /// How the run ended (`None`: it has not).
    pub outcome: Option<Outcome>,
    /// Whether a certificate was issued.
    pub certified: bool,
    /// Why the run was voided, when it was.
    pub voided: Option<String>,
    /// The number of the unit's certificate in force for the run (its newest amendment's, else
    /// its first; `None`: not numbered).
    pub certificate_number: Option<String>,
    /// Where that certificate stands (`None`: no certificate stored).
    pub certificate_state: Option<CertificateState>,
    /// The customer its certificate names (`None`: none, or not read: [`Db::customers`]).
    pub customer: Option<String>,
    /// The later calibration of the unit that passed on another reference of the kind.
    pub superseded_by: Option<Recalibration>,
    /// The unit's dismissal under the finding that covers the run.
    pub dismissed: Option<Dismissed>,
    /// What became of it under the finding that covers it (`None`: no finding covers the run,
    /// the asset was not found out of tolerance under its certificate since a day before it).
    pub recall: Option<RecallState>,
}

/// A finding and every run it affects ([`Db::recalls`]).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Recall {
    /// The finding.
    #[serde(flatten)]
    pub found_bad: FoundBad,
    /// Why its rows (or its asset's dismissals) do not match their hash chain, when they do not:
    /// its dismissals are then not taken as said.
    pub tampered: Option<String>,
    /// The runs it affects, oldest first.
    pub runs: Vec<AffectedRun>,
}

/// A unit a finding affects: its latest affected run that was not voided, and what became of it.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct UnitRecall<'a> {
    /// The unit's latest affected run (not voided).
    pub run: &'a AffectedRun,
    /// What became of the unit: that run's state.
    pub state: RecallState,
}

impl Recall {
    /// Each unit the finding affects (a unit whose affected runs were all voided is not one), by
    /// its latest affected run: open until a later calibration on another reference passed, or
    /// until it was dismissed. In the order of those runs.
    pub fn units(&self) -> Vec<UnitRecall<'_>> {
        let mut latest: Vec<&AffectedRun> = Vec::new();
        for r in self.runs.iter().filter(|r| r.voided.is_none()) {
            match latest.iter_mut().find(|l| l.device_id == r.device_id) {
                Some(l) => *l = r,
                None => latest.push(r),
            }
        }
        latest.sort_by(|a, b| (a.started_unix_s, &a.run_id).cmp(&(b.started_unix_s, &b.run_id)));
        latest
            .into_iter()
            .map(|run| UnitRecall { run, state: run.recall.unwrap_or(RecallState::Open) })
            .collect()
    }

    /// The units still open.
    pub fn open(&self) -> Vec<&AffectedRun> {
        self.units().into_iter().filter(|u| u.state == RecallState::Open).map(|u| u.run).collect()
    }
}

/// The affected runs' columns [`affected_run`] reads, after the selection's `FROM` (`ra` the
/// run's asset, `r` its run).
fn select_affected() -> String {
    let in_force = super::certificate::IN_FORCE.replace("$1", "r.run_id");
    format!(
        "SELECT r.run_id, r.device_id, r.serial, r.station, r.started_unix_s, ra.certificate, e.outcome, \
         CASE WHEN c.run_id IS NULL THEN 0 ELSE 1 END, v.reason, {in_force}, \
         (SELECT ap.meaning FROM approval ap WHERE ap.number = {in_force}), \
         (SELECT l.run_id FROM run l JOIN run_asset la ON la.run_id = l.run_id AND la.kind = ra.kind \
          JOIN run_end le ON le.run_id = l.run_id AND le.outcome = 'pass' \
          WHERE l.device_id = r.device_id AND l.started_unix_s > r.started_unix_s \
          AND NOT (la.asset_id = ra.asset_id AND la.certificate = ra.certificate) \
          AND l.run_id NOT IN (SELECT lv.run_id FROM void lv) ORDER BY l.started_unix_s, l.run_id LIMIT 1), \
         d.reason, d.operator, d.dismissed_unix_s, ra.kind \
         FROM run_asset ra JOIN run r ON r.run_id = ra.run_id \
         LEFT JOIN run_end e ON e.run_id = ra.run_id LEFT JOIN certificate c ON c.run_id = ra.run_id \
         LEFT JOIN void v ON v.run_id = ra.run_id \
         LEFT JOIN recall_dismissal d ON d.asset_id = ra.asset_id AND d.certificate = ra.certificate \
         AND d.device_id = r.device_id \
         WHERE ra.asset_id = $1 AND ($2 = '' OR ra.certificate = $2) AND r.started_unix_s >= $3 \
         AND ($4 = '' OR r.device_id = $4) ORDER BY r.started_unix_s, r.run_id"
    )
}

/// The runs that used asset `asset` (under `certificate` when it is not empty), started on or
/// after `since_unix_s` (of `device` when it is not empty), oldest first; `recall` not set.
fn affected_runs(
    tx: &mut Tx<'_>,
    asset: &str,
    certificate: &str,
    since_unix_s: i64,
    device: &str,
) -> Result<Vec<AffectedRun>, DbError> {
    let rows = tx.query(
        &select_affected(),
        &[
            asset.to_string().into(),
            certificate.to_string().into(),
            since_unix_s.into(),
            device.to_string().into(),
        ],
    )?;
    let mut out = Vec::with_capacity(rows.len());
    for r in &rows {
        let certified = r[7].int()? != 0;
        let meaning = r[10].opt_text()?;
        let superseded_by = match r[11].opt_text()? {
            Some(id) => {
                let kind = r[15].text()?;
                let l = tx.query(
                    "SELECT l.started_unix_s, la.asset_id, la.certificate FROM run l \
                     JOIN run_asset la ON la.run_id = l.run_id WHERE l.run_id = $1 AND la.kind = $2",
                    &[id.clone().into(), kind.into()],
                )?;
                let l = l.first().ok_or_else(|| DbError::schema(format!("the run {id} that supersedes")))?;
                Some(Recalibration {
                    run_id: id,
                    started_unix_s: l[0].int()?,
                    asset_id: l[1].text()?,
                    certificate: l[2].text()?,
                })
            }
            None => None,
        };
        out.push(AffectedRun {
            run_id: r[0].text()?,
            device_id: r[1].text()?,
            serial: r[2].text()?,
            station: r[3].text()?,
            started_unix_s: r[4].int()?,
            certificate: r[5].text()?,
            outcome: r[6].opt_text()?.map(|o| Outcome::from_sql(&o)).transpose()?,
            certified,
            voided: r[8].opt_text()?,
            certificate_number: r[9].opt_text()?,
            certificate_state: certified.then(|| CertificateState::of(meaning.as_deref())),
            customer: None,
            superseded_by,
            dismissed: match r[12].opt_text()? {
                Some(reason) => {
                    Some(Dismissed { reason, operator: r[13].text()?, dismissed_unix_s: r[14].int()? })
                }
                None => None,
            },
            recall: None,
        });
    }
    Ok(out)
}

/// What became of `r` under a finding that covers it.
fn state_of(r: &AffectedRun) -> RecallState {
    if r.voided.is_some() {
        RecallState::Voided
    } else if r.dismissed.is_some() {
        RecallState::Dismissed
    } else if r.superseded_by.is_some() {
        RecallState::Recalibrated
    } else {
        RecallState::Open
    }
}

const FOUND_BAD_COLUMNS: &str =
    "f.asset_id, f.certificate, f.since_date, f.reason, f.operator, f.recorded_unix_s, \
     (SELECT a.kind FROM asset a WHERE a.asset_id = f.asset_id AND a.certificate = f.certificate)";

/// The findings of asset `asset` (every asset's when it is empty), oldest first.
fn findings(tx: &mut Tx<'_>, asset: &str) -> Result<Vec<FoundBad>, DbError> {
    tx.query(
        &format!(
            "SELECT {FOUND_BAD_COLUMNS} FROM asset_found_bad f WHERE ($1 = '' OR f.asset_id = $1) \
             ORDER BY f.recorded_unix_s, f.asset_id, f.certificate"
        ),
        &[asset.to_string().into()],
    )?
    .iter()
    .map(|r| {
        let what = || format!("the finding of asset {:?}", r[0]);
        Ok(FoundBad {
            asset_id: r[0].text()?,
            certificate: r[1].text()?,
            since: super::asset::parse_date(&r[2].text()?)
                .map_err(|e| DbError::schema(format!("{}: {e}", what())))?,
            reason: r[3].text()?,
            operator: r[4].text()?,
            recorded_unix_s: r[5].int()?,
            kind: match r[6].opt_text()? {
                Some(k) => AssetKind::from_sql(&k)?,
                None => {
                    return Err(DbError::schema(format!("{}: its certificate is not registered", what())))
                }
            },
        })
    })
    .collect()
}

/// The runs finding `f` affects, each with its state.
fn runs_of_finding(tx: &mut Tx<'_>, f: &FoundBad, device: &str) -> Result<Vec<AffectedRun>, DbError> {
    let mut runs = affected_runs(tx, &f.asset_id, &f.certificate, start_of_day_unix_s(f.since), device)?;
    for r in &mut runs {
        r.recall = Some(state_of(r));
    }
    Ok(runs)
}

/// The customer named by the document run `run`'s certificate in force carries.
fn customer_of(tx: &mut Tx<'_>, run: &str) -> Result<Option<String>, DbError> {
    let in_force = super::certificate::IN_FORCE;
    let html = tx.query(
        &format!(
            "SELECT COALESCE((SELECT am.html FROM amendment am WHERE am.number = {in_force}), \
             (SELECT c.html FROM certificate c WHERE c.run_id = $1))"
        ),
        &[run.to_string().into()],
    )?;
    let Some(html) = html.first().map(|r| r[0].opt_text()).transpose()?.flatten() else { return Ok(None) };
    Ok(match accelcal_core::certificate::Certificate::of_page(&html) {
        Some(Ok(doc)) => doc.facts.customer.map(|p| p.name),
        _ => None,
    })
}

/// A text the register stores: one line, not empty.
fn one_line(asset_id: &str, field: &str, v: &str) -> Result<(), DbError> {
    let bad = |why: String| DbError::Asset(AssetError::Bad { asset_id: asset_id.into(), why });
    accelcal_core::text::single_line(field, v).map_err(|e| bad(e.to_string()))?;
    if v.trim().is_empty() {
        return Err(bad(format!("the {field} is empty: say why (it is stored with it)")));
    }
    Ok(())
}

impl Db {
    /// Records that asset `asset_id` was found out of tolerance at the recalibration that ended
    /// its certificate `certificate`, so that its runs under that certificate from day `since`
    /// (UTC) on are affected: a global row of the chain. Refused, with nothing stored, for an
    /// unknown asset ([`AssetError::Unknown`]), a certificate it does not have, a day after
    /// today, an empty reason or operator, and a certificate found bad already.
    pub fn record_found_bad(
        &mut self,
        asset_id: &str,
        certificate: &str,
        since: Date,
        reason: &str,
        operator: &str,
    ) -> Result<FoundBad, DbError> {
        let bad = |why: String| DbError::Asset(AssetError::Bad { asset_id: asset_id.into(), why });
        one_line(asset_id, "reason", reason)?;
        one_line(asset_id, "operator", operator)?;
        let today = today_utc();
        if since > today {
            return Err(bad(format!(
                "--since {since} is after today ({today}, UTC): a finding covers runs already made"
            )));
        }
        let known = self.asset_certificates(asset_id)?;
        let Some(cert) = known.iter().find(|a| a.certificate == certificate) else {
            let have: Vec<&str> = known.iter().map(|a| a.certificate.as_str()).collect();
            return Err(bad(format!(
                "it has no certificate {certificate} (its certificates: {})",
                have.join(", ")
            )));
        };
        let found = FoundBad {
            asset_id: asset_id.into(),
            kind: cert.kind,
            certificate: certificate.into(),
            since,
            reason: reason.into(),
            operator: operator.into(),
            recorded_unix_s: now_unix_s(),
        };
        let sha = sha256_hex(found_bad_content(asset_id, certificate, &since.to_string(), reason).as_bytes());
        let row: Vec<Val> = vec![
            found.asset_id.clone().into(),
            found.certificate.clone().into(),
            since.to_string().into(),
            found.reason.clone().into(),
            found.operator.clone().into(),
            found.recorded_unix_s.into(),
            sha.into(),
        ];
        self.retried(|conn| {
            conn.transaction(|tx| {
                if let Some(f) = findings(tx, asset_id)?.into_iter().find(|f| f.certificate == certificate) {
                    return Err(bad(format!(
                        "its certificate {certificate} was found out of tolerance already (recorded {} by {}: its \
                         runs from {} on, {}): a finding is recorded once",
                        super::signer::date_of(f.recorded_unix_s),
                        f.operator,
                        f.since,
                        f.reason
                    )));
                }
                insert_row(tx, chain::table("asset_found_bad"), &row)
            })
        })?;
        Ok(found)
    }

    /// Asset `id`'s findings, oldest first ([`AssetError::Unknown`] when it is not registered).
    /// Its register and recall rows are checked against their chain first
    /// ([`DbError::AssetTampered`]).
    pub fn found_bad(&mut self, id: &str) -> Result<Vec<FoundBad>, DbError> {
        self.asset_certificates(id)?;
        let (found, bad) = self.conn.reading(|tx| Ok((findings(tx, id)?, chain::verify_recall(tx, id)?)))?;
        super::asset::untampered(id, bad)?;
        Ok(found)
    }

    /// Every run that used asset `id` and started on or after `since_unix_s`, oldest first
    /// ([`AssetError::Unknown`] when the asset is not registered), each with what became of it
    /// when a finding covers it. The customers are not read ([`Db::customers`]).
    pub fn affected(&mut self, id: &str, since_unix_s: i64) -> Result<Vec<AffectedRun>, DbError> {
        let found = self.found_bad(id)?;
        let mut runs = self.conn.reading(|tx| affected_runs(tx, id, "", since_unix_s, ""))?;
        for r in &mut runs {
            let covered = found
                .iter()
                .any(|f| f.certificate == r.certificate && r.started_unix_s >= start_of_day_unix_s(f.since));
            if covered {
                r.recall = Some(state_of(r));
            } else {
                r.dismissed = None;
            }
        }
        Ok(runs)
    }

    /// Asset `id`'s findings, each with the runs it affects (its runs under the finding's
    /// certificate from the finding's day on), oldest first; refused as [`Db::found_bad`] is.
    /// The customers are not read ([`Db::customers`]).
    pub fn recall(&mut self, id: &str) -> Result<Vec<Recall>, DbError> {
        let found = self.found_bad(id)?;
        self.conn.reading(|tx| {
            found
                .into_iter()
                .map(|f| Ok(Recall { runs: runs_of_finding(tx, &f, "")?, found_bad: f, tampered: None }))
                .collect()
        })
    }

    /// Every finding of every asset with the runs it affects (of `device` only, when given),
    /// oldest first: what `fleet` and `serve` show until each unit is recalibrated or dismissed.
    /// A finding whose asset's recall rows do not match their chain is listed `tampered`, and no
    /// dismissal of it is taken as said.
    pub fn recalls(&mut self, device: Option<&str>) -> Result<Vec<Recall>, DbError> {
        let device = device.map(|d| d.trim().to_ascii_lowercase()).unwrap_or_default();
        self.conn.reading(|tx| {
            let found = findings(tx, "")?;
            let mut checked: std::collections::HashMap<String, Option<String>> = Default::default();
            let mut out = Vec::with_capacity(found.len());
            for f in found {
                if !checked.contains_key(&f.asset_id) {
                    let bad = chain::verify_recall(tx, &f.asset_id)?;
                    let why =
                        bad.first().map(|m| format!("its recall rows do not match their hash chain: {m}"));
                    checked.insert(f.asset_id.clone(), why);
                }
                let tampered = checked[&f.asset_id].clone();
                let mut runs = runs_of_finding(tx, &f, &device)?;
                if tampered.is_some() {
                    for r in &mut runs {
                        r.dismissed = None;
                        r.recall = Some(state_of(r));
                    }
                }
                out.push(Recall { found_bad: f, tampered, runs });
            }
            Ok(out)
        })
    }

    /// Reads the customer of each run's certificate in force ([`AffectedRun::customer`]): where
    /// the certificate states it, in the document its stored page carries.
    pub fn customers(&mut self, runs: &mut [AffectedRun]) -> Result<(), DbError> {
        self.conn.reading(|tx| {
            for r in runs.iter_mut().filter(|r| r.certified) {
                r.customer = customer_of(tx, &r.run_id)?;
            }
            Ok(())
        })
    }

    /// The customer each of `runs` names on its certificate in force, by run id (`fleet --csv`'s
    /// `customer` column): runs without a certificate, or whose certificate names none, are left
    /// out.
    pub fn run_customers<'r>(
        &mut self,
        runs: impl IntoIterator<Item = &'r str>,
    ) -> Result<std::collections::HashMap<String, String>, DbError> {
        let runs: Vec<&str> = runs.into_iter().collect();
        self.conn.reading(|tx| {
            let mut out = std::collections::HashMap::new();
            for r in &runs {
                if let Some(c) = customer_of(tx, r)? {
                    out.insert(r.to_string(), c);
                }
            }
            Ok(out)
        })
    }

    /// Records that unit `unit` (a serial, or a device id), whose runs a finding of asset
    /// `asset_id` affects, was reviewed and needs no recall: a global row of the chain. The
    /// finding is the one under `certificate`, or the one that affects the unit. Refused, with
    /// nothing stored, for an unknown asset, an asset not found bad (or not under
    /// `certificate`), a unit none of whose runs it affects (voided ones aside), a serial of
    /// several devices among them, a unit affected under several of the asset's certificates
    /// without `certificate`, an empty reason, and a unit dismissed already.
    pub fn dismiss(
        &mut self,
        asset_id: &str,
        certificate: Option<&str>,
        unit: &str,
        reason: &str,
        operator: &str,
    ) -> Result<Dismissal, DbError> {
        let bad = |why: String| DbError::Asset(AssetError::Bad { asset_id: asset_id.into(), why });
        one_line(asset_id, "reason", reason)?;
        one_line(asset_id, "operator", operator)?;
        let found: Vec<FoundBad> = self
            .found_bad(asset_id)?
            .into_iter()
            .filter(|f| certificate.is_none_or(|c| c == f.certificate))
            .collect();
        if found.is_empty() {
            return Err(bad(match certificate {
                Some(c) => {
                    format!("it was not found out of tolerance under certificate {c}: nothing to dismiss")
                }
                None => {
                    "it was not found out of tolerance (`accelcal asset found-bad` records it): nothing to \
                         dismiss"
                        .into()
                }
            }));
        }
        let key = unit.trim();
        let at = now_unix_s();
        self.retried(|conn| {
            conn.transaction(|tx| {
                let mut hits: Vec<(FoundBad, AffectedRun)> = Vec::new();
                for f in &found {
                    for r in runs_of_finding(tx, f, "")? {
                        if r.voided.is_none() && (r.serial == key || r.device_id.eq_ignore_ascii_case(key)) {
                            hits.push((f.clone(), r));
                        }
                    }
                }
                let Some((f, r)) = hits.last().cloned() else {
                    let which: Vec<String> = found
                        .iter()
                        .map(|f| format!("certificate {}, since {}", f.certificate, f.since))
                        .collect();
                    return Err(bad(format!(
                        "no run of unit {key} is affected by its finding ({}): nothing to dismiss",
                        which.join("; ")
                    )));
                };
                let mut devices: Vec<&str> = hits.iter().map(|(_, r)| r.device_id.as_str()).collect();
                devices.sort_unstable();
                devices.dedup();
                if devices.len() > 1 {
                    return Err(bad(format!(
                        "serial {key} is on several devices among its affected runs ({}): give the device id",
                        devices.join(", ")
                    )));
                }
                let mut certs: Vec<&str> = hits.iter().map(|(f, _)| f.certificate.as_str()).collect();
                certs.sort_unstable();
                certs.dedup();
                if certs.len() > 1 {
                    return Err(bad(format!(
                        "unit {key} has runs affected under its certificates {}: give --certificate N",
                        certs.join(" and ")
                    )));
                }
                if let Some(d) = &r.dismissed {
                    return Err(bad(format!(
                        "unit {key} was dismissed already under certificate {} ({} by {}: {})",
                        f.certificate,
                        super::signer::date_of(d.dismissed_unix_s),
                        d.operator,
                        d.reason
                    )));
                }
                let d = Dismissal {
                    asset_id: asset_id.into(),
                    certificate: f.certificate.clone(),
                    device_id: r.device_id.clone(),
                    serial: r.serial.clone(),
                    reason: reason.into(),
                    operator: operator.into(),
                    dismissed_unix_s: at,
                };
                let sha = sha256_hex(
                    dismissal_content(&d.asset_id, &d.certificate, &d.device_id, &d.serial, &d.reason)
                        .as_bytes(),
                );
                let row: Vec<Val> = vec![
                    d.asset_id.clone().into(),
                    d.certificate.clone().into(),
                    d.device_id.clone().into(),
                    d.serial.clone().into(),
                    d.reason.clone().into(),
                    d.operator.clone().into(),
                    d.dismissed_unix_s.into(),
                    sha.into(),
                ];
                insert_row(tx, chain::table("recall_dismissal"), &row)?;
                Ok(d)
            })
        })
    }
}
