//! Combinatorial GMDH: fit every candidate structure on part A, score it by an external
//! criterion, and pick the simplest model within a tolerance of the best.
//!
//! Criteria, all reported as an RMS in ADC codes of the dwell-mean residuals over the positions of
//! the part they score (each position weighted by its rows). The regressors depend on the
//! position only, so the within-dwell scatter is the same for every model: it is left out, so that
//! the one-code tolerance compares what the models can change.
//!
//! - regularity `Δ(B|A)`: error on B of the model fitted on A;
//! - symmetric `d`: error on B of the A-fit together with error on A of the B-fit, over A∪B;
//! - rss: error on A∪B of the model fitted on A∪B.
//!
//! Engine: regressors are scaled to unit weighted RMS; the weighted Gram matrix and moment vector
//! of each part are formed once for the whole basis; each candidate solves its sub-system by a
//! Cholesky factorisation that flags a pivot below [`PIVOT_TOL`] of its diagonal as rank
//! deficiency (the model is then "not identifiable", never ranked). Residuals are evaluated on the
//! dwell means.

use accelcal_shared::{Basis, Structure, N_BASIS};
use rayon::prelude::*;

use crate::lsq::{self, LsqFit};
use crate::positions::{ChannelStats, Positions};

/// Relative Cholesky pivot (squared sine of the angle between a regressor and the span of the
/// others) below which a candidate counts as rank deficient.
pub const PIVOT_TOL: f64 = 1e-10;

/// The external criterion.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Criterion {
    /// Error on B of the model fitted on A (the paper's choice).
    Regularity,
    /// Error on B of the A-fit plus error on A of the B-fit.
    Symmetric,
    /// Residual on A∪B of the model fitted on A∪B.
    Rss,
}

/// How the positions are divided into the fitting part A and the checking part B.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Split {
    /// Even positions in A, odd ones in B.
    Alternate,
    /// First half in A, second half in B.
    Halves,
    /// The last `FRACTION` of the positions in B.
    Tail(f64),
}

impl std::str::FromStr for Split {
    type Err = String;
    fn from_str(s: &str) -> Result<Split, String> {
        match s {
            "alternate" => Ok(Split::Alternate),
            "halves" => Ok(Split::Halves),
            _ => match s.strip_prefix("tail:").map(str::parse::<f64>) {
                Some(Ok(f)) if f > 0.0 && f < 1.0 => Ok(Split::Tail(f)),
                Some(_) => Err(format!("`{s}`: the tail fraction must be a number in (0, 1)")),
                None => Err(format!("`{s}`: expected alternate, halves or tail:FRACTION")),
            },
        }
    }
}

impl std::fmt::Display for Split {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Split::Alternate => f.write_str("alternate"),
            Split::Halves => f.write_str("halves"),
            Split::Tail(x) => write!(f, "tail:{x}"),
        }
    }
}

impl Split {
    /// Position indices of parts A and B for `n` positions.
    pub fn parts(self, n: usize) -> (Vec<usize>, Vec<usize>) {
        let (mut a, mut b) = (Vec::new(), Vec::new());
        for i in 0..n {
            let in_b = match self {
                Split::Alternate => i % 2 == 1,
                Split::Halves => i >= n.div_ceil(2),
                Split::Tail(f) => {
                    i >= n - ((n as f64 * f).round() as usize).clamp(1, n.saturating_sub(1).max(1))
                }
            };
            if in_b {
                b.push(i)
            } else {
                a.push(i)
            }
        }
        (a, b)
    }
}

/// Why selection could not run.
#[derive(Debug, thiserror::Error)]
pub enum GmdhError {
    /// One part of the split is empty.
    #[error("the split leaves part {0} without positions ({1} positions in all)")]
    EmptyPart(char, usize),
    /// No candidate is identifiable on this plan and split.
    #[error("no candidate model is identifiable on this plan and split")]
    NothingIdentifiable,
    /// The refit of the selected model failed.
    #[error(transparent)]
    Refit(#[from] lsq::LsqError),
}

/// One candidate's score.
#[derive(Clone, Debug, PartialEq)]
pub struct Candidate {
    /// Its terms.
    pub structure: Structure,
    /// Criterion (RMS codes); `None` when the model is not identifiable where it is fitted.
    pub criterion: Option<f64>,
}

/// The outcome of selection for one channel.
#[derive(Clone, Debug)]
pub struct Selection {
    /// Channel name.
    pub channel: String,
    /// Every candidate, in enumeration order.
    pub candidates: Vec<Candidate>,
    /// Index into `candidates` of the selected model.
    pub selected: usize,
    /// Smallest criterion among identifiable candidates.
    pub best: f64,
    /// The selected structure refitted on A∪B (the paper refines coefficients by RSS).
    pub fit: LsqFit,
}

impl Selection {
    /// The selected candidate.
    pub fn selected(&self) -> &Candidate {
        &self.candidates[self.selected]
    }
}

/// Settings of a selection run.
#[derive(Clone, Copy, Debug)]
pub struct Settings {
    /// Candidate set.
    pub basis: Basis,
    /// External criterion.
    pub criterion: Criterion,
    /// A/B split.
    pub split: Split,
    /// Tolerance in codes: the simplest model within this of the best wins.
    pub tolerance: f64,
}

/// Weighted sufficient statistics of one part, over the scaled basis columns.
struct Part {
    /// Position indices.
    idx: Vec<usize>,
    /// Gram matrix, row-major `m × m`.
    gram: Vec<f64>,
    /// Moment vector.
    moment: Vec<f64>,
    /// Rows in the part.
    rows: f64,
}

struct Design {
    /// Basis indices of the columns.
    cols: Vec<usize>,
    /// Scaled regressors, row-major `positions × m`.
    z: Vec<f64>,
    m: usize,
}

impl Design {
    fn new(pos: &Positions, full: Structure) -> Design {
        let cols: Vec<usize> = full.indices().collect();
        let m = cols.len();
        let n = pos.len();
        let mut z = vec![0.0; n * m];
        let wsum: f64 = pos.weight.iter().sum();
        for (c, &bi) in cols.iter().enumerate() {
            let t = accelcal_shared::BASIS[bi];
            let mut ss = 0.0;
            for p in 0..n {
                let v = t.eval(pos.accel[p]);
                z[p * m + c] = v;
                ss += pos.weight[p] * v * v;
            }
            let s = (ss / wsum).sqrt();
            let s = if s > 0.0 { s } else { 1.0 };
            for p in 0..n {
                z[p * m + c] /= s;
            }
        }
        Design { cols, z, m }
    }

    fn part(&self, pos: &Positions, ch: &ChannelStats, idx: Vec<usize>) -> Part {
        let m = self.m;
        let mut gram = vec![0.0; m * m];
        let mut moment = vec![0.0; m];
        for &p in &idx {
            let w = pos.weight[p];
            let zp = &self.z[p * m..(p + 1) * m];
            for i in 0..m {
                moment[i] += w * zp[i] * ch.mean[p];
                for j in 0..m {
                    gram[i * m + j] += w * zp[i] * zp[j];
                }
            }
        }
        let rows = idx.iter().map(|&p| pos.weight[p]).sum();
        Part { idx, gram, moment, rows }
    }
}

/// Solves the sub-system of `part` on columns `sel` into `beta`. Returns false when a pivot is
/// below [`PIVOT_TOL`] of its diagonal (rank deficiency).
fn solve(part: &Part, m: usize, sel: &[usize], beta: &mut [f64]) -> bool {
    let k = sel.len();
    let mut l = [0.0f64; N_BASIS * N_BASIS];
    for i in 0..k {
        for j in 0..=i {
            let mut s = part.gram[sel[i] * m + sel[j]];
            for q in 0..j {
                s -= l[i * k + q] * l[j * k + q];
            }
            if i == j {
                let diag = part.gram[sel[i] * m + sel[i]];
                if !(s > PIVOT_TOL * diag) {
                    return false;
                }
                l[i * k + i] = s.sqrt();
            } else {
                l[i * k + j] = s / l[j * k + j];
            }
        }
    }
    // Forward then backward substitution.
    for i in 0..k {
        let mut s = part.moment[sel[i]];
        for q in 0..i {
            s -= l[i * k + q] * beta[q];
        }
        beta[i] = s / l[i * k + i];
    }
    for i in (0..k).rev() {
        let mut s = beta[i];
        for q in i + 1..k {
            s -= l[q * k + i] * beta[q];
        }
        beta[i] = s / l[i * k + i];
    }
    true
}

/// Weighted sum of squared residuals of `beta` (on columns `sel`) over the dwell means of `part`.
fn sse(d: &Design, pos: &Positions, ch: &ChannelStats, part: &Part, sel: &[usize], beta: &[f64]) -> f64 {
    let mut s = 0.0;
    for &p in &part.idx {
        let zp = &d.z[p * d.m..(p + 1) * d.m];
        let pred: f64 = sel.iter().zip(beta).map(|(&c, b)| zp[c] * b).sum();
        let r = ch.mean[p] - pred;
        s += pos.weight[p] * r * r;
    }
    s
}

/// Scores every candidate of `settings.basis` on one channel and selects the model.
/// `progress` is called with the number of candidates finished since its last call.
pub fn select(
    pos: &Positions,
    ch: &ChannelStats,
    settings: &Settings,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<Selection, GmdhError> {
    let n = pos.len();
    let (ia, ib) = settings.split.parts(n);
    if ia.is_empty() {
        return Err(GmdhError::EmptyPart('A', n));
    }
    if ib.is_empty() {
        return Err(GmdhError::EmptyPart('B', n));
    }
    let d = Design::new(pos, settings.basis.full());
    let mut all: Vec<usize> = (0..n).collect();
    all.sort_unstable();
    let a = d.part(pos, ch, ia);
    let b = d.part(pos, ch, ib);
    let ab = d.part(pos, ch, all);
    let count = settings.basis.candidate_count();
    // Column positions (in the design) of a structure's terms.
    let col_of = |bi: usize| d.cols.iter().position(|&c| c == bi).expect("candidate within the basis");
    let score = |s: Structure| -> Option<f64> {
        let mut sel = [0usize; N_BASIS];
        let k = s.len();
        for (n, bi) in s.indices().enumerate() {
            sel[n] = col_of(bi);
        }
        let sel = &sel[..k];
        let mut beta = [0.0; N_BASIS];
        let beta = &mut beta[..k];
        match settings.criterion {
            Criterion::Regularity => {
                if !solve(&a, d.m, sel, beta) {
                    return None;
                }
                Some((sse(&d, pos, ch, &b, sel, beta) / b.rows).sqrt())
            }
            Criterion::Symmetric => {
                if !solve(&a, d.m, sel, beta) {
                    return None;
                }
                let eb = sse(&d, pos, ch, &b, sel, beta);
                if !solve(&b, d.m, sel, beta) {
                    return None;
                }
                let ea = sse(&d, pos, ch, &a, sel, beta);
                Some(((ea + eb) / (a.rows + b.rows)).sqrt())
            }
            Criterion::Rss => {
                if !solve(&ab, d.m, sel, beta) {
                    return None;
                }
                Some((sse(&d, pos, ch, &ab, sel, beta) / ab.rows).sqrt())
            }
        }
    };
    const CHUNK: usize = 4096;
    let candidates: Vec<Candidate> = (0..count)
        .into_par_iter()
        .with_min_len(CHUNK)
        .map(|i| {
            let structure = settings.basis.candidate(i);
            let c = Candidate { structure, criterion: score(structure) };
            if (i + 1) % CHUNK == 0 {
                progress(CHUNK as u64);
            }
            c
        })
        .collect();
    progress((count % CHUNK) as u64);
    let best = candidates.iter().filter_map(|c| c.criterion).fold(f64::INFINITY, f64::min);
    if !best.is_finite() {
        return Err(GmdhError::NothingIdentifiable);
    }
    let selected = candidates
        .iter()
        .enumerate()
        .filter_map(|(i, c)| {
            c.criterion.filter(|&v| v <= best + settings.tolerance).map(|v| (i, c.structure.len(), v))
        })
        .min_by(|x, y| x.1.cmp(&y.1).then(x.2.total_cmp(&y.2)))
        .map(|x| x.0)
        .expect("the best candidate qualifies");
    let fit = lsq::fit(pos, ch, candidates[selected].structure, None)?;
    Ok(Selection { channel: ch.name.clone(), candidates, selected, best, fit })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn splits_cover_every_position_once() {
        assert_eq!(Split::Alternate.parts(5), (vec![0, 2, 4], vec![1, 3]));
        assert_eq!(Split::Halves.parts(5), (vec![0, 1, 2], vec![3, 4]));
        assert_eq!(Split::Tail(0.25).parts(8), (vec![0, 1, 2, 3, 4, 5], vec![6, 7]));
        assert_eq!("tail:0.5".parse::<Split>(), Ok(Split::Tail(0.5)));
        assert!("tail:1.5".parse::<Split>().is_err());
        assert!("every".parse::<Split>().is_err());
    }
}
