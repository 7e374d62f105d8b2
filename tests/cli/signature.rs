//! `bench-signature`: every change of the head it studies, the weaker ones included, in its
//! table and its JSON; a change inside the tracking's baseline refused.

use super::*;

#[test]
fn the_signature_bench_studies_each_change_and_refuses_one_inside_the_baseline() {
    let d = Dir::new();
    let doc = d.s("signature.json");
    let out = ok(&["bench-signature", "--fleets", "2", "--units", "90", "--change-at", "60", "--json", &doc]);
    for case in [
        "none (a true head)",
        "α of position 27 (α 60°, β 0°) +0.5 mrad",
        "α of position 8 (α 210°, β -60°) +0.5 mrad",
        "α of position 27 (α 60°, β 0°) +0.25 mrad",
        "α of position 27 (α 60°, β 0°) +0.1 mrad",
        "mount rotated 1 mrad about z",
        "mount rotated 0.5 mrad about z",
    ] {
        assert!(out.contains(case), "{case}: {out}");
    }
    let rows = json(Path::new(&doc));
    let rows = rows.as_array().unwrap();
    assert_eq!(rows.len(), 7);
    for r in rows {
        assert_eq!(r["fleets"], 2);
        assert_eq!(r["delays"].as_array().unwrap().len(), 2);
    }
    let e = bad(&["bench-signature", "--fleets", "2", "--units", "90", "--change-at", "20"]);
    assert!(e.contains("inside the tracking's baseline of 50 units"), "{e}");
}
