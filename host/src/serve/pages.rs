//! The pages of `accelcal serve`: what each shows, gathered from the database with the functions
//! `fleet`, `history` and `certificate` use, formatted into the askama templates of
//! `host/templates/serve/` (which escape every value).

use accelcal_core::output::utc_date_time;
use accelcal_db::asset::{parse_date, today_utc, Date};
use accelcal_db::fleet::{Counts, FleetRun};
use accelcal_db::history::{history, DEFAULT_RULE};
use accelcal_db::{Db, DbError, Outcome, RunId};
use askama::Template;
use axum::http::StatusCode;

use super::escape;
use super::svg::{control_chart, drift_chart, signature_chart, Lines};
use super::{links, App, PageError};
use crate::app::attention;
use crate::cmd::fleet::{
    certified, change_point, csv_of, due_by, filter_of, gather, measured_line, FleetData, Parts,
};
use crate::cmd::history::{outcome, verification};
use crate::report::sig;
use crate::settings::reader::Which;

pub(super) const VERSION: &str = env!("CARGO_PKG_VERSION");

/// The filters of the fleet and charts pages, as the form sends them (`fleet`'s options).
#[derive(Debug, Default, serde::Deserialize)]
struct Filters {
    since: Option<String>,
    until: Option<String>,
    station: Option<String>,
    head_asset: Option<String>,
    serial_prefix: Option<String>,
    operator: Option<String>,
}

/// A field of the form: an empty one is no filter.
fn given(s: &Option<String>) -> Option<String> {
    s.as_ref().map(|v| v.trim().to_string()).filter(|v| !v.is_empty())
}

impl Filters {
    fn parse(q: &str) -> Result<Filters, PageError> {
        serde_urlencoded::from_str(q).map_err(|e| PageError::bad(format!("the query `{q}`: {e}")))
    }

    /// The period: `until` (default today), `since` (default 30 days before it), and the day up
    /// to which what falls due is listed (`due_days` after `until`). A day the view cannot count
    /// from is refused naming its field.
    fn period(&self, due_days: u32) -> Result<(Date, Date, Date), PageError> {
        let day = |name: &str, v: &Option<String>| -> Result<Option<Date>, PageError> {
            given(v).map(|s| parse_date(&s).map_err(|e| PageError::bad(format!("{name}: {e}")))).transpose()
        };
        let until = day("until", &self.until)?.unwrap_or_else(today_utc);
        let since = crate::settings::reader::period_start(day("since", &self.since)?, until)
            .ok_or_else(|| PageError::bad("until is too early"))?;
        if since > until {
            return Err(PageError::bad(format!("since {since} is after until {until}: the period is empty")));
        }
        let due = due_by(until, due_days).map_err(|_| {
            PageError::bad(format!(
                "until: {until} is too late: this view lists what falls due up to {due_days} days after it \
                 (serve --due-days), beyond the last day it can count"
            ))
        })?;
        Ok((since, until, due))
    }

    fn gather(&self, db: &mut Db, due_days: u32, parts: Parts) -> Result<(FleetData, Date, Date), PageError> {
        let (since, until, due) = self.period(due_days)?;
        let f = filter_of(
            since,
            until,
            given(&self.station),
            given(&self.head_asset),
            given(&self.serial_prefix),
            given(&self.operator),
        );
        let data = gather(db, &f, due, parts).map_err(PageError::of)?;
        Ok((data, since, until))
    }

    /// The form's fields as the page shows them again.
    fn form(&self, since: Date, until: Date) -> Form {
        Form {
            since: since.to_string(),
            until: until.to_string(),
            station: given(&self.station).unwrap_or_default(),
            head_asset: given(&self.head_asset).unwrap_or_default(),
            serial_prefix: given(&self.serial_prefix).unwrap_or_default(),
            operator: given(&self.operator).unwrap_or_default(),
        }
    }
}

/// The filter form's values.
struct Form {
    since: String,
    until: String,
    station: String,
    head_asset: String,
    serial_prefix: String,
    operator: String,
}

/// A period's counts as the pages show them.
struct CountsView {
    runs: i64,
    units: i64,
    passed: i64,
    rejected: i64,
    unfinished: i64,
    voided: i64,
    first_pass: String,
    final_pass: String,
    rejections: Vec<(String, i64)>,
    /// `; 1 tampered run set aside` when any were (empty otherwise).
    set_aside: String,
}

fn pct(n: i64, of: i64) -> String {
    if of == 0 {
        "-".into()
    } else {
        format!("{n}/{of} ({:.1} %)", 100.0 * n as f64 / of as f64)
    }
}

impl From<&Counts> for CountsView {
    fn from(c: &Counts) -> CountsView {
        CountsView {
            runs: c.runs,
            units: c.units,
            passed: c.passed,
            rejected: c.rejected,
            unfinished: c.unfinished,
            voided: c.voided,
            first_pass: pct(c.first_pass_units, c.units_finished),
            final_pass: pct(c.final_pass_units, c.units_finished),
            rejections: c.rejections.clone(),
            set_aside: c.set_aside().map(|s| format!("; {s}")).unwrap_or_default(),
        }
    }
}

/// One run in a table.
struct RunRow {
    run_id: String,
    /// The run's first 8 hex digits (what the search box takes), and its link.
    run_short: String,
    run_href: String,
    /// Its certificate in force: its number and link (empty: none).
    certificate: String,
    certificate_href: String,
    /// Where it stands (`awaiting approval`, …; empty: no certificate).
    certificate_state: &'static str,
    serial: String,
    device_id: String,
    /// The unit's page, by its serial, else its device id.
    unit_href: String,
    station: String,
    head: String,
    operator: String,
    started: String,
    state: String,
    reason: String,
    as_found: String,
    as_left: String,
    /// The largest U of the fit, m/s² (empty: none).
    u_max: String,
    /// The model-4 coefficients, `x:1 … z:az` (empty: none).
    coefficients: Vec<String>,
}

impl From<&FleetRun> for RunRow {
    fn from(r: &FleetRun) -> RunRow {
        RunRow {
            run_id: r.run_id.clone(),
            run_short: r.run_id.chars().take(8).collect(),
            run_href: links::run(&r.run_id),
            certificate: r.certificate_number.clone().unwrap_or_default(),
            certificate_state: r.certificate_state.map(|s| s.words()).unwrap_or_default(),
            certificate_href: r.certificate_number.as_deref().map(links::certificate).unwrap_or_default(),
            serial: r.serial.clone(),
            device_id: r.device_id.clone(),
            unit_href: links::unit(if r.serial.is_empty() { &r.device_id } else { &r.serial }),
            station: r.station.clone(),
            head: r.head_asset.clone().unwrap_or_default(),
            operator: r.operator.clone(),
            started: utc_date_time(r.started_unix_s),
            state: r.shown_state().to_string(),
            reason: match &r.tampered {
                Some(why) => format!("TAMPERED, not used: {why}"),
                None => r.reason.clone().unwrap_or_default(),
            },
            as_found: r.as_found_decision.clone().unwrap_or_default(),
            as_left: r.as_left_decision.clone().unwrap_or_default(),
            u_max: r
                .u_m_s2()
                .map(|u| format!("{:.3e}", u.into_iter().fold(0.0, f64::max)))
                .unwrap_or_default(),
            coefficients: r
                .model4()
                .map(|m| m.iter().flatten().map(|v| sig(*v, 5)).collect())
                .unwrap_or_default(),
        }
    }
}

/// The runs set aside, each in words (its bad cells named).
fn words(runs: &[accelcal_db::cells::UnreadableRun]) -> Vec<String> {
    runs.iter().map(ToString::to_string).collect()
}

struct StationRow {
    name: String,
    runs: usize,
    passed: usize,
    check: String,
}

struct AssetRow {
    id: String,
    kind: &'static str,
    certificate: String,
    due: String,
    state: &'static str,
}

/// A unit still to recall (`FleetData::recalls_open`), a row of the overview.
struct RecallRow {
    /// The finding's reference and certificate: `HEAD-1 (head) certificate DKD-17-001`.
    reference: String,
    /// From which day, and why.
    finding: String,
    serial: String,
    device_id: String,
    unit_key: String,
    run_id: String,
    started: String,
    /// The unit's certificate in force for the run, in words.
    certificate: String,
}

struct DueRow {
    serial: String,
    device_id: String,
    unit_href: String,
    due: String,
    run: RunLink,
}

/// A run id as a link to its row on its unit's page.
struct RunLink {
    id: String,
    href: String,
}

impl RunLink {
    fn of(id: &str) -> RunLink {
        RunLink { id: id.to_string(), href: links::run(id) }
    }
}

/// A line of text that names a run: the text before the run's id, the id as a link, the rest.
struct Linked {
    before: String,
    run: Option<RunLink>,
    after: String,
}

impl Linked {
    /// `text` with the first `run_id` in it a link (none when it is not there).
    fn around(text: String, run_id: &str) -> Linked {
        match text.find(run_id).filter(|_| !run_id.is_empty()) {
            Some(at) => Linked {
                before: text[..at].to_string(),
                run: Some(RunLink::of(run_id)),
                after: text[at + run_id.len()..].to_string(),
            },
            None => Linked { before: text, run: None, after: String::new() },
        }
    }
}

/// The attention panel's entries of one kind at most (the rest are counted, with a link to them).
const ATTENTION_PER_KIND: usize = 10;

/// An entry of the panel of what needs attention: its kind, its words, where it links.
struct AttentionRow {
    kind: &'static str,
    words: String,
    href: String,
}

#[derive(Template)]
#[template(path = "serve/overview.html")]
struct OverviewPage<'a> {
    db: &'a str,
    version: &'a str,
    /// The runs the page's reads set aside (`Db::listing_unreadable`), in words.
    unreadable: Vec<String>,
    today: String,
    day: CountsView,
    month: CountsView,
    month_since: String,
    stations: Vec<StationRow>,
    assets: Vec<AssetRow>,
    month_until: String,
    /// What needs attention (`app::attention`), first on the page.
    attention: Vec<AttentionRow>,
    due_by: String,
    due: Vec<DueRow>,
    /// The units references found out of tolerance calibrated, not yet recalibrated or dismissed.
    recalls: Vec<RecallRow>,
    /// The findings whose recall rows do not match their hash chain, in words.
    recalls_tampered: Vec<String>,
    today_runs: Vec<RunRow>,
    /// Why the database's hash chain is broken, when it is (`FleetData::chain_broken`).
    chain_broken: Option<String>,
}

/// `/`: what needs attention, today's units, the period's yield (the last 30 days unless the
/// query gives `since` and `until`), stations, assets and units due.
pub(super) fn overview(db: &mut Db, app: &App, q: &str) -> Result<String, PageError> {
    let today = today_utc();
    let month = Filters::parse(q)?;
    let (data, since, until) = month.gather(db, app.due_days, Parts::Attention)?;
    let found_out = data.found_out();
    let recalls_open = data.recalls_open();
    let period = format!("since={since}&until={until}");
    let all = attention::entries(&attention::Sources {
        recalls: &recalls_open,
        today,
        assets: &data.assets,
        charts: &data.charts,
        heads: data.heads.iter().map(|h| (h.asset.as_str(), h.head.change_points.as_slice())).collect(),
        found_out: &found_out,
        runs: &data.runs,
    });
    let panel = attention::panel(all, ATTENTION_PER_KIND);
    // Each kind's entries, then how many of it were left out, with a link to them all.
    let mut attention: Vec<AttentionRow> = Vec::new();
    for (i, e) in panel.shown.iter().enumerate() {
        attention.push(AttentionRow {
            kind: e.kind(),
            words: e.words(),
            href: links::href(&e.page(), &period),
        });
        if panel.shown.get(i + 1).is_some_and(|next| next.kind() == e.kind()) {
            continue;
        }
        if let Some((kind, n, page)) = panel.left_out.iter().find(|l| l.0 == e.kind()) {
            attention.push(AttentionRow {
                kind,
                words: format!("{n} more, not listed here: the whole list"),
                href: links::href(page, &period),
            });
        }
    }
    let day_filter =
        db.checked(&filter_of(today, today, None, None, None, None)).map_err(PageError::unavailable)?;
    let day_counts = db.fleet_counts(&day_filter).map_err(PageError::unavailable)?;
    let day_runs = db.fleet_runs(&day_filter).map_err(PageError::unavailable)?;
    let mut unreadable = words(&data.unreadable);
    unreadable.extend(words(&db.unreadable().map_err(PageError::unavailable)?));
    unreadable.dedup();
    let mut names: Vec<&str> = data.stations.iter().map(|s| s.0.as_str()).collect();
    names.extend(data.check_standards.iter().map(|c| c.station.as_str()));
    names.sort_unstable();
    names.dedup();
    let stations = names
        .iter()
        .map(|&n| {
            let (runs, passed) =
                data.stations.iter().find(|s| s.0 == n).map_or((0, 0), |s| (s.1 as usize, s.2 as usize));
            let check = data
                .check_standards
                .iter()
                .find(|c| c.station == n)
                .map(|c| format!("{} ({}, {} checks)", c.state, c.serial, c.checks))
                .unwrap_or_else(|| "no check standard".into());
            StationRow { name: n.to_string(), runs, passed, check }
        })
        .collect();
    let assets = data
        .assets
        .iter()
        .map(|a| AssetRow {
            id: a.asset_id.clone(),
            kind: a.kind.name(),
            certificate: a.certificate.clone(),
            due: a.due_date.to_string(),
            state: if a.due_date < today {
                "overdue"
            } else if a.due_date <= data.due_by {
                "due soon"
            } else {
                "in force"
            },
        })
        .collect();
    let due = data
        .units_due
        .iter()
        .map(|u| DueRow {
            serial: u.serial.clone(),
            device_id: u.device_id.clone(),
            unit_href: links::unit(if u.serial.is_empty() { &u.device_id } else { &u.serial }),
            due: utc_date_time(u.due_unix_s)[..10].to_string(),
            run: RunLink::of(&u.run_id),
        })
        .collect();
    let mut recalls = Vec::new();
    let mut recalls_tampered = Vec::new();
    for r in recalls_open {
        let f = &r.found_bad;
        if let Some(t) = &r.tampered {
            recalls_tampered.push(format!("{}: {t}", crate::app::recall::finding(f)));
        }
        for x in r.open() {
            recalls.push(RecallRow {
                reference: format!("{} ({}) certificate {}", f.asset_id, f.kind.name(), f.certificate),
                finding: format!("from {} on: {}", f.since, f.reason),
                serial: x.serial.clone(),
                device_id: x.device_id.clone(),
                unit_key: crate::app::recall::unit_key(x).to_string(),
                run_id: x.run_id.clone(),
                started: utc_date_time(x.started_unix_s),
                certificate: crate::app::recall::certificate(x),
            });
        }
    }
    let page = OverviewPage {
        db: &app.target,
        version: VERSION,
        unreadable,
        today: today.to_string(),
        day: (&day_counts).into(),
        month: (&data.counts).into(),
        month_since: since.to_string(),
        month_until: until.to_string(),
        attention,
        stations,
        assets,
        due_by: data.due_by.to_string(),
        due,
        recalls,
        recalls_tampered,
        today_runs: day_runs.iter().map(RunRow::from).collect(),
        chain_broken: data.chain_broken.clone(),
    };
    page.render().map_err(PageError::internal)
}

struct PopulationRow {
    name: String,
    unit: &'static str,
    n: usize,
    mean: String,
    sd: String,
    limit: String,
    cpk: String,
}

#[derive(Template)]
#[template(path = "serve/fleet.html")]
struct FleetPage<'a> {
    db: &'a str,
    version: &'a str,
    /// The runs the page's reads set aside (`Db::listing_unreadable`), in words.
    unreadable: Vec<String>,
    form: Form,
    query: &'a str,
    counts: CountsView,
    found_out: Vec<RunRow>,
    populations: Vec<PopulationRow>,
    runs: Vec<RunRow>,
    names: Vec<String>,
}

/// `/fleet`: `fleet`'s table over the filters, and a CSV download of the same rows.
pub(super) fn fleet(db: &mut Db, app: &App, q: &str) -> Result<String, PageError> {
    let f = Filters::parse(q)?;
    let (data, since, until) = f.gather(db, app.due_days, Parts::Table)?;
    let populations = data
        .pops
        .iter()
        .map(|p| PopulationRow {
            name: p.name.clone(),
            unit: p.unit,
            n: p.n,
            mean: format!("{:+.4}", p.mean),
            sd: format!("{:.4}", p.sd),
            limit: p.limit.map_or("-".into(), |l| format!("±{l}")),
            cpk: p.cpk.map_or("-".into(), |c| format!("{c:.2}")),
        })
        .collect();
    let mut names = Vec::new();
    for ch in ["x", "y", "z"] {
        for t in ["1", "ax", "ay", "az"] {
            names.push(format!("{ch}:{t}"));
        }
    }
    let page = FleetPage {
        db: &app.target,
        version: VERSION,
        unreadable: words(&data.unreadable),
        form: f.form(since, until),
        query: q,
        counts: (&data.counts).into(),
        found_out: data.found_out().into_iter().map(RunRow::from).collect(),
        populations,
        runs: data.runs.iter().map(RunRow::from).collect(),
        names,
    };
    page.render().map_err(PageError::internal)
}

/// `/fleet.csv`: `fleet --csv`'s rows over the filters.
pub(super) fn fleet_csv(db: &mut Db, app: &App, q: &str) -> Result<String, PageError> {
    let f = Filters::parse(q)?;
    let (data, _, _) = f.gather(db, app.due_days, Parts::Table)?;
    let customers = db.run_customers(certified(&data.runs)).map_err(PageError::unavailable)?;
    csv_of(&data.runs, &data, &customers).map_err(PageError::internal)
}

struct ChartView {
    title: String,
    svg: String,
    violations: Vec<Linked>,
}

struct HeadView {
    asset: String,
    units: usize,
    settings: String,
    /// The head's angle error as its units measure it, or empty.
    measured: String,
    change_points: Vec<Linked>,
    svg: String,
    /// "not enough units …" while the head has too few to flag a change, else empty.
    too_few: String,
}

#[derive(Template)]
#[template(path = "serve/charts.html")]
struct ChartsPage<'a> {
    db: &'a str,
    version: &'a str,
    /// The runs the page's reads set aside (`Db::listing_unreadable`), in words.
    unreadable: Vec<String>,
    form: Form,
    charts: Vec<ChartView>,
    checks: Vec<(String, Vec<ChartView>)>,
    heads: Vec<HeadView>,
}

/// `/charts`: the control charts by head (or station), each station's check standard, and each
/// head's signature.
pub(super) fn charts(db: &mut Db, app: &App, q: &str) -> Result<String, PageError> {
    let f = Filters::parse(q)?;
    let (data, since, until) = f.gather(db, app.due_days, Parts::Charts)?;
    let mut charts = Vec::new();
    for c in &data.charts {
        let values: Vec<f64> = c.points.iter().map(|p| p.value).collect();
        let started: Vec<i64> = c.points.iter().map(|p| p.started_unix_s).collect();
        let broken: Vec<usize> = c.violations.iter().map(|(v, _)| v.index).collect();
        let l = Lines { center: c.limits.center, lcl: c.limits.lcl, ucl: c.limits.ucl };
        charts.push(ChartView {
            title: format!(
                "{}, {} ({}): {} points, {} violations (about {:.1} by chance)",
                c.group,
                c.quantity,
                c.unit,
                c.points.len(),
                c.violations.len(),
                c.expected_by_chance
            ),
            svg: escape::markup(
                control_chart(c.unit, &values, Some(&started), Some(&l), &broken)
                    .map_err(PageError::internal)?,
            ),
            violations: c
                .violations
                .iter()
                .map(|(v, p)| {
                    let text = format!(
                        "rule {} ({}) at {} (run {}, {}): {:.6}",
                        v.rule,
                        v.what,
                        if p.serial.is_empty() { "-" } else { &p.serial },
                        p.run_id,
                        utc_date_time(p.started_unix_s),
                        p.value
                    );
                    Linked::around(text, &p.run_id)
                })
                .collect(),
        });
    }
    let mut checks = Vec::new();
    for s in &data.check_standards {
        let mut views = Vec::new();
        for c in &s.charts {
            let values: Vec<f64> = c.points.iter().map(|p| p.1).collect();
            let broken: Vec<usize> = c.violations.iter().map(|v| v.index).collect();
            let l = c.limits.as_ref().map(|l| Lines { center: l.center, lcl: l.lcl, ucl: l.ucl });
            views.push(ChartView {
                title: format!("{} ({})", c.quantity, c.unit),
                svg: escape::markup(
                    control_chart(c.unit, &values, None, l.as_ref(), &broken).map_err(PageError::internal)?,
                ),
                violations: c
                    .violations
                    .iter()
                    .map(|v| {
                        Linked::around(format!("rule {} ({}) at check {}", v.rule, v.what, v.index + 1), "")
                    })
                    .collect(),
            });
        }
        let state = format!(
            "station {}: {} ({}, {} checks){}",
            s.station,
            s.state,
            s.serial,
            s.checks,
            s.why.as_ref().map(|w| format!(": {w}")).unwrap_or_default()
        );
        checks.push((state, views));
    }
    let mut heads = Vec::new();
    for h in &data.heads {
        let arcsec: Vec<f64> = h.head.signature.positions.iter().map(|p| p.arcsec).collect();
        // A residual's standard error as a head angle, as `arcsec` is its mean's.
        let se_arcsec: Vec<f64> = h
            .head
            .signature
            .positions
            .iter()
            .map(|p| {
                let se = p.se_m_s2.iter().map(|s| s * s).sum::<f64>().sqrt();
                (se / accelcal_shared::kinematics::G_STANDARD).atan().to_degrees() * 3600.0
            })
            .collect();
        let baseline = h.head.signature.settings.baseline;
        heads.push(HeadView {
            asset: h.asset.clone(),
            units: h.head.units,
            settings: h.head.settings_line(),
            measured: h.head.signature.measured_angle.as_ref().map(measured_line).unwrap_or_default(),
            change_points: h
                .head
                .change_points
                .iter()
                .map(|c| Linked::around(change_point(c), &c.run_id))
                .collect(),
            svg: if arcsec.is_empty() {
                String::new()
            } else {
                escape::markup(signature_chart(&arcsec, &se_arcsec).map_err(PageError::internal)?)
            },
            too_few: if h.head.units <= baseline {
                format!(
                    "not enough units to flag a change: {} of the {} a head's tracking starts from",
                    h.head.units,
                    baseline + 1
                )
            } else {
                String::new()
            },
        });
    }
    let page = ChartsPage {
        db: &app.target,
        version: VERSION,
        unreadable: words(&data.unreadable),
        form: f.form(since, until),
        charts,
        checks,
        heads,
    };
    page.render().map_err(PageError::internal)
}

struct UnitRun {
    run_id: String,
    /// Its first 8 hex digits.
    run_short: String,
    /// Its certificate in force's page: by its number, else by the run.
    certificate_href: String,
    calibration: String,
    started: String,
    station: String,
    operator: String,
    outcome: String,
    record: String,
    as_found: String,
    as_left: String,
    note: String,
    certificate: bool,
    /// The certificate in force: its number and where it stands, and the numbers it superseded.
    certificate_words: String,
}

#[derive(Template)]
#[template(path = "serve/unit.html")]
struct UnitPage<'a> {
    db: &'a str,
    version: &'a str,
    /// The runs the page's reads set aside (`Db::listing_unreadable`), in words.
    unreadable: Vec<String>,
    /// The unit's serial (its latest), else its device id.
    title: String,
    device_id: String,
    serials: String,
    runs: Vec<UnitRun>,
    drift_svg: String,
    drifts: Vec<String>,
    recalibration: String,
    /// Each finding that affects the unit: what became of it, in words, and whether it is open.
    recalls: Vec<(String, bool)>,
}

/// A run's certificate in force in words: `2026-000004 approved (replaces 2026-000003,
/// superseded)`, or `certificate` for a page stored without a number.
pub(super) fn certificate_words(r: &accelcal_db::history::RunLine) -> String {
    let mut w = r.certificate_number.clone().unwrap_or_else(|| "certificate".into());
    if let Some(s) = r.certificate_state {
        w.push(' ');
        w.push_str(s.words());
    }
    if !r.superseded_certificates.is_empty() {
        w.push_str(&format!(" (replaces {}, superseded)", r.superseded_certificates.join(", ")));
    }
    w
}

/// `/unit/KEY` (a serial or a device id): `history`'s runs, drift and recalibration date, with
/// links to the stored certificates.
pub(super) fn unit(db: &mut Db, app: &App, key: &str) -> Result<String, PageError> {
    // A unit that is not there (or a serial of several devices) is 404; a query that fails is the
    // database's failure (503).
    let runs = db.unit_runs(key).map_err(|e| match e {
        DbError::NoUnit { .. } | DbError::Ambiguous { .. } => PageError::not_found(e.to_string()),
        e => PageError::unavailable(e),
    })?;
    if runs.is_empty() && db.unreadable_count() == 0 {
        return Err(PageError::not_found(format!("no unit `{key}` in the database")));
    }
    let h = history(&runs, DEFAULT_RULE);
    let mut rows = Vec::new();
    for r in &h.runs {
        let outcome = outcome(r);
        let certificate = match RunId::parse(&r.run_id) {
            // A run whose rows do not match their chain offers no certificate.
            Ok(id) if r.tampered.is_none() => {
                db.certificate_sha256(id).map_err(PageError::unavailable)?.is_some()
            }
            Ok(_) => false,
            Err(_) => false,
        };
        let note = match (&r.voided, &r.not_a_calibration, r.outcome) {
            _ if r.tampered.is_some() => format!("TAMPERED: {}", r.tampered.as_deref().unwrap_or_default()),
            (Some(why), _, _) => format!("voided: {why}"),
            (None, Some(why), _) => format!("not a calibration: {why}"),
            (None, None, Some(Outcome::Rejected)) => format!("rejected: {}", r.reason),
            _ => String::new(),
        };
        rows.push(UnitRun {
            run_id: r.run_id.clone(),
            run_short: r.run_id.chars().take(8).collect(),
            certificate_href: match &r.certificate_number {
                Some(n) => links::certificate(n),
                None => format!("{}/certificate", links::run(&r.run_id)),
            },
            calibration: r.calibration.map_or("-".into(), |n| n.to_string()),
            started: utc_date_time(r.started_unix_s),
            station: r.station.clone(),
            operator: r.operator.clone(),
            outcome: outcome.into(),
            record: r.record_crc32.clone().unwrap_or_else(|| "-".into()),
            as_found: verification(&r.as_found),
            as_left: verification(&r.as_left),
            note,
            certificate,
            certificate_words: certificate_words(r),
        });
    }
    let pairs: Vec<[(f64, f64); 3]> = h
        .drifts
        .iter()
        .map(|d| {
            std::array::from_fn(|c| {
                let ch = ["x", "y", "z"][c];
                d.terms
                    .iter()
                    .find(|t| t.channel == ch && t.term == "1")
                    .map_or((0.0, 0.0), |t| (t.delta_m_s2, t.sigma_m_s2))
            })
        })
        .collect();
    let drift_svg = if pairs.is_empty() {
        String::new()
    } else {
        // Each drift's x: the date of its later calibration.
        let started: Vec<i64> = h
            .drifts
            .iter()
            .map(|d| h.runs.iter().find(|r| r.calibration == Some(d.to)).map_or(0, |r| r.started_unix_s))
            .collect();
        escape::markup(drift_chart(&pairs, &started).map_err(PageError::internal)?)
    };
    let drifts = h
        .drifts
        .iter()
        .map(|d| {
            let largest = d
                .terms
                .iter()
                .max_by(|a, b| (a.delta_m_s2.abs()).total_cmp(&b.delta_m_s2.abs()))
                .map(|t| {
                    format!(
                        "largest {}:{} {} ± {} m/s²",
                        t.channel,
                        t.term,
                        sig(t.delta_m_s2, 3),
                        sig(t.sigma_m_s2, 2)
                    )
                })
                .unwrap_or_default();
            format!("calibration {} → {} ({:.1} days): {largest}", d.from, d.to, d.days)
        })
        .collect();
    let rc = &h.recalibration;
    let recalibration = match rc.due_unix_s {
        Some(t) => format!("recalibrate by {} ({})", &utc_date_time(t)[..10], rc.basis),
        None => format!("recalibration: {}", rc.basis),
    };
    // The references found out of tolerance that calibrated the unit, and what became of it.
    let mut recalls = Vec::new();
    for r in db.recalls(Some(&h.device_id)).map_err(PageError::unavailable)? {
        for u in r.units() {
            let open = u.state == accelcal_db::RecallState::Open;
            let then = if open {
                format!(
                    "open: recall the unit, or dismiss it (accelcal affected {} --dismiss {} --reason TEXT)",
                    r.found_bad.asset_id,
                    crate::app::recall::unit_key(u.run)
                )
            } else {
                crate::app::recall::state(u.run)
            };
            let tampered = r
                .tampered
                .as_ref()
                .map(|t| format!(" (TAMPERED: {t}; no dismissal taken)"))
                .unwrap_or_default();
            recalls.push((
                format!(
                    "Recall: run {} ({}) was calibrated on {}: {then}{tampered}",
                    u.run.run_id,
                    utc_date_time(u.run.started_unix_s),
                    crate::app::recall::finding(&r.found_bad)
                ),
                open,
            ));
        }
    }
    let page = UnitPage {
        db: &app.target,
        version: VERSION,
        unreadable: words(&db.unreadable().map_err(PageError::unavailable)?),
        title: h.serials.last().unwrap_or(&h.device_id).clone(),
        device_id: h.device_id.clone(),
        serials: match h.serials.len() {
            0 => "no serial number".into(),
            1 => String::new(),
            _ => format!("labelled {} in turn", h.serials.join(", ")),
        },
        runs: rows,
        drift_svg,
        drifts,
        recalibration,
        recalls,
    };
    page.render().map_err(PageError::internal)
}

/// `/run/ID/certificate`: the run's certificate in force as printed (with its decision, or a
/// draft), its control characters shown as text (`\u{1b}`, [`escape::markup`]).
pub(super) fn certificate(db: &mut Db, id: &str) -> Result<String, PageError> {
    let run = RunId::parse(id).map_err(|e| PageError::bad(e.to_string()))?;
    shown(db, &Which::Run(run))
}

/// `/certificate/NUMBER`: the certificate so numbered (an amendment's number too), as
/// [`certificate`] shows it.
pub(super) fn numbered(db: &mut Db, number: &str) -> Result<String, PageError> {
    if !accelcal_db::certificate::is_number(number) {
        return Err(PageError::bad(format!(
            "`{number}` is not a certificate number (YYYY-NNNNNN, as printed)"
        )));
    }
    shown(db, &Which::Number(number.to_string()))
}

/// The certificate `which` names, as printed.
fn shown(db: &mut Db, which: &Which) -> Result<String, PageError> {
    crate::app::certificate::Stored::read(db, which).and_then(|c| c.page(db)).map(escape::markup).map_err(
        |e| {
            match e.downcast_ref::<DbError>() {
                // A forged certificate is not shown as issued.
                Some(DbError::Tampered { .. }) => PageError::tampered(format!("{e:#}")),
                Some(_) => PageError::unavailable(format!("{e:#}")),
                None => PageError::not_found(format!("{e:#}")),
            }
        },
    )
}

#[derive(Template)]
#[template(path = "serve/error.html")]
struct ErrorPage<'a> {
    db: &'a str,
    version: &'a str,
    /// The runs the page's reads set aside (`Db::listing_unreadable`), in words.
    unreadable: Vec<String>,
    status: String,
    message: &'a str,
}

/// The page of an error.
pub(super) fn error(target: &str, status: StatusCode, message: &str) -> String {
    let page = ErrorPage {
        db: target,
        version: VERSION,
        unreadable: Vec::new(),
        status: status.to_string(),
        message,
    };
    page.render().unwrap_or_else(|_| format!("{status}"))
}
