//! The uncertainty budget of a model-4 triad calibration (GUM, JCGM 100:2008): every contributor
//! propagated to the twelve coefficients and from them to the calibrated acceleration.
//!
//! The coefficients of each channel are a linear function of its dwell means: `c = A·y` with
//! `A = (XᵀWX)⁻¹XᵀW` (X the rows `[1, ax, ay, az]` of the head's nominal accelerations, W the
//! dwells' row counts). Each contributor is a perturbation of the dwell means (or, for g, of the
//! regressors), so its covariance of the coefficients follows through `A` exactly to first order:
//!
//! - **dwell scatter** (Type A, [`scatter`]): the noise of each dwell mean, the samples' scatter
//!   within the dwells (pooled per channel, Σ(m − 1) degrees of freedom) over the dwell's samples;
//!   then the dwell means' scatter about the fit (n − 4 degrees of freedom) is checked against
//!   that noise and the stated references, and what it holds beyond them (samples correlated in
//!   time, a head worse than stated) is counted too. The channels' residuals are correlated (the
//!   head's errors are common to them), and the 3 × 3 residual covariance carries that. Where the
//!   dwells hold one sample each, the dwell means' scatter less what the stated references
//!   account for (below) is the whole of it, so nothing is counted twice.
//! - **head angle** (Type B, the head's register entry or `fit --head-angle-u`): each angle of
//!   each position set with an independent error of one sigma `u_θ`, as the simulator's
//!   `angle_error` draws it; common to all channels.
//! - **head orthogonality** (Type B, `--head-orthogonality-u`): the three rotations between the
//!   α and β stages (the simulator's `head_misalignment`), one sigma each; common to every
//!   position and channel. What the fit cannot absorb of this head's rotation stays in the
//!   residuals with a shape of its own; that part (the residuals' projection on those shapes) is
//!   this head's rotation as realised, not scatter, and is taken out of the dwell scatter.
//! - **gravity** (Type B): the standard uncertainty its source gives g
//!   ([`crate::campaign::GSource::standard_u`]: a survey's or a stated one as given, else a bound
//!   taken as rectangular): a relative error of g is a relative error of every sensitivity.
//! - **quantisation** (Type B): each sample rounded to a whole code, 1/12 code² per sample.
//! - **model 4's lack of fit** (Type A, [`lack_of_fit`]): each channel's dwell means fitted with
//!   the quadratic model on the sphere (every one of the paper's 11 models is inside it), and the
//!   RMS over the sphere of what model 4, fitted on the same positions, leaves of its quadratic
//!   part, less what the dwell scatter puts there; an output error at an orientation nobody
//!   chose, so it sits on each channel's bias term (the same at every orientation). What it
//!   explains of the residuals at the positions is taken out of the dwell scatter. GMDH's
//!   criterion gap to the best of the 11 models is stated beside it. Terms above the second
//!   degree are not measured, and the budget says so.
//! - **temperature** (Type B, stated by the unit type's data sheet: `fit --bias-tempco-u`,
//!   `--scale-tempco-u`, `--thermometer-u`): the coefficients are the unit's at the campaign's
//!   mean temperature T̄, the result is stated at the reference temperature T_ref; each
//!   channel's bias and scale factor move by an unknown coefficient (one sigma as stated,
//!   independent per channel) times T̄ − T_ref, and T̄ is read with the thermometer's
//!   uncertainty: variance coefficient² · ((T̄ − T_ref)² + u(T)²).
//!
//! The calibrated acceleration `â = K⁻¹(u − u0)` then has, at a true acceleration `a`, the
//! covariance `G·Σ·Gᵀ` with `∂â/∂u0_c = −K⁻¹e_c` and `∂â/∂k_c = −K⁻¹e_c·aᵀ`; the expanded
//! uncertainty `U = k·√diag` (k = 2) depends on the orientation, and per axis its maximum over
//! the orientations at 1 g is what the certificate states. [`montecarlo`] checks the whole by
//! simulation (JCGM 101:2008).

mod contributors;
pub mod lack_of_fit;
pub mod montecarlo;
pub mod scatter;

use accelcal_shared::linear::{LinearCal, Model4};
use accelcal_shared::terms::MODEL_4;
use nalgebra::{SMatrix, Vector3};
use serde::{Deserialize, Serialize};

use crate::error::{Classify, Kind};
use crate::lsq::LsqFit;
use crate::positions::{ChannelStats, Positions};
use crate::sim::effects::{rotation, Kinematics};

/// The coverage factor of the expanded uncertainty when its degrees of freedom are many (the
/// conventional 2); with few, Student's t is larger ([`coverage_factor`]).
pub const K_COVERAGE: f64 = 2.0;

/// The coverage factor for about 95 % of a combined standard uncertainty made of parts given as
/// (variance, degrees of freedom; infinite for Type B): the effective degrees of freedom by
/// Welch–Satterthwaite (JCGM 100:2008 G.4.1), `ν_eff = u_c⁴ / Σ uᵢ⁴/νᵢ`, and Student's t at
/// 97.5 % for them (JCGM 100 G.3), never below [`K_COVERAGE`]. Gives (k, ν_eff).
pub fn coverage_factor(parts: &[(f64, f64)]) -> (f64, f64) {
    let uc2: f64 = parts.iter().map(|p| p.0.max(0.0)).sum();
    let denom: f64 =
        parts.iter().filter(|p| p.1.is_finite() && p.1 > 0.0).map(|p| p.0.max(0.0).powi(2) / p.1).sum();
    if !(denom > 0.0) || !(uc2 > 0.0) {
        return (K_COVERAGE, f64::INFINITY);
    }
    let nu = uc2 * uc2 / denom;
    // From 61 degrees of freedom on, t is below 2 (t(60) = 2.0003, t(61) = 1.9996): the
    // conventional 2 stands, and the quantile (whose iteration is slow for large ν) is not
    // needed.
    if !(nu < 61.0) {
        return (K_COVERAGE, nu);
    }
    let t = statrs::distribution::StudentsT::new(0.0, 1.0, nu.max(1.0))
        .map(|d| statrs::distribution::ContinuousCDF::inverse_cdf(&d, 0.975))
        .unwrap_or(f64::NAN);
    (if t.is_finite() { t.max(K_COVERAGE) } else { K_COVERAGE }, nu)
}

/// The probability that ±k standard uncertainties cover the value: normal for infinite `nu`,
/// else Student's t with `nu` degrees of freedom.
pub fn coverage_probability(k: f64, nu: f64) -> f64 {
    use statrs::distribution::{ContinuousCDF, Normal, StudentsT};
    let cdf = if nu.is_finite() && nu > 0.0 {
        StudentsT::new(0.0, 1.0, nu).map(|d| d.cdf(k)).ok()
    } else {
        Normal::new(0.0, 1.0).map(|d| d.cdf(k)).ok()
    };
    cdf.map_or(f64::NAN, |c| 2.0 * c - 1.0)
}

/// One arcsecond, rad.
pub const ARCSEC: f64 = std::f64::consts::PI / 648_000.0;

/// The number of coefficients: channels x, y, z × terms 1, ax, ay, az.
pub const N_COEF: usize = 12;

/// The 12 × 12 covariance of the coefficients.
pub type Cov12 = SMatrix<f64, N_COEF, N_COEF>;

/// The stated uncertainties of the references (one sigma each).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct References {
    /// Setting error of each head angle at each position, rad.
    pub head_angle_rad: f64,
    /// Each of the three rotations between the head's stages, rad.
    pub head_orthogonality_rad: f64,
    /// Standard uncertainty of g, m/s².
    pub g_m_s2: f64,
    /// GMDH's criterion gap of model 4 per channel (in the order of the fits given), codes
    /// ([`lack_of_fit::criterion_gap`]), stated beside the measured lack of fit; `None`: GMDH
    /// identifies no candidate on the plan.
    pub lack_of_fit_codes: Option<[f64; 3]>,
    /// The unit type's stated temperature coefficients; `None`: named as not included.
    pub temperature: Option<TempCoefficients>,
}

/// The stated temperature sensitivity of the unit type and the thermometer's uncertainty (one
/// sigma each).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct TempCoefficients {
    /// Each channel's bias temperature coefficient, mg/°C.
    pub bias_mg_per_c: f64,
    /// Each channel's scale-factor temperature coefficient, ppm/°C.
    pub scale_ppm_per_c: f64,
    /// The standard uncertainty of the campaign's temperature reading, °C.
    pub thermometer_c: f64,
}

/// Why no budget was made.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum UncertaintyError {
    /// The fits are not a model-4 triad.
    #[error("the uncertainty budget is made for a triad (three channels, sensitive axes x, y, z) fitted with model 4 (1,ax,ay,az); {0}")]
    NotATriad(String),
    /// Too few positions to estimate the dwell scatter.
    #[error("{positions} positions leave no degrees of freedom for the dwell scatter of a 4-term model (at least 6 are needed)")]
    TooFewPositions {
        /// Positions in the campaign.
        positions: usize,
    },
    /// A stated uncertainty is not a number ≥ 0.
    #[error("a stated uncertainty must be a finite number ≥ 0, got {0}")]
    BadStated(f64),
    /// The fitted sensitivity matrix cannot be inverted.
    #[error("the fitted sensitivity matrix is singular")]
    Singular,
    /// Temperature coefficients were stated for a campaign without temperatures.
    #[error("the temperature coefficients need the campaign's temperature, and it has no `temp_c` column")]
    NoTemperature,
}

impl Classify for UncertaintyError {
    fn kind(&self) -> Kind {
        Kind::BadInput
    }
}

/// One contributor to the budget.
#[derive(Clone, Debug, Serialize)]
pub struct Contributor {
    /// Its name: `dwell_scatter`, `head_angle`, `head_orthogonality`, `gravity`, `quantisation`,
    /// `temperature`, `lack_of_fit`.
    pub name: &'static str,
    /// Its standard uncertainty of the calibrated acceleration where U is stated (the axis and
    /// orientation of the largest U, [`Budget::stated`]), m/s²: the contributors' u² there add
    /// up to the combined u², so that √Σu² × k = U.
    pub u_m_s2: f64,
    /// Its share of the combined variance there; the shares add up to 1.
    pub share: f64,
    /// Its standard uncertainty at its own worst: the largest over the axes and the orientations
    /// at 1 g, m/s².
    pub u_worst_m_s2: f64,
    /// Its share of the combined variance summed over the axes and averaged over the
    /// orientations at 1 g.
    pub share_mean: f64,
    /// GUM type: `A` (from the data) or `B` (from a stated value).
    #[serde(rename = "type")]
    pub kind: &'static str,
    /// Where its value comes from.
    pub source: String,
    /// Its covariance of the coefficients.
    #[serde(skip)]
    pub covariance: Cov12,
}

/// The budget of one calibration.
#[derive(Clone, Debug)]
pub struct Budget {
    /// Channel index (in the fits given) of the x, y and z rows.
    pub order: [usize; 3],
    /// The fitted model 4, rows x, y, z.
    pub model: Model4,
    /// Its inversion, the calibration the node applies (`â = K⁻¹(u − u0)`).
    pub cal: LinearCal,
    /// The combined covariance of the 12 coefficients (codes, codes/(m/s²)).
    pub covariance: Cov12,
    /// The contributors.
    pub contributors: Vec<Contributor>,
    /// What the budget leaves out, in words.
    pub not_included: Vec<String>,
    /// Per axis, the largest expanded uncertainty over the orientations at 1 g, m/s².
    pub expanded_max: [f64; 3],
    /// The coverage factor ([`coverage_factor`]: 2, or Student's t when the Type A parts leave
    /// few effective degrees of freedom), the largest over the axes at their worst orientation.
    pub k: f64,
    /// The effective degrees of freedom that give `k` (infinite when every part is Type B).
    pub nu_eff: f64,
    /// The probability that the interval ±U covers the value: of the normal distribution for
    /// infinite `nu_eff`, else of Student's t with `nu_eff` degrees of freedom, at `k`.
    pub coverage_probability: f64,
    /// Where U is stated: the axis (0, 1, 2 for x, y, z) and the acceleration (m/s²) of the
    /// orientation at 1 g where the expanded uncertainty is largest.
    pub stated: (usize, [f64; 3]),
}

/// The design row of model 4 at an acceleration.
fn row(a: [f64; 3]) -> [f64; 4] {
    [1.0, a[0], a[1], a[2]]
}

/// The acceleration of the nominal head at a position with a rotation `w` (rad) between its
/// stages and angle offsets (rad): the simulator's kinematics.
fn head_accel(alpha_deg: f64, beta_deg: f64, d_alpha: f64, d_beta: f64, w: [f64; 3], g: f64) -> [f64; 3] {
    let k = Kinematics {
        position: 0,
        seed: 0,
        alpha_rad: alpha_deg.to_radians() + d_alpha,
        beta_rad: beta_deg.to_radians() + d_beta,
        r: rotation(w),
        changed: true,
    };
    k.accel(g)
}

/// ∂a/∂θ at a position for the five head parameters (δα, δβ, ωx, ωy, ωz), central differences.
pub(crate) fn head_partials(alpha_deg: f64, beta_deg: f64, g: f64) -> [[f64; 3]; 5] {
    const H: f64 = 1e-6;
    let mut out = [[0.0; 3]; 5];
    for (p, o) in out.iter_mut().enumerate() {
        let mut plus = [0.0; 5];
        plus[p] = H;
        let minus = plus.map(|v| -v);
        let f = |v: [f64; 5]| head_accel(alpha_deg, beta_deg, v[0], v[1], [v[2], v[3], v[4]], g);
        let (ap, am) = (f(plus), f(minus));
        *o = [0, 1, 2].map(|i| (ap[i] - am[i]) / (2.0 * H));
    }
    out
}

fn dot3(a: &[f64], b: &[f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// Which fit is the x, y and z row of the triad: each channel's largest sensitivity.
pub(crate) fn triad_order(fits: &[&LsqFit]) -> Result<[usize; 3], UncertaintyError> {
    if fits.len() != 3 {
        return Err(UncertaintyError::NotATriad(format!("the campaign has {} channels", fits.len())));
    }
    if let Some(f) = fits.iter().find(|f| f.structure != MODEL_4) {
        return Err(UncertaintyError::NotATriad(format!("a channel was fitted with {}", f.structure)));
    }
    let mut order = [usize::MAX; 3];
    for (ci, f) in fits.iter().enumerate() {
        let axis = crate::compare::own_axis(f);
        if order[axis] != usize::MAX {
            return Err(UncertaintyError::NotATriad("two channels have the same sensitive axis".into()));
        }
        order[axis] = ci;
    }
    Ok(order)
}

/// Adds `scale · u·vᵀ` to the (a, b) block of `cov` (4 × 4 blocks, one per pair of axes).
fn add_block(cov: &mut Cov12, a: usize, b: usize, u: &[f64; 4], v: &[f64; 4], scale: f64) {
    for i in 0..4 {
        for j in 0..4 {
            cov[(4 * a + i, 4 * b + j)] += scale * u[i] * v[j];
        }
    }
}

/// Points spread evenly on the unit sphere (a Fibonacci lattice).
pub fn sphere(n: usize) -> Vec<[f64; 3]> {
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    (0..n)
        .map(|i| {
            let z = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
            let r = (1.0 - z * z).max(0.0).sqrt();
            let phi = golden * i as f64;
            [r * phi.cos(), r * phi.sin(), z]
        })
        .collect()
}

/// The orientations the budget's maxima are taken over.
const SPHERE_POINTS: usize = 600;

/// Makes the budget of a model-4 triad fitted by least squares on `pos` (`fits` in the order of
/// `stats`), with the references' stated uncertainties: each contributor's covariance
/// ([`contributors`]), then their sum.
pub fn budget(
    pos: &Positions,
    stats: &[ChannelStats],
    fits: &[&LsqFit],
    refs: References,
) -> Result<Budget, UncertaintyError> {
    let tc = refs.temperature.unwrap_or_default();
    for v in [
        refs.head_angle_rad,
        refs.head_orthogonality_rad,
        refs.g_m_s2,
        tc.bias_mg_per_c,
        tc.scale_ppm_per_c,
        tc.thermometer_c,
    ]
    .into_iter()
    .chain(refs.lack_of_fit_codes.unwrap_or([0.0; 3]))
    {
        if !(v.is_finite() && v >= 0.0) {
            return Err(UncertaintyError::BadStated(v));
        }
    }
    let order = triad_order(fits)?;
    let n = pos.len();
    if n < 6 {
        return Err(UncertaintyError::TooFewPositions { positions: n });
    }
    let g = pos.g;
    let c = |ci: usize, t: usize| fits[ci].coefficients[t];
    let model = Model4 { u0: order.map(|ci| c(ci, 0)), k: order.map(|ci| [c(ci, 1), c(ci, 2), c(ci, 3)]) };
    let cal = model.invert().map_err(|_| UncertaintyError::Singular)?;
    let setup = contributors::Setup::new(pos, stats, fits, order, model)?;
    let dof = setup.dof;

    // Each contributor, and what it explains of the residual sum of squares (all channels): in
    // expectation (the head's angle errors, the quantisation) and as realised (this head's
    // rotation, model 4's lack of fit), which the dwell scatter then leaves out.
    let angle = contributors::head_angle(&setup, refs.head_angle_rad * refs.head_angle_rad);
    let ortho =
        contributors::head_orthogonality(&setup, refs.head_orthogonality_rad * refs.head_orthogonality_rad);
    let grav = contributors::gravity(&setup, refs.g_m_s2 / g);
    let quant = contributors::quantisation(&setup);
    let (thermal, thermal_source) = contributors::temperature(&setup, &refs)?;
    let points: Vec<[f64; 3]> = sphere(SPHERE_POINTS).into_iter().map(|d| d.map(|v| v * g)).collect();
    let within = scatter::Within::pooled(stats, order, &pos.weight);
    let (lof, lof_source, lof_missing) = contributors::lack_of_fit(&setup, &refs, within, &points);
    let expected = angle.explains + quant.explains;
    let realised = ortho.explains + lof.explains;
    let (noise, excess, scatter_source) =
        contributors::dwell_scatter(&setup, &refs, within, expected, realised);

    let stated = |rad: f64, what: &str| {
        if rad > 0.0 {
            format!("{:.2} arcsec {what}, stated", rad / ARCSEC)
        } else {
            "not stated".to_string()
        }
    };
    let parts: [(&'static str, &'static str, String, Cov12); 7] = [
        ("dwell_scatter", "A", scatter_source, noise + excess),
        ("head_angle", "B", stated(refs.head_angle_rad, "per angle and position"), angle.cov),
        (
            "head_orthogonality",
            "B",
            stated(refs.head_orthogonality_rad, "per rotation between the stages"),
            ortho.cov,
        ),
        ("gravity", "B", format!("u(g) = {:.3e} m/s²", refs.g_m_s2), grav),
        ("quantisation", "B", "1/12 code² per sample".to_string(), quant.cov),
        ("temperature", "B", thermal_source, thermal),
        ("lack_of_fit", "A", lof_source, lof.cov),
    ];
    let mut budget =
        sum(order, model, cal, parts, &points, [(noise, within.map_or(dof, |w| w.dof)), (excess, dof)], n);
    budget.not_included = not_included(&refs, lof_missing);
    Ok(budget)
}

/// A contributor before the sum: its name, GUM type, source in words and covariance.
type PartIn = (&'static str, &'static str, String, Cov12);

/// The budget of the contributors `parts` (the dwell scatter first, then the references): the
/// combined covariance; the coverage factor from the effective degrees of freedom at each
/// axis' worst orientation among `points` (the dwell scatter entering as its two parts
/// `scatter`, each with its degrees of freedom; the lack of fit with the quadratic model's
/// n − 9; Type B infinite); U per axis; and each contributor where U is largest.
fn sum(
    order: [usize; 3],
    model: Model4,
    cal: LinearCal,
    parts: [PartIn; 7],
    points: &[[f64; 3]],
    scatter: [(Cov12, f64); 2],
    n: usize,
) -> Budget {
    let covariance = parts.iter().fold(Cov12::zeros(), |acc, p| acc + p.3);
    let mut budget = Budget {
        order,
        model,
        cal,
        covariance,
        contributors: Vec::new(),
        not_included: Vec::new(),
        expanded_max: [0.0; 3],
        k: K_COVERAGE,
        nu_eff: f64::INFINITY,
        coverage_probability: 0.0,
        stated: (0, [0.0; 3]),
    };
    let combined: Vec<Vector3<f64>> = points.iter().map(|&a| budget.variance_at(&covariance, a)).collect();
    let total_var: f64 = combined.iter().map(|v| v.sum()).sum();
    let part_vars: Vec<Vec<Vector3<f64>>> =
        parts.iter().map(|p| points.iter().map(|&a| budget.variance_at(&p.3, a)).collect()).collect();
    // The Type A parts' degrees of freedom: the samples' noise Σ(m − 1), the dwell means' excess
    // n − 4, the lack of fit's the quadratic model's n − 9; Type B, infinite. The dwell scatter
    // enters as its two parts.
    let lof_dof = n.saturating_sub(lack_of_fit::QUADRATIC_TERMS).max(1) as f64;
    let scatter_vars: [(Vec<Vector3<f64>>, f64); 2] =
        scatter.map(|(cov, nu)| (points.iter().map(|&a| budget.variance_at(&cov, a)).collect(), nu));
    let ws_vars: Vec<(&Vec<Vector3<f64>>, f64)> = parts
        .iter()
        .zip(&part_vars)
        .skip(1)
        .map(|(p, v)| (v, if p.0 == "lack_of_fit" { lof_dof } else { f64::INFINITY }))
        .chain(scatter_vars.iter().map(|(v, nu)| (v, *nu)))
        .collect();
    for i in 0..3 {
        let worst = (0..points.len()).max_by(|&a, &b| combined[a][i].total_cmp(&combined[b][i])).unwrap_or(0);
        let at: Vec<(f64, f64)> = ws_vars.iter().map(|(v, nu)| (v[worst][i], *nu)).collect();
        let (k, nu) = coverage_factor(&at);
        if k > budget.k || (k == budget.k && nu < budget.nu_eff) {
            (budget.k, budget.nu_eff) = (k, nu);
        }
    }
    budget.expanded_max =
        [0, 1, 2].map(|i| budget.k * combined.iter().map(|v| v[i]).fold(0.0f64, f64::max).sqrt());
    budget.coverage_probability = coverage_probability(budget.k, budget.nu_eff);
    // Where U is stated: the axis and orientation of the largest combined variance.
    let mut parts_out = Vec::new();
    let (mut at_axis, mut at_point) = (0, 0);
    for (p, v) in combined.iter().enumerate() {
        for i in 0..3 {
            if v[i] > combined[at_point][at_axis] {
                (at_axis, at_point) = (i, p);
            }
        }
    }
    budget.stated = (at_axis, points.get(at_point).copied().unwrap_or([0.0; 3]));
    let stated_var = combined.get(at_point).map_or(0.0, |v| v[at_axis]);
    for ((name, kind, source, cov), vars) in parts.into_iter().zip(part_vars) {
        let u_worst = vars.iter().map(|v| v.max()).fold(0.0f64, f64::max).sqrt();
        let share_mean =
            if total_var > 0.0 { vars.iter().map(|v| v.sum()).sum::<f64>() / total_var } else { 0.0 };
        let var = vars.get(at_point).map_or(0.0, |v| v[at_axis].max(0.0));
        let share = if stated_var > 0.0 { var / stated_var } else { 0.0 };
        parts_out.push(Contributor {
            name,
            u_m_s2: var.sqrt(),
            share,
            u_worst_m_s2: u_worst,
            share_mean,
            kind,
            source,
            covariance: cov,
        });
    }
    budget.contributors = parts_out;
    budget
}

/// What the budget leaves out, in words.
fn not_included(refs: &References, lof_missing: Option<String>) -> Vec<String> {
    let mut out = Vec::new();
    if refs.head_angle_rad == 0.0 {
        out.push(
            "the head's angle setting errors as stated by its certificate (none given: they count only as far as the dwell scatter shows them)".into(),
        );
    }
    if refs.head_orthogonality_rad == 0.0 {
        out.push("the head's axis orthogonality (none given)".into());
    }
    if refs.temperature.is_none() {
        out.push(
            "the temperature during calibration against the reference temperature (no temperature coefficient stated)".into(),
        );
    }
    out.push(match lof_missing {
        None => {
            "terms of the output above the second degree in acceleration (model 4's lack of fit is measured \
                 against the quadratic model)"
                .into()
        }
        Some(why) => {
            format!("model 4's lack of fit beyond what the dwell scatter shows (not measured: {why})")
        }
    });
    out
}

impl Budget {
    /// Per axis, the variance of the calibrated acceleration at the true acceleration `a` (m/s²)
    /// under the coefficients' covariance `cov`, (m/s²)².
    pub fn variance_at(&self, cov: &Cov12, a: [f64; 3]) -> Vector3<f64> {
        // The Jacobian is −K⁻¹ ⊗ rᵀ (r = [1, a]): per pair of channels the 4 × 4 block's
        // quadratic form in r, then K⁻¹'s rows over them (the same as J·Σ·Jᵀ's diagonal).
        let r = row(a);
        let mut q = [[0.0; 3]; 3];
        for (c, qc) in q.iter_mut().enumerate() {
            for (d, v) in qc.iter_mut().enumerate() {
                *v = (0..4)
                    .map(|s| r[s] * (0..4).map(|t| cov[(4 * c + s, 4 * d + t)] * r[t]).sum::<f64>())
                    .sum();
            }
        }
        let m = &self.cal.m;
        Vector3::from_fn(|i, _| {
            (0..3).map(|c| (0..3).map(|d| m[i][c] * m[i][d] * q[c][d]).sum::<f64>()).sum()
        })
    }

    /// Per axis, the expanded uncertainty (coverage factor [`Budget::k`]) of the calibrated
    /// acceleration at `a`, m/s².
    pub fn expanded_at(&self, a: [f64; 3]) -> [f64; 3] {
        let v = self.variance_at(&self.covariance, a);
        [0, 1, 2].map(|i| self.k * v[i].max(0.0).sqrt())
    }

    /// The names of the 12 coefficients in the covariance's order (`x:1`, `x:ax`, …).
    pub fn coefficient_names() -> Vec<String> {
        let mut out = Vec::new();
        for ch in ["x", "y", "z"] {
            for t in ["1", "ax", "ay", "az"] {
                out.push(format!("{ch}:{t}"));
            }
        }
        out
    }
}

/// The JSON form of a budget (`fit --json`'s `uncertainty`), written by `fit` and read back by
/// `record show --fit|--db`.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct UncertaintyJson {
    /// The coverage factor: 2, or Student's t for the effective degrees of freedom when they are
    /// few ([`coverage_factor`]).
    pub k: f64,
    /// The effective degrees of freedom (Welch–Satterthwaite) that give `k`; absent when every
    /// contributor is Type B, or in a fit JSON written before it was stated.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub nu_eff: Option<f64>,
    /// Per axis x, y, z, the expanded uncertainty of the calibrated acceleration, its maximum
    /// over the orientations at 1 g, m/s².
    #[serde(rename = "U_m_s2")]
    pub u_m_s2: [f64; 3],
    /// The probability that ±U covers the value (`k` and `nu_eff`: normal or Student's t);
    /// absent in a fit JSON written before it was stated.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub coverage_probability: Option<f64>,
    /// Where the contributors' `u_m_s2` and `share` are taken: the axis and orientation of the
    /// largest U; absent in a fit JSON written before (its `u_m_s2` is each contributor's
    /// worst and its `share` the mean over the orientations).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stated_at: Option<StatedAt>,
    /// The coefficients' names in the covariance's order.
    pub coefficients: Vec<String>,
    /// The combined 12 × 12 covariance (codes², codes²/(m/s²), codes²/(m/s²)²).
    pub covariance: Vec<Vec<f64>>,
    /// The contributors.
    pub contributors: Vec<ContributorJson>,
    /// What the budget leaves out.
    pub not_included: Vec<String>,
}

/// Where a budget states U ([`Budget::stated`]).
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct StatedAt {
    /// The axis: `x`, `y` or `z`.
    pub axis: String,
    /// The acceleration of the orientation, m/s².
    pub acceleration_m_s2: [f64; 3],
}

/// One contributor as the fit JSON states it ([`Contributor`] without its covariance).
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct ContributorJson {
    /// Its name: `dwell_scatter`, `head_angle`, `head_orthogonality`, `gravity`, `quantisation`,
    /// `temperature`, `lack_of_fit`.
    pub name: String,
    /// Its standard uncertainty of the calibrated acceleration where U is stated (`stated_at`),
    /// m/s²: √Σu² × k = U there.
    pub u_m_s2: f64,
    /// Its share of the combined variance there.
    pub share: f64,
    /// Its standard uncertainty at its own worst axis and orientation, m/s² (absent in a fit
    /// JSON written before it was stated).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub u_worst_m_s2: Option<f64>,
    /// Its share of the variance summed over the axes and averaged over the orientations
    /// (absent likewise).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub share_mean: Option<f64>,
    /// GUM type: `A` or `B`.
    #[serde(rename = "type")]
    pub kind: String,
    /// Where its value comes from.
    pub source: String,
}

impl UncertaintyJson {
    /// The `uncertainty` of a fit JSON document: `Ok(None)` when the fit has none (test turns,
    /// gravity-norm, another model than model 4, a campaign that is not a triad), an error when
    /// it is there but not a budget.
    pub fn of_fit_json(doc: &serde_json::Value) -> Result<Option<UncertaintyJson>, serde_json::Error> {
        match doc.get("uncertainty") {
            None | Some(serde_json::Value::Null) => Ok(None),
            Some(v) => UncertaintyJson::deserialize(v).map(Some),
        }
    }
}

impl From<&Budget> for UncertaintyJson {
    fn from(b: &Budget) -> UncertaintyJson {
        UncertaintyJson {
            k: b.k,
            nu_eff: b.nu_eff.is_finite().then_some(b.nu_eff),
            u_m_s2: b.expanded_max,
            coverage_probability: b.coverage_probability.is_finite().then_some(b.coverage_probability),
            stated_at: Some(StatedAt {
                axis: ["x", "y", "z"][b.stated.0].to_string(),
                acceleration_m_s2: b.stated.1,
            }),
            coefficients: Budget::coefficient_names(),
            covariance: (0..N_COEF).map(|i| (0..N_COEF).map(|j| b.covariance[(i, j)]).collect()).collect(),
            contributors: b
                .contributors
                .iter()
                .map(|c| ContributorJson {
                    name: c.name.to_string(),
                    u_m_s2: c.u_m_s2,
                    share: c.share,
                    u_worst_m_s2: Some(c.u_worst_m_s2),
                    share_mean: Some(c.share_mean),
                    kind: c.kind.to_string(),
                    source: c.source.clone(),
                })
                .collect(),
            not_included: b.not_included.clone(),
        }
    }
}

#[cfg(test)]
mod tests;
