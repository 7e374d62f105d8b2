//! The line's view across units (`accelcal fleet`): the runs of a period, counted by the
//! database (states, units, first-pass and final yield, rejections by reason), each run with
//! what an MES takes of it, and the units whose certificate's recalibration date falls before a
//! day. Every query is one SQL statement on either engine; the filters are parameters.

use serde::Serialize;

use std::collections::BTreeMap;

use super::engine::Val;

/// What `fleet` counts and how, as `fleet --help` states it.
pub const METHOD: &str = "Method: the runs are those started in the period (UTC days, --until included) that pass every \
filter. A run is `pass` or `rejected` by its end, `unfinished` without one, `voided` when voided (voided runs count in \
no yield or population). First-pass yield: of the units with a finished run in the period, the share whose first finished \
run passed; final yield: the share whose last finished run passed. The populations are over the runs that passed: each \
channel's model-4 coefficients under IEEE Std 1293's names (bias K0 mg, scale factor K1 codes/g, misalignment δ µrad), and \
the as-left verification's measured parameters against the specification's limit ±L, with the sample standard deviation s \
(n − 1) and the process capability Cpk = min(L − mean, mean + L) / (3·s) (Montgomery, Introduction to Statistical Quality \
Control, the index with the specification limits −L and +L; > 1.33 is the usual aim). The counts and yields are computed \
by the database (SQL); the populations from the period's stored fits and verifications. Units due: each unit's latest \
certificate (not voided) whose recalibration date (stored with its number, schema 5) falls within --due-days of --until, \
or before. Recalls, whatever the period: each reference found out of tolerance at its own recalibration (asset \
found-bad) with the units its runs under the certificate found bad, from the finding's day on, calibrated; a unit, by \
its latest such run, is shown until a later calibration of it passed on another reference of the kind (another \
certificate of the asset, or another asset) or it was dismissed (affected --dismiss). Control charts, per head asset (or station, for runs without one) and per quantity (each model-4 \
coefficient, the as-left largest |error|) over the runs that passed, in start order: individuals and moving range \
(Montgomery §6.4): centre x̄, σ̂ = MR̄/d2 with d2 = 1.128, limits x̄ ± 3σ̂, the moving range's limit D4·MR̄ with D4 = 3.267, \
the limits those of the points charted; the Western Electric rules: 1 a point beyond 3σ̂, 2 two of three beyond 2σ̂ on one \
side, 3 four of five beyond 1σ̂ on one side, 4 eight in a row on one side of the centre line (5: a moving range beyond \
D4·MR̄). With all the rules, a chart of many in-control points breaks some by chance: a violation is a place to look, and \
each chart states the violations an in-control chart of as many points shows by chance (0.017 per point at 30 points, \
0.025 at 2,700). \
Head signature: per head asset, each unit's model-4 residuals read as head-angle errors at every position and its \
misalignments as the mount's rotations and the block's non-orthogonalities, tracked from the head's 5th unit: an \
angle standardised by the unit's own stated residual variance about the head's signature learned from its earlier \
units, the head certificate's angle uncertainty its prior (Quesenberry's Q statistic with known variance); a mount \
term by the earlier units' mean and spread (Hawkins' self-starting CUSUM, its Student t taken to the normal \
quantile); each followed by a two-sided CUSUM tuned to 0.5 mrad of its angle or 1 mrad of rotation (k half the \
change, h from Siegmund's approximation: one false alarm in 5,000 units of a true head between them); the first \
unit past its h is a change point. The head's angle error measured by its units since the last change \
point (RMS over the head angles of each angle's mean error, its standard error taken out) is what `fit --head-asset` \
takes for the budget's head_angle when it exceeds the certificate's. Check standards: a station's checks (station --check-standard) are not runs of the \
line (no count, yield or population takes them); each station's check standard is shown over all its checks, its state \
that of its latest check (station --help says how it is judged).";
use super::{Db, DbError};

/// Which runs a fleet query takes: started in `[since, until)`, and each filter that is set.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Filter {
    /// First second, Unix seconds.
    pub since_unix_s: i64,
    /// End (exclusive), Unix seconds.
    pub until_unix_s: i64,
    /// The station's name.
    pub station: Option<String>,
    /// The head's asset id (`run_asset`).
    pub head_asset: Option<String>,
    /// The start of the serial number.
    pub serial_prefix: Option<String>,
    /// Who ran it.
    pub operator: Option<String>,
    /// The period's runs whose rows do not match their hash chain, by run id with the first
    /// mismatch in words, once found ([`Db::checked`]): no count, yield, population or chart
    /// takes them, and [`Db::fleet_runs`] lists them marked. `None`: each query finds them
    /// itself ([`Db::tampered_runs`]), so that a tampered run is never counted as good.
    pub tampered: Option<BTreeMap<String, String>>,
}

/// The condition on `run r` of a [`Filter`], with its parameters `$1`…`$6`. A check of a
/// station's check standard ([`super::check`]) is not a calibration: it is left out.
pub(crate) const WHERE: &str =
    "r.started_unix_s >= $1 AND r.started_unix_s < $2 AND ($3 = '' OR r.station = $3) \
     AND substr(r.serial, 1, length($4)) = $4 AND ($5 = '' OR EXISTS (SELECT 1 FROM run_asset ha \
     WHERE ha.run_id = r.run_id AND ha.kind = 'head' AND ha.asset_id = $5)) AND ($6 = '' OR r.operator = $6) \
     AND r.run_id NOT IN (SELECT ce.run_id FROM run_end ce WHERE substr(ce.reason, 1, 14) = 'check standard')";

/// A run's state: `voided` before its end, `unfinished` without one, else its outcome.
const STATE: &str =
    "CASE WHEN v.run_id IS NOT NULL THEN 'voided' WHEN e.outcome IS NULL THEN 'unfinished' ELSE e.outcome END";

/// [`STATE`] for a query that takes nothing else of the void: `IN` a subquery, which both
/// engines read once into a hashed set (PostgreSQL's hashed SubPlan, SQLite's ephemeral index),
/// where a join looked the void up once per run. The check standards' runs are left out the
/// same way in [`WHERE`]: on a month of the whole line (8,230 runs of 300,000) the selection
/// took 62 ms instead of 87 ms.
const STATE_NO_JOIN: &str = "CASE WHEN r.run_id IN (SELECT v.run_id FROM void v) THEN 'voided' \
     WHEN e.outcome IS NULL THEN 'unfinished' ELSE e.outcome END";

/// The selected runs with their state (and what the readers take of each: serial, station, g), as
/// a common table expression `sel`. The runs set aside as tampered are not in it: their ids are
/// parameter `$7`, a JSON array (read by `json_each` on SQLite, `json_array_elements_text` on
/// PostgreSQL, each once into a hashed set).
///
/// `MATERIALIZED` (PostgreSQL 12, SQLite 3.35): the period's runs are selected once and then
/// joined. Inlined, PostgreSQL checked each run's end for a check standard once per joined
/// row (twelve per run for the fit parameters): on a month of 2,900 runs the populations took
/// 94 ms inlined and 74 ms materialised (window form, a database being written meanwhile).
fn selected(engine: &str) -> String {
    let aside = if engine == "postgres" {
        "SELECT json_array_elements_text(CAST($7 AS text)::json)"
    } else {
        "SELECT value FROM json_each($7)"
    };
    format!(
        "WITH sel AS MATERIALIZED (SELECT r.run_id, r.device_id, r.serial, r.station, r.started_unix_s, r.g_m_s2, \
         {STATE_NO_JOIN} AS state, e.reason FROM run r LEFT JOIN run_end e ON e.run_id = r.run_id WHERE {WHERE} \
         AND r.run_id NOT IN ({aside}))"
    )
}

impl Filter {
    /// The parameters of [`WHERE`], `$1`…`$6`.
    fn params(&self) -> Vec<Val> {
        let text = |v: &Option<String>| Val::from(v.clone().unwrap_or_default());
        vec![
            self.since_unix_s.into(),
            self.until_unix_s.into(),
            text(&self.station),
            text(&self.serial_prefix),
            text(&self.head_asset),
            text(&self.operator),
        ]
    }

    /// The parameters of [`selected`]: [`Filter::params`] and `$7`, the runs `aside`.
    fn params_aside(&self, aside: &BTreeMap<String, String>) -> Vec<Val> {
        let ids: Vec<&String> = aside.keys().collect();
        let mut p = self.params();
        p.push(serde_json::to_string(&ids).expect("strings serialise").into());
        p
    }
}

/// What the database counts of a period's runs: the runs set aside as tampered
/// ([`Filter::tampered`]) are in no count but [`Counts::tampered`].
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct Counts {
    /// Runs started in the period (the tampered ones set aside).
    pub runs: i64,
    /// Of them: ended `pass`, ended `rejected`, not ended, voided.
    pub passed: i64,
    /// Ended `rejected`.
    pub rejected: i64,
    /// Not ended (stopped, or still on the line).
    pub unfinished: i64,
    /// Voided (taken out of the statistics).
    pub voided: i64,
    /// Units (device ids) with a run in the period.
    pub units: i64,
    /// Units with a finished, not voided run in the period: the yields' denominator.
    pub units_finished: i64,
    /// Of them, units whose first finished run in the period passed.
    pub first_pass_units: i64,
    /// Of them, units whose last finished run in the period passed.
    pub final_pass_units: i64,
    /// Rejected runs by reason, most frequent first.
    pub rejections: Vec<(String, i64)>,
    /// Each station's runs and those that passed, by station name.
    #[serde(skip)]
    pub stations: Vec<(String, i64, i64)>,
    /// Runs of the period set aside because their rows do not match their hash chain: in no
    /// other count, yield or population.
    pub tampered: i64,
}

impl Counts {
    /// How many tampered runs were set aside, in words (`1 tampered run set aside`), when any
    /// were.
    pub fn set_aside(&self) -> Option<String> {
        (self.tampered > 0).then(|| {
            format!("{} tampered run{} set aside", self.tampered, if self.tampered == 1 { "" } else { "s" })
        })
    }
}

/// One run of the period, as the fleet's table and its CSV show it.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct FleetRun {
    /// The run.
    pub run_id: String,
    /// The unit's device id.
    pub device_id: String,
    /// Its serial.
    pub serial: String,
    /// The station.
    pub station: String,
    /// The head's asset id (`null`: no registered head).
    pub head_asset: Option<String>,
    /// Who ran it.
    pub operator: String,
    /// Start, Unix seconds.
    pub started_unix_s: i64,
    /// The g the run used, m/s².
    pub g_m_s2: f64,
    /// End, Unix seconds (`null`: not ended).
    pub ended_unix_s: Option<i64>,
    /// `pass`, `rejected`, `unfinished` or `voided`.
    pub state: String,
    /// Why it ended (or was voided) so.
    pub reason: Option<String>,
    /// The as-found verification's decision against a specification (`null`: none, or none
    /// decided).
    pub as_found_decision: Option<String>,
    /// The as-left verification's decision (`null`: none, or none decided).
    pub as_left_decision: Option<String>,
    /// Its stored fit's model-4 coefficients (`fit_summary`, [`super::derived`]).
    #[serde(skip)]
    pub model4: Option<[[f64; 4]; 3]>,
    /// Its stored fit's expanded uncertainty per axis (`fit_summary`).
    #[serde(skip)]
    pub u_m_s2: Option<[f64; 3]>,
    /// The as-left verification's largest |error|, m/s² (`verification_summary`), for the
    /// control charts.
    #[serde(skip)]
    pub as_left_max_abs_error_m_s2: Option<f64>,
    /// Why the rows the fleet shows of it do not match their hash chain ([`Db::tampered_runs`]),
    /// when they do not: such a run is listed as tampered, and charted nowhere.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub tampered: Option<String>,
    /// Where its stored certificate stands (`awaiting_approval`, `approved`, `rejected`; null:
    /// no certificate stored).
    pub certificate_state: Option<super::signer::CertificateState>,
    /// The number of its certificate in force (its newest amendment's, else its first).
    pub certificate_number: Option<String>,
    /// The recalibration date its certificate states, Unix seconds.
    pub due_unix_s: Option<i64>,
    /// Its record's CRC-32, 8 hex digits.
    pub record_crc32: Option<String>,
}

impl FleetRun {
    /// Its state as a table shows it: `tampered` when its rows do not match their hash chain
    /// (whatever they say), else [`FleetRun::state`].
    pub fn shown_state(&self) -> &str {
        if self.tampered.is_some() {
            "tampered"
        } else {
            &self.state
        }
    }

    /// Its stored fit's model-4 coefficients, `[channel x, y, z][term 1, ax, ay, az]`, when it
    /// has a model-4 fit.
    pub fn model4(&self) -> Option<[[f64; 4]; 3]> {
        self.model4
    }

    /// Its stored fit's expanded uncertainty per axis, m/s² (k = 2), when it has a budget.
    pub fn u_m_s2(&self) -> Option<[f64; 3]> {
        self.u_m_s2
    }
}

/// A unit whose latest certificate's recalibration date falls before a day.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct DueUnit {
    /// The unit's device id.
    pub device_id: String,
    /// Its serial.
    pub serial: String,
    /// The run of that certificate.
    pub run_id: String,
    /// The date, Unix seconds.
    pub due_unix_s: i64,
}

fn opt_int(v: &Val) -> Result<Option<i64>, DbError> {
    match v {
        Val::Null => Ok(None),
        v => v.int().map(Some),
    }
}

impl Db {
    /// `f` with the period's tampered runs found ([`Filter::tampered`], [`Db::tampered_runs`]):
    /// what the queries of one view of the period take, so that the runs are checked once.
    pub fn checked(&mut self, f: &Filter) -> Result<Filter, DbError> {
        let tampered = self.tampered_runs(f)?;
        Ok(Filter { tampered: Some(tampered), ..f.clone() })
    }

    /// The runs of `f` set aside as tampered: those it holds, else found now.
    fn aside(&mut self, f: &Filter) -> Result<BTreeMap<String, String>, DbError> {
        match &f.tampered {
            Some(t) => Ok(t.clone()),
            None => self.tampered_runs(f),
        }
    }

    /// The period's runs counted by state, its units, the yields, the rejections by reason and
    /// each station's runs: one statement, so that the period's runs are selected once. The
    /// tampered runs are set aside (counted in [`Counts::tampered`] alone).
    pub fn fleet_counts(&mut self, f: &Filter) -> Result<Counts, DbError> {
        let aside = self.aside(f)?;
        let sel = selected(self.conn.engine());
        // Three kinds of row: 0 a state and reason with its runs; 1 a station with its runs and
        // those that passed; 2 the units, the units with a finished run, and of those the units
        // whose first and last finished runs passed.
        let rows = self.conn.transaction(|tx| {
            tx.query(
                &format!(
                    "{sel}, w AS (SELECT device_id, state, state IN ('pass', 'rejected') AS fin, \
                     ROW_NUMBER() OVER (PARTITION BY device_id, state IN ('pass', 'rejected') \
                     ORDER BY started_unix_s, run_id) AS first_n, \
                     ROW_NUMBER() OVER (PARTITION BY device_id, state IN ('pass', 'rejected') \
                     ORDER BY started_unix_s DESC, run_id DESC) AS last_n FROM sel) \
                     SELECT 0, state, reason, COUNT(*), 0, 0, 0 FROM sel GROUP BY state, reason \
                     UNION ALL SELECT 1, station, NULL, COUNT(*), \
                     SUM(CASE WHEN state = 'pass' THEN 1 ELSE 0 END), 0, 0 FROM sel GROUP BY station \
                     UNION ALL SELECT 2, NULL, NULL, COUNT(DISTINCT device_id), \
                     COUNT(DISTINCT CASE WHEN fin THEN device_id END), \
                     COALESCE(SUM(CASE WHEN fin AND first_n = 1 AND state = 'pass' THEN 1 ELSE 0 END), 0), \
                     COALESCE(SUM(CASE WHEN fin AND last_n = 1 AND state = 'pass' THEN 1 ELSE 0 END), 0) FROM w"
                ),
                &f.params_aside(&aside),
            )
        })?;
        let mut c = Counts { tampered: aside.len() as i64, ..Counts::default() };
        for r in &rows {
            match r[0].int()? {
                0 => {
                    let n = r[3].int()?;
                    c.runs += n;
                    match r[1].text()?.as_str() {
                        "pass" => c.passed += n,
                        "rejected" => {
                            c.rejected += n;
                            c.rejections.push((r[2].opt_text()?.unwrap_or_default(), n));
                        }
                        "unfinished" => c.unfinished += n,
                        _ => c.voided += n,
                    }
                }
                1 => c.stations.push((r[1].text()?, r[3].int()?, r[4].int()?)),
                _ => {
                    (c.units, c.units_finished, c.first_pass_units, c.final_pass_units) =
                        (r[3].int()?, r[4].int()?, r[5].int()?, r[6].int()?);
                }
            }
        }
        c.rejections.sort_by(|a, b| b.1.cmp(&a.1).then_with(|| a.0.cmp(&b.0)));
        c.stations.sort();
        Ok(c)
    }

    /// The period's runs, oldest first, with their head, outcome, decisions, fit and as-left
    /// verification.
    pub fn fleet_runs(&mut self, f: &Filter) -> Result<Vec<FleetRun>, DbError> {
        let mut tampered = self.aside(f)?;
        let p = f.params();
        let rows = self.conn.transaction(|tx| {
            tx.query(
                &format!(
                    "SELECT r.run_id, r.device_id, r.serial, r.station, ra.asset_id, r.operator, r.started_unix_s, \
                     e.ended_unix_s, {STATE}, COALESCE(v.reason, e.reason), af.decision, al.decision, fs.model4_json, \
                     fs.u_json, r.g_m_s2, al.max_abs_error_m_s2, \
                     CASE WHEN EXISTS (SELECT 1 FROM certificate c WHERE c.run_id = r.run_id) THEN 1 ELSE 0 END, \
                     ap.meaning, {IN_FORCE}, rd.due_unix_s, cr.crc32 \
                     FROM run r LEFT JOIN run_end e ON e.run_id = r.run_id \
                     LEFT JOIN recalibration_due rd ON rd.run_id = r.run_id \
                     LEFT JOIN cal_record cr ON cr.run_id = r.run_id \
                     LEFT JOIN void v ON v.run_id = r.run_id \
                     LEFT JOIN approval ap ON ap.run_id = r.run_id AND ap.number = {IN_FORCE} \
                     LEFT JOIN run_asset ra ON ra.run_id = r.run_id AND ra.kind = 'head' \
                     LEFT JOIN verification_summary af ON af.run_id = r.run_id AND af.phase = 'as_found' \
                     LEFT JOIN verification_summary al ON al.run_id = r.run_id AND al.phase = 'as_left' \
                     LEFT JOIN fit_summary fs ON fs.run_id = r.run_id \
                     WHERE {WHERE} ORDER BY r.started_unix_s, r.run_id",
                    IN_FORCE = super::certificate::IN_FORCE.replace("$1", "r.run_id")
                ),
                &p,
            )
        })?;
        let mut runs = self.listed(&rows, 0, |r| {
            Ok(FleetRun {
                run_id: r[0].text()?,
                device_id: r[1].text()?,
                serial: r[2].text()?,
                station: r[3].text()?,
                head_asset: r[4].opt_text()?,
                operator: r[5].text()?,
                started_unix_s: r[6].int()?,
                g_m_s2: r[14].real()?,
                ended_unix_s: opt_int(&r[7])?,
                state: r[8].text()?,
                reason: r[9].opt_text()?,
                as_found_decision: r[10].opt_text()?,
                as_left_decision: r[11].opt_text()?,
                model4: r[12].opt_text()?.and_then(|t| serde_json::from_str(&t).ok()),
                u_m_s2: r[13].opt_text()?.and_then(|t| serde_json::from_str(&t).ok()),
                as_left_max_abs_error_m_s2: match &r[15] {
                    Val::Null => None,
                    v => Some(v.real()?),
                },
                tampered: None,
                certificate_state: match r[16].int()? {
                    0 => None,
                    _ => Some(super::signer::CertificateState::of(r[17].opt_text()?.as_deref())),
                },
                certificate_number: r[18].opt_text()?,
                due_unix_s: opt_int(&r[19])?,
                record_crc32: opt_int(&r[20])?
                    .and_then(|c| u32::try_from(c).ok())
                    .map(|c| format!("{c:08x}")),
            })
        })?;
        for r in &mut runs {
            r.tampered = tampered.remove(&r.run_id);
        }
        Ok(runs)
    }

    /// The period's runs whose chain does not match, each with its first mismatch in words:
    /// every run's ledger entries (chain values and links) and its rows of every run's table
    /// (the start, the campaign, the fit, the record, the flash, the verifications, the
    /// certificate and its number and date, the end, the void, the assets used) as
    /// [`Db::verify_run`] checks one, and the register rows of the assets the runs used; one
    /// statement per table for the whole period ([`super::chain::verify_selected`]), not a
    /// [`Db::verify_run`] per run.
    pub fn tampered_runs(&mut self, f: &Filter) -> Result<BTreeMap<String, String>, DbError> {
        let sel = selected(self.conn.engine());
        let p = f.params_aside(&BTreeMap::new());
        let found = self.conn.transaction(|tx| super::chain::verify_selected(tx, &sel, &p))?;
        Ok(found
            .into_iter()
            .filter_map(|(run, m)| {
                let first = m.into_iter().next()?;
                let at = if first.seq > 0 { format!(" (ledger entry {})", first.seq) } else { String::new() };
                let whose = if first.run_id.is_empty() { "the asset register's" } else { "its" };
                Some((run, format!("{whose} {} row{at}: {}", first.piece, first.what)))
            })
            .collect())
    }

    /// The units whose latest certificate (of a run not voided) states a recalibration date
    /// before `before_unix_s` (overdue ones too), soonest first; `serial_prefix` limits them.
    pub fn units_due(
        &mut self,
        before_unix_s: i64,
        serial_prefix: Option<&str>,
    ) -> Result<Vec<DueUnit>, DbError> {
        let rows = self.conn.transaction(|tx| {
            tx.query(
                "SELECT c.device_id, r.serial, c.run_id, c.due_unix_s FROM device_certificate c \
                 JOIN run r ON r.run_id = c.run_id \
                 WHERE c.due_unix_s < $1 AND substr(r.serial, 1, length($2)) = $2 \
                 ORDER BY c.due_unix_s, r.serial",
                &[before_unix_s.into(), serial_prefix.unwrap_or("").into()],
            )
        })?;
        self.listed(&rows, 2, |r| {
            Ok(DueUnit {
                device_id: r[0].text()?,
                serial: r[1].text()?,
                run_id: r[2].text()?,
                due_unix_s: r[3].int()?,
            })
        })
    }
}

/// A population over the period's calibrated units: its mean, sample standard deviation and,
/// against a two-sided limit ±L, the process capability `Cpk = min(L − mean, mean + L) / (3·sd)`
/// (the textbook index with the specification limits −L and +L).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Population {
    /// What it is: `K0 x` (bias), `K1 x` (scale factor), `δ x→y` (misalignment), `as-left bias
    /// x`, ….
    pub name: String,
    /// Its unit.
    pub unit: &'static str,
    /// Units in it.
    pub n: usize,
    /// Mean.
    pub mean: f64,
    /// Sample standard deviation (n − 1; 0 with one unit).
    pub sd: f64,
    /// The specification's limit L, when it limits this.
    pub limit: Option<f64>,
    /// `Cpk`, with a limit and at least two units that scatter.
    pub cpk: Option<f64>,
}

impl Population {
    /// The population of `n` values with mean `mean` and sum of squared deviations `ss`.
    fn of(name: String, unit: &'static str, n: usize, mean: f64, ss: f64, limit: Option<f64>) -> Population {
        let sd = if n > 1 { (ss / (n - 1) as f64).sqrt() } else { 0.0 };
        let cpk = limit.filter(|_| sd > 0.0).map(|l| (l - mean).min(mean + l) / (3.0 * sd));
        Population { name, unit, n, mean, sd, limit, cpk }
    }
}

const AXES: [&str; 3] = ["x", "y", "z"];

/// Why a run is left out of the populations ([`Db::populations`]).
const NOT_A_NUMBER: &str =
    "a value of its fit's or as-left verification's parameters is not a finite number: left out of the populations";

/// A unit as the database names it (`mg`, `ppm`, `µrad`, `codes/g`, `m/s²`).
fn unit_of(s: &str) -> &'static str {
    ["mg", "ppm", "codes/g", "m/s²"].into_iter().find(|u| *u == s).unwrap_or("µrad")
}

impl Db {
    /// The populations of the period's runs that passed (not voided), aggregated by the
    /// database (the mean by a window over each parameter's rows, then the sum of squared
    /// deviations from it: two passes over one read, no cancellation):
    /// each channel's model-4 coefficients under IEEE 1293's names (K0 mg, K1 codes/g, δ µrad;
    /// no limit: the specification limits the calibrated unit, not the sensor), then each
    /// parameter the as-left verification measured against the specification's limit (bias mg,
    /// scale factor ppm, misalignment µrad; the tightest limit stated) with its Cpk. A run whose
    /// fit is not model 4 is left out of the coefficients.
    pub fn populations(&mut self, f: &Filter) -> Result<Vec<Population>, DbError> {
        let aside = self.aside(f)?;
        let engine = self.conn.engine();
        let sel = selected(engine);
        let p = f.params_aside(&aside);
        // One statement, so that the period's runs are selected once. Rows of kind 0 are the
        // coefficients by `ord`, of kind 1 the as-left parameters by name: each with its count,
        // mean and sum of squared deviations from the mean, without cancellation. PostgreSQL's
        // AVG and VAR_SAMP of double precision take one pass (Youngs and Cramer's updates, since
        // PostgreSQL 12); SQLite has no variance, so there each population's mean is aggregated
        // first (`fm`, `vm`), then the squared deviations from it: two passes over one read.
        // These rows are derived, not chained, and an average takes whatever a cell holds
        // (SQLite's AVG reads 'abc' as 0): a run with a value that is not a finite number
        // (`bad`) is left out of every population and named, a row of kind 2.
        let not_number = |c: &str| {
            if engine == "postgres" {
                format!("{c} IN ('NaN'::float8, 'Infinity'::float8, '-Infinity'::float8)")
            } else {
                format!(
                    "(typeof({c}) NOT IN ('real', 'integer') OR {c} > 1.7976931348623157e308 \
                     OR {c} < -1.7976931348623157e308)"
                )
            }
        };
        let (fv, vv, vl) = (not_number("fp.value"), not_number("vp.value"), not_number("vp.limit_value"));
        let sql = if engine == "postgres" {
            format!(
                "{sel}, bad AS MATERIALIZED (SELECT fp.run_id FROM fit_parameter fp JOIN sel ON sel.run_id = fp.run_id \
                 WHERE sel.state = 'pass' AND {fv} UNION SELECT vp.run_id FROM verification_parameter vp \
                 JOIN sel ON sel.run_id = vp.run_id WHERE sel.state = 'pass' AND vp.phase = 'as_left' \
                 AND ({vv} OR {vl})) \
                 SELECT 0 AS kind, MIN(fp.name), MIN(fp.unit), COUNT(*), AVG(fp.value), \
                 COALESCE(VAR_SAMP(fp.value), 0) * (COUNT(*) - 1), NULL, fp.ord AS o \
                 FROM fit_parameter fp JOIN sel ON sel.run_id = fp.run_id WHERE sel.state = 'pass' \
                 AND fp.run_id NOT IN (SELECT run_id FROM bad) GROUP BY fp.ord \
                 UNION ALL SELECT 1, vp.name, MIN(vp.unit), COUNT(*), AVG(vp.value), \
                 COALESCE(VAR_SAMP(vp.value), 0) * (COUNT(*) - 1), MIN(vp.limit_value), MIN(vp.ord) \
                 FROM verification_parameter vp JOIN sel ON sel.run_id = vp.run_id \
                 WHERE sel.state = 'pass' AND vp.phase = 'as_left' AND vp.run_id NOT IN (SELECT run_id FROM bad) \
                 GROUP BY vp.name \
                 UNION ALL SELECT 2, run_id, NULL, 0, NULL, NULL, NULL, NULL FROM bad ORDER BY 1, 8, 2"
            )
        } else {
            format!(
                "{sel}, fp0 AS MATERIALIZED (SELECT fp.run_id, fp.ord, fp.name, fp.unit, fp.value FROM fit_parameter fp \
                 JOIN sel ON sel.run_id = fp.run_id WHERE sel.state = 'pass'), \
                 vp0 AS MATERIALIZED (SELECT vp.run_id, vp.ord, vp.name, vp.unit, vp.value, vp.limit_value \
                 FROM verification_parameter vp JOIN sel ON sel.run_id = vp.run_id \
                 WHERE sel.state = 'pass' AND vp.phase = 'as_left'), \
                 bad AS MATERIALIZED (SELECT fp.run_id FROM fp0 fp WHERE {fv} \
                 UNION SELECT vp.run_id FROM vp0 vp WHERE {vv} OR {vl}), \
                 fp AS (SELECT ord, name, unit, value FROM fp0 WHERE run_id NOT IN (SELECT run_id FROM bad)), \
                 fm AS (SELECT ord, AVG(value) AS mu FROM fp GROUP BY ord), \
                 vp AS (SELECT ord, name, unit, value, limit_value FROM vp0 \
                 WHERE run_id NOT IN (SELECT run_id FROM bad)), \
                 vm AS (SELECT name, AVG(value) AS mu FROM vp GROUP BY name) \
                 SELECT 0 AS kind, MIN(fp.name) AS name, MIN(fp.unit), COUNT(*), MIN(fm.mu), \
                 SUM((fp.value - fm.mu) * (fp.value - fm.mu)), NULL, fp.ord AS o \
                 FROM fp JOIN fm ON fm.ord = fp.ord GROUP BY fp.ord \
                 UNION ALL SELECT 1, vp.name, MIN(vp.unit), COUNT(*), MIN(vm.mu), \
                 SUM((vp.value - vm.mu) * (vp.value - vm.mu)), MIN(vp.limit_value), MIN(vp.ord) \
                 FROM vp JOIN vm ON vm.name = vp.name GROUP BY vp.name \
                 UNION ALL SELECT 2, run_id, NULL, 0, NULL, NULL, NULL, NULL FROM bad ORDER BY 1, 8, 2"
            )
        };
        let postgres = self.conn.engine() == "postgres";
        let rows = self.conn.transaction(|tx| {
            if postgres {
                // The coefficients' rows of a month of the whole line (97,000) are sorted by
                // parameter: in the default 4 MB that sort spills to disk (3.8 MB written).
                tx.execute("SET LOCAL work_mem = '32MB'", &[])?;
            }
            tx.query(&sql, &p)
        })?;
        let kind = |k: i64| rows.iter().filter(move |r| matches!(r[0].int(), Ok(x) if x == k));
        let (coef, asleft): (Vec<_>, Vec<_>) = (kind(0).collect(), kind(1).collect());
        let bad =
            kind(2).map(|r| Ok((r[1].text()?, NOT_A_NUMBER.to_string()))).collect::<Result<_, DbError>>()?;
        self.set_aside(bad);
        let mut out = Vec::new();
        if coef.is_empty() {
            // No model-4 unit: the coefficients' populations are there, empty.
            for (name, unit) in super::derived::fit_parameter_names() {
                out.push(Population::of(name, unit, 0, 0.0, 0.0, None));
            }
        }
        for r in coef {
            let n = r[3].int()? as usize;
            out.push(Population::of(
                r[1].text()?,
                unit_of(&r[2].text()?),
                n,
                r[4].real()?,
                r[5].real()?,
                None,
            ));
        }
        for r in asleft {
            let n = r[3].int()? as usize;
            let name = format!("as-left {}", r[1].text()?);
            out.push(Population::of(
                name,
                unit_of(&r[2].text()?),
                n,
                r[4].real()?,
                r[5].real()?,
                Some(r[6].real()?),
            ));
        }
        Ok(out)
    }

    /// What each run of the period that passed (not voided) with a registered head shows of its
    /// head (`head_observation`), by head asset, in the order the runs started.
    pub fn head_observations(&mut self, f: &Filter) -> Result<Vec<HeadObservation>, DbError> {
        let aside = self.aside(f)?;
        let sel = selected(self.conn.engine());
        let rows = self.conn.transaction(|tx| {
            tx.query(
                &format!(
                    "{sel} SELECT ra.asset_id, sel.serial, sel.run_id, sel.started_unix_s, sel.g_m_s2, {OBSERVED} \
                     FROM sel JOIN run_asset ra ON ra.run_id = sel.run_id AND ra.kind = 'head' \
                     JOIN head_observation h ON h.run_id = sel.run_id \
                     LEFT JOIN head_observation_f32 b ON b.run_id = sel.run_id WHERE sel.state = 'pass' \
                     ORDER BY sel.started_unix_s, sel.run_id"
                ),
                &f.params_aside(&aside),
            )
        })?;
        Ok(self.listed(&rows, 2, head_observation)?.into_iter().flatten().collect())
    }

    /// The head observations of the last `limit` runs on head asset `asset` that started before
    /// `before_unix_s` and passed (not voided, not a check standard's check), oldest first:
    /// what the uncertainty budget of a new calibration on that head takes its measured angle
    /// error from ([`accelcal_core::headsig::MeasuredAngle`]).
    pub fn latest_head_observations(
        &mut self,
        asset: &str,
        before_unix_s: i64,
        limit: usize,
    ) -> Result<Vec<HeadObservation>, DbError> {
        let rows = self.conn.transaction(|tx| {
            tx.query(
                &format!(
                    "SELECT ra.asset_id, r.serial, r.run_id, r.started_unix_s, r.g_m_s2, {OBSERVED} \
                     FROM run_asset ra JOIN run r ON r.run_id = ra.run_id \
                     JOIN run_end e ON e.run_id = ra.run_id AND e.outcome = 'pass' \
                     JOIN head_observation h ON h.run_id = ra.run_id \
                     LEFT JOIN head_observation_f32 b ON b.run_id = ra.run_id \
                     WHERE ra.kind = 'head' AND ra.asset_id = $1 AND r.started_unix_s < $2 \
                     AND NOT ({}) \
                     AND NOT EXISTS (SELECT 1 FROM void v WHERE v.run_id = ra.run_id) \
                     ORDER BY r.started_unix_s DESC, r.run_id DESC LIMIT $3",
                    super::check::IS_CHECK
                ),
                &[asset.into(), before_unix_s.into(), (limit.min(i64::MAX as usize) as i64).into()],
            )
        })?;
        let mut out: Vec<HeadObservation> =
            self.listed(&rows, 2, head_observation)?.into_iter().flatten().collect();
        out.reverse();
        Ok(out)
    }
}

/// The control charts of a period's runs ([`Db::fleet_runs`]: in the order they started) that
/// passed (not voided), by head asset (or station): each IEEE 1293 coefficient of its model-4
/// fit (the `fit_parameter` rows, [`super::derived::fit_parameters`]) and the as-left
/// verification's largest |error| ([`accelcal_core::spc`]: I-MR, the Western Electric rules).
/// A group needs two points. The runs already hold what the charts take, so the period's points
/// are not read a second time.
pub fn charts(runs: &[FleetRun]) -> Vec<Chart> {
    use accelcal_core::spc::ImrLimits;
    use std::collections::{BTreeMap, HashMap};
    let mut groups: BTreeMap<String, HashMap<String, Vec<ChartPoint>>> = BTreeMap::new();
    for run in runs.iter().filter(|r| r.state == "pass" && r.tampered.is_none()) {
        let group = match &run.head_asset {
            Some(asset) => format!("head {asset}"),
            None => format!("station {}", run.station),
        };
        let by = groups.entry(group).or_default();
        let point = |value: f64| ChartPoint {
            serial: run.serial.clone(),
            run_id: run.run_id.clone(),
            started_unix_s: run.started_unix_s,
            value,
        };
        for (name, _, value) in run.model4.as_ref().map(super::derived::fit_parameters).unwrap_or_default() {
            by.entry(name).or_default().push(point(value));
        }
        if let Some(e) = run.as_left_max_abs_error_m_s2 {
            by.entry(AS_LEFT_MAX.to_string()).or_default().push(point(e));
        }
    }
    // Each channel's K0, K1 and δ, then the as-left verification.
    let mut quantities: Vec<(String, &'static str)> = Vec::new();
    for c in 0..3 {
        quantities.push((format!("K0 {}", AXES[c]), "mg"));
        quantities.push((format!("K1 {}", AXES[c]), "codes/g"));
        for j in (0..3).filter(|&j| j != c) {
            quantities.push((format!("δ {}→{}", AXES[c], AXES[j]), "µrad"));
        }
    }
    quantities.push((AS_LEFT_MAX.into(), "m/s²"));
    let mut out = Vec::new();
    for (group, mut by) in groups {
        for (quantity, unit) in &quantities {
            let points = by.remove(quantity).unwrap_or_default();
            let values: Vec<f64> = points.iter().map(|p| p.value).collect();
            let Some(limits) = ImrLimits::of(&values) else { continue };
            let violations = limits
                .violations(&values)
                .into_iter()
                .map(|v| (v.clone(), points[v.index].clone()))
                .collect();
            out.push(Chart {
                group: group.clone(),
                quantity: quantity.clone(),
                unit,
                limits,
                expected_by_chance: accelcal_core::spc::violations_by_chance(points.len()),
                points,
                violations,
            });
        }
    }
    out
}

/// The as-left verification's chart.
const AS_LEFT_MAX: &str = "as-left max |error|";

/// The columns of a head observation [`head_observation`] reads, of `head_observation h` and
/// `head_observation_f32 b`: the compact form, the JSON only where there is none (a
/// database whose backfill has not reached it yet: it is not read otherwise), and why not.
const OBSERVED: &str = "b.obs, CASE WHEN b.obs IS NULL THEN h.obs_json END, h.why";

/// A row `asset, serial, run_id, started_unix_s, g_m_s2` and [`OBSERVED`]: `None` for a
/// campaign that shows nothing of its head (neither an observation nor why not: not a triad).
fn head_observation(r: &[Val]) -> Result<Option<HeadObservation>, DbError> {
    let run_id = r[2].text()?;
    let bad = |cause: String| DbError::BadPiece { run_id: run_id.clone(), piece: "head observation", cause };
    let compact = match &r[5] {
        Val::Null => None,
        v => Some(v.bytes()?),
    };
    let seen = match (compact, r[6].opt_text()?, r[7].opt_text()?) {
        (_, _, Some(why)) => Err(why),
        (Some(bytes), _, None) => Ok(super::derived::Observation::from_bytes(&bytes).map_err(bad)?),
        (None, Some(json), None) => Ok(serde_json::from_str(&json).map_err(|e| bad(e.to_string()))?),
        (None, None, None) => return Ok(None),
    };
    Ok(Some(HeadObservation {
        asset: r[0].text()?,
        serial: r[1].text()?,
        run_id,
        started_unix_s: r[3].int()?,
        g_m_s2: r[4].real()?,
        seen,
    }))
}

/// One run's view of its head ([`Db::head_observations`]).
#[derive(Clone, Debug, PartialEq)]
pub struct HeadObservation {
    /// The head's asset id.
    pub asset: String,
    /// The unit's serial.
    pub serial: String,
    /// The run.
    pub run_id: String,
    /// When it started, Unix seconds.
    pub started_unix_s: i64,
    /// The g the run used, m/s².
    pub g_m_s2: f64,
    /// What its campaign shows, or why its campaign does not read.
    pub seen: Result<super::derived::Observation, String>,
}

/// One point of a control chart.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ChartPoint {
    /// The unit.
    pub serial: String,
    /// Its run.
    pub run_id: String,
    /// When it started, Unix seconds.
    pub started_unix_s: i64,
    /// The value charted.
    pub value: f64,
}

/// An individuals and moving-range chart of one quantity of one head (or station).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Chart {
    /// `head ID`, or `station NAME` for runs without a registered head.
    pub group: String,
    /// What is charted (`K0 x`, `δ x→y`, `as-left max |error|`, …).
    pub quantity: String,
    /// Its unit.
    pub unit: &'static str,
    /// Its lines.
    pub limits: accelcal_core::spc::ImrLimits,
    /// The points, in time order.
    pub points: Vec<ChartPoint>,
    /// The points that break a rule.
    pub violations: Vec<(accelcal_core::spc::Violation, ChartPoint)>,
    /// The violations a chart of as many points shows by chance when in control
    /// ([`accelcal_core::spc::violations_by_chance`]).
    pub expected_by_chance: f64,
}
