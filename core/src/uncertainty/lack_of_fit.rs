//! Model 4's lack of fit: what the linear model leaves of a channel's output at every
//! orientation, measured from the campaign, and GMDH's criterion gap that the paper's selection
//! tolerates.
//!
//! The measure: each channel's dwell means fitted with the quadratic model on the sphere (the
//! nine functions `1, ux, uy, uz, ux², uy², ux·uy, ux·uz, uy·uz` of `u = a/g`; on the sphere
//! `uz² = 1 − ux² − uy²`, so these span every polynomial of degree ≤ 2 and every one of the
//! paper's 11 models). Model 4, fitted on the same positions, absorbs part of the quadratic part
//! `q` (its projection through the plan's `A`); what it leaves at an orientation `a` is
//! `e(a) = ψ(a)·β` with `ψ(a) = q(a) − (A·Q)ᵀ·row(a)`, linear in the quadratic coefficients β.
//! Its mean square over the sphere is `βᵀMβ` with `M` the sphere's mean of `ψψᵀ`.
//!
//! The estimate `β̂` carries the dwell scatter: `E[β̂ᵀMβ̂] = βᵀMβ + tr(MΣ)`, Σ the covariance of
//! β̂ from the samples' noise within the dwells and the head's stated errors (or, for dwells of
//! one sample, from the quadratic fit's own residuals). Noise alone makes `β̂ᵀMβ̂` a weighted χ² with mean
//! `tr(MΣ)` and standard deviation `√(2·tr((MΣ)²))`; the lack of fit stated is what is left above
//! the value noise alone stays below with the probability [`LEVEL`] ([`noise_limit`]: the
//! quantile of Satterthwaite's `c·χ²_ν` of that mean and spread), so that a linear unit's
//! scatter is not counted a second time (the dwell scatter already carries it); the estimate of
//! β is shrunk by the same factor.
//! The error at an orientation nobody chose is then known as a distribution over the sphere, and
//! the standard uncertainty taken is half its 95th percentile (a bounded quadratic form: twice
//! its RMS would cover more than 95 %). A lack of fit below the floor that the plan's scatter
//! sets is not seen, and the budget states that floor.

use accelcal_shared::terms::MODEL_4;
use nalgebra::{DMatrix, DVector, SMatrix, SVector};

use crate::positions::{ChannelStats, Positions};

/// The quadratic functions on the sphere.
pub const QUADRATIC_TERMS: usize = 9;

/// The probability with which noise alone stays below the limit taken out of a sum of squares
/// as its share ([`noise_limit`]): Φ(2), a Gaussian's mean and two standard deviations, so that
/// a linear unit is given a lack of fit on 2.3 % of its channels whatever the plan.
pub const LEVEL: f64 = 0.977_249_868_051_820_8;

/// The value that a weighted sum of squares of independent standard Gaussians, `Σ λᵢ·zᵢ²` with
/// `mean = Σ λᵢ` and `square = Σ λᵢ²` (`tr C` and `tr C²` of its covariance), stays below with
/// the probability [`LEVEL`]: the quantile of Satterthwaite's `c·χ²_ν` of the same mean and
/// variance, `c = square / mean`, `ν = mean² / square` (Satterthwaite 1946; Box 1954).
///
/// With few effective degrees of freedom (a plan of 16 positions gives the quadratic terms 1 to
/// 3) the mean and two standard deviations, `mean + 2·√(2·square)`, would be passed by noise
/// alone on 4 to 5 % of the channels instead of 2.3 %; with many, the two agree. 0 for a sum
/// that carries no noise.
pub fn noise_limit(mean: f64, square: f64) -> f64 {
    use statrs::distribution::{ChiSquared, ContinuousCDF};
    if !(mean > 0.0 && square > 0.0 && mean.is_finite() && square.is_finite()) {
        return mean.max(0.0);
    }
    let c = square / mean;
    let nu = mean * mean / square;
    match ChiSquared::new(nu) {
        Ok(chi) => c * chi.inverse_cdf(LEVEL),
        Err(_) => mean + 2.0 * (2.0 * square).sqrt(),
    }
}

/// Positions the measure needs: the quadratic model and three degrees of freedom for the scatter.
pub const MIN_POSITIONS: usize = QUADRATIC_TERMS + 3;

type Mat9 = SMatrix<f64, QUADRATIC_TERMS, QUADRATIC_TERMS>;
type Vec9 = SVector<f64, QUADRATIC_TERMS>;

/// The quadratic model's regressors at an acceleration (m/s²) on a sphere of radius `g`.
fn quadratic(a: [f64; 3], g: f64) -> Vec9 {
    let [x, y, z] = a.map(|v| v / g);
    Vec9::from([1.0, x, y, z, x * x, y * y, x * y, x * z, y * z])
}

/// Model 4's lack of fit on each channel of a triad, as measured from its campaign.
#[derive(Clone, Debug, PartialEq)]
pub struct Measured {
    /// Per channel (in the order of the stats given), the standard uncertainty the budget takes,
    /// codes: half the 95th percentile of |model 4's error| over the sphere. Its error is a
    /// fixed quadratic form, bounded, not Gaussian: twice its RMS would cover more than 95 % of
    /// the orientations (all of them for `ux·uy`), half its 95th percentile makes U's k = 2
    /// cover 95 % where it dominates.
    pub u_codes: Vec<f64>,
    /// Per channel, the RMS over the sphere of model 4's error, codes (0 where the quadratic part
    /// is within the scatter).
    pub rms_codes: Vec<f64>,
    /// Per channel, the RMS a lack of fit must exceed to be seen on this plan with this scatter,
    /// codes: `√(noise_limit(tr(MΣ), tr((MΣ)²)))`.
    pub floor_codes: Vec<f64>,
    /// Per channel, the part of model 4's residuals at the positions that the stated lack of fit
    /// explains (sum of squares, codes²): taken out of the dwell scatter.
    pub explained_ss: Vec<f64>,
}

/// What is known of the dwell means' scatter besides their residuals.
#[derive(Clone, Copy, Debug)]
pub struct Known<'a> {
    /// Per channel (in the order of the stats), per position: the variance of the dwell mean
    /// that the samples' noise within the dwells ([`super::scatter::Within`]) and the head's
    /// stated angle errors give it, codes². Independent across positions.
    pub mean_var: &'a [Vec<f64>],
}

/// Why the lack of fit could not be measured.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum NotMeasured {
    /// Too few positions for the quadratic model and its scatter.
    TooFewPositions(usize),
    /// The positions do not determine the quadratic model (too few distinct orientations).
    Undetermined,
}

impl std::fmt::Display for NotMeasured {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            NotMeasured::TooFewPositions(n) => write!(
                f,
                "the plan's {n} positions are too few for the quadratic model on the sphere, which needs {MIN_POSITIONS}"
            ),
            NotMeasured::Undetermined => {
                f.write_str("the plan's orientations do not determine the quadratic model on the sphere")
            }
        }
    }
}

/// Measures model 4's lack of fit on every channel of `stats` at the positions `pos`, with `a4`
/// model 4's fit operator `(XᵀWX)⁻¹XᵀW` (4 × n) and `resid_maker` its `I − X·A` on the same
/// positions; `sphere` are the orientations (m/s², radius g) the error is taken over.
/// `stated[c]` are the outputs (n × k codes, k ≥ 0) that one sigma of each independent error
/// stated for the head (its stage rotations) leaves on channel `c`: the head's, not the unit's,
/// counted by their own contributor, so what they put into the quadratic terms is expected of a
/// linear unit too and taken out with the scatter's share.
///
/// The dwell means' own scatter is estimated from the quadratic fit's residuals (n − 9 degrees
/// of freedom). With `known` (the samples' noise within the dwells and the head's stated angle
/// errors) it is the larger of that and what they predict: on few positions the residuals alone
/// understate the noise often enough to call a linear unit's scatter a lack of fit, and the
/// residuals still speak where something the stated values miss (a head worse than its
/// certificate) scatters the dwell means more.
pub fn measure(
    pos: &Positions,
    stats: &[ChannelStats],
    a4: &DMatrix<f64>,
    resid_maker: &DMatrix<f64>,
    sphere: &[[f64; 3]],
    stated: &[DMatrix<f64>],
    known: Option<Known<'_>>,
) -> Result<Measured, NotMeasured> {
    let n = pos.len();
    if n < MIN_POSITIONS {
        return Err(NotMeasured::TooFewPositions(n));
    }
    let g = pos.g;
    let xq = DMatrix::from_fn(n, QUADRATIC_TERMS, |i, t| quadratic(pos.accel[i], g)[t]);
    let xtw = DMatrix::from_fn(QUADRATIC_TERMS, n, |t, i| xq[(i, t)] * pos.weight[i]);
    let normal = &xtw * &xq;
    // Scaled regressors are of order 1: a tiny singular value is a plan that does not fix them.
    let sv = normal.clone().svd(false, false).singular_values;
    let (lo, hi) = sv.iter().fold((f64::INFINITY, 0.0f64), |(l, h), &s| (l.min(s), h.max(s)));
    if !(lo > hi * 1e-10) {
        return Err(NotMeasured::Undetermined);
    }
    let aq = normal.try_inverse().ok_or(NotMeasured::Undetermined)? * &xtw;
    // What model 4 absorbs of each quadratic function at the plan's positions, and what it
    // leaves of each at the orientations of the sphere.
    let absorbed = a4 * &xq;
    let psi: Vec<Vec9> = sphere
        .iter()
        .map(|&a| {
            let r4 = nalgebra::Vector4::new(1.0, a[0], a[1], a[2]);
            quadratic(a, g) - Vec9::from_iterator((absorbed.transpose() * r4).iter().copied())
        })
        .collect();
    let m = psi.iter().fold(Mat9::zeros(), |acc, p| acc + p * p.transpose()) / sphere.len().max(1) as f64;
    let cov_shape = Mat9::from_iterator((&aq * aq.transpose()).iter().copied());
    let dof = (n - QUADRATIC_TERMS) as f64;
    let mut out = Measured {
        u_codes: Vec::new(),
        rms_codes: Vec::new(),
        floor_codes: Vec::new(),
        explained_ss: Vec::new(),
    };
    for (c, ch) in stats.iter().enumerate() {
        let y = DVector::from_column_slice(&ch.mean);
        let beta_d = &aq * &y;
        let beta = Vec9::from_iterator(beta_d.iter().copied());
        let mut cov = cov_shape * ((&y - &xq * &beta_d).norm_squared() / dof);
        if let Some(v) = known.and_then(|k| k.mean_var.get(c)) {
            // Independent across positions: aq·diag(v)·aqᵀ.
            let predicted = Mat9::from_iterator(
                (&aq * DMatrix::from_fn(n, QUADRATIC_TERMS, |i, t| {
                    aq[(t, i)] * v.get(i).copied().unwrap_or(0.0)
                }))
                .iter()
                .copied(),
            );
            if (m * predicted).trace() > (m * cov).trace() {
                cov = predicted;
            }
        }
        if let Some(h) = stated.get(c) {
            for col in h.column_iter() {
                let b = Vec9::from_iterator((&aq * col).iter().copied());
                cov += b * b.transpose();
            }
        }
        let ms = (beta.transpose() * m * beta)[(0, 0)];
        let m_sigma = m * cov;
        let limit = noise_limit(m_sigma.trace(), (m_sigma * m_sigma).trace());
        let lof2 = (ms - limit).max(0.0);
        let shrink = if ms > 0.0 { (lof2 / ms).sqrt() } else { 0.0 };
        // The equivalent standard uncertainty: half the 95th percentile of |e| over the sphere.
        let mut abs: Vec<f64> = psi.iter().map(|p| (shrink * p.dot(&beta)).abs()).collect();
        abs.sort_by(f64::total_cmp);
        let q95 =
            abs.get(((abs.len() as f64 * 0.95).ceil() as usize).saturating_sub(1)).copied().unwrap_or(0.0);
        let at_positions = (resid_maker * (&xq * &beta_d)).norm_squared();
        out.u_codes.push(q95 / 2.0);
        out.rms_codes.push(lof2.sqrt());
        out.floor_codes.push(limit.sqrt());
        out.explained_ss.push(if ms > 0.0 { at_positions * lof2 / ms } else { 0.0 });
    }
    Ok(out)
}

/// Model 4's lack of fit on each channel (in the order of `stats`), codes: its regularity
/// criterion less the best of the paper's 11 models' (GMDH, [`crate::gmdh::Settings::paper`]),
/// 0 when model 4 is the best. A channel on which model 4 is not identifiable is refused.
pub fn criterion_gap(pos: &Positions, stats: &[ChannelStats]) -> Result<Vec<f64>, crate::gmdh::GmdhError> {
    let settings = crate::gmdh::Settings::paper();
    stats
        .iter()
        .map(|ch| {
            let prepared = crate::gmdh::Prepared::new(pos, ch, &settings)?;
            let candidates = prepared.score(settings.basis, settings.max_terms, &|_| {});
            let best = candidates.iter().filter_map(|c| c.criterion).fold(f64::INFINITY, f64::min);
            let own = candidates
                .iter()
                .find(|c| c.structure == MODEL_4)
                .and_then(|c| c.criterion)
                .ok_or(crate::gmdh::GmdhError::NothingIdentifiable)?;
            Ok((own - best).max(0.0))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_distr::{Distribution, StandardNormal};

    #[test]
    fn the_noise_limit_of_equal_weights_is_the_chi_squared_quantile() {
        // One square of weight 3: P(3·z² > x) = 2·(1 − Φ(√(x/3))).
        let normal = statrs::distribution::Normal::standard();
        let x = noise_limit(3.0, 9.0);
        let tail = 2.0 * (1.0 - statrs::distribution::ContinuousCDF::cdf(&normal, (x / 3.0).sqrt()));
        assert!((tail - (1.0 - LEVEL)).abs() < 1e-6, "{x} {tail}");
        // Four equal squares of weight 0.5: P(0.5·χ²₄ > x) = e^(−y)·(1 + y), y = x / 1.
        let y = noise_limit(2.0, 1.0);
        assert!(((-y).exp() * (1.0 + y) - (1.0 - LEVEL)).abs() < 1e-6, "{y}");
        // Many: the Gaussian's mean and two spreads, a little above for the skew.
        let (mean, square) = (10_000.0, 10_000.0);
        let l = noise_limit(mean, square);
        let gauss = mean + 2.0 * (2.0 * square).sqrt();
        assert!(l > gauss && l < gauss * 1.001, "{l} {gauss}");
        // No noise: nothing is taken.
        assert_eq!(noise_limit(0.0, 0.0), 0.0);
    }

    #[test]
    fn noise_alone_passes_the_limit_at_its_level_where_two_spreads_do_not_hold_it() {
        // A weighted χ² of few effective degrees of freedom, as the quadratic terms have on a
        // plan of 16 positions: weights 1, 0.3, 0.05.
        let lambda = [1.0, 0.3, 0.05];
        let mean: f64 = lambda.iter().sum();
        let square: f64 = lambda.iter().map(|l| l * l).sum();
        let limit = noise_limit(mean, square);
        let two_spreads = mean + 2.0 * (2.0 * square).sqrt();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let draws = 400_000;
        let (mut over_limit, mut over_spreads) = (0usize, 0usize);
        for _ in 0..draws {
            let q: f64 = lambda
                .iter()
                .map(|l| {
                    let z: f64 = StandardNormal.sample(&mut rng);
                    l * z * z
                })
                .sum();
            over_limit += usize::from(q > limit);
            over_spreads += usize::from(q > two_spreads);
        }
        let rate = |k: usize| k as f64 / draws as f64;
        // Within 0.6 percentage points of 2.28 % (the binomial's σ is 0.024 points).
        assert!((rate(over_limit) - (1.0 - LEVEL)).abs() < 6e-3, "{}", rate(over_limit));
        assert!(rate(over_spreads) > 0.04, "{}", rate(over_spreads));
    }
}
