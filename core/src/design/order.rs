//! The order of a designed plan: short moves, and GMDH's selection kept meaningful.
//!
//! A move costs the larger of the two stages' angles (they turn together); at β = ±90° the α
//! stage need not turn, so such a position takes the α of the one before it. The order is the
//! nearest neighbour's from α = β = 0, improved by 2-opt.
//!
//! GMDH ranks the paper's models that the plan identifies; on a head plan (every orientation at
//! 1 g) the largest of them is model 10 (`1, ax, ay, az, ax², ay², ax·ay`, 7 terms), and every
//! other identifiable one is inside it. So a plan keeps selection meaningful when its criterion
//! identifies model 10 where it fits: with the default alternate split, in both parts (the even
//! and the odd positions of the order), which the order is chosen to give — of its rotations and
//! reversals, the shortest that does; otherwise, by leave-one-out, with every position left out
//! in turn. [`Selection`] says which the plan needs.

use accelcal_shared::terms::PAPER_MODELS;
use serde::Serialize;

use super::DesignError;
use crate::gmdh::engine::{identifiable, Stats};
use crate::gmdh::Split;

/// How GMDH's criterion can rank the paper's models on a plan.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Selection {
    /// The regularity criterion with the alternate split (the default): both parts identify
    /// model 10.
    Alternate,
    /// Only leave-one-out: every position left out in turn leaves model 10 identified.
    LeaveOneOut,
}

/// The move between two positions, degrees: the larger of the stages' angles; a pole (β = ±90°)
/// needs no α move.
fn step((a1, b1): (f64, f64), (a2, b2): (f64, f64)) -> f64 {
    let pole = |b: f64| (b.abs() - 90.0).abs() < 1e-9;
    let da = if pole(b1) || pole(b2) {
        0.0
    } else {
        let d = (a1 - a2).rem_euclid(360.0);
        d.min(360.0 - d)
    };
    da.max((b1 - b2).abs())
}

/// The travel of a path from α = β = 0, degrees.
pub fn travel(path: &[(f64, f64)]) -> f64 {
    let mut at = (0.0, 0.0);
    let mut sum = 0.0;
    for &p in path {
        sum += step(at, p);
        at = p;
    }
    sum
}

/// The nearest neighbour's path from α = β = 0, then 2-opt.
fn short_path(mut left: Vec<(f64, f64)>) -> Vec<(f64, f64)> {
    let mut path = Vec::with_capacity(left.len());
    let mut at = (0.0, 0.0);
    while !left.is_empty() {
        let (i, _) = left
            .iter()
            .enumerate()
            .min_by(|x, y| step(at, *x.1).total_cmp(&step(at, *y.1)))
            .expect("not empty");
        at = left.swap_remove(i);
        path.push(at);
    }
    let n = path.len();
    let prev = |p: &[(f64, f64)], i: usize| if i == 0 { (0.0, 0.0) } else { p[i - 1] };
    for _pass in 0..50 {
        let mut better = false;
        for i in 0..n {
            for j in i + 1..n {
                // Reversing i..=j replaces the moves (i−1 → i) and (j → j+1).
                let before =
                    step(prev(&path, i), path[i]) + if j + 1 < n { step(path[j], path[j + 1]) } else { 0.0 };
                let after =
                    step(prev(&path, i), path[j]) + if j + 1 < n { step(path[i], path[j + 1]) } else { 0.0 };
                if after < before - 1e-9 {
                    path[i..=j].reverse();
                    better = true;
                }
            }
        }
        if !better {
            break;
        }
    }
    path
}

/// Whether the positions `idx` of `path` identify model 10, by the GMDH engine's own test.
fn identifies(path: &[(f64, f64)], idx: &[usize], g: f64) -> bool {
    let cols: Vec<usize> = PAPER_MODELS[9].indices().collect();
    let m = cols.len();
    let z: Vec<f64> = path
        .iter()
        .flat_map(|&(a, b)| {
            let acc = accelcal_shared::gravity(a, b, g).map(|v| v / g);
            cols.iter()
                .map(move |&t| accelcal_shared::BASIS[t].eval([acc[0], acc[1], acc[2], 0.0]))
                .collect::<Vec<_>>()
        })
        .collect();
    let zeros = vec![0.0; path.len()];
    let ones = vec![1.0; path.len()];
    let st = Stats::new(&z, m, &zeros, &ones, idx);
    identifiable(&st, m, &(0..m).collect::<Vec<_>>())
}

/// Whether the alternate split's both parts of `path` identify model 10.
fn split_identifies(path: &[(f64, f64)], g: f64) -> bool {
    let (a, b) = Split::Alternate.parts(path.len());
    identifies(path, &a, g) && identifies(path, &b, g)
}

/// Whether leaving out any one position of `path` leaves model 10 identified.
fn loo_identifies(path: &[(f64, f64)], g: f64) -> bool {
    let n = path.len();
    (0..n).all(|out| identifies(path, &(0..n).filter(|&i| i != out).collect::<Vec<_>>(), g))
}

/// A pole position takes the α of the position before it (no α move; the same orientation).
fn settle_poles(path: &mut [(f64, f64)]) {
    let mut alpha = 0.0;
    for p in path.iter_mut() {
        if (p.1.abs() - 90.0).abs() < 1e-9 {
            p.0 = alpha;
        }
        alpha = p.0;
    }
}

/// A plan in the head's order, how GMDH's selection can rank on it, and its travel (degrees).
pub type Arranged = (Vec<(f64, f64)>, Selection, f64);

/// Orders the positions of a design for short moves, keeping GMDH's selection meaningful.
pub fn arrange(positions: Vec<(f64, f64)>, g: f64) -> Result<Arranged, DesignError> {
    let n = positions.len();
    let path = short_path(positions);
    let mut best: Option<(Vec<(f64, f64)>, f64)> = None;
    for rev in [false, true] {
        for shift in 0..n {
            let mut p = path.clone();
            if rev {
                p.reverse();
            }
            p.rotate_left(shift);
            let t = travel(&p);
            if best.as_ref().is_none_or(|b| t < b.1) && split_identifies(&p, g) {
                best = Some((p, t));
            }
        }
    }
    let (mut path, selection) = match best {
        Some((p, _)) => (p, Selection::Alternate),
        None if loo_identifies(&path, g) => (path, Selection::LeaveOneOut),
        None => return Err(DesignError::Blind { n }),
    };
    settle_poles(&mut path);
    let t = travel(&path);
    Ok((path, selection, t))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_pole_needs_no_alpha_move_and_alpha_goes_the_short_way() {
        assert_eq!(step((350.0, 0.0), (10.0, 0.0)), 20.0);
        assert_eq!(step((120.0, 60.0), (0.0, 90.0)), 30.0);
        assert_eq!(step((0.0, 0.0), (90.0, 30.0)), 90.0);
    }

    #[test]
    fn the_paper_plan_is_identified_by_both_parts_and_six_positions_are_not() {
        let g = accelcal_shared::G_STANDARD;
        assert!(split_identifies(&crate::sim::Plan::head().positions, g));
        assert!(!split_identifies(&crate::sim::Plan::six().positions, g));
        assert!(!loo_identifies(&crate::sim::Plan::six().positions, g));
    }

    #[test]
    fn the_order_is_shorter_than_the_given_one_and_keeps_the_positions() {
        let g = accelcal_shared::G_STANDARD;
        let given = crate::sim::Plan::random(30, 4).positions;
        let (path, sel, t) = arrange(given.clone(), g).unwrap();
        assert_eq!(sel, Selection::Alternate);
        assert!(t < travel(&given), "{t} vs {}", travel(&given));
        let key = |p: &(f64, f64)| ((p.0 * 100.0).round() as i64, (p.1 * 100.0).round() as i64);
        let mut a: Vec<_> = given.iter().map(key).collect();
        let mut b: Vec<_> = path.iter().map(key).collect();
        a.sort();
        b.sort();
        assert_eq!(a, b);
    }
}
