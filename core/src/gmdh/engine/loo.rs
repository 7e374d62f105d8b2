//! The leave-one-out kernel of the engine: PRESS from the hat matrix.
//!
//! With every position's weight `w_p` (its rows), the weighted fit on all positions has residuals
//! `e_p` and leverages `h_p = w_p x_pᵀ (XᵀWX)⁻¹ x_p`; the residual at `p` of the fit on all the
//! other positions is `e_p / (1 − h_p)`, and the criterion is `sqrt(Σ w_p (e_p/(1 − h_p))² / Σ w_p)`,
//! in codes like the other criteria. A node keeps, for each state index still to come and for the
//! response, its residual *vector* over the positions (the column with the node's columns
//! projected out, in the weighted inner product) and the leverages. Adding column `s` with
//! residual `r_s` and `D = Σ w r_s²`:
//!
//! ```text
//! h_p' = h_p + w_p r_s,p² / D        r_u' = r_u − (Σ w r_s r_u / D) r_s
//! ```
//!
//! so a child costs O(n) per state index it updates (n positions) instead of the O(1) of the Gram
//! kernels. The pivot test is theirs (`D` at or below [`PIVOT_TOL`] of the column's diagonal); a
//! leverage within [`PIVOT_TOL`] of 1 means that leaving that position out leaves the model rank
//! deficient: the candidate is not identifiable, and neither is any superset (leverages only grow
//! as columns are added), so the subtree is pruned like a rank-deficient one.

use super::{Kernel, Layout, Problem, Setup, PIVOT_TOL};

/// The leave-one-out criterion.
pub(super) struct Loo;

/// Residual vectors of the state indices (state-major, `n` positions each) and the leverages.
pub(super) struct LooNode {
    r: Vec<f64>,
    h: Vec<f64>,
}

impl Clone for LooNode {
    fn clone(&self) -> LooNode {
        LooNode { r: self.r.clone(), h: self.h.clone() }
    }
    /// Reuses the allocation (the walkers reset their root once per task or subset).
    fn clone_from(&mut self, o: &LooNode) {
        self.r.clone_from(&o.r);
        self.h.clone_from(&o.h);
    }
}

/// `Σ w a b`.
#[inline(always)]
fn dot(w: &[f64], a: &[f64], b: &[f64]) -> f64 {
    w.iter().zip(a).zip(b).map(|((w, a), b)| w * a * b).sum()
}

impl Kernel for Loo {
    type Node = LooNode;

    fn root(p: &Problem, layout: &Layout) -> LooNode {
        let rows = &p.rows;
        let n = rows.w.len();
        let mut r = vec![0.0; layout.n * n];
        for (u, col) in layout.col.iter().enumerate().take(layout.n) {
            for (i, v) in r[u * n..(u + 1) * n].iter_mut().enumerate() {
                *v = match col {
                    Some(c) => rows.z[i * p.m + c],
                    None => rows.y[i],
                };
            }
        }
        LooNode { r, h: vec![0.0; n] }
    }

    /// False when the column is dependent or some leverage reaches 1; the child is then left
    /// partly written, and the walkers do not use it.
    #[inline(always)]
    fn extend<const FULL: bool>(
        p: &Setup,
        par: &LooNode,
        ch: &mut LooNode,
        s: usize,
        lo: usize,
        hi: usize,
    ) -> bool {
        let w = &p.w;
        let n = w.len();
        let rs = &par.r[s * n..(s + 1) * n];
        let d = dot(w, rs, rs);
        if !(d > PIVOT_TOL * p.diag[0][s]) {
            return false;
        }
        let inv = 1.0 / d;
        for i in 0..n {
            let h = par.h[i] + w[i] * rs[i] * rs[i] * inv;
            if !(1.0 - h > PIVOT_TOL) {
                return false;
            }
            ch.h[i] = h;
        }
        for u in lo..=hi {
            let ru = &par.r[u * n..(u + 1) * n];
            let c = dot(w, rs, ru) * inv;
            for ((o, a), b) in ch.r[u * n..(u + 1) * n].iter_mut().zip(ru).zip(rs) {
                *o = a - c * b;
            }
        }
        true
    }

    #[inline(always)]
    fn score(p: &Setup, node: &LooNode, y: usize) -> f64 {
        let n = p.w.len();
        let e = &node.r[y * n..(y + 1) * n];
        let press: f64 = p.w.iter().zip(e).zip(&node.h).map(|((w, e), h)| w * (e / (1.0 - h)).powi(2)).sum();
        (press / p.rows[2]).sqrt()
    }
}
