//! The guard on a selection: a model that lacks an axis term only because the criterion cannot
//! identify the models with it is not a selection, and neither is one without the channel's own
//! axis.
//!
//! A criterion ranks only the candidates it can identify where it fits them. When a split leaves
//! its fitting part too few positions (the six test-turn positions split alternately: three to
//! fit on, four terms in model 4), every candidate with all three axes is unidentifiable there and
//! the rule picks among models that each lack an axis, the worst kind, with a criterion of
//! hundreds or thousands of codes. [`check`] refuses such a selection: for each axis term the
//! selection lacks (the channel's own axis first), if all the positions identify the selection with
//! that term and the criterion cannot, it names the part, its positions and the positions needed.
//! It also refuses a selection without the channel's own axis: the channel named `x`, `y` or `z`
//! is along `ax`, `ay` or `az` (the record's and `verify`'s convention), another channel along the
//! axis of its largest sensitivity in model 4 fitted on all positions (`compare::own_axis`; not
//! known when the plan cannot identify model 4).

use accelcal_shared::terms::MODEL_4;
use accelcal_shared::{Structure, BASIS};

use super::{engine, Criterion, GmdhError, Prepared, Split};
use crate::lsq;
use crate::positions::{ChannelStats, Positions};

/// Basis indices of `ax`, `ay`, `az`.
const AXES: [usize; 3] = [1, 2, 3];

/// The channel's own axis (0, 1, 2 for x, y, z) and how it is known, when it is.
pub fn own_axis(pos: &Positions, ch: &ChannelStats) -> Option<(usize, &'static str)> {
    match ch.name.to_ascii_lowercase().as_str() {
        "x" => Some((0, "by the channel's name")),
        "y" => Some((1, "by the channel's name")),
        "z" => Some((2, "by the channel's name")),
        _ => lsq::fit(pos, ch, MODEL_4, None)
            .ok()
            .map(|f| (crate::compare::own_axis(&f), "its largest sensitivity in model 4")),
    }
}

/// Refuses `selected` (the selection of channel `ch` by `prep`) when it drops an axis term only
/// because the criterion cannot identify the model with it, or drops the channel's own axis.
pub fn check(
    prep: &Prepared,
    pos: &Positions,
    ch: &ChannelStats,
    selected: Structure,
) -> Result<(), GmdhError> {
    let own = own_axis(pos, ch);
    let p = &prep.problem;
    // The axes the selection lacks, the own axis first; then every set of them, smallest first.
    let mut missing: Vec<usize> = own.iter().map(|o| o.0).collect();
    missing.extend((0..3).filter(|&a| own.is_none_or(|o| o.0 != a)));
    missing.retain(|&a| !selected.contains(AXES[a]));
    let mut sets: Vec<u32> = (1..1u32 << missing.len()).collect();
    sets.sort_by_key(|&x| (x.count_ones(), x));
    for x in sets {
        let added: Vec<usize> = (0..missing.len()).filter(|i| x & 1 << i != 0).map(|i| missing[i]).collect();
        let with = Structure::from_mask(added.iter().fold(selected.mask(), |m, &a| m | 1 << AXES[a]));
        let cols = prep.columns(with);
        if engine::identifiable(&p.ab, p.m, &cols) && engine::listed(p, &[cols])[0].is_nan() {
            let is_own = own.is_some_and(|o| o.0 == added[0]);
            return Err(blind(prep, ch, selected, with, &added, is_own));
        }
    }
    let Some((a, how)) = own.filter(|o| !selected.contains(AXES[o.0])) else { return Ok(()) };
    let term = BASIS[AXES[a]].to_string();
    let with = Structure::from_mask(selected.mask() | 1 << AXES[a]);
    if !engine::identifiable(&p.ab, p.m, &prep.columns(Structure::from_indices(&[AXES[a]]))) {
        return Err(GmdhError::OwnAxisConstant { channel: ch.name.clone(), term, how });
    }
    let score = |s: Structure| engine::listed(p, &[prep.columns(s)])[0];
    Err(GmdhError::OwnAxisDropped {
        channel: ch.name.clone(),
        selected,
        term,
        how,
        criterion: format!("{:.2}", score(with)),
        best: format!("{:.2}", score(selected)),
    })
}

/// The refusal of a selection that lacks the axes `added` (the own axis first, when `own`)
/// because the criterion cannot identify `with`, the selection with them.
fn blind(
    prep: &Prepared,
    ch: &ChannelStats,
    selected: Structure,
    with: Structure,
    added: &[usize],
    own: bool,
) -> GmdhError {
    let settings = &prep.settings;
    let (k, n) = (with.len(), prep.problem.rows.w.len());
    let mut split = None;
    let why = match settings.criterion {
        Criterion::Loo => format!(
            "leaving one of the {n} positions out leaves too few (or too alike) to identify {with} \
             ({k} terms: at least {} positions, none of them needed to identify it)",
            k + 1
        ),
        criterion => {
            let a_fails = !engine::identifiable(&prep.problem.a, prep.problem.m, &prep.columns(with));
            let (part, have) = if a_fails { ('A', prep.parts[0]) } else { ('B', prep.parts[1]) };
            let both = criterion == Criterion::Symmetric;
            split = Some(settings.split.to_string());
            let lead = format!("leaves part {part} {have} of the {n} positions");
            if have < k {
                let campaign = min_positions(settings.split, k, both)
                    .map(|t| format!(", a campaign of at least {t} with this split"))
                    .unwrap_or_default();
                let place = if both { "each part" } else { "A" };
                format!("{lead}, too few to identify {with} ({k} terms: at least {k} positions in {place}{campaign})")
            } else {
                format!("{lead}, which do not identify {with} although all {n} positions do")
            }
        }
    };
    let loo_min = (settings.criterion != Criterion::Loo).then_some(k + 1);
    GmdhError::Blind { channel: ch.name.clone(), split, why, selected, dropped: dropped(added, own), loo_min }
}

/// "its own axis term `ax`", "the axis terms `ax`, `ay`", …
fn dropped(added: &[usize], own: bool) -> String {
    let names: Vec<String> = added.iter().map(|&a| format!("`{}`", BASIS[AXES[a]])).collect();
    match (own, names.len()) {
        (true, 1) => format!("its own axis term {}", names[0]),
        (true, _) => format!("its own axis term {} and {}", names[0], names[1..].join(", ")),
        (false, 1) => format!("the axis term {}", names[0]),
        (false, _) => format!("the axis terms {}", names.join(", ")),
    }
}

/// The smallest campaign for which `split` puts at least `k` positions in A (and in B when
/// `both`); `None` for a split by temperature, which depends on the dwells' temperatures.
fn min_positions(split: Split, k: usize, both: bool) -> Option<usize> {
    if matches!(split, Split::Temp { .. }) {
        return None;
    }
    (2..=64 * k.max(1)).find(|&n| {
        let (a, b) = split.parts(n);
        a.len() >= k && (!both || b.len() >= k)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn positions_needed_follow_the_split() {
        assert_eq!(min_positions(Split::Alternate, 4, false), Some(7));
        assert_eq!(min_positions(Split::Alternate, 4, true), Some(8));
        assert_eq!(min_positions(Split::Halves, 4, false), Some(7));
        assert_eq!(min_positions(Split::Tail(0.25), 4, false), Some(5));
        assert_eq!(min_positions(Split::Temp { at: [0.0; 4], n: 1 }, 4, false), None);
    }
}
