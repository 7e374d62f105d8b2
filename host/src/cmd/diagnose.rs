//! `accelcal diagnose`: the gap between a campaign and its linear-sensor simulation, and the
//! effects that explain it, checked on withheld positions.

use anyhow::Context;
use serde_json::json;

use crate::cli::DiagnoseArgs;
use accelcal_core::diagnose::{self, Binned, Data, Report};
use accelcal_core::error::bad;
use accelcal_core::output::write_json;

use crate::report::sig;

/// Runs `accelcal diagnose`.
pub fn run(a: &DiagnoseArgs, warnings: &mut super::Warnings) -> anyhow::Result<()> {
    super::check_g(a.common.g)?;
    let base = accelcal_core::lsq::parse_terms(&a.terms).map_err(|e| bad(format!("--terms {e}")))?;
    // Streamed in two passes: the diagnosis needs the bins only, so memory does not grow with
    // the rows.
    let binned = Binned::read_with(&a.campaign, a.common.codes).context("reading the campaign")?;
    warnings.extend(&binned.warnings);
    let d = Data::from_binned(&binned, a.common.g)
        .and_then(|d| diagnose::diagnose_data(&d, base).map(|r| (d, r)));
    let (d, report) = d.map_err(|e| bad(format!("{}: {e}", a.campaign.display())))?;
    print_report(&report);
    if let Some(dir) = &a.plot {
        for f in crate::report::diagnose_plot::gap_map(dir, &d, &report.gap)? {
            println!("wrote {}", f.display());
        }
    }
    if let Some(j) = &a.common.json {
        write_json(j, &to_json(&report))?;
    }
    Ok(())
}

/// The JSON output: the keys first, then the details.
pub fn to_json(r: &Report) -> serde_json::Value {
    json!({
        "effects": r.effects,
        "unexplained_rms": r.unexplained_rms,
        "baseline": r.baseline,
        "consistent_with_noise": r.gap.consistent_with_noise,
        "gap": r.gap,
        "rounds": r.attribution.rounds,
        "final_z": r.attribution.final_z,
    })
}

/// Prints the human tables.
pub fn print_report(r: &Report) {
    let g = &r.gap;
    println!(
        "baseline {}: chi2 {} on {} dof, z = {} (simulated twin: z = {}) -> {}",
        r.baseline,
        sig(g.chi2, 6),
        g.dof,
        sig(g.z, 3),
        sig(g.z_sim, 3),
        if g.consistent_with_noise { "consistent with the noise" } else { "NOT consistent with the noise" }
    );
    println!();
    println!("where the gap lies (z-scores; |z| > 4 is beyond the noise)");
    println!(
        "{:<8} {:>7} {:>9} {:>9} {:>9} {:>9} {:>8} {:>8} {:>9}",
        "channel", "sigma", "rms_pos", "rms_sim", "z_pos", "z_dwell", "z_time", "z_temp", "z_approach"
    );
    for c in &g.channels {
        println!(
            "{:<8} {:>7} {:>9} {:>9} {:>9} {:>9} {:>8} {:>8} {:>9}",
            c.name,
            sig(c.sigma, 3),
            sig(c.rms_position, 3),
            sig(c.rms_position_sim, 3),
            sig(c.z_position, 3),
            sig(c.z_in_dwell, 3),
            sig(c.z_time, 3),
            c.z_temp.map_or("-".into(), |z| sig(z, 3)),
            sig(c.z_approach, 3)
        );
    }
    println!();
    println!("largest position residuals (dwell residual / per-position noise)");
    for p in &g.worst_positions {
        let zs: Vec<String> = p.z.iter().map(|z| format!("{z:>7.1}")).collect();
        println!(
            "  #{:<3} alpha {:>7.2} beta {:>7.2}: {}",
            p.position,
            p.alpha_deg,
            p.beta_deg,
            zs.join(" ")
        );
    }
    println!();
    for (i, round) in r.attribution.rounds.iter().enumerate() {
        println!(
            "round {} (held-out chi2 {} over {} bins, rms {} codes)",
            i + 1,
            sig(round.before.chi2, 6),
            round.before.bins,
            sig(round.before.rms, 4)
        );
        println!(
            "  {:<18} {:>12} {:>10} {:>10} {:>10}",
            "effect", "chi2 drop", "threshold", "explained", "rms after"
        );
        // The share of the excess χ² (over one per bin) a trial removes; with no excess (the
        // baseline already fits to the noise) there is nothing to share.
        let has_excess = round.before.chi2 > round.before.bins as f64;
        for t in &round.trials {
            println!(
                "  {:<18} {:>12} {:>10} {:>10} {:>10}",
                t.name,
                sig(t.chi2_drop, 5),
                sig(t.threshold, 3),
                if has_excess { format!("{:.0}%", 100.0 * t.explained) } else { "-".into() },
                sig(t.score.rms, 4)
            );
        }
        println!("  -> {}", round.kept.unwrap_or("nothing significant"));
    }
    println!();
    let a = &r.attribution;
    if !a.not_named.is_empty() {
        println!(
            "kept by the rounds but not named: {} (together they remove {:.0}% of the excess, less than {:.0}%)",
            a.not_named.join(", "),
            100.0 * a.joint_explained,
            100.0 * diagnose::attribution::MIN_EXPLAINED
        );
    }
    if a.from_pairs {
        println!(
            "the greedy path stalled below {:.0}% of the excess; the pair search named the effects below",
            100.0 * diagnose::attribution::MIN_EXPLAINED
        );
    }
    if r.effects.is_empty() {
        println!("effects found: none");
    }
    for e in &r.effects {
        println!(
            "effect {} on {}: held-out rms {} -> {} codes",
            e.name,
            e.channels.join(","),
            sig(e.heldout_rms_before, 4),
            sig(e.heldout_rms_after, 4)
        );
        let kind = accelcal_core::effects::EffectKind::from_name(&e.name);
        for (who, ps) in &e.parameters {
            let list: Vec<String> = ps
                .iter()
                .map(|(k, v)| {
                    let unit = kind.and_then(|c| accelcal_core::effects::unit_of(c, k)).unwrap_or("");
                    let unit = if unit.is_empty() { String::new() } else { format!(" {unit}") };
                    match v.sd {
                        Some(sd) => format!("{k} = {} ± {}{unit}", sig(v.value, 4), sig(sd, 2)),
                        None => format!("{k} = {}{unit}", sig(v.value, 4)),
                    }
                })
                .collect();
            println!("  {who:<6} {}", list.join(", "));
        }
    }
    println!(
        "unexplained rms: {} codes (final z = {})",
        sig(r.unexplained_rms, 3),
        sig(r.attribution.final_z, 3)
    );
}

#[cfg(test)]
mod tests {
    use super::*;
    use accelcal_core::campaign::Campaign;
    use accelcal_core::sim::{effects, simulate, SimConfig, TempProfile};
    use accelcal_shared::terms::MODEL_4;

    #[test]
    fn streaming_diagnosis_matches_the_in_memory_diagnosis() {
        let (mut c, _) = simulate(&SimConfig {
            samples: 37,
            seed: 11,
            temp: Some(TempProfile { base_c: 25.0, amp_c: 5.0, cycles: 1.5, phase: 0.3 }),
            effects: vec![effects::parse("settling=gain:30,tau:0.2").unwrap()],
            ..SimConfig::default()
        });
        for i in [0, 5, 400, 401, 1000] {
            c.channels[i % 3].codes[i] = 0.0; // skipped by both readers
        }
        let f = tempfile::NamedTempFile::new().unwrap();
        c.write(std::fs::File::create(f.path()).unwrap()).unwrap();
        let mem = Campaign::read(f.path()).unwrap();
        let streamed = Binned::read(f.path()).unwrap();
        assert_eq!(Binned::from_campaign(&mem), streamed);
        assert_eq!(streamed.warnings.len(), 3, "{:?}", streamed.warnings);
        let a = diagnose::diagnose(&mem, 9.81, MODEL_4).unwrap();
        let b = diagnose::diagnose_data(&Data::from_binned(&streamed, 9.81).unwrap(), MODEL_4).unwrap();
        assert_eq!(to_json(&a), to_json(&b));
        assert_eq!(a.effects.iter().map(|e| e.name.as_str()).collect::<Vec<_>>(), ["settling"]);
    }
}
