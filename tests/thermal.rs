//! Temperature compensation on the host (issue 16): a thermal campaign from `simulate --chamber`,
//! GMDH choosing the thermal structure (`select --basis linear-thermal`, also with whole
//! temperatures held out), a thermal record from `fit --temp-input`, and what that record does
//! to the calibrated acceleration at each chamber temperature compared with a model-4 record,
//! evaluated the way a node evaluates it (`accelcal_shared::thermal`).

use crate::common;

use std::path::{Path, PathBuf};

use accelcal_core::campaign::Campaign;
use accelcal_core::positions::Positions;
use accelcal_shared::record::{Record, TempSource};
use accelcal_shared::thermal::ThermalModel;
use common::{bad, ok};
use serde_json::Value;

const ID: &str = "51454d552d422d4c34373545";
/// The unit: 3 codes/°C of bias and 100 ppm/°C of sensitivity, over −10…+50 °C.
const THERMAL_EFFECT: &str = "temperature=bias:3,scale:100";
const PLAN: &[&str] = &["--chamber=-10,10,30,50", "--soak-s", "900", "--thermal-lag-s", "120"];

fn json(p: &Path) -> Value {
    serde_json::from_str(&std::fs::read_to_string(p).unwrap()).unwrap()
}

fn simulate(dir: &Path, name: &str, extra: &[&str]) -> PathBuf {
    let out = dir.join(name);
    let mut args = vec!["simulate", "--out", out.to_str().unwrap(), "--seed", "5", "--samples", "200"];
    args.extend_from_slice(PLAN);
    args.extend_from_slice(extra);
    ok(&args);
    out
}

/// The selected terms of each channel (x, y, z) of `select --json`.
fn selected(dir: &Path, campaign: &Path, extra: &[&str]) -> Vec<Vec<String>> {
    let j = dir.join("select.json");
    let mut args = vec![
        "select",
        campaign.to_str().unwrap(),
        "--basis",
        "linear-thermal",
        "--json",
        j.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    ok(&args);
    json(&j)["channels"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| {
            c["selected"]["terms"]
                .as_array()
                .unwrap()
                .iter()
                .map(|t| t.as_str().unwrap().to_string())
                .collect()
        })
        .collect()
}

/// GMDH selects `t` and the channel's own-axis `·t` term on the thermal unit, with the alternate
/// split and with whole temperatures (the two ends) held out, and rejects every thermal term on
/// a unit without thermal coefficients.
#[test]
fn gmdh_chooses_the_thermal_terms_only_where_they_are() {
    let d = tempfile::tempdir().unwrap();
    let hot = simulate(d.path(), "thermal.csv", &["--effect", THERMAL_EFFECT]);
    let cold = simulate(d.path(), "plain.csv", &[]);
    for split in [&[][..], &["--split", "temp:-10,50"][..]] {
        for (ch, terms) in selected(d.path(), &hot, split).iter().enumerate() {
            let own = ["ax*t", "ay*t", "az*t"][ch];
            assert!(
                terms.contains(&"t".to_string()) && terms.contains(&own.to_string()),
                "{split:?} {ch}: {terms:?}"
            );
            assert!(["ax", "ay", "az"].iter().all(|a| terms.contains(&a.to_string())), "{terms:?}");
        }
        for terms in selected(d.path(), &cold, split) {
            assert_eq!(terms, ["1", "ax", "ay", "az"], "{split:?}");
        }
    }
}

/// Calibrated acceleration error (RMS over dwells and axes, m/s²) of `rec` at the dwells whose
/// temperature is within 2.5 °C of `at_c`, evaluated in the node's f32 thermal path (or model 4).
fn error_at(pos: &Positions, means: &[Vec<f64>], rec: &Record, at_c: f64) -> f64 {
    let temps = pos.temp_c.as_ref().unwrap();
    let thermal = ThermalModel::of(rec).map(|m| m.to_f32());
    let m4 = rec.model4().map(|m| m.invert().unwrap().to_f32());
    let (mut ss, mut n) = (0.0, 0);
    for p in (0..pos.len()).filter(|&p| (temps[p] - at_c).abs() <= 2.5) {
        let cal = match (&thermal, &m4) {
            (Some(th), _) => th.at(temps[p] as f32).unwrap(),
            (None, Some(m)) => *m,
            _ => unreachable!("a record the node applies"),
        };
        // Dwell means as codes (f32 carries them to 1/256 code).
        let d = [0, 1, 2].map(|c| means[c][p] as f32);
        let a = [0, 1, 2].map(|i| (0..3).map(|j| cal.m[i][j] * (d[j] - cal.u0[j])).sum::<f32>());
        for (ai, want) in a.iter().zip(pos.accel[p]) {
            ss += (*ai as f64 - want).powi(2);
            n += 1;
        }
    }
    assert!(n > 0);
    (ss / n as f64).sqrt()
}

/// The thermal record (model 4 with t and the ·t terms, front-end input) states its reference,
/// range and input; applied as a node applies it, it brings the error at −10, 10, 30 and 50 °C to
/// the noise level, where the model-4 record of the same campaign leaves an error that grows with
/// the distance from the middle of the range.
#[test]
fn a_thermal_record_removes_the_temperature_dependent_error() {
    let d = tempfile::tempdir().unwrap();
    let camp = simulate(d.path(), "thermal.csv", &["--effect", THERMAL_EFFECT]);
    let (th_rec, m4_rec) = (d.path().join("thermal.rec"), d.path().join("m4.rec"));
    let s = |p: &Path| p.to_str().unwrap().to_string();
    ok(&[
        "fit",
        &s(&camp),
        "--terms",
        "ax,ay,az,t,ax*t,ay*t,az*t",
        "--record",
        &s(&th_rec),
        "--device-id",
        ID,
        "--temp-input",
        "front-end",
        "--created",
        "1800000000",
    ]);
    ok(&["fit", &s(&camp), "--record", &s(&m4_rec), "--device-id", ID, "--created", "1800000000"]);
    let shown = ok(&["record", "show", &s(&th_rec), "--json", &s(&d.path().join("rec.json"))]);
    assert!(shown.contains("temperature: t = temp_c − 25 °C, calibrated "), "{shown}");
    let j = json(&d.path().join("rec.json"));
    assert_eq!(j["thermal"]["input"], "front-end");
    assert_eq!(j["g_m_s2"], 9.81);
    let th = Record::parse(&std::fs::read(&th_rec).unwrap()).unwrap();
    let m4 = Record::parse(&std::fs::read(&m4_rec).unwrap()).unwrap();
    let t = th.thermal.unwrap();
    assert_eq!((t.t_ref_c, t.source), (25.0, TempSource::FrontEnd));
    assert!(t.t_min_c < -9.0 && t.t_max_c > 49.0, "{t:?}");

    let c = Campaign::read(&camp).unwrap();
    let pos = Positions::new(&c, 9.81);
    let means: Vec<Vec<f64>> = pos.channel_stats(&c).into_iter().map(|s| s.mean).collect();
    // Dwell-mean noise: 80 codes / sqrt(200) ≈ 5.7 codes ≈ 3.4e-3 m/s² per axis.
    for temp in [-10.0, 10.0, 30.0, 50.0] {
        let (e_th, e_m4) = (error_at(&pos, &means, &th, temp), error_at(&pos, &means, &m4, temp));
        assert!(e_th < 5e-3, "{temp} °C: thermal record leaves {e_th} m/s²");
        assert!(e_m4 > 4.0 * e_th, "{temp} °C: model 4 {e_m4} m/s² against thermal {e_th} m/s²");
    }
}

/// Thermal terms and options without a temperature, or where they do not apply, are bad input
/// naming what is missing.
#[test]
fn thermal_terms_without_a_temperature_are_bad_input() {
    let d = tempfile::tempdir().unwrap();
    let plain = d.path().join("plain.csv");
    ok(&["simulate", "--out", plain.to_str().unwrap(), "--samples", "20"]);
    let p = plain.to_str().unwrap();
    let e = bad(&["fit", p, "--terms", "ax,ay,az,t"]);
    assert!(e.contains("term `t` needs the temperature, and the campaign has no `temp_c` column"), "{e}");
    let e = bad(&["select", p, "--basis", "linear-thermal"]);
    assert!(e.contains("no `temp_c` column"), "{e}");
    let e = bad(&["select", p, "--split", "temp:50"]);
    assert!(e.contains("no `temp_c` column"), "{e}");
    let e = bad(&["fit", p, "--temp-input", "mcu"]);
    assert!(e.contains("--temp-input applies to --record only"), "{e}");
    let e = bad(&["fit", p, "--terms", "ax,ay,az,t^3"]);
    assert!(e.contains("t, t^2, ax*t, ay*t and az*t"), "{e}");
    let e = bad(&[
        "simulate",
        "--out",
        d.path().join("x.csv").to_str().unwrap(),
        "--effect",
        "temperature=bias:3",
    ]);
    assert!(e.contains("--chamber T1,T2,…"), "{e}");
}

/// `diagnose` offers the remedy: on a campaign whose unit has the thermal coefficients it names
/// `temperature` and the baseline with `t` and the own-axis `·t` terms (text and JSON `remedy`);
/// diagnosed against that baseline, the same campaign shows no temperature effect, and no remedy.
#[test]
fn diagnose_names_the_thermal_terms_and_the_compensated_campaign_is_quiet() {
    let d = tempfile::tempdir().unwrap();
    let camp = d.path().join("warm.csv");
    let c = camp.to_str().unwrap();
    ok(&[
        "simulate",
        "--out",
        c,
        "--seed",
        "8",
        "--samples",
        "100",
        "--temp-profile",
        "25:15:1",
        "--effect",
        THERMAL_EFFECT,
    ]);
    let j = d.path().join("diag.json");
    let out = ok(&["diagnose", c, "--json", j.to_str().unwrap()]);
    assert!(out.contains("effect temperature on x,y,z"), "{out}");
    assert!(
        out.contains(
            "remedy: model the temperature: `accelcal fit CAMPAIGN --terms 'ax,ay,az,t,ax*t,ay*t,az*t'`"
        ),
        "{out}"
    );
    assert_eq!(json(&j)["remedy"], "1,ax,ay,az,t,ax*t,ay*t,az*t");
    let out = ok(&["diagnose", c, "--terms", "ax,ay,az,t,ax*t,ay*t,az*t", "--json", j.to_str().unwrap()]);
    assert!(out.contains("effects found: none"), "{out}");
    assert_eq!(json(&j)["remedy"], Value::Null);
    assert!(json(&j)["effects"].as_array().unwrap().is_empty());
    // A thermal baseline needs the temperature.
    let plain = d.path().join("plain.csv");
    ok(&["simulate", "--out", plain.to_str().unwrap(), "--samples", "20"]);
    let e = bad(&["diagnose", plain.to_str().unwrap(), "--terms", "ax,ay,az,t"]);
    assert!(e.contains("baseline term `t` needs the temperature"), "{e}");
}
