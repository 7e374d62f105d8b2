//! Tests of the sim-to-real gap diagnosis: every effect of the library found on a seeded campaign
//! that has it (magnitude ≥ 5σ of the per-position noise), nothing on clean campaigns, a foreign
//! residual left unexplained, a drift found behind random angle errors, an effect outside the
//! library not given a library name, a partial effect, a drift and a rising temperature reported
//! as confounded, the CLI's JSON keys and exit codes, and a small blind benchmark held to the aims.

use crate::common;

use accelcal_core::diagnose::{self, bench};
use accelcal_core::sim::{self, effects, SimConfig, TempProfile};
use accelcal_shared::terms::MODEL_4;
use common::accelcal;
use serde_json::Value;

fn config(seed: u64, spec: Option<&str>) -> SimConfig {
    SimConfig {
        seed,
        temp: Some(TempProfile { base_c: 25.0, amp_c: 5.0, cycles: 1.5, phase: 0.3 }),
        effects: spec.map(|s| effects::parse(s).unwrap()).into_iter().collect(),
        ..SimConfig::default()
    }
}

fn run(seed: u64, spec: Option<&str>) -> diagnose::Report {
    let (c, _) = sim::simulate(&config(seed, spec));
    diagnose::diagnose(&c, accelcal_shared::G_STANDARD, MODEL_4).unwrap()
}

/// The estimate of `param` for `who` (a channel or `all`) in the one effect found.
fn param(r: &diagnose::Report, who: &str, param: &str) -> (f64, f64) {
    let e = &r.effects[0].parameters[who][param];
    (e.value, e.sd.unwrap_or(f64::NAN))
}

#[test]
fn each_effect_is_found_with_its_parameters() {
    // Magnitudes between about 5 and 8 per-position noise sigmas (sigma/sqrt(400) = 4 codes).
    let cases: [(&str, &str); 7] = [
        ("bias_drift", "bias_drift=rate:0.2"),
        ("temperature", "temperature=bias:5"),
        ("nonlinearity", "nonlinearity=k2:0.3"),
        ("head_misalignment", "head_misalignment=rx_mrad:2"),
        ("hysteresis", "hysteresis=h:20"),
        ("settling", "settling=gain:30,tau:0.5"),
        ("angle_error", "angle_error=sd_mrad:2"),
    ];
    for (i, (name, spec)) in cases.iter().enumerate() {
        let r = run(100 + i as u64, Some(spec));
        let names: Vec<&str> = r.effects.iter().map(|e| e.name.as_str()).collect();
        assert_eq!(names, [*name], "{spec}: {:#?}", r.attribution.rounds);
        let e = &r.effects[0];
        assert!(e.heldout_rms_after < 0.9 * e.heldout_rms_before, "{spec}: {e:?}");
        assert!(!e.channels.is_empty());
        assert!(!r.gap.consistent_with_noise, "{spec}");
        assert_eq!(r.unexplained_rms, 0.0, "{spec}: the effect explains the whole gap");
    }
    let near = |(v, sd): (f64, f64), want: f64, rel: f64| {
        assert!((v - want).abs() <= rel * want.abs() + 4.0 * sd, "{v} ± {sd} vs {want}")
    };
    near(param(&run(100, Some(cases[0].1)), "y", "rate"), 0.2, 0.05);
    near(param(&run(101, Some(cases[1].1)), "z", "bias"), 5.0, 0.05);
    near(param(&run(102, Some(cases[2].1)), "x", "k2"), 0.3, 0.05);
    near(param(&run(103, Some(cases[3].1)), "all", "rx_mrad"), 2.0, 0.05);
    near(param(&run(104, Some(cases[4].1)), "x", "h"), 20.0, 0.05);
    let s = run(105, Some(cases[5].1));
    near(param(&s, "z", "gain"), 30.0, 0.1);
    near((param(&s, "z", "tau_s").0, 0.0), 0.5, 0.1);
    near(param(&run(106, Some(cases[6].1)), "all", "sd_mrad"), 2.0, 0.1);
}

#[test]
fn two_effects_that_a_third_mimics_are_found_by_the_pair_search() {
    // Drift plus hysteresis: settling mimics their sum better than either alone, so the first
    // greedy round keeps nothing and the pair search names both.
    let mut cfg = config(8, None);
    cfg.temp = Some(TempProfile { base_c: 25.0, amp_c: 5.0, cycles: 1.5, phase: 0.0 });
    cfg.effects =
        vec![effects::parse("bias_drift=rate:0.2").unwrap(), effects::parse("hysteresis=h:20").unwrap()];
    let (c, _) = sim::simulate(&cfg);
    let r = diagnose::diagnose(&c, accelcal_shared::G_STANDARD, MODEL_4).unwrap();
    let mut names: Vec<&str> = r.effects.iter().map(|e| e.name.as_str()).collect();
    names.sort();
    assert_eq!(names, ["bias_drift", "hysteresis"], "{:#?}", r.attribution.rounds);
    assert_eq!(r.unexplained_rms, 0.0);
    let h = &r.effects.iter().find(|e| e.name == "hysteresis").unwrap().parameters["z"]["h"];
    assert!((h.value - 20.0).abs() < 4.0 * h.sd.unwrap(), "{h:?}");
}

#[test]
fn clean_campaigns_report_nothing() {
    for seed in [1, 2, 3, 4] {
        let r = run(seed, None);
        assert!(r.effects.is_empty(), "seed {seed}: {:?}", r.effects);
        assert!(r.gap.consistent_with_noise, "seed {seed}: z = {}", r.gap.z);
        assert_eq!(r.unexplained_rms, 0.0);
    }
}

#[test]
fn a_residual_no_effect_explains_stays_unexplained() {
    // Random offsets of ±30 codes per position on channel x only: no effect of the library has
    // this shape (angle errors would move the other channels too).
    let (mut c, _) = sim::simulate(&config(21, None));
    for (k, w) in c.dwells().iter().enumerate() {
        let off = if (k * 7919) % 5 < 2 { 30.0 } else { -30.0 };
        for v in &mut c.channels[0].codes[w.start..w.end] {
            *v += off;
        }
    }
    let r = diagnose::diagnose(&c, accelcal_shared::G_STANDARD, MODEL_4).unwrap();
    assert!(r.effects.is_empty(), "{:?}", r.effects);
    assert!(r.unexplained_rms > 15.0, "{}", r.unexplained_rms);
    assert!(!r.gap.consistent_with_noise);
}

/// A clean campaign (seed 41) with `add(channel, t_s, position)` codes added to every sample.
fn disturbed(add: impl Fn(usize, f64, usize) -> f64) -> diagnose::Report {
    let (mut c, _) = sim::simulate(&config(41, None));
    for (k, w) in c.dwells().iter().enumerate() {
        for (ch, channel) in c.channels.iter_mut().enumerate() {
            for i in w.start..w.end {
                channel.codes[i] += add(ch, c.t_s[i], k).round();
            }
        }
    }
    diagnose::diagnose(&c, accelcal_shared::G_STANDARD, MODEL_4).unwrap()
}

#[test]
fn a_disturbance_periodic_in_time_is_found_with_its_period() {
    // 12 codes (3 per-position noise sigmas) with a period of 60 s on channel y only.
    let r = disturbed(
        |ch, t, _| if ch == 1 { 12.0 * (2.0 * std::f64::consts::PI * t / 60.0).sin() } else { 0.0 },
    );
    let p = r.gap.channels[1].period.as_ref().unwrap();
    assert!(p.significant && p.false_alarm < 1e-6, "{p:?}");
    assert!((p.period_s - 60.0).abs() < 0.05 * 60.0, "{p:?}");
    assert!((p.amplitude_codes - 12.0).abs() < 3.0, "{p:?}");
    for ch in [0, 2] {
        let q = r.gap.channels[ch].period.as_ref().unwrap();
        assert!(!q.significant, "channel {ch}: {q:?}");
    }
    // One channel's disturbance is not common to all.
    assert!(!r.gap.common_mode.as_ref().unwrap().common, "{:?}", r.gap.common_mode);
    // Clean campaigns have no significant period.
    for seed in [1, 2, 3, 4] {
        let r = run(seed, None);
        for c in &r.gap.channels {
            assert!(!c.period.as_ref().unwrap().significant, "seed {seed} {}: {:?}", c.name, c.period);
        }
    }
}

#[test]
fn a_disturbance_common_to_all_channels_is_reported_as_common() {
    // ±12 codes per position (3 per-position noise sigmas), the same on every channel: a
    // disturbance of the rig (supply, reference) rather than of one sensor.
    let offset = |k: usize| if (k * 7919) % 5 < 2 { 12.0 } else { -12.0 };
    let r = disturbed(|_, _, k| offset(k));
    let cm = r.gap.common_mode.as_ref().unwrap();
    assert!(cm.common, "{cm:?}");
    assert!(cm.pairs.iter().all(|p| p.r > 0.5), "{cm:?}");
    let r = disturbed(|ch, _, k| if ch == 0 { offset(k) } else { 0.0 });
    let cm = r.gap.common_mode.as_ref().unwrap();
    assert!(!cm.common, "{cm:?}");
    assert!(!r.gap.consistent_with_noise, "the disturbance is beyond the noise");
    assert!(!run(1, None).gap.common_mode.unwrap().common);
}

#[test]
fn the_gap_is_localised_where_the_effect_acts() {
    let r = run(31, Some("hysteresis=h:20"));
    assert!(r.gap.channels.iter().all(|c| c.z_approach.abs() > 5.0), "{:?}", r.gap.channels);
    let r = run(32, Some("settling=gain:30,tau:0.5"));
    assert!(r.gap.channels.iter().all(|c| c.z_in_dwell > 5.0 && c.in_dwell_profile[0] > 0.0));
    let r = run(33, Some("bias_drift=rate:0.2"));
    assert!(r.gap.channels.iter().all(|c| c.z_time.abs() > 5.0));
    let r = run(34, None);
    assert!(r.gap.channels.iter().all(|c| c.z_position.abs() < 4.0 && c.z_in_dwell.abs() < 4.0));
}

#[test]
fn small_blind_benchmark_meets_the_aims() {
    let s = bench::run(48, 0xb11d, bench::MAGNITUDE, &|| {});
    let kind = |k: bench::CaseKind| s.kinds[&k].clone();
    let (clean, one, two, out) = (
        kind(bench::CaseKind::Clean),
        kind(bench::CaseKind::Single),
        kind(bench::CaseKind::Pair),
        kind(bench::CaseKind::Outside),
    );
    assert_eq!((clean.campaigns, one.campaigns, two.campaigns, out.campaigns), (6, 12, 12, 12));
    assert_eq!(clean.wrong, 0, "{:#?}", s.confusion);
    assert!(one.right_share() >= 0.95, "{:#?}", s.confusion);
    assert!(two.right_share() >= 0.90, "{:#?}", s.confusion);
    assert!(s.outside_overclaimed <= 1, "{:#?}", s.confusion);
    assert!(s.shrink_vs_oracle > 0.9, "{}", s.shrink_vs_oracle);
    // Every effect of a campaign has its own magnitude in the range, the outside ones too.
    for o in &s.outcomes {
        assert_eq!(o.case.magnitudes.len(), o.case.truth.len());
        assert!(o.case.magnitudes.iter().all(|m| (2.95..=8.05).contains(m)), "{:?}", o.case);
    }
}

#[test]
fn a_drift_behind_random_angle_errors_is_named_with_them() {
    // The pair that named nothing before the joint search (angle errors hid the drift).
    let mut cfg = config(12, None);
    cfg.effects = vec![
        effects::parse("angle_error=sd_mrad:1").unwrap(),
        effects::parse("bias_drift=rate:0.12").unwrap(),
    ];
    let (c, _) = sim::simulate(&cfg);
    let r = diagnose::diagnose(&c, accelcal_shared::G_STANDARD, MODEL_4).unwrap();
    let mut names: Vec<&str> = r.effects.iter().map(|e| e.name.as_str()).collect();
    names.sort();
    assert_eq!(names, ["angle_error", "bias_drift"], "{:#?}", r.attribution.rounds);
    assert!(r.effects.iter().all(|e| !e.partial), "{:#?}", r.attribution.leftovers);
    assert!(r.attribution.signatures.iter().all(|s| s.present()), "{:?}", r.attribution.signatures);
    let rate = &r.effects.iter().find(|e| e.name == "bias_drift").unwrap().parameters["y"]["rate"];
    assert!((rate.value - 0.12).abs() < 4.0 * rate.sd.unwrap(), "{rate:?}");
}

#[test]
fn an_effect_outside_the_library_is_not_given_a_library_name() {
    // Cable wind-up: a bias proportional to the head's alpha (rewound at each row), 8 codes per
    // turn of 360 degrees on x, -6 on z. Hysteresis and the rest take a slice at most; what is
    // named is partial and the rest is reported as unexplained, with where it lies.
    let r = disturbed(|ch, _, k| {
        let alpha = (k % 12) as f64 * 30.0;
        [40.0, 0.0, -30.0][ch] * alpha / 360.0
    });
    let full: Vec<&str> = r.effects.iter().filter(|e| !e.partial).map(|e| e.name.as_str()).collect();
    assert!(full.is_empty() || r.attribution.joint_explained <= 0.5, "{full:?}: {:#?}", r.attribution);
    assert!(r.unexplained_rms > 2.0, "{}", r.unexplained_rms);
    let at = &r.attribution.residual_where;
    assert!(at[0].z_positions > 4.0 && at[2].z_positions > 4.0 && at[1].z_positions < 4.0, "{at:?}");
}

#[test]
fn an_effect_that_removes_part_of_a_wider_structure_is_partial() {
    // A transient even in the step (a square-law supply droop) on top of settling: settling is
    // named, but a transient of its kind is left, so it is reported as partial.
    let (mut c, _) = sim::simulate(&config(31, Some("settling=gain:20,tau:0.5")));
    let dwells = c.dwells();
    for (k, w) in dwells.iter().enumerate() {
        let droop = if k == 0 || k % 2 == 1 { 0.0 } else { 40.0 };
        for ch in &mut c.channels {
            for i in w.start..w.end {
                ch.codes[i] -= (droop * (-((i - w.start) as f64) / 50.0).exp()).round();
            }
        }
    }
    let r = diagnose::diagnose(&c, accelcal_shared::G_STANDARD, MODEL_4).unwrap();
    let e = r.effects.iter().find(|e| e.name == "settling").expect("settling is named");
    let left = r.attribution.leftovers.iter().find(|l| l.name == "settling").unwrap();
    assert!(e.partial && left.partial && left.z_family >= diagnose::structure::PARTIAL_Z, "{left:?}");
    assert_eq!(left.domain, "in dwell");
}

#[test]
fn a_drift_and_a_temperature_that_rises_with_time_are_reported_as_confounded() {
    let mut cfg = config(17, Some("bias_drift=rate:0.2"));
    // A quarter cycle from the trough: the temperature rises steadily over the campaign.
    cfg.temp =
        Some(TempProfile { base_c: 25.0, amp_c: 5.0, cycles: 0.25, phase: -std::f64::consts::FRAC_PI_2 });
    let (c, _) = sim::simulate(&cfg);
    let r = diagnose::diagnose(&c, accelcal_shared::G_STANDARD, MODEL_4).unwrap();
    let cf = &r.attribution.confounds;
    assert_eq!(cf.len(), 1, "{cf:?}");
    assert_eq!(cf[0].effects, ["bias_drift", "temperature"]);
    assert!(cf[0].r > 0.9 && cf[0].separate.contains("temperature"), "{cf:?}");
    // One of the two is named, never both, and the report says they cannot be told apart.
    let names: Vec<&str> = r.effects.iter().map(|e| e.name.as_str()).collect();
    assert_eq!(names.len(), 1, "{names:?}");
    assert!(["bias_drift", "temperature"].contains(&names[0]));
    // On the default profile (1.5 cycles), nothing is confounded.
    assert!(run(17, Some("bias_drift=rate:0.2")).attribution.confounds.is_empty());
}

/// Checks every "explained" share of a diagnosis report against the numbers on its row and its
/// round: the share is 100 × chi2 drop / (held-out chi2 − bins), so it lies below 100 × chi2 /
/// (chi2 − bins) (an effect cannot remove more than the whole chi2) and is negative when the
/// effect, fitted on the other positions, makes the withheld ones worse (with no lower bound:
/// −136 % for angle_error on the hysteresis campaign below); a kept effect removes at least half
/// the excess; a negative share is printed `worse` (no percentage: −136 % of an excess is no
/// share), and only it is followed by a note on why. Every `%` of the report is one of these
/// shares. Returns how many rows were checked (shares and `worse` rows).
fn check_shares(report: &str) -> usize {
    let num = |w: &str| w.parse::<f64>().unwrap_or_else(|_| panic!("`{w}` in\n{report}"));
    let (mut chi2, mut bins, mut shares, mut worse) = (f64::NAN, f64::NAN, 0, 0);
    let mut rows: Vec<(String, f64, Option<f64>)> = Vec::new();
    let mut in_round = false;
    for line in report.lines() {
        // A negative share is printed `worse`, with a note on why after the row.
        let (line, note) = match line.split_once("  (fitted on the other positions") {
            Some((row, _)) => (row, true),
            None => (line, false),
        };
        let w: Vec<&str> = line.split_whitespace().collect();
        if line.starts_with("round ") {
            // round N (held-out chi2 X over B bins, rms R codes)
            (chi2, bins) = (num(w[4]), num(w[6]));
            rows.clear();
            in_round = true;
        } else if in_round && w.len() == 5 {
            // effect, chi2 drop, threshold, explained, rms after
            if w[3] == "worse" {
                assert!(chi2 > bins && note && num(w[1]) < 0.0, "`worse` only for a negative drop: {line}");
                rows.push((w[0].to_string(), num(w[1]), None));
                worse += 1;
                continue;
            }
            let share = (w[3] != "-").then(|| num(w[3].strip_suffix('%').expect("a share in %")));
            assert_eq!(share.is_some(), chi2 > bins, "a share only where there is an excess: {line}");
            if let Some(pct) = share {
                let excess = chi2 - bins;
                let drop = num(w[1]);
                // Printed to 5 (drop) and 6 (chi2) digits, the share to a whole percent.
                let want = 100.0 * drop / excess;
                let tol = 0.5 + want.abs() * 1e-4 + 100.0 * drop.abs() * chi2 * 1e-5 / (excess * excess);
                assert!((pct - want).abs() <= tol, "{line}: {pct}% vs {want:.2}% of the excess");
                assert!(pct <= 100.0 * chi2 / excess + 0.5, "{line}: more than the whole chi2");
                assert_eq!(note, drop < 0.0, "{line}: a negative share, and only it, says why");
                shares += 1;
            }
            rows.push((w[0].to_string(), num(w[1]), share));
        } else if let Some(kept) = line.strip_prefix("  -> ") {
            in_round = false;
            if let Some((_, _, Some(pct))) = rows.iter().find(|r| r.0 == kept) {
                assert!(*pct >= 50.0 || kept == "angle_error", "{kept} kept with {pct}% of the excess");
            }
        }
    }
    let percents = report.split_whitespace().filter(|w| w.ends_with('%')).count();
    assert_eq!(percents, shares, "a `%` outside the trial rows:\n{report}");
    shares + worse
}

#[test]
fn cli_writes_the_issue_json_plots_and_refuses_bad_input() {
    let dir = tempfile::tempdir().unwrap();
    let p = |n: &str| dir.path().join(n).to_str().unwrap().to_string();
    let out = accelcal(&[
        "simulate",
        "--out",
        &p("c.csv"),
        "--seed",
        "5",
        "--temp-profile",
        "25:5:1.5",
        "--effect",
        "hysteresis=h:20",
    ]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let out = accelcal(&["diagnose", &p("c.csv"), "--json", &p("d.json"), "--plot", &p("plots")]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let stdout = String::from_utf8(out.stdout).unwrap();
    assert!(stdout.contains("effect hysteresis"), "{stdout}");
    // Each trial's share is what it says: its chi2 drop over the round's excess chi2, at most
    // the whole chi2; `-` when a round has no excess to share (as on a clean campaign).
    assert!(accelcal(&["simulate", "--out", &p("clean.csv")]).status.success());
    let clean = String::from_utf8(accelcal(&["diagnose", &p("clean.csv")]).stdout).unwrap();
    assert!(clean.contains("nothing significant"), "{clean}");
    assert!(check_shares(&stdout) >= 6, "{stdout}");
    check_shares(&clean);
    let v: Value = serde_json::from_str(&std::fs::read_to_string(p("d.json")).unwrap()).unwrap();
    assert!(v["unexplained_rms"].is_number());
    let e = &v["effects"][0];
    assert_eq!(e["name"], "hysteresis");
    for key in ["channels", "parameters", "heldout_rms_before", "heldout_rms_after"] {
        assert!(!e[key].is_null(), "{key} missing: {e}");
    }
    assert!(e["parameters"]["x"]["h"]["value"].as_f64().unwrap() > 15.0);
    assert!(std::fs::read_to_string(p("plots/gap-positions.svg")).unwrap().contains("<svg"));
    assert!(std::path::Path::new(&p("plots/gap-in-dwell.svg")).exists());
    // The campaign has temp_c: the residual against temperature, labelled in °C and codes.
    let temp = std::fs::read_to_string(p("plots/gap-temperature.svg")).unwrap();
    assert!(temp.contains("<svg") && temp.contains("°C") && temp.contains("codes"));
    assert!(stdout.contains("gap-temperature.svg"), "{stdout}");
    assert!(v["gap"]["channels"][0]["period"]["period_s"].is_number(), "{}", v["gap"]);
    assert!(v["gap"]["common_mode"]["common"].is_boolean(), "{}", v["gap"]);
    // Without temp_c, no temperature plot.
    let out = accelcal(&["diagnose", &p("clean.csv"), "--plot", &p("clean-plots")]);
    assert!(out.status.success());
    assert!(std::path::Path::new(&p("clean-plots/gap-positions.svg")).exists());
    assert!(!std::path::Path::new(&p("clean-plots/gap-temperature.svg")).exists());

    let exit2 = |args: &[&str], want: &str| {
        let out = accelcal(args);
        let err = String::from_utf8_lossy(&out.stderr).to_string();
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(want), "{args:?}: {err}");
    };
    exit2(&["diagnose", &p("missing.csv")], "missing.csv");
    exit2(&["diagnose", &p("c.csv"), "--terms", "aq"], "--terms");
    exit2(&["diagnose", &p("c.csv"), "--baseline", "aq"], "--terms");
    exit2(&["simulate", "--out", &p("t.csv"), "--effect", "temperature=bias:1"], "--temp-profile");
    exit2(&["simulate", "--out", &p("t.csv"), "--effect", "settling=gain:1,k:2"], "unknown parameter");
    exit2(&["bench-diagnose", "--campaigns", "0"], "--campaigns");
}
