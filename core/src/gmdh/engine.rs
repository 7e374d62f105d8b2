//! The exhaustive GMDH engine: every subset of a basis scored from sufficient statistics.
//!
//! Cost per candidate does not depend on the number of samples. The weighted Gram matrix,
//! moment vector and `yᵀy` of each part are formed once over the scaled regressors.
//!
//! Candidates are visited depth first, each child adding one column with an index above its
//! parent's. A node does not keep a factor of its own columns: it keeps, for the columns that its
//! descendants may still add and for the response `y`, the Gram matrices of their *residuals*
//! after projecting out the node's columns (one sweep, or Gauss–Jordan pivot, per added column):
//!
//! - `D(u, v) = ⟨e_u, e_v⟩` on the fitting part: the Schur complement of the node's columns in
//!   the fitting part's Gram matrix (its `(y, y)` entry is the fit's residual sum of squares, and
//!   its diagonal is the Cholesky pivot the column would get);
//! - `E(u, v) = ⟨e_u, e_v⟩` on the scoring part, with the same residuals `e` (projections fitted
//!   on the fitting part): its `(y, y)` entry is the criterion's sum of squares.
//!
//! Adding column `s` with `c_u = D(s, u) / D(s, s)` (so that `e_u' = e_u − c_u e_s`):
//!
//! ```text
//! D'(u, v) = D(u, v) − c_u D(s, v)
//! E'(u, v) = E(u, v) − c_u E(s, v) − c_v (E(s, u) − c_u E(s, s))
//! ```
//!
//! A child needs these only over the columns above `s` (its own possible children) and `y`, so a
//! node whose last column leaves `r` columns above it costs O(r²), and `r` is small for most
//! nodes (half of all subsets contain the last column; `E[r²] ≈ 3` over the cubic basis) — the
//! cost per candidate is nearly constant instead of growing as k². A pivot `D(s, s)` at or below
//! [`PIVOT_TOL`] of the column's own diagonal marks it as (numerically) dependent on the node's
//! columns: that candidate and its whole subtree are rank deficient and are recorded as such
//! without being visited. This is the same test, on the same number, as a Cholesky pivot.
//!
//! Leave-one-out needs each position's residual and leverage, not sums: its kernel
//! ([`loo`]) keeps residual vectors over the positions instead of Gram matrices, with the same
//! depth-first walk, pivot test and pruning, at O(n) per updated column for n positions.
//!
//! Work is split into tasks that each fix which of the highest-index terms are present; the
//! candidates of one task form a contiguous block of the result vector, so tasks write without
//! locks. A task allocates its per-depth state once; nothing is allocated per candidate.

mod loo;

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
    /// Leave-one-out (PRESS) over A∪B: each position predicted by the fit on all the others.
    Loo,
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

/// Whether the columns `cols` are identifiable from the statistics `st`: the engine's pivot test
/// (each column's pivot above [`PIVOT_TOL`] of its diagonal), by elimination of their Gram matrix
/// in the order given.
pub fn identifiable(st: &Stats, m: usize, cols: &[usize]) -> bool {
    let k = cols.len();
    let mut g: Vec<f64> = (0..k * k).map(|i| st.gram[cols[i / k] * m + cols[i % k]]).collect();
    for j in 0..k {
        let pivot = g[j * k + j];
        if !(pivot > PIVOT_TOL * st.gram[cols[j] * m + cols[j]]) {
            return false;
        }
        for u in j + 1..k {
            let c = g[u * k + j] / pivot;
            for v in j + 1..k {
                g[u * k + v] -= c * g[j * k + v];
            }
        }
    }
    true
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
    /// The rows of A∪B (leave-one-out needs each position's residual and leverage).
    pub rows: Rows,
}

/// The scaled rows of every position: what [`Stats`] sums.
#[derive(Clone, Debug, Default)]
pub struct Rows {
    /// Regressors, row-major `n × m`.
    pub z: Vec<f64>,
    /// Responses.
    pub y: Vec<f64>,
    /// Weights (the positions' rows).
    pub w: Vec<f64>,
}

/// Stride of the state matrices: room for every basis column and the response.
const S: usize = N_BASIS + 1;

/// A symmetric matrix over state indices (columns and the response), row-major with stride `S`.
/// Which triangle is valid depends on how it was made: [`sweep`] with `FULL` keeps both, the
/// depth-first steps keep the upper one.
type Mat = [f64; S * S];

/// The state of one node: a residual Gram matrix `D` and a cross matrix `E` per fitting part
/// (see the module documentation). Regularity uses `[D_A, E_B]`, symmetric
/// `[D_A, E_B, D_B, E_A]`, rss `[D_AB]`.
#[derive(Clone)]
struct Node<const NM: usize> {
    m: [Mat; NM],
}

/// One pivot step on a `D`/`E` pair (or on `D` alone when `pe`/`ce` are `None`), over the state
/// indices `lo..=hi`: the upper triangle (`FULL == false`, which needs `s < lo` and the parent's
/// upper triangle over `s..=hi`) or the whole square (`FULL == true`, which needs the parent's
/// whole square). False, and nothing written, when the pivot `D(s, s)` is at or below
/// `PIVOT_TOL · diag`.
#[inline(always)]
fn sweep<const FULL: bool>(
    pd: &Mat,
    cd: &mut Mat,
    cross: Option<(&Mat, &mut Mat)>,
    s: usize,
    diag: f64,
    lo: usize,
    hi: usize,
) -> bool {
    let ds = &pd[s * S..s * S + S];
    let pivot = ds[s];
    if !(pivot > PIVOT_TOL * diag) {
        return false;
    }
    let inv = 1.0 / pivot;
    let width = hi + 1 - lo;
    let mut c = [0.0; S];
    for (c, d) in c[lo..lo + width].iter_mut().zip(&ds[lo..lo + width]) {
        *c = d * inv;
    }
    match cross {
        None => {
            for u in lo..=hi {
                let first = if FULL { lo } else { u };
                let len = hi + 1 - first;
                let (row, cu) = (u * S + first, c[u]);
                let (o, p, q) = (&mut cd[row..row + len], &pd[row..row + len], &ds[first..first + len]);
                for i in 0..len {
                    o[i] = p[i] - cu * q[i];
                }
            }
        }
        Some((pe, ce)) => {
            let es = &pe[s * S..s * S + S];
            for u in lo..=hi {
                let first = if FULL { lo } else { u };
                let len = hi + 1 - first;
                let (row, cu) = (u * S + first, c[u]);
                let au = es[u] - cu * es[s];
                let (od, pd, qd) = (&mut cd[row..row + len], &pd[row..row + len], &ds[first..first + len]);
                let (oe, pe, qe) = (&mut ce[row..row + len], &pe[row..row + len], &es[first..first + len]);
                let cv = &c[first..first + len];
                for i in 0..len {
                    od[i] = pd[i] - cu * qd[i];
                    oe[i] = pe[i] - cu * qe[i] - au * cv[i];
                }
            }
        }
    }
    true
}

/// What a criterion keeps per node and how it scores one.
trait Kernel {
    /// The state of one node.
    type Node: Clone + Send + Sync;
    /// The root node (the empty model) of `p` in `layout`.
    fn root(p: &Problem, layout: &Layout) -> Self::Node;
    /// Adds the column at state index `s` to `par`, writing the child over `lo..=hi`.
    fn extend<const FULL: bool>(
        p: &Setup,
        par: &Self::Node,
        ch: &mut Self::Node,
        s: usize,
        lo: usize,
        hi: usize,
    ) -> bool;
    /// The criterion of a node; `y` is the response's state index.
    fn score(p: &Setup, n: &Self::Node, y: usize) -> f64;
}

/// The fixed data of a run in state indices: the columns' own diagonals (for the pivot test), the
/// parts' row counts and, for leave-one-out, the positions' weights.
struct Setup {
    diag: [[f64; S]; 2],
    rows: [f64; 3],
    w: Vec<f64>,
}

struct Regularity;
struct Symmetric;
struct Rss;

impl Kernel for Regularity {
    type Node = Node<2>;
    fn root(p: &Problem, layout: &Layout) -> Node<2> {
        Node { m: [root_mat(&p.a, p.m, layout), root_mat(&p.b, p.m, layout)] }
    }
    #[inline(always)]
    fn extend<const FULL: bool>(
        p: &Setup,
        par: &Node<2>,
        ch: &mut Node<2>,
        s: usize,
        lo: usize,
        hi: usize,
    ) -> bool {
        let [cd, ce] = &mut ch.m;
        sweep::<FULL>(&par.m[0], cd, Some((&par.m[1], ce)), s, p.diag[0][s], lo, hi)
    }
    #[inline(always)]
    fn score(p: &Setup, n: &Node<2>, y: usize) -> f64 {
        (n.m[1][y * S + y].max(0.0) / p.rows[1]).sqrt()
    }
}

impl Kernel for Symmetric {
    type Node = Node<4>;
    fn root(p: &Problem, layout: &Layout) -> Node<4> {
        let (a, b) = (root_mat(&p.a, p.m, layout), root_mat(&p.b, p.m, layout));
        Node { m: [a, b, b, a] }
    }
    #[inline(always)]
    fn extend<const FULL: bool>(
        p: &Setup,
        par: &Node<4>,
        ch: &mut Node<4>,
        s: usize,
        lo: usize,
        hi: usize,
    ) -> bool {
        let [cda, ceb, cdb, cea] = &mut ch.m;
        sweep::<FULL>(&par.m[0], cda, Some((&par.m[1], ceb)), s, p.diag[0][s], lo, hi)
            && sweep::<FULL>(&par.m[2], cdb, Some((&par.m[3], cea)), s, p.diag[1][s], lo, hi)
    }
    #[inline(always)]
    fn score(p: &Setup, n: &Node<4>, y: usize) -> f64 {
        ((n.m[1][y * S + y] + n.m[3][y * S + y]).max(0.0) / (p.rows[0] + p.rows[1])).sqrt()
    }
}

impl Kernel for Rss {
    type Node = Node<1>;
    fn root(p: &Problem, layout: &Layout) -> Node<1> {
        Node { m: [root_mat(&p.ab, p.m, layout)] }
    }
    #[inline(always)]
    fn extend<const FULL: bool>(
        p: &Setup,
        par: &Node<1>,
        ch: &mut Node<1>,
        s: usize,
        lo: usize,
        hi: usize,
    ) -> bool {
        sweep::<FULL>(&par.m[0], &mut ch.m[0], None, s, p.diag[0][s], lo, hi)
    }
    #[inline(always)]
    fn score(p: &Setup, n: &Node<1>, y: usize) -> f64 {
        (n.m[0][y * S + y].max(0.0) / p.rows[2]).sqrt()
    }
}

/// The map from state indices to columns: columns `0..=low` keep their index, the response comes
/// next (so that the depth-first steps over columns `1..=low` work on one contiguous range that
/// ends with it), then the columns above `low`.
struct Layout {
    /// Column of each state index, `None` for the response.
    col: [Option<usize>; S],
    /// State index of the response.
    y: usize,
    /// Number of state indices (`m + 1`).
    n: usize,
}

impl Layout {
    fn new(m: usize, low: usize) -> Layout {
        let mut col = [None; S];
        for (i, c) in col.iter_mut().enumerate().take(m + 1) {
            *c = match i {
                i if i <= low => Some(i),
                i if i == low + 1 => None,
                i => Some(i - 1),
            };
        }
        Layout { col, y: low + 1, n: m + 1 }
    }

    /// State index of column `c`.
    fn index(&self, c: usize) -> usize {
        if c < self.y {
            c
        } else {
            c + 1
        }
    }
}

/// The root state of `part` (0 = A, 1 = B, 2 = A∪B) in `layout`: the part's Gram matrix bordered by
/// its moments and `yᵀy`, both triangles.
fn root_mat(st: &Stats, m: usize, layout: &Layout) -> Mat {
    let mut out = [0.0; S * S];
    for u in 0..layout.n {
        for v in 0..layout.n {
            out[u * S + v] = match (layout.col[u], layout.col[v]) {
                (Some(a), Some(b)) => st.gram[a * m + b],
                (Some(a), None) | (None, Some(a)) => st.moment[a],
                (None, None) => st.yy,
            };
        }
    }
    out
}

/// Per-task working state: one node per depth (number of columns).
struct Walker<'p, K: Kernel> {
    setup: &'p Setup,
    nodes: Vec<K::Node>,
    y: usize,
    max_terms: usize,
}

impl<K: Kernel> Walker<'_, K> {
    /// Adds column state index `s` to the node at depth `k` as the node at depth `k + 1`, written
    /// over the state indices `lo..=hi`.
    #[inline(always)]
    fn step<const FULL: bool>(&mut self, k: usize, s: usize, lo: usize, hi: usize) -> bool {
        let (done, rest) = self.nodes.split_at_mut(k + 1);
        K::extend::<FULL>(self.setup, &done[k], &mut rest[0], s, lo, hi)
    }

    /// Scores the node at depth `k` whose result index is `n`, then its children: columns
    /// `from..to` (column c ↔ bit c−1 of the index; here state index = column).
    fn walk(&mut self, k: usize, n: usize, from: usize, to: usize, out: &mut [f64], base: usize) {
        out[n - base] = K::score(self.setup, &self.nodes[k], self.y);
        if k == self.max_terms {
            return;
        }
        for j in from..to {
            let child = n | 1 << (j - 1);
            if j + 1 == to || k + 1 == self.max_terms {
                // A leaf needs only its own `(y, y)` entry, and no recursion.
                out[child - base] = if self.step::<false>(k, j, self.y, self.y) {
                    K::score(self.setup, &self.nodes[k + 1], self.y)
                } else {
                    f64::NAN
                };
            } else if self.step::<false>(k, j, j + 1, self.y) {
                self.walk(k + 1, child, j + 1, to, out, base);
            } else {
                // The child and every superset of it in this subtree are rank deficient.
                mark_subtree(out, base, child, j + 1, to, k + 1, self.max_terms);
            }
        }
    }
}

/// Marks node `n` (with `k` columns) and its descendants over columns `from..to` as deficient,
/// except those beyond `max_terms`, which stay excluded. The descendants add any subset of the
/// bits `from−1..to−1` to `n`, which has none of them set.
fn mark_subtree(out: &mut [f64], base: usize, n: usize, from: usize, to: usize, k: usize, max_terms: usize) {
    if k > max_terms {
        return;
    }
    let room = (max_terms - k) as u32;
    let shift = from - 1;
    for x in 0..1usize << (to - from) {
        if x.count_ones() <= room {
            out[(n | x << shift) - base] = f64::NAN;
        }
    }
}

/// The setup and root node of a problem in `layout`.
fn prepare<K: Kernel>(p: &Problem, layout: &Layout) -> (Setup, K::Node) {
    let (fit, fit_b): (&Stats, &Stats) = match p.kind {
        Kind::Rss | Kind::Loo => (&p.ab, &p.ab),
        _ => (&p.a, &p.b),
    };
    let mut diag = [[0.0; S]; 2];
    for (i, c) in layout.col.iter().enumerate().take(layout.n) {
        if let Some(c) = c {
            diag[0][i] = fit.gram[c * p.m + c];
            diag[1][i] = fit_b.gram[c * p.m + c];
        }
    }
    let w = if p.kind == Kind::Loo { p.rows.w.clone() } else { Vec::new() };
    (Setup { diag, rows: [p.a.rows, p.b.rows, p.ab.rows], w }, K::root(p, layout))
}

/// Scores every subset of columns `1..m` (each with column 0, the intercept) with at most
/// `max_terms` columns. Result `n` belongs to the subset whose bit `c−1` is set for each column
/// `c`: the criterion, NaN when rank deficient, [`EXCLUDED`] when beyond `max_terms`.
/// `progress` receives counts of finished candidates.
pub fn exhaustive(p: &Problem, max_terms: usize, progress: &(dyn Fn(u64) + Sync)) -> Vec<f64> {
    match p.kind {
        Kind::Regularity => exhaustive_with::<Regularity>(p, max_terms, progress),
        Kind::Symmetric => exhaustive_with::<Symmetric>(p, max_terms, progress),
        Kind::Rss => exhaustive_with::<Rss>(p, max_terms, progress),
        Kind::Loo => exhaustive_with::<loo::Loo>(p, max_terms, progress),
    }
}

fn exhaustive_with<K: Kernel>(p: &Problem, max_terms: usize, progress: &(dyn Fn(u64) + Sync)) -> Vec<f64> {
    use rayon::prelude::*;
    let nb = p.m - 1;
    let total = 1usize << nb;
    let q = nb.min(6);
    let low = nb - q;
    let block = 1usize << low;
    let layout = Layout::new(p.m, low);
    let (setup, root) = prepare::<K>(p, &layout);
    let mut out = vec![EXCLUDED; total];
    let walker = || Walker::<K> { setup: &setup, nodes: vec![root.clone(); p.m + 1], y: layout.y, max_terms };
    out.par_chunks_mut(block).enumerate().for_each_init(walker, |w, (t, chunk)| {
        let base = t << low;
        // The task's fixed columns: the intercept and the high columns chosen by t.
        let size = 1 + (base >> low).count_ones() as usize;
        if size <= max_terms {
            w.nodes[0].clone_from(&root);
            let fixed =
                std::iter::once(0).chain((low..nb).filter(|bit| base & (1 << bit) != 0).map(|bit| bit + 1));
            // The prefix keeps every state index, both triangles (its columns come in any order).
            if fixed.enumerate().all(|(k, c)| w.step::<true>(k, layout.index(c), 0, layout.n - 1)) {
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
    match p.kind {
        Kind::Regularity => listed_with::<Regularity>(p, subsets),
        Kind::Symmetric => listed_with::<Symmetric>(p, subsets),
        Kind::Rss => listed_with::<Rss>(p, subsets),
        Kind::Loo => listed_with::<loo::Loo>(p, subsets),
    }
}

fn listed_with<K: Kernel>(p: &Problem, subsets: &[Vec<usize>]) -> Vec<f64> {
    let layout = Layout::new(p.m, p.m - 1);
    let (setup, root) = prepare::<K>(p, &layout);
    let mut w = Walker::<K> { setup: &setup, nodes: vec![root.clone(); 2], y: layout.y, max_terms: N_BASIS };
    subsets
        .iter()
        .map(|cols| {
            w.nodes[0].clone_from(&root);
            for &c in cols {
                if !w.step::<true>(0, layout.index(c), 0, layout.n - 1) {
                    return f64::NAN;
                }
                w.nodes.swap(0, 1);
            }
            K::score(&setup, &w.nodes[0], layout.y)
        })
        .collect()
}
