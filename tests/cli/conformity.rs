//! `verify --spec`: the specification file is read and checked before the node is touched.

use super::*;

#[test]
fn a_specification_file_is_checked_before_the_node_is_touched() {
    let d = Dir::new();
    let verify = |spec: &str| -> Vec<String> {
        ["verify", "--port", "/dev/null/none", "--head", "manual", "--g", "9.81", "--spec", spec]
            .iter()
            .map(|s| s.to_string())
            .collect()
    };
    for (text, want) in [
        (
            "unit_type = \"T\"\nacceleration_error_m_s2 = 0.05\nrule = \"guard-band\"\nlimit = 3\n",
            ":4:1: unknown field `limit`",
        ),
        (
            "unit_type = \"T\"\nacceleration_error_m_s2 = 0.05\nrule = \"strict\"\n",
            ":3:8: unknown variant `strict`",
        ),
        ("unit_type = \"T\"\nrule = \"simple\"\n", "missing field `acceleration_error_m_s2`"),
        (
            "unit_type = \"T\"\nacceleration_error_m_s2 = 0.05\nrule = \"simple\"\nguard_band_m_s2 = 0.01\n",
            "`guard_band_m_s2` does not apply to the rule `simple`",
        ),
        (
            "unit_type = \"T\"\nacceleration_error_m_s2 = 0\nrule = \"simple\"\n",
            "must be a positive number of m/s²",
        ),
        (
            "unit_type = \"T\"\nacceleration_error_m_s2 = 0.05\nrule = \"simple\"\nbias_mg = -1\n",
            "`bias_mg` must be a positive limit, got -1",
        ),
    ] {
        let f = d.p("spec.toml");
        std::fs::write(&f, text).unwrap();
        let args = verify(f.to_str().unwrap());
        let e = common::bad(&args.iter().map(String::as_str).collect::<Vec<_>>());
        assert!(e.contains(&format!("{}", f.display())) && e.contains(want), "{text}: {e}");
    }
    // --spec replaces the consistency bound: --tolerance and --coverage do not go with it.
    for (opt, v) in [("--tolerance", "0.01"), ("--coverage", "5")] {
        let mut args = verify(&d.s("spec.toml"));
        args.extend([opt.to_string(), v.to_string()]);
        let o = accelcal(&args.iter().map(String::as_str).collect::<Vec<_>>());
        assert_eq!(o.status.code(), Some(2), "{opt}");
        assert!(String::from_utf8_lossy(&o.stderr).contains("cannot be used with"), "{o:?}");
    }
    // A bias limit is measured at the ±axis positions: a plan without them is refused before
    // the port is opened (bad input, not the environment's exit code 3).
    std::fs::write(
        d.p("spec.toml"),
        "unit_type = \"T\"\nacceleration_error_m_s2 = 0.05\nrule = \"guard-band\"\nbias_mg = 3\n",
    )
    .unwrap();
    let mut args = verify(&d.s("spec.toml"));
    args.extend(["--plan".to_string(), "random:8".to_string()]);
    let e = common::bad(&args.iter().map(String::as_str).collect::<Vec<_>>());
    assert!(
        e.contains("a position imposing +g and one imposing −g along each axis: the plan has none along x"),
        "{e}"
    );
    let o = accelcal(&["verify", "--port", "/dev/null/none", "--head", "manual", "--head-angle-u", "3"]);
    assert_eq!(o.status.code(), Some(2), "--head-angle-u needs --spec");
}
