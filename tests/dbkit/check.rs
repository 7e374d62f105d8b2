//! The station's check standard in the database (issue 31 item 2), on either engine.

use super::*;

/// The station's check runs (issue 31 item 2) are found by the database on either engine: only
/// the runs of that station ended `check standard…`, oldest first, not voided, each with the mean
/// of its as-found errors; a calibration of the same unit is not a check.
pub fn check_runs_are_the_station_s_checks(spec: &str) {
    use accelcal_db::check::{check_charts, out_of_control};
    let mut db = Db::open(spec).unwrap();
    let dev = "51454d552d422d4c34373545";
    calibrate(&mut db, &start(RunId::new(), dev, "GOLD-1", "line-1", 1_000), &coefs(0.0, 0), None);
    let mut ids = Vec::new();
    for (i, (station, e)) in [
        ("line-1", 0.012),
        ("line-1", 0.006),
        ("line-2", 0.5),
        ("line-1", 0.012),
        ("line-1", 0.006),
        ("line-1", 0.012),
        ("line-1", 0.006),
        ("line-1", 0.3),
    ]
    .into_iter()
    .enumerate()
    {
        let run = RunId::new();
        db.begin_run(&start(run, dev, "GOLD-1", station, 2_000 + i as i64), None).unwrap();
        db.store_verification(run, Phase::AsFound, &verification(dev, e, 1.0)).unwrap();
        let (outcome, reason) = if e < 0.1 {
            (Outcome::Pass, "check standard: in control")
        } else {
            (Outcome::Rejected, "check standard: out of control")
        };
        db.finish_run(run, outcome, reason).unwrap();
        if station == "line-1" {
            ids.push(run.to_string());
        }
    }
    let checks = db.check_runs("line-1").unwrap();
    assert_eq!(checks.iter().map(|c| c.run_id.clone()).collect::<Vec<_>>(), ids);
    // `verification` spreads the error e·p/6 over positions 1..6 on x: mean 3.5·e/6.
    let m = checks[0].mean_error_m_s2.unwrap();
    assert!((m[0] - 0.012 * 3.5 / 6.0).abs() < 1e-12 && m[1] == 0.0, "{m:?}");
    assert_eq!(checks.last().unwrap().outcome.as_deref(), Some("rejected"));
    let why = out_of_control(&check_charts(&checks)).expect("the last check is far out");
    assert!(why.starts_with("mean error x: rule 1"), "{why}");
    assert!(db.check_runs("line-3").unwrap().is_empty());
    // `fleet` counts the calibration, not the checks, and shows each station's check standard.
    let all = accelcal_db::fleet::Filter { since_unix_s: 0, until_unix_s: i64::MAX, ..Default::default() };
    let c = db.fleet_counts(&all).unwrap();
    assert_eq!((c.runs, c.rejected), (1, 0), "{c:?}");
    assert_eq!(db.fleet_runs(&all).unwrap().len(), 1);
    let cs = db.check_standards(None).unwrap();
    let states: Vec<(&str, &str, usize)> =
        cs.iter().map(|c| (c.station.as_str(), c.state, c.checks)).collect();
    assert_eq!(states, [("line-1", "out of control", 7), ("line-2", "not judged", 1)]);
    assert_eq!(db.check_standards(Some("line-2")).unwrap().len(), 1);
}
