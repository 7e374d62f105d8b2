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
//! - rss: error on A∪B of the model fitted on A∪B;
//! - loo (leave-one-out, PRESS): error at each position of the model fitted on all the others,
//!   over A∪B; no split, so it works where a split leaves too few positions to fit on (the six
//!   test-turn positions identify model 4, three of them do not).
//!
//! [`guard`] refuses a selection that drops an axis term only because the criterion cannot
//! identify the model with it (a split's fitting part too small), or that drops the channel's own
//! axis: such a model is the worst kind, not the best.
//!
//! [`engine`] scores candidates from sufficient statistics (cost independent of the number of
//! samples); a rank-deficient candidate is reported as not identifiable, never ranked.
//! [`reference`] computes the same criteria the slow way (QR on the rows) for the tests.

pub mod engine;
pub mod guard;
pub mod multi;
pub mod reference;

use accelcal_shared::terms::PAPER_MODELS;
use accelcal_shared::{Basis, Structure};
use rayon::prelude::*;

use crate::error::{Classify, Kind, Plain, Setting, Worded, Wording};
use crate::lsq::{self, LsqFit};
use crate::positions::{ChannelStats, Positions};

pub use engine::PIVOT_TOL;

/// The external criterion.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Criterion {
    /// Error on B of the model fitted on A (the paper's choice).
    Regularity,
    /// Error on B of the A-fit plus error on A of the B-fit.
    Symmetric,
    /// Residual on A∪B of the model fitted on A∪B.
    Rss,
    /// Leave-one-out: the residual at each position of the model fitted on all the others.
    Loo,
}

impl Criterion {
    /// Its name in tables.
    pub fn name(self) -> &'static str {
        match self {
            Criterion::Regularity => "regularity",
            Criterion::Symmetric => "symmetric",
            Criterion::Rss => "rss",
            Criterion::Loo => "leave-one-out",
        }
    }
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
    /// Whole temperatures held out: every position whose dwell temperature lies within
    /// [`TEMP_SPLIT_TOL_C`] of one of the listed temperatures (°C, up to 4) in B, the others in A.
    Temp {
        /// The held-out temperatures, °C (the first `n` used).
        at: [f64; 4],
        /// How many are listed.
        n: usize,
    },
}

/// Half-width of the temperature band of `--split temp:…`, °C.
pub const TEMP_SPLIT_TOL_C: f64 = 2.5;

impl std::str::FromStr for Split {
    type Err = String;
    fn from_str(s: &str) -> Result<Split, String> {
        if let Some(list) = s.strip_prefix("temp:") {
            let v: Vec<f64> = list.split(',').filter_map(|x| x.trim().parse().ok()).collect();
            if v.is_empty()
                || v.len() > 4
                || v.len() != list.split(',').count()
                || v.iter().any(|x| !x.is_finite())
            {
                return Err(format!("`{s}`: expected temp:T1[,T2,…], 1 to 4 temperatures in °C"));
            }
            let mut at = [0.0; 4];
            at[..v.len()].copy_from_slice(&v);
            return Ok(Split::Temp { at, n: v.len() });
        }
        match s {
            "alternate" => Ok(Split::Alternate),
            "halves" => Ok(Split::Halves),
            _ => match s.strip_prefix("tail:").map(str::parse::<f64>) {
                Some(Ok(f)) if f > 0.0 && f < 1.0 => Ok(Split::Tail(f)),
                Some(_) => Err(format!("`{s}`: the tail fraction must be a number in (0, 1)")),
                None => Err(format!("`{s}`: expected alternate, halves, tail:FRACTION or temp:T1[,T2,…]")),
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
            Split::Temp { at, n } => {
                f.write_str("temp:")?;
                for (i, t) in at[..*n].iter().enumerate() {
                    write!(f, "{}{t}", if i > 0 { "," } else { "" })?;
                }
                Ok(())
            }
        }
    }
}

impl Split {
    /// Position indices of parts A and B of `pos`.
    pub fn parts_of(self, pos: &Positions) -> Result<(Vec<usize>, Vec<usize>), GmdhError> {
        match self {
            Split::Temp { at, n } => {
                let temps = pos.temp_c.as_ref().ok_or(GmdhError::NoTemperature)?;
                let (mut a, mut b) = (Vec::new(), Vec::new());
                for (i, t) in temps.iter().enumerate() {
                    if at[..n].iter().any(|x| (t - x).abs() <= TEMP_SPLIT_TOL_C) {
                        b.push(i)
                    } else {
                        a.push(i)
                    }
                }
                Ok((a, b))
            }
            _ => Ok(self.parts(pos.len())),
        }
    }

    /// Position indices of parts A and B for `n` positions (a temperature split puts all in A:
    /// use [`Split::parts_of`]).
    pub fn parts(self, n: usize) -> (Vec<usize>, Vec<usize>) {
        let (mut a, mut b) = (Vec::new(), Vec::new());
        for i in 0..n {
            let in_b = match self {
                Split::Temp { .. } => false,
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
    /// A thermal basis or a temperature split on a campaign without temperatures.
    #[error("{}", self.worded(&Plain).unwrap_or_default())]
    NoTemperature,
    /// No candidate is identifiable on this plan and split.
    #[error("no candidate model is identifiable on this plan and split")]
    NothingIdentifiable,
    /// The selection lacks axis terms only because the criterion cannot identify the model with
    /// them, although all the positions do ([`guard`]).
    #[error("{}", self.worded(&Plain).unwrap_or_default())]
    Blind {
        /// Channel name.
        channel: String,
        /// The split whose part is blind (its value, as `Split` prints it); `None` for
        /// leave-one-out.
        split: Option<String>,
        /// Where the criterion cannot identify which model (after the split, if any).
        why: String,
        /// The selection.
        selected: Structure,
        /// The axis terms it lacks, in words ("its own axis term `ax`", "the axis terms …").
        dropped: String,
        /// The fewest positions leave-one-out needs to identify the model with them, when it
        /// is the remedy (`None`: more positions are).
        loo_min: Option<usize>,
    },
    /// No position varies the channel's own axis.
    #[error(
        "channel {channel}: no position varies `{term}`, its own axis ({how}): the plan cannot calibrate it"
    )]
    OwnAxisConstant {
        /// Channel name.
        channel: String,
        /// The own axis term.
        term: String,
        /// How the own axis is known.
        how: &'static str,
    },
    /// The criterion drops the channel's own axis although the plan identifies it.
    #[error(
        "channel {channel}: the selection {selected} drops `{term}`, its own axis ({how}), although the \
         plan identifies it: the channel does not respond along its axis beyond the tolerance ({criterion} \
         codes with it, best {best})"
    )]
    OwnAxisDropped {
        /// Channel name.
        channel: String,
        /// The selection.
        selected: Structure,
        /// The own axis term.
        term: String,
        /// How the own axis is known.
        how: &'static str,
        /// Criterion of the selection with the own axis term, codes (2 decimals).
        criterion: String,
        /// Best criterion, codes (2 decimals).
        best: String,
    },
    /// The refit of the selected model failed.
    #[error(transparent)]
    Refit(#[from] lsq::LsqError),
}

impl Worded for GmdhError {
    fn worded(&self, w: &dyn Wording) -> Option<String> {
        match self {
            GmdhError::NoTemperature => Some(format!(
                "the campaign has no `temp_c` column: the thermal bases and {} need the temperature",
                w.name(Setting::SplitTemp)
            )),
            GmdhError::Blind { channel, split, why, selected, dropped, loo_min } => {
                let lead =
                    split.as_ref().map(|s| format!("{} {s} ", w.name(Setting::Split))).unwrap_or_default();
                let remedy = match loo_min {
                    None => "add positions".to_string(),
                    Some(m) => format!(
                        "use {} (leave-one-out: no split, {m} positions or more), or more positions",
                        w.name(Setting::CriterionLoo)
                    ),
                };
                Some(format!("channel {channel}: {lead}{why}, so the selection {selected} would drop {dropped}: {remedy}"))
            }
            _ => None,
        }
    }
}

impl Classify for GmdhError {
    fn kind(&self) -> Kind {
        Kind::BadInput
    }
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
    /// Wall time of the search (statistics and scoring, not the refit), s.
    pub search_seconds: f64,
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
    /// Largest number of terms (intercept included) a candidate may have.
    pub max_terms: usize,
}

impl Settings {
    /// The paper's selection: its 11 models, the regularity criterion, the alternate split, a
    /// 1-code tolerance (what `demo`, the certificate and the uncertainty budget run).
    pub fn paper() -> Settings {
        Settings {
            basis: accelcal_shared::Basis::Paper,
            criterion: Criterion::Regularity,
            split: Split::Alternate,
            tolerance: 1.0,
            max_terms: accelcal_shared::N_BASIS,
        }
    }
}

/// The scaled, centred problem of one channel: regressors over the basis columns scaled to unit
/// weighted RMS, the dwell means centred on their weighted mean (the intercept is in every model,
/// so centring changes no residual), and the statistics of A, B and A∪B.
pub struct Prepared {
    /// Basis indices of the columns (column 0 is the intercept).
    pub cols: Vec<usize>,
    /// Statistics for the engine.
    pub problem: engine::Problem,
    /// Positions in A and in B.
    pub parts: [usize; 2],
    /// What it was prepared for.
    pub settings: Settings,
}

impl Prepared {
    /// Prepares one channel for `settings` on positions `pos`.
    pub fn new(pos: &Positions, ch: &ChannelStats, settings: &Settings) -> Result<Prepared, GmdhError> {
        let n = pos.len();
        if settings.basis.is_thermal() && pos.temp_c.is_none() {
            return Err(GmdhError::NoTemperature);
        }
        let all: Vec<usize> = (0..n).collect();
        // Leave-one-out fits on all positions but one: no split.
        let (ia, ib) = match settings.criterion {
            Criterion::Loo => (all.clone(), Vec::new()),
            _ => settings.split.parts_of(pos)?,
        };
        if ia.is_empty() {
            return Err(GmdhError::EmptyPart('A', n));
        }
        if ib.is_empty() && settings.criterion != Criterion::Loo {
            return Err(GmdhError::EmptyPart('B', n));
        }
        let cols: Vec<usize> = settings.basis.full().indices().collect();
        let m = cols.len();
        let wsum: f64 = pos.weight.iter().sum();
        let mut z = vec![0.0; n * m];
        for (c, &bi) in cols.iter().enumerate() {
            let t = accelcal_shared::BASIS[bi];
            let mut ss = 0.0;
            for p in 0..n {
                let v = t.eval(pos.x(p));
                z[p * m + c] = v;
                ss += pos.weight[p] * v * v;
            }
            let s = (ss / wsum).sqrt();
            let s = if s > 0.0 { s } else { 1.0 };
            for p in 0..n {
                z[p * m + c] /= s;
            }
        }
        let ymean = (0..n).map(|p| pos.weight[p] * ch.mean[p]).sum::<f64>() / wsum;
        let y: Vec<f64> = ch.mean.iter().map(|v| v - ymean).collect();
        let kind = match settings.criterion {
            Criterion::Regularity => engine::Kind::Regularity,
            Criterion::Symmetric => engine::Kind::Symmetric,
            Criterion::Rss => engine::Kind::Rss,
            Criterion::Loo => engine::Kind::Loo,
        };
        let problem = engine::Problem {
            m,
            a: engine::Stats::new(&z, m, &y, &pos.weight, &ia),
            b: engine::Stats::new(&z, m, &y, &pos.weight, &ib),
            ab: engine::Stats::new(&z, m, &y, &pos.weight, &all),
            kind,
            rows: engine::Rows { z, y, w: pos.weight.clone() },
        };
        Ok(Prepared { cols, problem, parts: [ia.len(), ib.len()], settings: *settings })
    }

    /// The columns of the terms of `s`, which lie in the basis, in order (column 0 first).
    pub fn columns(&self, s: Structure) -> Vec<usize> {
        s.indices().map(|bi| self.cols.iter().position(|&c| c == bi).expect("term in the basis")).collect()
    }

    /// Scores every candidate of the basis with at most `max_terms` terms, in enumeration order.
    pub fn score(&self, basis: Basis, max_terms: usize, progress: &(dyn Fn(u64) + Sync)) -> Vec<Candidate> {
        let to_opt = |v: f64| if v.is_nan() { None } else { Some(v) };
        match basis {
            Basis::Paper => {
                let models: Vec<Structure> =
                    PAPER_MODELS.iter().copied().filter(|s| s.len() <= max_terms).collect();
                let lists: Vec<Vec<usize>> = models.iter().map(|&s| self.columns(s)).collect();
                let v = engine::listed(&self.problem, &lists);
                progress(models.len() as u64);
                models
                    .into_iter()
                    .zip(v)
                    .map(|(structure, v)| Candidate { structure, criterion: to_opt(v) })
                    .collect()
            }
            _ => {
                let v = engine::exhaustive(&self.problem, max_terms, progress);
                // An indexed parallel map collects straight into the result; the (rare) capped
                // run drops its excluded candidates afterwards.
                let mut out: Vec<Candidate> = v
                    .par_iter()
                    .enumerate()
                    .map(|(n, &x)| Candidate { structure: basis.candidate(n), criterion: to_opt(x) })
                    .collect();
                if v.contains(&engine::EXCLUDED) {
                    let mut scored = v.iter().map(|&x| x != engine::EXCLUDED);
                    out.retain(|_| scored.next() == Some(true));
                }
                out
            }
        }
    }
}

/// Picks the simplest candidate within `tolerance` of the best; ties in size go to the smaller
/// criterion, then to the lower canonical mask (subsets spanning the same space tie exactly).
/// Returns the index and the best criterion.
pub fn choose(candidates: &[Candidate], tolerance: f64) -> Option<(usize, f64)> {
    let best = candidates.iter().filter_map(|c| c.criterion).fold(f64::INFINITY, f64::min);
    if !best.is_finite() {
        return None;
    }
    let rel = |a: f64, b: f64| (a - b).abs() <= 1e-9 * a.abs().max(b.abs());
    let i = candidates
        .iter()
        .enumerate()
        .filter_map(|(i, c)| c.criterion.filter(|&v| v <= best + tolerance).map(|v| (i, c.structure, v)))
        .min_by(|x, y| {
            x.1.len().cmp(&y.1.len()).then(if rel(x.2, y.2) {
                x.1.mask().cmp(&y.1.mask())
            } else {
                x.2.total_cmp(&y.2)
            })
        })
        .map(|x| x.0)?;
    Some((i, best))
}

/// Scores every candidate of `settings.basis` on one channel and selects the model.
/// `progress` is called with the number of candidates finished since its last call.
pub fn select(
    pos: &Positions,
    ch: &ChannelStats,
    settings: &Settings,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<Selection, GmdhError> {
    let t0 = std::time::Instant::now();
    let prepared = Prepared::new(pos, ch, settings)?;
    let candidates = prepared.score(settings.basis, settings.max_terms, progress);
    let search_seconds = t0.elapsed().as_secs_f64();
    let (selected, best) = choose(&candidates, settings.tolerance).ok_or(GmdhError::NothingIdentifiable)?;
    guard::check(&prepared, pos, ch, candidates[selected].structure)?;
    let fit = lsq::fit(pos, ch, candidates[selected].structure, None)?;
    Ok(Selection { channel: ch.name.clone(), candidates, selected, best, fit, search_seconds })
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
        let temp: Split = "temp:50,-10".parse().unwrap();
        assert_eq!(temp.to_string(), "temp:50,-10");
        assert!("temp:".parse::<Split>().is_err() && "temp:1,x".parse::<Split>().is_err());
        let mut pos = Positions::from_dwells(Vec::new(), 9.81);
        assert!(matches!(temp.parts_of(&pos), Err(GmdhError::NoTemperature)));
        pos.temp_c = Some(vec![-9.0, 10.0, 30.0, 48.0, 52.4, 53.0]);
        assert_eq!(temp.parts_of(&pos).unwrap(), (vec![1, 2, 5], vec![0, 3, 4]));
    }
}
