//! `accelcal bench-diagnose`: the blind benchmark of the diagnosis (confusion table, accuracy,
//! held-out shrink against an oracle that knows the effect).

use indicatif::{ProgressBar, ProgressStyle};

use crate::settings::campaign::BenchDiagnose;
use accelcal_core::diagnose::bench::{self, CaseKind, Summary, Tally};
use accelcal_core::output::write_json;

/// Runs `accelcal bench-diagnose`.
pub fn run(a: &BenchDiagnose) -> anyhow::Result<()> {
    let pb = ProgressBar::new(a.campaigns as u64);
    pb.set_style(
        ProgressStyle::with_template("{bar:40} {pos}/{len} campaigns, {elapsed} elapsed, eta {eta}")
            .expect("valid template"),
    );
    let range = a.magnitude;
    let s = bench::run(a.campaigns, a.seed, range, &|| pb.inc(1));
    pb.finish_and_clear();
    print_summary(&s, a.seed, range)?;
    if let Some(j) = &a.json {
        write_json(j, &s)?;
    }
    Ok(())
}

/// Prints the table per case kind, the detail rows per true effect set, and the aims.
pub fn print_summary(s: &Summary, seed: u64, range: (f64, f64)) -> anyhow::Result<()> {
    outln!(
        "blind benchmark: {} campaigns, master seed {seed}, magnitudes {}..{} x per-position noise (each effect its own)",
        s.campaigns, range.0, range.1
    )?;
    let pct = |n: usize, t: &Tally| format!("{:.1}%", 100.0 * n as f64 / t.campaigns.max(1) as f64);
    let oracle = |t: &Tally| t.vs_oracle().map_or("-".to_string(), |v| format!("{v:.3}"));
    outln!(
        "{:<16} {:>9} {:>6} {:>7} {:>6} {:>7} {:>6} {:>7} {:>9}",
        "kind",
        "campaigns",
        "right",
        "%",
        "wrong",
        "%",
        "missed",
        "%",
        "shrink/or"
    )?;
    // The kinds in the order of their declaration: clean, one, two, three, outside.
    for (k, t) in &s.kinds {
        outln!(
            "{:<16} {:>9} {:>6} {:>7} {:>6} {:>7} {:>6} {:>7} {:>9}",
            k.name(),
            t.campaigns,
            t.right,
            pct(t.right, t),
            t.wrong,
            pct(t.wrong, t),
            t.missed,
            pct(t.missed, t),
            oracle(t)
        )?;
    }
    outln!()?;
    outln!("per true effect set (right/wrong/missed; what was reported when not right, ~ = partial):")?;
    for k in s.kinds.keys() {
        for (truth, (kind, t)) in s.truths.iter().filter(|(_, (kind, _))| kind == k) {
            let others: Vec<String> = s.confusion[truth]
                .iter()
                .filter(|(rep, _)| t.right < t.campaigns && rep.as_str() != truth.as_str())
                .map(|(rep, n)| format!("{n}x {}", abbrev(rep)))
                .collect();
            let row = format!(
                "  {:<15} {:<24} {:>10}  {}",
                kind.name(),
                abbrev(truth),
                format!("{}/{}/{}", t.right, t.wrong, t.missed),
                others.join(", ")
            );
            outln!("{}", row.trim_end())?;
        }
    }
    outln!()?;
    let get = |k: CaseKind| s.kinds.get(&k).cloned().unwrap_or_default();
    let aim = |ok: bool| if ok { "met" } else { "NOT met" };
    let (one, two, clean, out) =
        (get(CaseKind::Single), get(CaseKind::Pair), get(CaseKind::Clean), get(CaseKind::Outside));
    outln!("aims:")?;
    outln!(
        "  one effect right >= 95%: {:.1}% ({})",
        100.0 * one.right_share(),
        aim(one.right_share() >= 0.95)
    )?;
    outln!(
        "  two effects, both named and nothing else >= 90%: {:.1}% ({})",
        100.0 * two.right_share(),
        aim(two.right_share() >= 0.90)
    )?;
    outln!(
        "  no effect named on clean campaigns: {}/{} with a name ({})",
        clean.wrong,
        clean.campaigns,
        aim(clean.wrong == 0)
    )?;
    let over = s.outside_overclaimed as f64 / out.campaigns.max(1) as f64;
    outln!(
        "  outside the library, a library name claiming more than half of the held-out gap <= 10%: {}/{} = {:.1}% ({})",
        s.outside_overclaimed,
        out.campaigns,
        100.0 * over,
        aim(over <= 0.10)
    )?;
    outln!(
        "  held-out shrink within 10% of the oracle's (>= 0.900): {:.3} ({})",
        s.shrink_vs_oracle,
        aim(s.shrink_vs_oracle >= 0.9)
    )?;
    Ok(())
}

fn abbrev(name: &str) -> String {
    name.split('+')
        .map(|n| match n.strip_prefix('~') {
            Some(p) => format!("~{}", accelcal_core::effects::short_name(p)),
            None => accelcal_core::effects::short_name(n).to_string(),
        })
        .collect::<Vec<_>>()
        .join("+")
}
