//! `bench-fleet` (issue 31 item 5): a small line generated through the store path is what
//! `fleet` counts, the commands and pages are timed, and a second run times the database as it
//! is; a line with fewer runs than units, or a month that is not one, is refused.

use super::*;

#[test]
fn the_fleet_bench_generates_a_line_through_the_store_path_and_times_its_pages() {
    let d = Dir::new();
    let db = d.s("line.db");
    let args =
        ["bench-fleet", "--db", &db, "--units", "20", "--runs", "50", "--month", "2024-06", "--repeat", "1"];
    let out = ok(&args);
    assert!(out.contains("generated 20 units, 50 runs through the store path"), "{out}");
    for line in
        ["fleet --json, 2024-06", "overview /", "unit /unit/MS9-000010", "fleet page 2024-06-01…2024-06-30"]
    {
        assert!(out.contains(line), "{line}: {out}");
    }
    let doc = d.s("fleet.json");
    ok(&["fleet", "--db", &db, "--since", "2024-01-01", "--until", "2026-12-31", "--json", &doc]);
    let j = json(Path::new(&doc));
    assert_eq!(
        (j["counts"]["runs"].as_i64(), j["counts"]["units"].as_i64()),
        (Some(50), Some(20)),
        "{}",
        j["counts"]
    );
    // Every run that passed has its fit's coefficients and U (the store path's derived rows).
    let runs = j["runs"].as_array().unwrap();
    assert!(runs.iter().any(|r| r["state"] == "pass"));
    let pops = j["populations"].as_array().unwrap();
    assert!(pops.iter().any(|p| p["name"] == "as-left bias x" && p["n"].as_i64().unwrap() > 10), "{pops:?}");
    assert!(
        j["heads"].as_array().unwrap().iter().all(|h| h["units"].as_i64().unwrap() > 0),
        "{}",
        j["heads"]
    );
    let again = ok(&args);
    assert!(again.contains("holds 50 runs of 20 units already: not generated again"), "{again}");
    let e = bad(&["bench-fleet", "--db", &db, "--units", "20", "--runs", "10"]);
    assert!(e.contains("--runs 10 is fewer than --units 20"), "{e}");
    let e = bad(&["bench-fleet", "--db", &db, "--month", "2024-13"]);
    assert!(e.contains("--month 2024-13"), "{e}");
}
