//! Multilayer (iterative) GMDH for bases too large for exhaustive search.
//!
//! Layer 1 holds the intercept-only model. Each next layer grows every one of the `width` best
//! models of the previous layer by one basis term it lacks (duplicates merged), scores the new
//! models by the external criterion, and keeps its `width` best. The search stops when a layer's
//! best criterion does not improve on the best so far, or at `max_terms`. Every model scored on the
//! way is a candidate; selection then applies the same rule as the exhaustive search.

use std::collections::HashSet;

use accelcal_shared::Structure;
use rayon::prelude::*;

use super::{choose, engine, lsq, Candidate, GmdhError, Prepared, Selection, Settings};
use crate::positions::{ChannelStats, Positions};

/// Runs the multilayer search on one channel.
pub fn select(
    pos: &Positions,
    ch: &ChannelStats,
    settings: &Settings,
    width: usize,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<Selection, GmdhError> {
    let t0 = std::time::Instant::now();
    let prep = Prepared::new(pos, ch, settings)?;
    let score = |models: &[Structure]| -> Vec<Candidate> {
        let v: Vec<f64> = models
            .par_chunks(64)
            .flat_map_iter(|chunk| {
                let lists: Vec<Vec<usize>> = chunk.iter().map(|&s| prep.columns(s)).collect();
                engine::listed(&prep.problem, &lists)
            })
            .collect();
        progress(models.len() as u64);
        models
            .iter()
            .zip(v)
            .map(|(&structure, v)| Candidate { structure, criterion: (!v.is_nan()).then_some(v) })
            .collect()
    };
    let full = settings.basis.full();
    let mut candidates = score(&[Structure::INTERCEPT]);
    let mut layer: Vec<Candidate> = candidates.clone();
    let mut best = candidates[0].criterion.unwrap_or(f64::INFINITY);
    let mut seen: HashSet<Structure> = HashSet::from([Structure::INTERCEPT]);
    for _ in 1..settings.max_terms.min(full.len()) {
        let mut next = Vec::new();
        for parent in layer.iter().filter(|c| c.criterion.is_some()) {
            for bi in full.indices().filter(|&bi| !parent.structure.contains(bi)) {
                let child = Structure::from_mask(parent.structure.mask() | 1 << bi);
                if seen.insert(child) {
                    next.push(child);
                }
            }
        }
        if next.is_empty() {
            break;
        }
        let mut scored = score(&next);
        candidates.extend(scored.iter().cloned());
        scored.sort_by(|a, b| {
            a.criterion.unwrap_or(f64::INFINITY).total_cmp(&b.criterion.unwrap_or(f64::INFINITY))
        });
        scored.truncate(width);
        let layer_best = scored[0].criterion.unwrap_or(f64::INFINITY);
        layer = scored;
        if !(layer_best < best) {
            break;
        }
        best = layer_best;
    }
    let search_seconds = t0.elapsed().as_secs_f64();
    let (selected, best) = choose(&candidates, settings.tolerance).ok_or(GmdhError::NothingIdentifiable)?;
    super::guard::check(&prep, pos, ch, candidates[selected].structure)?;
    let fit = lsq::fit(pos, ch, candidates[selected].structure, None)?;
    Ok(Selection { channel: ch.name.clone(), candidates, selected, best, fit, search_seconds })
}
