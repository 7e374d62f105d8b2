//! `accelcal fleet` (the line across units over a period, [`accelcal_db::fleet`]) and
//! `accelcal certificate` (a stored certificate printed again).

use accelcal_core::output::{utc_date_time, write_atomic, write_json};
use accelcal_db::asset::{start_of_day_unix_s, Asset, Date};
use accelcal_db::cells::UnreadableRun;
use accelcal_db::fleet::{Chart, Counts, DueUnit, Filter, FleetRun, Population};
use accelcal_db::recall::{AffectedRun, FoundBad, Recall, RecallState};
use accelcal_db::{CertificateState, Db};
use anyhow::Context;
use serde::Serialize;

use super::store::reader_spec;
use crate::settings::reader::Fleet;

/// Seconds in a day.
const DAY_S: i64 = 86_400;

/// `fleet --json`.
#[derive(Serialize)]
struct FleetJson<'a> {
    database: String,
    since: Date,
    until: Date,
    station: Option<&'a str>,
    head_asset: Option<&'a str>,
    serial_prefix: Option<&'a str>,
    operator: Option<&'a str>,
    counts: &'a Counts,
    /// The runs whose as-found verification was decided out of tolerance (conditional fail or
    /// fail): their units' users must be told.
    as_found_out_of_tolerance: Vec<&'a FleetRun>,
    populations: &'a [Population],
    due_by: Date,
    units_due: &'a [DueUnit],
    assets_due: Vec<&'a Asset>,
    /// Per head asset, its units' signature and change points (`accelcal_core::headsig`).
    heads: &'a [HeadJson],
    /// The control charts by head (or station) and quantity (`accelcal_core::spc`).
    charts: &'a [Chart],
    /// Each station's check standard (`station --check-standard`): its state and charts, over
    /// all its checks (the limits need the first 20), whatever the period.
    check_standards: &'a [accelcal_db::check::CheckStandard],
    /// The references found out of tolerance (`asset found-bad`) whose affected units are not
    /// all recalibrated or dismissed yet, whatever the period: each finding with its units still
    /// open (issue 59).
    recalls: Vec<RecallJson<'a>>,
    /// `null`, or why the database's hash chain is broken: the numbers may be forged.
    chain_broken: Option<&'a str>,
    /// The period's runs that do not read: each named by its cells that do not read as their
    /// column's type; they are in no other field.
    unreadable_runs: &'a [UnreadableRun],
    runs: &'a [FleetRun],
}

/// A finding with units still open (`fleet --json`'s `recalls`).
#[derive(Serialize)]
struct RecallJson<'a> {
    #[serde(flatten)]
    found_bad: &'a FoundBad,
    /// Why the finding's rows do not match their hash chain (its dismissals are then not taken).
    tampered: Option<&'a str>,
    /// The runs it affects, voided ones aside.
    runs: usize,
    /// The units it affects.
    units: usize,
    /// Of those, recalibrated on another reference since.
    recalibrated_units: usize,
    /// Of those, dismissed (no recall needed).
    dismissed_units: usize,
    /// The units still open, each by its latest affected run.
    open_units: Vec<&'a AffectedRun>,
}

impl<'a> RecallJson<'a> {
    fn of(r: &'a Recall) -> RecallJson<'a> {
        let units = r.units();
        let count = |s: RecallState| units.iter().filter(|u| u.state == s).count();
        RecallJson {
            found_bad: &r.found_bad,
            tampered: r.tampered.as_deref(),
            runs: r.runs.iter().filter(|x| x.voided.is_none()).count(),
            units: units.len(),
            recalibrated_units: count(RecallState::Recalibrated),
            dismissed_units: count(RecallState::Dismissed),
            open_units: r.open(),
        }
    }
}

/// One head asset's units tracked.
#[derive(Serialize)]
pub(crate) struct HeadJson {
    pub asset: String,
    #[serde(flatten)]
    pub head: accelcal_core::headsig::Head,
}

/// The head signature of every head asset over the period's runs that passed (not voided), each
/// unit observed from its stored campaign (the observation derived when it was stored), in the
/// order the runs started; a campaign that cannot be read is left out with a warning.
fn heads(db: &mut Db, filter: &Filter) -> anyhow::Result<Vec<HeadJson>> {
    use accelcal_core::headsig::{track, UnitObs};
    let seen = db.head_observations(filter)?;
    let stated = db.assets()?;
    let mut assets: Vec<&str> = seen.iter().map(|o| o.asset.as_str()).collect();
    assets.sort_unstable();
    assets.dedup();
    let mut out = Vec::new();
    for asset in assets {
        let mut units: Vec<UnitObs> = Vec::new();
        let mut g = accelcal_shared::G_STANDARD;
        for o in seen.iter().filter(|o| o.asset == asset) {
            match &o.seen {
                Err(why) => {
                    errln!(
                        "warning: head {asset}: run {}'s {why}: left out of the head's signature",
                        o.run_id
                    );
                }
                Ok(obs) => {
                    g = o.g_m_s2;
                    units.push(unit_obs(o, obs));
                }
            }
        }
        out.push(HeadJson {
            asset: asset.to_string(),
            head: track(&units, g, head_settings(&stated, asset)),
        });
    }
    Ok(out)
}

/// The tracking's settings for head asset `asset`: the default's, with the angle uncertainty its
/// certificate in force states (`assets`: every asset's) as the prior of its signature.
fn head_settings(assets: &[accelcal_db::Asset], asset: &str) -> accelcal_core::headsig::Settings {
    let s = accelcal_core::headsig::Settings::default();
    match assets.iter().find(|a| a.asset_id == asset && a.angle_u_arcsec > 0.0) {
        Some(a) => accelcal_core::headsig::Settings { head_u_arcsec: a.angle_u_arcsec, ..s },
        None => s,
    }
}

/// One unit's observation of its head, for the tracking.
fn unit_obs(
    o: &accelcal_db::fleet::HeadObservation,
    obs: &accelcal_db::derived::Observation,
) -> accelcal_core::headsig::UnitObs {
    accelcal_core::headsig::UnitObs {
        serial: o.serial.clone(),
        run_id: o.run_id.clone(),
        started_unix_s: o.started_unix_s,
        positions: obs.positions.clone(),
        resid_m_s2: obs.resid_m_s2.clone(),
        misalign_urad: obs.misalign_urad,
    }
}

/// Units of a head read for its measured angle error ([`measured_head_angle`]).
pub const MEASURED_UNITS: usize = 1000;

/// The head asset's angle setting error as its last [`MEASURED_UNITS`] passed units measure it
/// (those on the newest unit's plan, since the tracking's last change point among them;
/// `accelcal_core::headsig::MeasuredAngle`), for the budget of a calibration starting now:
/// `None` when fewer units than the tracking needs show it. A unit whose campaign showed
/// nothing of the head is left out.
pub fn measured_head_angle(
    db: &mut Db,
    asset: &str,
) -> anyhow::Result<Option<accelcal_core::headsig::MeasuredAngle>> {
    use accelcal_core::headsig::track;
    let now =
        std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map_or(0, |d| d.as_secs() as i64);
    let seen = db
        .latest_head_observations(asset, now + 1, MEASURED_UNITS)
        .with_context(|| format!("reading head asset {asset}'s units"))?;
    let read: Vec<_> = seen.iter().filter_map(|o| o.seen.as_ref().ok().map(|obs| (o, obs))).collect();
    let Some((newest, plan)) = read.last().map(|(o, obs)| (o, &obs.positions)) else { return Ok(None) };
    let units: Vec<_> =
        read.iter().filter(|(_, obs)| &obs.positions == plan).map(|(o, obs)| unit_obs(o, obs)).collect();
    let stated = db.assets().context("reading the assets")?;
    Ok(track(&units, newest.g_m_s2, head_settings(&stated, asset)).signature.measured_angle)
}

/// The warning that a head's units measure more angle error than its certificate states, and
/// that the budget takes theirs (`fit --head-asset` and the station say it alike); `None` when the
/// certificate covers it.
pub(crate) fn over_certificate(h: &Asset, m: &accelcal_core::headsig::MeasuredAngle) -> Option<String> {
    (m.rms_arcsec > h.angle_u_arcsec).then(|| {
        format!(
            "head asset {}: its last {} units measure {:.1}″ of angle error, more than its certificate's {}″: the budget takes the measured value (`accelcal fleet --head-asset {}` shows its signature)",
            h.asset_id, m.units, m.rms_arcsec, h.angle_u_arcsec, h.asset_id
        )
    })
}

/// The head's angle error as its units measure it, in words.
pub(crate) fn measured_line(m: &accelcal_core::headsig::MeasuredAngle) -> String {
    format!(
        "its angle error as its last {} units measure it: {:.1}″ RMS over {} head angles",
        m.units, m.rms_arcsec, m.angles
    )
}

/// A change point of a head's signature in words: its unit, run, time, rule and estimate.
pub(crate) fn change_point(c: &accelcal_core::headsig::ChangePoint) -> String {
    format!(
        "unit {} (run {}, {}): {}, {:.0} {}",
        if c.serial.is_empty() { "-" } else { &c.serial },
        c.run_id,
        utc_date_time(c.started_unix_s),
        c.rule,
        c.estimate,
        c.unit
    )
}

fn pct(n: i64, of: i64) -> String {
    if of == 0 {
        "-".into()
    } else {
        format!("{:.1} %", 100.0 * n as f64 / of as f64)
    }
}

/// Whether a decision is out of tolerance.
fn out_of_tolerance(decision: Option<&str>) -> bool {
    matches!(decision, Some("conditional fail" | "fail"))
}

/// What `fleet` and `serve` show of a period: every number computed from the stored pieces.
pub(crate) struct FleetData {
    pub counts: Counts,
    /// Each station's runs and those that passed.
    pub stations: Vec<(String, i64, i64)>,
    pub runs: Vec<FleetRun>,
    pub due_by: Date,
    pub units_due: Vec<DueUnit>,
    pub assets: Vec<Asset>,
    pub pops: Vec<Population>,
    pub heads: Vec<HeadJson>,
    pub charts: Vec<Chart>,
    pub check_standards: Vec<accelcal_db::check::CheckStandard>,
    /// Every finding (`asset found-bad`) with the runs it affects (of the units the serial
    /// prefix takes), whatever the period ([`FleetData::recalls_open`]).
    pub recalls: Vec<Recall>,
    /// `Some`: the ledger's shape says rows were written or removed behind accelcal's back
    /// (`Db::chain_broken`): every number here may be forged.
    pub chain_broken: Option<String>,
    /// The period's runs that do not read (a cell that does not read as its column's type):
    /// named, and in no table, population or chart ([`Db::listing_unreadable`]).
    pub unreadable: Vec<UnreadableRun>,
}

impl FleetData {
    /// The assets due by `due_by` (overdue included).
    pub fn assets_due(&self) -> Vec<&Asset> {
        self.assets.iter().filter(|x| x.due_date <= self.due_by).collect()
    }

    /// The findings whose affected units are not all recalibrated or dismissed (or whose rows do
    /// not match their chain): what `fleet` and `serve` show until each unit is.
    pub fn recalls_open(&self) -> Vec<&Recall> {
        self.recalls.iter().filter(|r| r.tampered.is_some() || !r.open().is_empty()).collect()
    }

    /// What became of each run a finding affects, by run id: the state and the finding's
    /// reference (`HEAD-1 DKD-17-001`).
    pub fn recall_of_runs(&self) -> std::collections::HashMap<&str, (RecallState, String)> {
        let mut out = std::collections::HashMap::new();
        for r in &self.recalls {
            for x in &r.runs {
                let state = x.recall.unwrap_or(RecallState::Open);
                out.insert(
                    x.run_id.as_str(),
                    (state, format!("{} {}", r.found_bad.asset_id, r.found_bad.certificate)),
                );
            }
        }
        out
    }

    /// The runs whose as-found verification was out of tolerance (not voided).
    pub fn found_out(&self) -> Vec<&FleetRun> {
        self.runs
            .iter()
            .filter(|r| r.state != "voided" && out_of_tolerance(r.as_found_decision.as_deref()))
            .collect()
    }
}

/// The filter of a period of whole UTC days.
pub(crate) fn filter_of(
    since: Date,
    until: Date,
    station: Option<String>,
    head_asset: Option<String>,
    serial_prefix: Option<String>,
    operator: Option<String>,
) -> Filter {
    Filter {
        since_unix_s: start_of_day_unix_s(since),
        until_unix_s: start_of_day_unix_s(until) + DAY_S,
        station,
        head_asset,
        serial_prefix,
        operator,
        tampered: None,
    }
}

/// What [`gather`] works out besides the counts, the stations and what is due: only what the
/// caller shows.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Parts {
    /// The runs, the populations, the control charts and the heads' signatures (every point of
    /// the period).
    Charts,
    /// The runs and the populations.
    Table,
    /// The runs, the control charts and the heads' signatures, not the populations: the
    /// overview's counts and what needs attention (`app::attention`).
    Attention,
}

/// Gathers a period's fleet from the database; `due_by`: the last day of the units and assets due.
pub(crate) fn gather(db: &mut Db, filter: &Filter, due_by: Date, parts: Parts) -> anyhow::Result<FleetData> {
    // The period's runs are checked against their chain once, first: every count, population,
    // chart and signature below sets the tampered ones aside, and the runs' table marks them.
    let checked = db.checked(filter)?;
    let filter = &checked;
    // The populations and the heads' signatures read every parameter and observation of the
    // period: each on a connection of its own (a reader takes no lock, so they run at once),
    // started first, while this one counts, finds what is due, reads the runs and draws the
    // control charts from them. On the whole line (a month of 8,200 runs) the populations
    // take the longest; counting first and then starting them left one core idle.
    std::thread::scope(|s| -> anyhow::Result<FleetData> {
        let joined = |what: &str| anyhow::anyhow!("the thread reading {what} panicked");
        let (h, p) = match parts {
            Parts::Attention => {
                let mut dh = db.open_again()?;
                (Some(s.spawn(move || (heads(&mut dh, filter), dh))), None)
            }
            Parts::Charts => {
                let (mut dh, mut dp) = (db.open_again()?, db.open_again()?);
                (
                    Some(s.spawn(move || (heads(&mut dh, filter), dh))),
                    Some(s.spawn(move || (dp.populations(filter), dp))),
                )
            }
            Parts::Table => {
                let mut dp = db.open_again()?;
                (None, Some(s.spawn(move || (dp.populations(filter), dp))))
            }
        };
        let mut counts = db.fleet_counts(filter)?;
        let stations = std::mem::take(&mut counts.stations);
        let units_due = db.units_due(start_of_day_unix_s(due_by) + DAY_S, filter.serial_prefix.as_deref())?;
        let assets = db.assets()?;
        let runs = db.fleet_runs(filter)?;
        let charts = match parts {
            Parts::Charts | Parts::Attention => accelcal_db::fleet::charts(&runs),
            Parts::Table => Vec::new(),
        };
        let check_standards = db.check_standards(filter.station.as_deref())?;
        let mut recalls = db.recalls(None)?;
        if let Some(p) = filter.serial_prefix.as_deref() {
            for r in &mut recalls {
                r.runs.retain(|x| x.serial.starts_with(p));
            }
        }
        let chain_broken = db.chain_broken()?;
        let pops = match p {
            Some(p) => {
                let (pops, mut dp) = p.join().map_err(|_| joined("the populations"))?;
                db.unreadable_from(&mut dp);
                pops?
            }
            None => Vec::new(),
        };
        let heads = match h {
            Some(h) => {
                let (heads, mut dh) = h.join().map_err(|_| joined("the heads' signatures"))?;
                db.unreadable_from(&mut dh);
                heads?
            }
            None => Vec::new(),
        };
        let unreadable = db.unreadable()?;
        Ok(FleetData {
            counts,
            stations,
            runs,
            due_by,
            units_due,
            assets,
            pops,
            heads,
            charts,
            check_standards,
            recalls,
            chain_broken,
            unreadable,
        })
    })
}

/// The last day of the units due: `days` after `until`.
pub(crate) fn due_by(until: Date, days: u32) -> anyhow::Result<Date> {
    until.checked_add(std::time::Duration::from_secs(u64::from(days) * DAY_S as u64)).context("--due-days")
}

/// Runs `accelcal fleet`.
pub fn run(a: &Fleet) -> anyhow::Result<()> {
    let (since, until) = (a.since, a.until);
    let filter = filter_of(
        since,
        until,
        a.station.clone(),
        a.head_asset.clone(),
        a.serial_prefix.clone(),
        a.operator.clone(),
    );
    let mut db = Db::open_existing(&reader_spec(a.db.as_deref())?)?.listing_unreadable();
    let data = gather(&mut db, &filter, due_by(until, a.due_days)?, Parts::Charts)?;
    let FleetData { counts, runs, due_by, units_due, pops, heads, charts, check_standards, .. } = &data;
    let (runs, due_by) = (runs.as_slice(), *due_by);
    let (pops, heads, charts) = (pops.as_slice(), heads.as_slice(), charts.as_slice());
    let (units_due, check_standards) = (units_due.as_slice(), check_standards.as_slice());
    let assets_due = data.assets_due();
    let found_out = data.found_out();

    let filters: Vec<String> = [
        ("station", &a.station),
        ("head", &a.head_asset),
        ("serials", &a.serial_prefix),
        ("operator", &a.operator),
    ]
    .iter()
    .filter_map(|(k, v)| v.as_ref().map(|v| format!("{k} {v}")))
    .collect();
    outln!(
        "fleet: {since} to {until} (UTC) in {}{}: {} of {}{}",
        db.target(),
        if filters.is_empty() { String::new() } else { format!(" ({})", filters.join(", ")) },
        crate::out::count(counts.runs, "run"),
        crate::out::count(counts.units, "unit"),
        counts.set_aside().map(|s| format!(" ({s})")).unwrap_or_default()
    )?;
    if let Some(why) = &data.chain_broken {
        outln!("  WARNING: the database's hash chain is broken ({why}): these numbers may be forged; `accelcal db verify` lists what does not match")?;
    }
    let tampered: Vec<&FleetRun> = runs.iter().filter(|r| r.tampered.is_some()).collect();
    if !tampered.is_empty() {
        outln!(
            "  TAMPERED: {} run{} whose rows do not match their hash chain (set aside: in no count, yield, population or chart; `accelcal db verify` lists every mismatch):",
            tampered.len(),
            if tampered.len() == 1 { "" } else { "s" }
        )?;
        for r in tampered {
            outln!("    run {} ({}): {}", r.run_id, r.serial, r.tampered.as_deref().unwrap_or_default())?;
        }
    }
    for u in &data.unreadable {
        outln!("  UNREADABLE, left out of whatever reads its bad cells (counted): {u}")?;
    }
    outln!(
        "  runs: {} pass, {} rejected, {} unfinished, {} voided",
        counts.passed,
        counts.rejected,
        counts.unfinished,
        counts.voided
    )?;
    outln!(
        "  yield: first pass {}/{} units ({}), final {}/{} ({})",
        counts.first_pass_units,
        counts.units_finished,
        pct(counts.first_pass_units, counts.units_finished),
        counts.final_pass_units,
        counts.units_finished,
        pct(counts.final_pass_units, counts.units_finished)
    )?;
    for (reason, n) in &counts.rejections {
        outln!("  rejected {n}×: {reason}")?;
    }
    // Where the period's certificates stand (issue 57): those a signer has yet to decide first.
    let state_count = |st: CertificateState| {
        runs.iter().filter(|r| r.tampered.is_none() && r.certificate_state == Some(st)).count()
    };
    let (awaiting, approved, rejected) = (
        state_count(CertificateState::AwaitingApproval),
        state_count(CertificateState::Approved),
        state_count(CertificateState::Rejected),
    );
    if awaiting + approved + rejected > 0 {
        outln!("  certificates: {awaiting} awaiting approval, {approved} approved, {rejected} rejected")?;
    }
    if found_out.is_empty() {
        outln!("  as found out of tolerance: none")?;
    }
    for r in &found_out {
        outln!(
            "  as found out of tolerance: {} ({}) run {} {}: {}",
            if r.serial.is_empty() { "-" } else { &r.serial },
            r.device_id,
            r.run_id,
            utc_date_time(r.started_unix_s),
            r.as_found_decision.as_deref().unwrap_or("-")
        )?;
    }
    // The units a reference found out of tolerance calibrated, until each is recalibrated on
    // another reference or dismissed, whatever the period (issue 59).
    let recalls = data.recalls_open();
    if recalls.is_empty() {
        outln!("  recalls (references found out of tolerance): none open")?;
    }
    for r in &recalls {
        let j = RecallJson::of(r);
        outln!(
            "  recall: {}: {} units, {} recalibrated, {} dismissed, {} open{}",
            crate::app::recall::finding(&r.found_bad),
            j.units,
            j.recalibrated_units,
            j.dismissed_units,
            j.open_units.len(),
            r.tampered.as_ref().map(|t| format!(" (TAMPERED: {t}; no dismissal taken)")).unwrap_or_default()
        )?;
        for x in &j.open_units {
            outln!(
                "    {} ({}) run {} {}: certificate {}",
                if x.serial.is_empty() { "-" } else { &x.serial },
                x.device_id,
                x.run_id,
                utc_date_time(x.started_unix_s),
                crate::app::recall::certificate(x)
            )?;
        }
    }
    // A unit calibrated twice in the period is two runs of one unit (issue 59).
    let calibrated = pops.first().map_or(0, |p| p.n);
    let passed_units: std::collections::BTreeSet<&str> = runs
        .iter()
        .filter(|r| r.state == "pass" && r.tampered.is_none())
        .map(|r| r.device_id.as_str())
        .collect();
    outln!(
        "  populations of the {} of {} that passed (Cpk = min(L − mean, mean + L)/(3·s) against the specification's ±L):",
        crate::out::count(calibrated, "run"),
        crate::out::count(passed_units.len(), "unit")
    )?;
    outln!(
        "    {:<30} {:>8} {:>4} {:>14} {:>12} {:>10} {:>6}",
        "",
        "unit",
        "n",
        "mean",
        "s",
        "limit",
        "Cpk"
    )?;
    for p in pops {
        outln!(
            "    {:<30} {:>8} {:>4} {:>14} {:>12} {:>10} {:>6}",
            p.name,
            p.unit,
            p.n,
            format!("{:+.4}", p.mean),
            format!("{:.4}", p.sd),
            p.limit.map_or("-".into(), |l| format!("±{l}")),
            p.cpk.map_or("-".into(), |c| format!("{c:.2}"))
        )?;
    }
    let broken: Vec<&Chart> = charts.iter().filter(|c| !c.violations.is_empty()).collect();
    outln!(
        "  control charts (I-MR, Western Electric rules, limits from the points charted): {} charts, {} out of control",
        charts.len(),
        broken.len()
    )?;
    for c in broken {
        let (v, p) = c.violations.last().expect("a violation");
        outln!(
            "    {}, {} ({}): {} violation{} in {} points (about {:.1} by chance), the last rule {} ({}) at {} (run {}, {}): {:.6}, centre {:.6}, limits {:.6} .. {:.6}",
            c.group,
            c.quantity,
            c.unit,
            c.violations.len(),
            if c.violations.len() == 1 { "" } else { "s" },
            c.points.len(),
            c.expected_by_chance,
            v.rule,
            v.what,
            if p.serial.is_empty() { "-" } else { &p.serial },
            p.run_id,
            utc_date_time(p.started_unix_s),
            p.value,
            c.limits.center,
            c.limits.lcl,
            c.limits.ucl
        )?;
    }
    for c in check_standards {
        outln!(
            "  check standard of {}: {}, {} checks, {}{}",
            c.station,
            c.serial,
            c.checks,
            c.state.to_uppercase(),
            c.why.as_ref().map(|w| format!(" ({w})")).unwrap_or_default()
        )?;
    }
    for h in heads {
        let s = h.head.settings_line();
        match h.head.change_points.last() {
            None => outln!("  head {}: {} units, no change point ({s})", h.asset, h.head.units)?,
            Some(c) => outln!(
                "  head {}: {} units, {} change point{}, the last at {}",
                h.asset,
                h.head.units,
                h.head.change_points.len(),
                if h.head.change_points.len() == 1 { "" } else { "s" },
                change_point(c)
            )?,
        }
        if let Some(m) = &h.head.signature.measured_angle {
            outln!("    {}", measured_line(m))?;
        }
    }
    outln!(
        "  units due for recalibration by {due_by} ({} days after {until}, overdue included):",
        a.due_days
    )?;
    if units_due.is_empty() {
        outln!("    none")?;
    }
    for u in units_due {
        outln!(
            "    {:<16} {}  due {}  (certificate of run {})",
            if u.serial.is_empty() { "-" } else { &u.serial },
            u.device_id,
            &utc_date_time(u.due_unix_s)[..10],
            u.run_id
        )?;
    }
    outln!("  assets due by {due_by}:")?;
    if assets_due.is_empty() {
        outln!("    none")?;
    }
    for x in &assets_due {
        outln!("    {} ({}) certificate {}, due {}", x.asset_id, x.kind.name(), x.certificate, x.due_date)?;
    }
    if let Some(c) = &a.csv {
        let customers = db.run_customers(certified(runs))?;
        write_atomic(c, csv_of(runs, &data, &customers)?.as_bytes())?;
        outln!("wrote {} ({} runs)", c.display(), runs.len())?;
    }
    if let Some(j) = &a.json {
        write_json(
            j,
            &FleetJson {
                database: db.target(),
                since,
                until,
                station: a.station.as_deref(),
                head_asset: a.head_asset.as_deref(),
                serial_prefix: a.serial_prefix.as_deref(),
                operator: a.operator.as_deref(),
                counts,
                as_found_out_of_tolerance: found_out,
                populations: pops,
                due_by,
                units_due,
                assets_due,
                heads,
                charts,
                check_standards,
                recalls: recalls.iter().map(|r| RecallJson::of(r)).collect(),
                chain_broken: data.chain_broken.as_deref(),
                unreadable_runs: &data.unreadable,
                runs,
            },
        )?;
        outln!("wrote {}", j.display())?;
    }
    Ok(())
}

/// A text cell of a CSV as a spreadsheet must read it: a cell that begins with `=`, `+`, `-`, `@`,
/// a tab or a carriage return would be run as a formula (`=HYPERLINK(...)`, `@SUM(...)`, DDE), so
/// it is prefixed with a single quote, as OWASP's "CSV Injection" page says; every other text
/// is kept as it is. Only text columns go through it: a negative number stays a number.
pub(crate) fn spreadsheet_text(cell: &str) -> String {
    if cell.starts_with(['=', '+', '-', '@', '\t', '\r']) {
        format!("'{cell}")
    } else {
        cell.to_string()
    }
}

/// One row per run: the columns an MES takes (`fleet --csv` and serve's `/fleet.csv`); `recall`
/// is what became of a run a reference found out of tolerance calibrated (`open`,
/// `recalibrated`, `dismissed`, `voided`; empty for the others) and `recall_reference` that
/// reference (`HEAD-1 DKD-17-001`), from `data`'s findings. Text cells are neutralised
/// ([`spreadsheet_text`]) and quoted, numbers are written unquoted.
/// The runs of `runs` that hold a certificate: those whose customer the CSV states.
pub(crate) fn certified(runs: &[FleetRun]) -> impl Iterator<Item = &str> {
    runs.iter().filter(|r| r.certificate_number.is_some()).map(|r| r.run_id.as_str())
}

pub(crate) fn csv_of(
    runs: &[FleetRun],
    data: &FleetData,
    customers: &std::collections::HashMap<String, String>,
) -> anyhow::Result<String> {
    let recall = data.recall_of_runs();
    let mut w = csv::WriterBuilder::new().quote_style(csv::QuoteStyle::NonNumeric).from_writer(Vec::new());
    let mut header: Vec<String> = [
        "run_id",
        "serial",
        "device_id",
        "station",
        "head_asset",
        "operator",
        "started_utc",
        "ended_utc",
        "state",
        "reason",
        "as_found_decision",
        "as_left_decision",
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    for ch in ["x", "y", "z"] {
        for t in ["1", "ax", "ay", "az"] {
            header.push(format!("{ch}_{t}"));
        }
    }
    header.extend(["U_x_m_s2", "U_y_m_s2", "U_z_m_s2"].map(String::from));
    header.extend(["certificate_number", "certificate_state", "due_date", "record_crc"].map(String::from));
    header.extend(["recall", "recall_reference", "customer"].map(String::from));
    w.write_record(&header)?;
    for r in runs {
        let mut row = vec![
            spreadsheet_text(&r.run_id),
            spreadsheet_text(&r.serial),
            spreadsheet_text(&r.device_id),
            spreadsheet_text(&r.station),
            spreadsheet_text(r.head_asset.as_deref().unwrap_or_default()),
            spreadsheet_text(&r.operator),
            utc_date_time(r.started_unix_s),
            r.ended_unix_s.map(utc_date_time).unwrap_or_default(),
            spreadsheet_text(r.shown_state()),
            spreadsheet_text(r.reason.as_deref().unwrap_or_default()),
            spreadsheet_text(r.as_found_decision.as_deref().unwrap_or_default()),
            spreadsheet_text(r.as_left_decision.as_deref().unwrap_or_default()),
        ];
        match r.model4() {
            Some(m) => row.extend(m.iter().flatten().map(|v| format!("{v}"))),
            None => row.extend(std::iter::repeat_n(String::new(), 12)),
        }
        match r.u_m_s2() {
            Some(u) => row.extend(u.iter().map(|v| format!("{v}"))),
            None => row.extend(std::iter::repeat_n(String::new(), 3)),
        }
        row.push(spreadsheet_text(r.certificate_number.as_deref().unwrap_or_default()));
        row.push(spreadsheet_text(r.certificate_state.map(|c| c.words()).unwrap_or_default()));
        row.push(r.due_unix_s.map(|t| utc_date_time(t).chars().take(10).collect()).unwrap_or_default());
        row.push(spreadsheet_text(r.record_crc32.as_deref().unwrap_or_default()));
        let (state, reference) = match recall.get(r.run_id.as_str()) {
            Some((s, reference)) => (s.words(), reference.as_str()),
            None => ("", ""),
        };
        row.push(state.to_string());
        row.push(spreadsheet_text(reference));
        row.push(spreadsheet_text(customers.get(&r.run_id).map(String::as_str).unwrap_or_default()));
        w.write_record(&row)?;
    }
    let bytes = w.into_inner().map_err(|e| anyhow::anyhow!("writing the CSV: {e}"))?;
    String::from_utf8(bytes).context("the CSV is UTF-8")
}

/// The changes `bench-signature` studies at each unit of `--change-at`.
const BENCH_CHANGES: [accelcal_core::headsig::HeadChange; 7] = {
    use accelcal_core::headsig::HeadChange::{Mount, Offset};
    [
        Offset { position: 26, mrad: 0.5 },
        Offset { position: 7, mrad: 0.5 },
        Offset { position: 7, mrad: 0.25 },
        // Weaker: how small an error the tracking still finds, and how late.
        Offset { position: 26, mrad: 0.25 },
        Offset { position: 26, mrad: 0.1 },
        Mount { mrad: 1.0 },
        Mount { mrad: 0.5 },
    ]
};

/// A case of `bench-signature` in words, with its estimate's unit.
fn bench_case(c: accelcal_core::headsig::HeadChange) -> (String, &'static str) {
    use accelcal_core::headsig::HeadChange;
    match c {
        HeadChange::None => ("none (a true head)".to_string(), ""),
        HeadChange::Offset { position, mrad } => {
            let (al, be) = accelcal_core::sim::Plan::head().positions[position];
            (format!("α of position {} (α {al}°, β {be}°) +{mrad} mrad", position + 1), "″")
        }
        HeadChange::Mount { mrad } => (format!("mount rotated {mrad} mrad about z"), "µrad"),
        HeadChange::Errors { arcsec, .. } => (format!("every angle off by a draw of {arcsec}″"), "″"),
    }
}

/// Flagged fleets and the median and longest delay of `delays`, in words.
fn delay_cells(delays: &[Option<usize>]) -> (String, String, String) {
    let mut d: Vec<usize> = delays.iter().flatten().copied().collect();
    d.sort_unstable();
    let flagged = format!("{}/{}", d.len(), delays.len());
    // The median over every fleet, a fleet not flagged counting as the longest.
    let median =
        if 2 * d.len() > delays.len() { format!("{}", d[(delays.len() - 1) / 2]) } else { "-".into() };
    let longest =
        if d.len() == delays.len() { d.last().map_or("-".into(), |m| m.to_string()) } else { "-".into() };
    (flagged, median, longest)
}

/// Runs `accelcal bench-signature`.
pub fn run_bench_signature(a: &crate::settings::campaign::BenchSignature) -> anyhow::Result<()> {
    use accelcal_core::headsig::{study, HeadChange, Settings, DESIGN_UNITS_PER_FALSE_ALARM};
    let s = Settings { head_u_arcsec: a.head_u, ..Settings::default() };
    let (fleets, units) = (a.fleets as usize, a.units as usize);
    let mut rows = study(&[HeadChange::None], fleets, units, units, s);
    for &at in &a.change_at {
        let len = units.min(at as usize + a.after as usize);
        rows.extend(study(&BENCH_CHANGES, fleets, len, at as usize, s));
    }
    outln!(
        "head signature: {fleets} fleets per case, the head changed at a unit the tracking is not told; tracked from unit {} (a reference of at least {} units; the head's stated angle uncertainty {}″), each CUSUM tuned to 0.5 mrad of its angle or 1 mrad of mount rotation (k = {} of it; h = {:.2} at one standard deviation), designed for one false alarm in {DESIGN_UNITS_PER_FALSE_ALARM} units of a true head; the oracle: a CUSUM on the one statistic the change moves, told its size, sign and in-control mean and spread, at the same design rate",
        s.baseline + 1, s.baseline, a.head_u, s.k, s.h
    )?;
    let true_units: usize = rows.iter().map(|r| r.fleets * r.change_at).sum();
    let false_alarms: usize = rows.iter().map(|r| r.false_alarms).sum();
    outln!(
        "false alarms: {false_alarms} in {true_units} units of a true head ({:.3} per 1,000 units; {fleets} true heads of {units} units and the units before each change)",
        1000.0 * false_alarms as f64 / true_units.max(1) as f64
    )?;
    for &at in &a.change_at {
        outln!(
            "\nchange at unit {at} ({} units simulated after it)",
            units.min(at as usize + a.after as usize) - at as usize
        )?;
        outln!(
            "{:<44} {:>8} {:>7} {:>8} {:>8} {:>7} {:>10} {:>9} {:>6}",
            "change",
            "flagged",
            "median",
            "longest",
            "oracle",
            "median",
            "mean est.",
            "true",
            "error"
        )?;
        for r in rows.iter().filter(|r| r.change != HeadChange::None && r.change_at == at as usize) {
            let (case, unit) = bench_case(r.change);
            let (flagged, median, longest) = delay_cells(&r.delays);
            let (o_flagged, o_median, _) = delay_cells(&r.oracle_delays);
            let mean = r.estimates.iter().sum::<f64>() / r.estimates.len().max(1) as f64;
            let err = r.estimates.iter().map(|e| (e - r.true_change).abs()).sum::<f64>()
                / r.estimates.len().max(1) as f64
                / r.true_change.abs().max(f64::MIN_POSITIVE);
            let (est, error) = if r.estimates.is_empty() {
                ("-".to_string(), "-".to_string())
            } else {
                (format!("{mean:.0}{unit}"), format!("{:.0} %", 100.0 * err))
            };
            outln!(
                "{:<44} {:>8} {:>7} {:>8} {:>8} {:>7} {:>10} {:>9} {:>6}",
                case,
                flagged,
                median,
                longest,
                o_flagged,
                o_median,
                est,
                format!("{:.0}{unit}", r.true_change),
                error
            )?;
        }
    }
    outln!("delays in units after the change (0: flagged at the changed unit itself); a median is \"-\" when half the fleets or more are not flagged, a longest when any is not; error: the mean of |estimate − true| over the flagged fleets, relative to the true change")?;
    if let Some(j) = &a.json {
        write_json(j, &rows)?;
        outln!("wrote {}", j.display())?;
    }
    Ok(())
}
