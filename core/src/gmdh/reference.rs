//! The reference criterion: each candidate fitted by QR on the weighted rows of its fitting part
//! and its residuals summed row by row on the scoring part. Slow and independent of the engine's
//! Gram matrices; the tests hold the engine to it.

use accelcal_shared::Structure;
use nalgebra::{DMatrix, DVector};

use super::{Criterion, Settings};
use crate::lsq::RANK_TOL;
use crate::positions::{ChannelStats, Positions};

/// Weighted LSQ coefficients of `s` on positions `idx` by QR (columns scaled to unit RMS), or
/// `None` when the scaled design's singular values fall below `RANK_TOL` of the largest.
fn fit(pos: &Positions, ch: &ChannelStats, s: Structure, idx: &[usize]) -> Option<Vec<f64>> {
    let terms: Vec<_> = s.terms().collect();
    let (n, k) = (idx.len(), terms.len());
    if n < k {
        return None;
    }
    let mut x = DMatrix::from_fn(n, k, |r, c| pos.weight[idx[r]].sqrt() * terms[c].eval(pos.x(idx[r])));
    let y = DVector::from_fn(n, |r, _| pos.weight[idx[r]].sqrt() * ch.mean[idx[r]]);
    let mut scale = vec![1.0; k];
    for c in 0..k {
        let norm = x.column(c).norm();
        scale[c] = if norm > 0.0 { norm } else { 1.0 };
        x.column_mut(c).scale_mut(1.0 / scale[c]);
    }
    let sv = x.clone().singular_values();
    if !(sv.min() > RANK_TOL * sv.max()) {
        return None;
    }
    let qr = x.qr();
    let qty = qr.q().transpose() * &y;
    let beta = qr.r().solve_upper_triangular(&qty)?;
    Some((0..k).map(|c| beta[c] / scale[c]).collect())
}

/// Weighted sum of squared dwell-mean residuals of `beta` on positions `idx`.
fn sse(pos: &Positions, ch: &ChannelStats, s: Structure, beta: &[f64], idx: &[usize]) -> f64 {
    idx.iter()
        .map(|&p| {
            let pred: f64 = s.terms().zip(beta).map(|(t, b)| b * t.eval(pos.x(p))).sum();
            pos.weight[p] * (ch.mean[p] - pred).powi(2)
        })
        .sum()
}

/// The criterion of structure `s`, or `None` when it is not identifiable where it is fitted.
pub fn criterion(pos: &Positions, ch: &ChannelStats, s: Structure, settings: &Settings) -> Option<f64> {
    let (a, b) = match settings.criterion {
        Criterion::Loo => (Vec::new(), Vec::new()),
        _ => settings.split.parts_of(pos).expect("split of the positions"),
    };
    let all: Vec<usize> = (0..pos.len()).collect();
    let rows = |idx: &[usize]| idx.iter().map(|&p| pos.weight[p]).sum::<f64>();
    match settings.criterion {
        Criterion::Regularity => {
            let beta = fit(pos, ch, s, &a)?;
            Some((sse(pos, ch, s, &beta, &b) / rows(&b)).sqrt())
        }
        Criterion::Symmetric => {
            let ba = fit(pos, ch, s, &a)?;
            let bb = fit(pos, ch, s, &b)?;
            Some(((sse(pos, ch, s, &ba, &b) + sse(pos, ch, s, &bb, &a)) / rows(&all)).sqrt())
        }
        Criterion::Rss => {
            let beta = fit(pos, ch, s, &all)?;
            Some((sse(pos, ch, s, &beta, &all) / rows(&all)).sqrt())
        }
        // Every position left out in turn and predicted by the fit on the others (no hat matrix).
        Criterion::Loo => {
            let mut press = 0.0;
            for p in 0..pos.len() {
                let others: Vec<usize> = all.iter().copied().filter(|&q| q != p).collect();
                press += sse(pos, ch, s, &fit(pos, ch, s, &others)?, &[p]);
            }
            Some((press / rows(&all)).sqrt())
        }
    }
}
