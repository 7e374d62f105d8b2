//! `accelcal select`: combinatorial GMDH per channel.

use std::path::Path;

use accelcal_shared::terms::PAPER_MODELS;
use accelcal_shared::{Basis, Structure};
use anyhow::Context;
use indicatif::{ProgressBar, ProgressStyle};

use crate::settings::campaign::{Search, Select};
use accelcal_core::campaign::Campaign;
use accelcal_core::document::{CandidateDoc, SelectChannelDoc, SelectDoc, SelectedDoc};
use accelcal_core::error::bad;
use accelcal_core::gmdh::{self, Selection, Settings};
use accelcal_core::output::{finite, write_json};
use accelcal_core::positions::{ChannelStats, Positions};

fn names(s: Structure) -> Vec<String> {
    s.terms().map(|t| t.to_string()).collect()
}

/// Runs exhaustive GMDH on the chosen channels of a campaign, with a progress bar for large bases.
pub fn compute(
    c: &Campaign,
    g: f64,
    channels: &[String],
    settings: &Settings,
) -> anyhow::Result<Vec<Selection>> {
    let pos = Positions::new(c, g);
    compute_on(&pos, &pos.channel_stats(c), channels, settings)
}

/// [`compute`] from the dwell statistics (all that GMDH needs, so a streamed campaign will do).
pub fn compute_on(
    pos: &Positions,
    stats: &[ChannelStats],
    channels: &[String],
    settings: &Settings,
) -> anyhow::Result<Vec<Selection>> {
    run_channels(pos, stats, channels, settings.basis.candidate_count() as u64, |pos, s, progress| {
        gmdh::select(pos, s, settings, progress)
    })
}

/// Runs multilayer GMDH (`width` models per layer) on the chosen channels.
pub fn compute_multi_on(
    pos: &Positions,
    stats: &[ChannelStats],
    channels: &[String],
    settings: &Settings,
    width: usize,
) -> anyhow::Result<Vec<Selection>> {
    run_channels(pos, stats, channels, 0, |pos, s, progress| {
        gmdh::multi::select(pos, s, settings, width, progress)
    })
}

/// Applies `one` to each chosen channel; `per_channel` candidates drive the progress bar (0: a
/// spinner counting models).
fn run_channels(
    pos: &Positions,
    stats: &[ChannelStats],
    channels: &[String],
    per_channel: u64,
    one: impl Fn(&Positions, &ChannelStats, &(dyn Fn(u64) + Sync)) -> Result<Selection, gmdh::GmdhError>,
) -> anyhow::Result<Vec<Selection>> {
    for name in channels {
        if !stats.iter().any(|s| &s.name == name) {
            return Err(bad(format!(
                "no channel `{name}` in the campaign (it has: {})",
                stats.iter().map(|s| s.name.as_str()).collect::<Vec<_>>().join(",")
            )));
        }
    }
    let chosen: Vec<_> = stats.iter().filter(|s| channels.is_empty() || channels.contains(&s.name)).collect();
    let total = per_channel * chosen.len() as u64;
    let pb = if total > 50_000 {
        ProgressBar::new(total)
    } else if per_channel == 0 && std::io::IsTerminal::is_terminal(&std::io::stderr()) {
        ProgressBar::new_spinner()
    } else {
        ProgressBar::hidden()
    };
    pb.set_style(
        ProgressStyle::with_template(
            "{msg:8} [{bar:30}] {human_pos}/{human_len} models, {per_sec}, eta {eta}",
        )
        .expect("valid template")
        .progress_chars("=> "),
    );
    let mut out = Vec::new();
    for s in chosen {
        pb.set_message(s.name.clone());
        out.push(one(pos, s, &|n| pb.inc(n))?);
    }
    pb.finish_and_clear();
    Ok(out)
}

/// Keeps the `n` candidates with the smallest criterion (unidentifiable ones last, ties to the
/// lower index), sorted. One pass with a bounded max-heap, so a cubic sweep's half a million
/// candidates are neither sorted nor copied whole.
fn best_first(idx: &mut Vec<usize>, n: usize, crit: impl Fn(usize) -> Option<f64>) {
    #[derive(PartialEq)]
    struct Key(f64, usize);
    impl Eq for Key {}
    impl PartialOrd for Key {
        fn partial_cmp(&self, o: &Key) -> Option<std::cmp::Ordering> {
            Some(self.cmp(o))
        }
    }
    impl Ord for Key {
        fn cmp(&self, o: &Key) -> std::cmp::Ordering {
            self.0.total_cmp(&o.0).then(self.1.cmp(&o.1))
        }
    }
    let mut heap = std::collections::BinaryHeap::with_capacity(n.min(idx.len()) + 1);
    for &i in idx.iter() {
        let k = Key(crit(i).unwrap_or(f64::INFINITY), i);
        if heap.len() < n {
            heap.push(k);
        } else if heap.peek().is_some_and(|top| k < *top) {
            heap.pop();
            heap.push(k);
        }
    }
    *idx = heap.into_sorted_vec().into_iter().map(|k| k.1).collect();
}

/// Label of a candidate in tables: the paper's model number for the paper basis.
fn label(basis: Basis, s: Structure) -> String {
    match basis {
        Basis::Paper => {
            PAPER_MODELS.iter().position(|&m| m == s).map(|i| format!("{}", i + 1)).unwrap_or_default()
        }
        _ => String::new(),
    }
}

/// Prints Table 1 for each channel: every candidate for small bases, else the 15 best.
pub fn print_tables(sel: &[Selection], settings: &Settings) -> anyhow::Result<()> {
    for s in sel {
        outln!(
            "channel {}: {} criterion, RMS ADC codes of dwell means (best {:.2}, tolerance {} code{})",
            s.channel,
            settings.criterion.name(),
            s.best,
            settings.tolerance,
            if settings.tolerance == 1.0 { "" } else { "s" }
        )?;
        outln!("  {:>3}  {:<44} {:>12}  ", "#", "model terms", "criterion")?;
        let mut rows: Vec<usize> = (0..s.candidates.len()).collect();
        let many = rows.len() > 32;
        if many {
            best_first(&mut rows, 15, |i| s.candidates[i].criterion);
            if !rows.contains(&s.selected) {
                rows.push(s.selected);
            }
        }
        for i in rows {
            let c = &s.candidates[i];
            let crit = match c.criterion {
                Some(v) => format!("{v:12.2}"),
                None => format!("{:>12}", "unidentif."),
            };
            let mark = if i == s.selected { "  <- selected" } else { "" };
            outln!(
                "  {:>3}  {:<44} {crit}{mark}",
                label(settings.basis, c.structure),
                c.structure.to_string()
            )?;
        }
        if many {
            let unid = s.candidates.iter().filter(|c| c.criterion.is_none()).count();
            outln!(
                "  (15 best of {} candidates shown; {unid} not identifiable on this plan)",
                s.candidates.len()
            )?;
        }
        outln!()?;
    }
    Ok(())
}

/// Builds the JSON document.
pub fn to_json(sel: &[Selection], settings: &Settings, split: &str, top: Option<usize>) -> SelectDoc {
    let channels = sel
        .iter()
        .map(|s| {
            let n = s.candidates.len();
            let top = top.unwrap_or(if n > 4096 { 1000 } else { 0 });
            let mut idx: Vec<usize> = (0..n).collect();
            if top > 0 && top < n {
                best_first(&mut idx, top, |i| s.candidates[i].criterion);
            }
            SelectChannelDoc {
                channel: s.channel.clone(),
                selected: SelectedDoc {
                    terms: names(s.selected().structure),
                    coefficients: s.fit.coefficients.clone(),
                    criterion: s.selected().criterion.expect("selected is identifiable"),
                },
                best_criterion: s.best,
                candidates_total: n,
                search_seconds: s.search_seconds,
                models_per_second: n as f64 / s.search_seconds.max(1e-9),
                unidentifiable: s.candidates.iter().filter(|c| c.criterion.is_none()).count(),
                candidates: idx
                    .into_iter()
                    .map(|i| {
                        let c = &s.candidates[i];
                        CandidateDoc {
                            terms: names(c.structure),
                            criterion: c.criterion.and_then(finite),
                            identifiable: c.criterion.is_some(),
                        }
                    })
                    .collect(),
            }
        })
        .collect();
    SelectDoc {
        version: accelcal_core::document::SELECT_VERSION,
        basis: format!("{:?}", settings.basis).to_lowercase(),
        criterion: settings.criterion,
        split: (settings.criterion != gmdh::Criterion::Loo).then(|| split.to_string()),
        tolerance: settings.tolerance,
        channels,
    }
}

/// Writes one criterion-against-complexity plot per channel into `dir`.
pub fn plots(dir: &Path, sel: &[Selection], settings: &Settings) -> anyhow::Result<Vec<std::path::PathBuf>> {
    std::fs::create_dir_all(dir).map_err(|e| anyhow::anyhow!("creating {}: {e}", dir.display()))?;
    let mut written = Vec::new();
    for s in sel {
        let pts: Vec<(usize, f64)> =
            s.candidates.iter().filter_map(|c| c.criterion.map(|v| (c.structure.len(), v))).collect();
        let path = dir.join(format!("criterion-{}.svg", s.channel));
        let sc = s.selected();
        crate::report::plot::criterion_vs_complexity(
            &path,
            &format!("channel {}: {} criterion against complexity", s.channel, settings.criterion.name()),
            &pts,
            (sc.structure.len(), sc.criterion.expect("selected is identifiable")),
            s.best + settings.tolerance,
        )?;
        written.push(path);
    }
    Ok(written)
}

/// Runs `accelcal select`.
pub fn run(a: &Select, g: &super::Gravity, warnings: &mut super::Warnings) -> anyhow::Result<()> {
    // Streamed: GMDH needs the dwell statistics only.
    let r = super::reduce_campaign(&a.campaign.path, a.campaign.codes, warnings)?;
    let (mut pos, stats) = (r.positions(g.g), r.channel_stats());
    pos.t_ref_c = a.t_ref_c;
    let settings = &a.settings;
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(a.threads.unwrap_or(0))
        .build()
        .map_err(|e| anyhow::anyhow!("starting worker threads: {e}"))?;
    let sel = pool
        .install(|| match a.search {
            Search::Combi => compute_on(&pos, &stats, &a.channels, settings),
            Search::Multi { width } => compute_multi_on(&pos, &stats, &a.channels, settings, width),
        })
        .with_context(|| a.campaign.path.display().to_string())?;
    print_tables(&sel, settings)?;
    if let Some(j) = &a.campaign.json {
        write_json(j, &to_json(&sel, settings, &settings.split.to_string(), a.top))?;
    }
    if let Some(dir) = &a.plot {
        for p in plots(dir, &sel, settings)? {
            outln!("plot: {}", p.display())?;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::best_first;

    /// The heap keeps exactly what a full sort would put first, ties and unidentifiable included.
    #[test]
    fn best_first_equals_the_head_of_a_full_sort() {
        let crit: Vec<Option<f64>> =
            (0..500u64).map(|i| (i % 7 != 3).then(|| ((i * 7919) % 97) as f64 / 4.0)).collect();
        let key = |i: usize| (crit[i].unwrap_or(f64::INFINITY), i);
        let mut sorted: Vec<usize> = (0..crit.len()).collect();
        sorted.sort_by(|&a, &b| key(a).partial_cmp(&key(b)).unwrap());
        for n in [0, 1, 15, 100, 499, 500, 800] {
            let mut idx: Vec<usize> = (0..crit.len()).collect();
            best_first(&mut idx, n, |i| crit[i]);
            assert_eq!(idx, sorted[..n.min(crit.len())], "n = {n}");
        }
    }
}
