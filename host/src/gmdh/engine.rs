//! The exhaustive GMDH engine: every subset of a basis scored from sufficient statistics.
//!
//! Cost per candidate does not depend on the number of samples. The weighted Gram matrix,
//! moment vector and `yᵀy` of each part are formed once over the scaled regressors. Candidates
//! are visited depth first, each child adding one column with an index above its parent's; the
//! child's Cholesky factor is the parent's with one more row, computed in O(k²), as is the
//! forward-substituted moment vector. A pivot at or below [`PIVOT_TOL`] of its diagonal marks the
//! column as (numerically) dependent on the ones before it: that candidate and its whole subtree
//! are rank deficient and are recorded as such without being visited.
//!
//! Work is split into tasks that each fix which of the highest-index terms are present; the
//! candidates of one task form a contiguous block of the result vector, so tasks write without
//! locks. Nothing is allocated per candidate.

use accelcal_shared::N_BASIS;

/// Relative Cholesky pivot (the squared sine of the angle between a regressor and the span of the
/// ones before it, regressors scaled to unit RMS) at or below which a candidate counts as rank
/// deficient.
pub const PIVOT_TOL: f64 = 1e-10;

/// Marker in the result vector: the candidate was not scored (beyond `max_terms`).
pub const EXCLUDED: f64 = -1.0;

/// Which criterion the engine computes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    /// Error on B of the fit on A.
    Regularity,
    /// Error on B of the A-fit plus error on A of the B-fit.
    Symmetric,
    /// Error on A∪B of the fit on A∪B.
    Rss,
}

/// Sufficient statistics of one part over `m` scaled columns.
#[derive(Clone, Debug)]
pub struct Stats {
    /// Gram matrix, row-major `m × m`.
    pub gram: Vec<f64>,
    /// Moment vector `Σ w z y`.
    pub moment: Vec<f64>,
    /// `Σ w y²`.
    pub yy: f64,
    /// `Σ w` (rows).
    pub rows: f64,
}

impl Stats {
    /// Accumulates the statistics of rows `z` (row-major, `m` wide) with responses `y` and weights
    /// `w`, over the row indices `idx`.
    pub fn new(z: &[f64], m: usize, y: &[f64], w: &[f64], idx: &[usize]) -> Stats {
        let mut s = Stats { gram: vec![0.0; m * m], moment: vec![0.0; m], yy: 0.0, rows: 0.0 };
        for &p in idx {
            let zp = &z[p * m..(p + 1) * m];
            let wp = w[p];
            for i in 0..m {
                let wz = wp * zp[i];
                s.moment[i] += wz * y[p];
                for j in 0..=i {
                    s.gram[i * m + j] += wz * zp[j];
                }
            }
            s.yy += wp * y[p] * y[p];
            s.rows += wp;
        }
        for i in 0..m {
            for j in 0..i {
                s.gram[j * m + i] = s.gram[i * m + j];
            }
        }
        s
    }
}

/// The statistics a run needs.
pub struct Problem {
    /// Number of columns (column 0 is the intercept).
    pub m: usize,
    /// Part A, part B, and A∪B.
    pub a: Stats,
    /// Part B.
    pub b: Stats,
    /// A∪B.
    pub ab: Stats,
    /// Criterion.
    pub kind: Kind,
}

/// A Cholesky factor over a growing list of columns, with the forward-substituted moments.
struct Factor {
    l: [f64; N_BASIS * N_BASIS],
    z: [f64; N_BASIS],
}

impl Factor {
    fn new() -> Factor {
        Factor { l: [0.0; N_BASIS * N_BASIS], z: [0.0; N_BASIS] }
    }

    /// Adds column `j` as row `k` after columns `sel[..k]`. False when the pivot is too small.
    #[inline]
    fn extend(&mut self, st: &Stats, m: usize, sel: &[usize], k: usize, j: usize) -> bool {
        let g = &st.gram[j * m..(j + 1) * m];
        let row = k * N_BASIS;
        let mut ss = 0.0;
        let mut zs = 0.0;
        for q in 0..k {
            let rq = q * N_BASIS;
            let mut s = g[sel[q]];
            for r in 0..q {
                s -= self.l[row + r] * self.l[rq + r];
            }
            let v = s / self.l[rq + q];
            self.l[row + q] = v;
            ss += v * v;
            zs += v * self.z[q];
        }
        let d = g[j] - ss;
        if !(d > PIVOT_TOL * g[j]) {
            return false;
        }
        let lkk = d.sqrt();
        self.l[row + k] = lkk;
        self.z[k] = (st.moment[j] - zs) / lkk;
        true
    }

    /// Coefficients of the first `k` columns: `β = L⁻ᵀ z`.
    #[inline]
    fn beta(&self, k: usize, beta: &mut [f64; N_BASIS]) {
        for i in (0..k).rev() {
            let mut s = self.z[i];
            for q in i + 1..k {
                s -= self.l[q * N_BASIS + i] * beta[q];
            }
            beta[i] = s / self.l[i * N_BASIS + i];
        }
    }

    /// Residual sum of squares on the part this factor was built from.
    #[inline]
    fn own_sse(&self, st: &Stats, k: usize) -> f64 {
        st.yy - self.z[..k].iter().map(|v| v * v).sum::<f64>()
    }
}

/// Residual sum of squares on part `st` of coefficients `beta` on columns `sel`.
#[inline]
fn sse(st: &Stats, m: usize, sel: &[usize], beta: &[f64]) -> f64 {
    let mut quad = 0.0;
    let mut lin = 0.0;
    for (i, &ci) in sel.iter().enumerate() {
        let g = &st.gram[ci * m..(ci + 1) * m];
        let mut s = 0.0;
        for (q, &cq) in sel[..i].iter().enumerate() {
            s += g[cq] * beta[q];
        }
        quad += beta[i] * (2.0 * s + g[ci] * beta[i]);
        lin += beta[i] * st.moment[ci];
    }
    st.yy - 2.0 * lin + quad
}

/// Per-task working state.
struct Walker<'p> {
    p: &'p Problem,
    fa: Factor,
    fb: Factor,
    sel: [usize; N_BASIS],
    beta: [f64; N_BASIS],
    max_terms: usize,
}

impl Walker<'_> {
    fn new(p: &Problem, max_terms: usize) -> Walker<'_> {
        Walker { p, fa: Factor::new(), fb: Factor::new(), sel: [0; N_BASIS], beta: [0.0; N_BASIS], max_terms }
    }

    /// Adds column `j` at depth `k` to the factor(s) the criterion needs.
    #[inline]
    fn extend(&mut self, k: usize, j: usize) -> bool {
        let p = self.p;
        let ok = match p.kind {
            Kind::Regularity => self.fa.extend(&p.a, p.m, &self.sel, k, j),
            Kind::Rss => self.fa.extend(&p.ab, p.m, &self.sel, k, j),
            Kind::Symmetric => {
                self.fa.extend(&p.a, p.m, &self.sel, k, j) && self.fb.extend(&p.b, p.m, &self.sel, k, j)
            }
        };
        if ok {
            self.sel[k] = j;
        }
        ok
    }

    /// The criterion of the first `k` columns (factors already extended).
    #[inline]
    fn score(&mut self, k: usize) -> f64 {
        let p = self.p;
        let sel = &self.sel[..k];
        match p.kind {
            Kind::Regularity => {
                self.fa.beta(k, &mut self.beta);
                (sse(&p.b, p.m, sel, &self.beta[..k]).max(0.0) / p.b.rows).sqrt()
            }
            Kind::Rss => (self.fa.own_sse(&p.ab, k).max(0.0) / p.ab.rows).sqrt(),
            Kind::Symmetric => {
                self.fa.beta(k, &mut self.beta);
                let eb = sse(&p.b, p.m, sel, &self.beta[..k]);
                self.fb.beta(k, &mut self.beta);
                let ea = sse(&p.a, p.m, sel, &self.beta[..k]);
                ((ea + eb).max(0.0) / (p.a.rows + p.b.rows)).sqrt()
            }
        }
    }

    /// Scores the node with `k` columns whose result index is `n`, then its children: columns
    /// `from..to` (column c ↔ bit c−1 of the index).
    fn walk(&mut self, k: usize, n: usize, from: usize, to: usize, out: &mut [f64], base: usize) {
        out[n - base] = self.score(k);
        if k == self.max_terms {
            return;
        }
        for j in from..to {
            let child = n | 1 << (j - 1);
            if self.extend(k, j) {
                self.walk(k + 1, child, j + 1, to, out, base);
            } else {
                // The child and every superset of it in this subtree are rank deficient.
                mark_subtree(out, base, child, j + 1, to, k + 1, self.max_terms);
            }
        }
    }
}

/// Marks node `n` (with `k` columns) and its descendants over columns `from..to` as deficient,
/// except those beyond `max_terms`, which stay excluded.
fn mark_subtree(out: &mut [f64], base: usize, n: usize, from: usize, to: usize, k: usize, max_terms: usize) {
    if k > max_terms {
        return;
    }
    out[n - base] = f64::NAN;
    for j in from..to {
        mark_subtree(out, base, n | 1 << (j - 1), j + 1, to, k + 1, max_terms);
    }
}

/// Scores every subset of columns `1..m` (each with column 0, the intercept) with at most
/// `max_terms` columns. Result `n` belongs to the subset whose bit `c−1` is set for each column
/// `c`: the criterion, NaN when rank deficient, [`EXCLUDED`] when beyond `max_terms`.
/// `progress` receives counts of finished candidates.
pub fn exhaustive(p: &Problem, max_terms: usize, progress: &(dyn Fn(u64) + Sync)) -> Vec<f64> {
    use rayon::prelude::*;
    let nb = p.m - 1;
    let total = 1usize << nb;
    let q = nb.min(6);
    let low = nb - q;
    let block = 1usize << low;
    let mut out = vec![EXCLUDED; total];
    out.par_chunks_mut(block).enumerate().for_each(|(t, chunk)| {
        let mut w = Walker::new(p, max_terms);
        let base = t << low;
        // The task's fixed columns: the intercept and the high columns chosen by t.
        let size = 1 + (base >> low).count_ones() as usize;
        if size <= max_terms {
            let mut ok = w.extend(0, 0);
            let mut k = 1;
            for bit in low..nb {
                if ok && base & (1 << bit) != 0 {
                    ok = w.extend(k, bit + 1);
                    k += 1;
                }
            }
            if ok {
                w.walk(size, base, 1, low + 1, chunk, base);
            } else {
                mark_subtree(chunk, base, base, 1, low + 1, size, max_terms);
            }
        }
        progress(block as u64);
    });
    out
}

/// Scores a given list of subsets (column lists, each starting with column 0).
pub fn listed(p: &Problem, subsets: &[Vec<usize>]) -> Vec<f64> {
    subsets
        .iter()
        .map(|cols| {
            let mut w = Walker::new(p, N_BASIS);
            for (k, &c) in cols.iter().enumerate() {
                if !w.extend(k, c) {
                    return f64::NAN;
                }
            }
            w.score(cols.len())
        })
        .collect()
}
