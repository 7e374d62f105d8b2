//! `bench-signature`: every change of the head it studies, the weaker ones included, at each
//! unit of `--change-at`, beside its oracle, in its table and its JSON; a change before the
//! tracking's first tracked unit refused.

use super::*;

#[test]
fn the_signature_bench_studies_each_change_beside_its_oracle_and_refuses_one_too_early() {
    let d = Dir::new();
    let doc = d.s("signature.json");
    let out = ok(&[
        "bench-signature",
        "--fleets",
        "2",
        "--units",
        "90",
        "--change-at",
        "10,60",
        "--after",
        "20",
        "--json",
        &doc,
    ]);
    for case in [
        "false alarms: ",
        "change at unit 10 (20 units simulated after it)",
        "change at unit 60 (20 units simulated after it)",
        "α of position 27 (α 60°, β 0°) +0.5 mrad",
        "α of position 8 (α 210°, β -60°) +0.5 mrad",
        "α of position 8 (α 210°, β -60°) +0.25 mrad",
        "α of position 27 (α 60°, β 0°) +0.25 mrad",
        "α of position 27 (α 60°, β 0°) +0.1 mrad",
        "mount rotated 1 mrad about z",
        "mount rotated 0.5 mrad about z",
    ] {
        assert!(out.contains(case), "{case}: {out}");
    }
    let rows = json(Path::new(&doc));
    let rows = rows.as_array().unwrap();
    // The true head, then the seven changes at each of the two units.
    assert_eq!(rows.len(), 1 + 2 * 7);
    assert_eq!((rows[0]["change"]["kind"].as_str(), rows[0]["units"].as_u64()), (Some("none"), Some(90)));
    for r in &rows[1..] {
        assert_eq!(r["fleets"], 2);
        assert_eq!(r["delays"].as_array().unwrap().len(), 2);
        assert_eq!(r["oracle_delays"].as_array().unwrap().len(), 2);
        assert!(r["oracle"]["h"].as_f64().unwrap() > 0.0, "{r}");
        let at = r["change_at"].as_u64().unwrap();
        assert!([10, 60].contains(&at) && r["units"].as_u64() == Some(at + 20), "{r}");
    }
    let e = bad(&["bench-signature", "--fleets", "2", "--units", "90", "--change-at", "2"]);
    assert!(e.contains("before the tracking's first tracked unit (unit 4, from 0)"), "{e}");
}
