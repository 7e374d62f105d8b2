//! A line of six units for `fleet` (issue 31): runs passed, rejected, unfinished and voided on
//! two stations, one head asset, an as-found out of tolerance, certificates numbered with their
//! recalibration dates.

use accelcal_core::conformity::{Decision, ParameterCheck};
use accelcal_db::fleet::Filter;
use accelcal_db::{Db, Outcome, Phase, RecalibrationDue, RunId};
use accelcal_line::verify::VerifyReport;

use accelcal_core::sim::Plan;

use super::*;

/// The runs of [`line_of_units`].
pub struct Line {
    /// Unit A's passed run (head HEAD-1, due T0 + 200 days).
    pub a: RunId,
    /// Unit B's rejected run, then its passed one (due T0 + 20 days).
    pub b: [RunId; 2],
    /// Unit C's run, found out of tolerance (due T0 + 365 days).
    pub c: RunId,
    /// Unit D's unfinished run.
    pub d: RunId,
    /// Unit E's voided run.
    pub e: RunId,
    /// Unit F's run, 40 days after T0.
    pub f: RunId,
}

/// An as-left verification that measured channel x's bias error (mg, limit ±2 mg).
fn as_left(device: &str, bias_mg: f64) -> VerifyReport {
    let mut v = verification(device, 0.002, 0.05);
    v.parameters = Some(vec![ParameterCheck {
        parameter: "bias".into(),
        axis: "x".into(),
        value: bias_mg,
        u_expanded: 0.2,
        limit: 2.0,
        unit: "mg".into(),
        decision: Decision::Pass,
    }]);
    v
}

/// A unit's whole run that passes: as found (when given), campaign, fit, record flashed, as
/// left with x's bias error `bias_mg`, the certificate numbered with its recalibration date (when
/// given), on a registered head (when given).
struct Unit<'a> {
    device: &'a str,
    serial: &'a str,
    station: &'a str,
    t: i64,
    bias_mg: f64,
    due: Option<i64>,
    head: Option<&'a accelcal_db::Asset>,
    as_found: Option<VerifyReport>,
    coefs: Coefs,
}

fn calibrated(db: &mut Db, u: Unit<'_>) -> RunId {
    let s = start(RunId::new(), u.device, u.serial, u.station, u.t);
    let run = s.run_id;
    db.begin_run(&s, None).unwrap();
    if let Some(h) = u.head {
        db.store_run_asset(run, h).unwrap();
    }
    if let Some(v) = &u.as_found {
        db.store_verification(run, Phase::AsFound, v).unwrap();
    }
    let c = u.coefs;
    db.store_campaign(run, &campaign(600)).unwrap();
    db.store_fit(run, &fit_json(&c)).unwrap();
    let rec = db.store_record(run, &record(u.device, &c)).unwrap();
    db.record_flashed(&rec).unwrap();
    db.store_verification(run, Phase::AsLeft, &as_left(u.device, u.bias_mg)).unwrap();
    if let Some(d) = u.due {
        db.certificate_number_with_due(run, &RecalibrationDue { due_unix_s: d, basis: "test".into() })
            .unwrap();
    }
    db.store_certificate(run, &format!("<html>certificate of {}</html>", u.serial)).unwrap();
    db.finish_run(run, Outcome::Pass, "verified").unwrap();
    run
}

/// Six units between T0 and T0 + 40 days.
pub fn line_of_units(db: &mut Db) -> Line {
    let head = head_asset("HEAD-1", "DKD-17-001", "2026-01-20", 3.0, T0 - DAY);
    db.add_asset(&head).unwrap();
    let unit = |device, serial, station, t, bias_mg, due| Unit {
        device,
        serial,
        station,
        t,
        bias_mg,
        due,
        head: None,
        as_found: None,
        coefs: coefs(0.0, 0),
    };
    let later = |u: Unit<'static>| Unit { coefs: coefs(10.0, 1), ..u };
    let a = calibrated(
        db,
        Unit { head: Some(&head), ..unit(DEVICE, "SN-A1", "st-1", T0 + DAY, 0.5, Some(T0 + 200 * DAY)) },
    );
    let b0 = {
        let s = start(RunId::new(), DEVICE_2, "SN-B1", "st-1", T0 + 2 * DAY);
        db.begin_run(&s, None).unwrap();
        db.store_campaign(s.run_id, &campaign(600)).unwrap();
        db.finish_run(s.run_id, Outcome::Rejected, "selection beyond model 4").unwrap();
        s.run_id
    };
    let b1 = calibrated(db, later(unit(DEVICE_2, "SN-B1", "st-1", T0 + 3 * DAY, 1.0, Some(T0 + 20 * DAY))));
    let c_dev = "aabbccddeeff001122334455";
    let c = calibrated(
        db,
        Unit {
            as_found: Some(decided_as_found(c_dev, Decision::Fail)),
            ..unit(c_dev, "SN-C1", "st-2", T0 + 4 * DAY, 1.5, Some(T0 + 365 * DAY))
        },
    );
    let d = {
        let s = start(RunId::new(), "bbccddeeff00112233445566", "SN-D1", "st-2", T0 + 5 * DAY);
        db.begin_run(&s, None).unwrap();
        db.store_campaign(s.run_id, &campaign(600)).unwrap();
        s.run_id
    };
    let e = calibrated(db, later(unit("ccddeeff0011223344556677", "SN-E1", "st-1", T0 + 6 * DAY, 1.0, None)));
    db.void_run(e, "mislabelled", "qa").unwrap();
    let f = calibrated(
        db,
        later(unit("ddeeff001122334455667788", "XX-F1", "st-1", T0 + 40 * DAY, 1.0, Some(T0 + 400 * DAY))),
    );
    Line { a, b: [b0, b1], c, d, e, f }
}

/// The period T0 .. T0 + 31 days.
pub fn january() -> Filter {
    Filter { since_unix_s: T0, until_unix_s: T0 + 31 * DAY, ..Filter::default() }
}

/// What the database counts of [`line_of_units`], by period and filter, and the units due.
pub fn the_fleet_is_counted_by_the_database(spec: &str) {
    let mut db = Db::open(spec).unwrap();
    let line = line_of_units(&mut db);
    let c = db.fleet_counts(&january()).unwrap();
    assert_eq!((c.runs, c.passed, c.rejected, c.unfinished, c.voided, c.units), (6, 3, 1, 1, 1, 5), "{c:?}");
    assert_eq!((c.units_finished, c.first_pass_units, c.final_pass_units), (3, 2, 3), "{c:?}");
    assert_eq!(c.rejections, [("selection beyond model 4".to_string(), 1)]);
    let st2 = db.fleet_counts(&Filter { station: Some("st-2".into()), ..january() }).unwrap();
    assert_eq!((st2.runs, st2.units, st2.passed, st2.unfinished), (2, 2, 1, 1), "{st2:?}");
    let b = db.fleet_counts(&Filter { serial_prefix: Some("SN-B".into()), ..january() }).unwrap();
    assert_eq!((b.runs, b.first_pass_units, b.final_pass_units), (2, 0, 1), "{b:?}");
    let nobody = db.fleet_counts(&Filter { operator: Some("bo".into()), ..january() }).unwrap();
    assert_eq!((nobody.runs, nobody.units), (0, 0));
    let ana = db.fleet_counts(&Filter { operator: Some("ana".into()), ..january() }).unwrap();
    assert_eq!(ana.runs, 6);
    let h = db.fleet_counts(&Filter { head_asset: Some("HEAD-1".into()), ..january() }).unwrap();
    assert_eq!((h.runs, h.units), (1, 1), "{h:?}");
    // A serial prefix with LIKE's wildcards in it is a prefix, not a pattern.
    let none = db.fleet_counts(&Filter { serial_prefix: Some("SN_%".into()), ..january() }).unwrap();
    assert_eq!(none.runs, 0);

    let runs = db.fleet_runs(&january()).unwrap();
    let ids: Vec<String> = runs.iter().map(|r| r.run_id.clone()).collect();
    let want: Vec<String> =
        [line.a, line.b[0], line.b[1], line.c, line.d, line.e].map(|r| r.to_string()).into();
    assert_eq!(ids, want);
    assert_eq!(runs[0].head_asset.as_deref(), Some("HEAD-1"));
    assert_eq!(runs[3].as_found_decision.as_deref(), Some("fail"));
    assert_eq!(runs[5].state, "voided");
    assert_eq!(runs[5].reason.as_deref(), Some("mislabelled"));
    assert!(runs[0].model4().is_some() && runs[4].model4().is_none());
    let pops = db.populations(&january()).unwrap();
    assert_eq!(pops[0].name, "K0 x");
    assert_eq!(pops[0].n, 3, "the three runs that passed: {pops:?}");
    // The database's aggregation is the textbook one over the runs' own coefficients.
    let passed: Vec<[[f64; 4]; 3]> =
        runs.iter().filter(|r| r.state == "pass").filter_map(|r| r.model4()).collect();
    for (k, name) in ["K0 x", "K0 y", "K0 z"].iter().enumerate() {
        let v: Vec<f64> =
            passed.iter().map(|m| accelcal_core::ieee1293::Parameters::of(k, m[k]).k0_mg).collect();
        let mean = v.iter().sum::<f64>() / v.len() as f64;
        let sd = (v.iter().map(|x| (x - mean) * (x - mean)).sum::<f64>() / (v.len() - 1) as f64).sqrt();
        let p = pops.iter().find(|p| p.name == *name).unwrap();
        assert!(
            (p.mean - mean).abs() <= 1e-9 * mean.abs().max(1.0) && (p.sd - sd).abs() <= 1e-9 * sd.max(1e-12),
            "{p:?}: {mean} {sd}"
        );
    }
    // The as-left bias of x: 0.5, 1.0 and 1.5 mg against ±2 mg: mean 1, s 0.5, Cpk (2 − 1)/1.5.
    let bias = pops.iter().find(|p| p.name == "as-left bias x").unwrap();
    assert_eq!((bias.n, bias.unit, bias.limit), (3, "mg", Some(2.0)));
    assert!((bias.mean - 1.0).abs() < 1e-12 && (bias.sd - 0.5).abs() < 1e-12, "{bias:?}");
    assert!((bias.cpk.unwrap() - 1.0 / 1.5).abs() < 1e-12, "{bias:?}");

    let due: Vec<String> = db.units_due(T0 + 30 * DAY, None).unwrap().into_iter().map(|u| u.serial).collect();
    assert_eq!(due, ["SN-B1"]);
    let due: Vec<String> =
        db.units_due(T0 + 500 * DAY, None).unwrap().into_iter().map(|u| u.serial).collect();
    assert_eq!(due, ["SN-B1", "SN-A1", "SN-C1", "XX-F1"]);
    let due = db.units_due(T0 + 500 * DAY, Some("XX")).unwrap();
    assert_eq!(due.iter().map(|u| u.run_id.clone()).collect::<Vec<_>>(), [line.f.to_string()]);
    assert_eq!(db.certificate_html(line.c).unwrap().as_deref(), Some("<html>certificate of SN-C1</html>"));
    assert_eq!(db.certificate_html(line.d).unwrap(), None);
}

/// A serial that is HTML: a unit calibrated on station `st-1` at `t` whose serial (and so its
/// stored certificate, `<html>certificate of SERIAL</html>`) carries a script.
pub const HOSTILE_SERIAL: &str = "<script>document.write('PWNED')</script>";

/// Calibrates the unit of [`HOSTILE_SERIAL`].
pub fn hostile_unit(db: &mut Db, t: i64) -> RunId {
    calibrated(
        db,
        Unit {
            device: "eeff00112233445566778899",
            serial: HOSTILE_SERIAL,
            station: "st-1",
            t,
            bias_mg: 0.8,
            due: Some(t + 100 * DAY),
            head: None,
            as_found: None,
            coefs: coefs(5.0, 2),
        },
    )
}

/// Issue 31 item 3's line: 70 units on the registered head HEAD-2 on station `st-1`, an hour
/// apart from T0, their simulated campaigns and model-4 fits stored; from the 56th unit on, the
/// head reaches position 27's α 2 mrad off what it says.
pub fn head_knocked_out(db: &mut Db) {
    let head = head_asset("HEAD-2", "DKD-17-009", "2099-12-31", 3.0, T0 - DAY);
    head_line(db, &head, 70, |u, plan| {
        if u >= 55 {
            plan.positions[26].0 += (2e-3f64).to_degrees();
        }
    });
}

/// `units` units calibrated on the registered head `head` (registered here) on station `st-1`,
/// an hour apart from T0, serials `SN-H000`…: each its simulated campaign (the 62-position plan,
/// 30 sets per position) on the plan the head really reaches (`reach(unit, plan)` changes the
/// nominal plan's angles), stated at the nominal angles, stored with its model-4 fit, passed.
pub fn head_line(db: &mut Db, head: &accelcal_db::Asset, units: usize, reach: impl Fn(usize, &mut Plan)) {
    db.add_asset(head).unwrap();
    for u in 0..units {
        let c = head_campaign(100 + u as u64, |plan| reach(u, plan));
        let mut bytes = Vec::new();
        c.write(&mut bytes).unwrap();
        let device = format!("{:024x}", 0xa000 + u);
        let s = accelcal_db::RunStart {
            g_m_s2: accelcal_shared::G_STANDARD,
            ..start(RunId::new(), &device, &format!("SN-H{u:03}"), "st-1", T0 + u as i64 * 3600)
        };
        db.begin_run(&s, None).unwrap();
        db.store_run_asset(s.run_id, head).unwrap();
        db.store_campaign(s.run_id, &bytes).unwrap();
        // Its model-4 fit, for the control charts.
        let pos = accelcal_core::positions::Positions::new(&c, s.g_m_s2);
        let fits = accelcal_core::calibrate::fit_positions(
            &pos,
            &pos.channel_stats(&c),
            accelcal_core::calibrate::Method::Lsq,
            accelcal_shared::terms::MODEL_4,
        )
        .unwrap();
        let coefs: Coefs = std::array::from_fn(|i| std::array::from_fn(|t| fits[i].1.coefficients[t]));
        db.store_fit(s.run_id, &fit_json(&coefs)).unwrap();
        db.finish_run(s.run_id, Outcome::Pass, "verified").unwrap();
    }
}

/// A simulated unit's campaign (seed `seed`, the 62-position plan, 30 sets per position, 2 mrad
/// of misalignment spread) on the plan `reach` makes of the nominal one, its rows stating the
/// nominal angles.
pub fn head_campaign(seed: u64, reach: impl Fn(&mut Plan)) -> accelcal_core::campaign::Campaign {
    use accelcal_core::sim::{simulate, SimConfig};
    let nominal = Plan::head();
    let mut plan = nominal.clone();
    reach(&mut plan);
    let cfg = SimConfig { seed, plan, samples: 30, misalign_sd: 0.002, ..SimConfig::default() };
    let (mut c, _) = simulate(&cfg);
    for (row, (a, b)) in c.alpha_deg.iter_mut().zip(c.beta_deg.iter_mut()).enumerate() {
        (*a, *b) = nominal.positions[row / 30];
    }
    c
}
