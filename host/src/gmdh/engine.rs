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

/// Dot product of two short vectors (the length of `a`), with four independent accumulators so the
/// compiler can pipeline (and vectorise) the sum.
#[inline(always)]
fn dot(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len();
    let b = &b[..n];
    let split = n & !3;
    let mut acc = [0.0; 4];
    for (x, y) in a[..split].chunks_exact(4).zip(b[..split].chunks_exact(4)) {
        for i in 0..4 {
            acc[i] += x[i] * y[i];
        }
    }
    let mut s = (acc[0] + acc[1]) + (acc[2] + acc[3]);
    for (x, y) in a[split..].iter().zip(&b[split..]) {
        s += x * y;
    }
    s
}

impl Factor {
    fn new() -> Factor {
        Factor { l: [0.0; N_BASIS * N_BASIS], z: [0.0; N_BASIS] }
    }

    /// Adds a column as row `k`, given its Gram entries against the first `k` columns (`g_row`),
    /// its own diagonal `g_jj` and moment `b_j`. False when the pivot is too small.
    #[inline]
    fn extend(&mut self, g_row: &[f64], g_jj: f64, b_j: f64, k: usize) -> bool {
        let (done, rest) = self.l.split_at_mut(k * N_BASIS);
        let row = &mut rest[..N_BASIS];
        for q in 0..k {
            let rq = &done[q * N_BASIS..q * N_BASIS + q + 1];
            row[q] = (g_row[q] - dot(&row[..q], &rq[..q])) / rq[q];
        }
        let d = g_jj - dot(&row[..k], &row[..k]);
        if !(d > PIVOT_TOL * g_jj) {
            return false;
        }
        let lkk = d.sqrt();
        row[k] = lkk;
        self.z[k] = (b_j - dot(&row[..k], &self.z[..k])) / lkk;
        true
    }

    /// Coefficients of the first `k` columns: `β = L⁻ᵀ z`, column-oriented so that each step is a
    /// contiguous update with one row of L.
    #[inline]
    fn beta(&self, k: usize, beta: &mut [f64; N_BASIS]) {
        beta[..k].copy_from_slice(&self.z[..k]);
        for q in (0..k).rev() {
            let row = &self.l[q * N_BASIS..q * N_BASIS + q + 1];
            let bq = beta[q] / row[q];
            beta[q] = bq;
            for (b, l) in beta[..q].iter_mut().zip(&row[..q]) {
                *b -= bq * l;
            }
        }
    }

    /// Residual sum of squares on the part this factor was built from.
    #[inline]
    fn own_sse(&self, st: &Stats, k: usize) -> f64 {
        st.yy - dot(&self.z[..k], &self.z[..k])
    }
}

/// The Gram rows of one part gathered for the current columns: row `k` holds the entries against
/// columns `0..=k` in selection order, contiguous, so the inner loops need no index gathers.
struct Compact {
    g: [f64; N_BASIS * N_BASIS],
    b: [f64; N_BASIS],
}

impl Compact {
    fn new() -> Compact {
        Compact { g: [0.0; N_BASIS * N_BASIS], b: [0.0; N_BASIS] }
    }

    /// Gathers column `j` as row `k` after columns `sel[..k]`.
    #[inline]
    fn push(&mut self, st: &Stats, m: usize, sel: &[usize], k: usize, j: usize) {
        let g = &st.gram[j * m..(j + 1) * m];
        let row = &mut self.g[k * N_BASIS..(k + 1) * N_BASIS];
        for (r, &c) in row.iter_mut().zip(&sel[..k]) {
            *r = g[c];
        }
        row[k] = g[j];
        self.b[k] = st.moment[j];
    }

    /// Residual sum of squares of `beta` (first `k` columns) on this part.
    #[inline]
    fn sse(&self, yy: f64, beta: &[f64], k: usize) -> f64 {
        let mut quad = 0.0;
        for i in 0..k {
            let row = &self.g[i * N_BASIS..i * N_BASIS + i + 1];
            quad += beta[i] * (2.0 * dot(&row[..i], &beta[..i]) + row[i] * beta[i]);
        }
        yy - 2.0 * dot(&beta[..k], &self.b[..k]) + quad
    }
}

/// Per-task working state.
struct Walker<'p> {
    p: &'p Problem,
    fa: Factor,
    fb: Factor,
    /// Gathered Gram rows of the part that fits (A, or A∪B for rss) and of B.
    ca: Compact,
    cb: Compact,
    sel: [usize; N_BASIS],
    beta: [f64; N_BASIS],
    max_terms: usize,
}

impl Walker<'_> {
    fn new(p: &Problem, max_terms: usize) -> Walker<'_> {
        Walker {
            p,
            fa: Factor::new(),
            fb: Factor::new(),
            ca: Compact::new(),
            cb: Compact::new(),
            sel: [0; N_BASIS],
            beta: [0.0; N_BASIS],
            max_terms,
        }
    }

    /// Adds column `j` at depth `k` to the factor(s) the criterion needs.
    #[inline]
    fn extend(&mut self, k: usize, j: usize) -> bool {
        let p = self.p;
        let fit = if p.kind == Kind::Rss { &p.ab } else { &p.a };
        self.ca.push(fit, p.m, &self.sel, k, j);
        let row = k * N_BASIS;
        if !self.fa.extend(&self.ca.g[row..row + k], self.ca.g[row + k], self.ca.b[k], k) {
            return false;
        }
        if p.kind != Kind::Rss {
            self.cb.push(&p.b, p.m, &self.sel, k, j);
            if p.kind == Kind::Symmetric
                && !self.fb.extend(&self.cb.g[row..row + k], self.cb.g[row + k], self.cb.b[k], k)
            {
                return false;
            }
        }
        self.sel[k] = j;
        true
    }

    /// The criterion of the first `k` columns (factors already extended).
    #[inline]
    fn score(&mut self, k: usize) -> f64 {
        let p = self.p;
        match p.kind {
            Kind::Regularity => {
                self.fa.beta(k, &mut self.beta);
                (self.cb.sse(p.b.yy, &self.beta, k).max(0.0) / p.b.rows).sqrt()
            }
            Kind::Rss => (self.fa.own_sse(&p.ab, k).max(0.0) / p.ab.rows).sqrt(),
            Kind::Symmetric => {
                self.fa.beta(k, &mut self.beta);
                let eb = self.cb.sse(p.b.yy, &self.beta, k);
                self.fb.beta(k, &mut self.beta);
                let ea = self.ca.sse(p.a.yy, &self.beta, k);
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
        let base = t << low;
        // The task's fixed columns: the intercept and the high columns chosen by t.
        let size = 1 + (base >> low).count_ones() as usize;
        let fixed =
            std::iter::once(0).chain((low..nb).filter(|bit| base & (1 << bit) != 0).map(|bit| bit + 1));
        if size <= max_terms {
            let mut w = Walker::new(p, max_terms);
            if fixed.enumerate().all(|(k, c)| w.extend(k, c)) {
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
