//! `verify`'s unit tests: the tolerances from a fit's uncertainty, the rules, the reports.

use super::*;
use accelcal_core::error::Classify;

fn model4(se_bias: f64, se_k: [f64; 3], k_own: f64) -> ChannelUncertainty {
    let terms = ["1", "ax", "ay", "az"].iter().zip([se_bias, se_k[0], se_k[1], se_k[2]]);
    ChannelUncertainty {
        terms: terms.map(|(t, se)| (Term::parse(t).unwrap(), se)).collect(),
        covariance: None,
        k_own,
        k_own_t: 0.0,
    }
}

/// Issue 24.2: a fit JSON of another device, of another record, or written without a record
/// is refused before the node is verified, naming both values.
#[test]
fn a_fit_of_another_unit_or_record_is_refused() {
    let id = Identity {
        device_id: Some("51454d552d422d4c34373545".into()),
        serial: Some("U-1".into()),
        g_m_s2: 9.81,
        g_source: None,
        campaign_sha256: "00".repeat(32),
        record_crc: Some("b1fe3d0c".into()),
    };
    let running = |crc| RecordStatus::InUse { slot: 0, sequence: 1, created_unix_s: 0, crc };
    let node = "the node on /dev/pts/3";
    let check =
        |id: &Identity, dev: &str, crc| check_fit(&("f.json".into(), id.clone()), node, dev, running(crc));
    assert!(check(&id, "51454d552d422d4c34373545", 0xb1fe3d0c).is_ok());
    let e = check(&id, "0123456789abcdef01234567", 0xb1fe3d0c).unwrap_err();
    assert_eq!(
        e.to_string(),
        "f.json has device id 51454d552d422d4c34373545 but the node on /dev/pts/3 has 0123456789abcdef01234567: \
         not the same unit"
    );
    assert_eq!(
        e.downcast_ref::<accelcal_core::campaign::identity::IdentityError>().map(Classify::kind),
        Some(accelcal_core::error::Kind::BadInput)
    );
    let e = check(&id, "51454d552d422d4c34373545", 0x1617f971).unwrap_err().to_string();
    assert!(e.starts_with("f.json has record CRC b1fe3d0c but the node on /dev/pts/3 has 1617f971"), "{e}");
    let no_record = Identity { record_crc: None, ..id };
    let e = check(&no_record, "51454d552d422d4c34373545", 0xb1fe3d0c).unwrap_err().to_string();
    assert!(e.starts_with("f.json: written without a record"), "{e}");
}

#[test]
fn tolerances_follow_the_stated_rule() {
    let c = model4(0.5, [0.03, 0.0, 0.0], 1670.0);
    let a = [9.81, 0.0, 0.0];
    let s = c.sigma(a, 0.0);
    assert!((s - (0.25f64 + (0.03f64 * 9.81).powi(2)).sqrt() / 1670.0).abs() < 1e-15);
    let t = Tolerance::Derived {
        cal: Some(Box::new(CalUncertainty { channels: [c.clone(), c.clone(), c], t_ref_c: None })),
        k: DEFAULT_COVERAGE,
    };
    let b = t.bounds(a, Some(40.0), [0.002, 0.0, 0.0]);
    assert!(
        (b[0] - 4.0 * (s * s + 4e-6).sqrt()).abs() < 1e-12,
        "no thermal terms: the temperature is not used"
    );
    assert_eq!(Tolerance::Fixed(0.01).bounds(a, None, [1.0; 3]), [0.01; 3]);
    let none = Tolerance::Derived { cal: None, k: DEFAULT_COVERAGE };
    assert_eq!(none.bounds(a, None, [0.001; 3]), [0.004; 3]);
    assert!(none.describe().contains("not included"));
    assert!(t.describe().contains("no covariance"), "{}", t.describe());
    // The coverage factor scales the bound.
    let five = Tolerance::Derived { cal: None, k: 5.0 };
    assert_eq!(five.bounds(a, None, [0.001; 3]), [0.005; 3]);
    assert!(five.describe().starts_with("|error| <= 5·σ_mean"), "{}", five.describe());
}

#[test]
fn thermal_terms_widen_the_tolerance_away_from_t_ref() {
    let mut c = model4(0.5, [0.03, 0.0, 0.0], 1670.0);
    c.terms.push((Term::parse("t").unwrap(), 0.02));
    c.terms.push((Term::parse("ax*t").unwrap(), 0.001));
    c.k_own_t = 0.167;
    let a = [9.81, 0.0, 0.0];
    let at_ref = c.sigma(a, 0.0);
    assert!((at_ref - model4(0.5, [0.03, 0.0, 0.0], 1670.0).sigma(a, 0.0)).abs() < 1e-18);
    let t = -35.0;
    let want = (0.25f64 + (0.03f64 * 9.81).powi(2) + (0.02f64 * t).powi(2) + (0.001f64 * 9.81 * t).powi(2))
        .sqrt()
        / (1670.0 + 0.167 * t);
    assert!((c.sigma(a, t) - want).abs() < 1e-15);
    let cal = CalUncertainty { channels: [c.clone(), c.clone(), c], t_ref_c: Some(25.0) };
    assert_eq!(cal.t(Some(-10.0)), -35.0);
    assert_eq!(cal.t(None), 0.0);
    let tol = Tolerance::Derived { cal: Some(Box::new(cal)), k: DEFAULT_COVERAGE };
    assert!(tol.bounds(a, Some(-10.0), [1e-4; 3])[0] > tol.bounds(a, Some(25.0), [1e-4; 3])[0]);
    assert!(tol.describe().contains("and temperature"));
}

#[test]
fn uncertainties_are_read_from_fit_json() {
    let j = r#"{"method":"lsq","channels":[
        {"channel":"x","terms":["1","ax","ay","az"],"coefficients":[32768,1670,3,-2],"std_errors":[0.5,0.01,0.02,0.03]},
        {"channel":"y","terms":["1","ax","ay","az"],"coefficients":[32000,1,1650,2],"std_errors":[0.6,0.01,0.02,0.03]},
        {"channel":"z","terms":["1","ax","ay","az"],"coefficients":[33000,1,2,1690],"std_errors":[0.7,0.01,0.02,0.03]}]}"#;
    let u = uncertainty_from_fit_json(j, "fit.json").unwrap();
    assert_eq!(u.channels[1], model4(0.6, [0.01, 0.02, 0.03], 1650.0));
    assert_eq!(u.t_ref_c, None);
    let quad = j.replacen(r#""terms":["1","ax","ay","az"]"#, r#""terms":["1","ax","ay","ax^2"]"#, 1);
    let e = uncertainty_from_fit_json(&quad, "fit.json").unwrap_err().to_string();
    assert!(e.contains("channel x has no term `az`"), "{e}");
    // A thermal fit: its terms in t are read, with the document's reference temperature.
    let th = j.replacen(
        r#""terms":["1","ax","ay","az"],"coefficients":[32768,1670,3,-2],"std_errors":[0.5,0.01,0.02,0.03]"#,
        r#""terms":["1","ax","ay","az","t","ax*t"],"coefficients":[32768,1670,3,-2,3,0.167],"std_errors":[0.5,0.01,0.02,0.03,0.02,0.001]"#,
        1,
    );
    let e = uncertainty_from_fit_json(&th, "fit.json").unwrap_err().to_string();
    assert!(e.contains("no `t_ref_c`"), "{e}");
    let th = th.replacen(r#"{"method":"lsq","#, r#"{"method":"lsq","t_ref_c":25.0,"#, 1);
    let u = uncertainty_from_fit_json(&th, "fit.json").unwrap();
    assert_eq!(u.t_ref_c, Some(25.0));
    assert_eq!((u.channels[0].terms.len(), u.channels[0].k_own_t), (6, 0.167));
    assert_eq!(u.channels[1].k_own_t, 0.0);
    assert_eq!(u.channels[0].covariance, None);
}

/// With a covariance matrix, σ_cal is sqrt(φᵀCφ): a positive covariance of the bias and its
/// temperature coefficient widens the bound on the side of t where both terms have the same
/// sign and narrows it on the other, against the diagonal-only rule.
#[test]
fn the_covariance_enters_the_calibration_uncertainty() {
    let mut c = model4(0.5, [0.0; 3], 1670.0);
    c.terms.push((Term::parse("t").unwrap(), 0.02));
    let diag = c.sigma([0.0; 3], 25.0);
    let mut cov = vec![vec![0.0; 5]; 5];
    (cov[0][0], cov[4][4]) = (0.25, 0.0004);
    (cov[0][4], cov[4][0]) = (0.005, 0.005);
    c.covariance = Some(cov);
    let want = |t: f64| (0.25 + 0.0004 * t * t + 2.0 * 0.005 * t).sqrt() / 1670.0;
    assert!((c.sigma([0.0; 3], 25.0) - want(25.0)).abs() < 1e-15);
    assert!(c.sigma([0.0; 3], 25.0) > diag);
    assert!(c.sigma([0.0; 3], -25.0) < diag);
    let cal = CalUncertainty { channels: [c.clone(), c.clone(), c], t_ref_c: Some(25.0) };
    assert!(Tolerance::Derived { cal: Some(Box::new(cal)), k: 4.0 }.describe().contains("covariance matrix"));
}

#[test]
fn covariances_are_read_from_fit_json_and_checked() {
    let ch = |name: &str, cov: &str| {
        format!(
            r#"{{"channel":"{name}","terms":["1","ax","ay","az"],"coefficients":[32768,1670,3,1670],"std_errors":[0.5,0.01,0.02,0.03],"covariance":{cov}}}"#
        )
    };
    let good = "[[0.25,0.001,0,0],[0.001,0.0001,0,0],[0,0,0.0004,0],[0,0,0,0.0009]]";
    let doc = |x: &str| {
        format!(r#"{{"method":"lsq","channels":[{},{},{}]}}"#, ch("x", x), ch("y", good), ch("z", good))
    };
    let u = uncertainty_from_fit_json(&doc(good), "fit.json").unwrap();
    let c = u.channels[0].covariance.as_ref().unwrap();
    assert_eq!((c[0][1], c[3][3]), (0.001, 0.0009));
    for (bad_cov, why) in [
        ("[[0.25,0.001,0,0],[0.002,0.0001,0,0],[0,0,0.0004,0],[0,0,0,0.0009]]", "not symmetric at (1, 0)"),
        ("[[0.25,0,0,0],[0,0.0001,0,0],[0,0,0.0004,0]]", "is not 4 rows"),
        ("[[0.25,0,0,0],[0,0.0001,0,0],[0,0,0.0004,0],[0,0,null,0.0009]]", "row 3 has a value"),
        ("[[-0.25,0,0,0],[0,0.0001,0,0],[0,0,0.0004,0],[0,0,0,0.0009]]", "negative variance at 0"),
    ] {
        let e = uncertainty_from_fit_json(&doc(bad_cov), "fit.json").unwrap_err().to_string();
        assert!(e.contains("fit.json: channel x: `covariance`") && e.contains(why), "{e}");
    }
}
