//! Selection of the effects that explain the gap, decided on withheld positions (the GMDH idea
//! applied to effects: an external criterion decides), by the scores of [`super::attribution`].
//!
//! **Greedy rounds.** Starting from the baseline, every remaining candidate is added in turn; the
//! one with the largest held-out χ² drop `D` among those passing both rules is kept:
//! (1) `D > max(25 + 5·√(2p), 0.05·χ²_before)`, p the parameters it adds (under the null
//! hypothesis, that the effect is absent, an added column raises the held-out χ² on average and
//! `D` has a spread of about `2√(2p)`, so the first term is more than five spreads; the second
//! asks for a practically relevant drop, as collinear columns widen the null spread); (2) `D` is
//! at least [`MIN_EXPLAINED`] (50%) of the remaining excess held-out χ² (held-out χ² minus its
//! noise expectation, the number of withheld bins), for `angle_error` the shape rule
//! [`MIN_ANGLE_SHAPE`] instead. Rounds go on until no candidate passes.
//!
//! **Joint search.** When the greedy path stalls (fewer than three effects kept and the full-data
//! residual still beyond the noise), sets of two and three effects are refitted jointly and scored
//! (greedy's blind spots: two effects whose sum a third mimics better than either alone, a drift
//! hidden behind angle errors, each effect holding less than half the excess on its own). Every
//! pair of available candidates is scored, and the four best pairs are extended by each other
//! candidate. A set qualifies when every member's marginal drop (the set against the set without
//! it) passes rule (1), `angle_error`'s marginal drop passes its shape rule on what the others
//! leave, and together they remove at least half the excess; the qualifying set with the lowest
//! held-out χ² replaces the greedy set when it scores lower.
//!
//! **Signature.** A kept effect must also show its own signature on the withheld positions
//! ([`Signature`]: its predicted contribution is found there with at least half its amplitude, at
//! z ≥ 5); one that does not is dropped, and the set is named only when together the effects
//! remove at least half the excess.

use std::collections::BTreeMap;

use accelcal_shared::Structure;
use serde::Serialize;

use super::attribution::{full_fit, heldout, heldout_signatures, Cand, Score, Signature};
use super::{zscore, Data, NOISE_Z};

/// One candidate's trial in one round of the greedy selection.
#[derive(Clone, Debug, Serialize)]
pub struct Trial {
    /// Effect name.
    pub name: &'static str,
    /// Held-out score with the effect added.
    pub score: Score,
    /// Drop of the held-out χ² it brings.
    pub chi2_drop: f64,
    /// Threshold of the drop: the larger of 25 + 5·√(2p) and 5% of the held-out χ² before.
    pub threshold: f64,
    /// Fraction of the remaining excess χ² it removes.
    pub explained: f64,
    /// The fraction its shape rule uses: `explained`, except for `angle_error` (see
    /// [`significant`]).
    pub shape_explained: f64,
}

/// One round of the greedy selection.
#[derive(Clone, Debug, Serialize)]
pub struct Round {
    /// Held-out score of the model so far.
    pub before: Score,
    /// Every candidate tried, best first.
    pub trials: Vec<Trial>,
    /// The effect kept, if any.
    pub kept: Option<&'static str>,
}

/// The least fraction of the remaining excess χ² an effect must remove on withheld positions to
/// be kept in a round, and that the kept effects together must remove to be named.
pub const MIN_EXPLAINED: f64 = 0.5;

/// The least fraction of the excess χ² that the per-position angle subspace must hold for
/// `angle_error` to be named. Its held-out prediction (each channel from the others) is limited
/// by geometry (on a triad at α = 0 a change of α moves ax only), so its shape is checked by
/// estimating the angles from all channels: two parameters per position in a space of three
/// channels hold about 2/3 of a residual without angle structure, all of one with it.
pub const MIN_ANGLE_SHAPE: f64 = 0.8;

/// Whether a trial may be kept in its round: a drop above the threshold that removes at least
/// [`MIN_EXPLAINED`] of the remaining excess (for `angle_error`: the shape rule).
pub fn significant(t: &Trial) -> bool {
    let min = if t.name == Cand::AngleError.name() { MIN_ANGLE_SHAPE } else { MIN_EXPLAINED };
    t.chi2_drop > t.threshold && t.shape_explained >= min
}

/// The outcome of the selection.
#[derive(Clone, Debug, Serialize)]
pub struct EffectSelection {
    /// The effects named, in the order kept (empty when they explain too little together).
    pub set: Vec<Cand>,
    /// Every greedy round.
    pub rounds: Vec<Round>,
    /// Fraction of the baseline's held-out excess χ² the kept effects remove together.
    pub joint_explained: f64,
    /// Effects kept but not named because together they explain less than [`MIN_EXPLAINED`] of
    /// the excess, or because their signature is missing from the withheld data.
    pub not_named: Vec<&'static str>,
    /// For each named effect: the held-out score before and after adding it.
    pub steps: Vec<(Score, Score)>,
    /// Whether the set came from the joint search of pairs and triples (the greedy path stalled).
    pub from_joint_search: bool,
    /// The held-out signature of every effect kept (named or dropped for its signature).
    pub signatures: Vec<Signature>,
}

/// The threshold of rule (1) for a drop from `before` that adds `p` parameters.
fn threshold(before: &Score, p: usize) -> f64 {
    (25.0 + 5.0 * (2.0 * p.max(1) as f64).sqrt()).max(0.05 * before.chi2)
}

/// Greedy rounds, then the joint search when they stall, then the signature check; the kept
/// effects are named when together they remove at least [`MIN_EXPLAINED`] of the baseline's
/// held-out excess χ².
pub fn select(d: &Data, base: Structure) -> EffectSelection {
    let mut set: Vec<Cand> = Vec::new();
    let mut rounds = Vec::new();
    let mut before = heldout(d, base, &set);
    loop {
        let remaining: Vec<Cand> =
            Cand::ALL.into_iter().filter(|c| !set.contains(c) && c.available(d)).collect();
        if remaining.is_empty() {
            break;
        }
        let excess = (before.chi2 - before.bins as f64).max(1e-9);
        let mut trials: Vec<(Cand, Trial)> = remaining
            .iter()
            .map(|&c| {
                let mut s = set.clone();
                s.push(c);
                let score = heldout(d, base, &s);
                let drop = before.chi2 - score.chi2;
                let shape_explained = if c == Cand::AngleError {
                    (before.chi2 - score.chi2_shape) / excess
                } else {
                    drop / excess
                };
                let t = Trial {
                    name: c.name(),
                    score,
                    chi2_drop: drop,
                    threshold: threshold(&before, score.params.saturating_sub(before.params)),
                    explained: drop / excess,
                    shape_explained,
                };
                (c, t)
            })
            .collect();
        trials.sort_by(|a, b| b.1.chi2_drop.total_cmp(&a.1.chi2_drop));
        let best = trials.iter().find(|(_, t)| significant(t)).map(|(c, t)| (*c, t.score));
        rounds.push(Round {
            before,
            trials: trials.iter().map(|(_, t)| t.clone()).collect(),
            kept: best.map(|b| b.0.name()),
        });
        match best {
            Some((c, score)) => {
                set.push(c);
                before = score;
            }
            None => break,
        }
    }
    let first = rounds.first().map_or(before, |r| r.before);
    let excess = (first.chi2 - first.bins as f64).max(1e-9);
    let mut steps: Vec<(Score, Score)> = Vec::new();
    for (i, r) in rounds.iter().enumerate().take(set.len()) {
        let after = rounds.get(i + 1).map_or(before, |n| n.before);
        steps.push((r.before, after));
    }
    let mut joint_explained = if set.is_empty() { 0.0 } else { (first.chi2 - before.chi2_shape) / excess };
    let mut from_joint_search = false;
    let stalled = set.len() < 3 && residual_z(d, base, &set) >= NOISE_Z;
    if stalled && !rounds.is_empty() {
        if let Some(pick) = best_subset(d, base, &rounds[0]) {
            if set.is_empty() || pick.score.chi2 < before.chi2 {
                (set, steps, joint_explained, from_joint_search) = (pick.set, pick.steps, pick.joint, true);
            }
        }
    }
    let mut not_named = Vec::new();
    let mut signatures = Vec::new();
    if !set.is_empty() {
        let (score, sigs) = heldout_signatures(d, base, &set);
        signatures = sigs;
        let missing: Vec<Cand> =
            set.iter().zip(&signatures).filter(|(_, s)| !s.present()).map(|(c, _)| *c).collect();
        if !missing.is_empty() {
            not_named.extend(missing.iter().map(|c| c.name()));
            let keep: Vec<usize> = (0..set.len()).filter(|&i| !missing.contains(&set[i])).collect();
            set = keep.iter().map(|&i| set[i]).collect();
            // The steps of the effects left, re-scored without the dropped ones.
            steps.clear();
            let mut prev = first;
            for k in 1..=set.len() {
                let s = heldout(d, base, &set[..k]);
                steps.push((prev, s));
                prev = s;
            }
            joint_explained = if set.is_empty() { 0.0 } else { (first.chi2 - prev.chi2_shape) / excess };
        } else {
            joint_explained = joint_explained.min((first.chi2 - score.chi2_shape) / excess);
        }
    }
    if joint_explained < MIN_EXPLAINED {
        not_named.extend(set.iter().map(|c| c.name()));
        set.clear();
        steps.clear();
    }
    EffectSelection { set, rounds, joint_explained, not_named, steps, from_joint_search, signatures }
}

/// z of the χ² of the full-data fit of the baseline and `set`.
fn residual_z(d: &Data, base: Structure, set: &[Cand]) -> f64 {
    full_fit(d, base, set).map_or(f64::INFINITY, |f| zscore(f.chi2, f.dof))
}

/// A set found by [`best_subset`].
struct Pick {
    set: Vec<Cand>,
    steps: Vec<(Score, Score)>,
    joint: f64,
    score: Score,
}

/// The joint search (see the module's documentation): every pair of available candidates, the
/// four best pairs extended by a third; the qualifying set with the lowest held-out χ², its
/// members ordered by single-effect drop, with its steps and the fraction of the excess removed.
fn best_subset(d: &Data, base: Structure, r1: &Round) -> Option<Pick> {
    let single = |c: Cand| r1.trials.iter().find(|t| t.name == c.name());
    let cands: Vec<Cand> = Cand::ALL.into_iter().filter(|&c| c.available(d) && single(c).is_some()).collect();
    let excess = (r1.before.chi2 - r1.before.bins as f64).max(1e-9);
    let mut scores: BTreeMap<Vec<Cand>, Score> = BTreeMap::new();
    scores.insert(Vec::new(), r1.before);
    for &c in &cands {
        scores.insert(vec![c], single(c)?.score);
    }
    let key = |mut v: Vec<Cand>| {
        v.sort();
        v
    };
    for (i, &a) in cands.iter().enumerate() {
        for &b in &cands[i + 1..] {
            scores.insert(key(vec![a, b]), heldout(d, base, &[a, b]));
        }
    }
    let mut pairs: Vec<(Vec<Cand>, f64)> =
        scores.iter().filter(|(k, _)| k.len() == 2).map(|(k, s)| (k.clone(), s.chi2)).collect();
    pairs.sort_by(|a, b| a.1.total_cmp(&b.1));
    for (pair, _) in pairs.iter().take(4) {
        for &c in cands.iter().filter(|c| !pair.contains(c)) {
            let t = key(vec![pair[0], pair[1], c]);
            if let std::collections::btree_map::Entry::Vacant(e) = scores.entry(t) {
                let s = heldout(d, base, e.key());
                e.insert(s);
            }
        }
    }
    let qualifies = |set: &[Cand], score: &Score| -> bool {
        if (r1.before.chi2 - score.chi2_shape) / excess < MIN_EXPLAINED {
            return false;
        }
        set.iter().all(|&m| {
            let rest: Vec<Cand> = set.iter().copied().filter(|&c| c != m).collect();
            let Some(without) = scores.get(&rest) else { return false };
            let drop = without.chi2 - score.chi2;
            let p = score.params.saturating_sub(without.params);
            let shape_ok = m != Cand::AngleError || {
                let left = (without.chi2 - without.bins as f64).max(1e-9);
                (without.chi2 - score.chi2_shape) / left >= MIN_ANGLE_SHAPE
            };
            drop > threshold(without, p) && shape_ok
        })
    };
    let (set, score) = scores
        .iter()
        .filter(|(k, s)| k.len() >= 2 && qualifies(k, s))
        .min_by(|a, b| a.1.chi2.total_cmp(&b.1.chi2))
        .map(|(k, s)| (k.clone(), *s))?;
    let mut ordered = set.clone();
    ordered.sort_by(|a, b| {
        single(*b)
            .map(|t| t.chi2_drop)
            .unwrap_or(0.0)
            .total_cmp(&single(*a).map(|t| t.chi2_drop).unwrap_or(0.0))
    });
    let mut steps = Vec::new();
    let mut prev = r1.before;
    for k in 1..=ordered.len() {
        let s = *scores.get(&key(ordered[..k].to_vec()))?;
        steps.push((prev, s));
        prev = s;
    }
    Some(Pick { set: ordered, steps, joint: (r1.before.chi2 - score.chi2_shape) / excess, score })
}
