//! What needs attention on the line (issue 59, the morning view): overdue assets, control charts
//! out of control, head change points, units found out of tolerance, certificates awaiting
//! approval. Each is an [`Entry`]: its kind, its words and the [`Page`] it is about. `serve`'s
//! overview opens with them; they are worked out here, from what the fleet's readers gathered,
//! so a page or a command only shows them.

use accelcal_core::headsig::ChangePoint;
use accelcal_core::output::utc_date_time;
use accelcal_db::asset::{Asset, Date};
use accelcal_db::fleet::{Chart, ChartPoint, FleetRun};
use accelcal_db::recall::Recall;
use accelcal_db::CertificateState;

/// The page an entry is about.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Page {
    /// An asset of the register, by its id.
    Asset(String),
    /// The control charts of a head asset.
    HeadCharts(String),
    /// The control charts of a station.
    StationCharts(String),
    /// A run, by its id.
    Run(String),
    /// A certificate, by its number.
    Certificate(String),
    /// The asset register.
    Assets,
    /// Every control chart and head of the period.
    Charts,
    /// The fleet's runs of the period (those found out of tolerance, the certificates).
    Fleet,
    /// The units to recall (the overview's table).
    Recalls,
}

/// One thing that needs attention, in the order of [`entries`].
#[derive(Clone, Debug, PartialEq)]
pub enum Entry {
    /// A reference whose own certificate's due date has passed.
    AssetOverdue { asset_id: String, kind: &'static str, certificate: String, due: Date },
    /// A control chart with points that break a rule; `last`: the latest such point.
    OutOfControl {
        group: String,
        quantity: String,
        unit: &'static str,
        violations: usize,
        points: usize,
        last: ChartPoint,
    },
    /// A change point of a head's signature.
    HeadChange { asset: String, change: ChangePoint },
    /// A run whose as-found verification was out of tolerance: the unit's users must be told.
    FoundOut { unit: String, device_id: String, run_id: String, started_unix_s: i64, decision: String },
    /// A certificate no signer has decided yet.
    AwaitingApproval { number: String, unit: String, run_id: String },
    /// A reference found out of tolerance at its own recalibration, with units still to recall
    /// (or whose recall rows do not match their hash chain).
    ReferenceBad { asset_id: String, certificate: String, open_units: usize, tampered: bool },
}

/// What [`entries`] reads: the day, the asset register, and a period's runs and charts as the
/// fleet's readers gathered them.
pub struct Sources<'a> {
    /// Today (UTC): an asset due before it is overdue.
    pub today: Date,
    /// The asset register.
    pub assets: &'a [Asset],
    /// The period's control charts.
    pub charts: &'a [Chart],
    /// Each head asset and its signature's change points.
    pub heads: Vec<(&'a str, &'a [ChangePoint])>,
    /// The period's runs found out of tolerance as found (not voided).
    pub found_out: &'a [&'a FleetRun],
    /// The period's runs.
    pub runs: &'a [FleetRun],
    /// The findings of references out of tolerance with units still open (or tampered).
    pub recalls: &'a [&'a Recall],
}

/// A panel's share of the entries: at most so many of each kind, and what was left out.
#[derive(Clone, Debug, PartialEq)]
pub struct Panel {
    /// The entries shown, in their order.
    pub shown: Vec<Entry>,
    /// Per kind cut short: the kind, how many entries of it were left out, and the page that
    /// lists them all.
    pub left_out: Vec<(&'static str, usize, Page)>,
}

/// At most `per_kind` of each kind of `entries` (the first ones), so that a morning with 900
/// certificates to sign still shows the one overdue asset.
pub fn panel(entries: Vec<Entry>, per_kind: usize) -> Panel {
    let mut shown: Vec<Entry> = Vec::new();
    let mut left_out: Vec<(&'static str, usize, Page)> = Vec::new();
    for e in entries {
        let kind = e.kind();
        if shown.iter().filter(|s| s.kind() == kind).count() < per_kind {
            shown.push(e);
        } else if let Some(l) = left_out.iter_mut().find(|l| l.0 == kind) {
            l.1 += 1;
        } else {
            left_out.push((kind, 1, e.whole_list()));
        }
    }
    Panel { shown, left_out }
}

/// A unit as the line names it: its serial, else its device id.
fn unit_of(serial: &str, device_id: &str) -> String {
    if serial.is_empty() { device_id } else { serial }.to_string()
}

/// What needs attention, by kind in the order of [`Entry`]'s variants, each kind in the order
/// its source lists it: overdue assets, charts out of control, head change points, units found
/// out of tolerance, certificates awaiting approval. Tampered runs are set aside.
pub fn entries(s: &Sources<'_>) -> Vec<Entry> {
    let mut out: Vec<Entry> = s
        .assets
        .iter()
        .filter(|a| a.due_date < s.today)
        .map(|a| Entry::AssetOverdue {
            asset_id: a.asset_id.clone(),
            kind: a.kind.name(),
            certificate: a.certificate.clone(),
            due: a.due_date,
        })
        .collect();
    out.extend(s.charts.iter().filter_map(|c| {
        let (_, last) = c.violations.last()?;
        Some(Entry::OutOfControl {
            group: c.group.clone(),
            quantity: c.quantity.clone(),
            unit: c.unit,
            violations: c.violations.len(),
            points: c.points.len(),
            last: last.clone(),
        })
    }));
    for (asset, changes) in &s.heads {
        out.extend(changes.iter().map(|c| Entry::HeadChange { asset: asset.to_string(), change: c.clone() }));
    }
    out.extend(s.found_out.iter().filter(|r| r.tampered.is_none()).map(|r| Entry::FoundOut {
        unit: unit_of(&r.serial, &r.device_id),
        device_id: r.device_id.clone(),
        run_id: r.run_id.clone(),
        started_unix_s: r.started_unix_s,
        decision: r.as_found_decision.clone().unwrap_or_default(),
    }));
    out.extend(
        s.runs
            .iter()
            .filter(|r| {
                r.tampered.is_none()
                    && r.state != "voided"
                    && r.certificate_state == Some(CertificateState::AwaitingApproval)
            })
            .filter_map(|r| {
                Some(Entry::AwaitingApproval {
                    number: r.certificate_number.clone()?,
                    unit: unit_of(&r.serial, &r.device_id),
                    run_id: r.run_id.clone(),
                })
            }),
    );
    out.extend(s.recalls.iter().map(|r| Entry::ReferenceBad {
        asset_id: r.found_bad.asset_id.clone(),
        certificate: r.found_bad.certificate.clone(),
        open_units: r.open().len(),
        tampered: r.tampered.is_some(),
    }));
    out
}

impl Entry {
    /// The kind in words, as the panel heads the entry.
    pub fn kind(&self) -> &'static str {
        match self {
            Entry::AssetOverdue { .. } => "asset overdue",
            Entry::OutOfControl { .. } => "chart out of control",
            Entry::HeadChange { .. } => "head change point",
            Entry::FoundOut { .. } => "as found out of tolerance",
            Entry::AwaitingApproval { .. } => "certificate awaiting approval",
            Entry::ReferenceBad { .. } => "reference found bad",
        }
    }

    /// The entry in words.
    pub fn words(&self) -> String {
        match self {
            Entry::AssetOverdue { asset_id, kind, certificate, due } => {
                format!("{kind} {asset_id}: certificate {certificate} was due {due}")
            }
            Entry::OutOfControl { group, quantity, unit, violations, points, last } => format!(
                "{group}, {quantity} ({unit}): {violations} violation{} in {points} points, the last at {} \
                 (run {}, {})",
                if *violations == 1 { "" } else { "s" },
                if last.serial.is_empty() { "-" } else { &last.serial },
                last.run_id,
                &utc_date_time(last.started_unix_s)[..10]
            ),
            Entry::HeadChange { asset, change: c } => format!(
                "head {asset}: {}, {:.0} {} at unit {} (run {}, {})",
                c.rule,
                c.estimate,
                c.unit,
                if c.serial.is_empty() { "-" } else { &c.serial },
                c.run_id,
                &utc_date_time(c.started_unix_s)[..10]
            ),
            Entry::FoundOut { unit, device_id, run_id, started_unix_s, decision } => format!(
                "{unit} ({device_id}): {decision} as found (run {run_id}, {}): tell its users",
                &utc_date_time(*started_unix_s)[..10]
            ),
            Entry::AwaitingApproval { number, unit, run_id } => {
                format!("{number} of {unit} (run {run_id}) awaits a signer's decision")
            }
            Entry::ReferenceBad { asset_id, certificate, open_units, tampered } => format!(
                "{asset_id} under certificate {certificate} was out of tolerance: {open_units} unit{} to recall or \
                 dismiss{}",
                if *open_units == 1 { "" } else { "s" },
                if *tampered { " (TAMPERED: its recall rows do not match their hash chain)" } else { "" }
            ),
        }
    }

    /// The page that lists every entry of its kind.
    pub fn whole_list(&self) -> Page {
        match self {
            Entry::AssetOverdue { .. } => Page::Assets,
            Entry::OutOfControl { .. } | Entry::HeadChange { .. } => Page::Charts,
            Entry::FoundOut { .. } | Entry::AwaitingApproval { .. } => Page::Fleet,
            Entry::ReferenceBad { .. } => Page::Recalls,
        }
    }

    /// The page the entry is about.
    pub fn page(&self) -> Page {
        match self {
            Entry::AssetOverdue { asset_id, .. } => Page::Asset(asset_id.clone()),
            Entry::OutOfControl { group, last, .. } => {
                if let Some(head) = group.strip_prefix("head ") {
                    Page::HeadCharts(head.to_string())
                } else if let Some(station) = group.strip_prefix("station ") {
                    Page::StationCharts(station.to_string())
                } else {
                    Page::Run(last.run_id.clone())
                }
            }
            Entry::HeadChange { asset, .. } => Page::HeadCharts(asset.clone()),
            Entry::FoundOut { run_id, .. } => Page::Run(run_id.clone()),
            Entry::AwaitingApproval { number, .. } => Page::Certificate(number.clone()),
            Entry::ReferenceBad { .. } => Page::Recalls,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use accelcal_core::spc::{ImrLimits, Violation};
    use accelcal_db::asset::{parse_date, AssetKind};

    fn asset(id: &str, due: &str) -> Asset {
        Asset {
            asset_id: id.into(),
            kind: AssetKind::Head,
            certificate: format!("C-{id}"),
            due_date: parse_date(due).unwrap(),
            angle_u_arcsec: 3.0,
            orthogonality_u_arcsec: 3.0,
            operator: "qa".into(),
            registered_unix_s: 0,
            value: None,
        }
    }

    fn point(serial: &str, run: &str) -> ChartPoint {
        ChartPoint { serial: serial.into(), run_id: run.into(), started_unix_s: 1_767_225_600, value: 1.0 }
    }

    fn chart(group: &str, broken: &[&str]) -> Chart {
        let limits = ImrLimits { center: 0.0, sigma: 1.0, ucl: 3.0, lcl: -3.0, mr_bar: 1.1, mr_ucl: 3.7 };
        Chart {
            group: group.into(),
            quantity: "K0 x".into(),
            unit: "mg",
            limits,
            points: vec![point("SN-1", "r1"), point("SN-2", "r2"), point("SN-3", "r3")],
            violations: broken
                .iter()
                .enumerate()
                .map(|(i, run)| (Violation { rule: 1, index: i, what: "beyond a limit" }, point("SN-9", run)))
                .collect(),
            expected_by_chance: 0.1,
        }
    }

    /// Each kind in its order, only what needs attention (an asset due today is not overdue, a
    /// chart without violations is in control), each with its words and its page.
    #[test]
    fn what_needs_attention_is_listed_by_kind_with_its_page() {
        let assets =
            [asset("HEAD-1", "2026-01-19"), asset("HEAD-2", "2026-01-20"), asset("THERMO", "2025-12-01")];
        let charts =
            [chart("head HEAD-1", &["r7", "r8"]), chart("station st-1", &[]), chart("station st-2", &["r5"])];
        let change = ChangePoint {
            serial: "SN-4".into(),
            run_id: "r4".into(),
            started_unix_s: 1_767_225_600,
            index: 5,
            rule: "CUSUM up".into(),
            estimate: 12.4,
            unit: "arcsec",
        };
        let changes = [change];
        let finding = Recall {
            found_bad: accelcal_db::recall::FoundBad {
                asset_id: "HEAD-0".into(),
                kind: AssetKind::Head,
                certificate: "C-0".into(),
                since: parse_date("2025-06-01").unwrap(),
                reason: "40 arcsec off".into(),
                operator: "qa".into(),
                recorded_unix_s: 0,
            },
            tampered: Some("a dismissal was changed".into()),
            runs: Vec::new(),
        };
        let s = Sources {
            recalls: &[&finding],
            today: parse_date("2026-01-20").unwrap(),
            assets: &assets,
            charts: &charts,
            heads: vec![("HEAD-1", &changes[..]), ("HEAD-2", &[])],
            found_out: &[],
            runs: &[],
        };
        let listed: Vec<(&str, String, Page)> =
            entries(&s).iter().map(|e| (e.kind(), e.words(), e.page())).collect();
        assert_eq!(
            listed,
            [
                (
                    "asset overdue",
                    "head HEAD-1: certificate C-HEAD-1 was due 2026-01-19".to_string(),
                    Page::Asset("HEAD-1".into())
                ),
                (
                    "asset overdue",
                    "head THERMO: certificate C-THERMO was due 2025-12-01".to_string(),
                    Page::Asset("THERMO".into())
                ),
                (
                    "chart out of control",
                    "head HEAD-1, K0 x (mg): 2 violations in 3 points, the last at SN-9 (run r8, 2026-01-01)"
                        .to_string(),
                    Page::HeadCharts("HEAD-1".into())
                ),
                (
                    "chart out of control",
                    "station st-2, K0 x (mg): 1 violation in 3 points, the last at SN-9 (run r5, 2026-01-01)"
                        .to_string(),
                    Page::StationCharts("st-2".into())
                ),
                (
                    "head change point",
                    "head HEAD-1: CUSUM up, 12 arcsec at unit SN-4 (run r4, 2026-01-01)".to_string(),
                    Page::HeadCharts("HEAD-1".into())
                ),
                (
                    "reference found bad",
                    "HEAD-0 under certificate C-0 was out of tolerance: 0 units to recall or dismiss (TAMPERED: \
                     its recall rows do not match their hash chain)"
                        .to_string(),
                    Page::Recalls
                ),
            ]
        );
        // One of each kind: the second overdue asset and the second chart are left out, counted.
        let p = panel(entries(&s), 1);
        let kinds: Vec<&str> = p.shown.iter().map(Entry::kind).collect();
        assert_eq!(
            kinds,
            ["asset overdue", "chart out of control", "head change point", "reference found bad"]
        );
        assert_eq!(
            p.left_out,
            [("asset overdue", 1, Page::Assets), ("chart out of control", 1, Page::Charts)]
        );
        assert_eq!(panel(entries(&s), 2).left_out, []);
    }
}
