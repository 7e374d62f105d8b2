//! `accelcal diagnose`: the gap between a campaign and its linear-sensor simulation, and the
//! effects that explain it, checked on withheld positions.

use anyhow::Context;
use serde_json::json;

use crate::settings::campaign::Diagnose;
use accelcal_core::diagnose::{self, Binned, Data, Report};
use accelcal_core::error::bad;
use accelcal_core::output::write_json;

use crate::report::sig;

/// Runs `accelcal diagnose`.
pub fn run(a: &Diagnose, g: &super::Gravity, warnings: &mut super::Warnings) -> anyhow::Result<()> {
    let base = a.terms;
    // Streamed in two passes: the diagnosis needs the bins only, so memory does not grow with
    // the rows.
    let binned = Binned::read_with(&a.campaign.path, a.campaign.codes).context("reading the campaign")?;
    warnings.extend(&binned.warnings);
    let d = Data::from_binned(&binned, g.g).and_then(|d| diagnose::diagnose_data(&d, base).map(|r| (d, r)));
    let (d, report) = d.map_err(|e| bad(format!("{}: {e}", a.campaign.path.display())))?;
    print_report(&report)?;
    if let Some(dir) = &a.plot {
        for f in crate::report::diagnose_plot::gap_map(dir, &d, &report.gap)? {
            outln!("wrote {}", f.display())?;
        }
    }
    if let Some(j) = &a.campaign.json {
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
        "joint_explained": r.attribution.joint_explained,
        "signatures": r.attribution.signatures,
        "leftovers": r.attribution.leftovers,
        "residual_where": r.attribution.residual_where,
        "confounds": r.attribution.confounds,
        "remedy": r.remedy,
    })
}

/// Appended to a trial row whose share of the excess is negative (printed `worse`).
pub const NEGATIVE_SHARE: &str = "  (fitted on the other positions, the effect made the held-out fit worse)";

/// The verdict of the headline: the noise test, and never "consistent with the noise" while an
/// effect is named (the attribution may name one below the noise threshold when it passes its
/// own held-out test).
fn headline(r: &Report) -> String {
    let names: Vec<&str> = r.effects.iter().map(|e| e.name.as_str()).collect();
    match (r.gap.consistent_with_noise, names.is_empty()) {
        (true, true) => "consistent with the noise".into(),
        (true, false) => format!(
            "below the noise threshold (z < {}), but the held-out test names {}",
            diagnose::NOISE_Z,
            names.join(", ")
        ),
        (false, _) => "NOT consistent with the noise".into(),
    }
}

/// The strongest period over time of each channel's dwell residuals.
fn print_periods(r: &Report) -> anyhow::Result<()> {
    let Some((lo, hi)) = r.gap.channels.iter().find_map(|c| c.period.as_ref().map(|p| p.searched_s)) else {
        return Ok(());
    };
    outln!()?;
    outln!(
        "periodicity over time (sine fitted to the dwell residuals, periods {} to {} s; false alarm: F test against the rest of the residual, over the whole search; below {} is significant)",
        sig(lo, 3),
        sig(hi, 3),
        diagnose::periodic::FALSE_ALARM
    )?;
    outln!(
        "{:<8} {:>10} {:>15} {:>12} {:>12}",
        "channel",
        "period_s",
        "amplitude_codes",
        "amplitude_mg",
        "false_alarm"
    )?;
    for c in &r.gap.channels {
        match &c.period {
            Some(p) => {
                let (codes, mg) = if p.amplitude_resolved {
                    (sig(p.amplitude_codes, 3), mg(p.amplitude_codes, c.mg_per_code))
                } else {
                    ("unresolved".into(), "-".into())
                };
                outln!(
                    "{:<8} {:>10} {:>15} {:>12} {:>12}  {}",
                    c.name,
                    sig(p.period_s, 3),
                    codes,
                    mg,
                    format!("{:.2e}", p.false_alarm),
                    if p.significant { "significant" } else { "not significant" }
                )?
            }
            None => outln!("{:<8} {:>10} {:>15} {:>12} {:>12}", c.name, "-", "-", "-", "-")?,
        }
    }
    if r.gap.channels.iter().any(|c| c.period.as_ref().is_some_and(|p| !p.amplitude_resolved)) {
        outln!("  (unresolved: the sine reaches its amplitude only between the positions' times, or beyond the ADC's range)")?;
    }
    Ok(())
}

/// `codes` in mg at `mg_per_code` (3 significant digits), or `-` without a sensitivity.
fn mg(codes: f64, mg_per_code: f64) -> String {
    if mg_per_code.is_finite() {
        sig(codes * mg_per_code, 3)
    } else {
        "-".into()
    }
}

/// mg per code of the named channels together: their mean, of every channel when none is named
/// or none of the names is a channel; NaN when none has a sensitivity.
fn mg_per_code_of<'a>(r: &Report, names: impl IntoIterator<Item = &'a str>) -> f64 {
    let names: Vec<&str> = names.into_iter().collect();
    let named = |c: &&diagnose::gap::ChannelGap| names.contains(&c.name.as_str());
    let all = !r.gap.channels.iter().any(|c| named(&c));
    let v: Vec<f64> = r
        .gap
        .channels
        .iter()
        .filter(|c| all || named(c))
        .map(|c| c.mg_per_code)
        .filter(|m| m.is_finite())
        .collect();
    if v.is_empty() {
        f64::NAN
    } else {
        v.iter().sum::<f64>() / v.len() as f64
    }
}

/// Whether the dwell residual is common to all channels.
fn print_common_mode(r: &Report) -> anyhow::Result<()> {
    let Some(cm) = &r.gap.common_mode else { return Ok(()) };
    outln!()?;
    outln!("common mode (correlation r of the dwell residuals of two channels over the positions, z = atanh(r)*sqrt(positions - 3))")?;
    let pairs: Vec<String> = cm
        .pairs
        .iter()
        .map(|p| format!("{}-{}: r = {} (z = {})", p.channels.0, p.channels.1, sig(p.r, 3), sig(p.z, 3)))
        .collect();
    outln!("  {}", pairs.join("; "))?;
    outln!(
        "  -> {}",
        if cm.common {
            "common to all channels (every pair beyond |z| = 4, one sign)"
        } else {
            "not common to all channels"
        }
    )?;
    Ok(())
}

/// Prints the human tables.
pub fn print_report(r: &Report) -> anyhow::Result<()> {
    let g = &r.gap;
    outln!(
        "baseline {}: chi2 {} on {} dof, z = {} (simulated twin: z = {}) -> {}",
        r.baseline,
        sig(g.chi2, 6),
        g.dof,
        sig(g.z, 3),
        sig(g.z_sim, 3),
        headline(r)
    )?;
    outln!()?;
    outln!("where the gap lies (sigma per sample, rms_pos and rms_sim in codes; z-scores: |z| > 4 is beyond the noise)")?;
    outln!(
        "{:<8} {:>7} {:>9} {:>9} {:>9} {:>9} {:>8} {:>8} {:>9}",
        "channel",
        "sigma",
        "rms_pos",
        "rms_sim",
        "z_pos",
        "z_dwell",
        "z_time",
        "z_temp",
        "z_approach"
    )?;
    for c in &g.channels {
        outln!(
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
        )?;
    }
    print_periods(r)?;
    print_common_mode(r)?;
    outln!()?;
    outln!("largest position residuals (dwell residual / per-position noise)")?;
    for p in &g.worst_positions {
        let zs: Vec<String> = p.z.iter().map(|z| format!("{z:>7.1}")).collect();
        outln!("  #{:<3} alpha {:>7.2} beta {:>7.2}: {}", p.position, p.alpha_deg, p.beta_deg, zs.join(" "))?;
    }
    outln!()?;
    for (i, round) in r.attribution.rounds.iter().enumerate() {
        outln!(
            "round {} (held-out chi2 {} over {} bins, rms {} codes)",
            i + 1,
            sig(round.before.chi2, 6),
            round.before.bins,
            sig(round.before.rms, 4)
        )?;
        outln!(
            "  {:<18} {:>12} {:>10} {:>10} {:>10}",
            "effect",
            "chi2 drop",
            "threshold",
            "explained",
            "rms after"
        )?;
        // The share of the excess χ² (over one per bin) a trial removes; with no excess (the
        // baseline already fits to the noise) there is nothing to share.
        let has_excess = round.before.chi2 > round.before.bins as f64;
        for t in &round.trials {
            // A negative share is no share: the row says "worse" and why (the JSON keeps the value).
            let worse = has_excess && t.explained < 0.0;
            let share = match (has_excess, worse) {
                (false, _) => "-".into(),
                (true, true) => "worse".into(),
                (true, false) => format!("{:.0}%", 100.0 * t.explained),
            };
            outln!(
                "  {:<18} {:>12} {:>10} {:>10} {:>10}{}",
                t.name,
                sig(t.chi2_drop, 5),
                sig(t.threshold, 3),
                share,
                sig(t.score.rms, 4),
                if worse { NEGATIVE_SHARE } else { "" }
            )?;
        }
        outln!("  -> {}", round.kept.unwrap_or("nothing significant"))?;
    }
    outln!()?;
    print_selection_notes(r)?;
    if r.effects.is_empty() {
        outln!("effects found: none")?;
    }
    for e in &r.effects {
        let per = mg_per_code_of(r, e.channels.iter().map(String::as_str));
        outln!(
            "effect {}{} on {}: held-out rms {} -> {} codes ({} -> {} mg)",
            e.name,
            if e.partial { " (PARTIAL)" } else { "" },
            e.channels.join(","),
            sig(e.heldout_rms_before, 4),
            sig(e.heldout_rms_after, 4),
            mg(e.heldout_rms_before, per),
            mg(e.heldout_rms_after, per)
        )?;
        let kind = accelcal_core::effects::EffectKind::from_name(&e.name);
        for (who, ps) in &e.parameters {
            let list: Vec<String> = ps
                .iter()
                .map(|(k, v)| {
                    let unit = kind.and_then(|c| accelcal_core::effects::unit_of(c, k)).unwrap_or("");
                    let text = |value: f64, sd: Option<f64>, unit: &str| {
                        let unit = if unit.is_empty() { String::new() } else { format!(" {unit}") };
                        match sd {
                            Some(sd) => format!("{} ± {}{unit}", sig(value, 4), sig(sd, 2)),
                            None => format!("{}{unit}", sig(value, 4)),
                        }
                    };
                    // A size in codes is also given in mg, at the channel's sensitivity.
                    let per = mg_per_code_of(r, [who.as_str()]);
                    match unit.strip_prefix("codes") {
                        Some(rest) if per.is_finite() => format!(
                            "{k} = {} ({})",
                            text(v.value, v.sd, unit),
                            text(v.value * per, v.sd.map(|sd| sd * per), &format!("mg{rest}"))
                        ),
                        _ => format!("{k} = {}", text(v.value, v.sd, unit)),
                    }
                })
                .collect();
            outln!("  {who:<6} {}", list.join(", "))?;
        }
    }
    outln!(
        "unexplained rms: {} codes, {} mg (final z = {})",
        sig(r.unexplained_rms, 3),
        mg(r.unexplained_rms, mg_per_code_of(r, [])),
        sig(r.attribution.final_z, 3)
    )?;
    if let Some(terms) = &r.remedy {
        let terms = terms.trim_start_matches("1,");
        outln!(
            "remedy: model the temperature: `accelcal fit CAMPAIGN --terms '{terms}'` (with --record, add --temp-input mcu or front-end); `accelcal select CAMPAIGN --basis linear-thermal` lets GMDH choose; `diagnose --terms '{terms}'` shows what is left"
        )?;
    }
    print_leftovers(r)?;
    Ok(())
}

/// Effects kept but not named, and where the named set came from.
fn print_selection_notes(r: &Report) -> anyhow::Result<()> {
    let a = &r.attribution;
    let min = 100.0 * diagnose::selection::MIN_EXPLAINED;
    for s in a.signatures.iter().filter(|s| !s.present()) {
        outln!(
            "{}: its signature is not in the withheld data (amplitude {}, z = {}; needs >= {} and >= {}): not named",
            s.name,
            sig(s.amplitude, 3),
            sig(s.z, 3),
            diagnose::attribution::SIGNATURE.0,
            diagnose::attribution::SIGNATURE.1
        )?;
    }
    if !a.not_named.is_empty() && r.effects.is_empty() {
        outln!(
            "kept but not named: {} (together they remove {:.0}% of the excess, less than {min:.0}%, or their signature is missing)",
            a.not_named.join(", "),
            100.0 * a.joint_explained,
        )?;
    }
    if a.from_joint_search && !r.effects.is_empty() {
        outln!("the greedy path stalled; the joint search of pairs and triples named the effects below")?;
    }
    Ok(())
}

/// What the named effects left of their kind, where the residual lies, and confounded effects.
fn print_leftovers(r: &Report) -> anyhow::Result<()> {
    let a = &r.attribution;
    let z = diagnose::structure::PARTIAL_Z;
    for l in a.leftovers.iter().filter(|l| l.partial) {
        outln!(
            "  {} is partial: structure of its kind is left (its wider family, {}: z = {}; the residual {}: z = {}; partial at z >= {z})",
            l.name,
            l.family,
            sig(l.z_family, 3),
            l.domain,
            sig(l.z_domain, 3)
        )?;
    }
    if r.unexplained_rms > 0.0 {
        let at: Vec<String> = a
            .residual_where
            .iter()
            .filter(|w| w.z_positions >= diagnose::NOISE_Z || w.z_in_dwell >= diagnose::NOISE_Z)
            .map(|w| {
                format!(
                    "{} (positions z = {}, in dwell z = {})",
                    w.channel,
                    sig(w.z_positions, 3),
                    sig(w.z_in_dwell, 3)
                )
            })
            .collect();
        if !at.is_empty() {
            outln!("  the unexplained residual lies on {}", at.join("; "))?;
        }
    }
    for c in &a.confounds {
        // What each alone does on the withheld positions, from the first round.
        let drops: Vec<String> = c
            .effects
            .iter()
            .filter_map(|n| a.rounds.first()?.trials.iter().find(|t| t.name == *n))
            .map(|t| format!("{} {}", t.name, sig(t.chi2_drop, 4)))
            .collect();
        outln!(
            "confounded: {} and {} (time and temperature correlate, r = {}; held-out chi2 drop alone: {}): on this campaign each can stand for the other, and only the shape of the temperature curve tells them apart; to separate them: {}",
            c.effects[0],
            c.effects[1],
            sig(c.r, 3),
            drops.join(", "),
            c.separate
        )?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use accelcal_core::campaign::Campaign;
    use accelcal_core::sim::{effects, simulate, SimConfig, TempProfile};
    use accelcal_shared::terms::MODEL_4;

    #[test]
    fn the_headline_never_says_consistent_with_the_noise_while_an_effect_is_named() {
        let (c, _) = simulate(&SimConfig { seed: 3, ..SimConfig::default() });
        let mut r = diagnose::diagnose(&c, 9.81, MODEL_4).unwrap();
        assert!(r.gap.consistent_with_noise && r.effects.is_empty());
        assert_eq!(headline(&r), "consistent with the noise");
        // The attribution may name an effect below the noise threshold (it passes its own
        // held-out test); the headline then says so.
        let (s, _) = simulate(&SimConfig {
            seed: 3,
            effects: vec![effects::parse("hysteresis=h:20").unwrap()],
            ..SimConfig::default()
        });
        r.effects = diagnose::diagnose(&s, 9.81, MODEL_4).unwrap().effects;
        let h = headline(&r);
        assert!(!h.contains("consistent with the noise") && h.ends_with("names hysteresis"), "{h}");
    }

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
