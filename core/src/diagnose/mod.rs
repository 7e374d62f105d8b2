//! Sim-to-real gap diagnosis: where a campaign departs from its linear-sensor simulation, and
//! which unmodelled effect explains the departure, checked on withheld data.
//!
//! The data are reduced to *bins* ([`bins`], built row by row, so a campaign file streams): each
//! dwell is cut into up to [`BINS`] consecutive runs of samples, and every bin keeps its mean code
//! per channel, its mean time, temperature and the within-bin scatter (which estimates the white
//! noise, that no model can change). Every model
//! here (the baseline and the effects) is linear in its parameters on the bins, so fitting is a
//! weighted least squares with weights `n/σ²`. [`gap`] localises the residual of the baseline,
//! [`attribution`] fits effects on one half of the positions and scores them on the other,
//! [`selection`] chooses the set that explains the gap, [`structure`] checks what each named
//! effect left (partial effects, where the rest lies, confounded effects), and [`bench`] runs
//! the blind benchmark.
//!
//! [`periodic`] is the periodogram of the dwell residuals over time and their correlation across
//! channels. This file holds what they all use (the data, [`wls`], [`solve_normal`], [`zscore`],
//! [`NOISE_Z`]) and [`thermal_remedy`] (a found `temperature` effect turned into the baseline
//! terms `fit` would use). Imports go one way: `gap`, `selection`, `structure` and `bench` →
//! `attribution`, never back; the benchmark's effects outside the library live in `bench` only,
//! and neither the registry (`crate::effects`) nor the diagnosis names them.

pub mod attribution;
pub mod bench;
pub mod bins;
pub mod gap;
pub mod periodic;
pub mod selection;
pub mod structure;

use std::collections::BTreeMap;

use accelcal_shared::Structure;
use nalgebra::{DMatrix, DVector};

use crate::campaign::Campaign;
use crate::error::{Classify, Kind};
pub use bins::{Bin, Binned, BINS};

/// The z-score of the χ² below which a residual is consistent with the noise.
pub const NOISE_Z: f64 = 4.0;

pub fn zscore(chi2: f64, dof: f64) -> f64 {
    (chi2 - dof) / (2.0 * dof.max(1.0)).sqrt()
}

/// Minimum of `g` on `[lo, hi]` by golden-section search, `iterations` steps; the midpoint of the
/// last bracket.
pub fn golden_min(g: &dyn Fn(f64) -> f64, mut lo: f64, mut hi: f64, iterations: usize) -> f64 {
    let k = (5f64.sqrt() - 1.0) / 2.0;
    let (mut x1, mut x2) = (hi - k * (hi - lo), lo + k * (hi - lo));
    let (mut g1, mut g2) = (g(x1), g(x2));
    for _ in 0..iterations {
        if g1 < g2 {
            hi = x2;
            (x2, g2) = (x1, g1);
            x1 = hi - k * (hi - lo);
            g1 = g(x1);
        } else {
            lo = x1;
            (x1, g1) = (x2, g2);
            x2 = lo + k * (hi - lo);
            g2 = g(x2);
        }
    }
    (lo + hi) / 2.0
}

/// Range of settling time constants searched, s: from the lower bound to the larger of the upper
/// bound and the longest dwell ([`Data::tau_range`]).
pub const TAU_RANGE: (f64, f64) = (0.03, 2.0);

/// Why a campaign cannot be diagnosed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum DiagnoseError {
    /// Too few positions for fitting on one half and checking on the other.
    #[error("{positions} positions: the diagnosis needs at least {need} (twice the baseline's terms)")]
    TooFewPositions {
        /// Positions in the campaign.
        positions: usize,
        /// Positions needed.
        need: usize,
    },
    /// No dwell has two samples, so the noise cannot be estimated.
    #[error("every dwell has a single sample: the white noise cannot be estimated")]
    NoNoiseEstimate,
    /// The baseline cannot be fitted.
    #[error("the baseline cannot be fitted on this campaign")]
    Unfittable,
    /// A baseline term in `t` on a campaign without `temp_c`.
    #[error("baseline term `{0}` needs the temperature, and the campaign has no `temp_c` column")]
    NoTemperature(String),
}

impl Classify for DiagnoseError {
    fn kind(&self) -> Kind {
        Kind::BadInput
    }
}

/// A campaign reduced to bins, with what every model needs.
#[derive(Clone, Debug)]
pub struct Data {
    /// Channel names.
    pub channels: Vec<String>,
    /// Gravity, m/s².
    pub g: f64,
    /// Commanded angles of each position, degrees.
    pub angles: Vec<(f64, f64)>,
    /// Imposed acceleration of each position, m/s².
    pub accel: Vec<[f64; 3]>,
    /// Mean time of each position, s.
    pub t_pos: Vec<f64>,
    /// The bins.
    pub bins: Vec<Bin>,
    /// Mean code of each bin, per channel: `mean[channel][bin]`.
    pub mean: Vec<Vec<f64>>,
    /// White noise per sample of each channel (pooled within-bin), codes.
    pub sigma: Vec<f64>,
    /// Mean temperature of each bin, °C, when the campaign has `temp_c`.
    pub temp: Option<Vec<f64>>,
    /// Model-4 sensitivities of each channel to ax, ay, az (codes per m/s²), fitted on all data.
    pub k: Vec<[f64; 3]>,
    /// Each channel's sensitive axis (largest |k|).
    pub own: Vec<usize>,
    /// Change of each channel's sensitive-axis input since the previous position: `step[ch][pos]`.
    pub step: Vec<Vec<f64>>,
}

impl Data {
    /// mg per code of channel `ch`: `1000 / (|k_own| · g₀)` with g₀ = 9.80665 m/s² (a code is
    /// `1/|k_own|` m/s² on the sensitive axis); NaN when the channel has no sensitivity.
    pub fn mg_per_code(&self, ch: usize) -> f64 {
        let k = self.k[ch][self.own[ch]].abs();
        if k > 0.0 && k.is_finite() {
            1000.0 / (k * accelcal_shared::G_STANDARD)
        } else {
            f64::NAN
        }
    }

    /// Reduces an in-memory campaign to bins.
    pub fn new(c: &Campaign, g: f64) -> Result<Data, DiagnoseError> {
        Data::from_binned(&Binned::from_campaign(c), g)
    }

    /// The data of a campaign already reduced to bins ([`Binned::read`] streams a file).
    pub fn from_binned(b: &Binned, g: f64) -> Result<Data, DiagnoseError> {
        let nch = b.channels.len();
        let dof: f64 = b.bins.iter().map(|bin| bin.n - 1.0).sum();
        if !(dof > 0.0) {
            return Err(DiagnoseError::NoNoiseEstimate);
        }
        let mut d = Data {
            channels: b.channels.clone(),
            g,
            angles: b.angles.clone(),
            accel: b.angles.iter().map(|&(a, be)| accelcal_shared::gravity(a, be, g)).collect(),
            t_pos: b.t_pos.clone(),
            bins: b.bins.clone(),
            mean: b.mean.clone(),
            // A floor at the quantisation noise of one code keeps noise-free data usable.
            sigma: b.within.iter().map(|s| (s / dof).sqrt().max(1.0 / 12f64.sqrt())).collect(),
            temp: b.temp.clone(),
            k: Vec::new(),
            own: Vec::new(),
            step: Vec::new(),
        };
        for ch in 0..nch {
            let k = d.linear_k(ch);
            let own = (0..3).max_by(|&i, &j| k[i].abs().total_cmp(&k[j].abs())).unwrap_or(0);
            let step = (0..d.npos())
                .map(|p| if p == 0 { 0.0 } else { d.accel[p][own] - d.accel[p - 1][own] })
                .collect();
            d.k.push(k);
            d.own.push(own);
            d.step.push(step);
        }
        Ok(d)
    }

    /// The same bins with other codes: per-bin means `mean[channel][bin]` and pooled within-bin
    /// sums of squares `within[channel]` (the simulated twin).
    pub fn with_codes(&self, mean: Vec<Vec<f64>>, within: Vec<f64>) -> Result<Data, DiagnoseError> {
        let b = Binned {
            channels: self.channels.clone(),
            angles: self.angles.clone(),
            t_pos: self.t_pos.clone(),
            bins: self.bins.clone(),
            mean,
            within,
            temp: self.temp.clone(),
            warnings: Vec::new(),
        };
        Data::from_binned(&b, self.g)
    }

    /// The settling time constants searched on these data, s: [`TAU_RANGE`], its upper end raised
    /// to the longest dwell (a relaxation as slow as the hold is a transient of the hold too).
    pub fn tau_range(&self) -> (f64, f64) {
        let longest = self.bins.iter().map(|b| b.span.1).fold(0.0, f64::max);
        (TAU_RANGE.0, TAU_RANGE.1.max(longest))
    }

    /// Number of positions.
    pub fn npos(&self) -> usize {
        self.accel.len()
    }

    /// Number of channels.
    pub fn nch(&self) -> usize {
        self.channels.len()
    }

    /// Weight `n/σ²` of bin `row` of channel `ch`.
    pub fn weight(&self, ch: usize, row: usize) -> f64 {
        self.bins[row].n / (self.sigma[ch] * self.sigma[ch])
    }

    /// Per-position noise of a channel: σ over the square root of the dwell's samples, codes.
    pub fn sigma_pos(&self, ch: usize, p: usize) -> f64 {
        let n: f64 = self.bins.iter().filter(|b| b.pos == p).map(|b| b.n).sum();
        self.sigma[ch] / n.sqrt()
    }

    /// Model-4 sensitivities of one channel from an unweighted fit of the bins.
    fn linear_k(&self, ch: usize) -> [f64; 3] {
        let x = DMatrix::from_fn(self.bins.len(), 4, |r, c| {
            if c == 0 {
                1.0
            } else {
                self.accel[self.bins[r].pos][c - 1]
            }
        });
        let w = vec![1.0; self.bins.len()];
        let rows: Vec<usize> = (0..self.bins.len()).collect();
        match wls(&x, &self.mean[ch], &w, &rows) {
            Some(f) => [f.beta[1], f.beta[2], f.beta[3]],
            None => [0.0; 3],
        }
    }

    /// Mean of `exp(−t_in_dwell/τ)` over the samples of each bin (see [`Bin::settle`]).
    pub fn settle(&self, tau: f64) -> Vec<f64> {
        self.bins.iter().map(|b| b.settle(tau)).collect()
    }

    /// Dwell-mean of per-bin values (weighted by samples) for every position.
    pub fn dwell_means(&self, v: &[f64]) -> Vec<f64> {
        let mut s = vec![0.0; self.npos()];
        let mut n = vec![0.0; self.npos()];
        for (b, x) in self.bins.iter().zip(v) {
            s[b.pos] += b.n * x;
            n[b.pos] += b.n;
        }
        s.iter().zip(&n).map(|(s, n)| s / n).collect()
    }

    /// Checks that the baseline can be fitted on half the positions.
    pub fn check(&self, baseline: Structure) -> Result<(), DiagnoseError> {
        if let Some(t) = baseline.terms().find(|t| t.is_thermal()).filter(|_| self.temp.is_none()) {
            return Err(DiagnoseError::NoTemperature(t.to_string()));
        }
        let need = 2 * baseline.terms().count() + 2;
        if self.npos() < need {
            return Err(DiagnoseError::TooFewPositions { positions: self.npos(), need });
        }
        Ok(())
    }
}

/// A weighted least-squares solution.
#[derive(Clone, Debug)]
pub struct Wls {
    /// Coefficients.
    pub beta: Vec<f64>,
    /// Covariance of the coefficients for unit-variance weighted residuals.
    pub cov: DMatrix<f64>,
    /// Weighted residual sum of squares on the rows used.
    pub wsse: f64,
}

/// Solves `min Σ w·(y − X·β)²` over `rows` through the normal equations with the columns scaled
/// to unit diagonal and a pseudo-inverse (directions with eigenvalue below 1e-12 of the largest
/// are dropped, so a confounded column gets a zero coefficient rather than a wild one).
pub fn wls(x: &DMatrix<f64>, y: &[f64], w: &[f64], rows: &[usize]) -> Option<Wls> {
    let k = x.ncols();
    let xs = DMatrix::from_fn(rows.len(), k, |r, c| w[rows[r]].sqrt() * x[(rows[r], c)]);
    let ys = DVector::from_fn(rows.len(), |r, _| w[rows[r]].sqrt() * y[rows[r]]);
    let (beta_v, cov) = solve_normal(&(xs.transpose() * &xs), &(xs.transpose() * &ys))?;
    let resid = &ys - &xs * &beta_v;
    Some(Wls { beta: beta_v.iter().copied().collect(), cov, wsse: resid.norm_squared() })
}

/// Solves the normal equations `gram·β = rhs` with the columns scaled to unit diagonal and a
/// pseudo-inverse (eigenvalues below 1e-12 of the largest dropped); returns β and the inverse.
pub fn solve_normal(gram: &DMatrix<f64>, rhs: &DVector<f64>) -> Option<(DVector<f64>, DMatrix<f64>)> {
    let k = gram.ncols();
    let d: Vec<f64> =
        (0..k).map(|i| gram[(i, i)].max(0.0).sqrt()).map(|v| if v > 0.0 { v } else { 1.0 }).collect();
    let gs = DMatrix::from_fn(k, k, |i, j| gram[(i, j)] / (d[i] * d[j]));
    let eig = gs.symmetric_eigen();
    let lmax = eig.eigenvalues.iter().cloned().fold(0.0, f64::max);
    if !(lmax > 0.0) {
        return None;
    }
    let mut inv = DMatrix::zeros(k, k);
    for (i, &l) in eig.eigenvalues.iter().enumerate() {
        if l > 1e-12 * lmax {
            let v = eig.eigenvectors.column(i);
            inv += (v * v.transpose()) / l;
        }
    }
    let cov = DMatrix::from_fn(k, k, |i, j| inv[(i, j)] / (d[i] * d[j]));
    let beta = &cov * rhs;
    Some((beta, cov))
}

/// An effect the diagnosis found.
#[derive(Clone, Debug, serde::Serialize)]
pub struct FoundEffect {
    /// Effect name (as in `simulate --effect`).
    pub name: String,
    /// Channels it shows on (a parameter at least 5 standard errors from zero; every channel for
    /// the effects of the head).
    pub channels: Vec<String>,
    /// Parameters per channel (`all` for those shared by the channels), fitted on all the data.
    pub parameters: BTreeMap<String, BTreeMap<String, attribution::Estimate>>,
    /// RMS of the withheld bin residuals before adding the effect, codes.
    pub heldout_rms_before: f64,
    /// The same after adding it, codes.
    pub heldout_rms_after: f64,
    /// Drop of the held-out χ² it brought.
    pub heldout_chi2_drop: f64,
    /// Whether the effect is partial: structure of its kind is left in the residual (see
    /// [`structure`]); the rest is reported as unexplained.
    pub partial: bool,
}

/// The attribution's result.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Attribution {
    /// The effects kept, in the order of selection.
    pub effects: Vec<FoundEffect>,
    /// RMS of the residual left beyond the noise once the effects are in (0 when the rest is
    /// consistent with the noise), codes.
    pub unexplained_rms: f64,
    /// z of the final χ² (below 4: consistent with the noise).
    pub final_z: f64,
    /// Every round of the greedy selection.
    pub rounds: Vec<selection::Round>,
    /// Fraction of the baseline's held-out excess χ² the kept effects remove together.
    pub joint_explained: f64,
    /// Effects kept but not named (they explain too little together, or their signature is
    /// missing from the withheld data).
    pub not_named: Vec<&'static str>,
    /// Whether the effects came from the joint search of pairs and triples (the greedy path
    /// stalled).
    pub from_joint_search: bool,
    /// The held-out signature of every effect kept.
    pub signatures: Vec<attribution::Signature>,
    /// What each named effect left of its kind.
    pub leftovers: Vec<structure::Leftover>,
    /// Where the residual of the final model lies, per channel.
    pub residual_where: Vec<structure::Where>,
    /// Effects the campaign cannot tell apart.
    pub confounds: Vec<structure::Confound>,
}

/// The whole diagnosis: the gap and its attribution.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Report {
    /// Effects found (the interface).
    pub effects: Vec<FoundEffect>,
    /// Residual no effect explains, codes.
    pub unexplained_rms: f64,
    /// Baseline terms.
    pub baseline: String,
    /// The localised gap of the baseline.
    pub gap: gap::Gap,
    /// Details of the attribution.
    pub attribution: Attribution,
    /// When `temperature` is found: the baseline with the thermal terms its parameters call for
    /// (what `fit --terms` and a thermal record would use; `null` otherwise).
    pub remedy: Option<String>,
}

/// Significance of a temperature parameter for the remedy, in standard errors.
pub const REMEDY_Z: f64 = 3.0;

/// The baseline `base` with the thermal terms that a found `temperature` effect calls for: `t`
/// where a channel's bias coefficient is beyond [`REMEDY_Z`] standard errors, and the own-axis
/// `·t` term of every channel whose scale coefficient is (one record holds one structure, so the
/// union over the channels). `None` when no effect is `temperature` or nothing is significant.
pub fn thermal_remedy(effects: &[FoundEffect], d: &Data, base: Structure) -> Option<Structure> {
    let e = effects.iter().find(|e| e.name == crate::effects::EffectKind::Temperature.name())?;
    let sig = |v: &attribution::Estimate| v.sd.is_some_and(|sd| v.value.abs() > REMEDY_Z * sd);
    let mut mask = base.mask();
    for (ch, name) in d.channels.iter().enumerate() {
        let Some(ps) = e.parameters.get(name) else { continue };
        if ps.get("bias").is_some_and(sig) {
            mask |= 1 << accelcal_shared::terms::T_INDEX;
        }
        if ps.get("scale").is_some_and(sig) {
            mask |= 1 << (accelcal_shared::terms::T_INDEX + 2 + d.own[ch]);
        }
    }
    let s = Structure::from_mask(mask);
    (s != base).then_some(s)
}

/// Selects and fits the effects on prepared data.
pub fn attribute(d: &Data, base: Structure) -> Attribution {
    let sel = selection::select(d, base);
    let set = sel.set.clone();
    let ff = attribution::full_fit(d, base, &set);
    let (leftovers, residual_where) = structure::leftovers(d, base, &set);
    let mut effects = Vec::new();
    for (i, &c) in set.iter().enumerate() {
        let (before, after) = sel.steps[i];
        let parameters: BTreeMap<String, BTreeMap<String, attribution::Estimate>> = ff
            .as_ref()
            .and_then(|f| f.params.get(&c))
            .map(|m| m.iter().map(|(k, v)| (k.clone(), v.clone())).collect())
            .unwrap_or_default();
        let strong = |m: &BTreeMap<String, attribution::Estimate>| {
            m.values().any(|e| e.sd.is_some_and(|sd| sd > 0.0 && (e.value / sd).abs() >= 5.0))
        };
        let mut channels: Vec<String> =
            d.channels.iter().filter(|ch| parameters.get(*ch).is_some_and(strong)).cloned().collect();
        if channels.is_empty() {
            channels = d.channels.clone();
        }
        effects.push(FoundEffect {
            name: c.name().to_string(),
            channels,
            parameters,
            heldout_rms_before: before.rms,
            heldout_rms_after: after.rms,
            heldout_chi2_drop: before.chi2 - after.chi2,
            partial: leftovers.get(i).is_some_and(|l| l.partial),
        });
    }
    let (unexplained_rms, final_z) = match &ff {
        Some(f) => {
            let z = zscore(f.chi2, f.dof);
            let nb = d.bins.len();
            let ss: f64 = f.resid.iter().map(|r| r * r).sum();
            let noise: f64 = (0..f.resid.len()).map(|i| 1.0 / d.weight(i / nb, i % nb)).sum();
            let u = if z >= NOISE_Z { ((ss - noise).max(0.0) / f.resid.len() as f64).sqrt() } else { 0.0 };
            (u, z)
        }
        None => (f64::NAN, f64::NAN),
    };
    Attribution {
        effects,
        unexplained_rms,
        final_z,
        rounds: sel.rounds,
        joint_explained: sel.joint_explained,
        not_named: sel.not_named,
        from_joint_search: sel.from_joint_search,
        signatures: sel.signatures,
        leftovers,
        residual_where,
        confounds: structure::confounds(d),
    }
}

/// Diagnoses an in-memory campaign against the baseline `base`.
pub fn diagnose(c: &Campaign, g: f64, base: Structure) -> Result<Report, DiagnoseError> {
    diagnose_data(&Data::new(c, g)?, base)
}

/// Diagnoses a campaign reduced to bins against the baseline `base`.
pub fn diagnose_data(d: &Data, base: Structure) -> Result<Report, DiagnoseError> {
    d.check(base)?;
    let gap = gap::localise(d, base).ok_or(DiagnoseError::Unfittable)?;
    let attribution = attribute(d, base);
    Ok(Report {
        effects: attribution.effects.clone(),
        unexplained_rms: attribution.unexplained_rms,
        baseline: base.to_string(),
        remedy: thermal_remedy(&attribution.effects, d, base).map(|s| s.to_string()),
        gap,
        attribution,
    })
}
