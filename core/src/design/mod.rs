//! Plan design: which head positions, how many, and how long to dwell at each, chosen before a
//! single sample is taken, from the uncertainty budget's own propagation ([`crate::uncertainty`]).
//!
//! A plan's expanded uncertainty of the calibrated acceleration is known in advance once the unit
//! type's sensitivities and noise (the [`Prior`], from an earlier campaign of the same kind of
//! unit or the nominal unit) and the references' stated uncertainties ([`Stated`]) are. Model 4 is
//! fitted by least squares on the dwell means, `c = M⁻¹Xᵀy` with `M = XᵀX` over the positions'
//! rows `[1, ax, ay, az]`, so each contributor's covariance of the twelve coefficients is, per
//! pair of channels `p, q` (a 4 × 4 block):
//!
//! - **noise**: `δ_pq · σ_p² / n · M⁻¹`, the sample noise averaged over the `n` samples of a dwell;
//! - **quantisation**: `δ_pq · 1/(12 n) · M⁻¹`, as the budget counts it;
//! - **head angle**: `u_θ² · M⁻¹ (Σ_i s_i,pq x_i x_iᵀ) M⁻¹`, with `s_i,pq` the sum over the two
//!   angles of `(k_p·∂a/∂θ)(k_q·∂a/∂θ)` at position `i`: each angle of each position set with an
//!   independent error, common to the channels, that averages down with the number of positions
//!   and not with the dwell;
//! - **gravity**: `(u_g/g)² · dk_p dk_qᵀ` with `dk = [0, k]`: the same for every plan.
//!
//! The calibrated acceleration `â = K⁻¹(u − u0)` then has at a true acceleration `a` the variance
//! `Σ_pq m_ip m_iq rᵀ B_pq r` per axis `i` (`r = [1, a]`, `m = K⁻¹`), and the criterion is the
//! budget's: the largest expanded uncertainty over the axes and over the orientations at 1 g,
//! with the budget's coverage factor (2, or Student's t where the noise's degrees of freedom,
//! the samples' within the dwells, are few: [`crate::uncertainty::coverage_factor`]). It is what [`crate::uncertainty::budget`] states after the campaign when its dwell scatter
//! is the noise assumed here; the head's orthogonality, the temperature and model 4's lack of fit
//! are not predicted (they depend on the head and the unit, not on the plan's noise), and
//! [`Prediction::not_included`] says so.
//!
//! **In a thermal chamber** ([`Chamber`]: the plan run once at each setpoint, the linear thermal
//! model `1, ax, ay, az, t, ax·t, ay·t, az·t` fitted), each channel's rows are `x ⊗ [1, t]`, so
//! `M = M₄ ⊗ M_T` with `M_T = Σ_j [1, t_j][1, t_j]ᵀ` over the setpoints, and the head's angles,
//! set anew at every pass, give `H ⊗ M_T` alike. The model-4 coefficients in force at a
//! temperature `t` are `(I ⊗ [1, t])` of the thermal ones, with the covariance of model 4's
//! noise, quantisation and head-angle parts times `f(t) = [1, t] M_T⁻¹ [1, t]ᵀ = 1/J + (t − t̄)²/S_tt`
//! (`J` setpoints, `S_tt` their sum of squares about their mean `t̄`), largest at an end of the
//! calibrated range. The criterion is then taken at that worst temperature, and the noise is
//! estimated from the samples within the dwells of every pass. The positions that minimise it are
//! model 4's up to the gravity part, which the factor does not scale.
//!
//! [`search`] chooses the positions among those the head reaches (an exchange algorithm on the
//! criterion), and with [`search::design_auto`] the number of positions and the dwell too, for the
//! least head time that reaches a target; [`order`] orders them for short moves and keeps GMDH's
//! selection meaningful on them.

pub mod order;
pub mod search;

use accelcal_shared::linear::Model4;
use accelcal_shared::terms::MODEL_4;
use nalgebra::{Matrix4, SMatrix, Vector4};
use serde::Serialize;

use crate::calibrate::{fit_positions, Method};
use crate::campaign::Campaign;
use crate::error::{Classify, Kind};
use crate::positions::Positions;
use crate::sim::NOMINAL_CODES_PER_G;
use crate::uncertainty::{coverage_factor, head_partials, sphere, triad_order, K_COVERAGE};

/// What the unit type is assumed to be: its sensitivities and its sample noise.
#[derive(Clone, Debug, PartialEq)]
pub struct Prior {
    /// Model 4 of the unit type, rows x, y, z (only its sensitivities matter).
    pub model: Model4,
    /// White noise of one sample per channel x, y, z, codes (one sigma).
    pub noise_codes: [f64; 3],
    /// Where it comes from, in words.
    pub source: String,
}

impl Prior {
    /// The simulator's nominal triad (16384 codes per g on its own axis, no cross-sensitivity)
    /// with `noise_codes` of white noise per sample.
    pub fn nominal(noise_codes: f64, g: f64) -> Result<Prior, DesignError> {
        if !(noise_codes.is_finite() && noise_codes >= 0.0) {
            return Err(DesignError::Prior(format!(
                "the noise must be a number of codes ≥ 0, got {noise_codes}"
            )));
        }
        let s = NOMINAL_CODES_PER_G / g;
        Ok(Prior {
            model: Model4 { u0: [0.0; 3], k: [[s, 0.0, 0.0], [0.0, s, 0.0], [0.0, 0.0, s]] },
            noise_codes: [noise_codes; 3],
            source: format!("the nominal triad ({NOMINAL_CODES_PER_G} codes per g), {noise_codes} codes of noise per sample"),
        })
    }

    /// The prior an earlier campaign of the same kind of unit gives: model 4 fitted by least
    /// squares on all its positions, and each channel's noise pooled from the scatter within its
    /// dwells.
    pub fn from_campaign(c: &Campaign, g: f64, name: &str) -> Result<Prior, DesignError> {
        let pos = Positions::new(c, g);
        let stats = pos.channel_stats(c);
        let fits = fit_positions(&pos, &stats, Method::Lsq, MODEL_4)
            .map_err(|e| DesignError::Prior(format!("model 4 cannot be fitted on it: {e}")))?;
        let refs: Vec<_> = fits.iter().map(|(_, f)| f).collect();
        let order = triad_order(&refs).map_err(|e| DesignError::Prior(e.to_string()))?;
        // The samples' noise as the budget pools it.
        let Some(within) = crate::uncertainty::scatter::Within::pooled(&stats, order, &pos.weight) else {
            return Err(DesignError::Prior(
                "its dwells hold one sample each, so it shows no sample noise".to_string(),
            ));
        };
        let noise = within.var_codes2.map(f64::sqrt);
        let c4 = |ci: usize| &refs[ci].coefficients;
        let model =
            Model4 { u0: order.map(|ci| c4(ci)[0]), k: order.map(|ci| [c4(ci)[1], c4(ci)[2], c4(ci)[3]]) };
        let [nx, ny, nz] = noise;
        Ok(Prior {
            model,
            noise_codes: noise,
            source: format!(
                "{name}: model 4 fitted on its {} positions, noise per sample x {nx:.1}, y {ny:.1}, z {nz:.1} codes",
                pos.len()
            ),
        })
    }
}

/// The references' stated uncertainties (one sigma each).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Stated {
    /// Setting error of each head angle at each position, rad.
    pub head_angle_rad: f64,
    /// Standard uncertainty of g, m/s².
    pub g_m_s2: f64,
    /// The thermal chamber the plan is run in, at each of its setpoints (`None`: one pass, model 4).
    pub chamber: Option<Chamber>,
}

/// A thermal campaign's chamber: the plan is run once at each setpoint, after a soak, and the
/// linear thermal model is fitted (see the module's documentation).
#[derive(Clone, Debug, PartialEq)]
pub struct Chamber {
    /// The setpoints, °C, in the order they are run.
    pub setpoints_c: Vec<f64>,
    /// Seconds the chamber holds each setpoint before its pass (head time spent waiting).
    pub soak_s: f64,
}

impl Chamber {
    /// A chamber with at least two distinct, finite setpoints and a soak of ≥ 0 s.
    pub fn new(setpoints_c: Vec<f64>, soak_s: f64) -> Result<Chamber, DesignError> {
        if let Some(&t) = setpoints_c.iter().find(|t| !t.is_finite()) {
            return Err(DesignError::Chamber(format!("a setpoint must be a number of °C, got {t}")));
        }
        let (lo, hi) = range(&setpoints_c);
        if setpoints_c.len() < 2 || hi <= lo {
            return Err(DesignError::Chamber(
                "the thermal model's t terms need at least two different setpoints".into(),
            ));
        }
        if !(soak_s.is_finite() && soak_s >= 0.0) {
            return Err(DesignError::Chamber(format!(
                "the soak must be a number of seconds ≥ 0, got {soak_s}"
            )));
        }
        Ok(Chamber { setpoints_c, soak_s })
    }

    /// The passes of the plan: one per setpoint.
    pub fn passes(&self) -> usize {
        self.setpoints_c.len()
    }

    /// The calibrated range, °C (lowest and highest setpoint).
    pub fn range_c(&self) -> (f64, f64) {
        range(&self.setpoints_c)
    }

    /// `f(t) = [1, t] M_T⁻¹ [1, t]ᵀ` at the end of the calibrated range where it is largest: the
    /// factor on the variances of model 4's coefficients in force there.
    pub fn factor(&self) -> f64 {
        let j = self.setpoints_c.len() as f64;
        let mean = self.setpoints_c.iter().sum::<f64>() / j;
        let stt: f64 = self.setpoints_c.iter().map(|t| (t - mean) * (t - mean)).sum();
        let (lo, hi) = self.range_c();
        let d = (mean - lo).max(hi - mean);
        1.0 / j + d * d / stt
    }

    /// The head time of a plan whose single pass takes `one_pass_s`: every pass and its soak, s.
    pub fn head_time_s(&self, one_pass_s: f64) -> f64 {
        self.passes() as f64 * (one_pass_s + self.soak_s)
    }
}

fn range(v: &[f64]) -> (f64, f64) {
    v.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &t| (lo.min(t), hi.max(t)))
}

/// Why no plan was designed or predicted.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum DesignError {
    /// The unit type cannot be taken from what was given.
    #[error("the unit type cannot be taken from the earlier campaign: {0}")]
    Prior(String),
    /// The chamber's setpoints or soak are not usable.
    #[error("the chamber: {0}")]
    Chamber(String),
    /// The head's reach is not a usable description.
    #[error("the head's reach: {0}")]
    Head(String),
    /// Fewer positions than GMDH needs to rank the paper's models.
    #[error("{n} positions are too few: GMDH ranks the paper's models (up to 7 terms) only on at least {min} positions (leave-one-out), 14 with the alternate split")]
    TooFew {
        /// Positions asked for.
        n: usize,
        /// The fewest that work.
        min: usize,
    },
    /// More positions than the head reaches.
    #[error("{n} positions asked for, and the head reaches only {reachable} distinct ones with these steps")]
    TooMany {
        /// Positions asked for.
        n: usize,
        /// Positions the head reaches.
        reachable: usize,
    },
    /// The plan does not identify model 4.
    #[error("the plan does not identify model 4 (its positions leave an axis unexcited)")]
    Singular,
    /// A number that must be positive is not.
    #[error("{what} must be a finite number > 0, got {value}")]
    NotPositive {
        /// What it is.
        what: &'static str,
        /// Its value.
        value: f64,
    },
    /// No plan within the limits reaches the target.
    #[error("no plan reaches U = {target:.3e} m/s²: {why}")]
    Unreachable {
        /// The target, m/s².
        target: f64,
        /// Why, in words.
        why: String,
    },
    /// GMDH cannot rank its candidates on the designed positions.
    #[error("GMDH could not rank the paper's models on the {n} designed positions, by the alternate split or leave-one-out")]
    Blind {
        /// Positions.
        n: usize,
    },
}

impl Classify for DesignError {
    fn kind(&self) -> Kind {
        Kind::BadInput
    }
}

/// One contributor of a prediction.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct Part {
    /// `noise`, `quantisation`, `head_angle`, `gravity`.
    pub name: &'static str,
    /// Its standard uncertainty of the calibrated acceleration, m/s²: the largest over the axes
    /// and the orientations at 1 g.
    pub u_m_s2: f64,
}

/// What a plan with a dwell is predicted to give.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct Prediction {
    /// Per axis x, y, z, the largest expanded uncertainty over the orientations at 1 g, m/s².
    pub expanded_m_s2: [f64; 3],
    /// Its coverage factor: the budget's ([`coverage_factor`]: 2, or Student's t when the noise,
    /// estimated from the samples within the dwells, has few degrees of freedom).
    pub k: f64,
    /// The effective degrees of freedom that give `k`.
    pub nu_eff: Option<f64>,
    /// The largest of them: the worst axis at its worst orientation, m/s² (the worst-case
    /// criterion).
    pub worst_m_s2: f64,
    /// D-criterion: the geometric mean of the twelve coefficients' standard uncertainties, the
    /// sensitivities taken at 1 g (`det(Σ)^(1/24)`), codes.
    pub d_codes: f64,
    /// A-criterion: the root mean square of the twelve coefficients' standard uncertainties, the
    /// sensitivities at 1 g (`√(tr Σ / 12)`), codes.
    pub a_codes: f64,
    /// The contributors.
    pub parts: Vec<Part>,
    /// What the prediction leaves out.
    pub not_included: Vec<&'static str>,
}

/// What the prediction leaves out, in words.
pub const NOT_INCLUDED: [&str; 3] = [
    "the head's orthogonality (a rotation common to every position)",
    "the temperature against the reference temperature",
    "model 4's lack of fit (measured on the campaign, not known before it)",
];

/// What a prediction in a chamber leaves out, in words.
pub const NOT_INCLUDED_CHAMBER: [&str; 4] = [
    "the head's orthogonality (a rotation common to every position)",
    "the thermometer's uncertainty, and the sensor lagging the chamber (each soak assumed long enough)",
    "terms of the temperature above the first degree (the linear thermal model is assumed)",
    "model 4's lack of fit (measured on the campaign, not known before it)",
];

/// The orientations at 1 g over which a design is searched (fewer than a prediction's, for speed).
pub(crate) const SEARCH_POINTS: usize = 150;

/// The orientations a prediction's maxima are taken over (the budget's number).
const PREDICT_POINTS: usize = 600;

type Blocks = [[Matrix4<f64>; 3]; 3];

/// What one position adds to the sums: its row `[1, a]` and the products `s_pq` of the channels'
/// responses to its two angles.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Point {
    pub(crate) x: Vector4<f64>,
    pub(crate) s: [[f64; 3]; 3],
}

/// The sums a plan's covariance is made from: `M = Σ x xᵀ` and `H_pq = Σ s_pq x xᵀ`.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Sums {
    m: Matrix4<f64>,
    h: Blocks,
}

impl Sums {
    pub(crate) fn zero() -> Sums {
        Sums { m: Matrix4::zeros(), h: [[Matrix4::zeros(); 3]; 3] }
    }

    /// Adds `sign` times a point.
    pub(crate) fn add(&mut self, p: &Point, sign: f64) {
        let xx = p.x * p.x.transpose() * sign;
        self.m += xx;
        for a in 0..3 {
            for b in 0..3 {
                self.h[a][b] += xx * p.s[a][b];
            }
        }
    }
}

/// Which contributors a covariance holds.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Only {
    All,
    Noise,
    Quantisation,
    HeadAngle,
    Gravity,
}

/// The fixed part of every evaluation: the unit, the stated values, the dwell.
#[derive(Clone, Debug)]
pub(crate) struct Evaluator {
    /// `K⁻¹`, rows x, y, z.
    cal: [[f64; 3]; 3],
    k: [[f64; 3]; 3],
    g: f64,
    /// Noise variance of a dwell mean per channel, codes².
    noise: [f64; 3],
    /// Quantisation variance of a dwell mean, codes².
    quant: f64,
    /// Head angle variance, rad².
    ua2: f64,
    grav: Blocks,
    /// In a chamber, its passes (one without); the noise, quantisation and head-angle variances
    /// above hold its factor ([`Chamber::factor`]).
    passes: usize,
    /// Samples per position.
    samples: f64,
}

impl Evaluator {
    pub(crate) fn new(
        prior: &Prior,
        stated: &Stated,
        g: f64,
        samples: usize,
    ) -> Result<Evaluator, DesignError> {
        for (what, value) in [("g", g), ("the samples per position", samples as f64)] {
            if !(value.is_finite() && value > 0.0) {
                return Err(DesignError::NotPositive { what, value });
            }
        }
        for v in [stated.head_angle_rad, stated.g_m_s2] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(DesignError::Prior(format!(
                    "a stated uncertainty must be a number ≥ 0, got {v}"
                )));
            }
        }
        let cal = prior
            .model
            .invert()
            .map_err(|_| DesignError::Prior("its sensitivity matrix is singular".into()))?;
        let n = samples as f64;
        let rel = stated.g_m_s2 / g;
        let k = prior.model.k;
        let dk = |p: usize| Vector4::new(0.0, k[p][0], k[p][1], k[p][2]);
        let grav = std::array::from_fn(|p| std::array::from_fn(|q| dk(p) * dk(q).transpose() * (rel * rel)));
        let (passes, thermal) = stated.chamber.as_ref().map_or((1, 1.0), |c| (c.passes(), c.factor()));
        Ok(Evaluator {
            cal: cal.m,
            k,
            g,
            noise: prior.noise_codes.map(|s| s * s / n * thermal),
            quant: thermal / (12.0 * n),
            ua2: stated.head_angle_rad * stated.head_angle_rad * thermal,
            grav,
            passes,
            samples: n,
        })
    }

    /// A head position as the sums take it.
    pub(crate) fn point(&self, (alpha_deg, beta_deg): (f64, f64)) -> Point {
        let a = accelcal_shared::gravity(alpha_deg, beta_deg, self.g);
        let d = head_partials(alpha_deg, beta_deg, self.g);
        let resp = |p: usize, angle: usize| (0..3).map(|j| self.k[p][j] * d[angle][j]).sum::<f64>();
        let s = std::array::from_fn(|p| {
            std::array::from_fn(|q| resp(p, 0) * resp(q, 0) + resp(p, 1) * resp(q, 1))
        });
        Point { x: Vector4::new(1.0, a[0], a[1], a[2]), s }
    }

    /// The coefficients' covariance blocks of the sums, or `None` when they do not identify model 4.
    fn blocks(&self, sums: &Sums, only: Only) -> Option<Blocks> {
        let minv = sums.m.try_inverse()?;
        if !minv.iter().all(|v| v.is_finite()) {
            return None;
        }
        let on = |o: Only| only == Only::All || only == o;
        Some(std::array::from_fn(|p| {
            std::array::from_fn(|q| {
                let mut b = Matrix4::zeros();
                if p == q {
                    let v = if on(Only::Noise) { self.noise[p] } else { 0.0 }
                        + if on(Only::Quantisation) { self.quant } else { 0.0 };
                    b += minv * v;
                }
                if on(Only::HeadAngle) && self.ua2 > 0.0 {
                    b += minv * sums.h[p][q] * minv * self.ua2;
                }
                if on(Only::Gravity) {
                    b += self.grav[p][q];
                }
                b
            })
        }))
    }

    /// Per axis, the largest variance of the calibrated acceleration over `points` (at 1 g).
    fn worst(&self, b: &Blocks, points: &[[f64; 3]]) -> [f64; 3] {
        let mut out = [0.0f64; 3];
        for a in points {
            let r = Vector4::new(1.0, a[0], a[1], a[2]);
            let mut q = [[0.0; 3]; 3];
            for p in 0..3 {
                for s in p..3 {
                    q[p][s] = (r.transpose() * b[p][s] * r)[(0, 0)];
                }
            }
            for i in 0..3 {
                let m = self.cal[i];
                let mut v = 0.0;
                for p in 0..3 {
                    v += m[p] * m[p] * q[p][p];
                    for s in p + 1..3 {
                        v += 2.0 * m[p] * m[s] * q[p][s];
                    }
                }
                out[i] = out[i].max(v);
            }
        }
        out
    }

    /// The search's objective: the worst axis' largest variance, the others' breaking ties.
    pub(crate) fn objective(&self, sums: &Sums, points: &[[f64; 3]]) -> f64 {
        match self.blocks(sums, Only::All) {
            Some(b) => {
                let v = self.worst(&b, points);
                v[0].max(v[1]).max(v[2]) + 1e-3 * (v[0] + v[1] + v[2])
            }
            None => f64::INFINITY,
        }
    }

    /// The orientations at 1 g, `n` of them.
    pub(crate) fn sphere(&self, n: usize) -> Vec<[f64; 3]> {
        sphere(n).into_iter().map(|d| d.map(|v| v * self.g)).collect()
    }

    /// Per point of `points` and axis, the variance of the calibrated acceleration under `b`.
    fn variances(&self, b: &Blocks, points: &[[f64; 3]]) -> Vec<[f64; 3]> {
        points.iter().map(|p| self.worst(b, std::slice::from_ref(p))).collect()
    }

    /// The full prediction of the sums.
    fn predict(&self, sums: &Sums) -> Result<Prediction, DesignError> {
        let points = self.sphere(PREDICT_POINTS);
        let all = self.blocks(sums, Only::All).ok_or(DesignError::Singular)?;
        let combined = self.variances(&all, &points);
        // The budget estimates the noise from the samples' scatter within the dwells, on
        // Σ(m − 1) degrees of freedom over every dwell of every pass, and counts the
        // quantisation as stated (Type B): its coverage factor is the budget's
        // (`coverage_factor`).
        let n = sums.m[(0, 0)].round();
        let dof = self.passes as f64 * n * (self.samples - 1.0);
        let parts_of = [
            ("noise", Only::Noise, dof),
            ("quantisation", Only::Quantisation, f64::INFINITY),
            ("head_angle", Only::HeadAngle, f64::INFINITY),
            ("gravity", Only::Gravity, f64::INFINITY),
        ];
        let part_vars: Vec<Vec<[f64; 3]>> = parts_of
            .iter()
            .map(|&(_, only, _)| {
                self.blocks(sums, only)
                    .map_or(vec![[f64::NAN; 3]; points.len()], |b| self.variances(&b, &points))
            })
            .collect();
        let (mut k, mut nu_eff) = (K_COVERAGE, f64::INFINITY);
        for i in 0..3 {
            let worst =
                (0..points.len()).max_by(|&a, &b| combined[a][i].total_cmp(&combined[b][i])).unwrap_or(0);
            let at: Vec<(f64, f64)> =
                parts_of.iter().zip(&part_vars).map(|(p, v)| (v[worst][i], p.2)).collect();
            let (ki, nu) = coverage_factor(&at);
            if ki > k || (ki == k && nu < nu_eff) {
                (k, nu_eff) = (ki, nu);
            }
        }
        let var: [f64; 3] = std::array::from_fn(|i| combined.iter().map(|v| v[i]).fold(0.0f64, f64::max));
        let expanded_m_s2 = var.map(|v| k * v.max(0.0).sqrt());
        let parts = parts_of
            .iter()
            .zip(&part_vars)
            .map(|(&(name, _, _), v)| Part {
                name,
                u_m_s2: v.iter().map(|x| x[0].max(x[1]).max(x[2])).fold(0.0f64, f64::max).max(0.0).sqrt(),
            })
            .collect();
        // The coefficients with the sensitivities at 1 g: all in codes.
        let scale = |t: usize| if t == 0 { 1.0 } else { self.g };
        let cov = SMatrix::<f64, 12, 12>::from_fn(|i, j| {
            all[i / 4][j / 4][(i % 4, j % 4)] * scale(i % 4) * scale(j % 4)
        });
        let d_codes = cov.determinant().max(0.0).powf(1.0 / 24.0);
        let a_codes = (cov.trace() / 12.0).max(0.0).sqrt();
        Ok(Prediction {
            worst_m_s2: expanded_m_s2[0].max(expanded_m_s2[1]).max(expanded_m_s2[2]),
            expanded_m_s2,
            k,
            nu_eff: nu_eff.is_finite().then_some(nu_eff),
            d_codes,
            a_codes,
            parts,
            not_included: if self.passes == 1 {
                NOT_INCLUDED.to_vec()
            } else {
                NOT_INCLUDED_CHAMBER.to_vec()
            },
        })
    }
}

/// Predicts the expanded uncertainty of a plan (`positions` as `(alpha_deg, beta_deg)`) with
/// `samples` samples per position, for the unit type `prior` and the references `stated`.
pub fn predict(
    positions: &[(f64, f64)],
    samples: usize,
    prior: &Prior,
    stated: &Stated,
    g: f64,
) -> Result<Prediction, DesignError> {
    let ev = Evaluator::new(prior, stated, g, samples)?;
    let mut sums = Sums::zero();
    for &p in positions {
        sums.add(&ev.point(p), 1.0);
    }
    ev.predict(&sums)
}

/// A plan's head time: each position costs its move and settling time and its dwell, s.
pub fn head_time_s(positions: usize, samples: usize, rate_hz: f64, move_s: f64) -> f64 {
    positions as f64 * (move_s + samples as f64 / rate_hz)
}

#[cfg(test)]
mod tests;
