//! The dividing head's signature across units (the line-level sim-to-real diagnosis): a head
//! error is the same for every unit calibrated on it, so it leaves the same pattern in every
//! unit's model-4 residuals (the part of a position's angle error that the linear model cannot
//! absorb), and a rotation of the mount, which model 4 absorbs, shifts the population of the
//! cross terms. Each single unit's verification on that head passes; the population does not.
//!
//! Per unit ([`observe`]): at each position the residual of the dwell means about the unit's
//! model-4 fit, as an acceleration (`K⁻¹·r`, m/s²), and its six misalignments δ (µrad). Across
//! units in time order ([`track`]), from a head's 5th unit: each position's residual read along
//! `∂a/∂α` and `∂a/∂β` (the head-angle errors model 4 left), standardised by the unit's own
//! stated variance about the head's signature learned from its earlier units (the head
//! certificate's angle uncertainty the prior), and the misalignments as the mount's three
//! rotations and the block's three non-orthogonalities ([`mount_terms`]), standardised by the
//! earlier units' mean and spread ([`chart`]: Quesenberry's Q statistics, Hawkins' self-starting
//! CUSUM). Each is followed by a two-sided CUSUM (Page 1954) tuned to the smallest change issue
//! 60 names, its decision interval from Siegmund's approximation for one false alarm in
//! [`DESIGN_UNITS_PER_FALSE_ALARM`] units of a true head between them. The first unit whose
//! CUSUM passes its `h` is a change point, with the statistic that passed and the estimated
//! shift (the mean since its CUSUM last left zero less the reference, over the share model 4
//! leaves: arcsec of head angle at a position, µrad of a mount term); a new stretch starts where
//! that CUSUM left zero. [`Signature`] is the mean residual pattern of the units since the last
//! change point, with its standard error, per position. [`study`] measures the tracking on
//! simulated fleets beside an oracle ([`Oracle`]).

use accelcal_shared::terms::MODEL_4;
use serde::Serialize;

use crate::calibrate::{fit_positions, Method};
use crate::compare::own_axis;
use crate::positions::{ChannelStats, Positions};

pub mod chart;
mod study;

pub use study::{simulate_fleet, study, HeadChange, Oracle, StudyRow};

/// One arcsecond, rad.
const ARCSEC: f64 = std::f64::consts::PI / 648_000.0;

/// The misalignments' names, in [`UnitObs::misalign_urad`]'s order.
pub const CROSS_TERMS: [&str; 6] = ["x→y", "x→z", "y→x", "y→z", "z→x", "z→y"];

/// What one unit's calibration shows of the head.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct UnitObs {
    /// The unit's serial.
    pub serial: String,
    /// Its run.
    pub run_id: String,
    /// When the run started, Unix seconds.
    pub started_unix_s: i64,
    /// The commanded positions `(α, β)`, degrees.
    pub positions: Vec<(f64, f64)>,
    /// At each position, the model-4 residual as an acceleration, m/s² (x, y, z).
    pub resid_m_s2: Vec<[f64; 3]>,
    /// The misalignments δ (µrad) in [`CROSS_TERMS`]' order.
    pub misalign_urad: [f64; 6],
}

/// The observation of one unit from its campaign's dwell statistics (its serial, run and start
/// left for the caller): `None` unless the campaign is a triad that model 4 fits by least
/// squares with an invertible sensitivity.
pub fn observe(pos: &Positions, stats: &[ChannelStats]) -> Option<UnitObs> {
    if stats.len() != 3 {
        return None;
    }
    let fits = fit_positions(pos, stats, Method::Lsq, MODEL_4).ok()?;
    let mut order = [usize::MAX; 3];
    for (ci, (_, f)) in fits.iter().enumerate() {
        let axis = own_axis(f);
        if order[axis] != usize::MAX {
            return None;
        }
        order[axis] = ci;
    }
    let row = |axis: usize| -> [f64; 4] {
        let c = &fits[order[axis]].1.coefficients;
        [c[0], c[1], c[2], c[3]]
    };
    let k = nalgebra::Matrix3::from_fn(|i, j| row(i)[j + 1]);
    let kinv = k.try_inverse()?;
    let resid = (0..pos.len())
        .map(|p| {
            let a = pos.accel[p];
            let r = nalgebra::Vector3::from_fn(|i, _| {
                let c = row(i);
                stats[order[i]].mean[p] - (c[0] + c[1] * a[0] + c[2] * a[1] + c[3] * a[2])
            });
            let ra = kinv * r;
            [ra[0], ra[1], ra[2]]
        })
        .collect();
    let mut cross = [0.0; 6];
    let mut n = 0;
    for c in 0..3 {
        for j in (0..3).filter(|&j| j != c) {
            cross[n] = row(c)[j + 1] / row(c)[c + 1] * 1e6;
            n += 1;
        }
    }
    Some(UnitObs {
        serial: String::new(),
        run_id: String::new(),
        started_unix_s: 0,
        positions: pos.dwells.iter().map(|d| (d.alpha_deg, d.beta_deg)).collect(),
        resid_m_s2: resid,
        misalign_urad: cross,
    })
}

/// The head's angle setting error measured across units: what the metrology's budget takes as
/// the head's measured contribution beside its certificate's stated one.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct MeasuredAngle {
    /// The RMS over the plan's head angles of the mean error each shows (arcsec), its
    /// units' noise taken out (each angle's squared mean less its squared standard error). On
    /// the 62-position plan model 4 takes little of random angle errors into its coefficients:
    /// the unit test `the_head_s_angle_error_is_measured_across_units` finds 0.97 to 1.01 of
    /// the RMS of the errors drawn (30″ per angle, four heads of 150 units).
    pub rms_arcsec: f64,
    /// Units it is the mean of: those since the last change point.
    pub units: usize,
    /// Head angles it is the RMS over (two per position, less those a position cannot show:
    /// α at β = ±90°).
    pub angles: usize,
}

/// Units needed since the last change point before [`MeasuredAngle`] is stated.
pub const MEASURED_MIN_UNITS: usize = 10;

/// The head's angle error from the angle statistics of the units since the last change (one
/// row per unit; `to_unit` their factors to arcsec, 0 for an angle a position cannot show):
/// `None` before [`MEASURED_MIN_UNITS`] units.
fn measured_angle(recent: &[Vec<f64>], to_unit: &[f64]) -> Option<MeasuredAngle> {
    if recent.len() < MEASURED_MIN_UNITS {
        return None;
    }
    let n = recent.len() as f64;
    let (mut sum, mut angles) = (0.0, 0);
    for (q, &f) in to_unit.iter().enumerate().filter(|(_, f)| **f != 0.0) {
        let (m, sd) = mean_sd(&recent.iter().map(|v| v[q]).collect::<Vec<_>>());
        sum += (m * m - sd * sd / n) * f * f;
        angles += 1;
    }
    (angles > 0).then(|| MeasuredAngle {
        rms_arcsec: (sum / angles as f64).max(0.0).sqrt(),
        units: recent.len(),
        angles,
    })
}

/// The tracking's settings.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Settings {
    /// Units before the first that is tracked: the least reference a chart starts from.
    pub baseline: usize,
    /// Each CUSUM's reference value as a share of the change it is tuned to (0.5: the CUSUM
    /// optimal for that change, Moustakides 1986).
    pub k: f64,
    /// The decision interval, standard deviations, of a CUSUM tuned to a change of one
    /// standard deviation per unit; each CUSUM's own is Siegmund's for its change at the same
    /// in-control run length ([`chart::decision_interval`]).
    pub h: f64,
    /// The head certificate's angle setting uncertainty (arcsec, standard): the prior of the
    /// head's signature at every angle until the first change point (0: none, the signature
    /// learned from the units alone).
    #[serde(skip)]
    pub head_u_arcsec: f64,
    /// The head angle change each angle's CUSUM is tuned to, arcsec.
    #[serde(skip)]
    pub design_arcsec: f64,
    /// The mount rotation each mount term's CUSUM is tuned to, µrad.
    #[serde(skip)]
    pub design_mount_urad: f64,
}

impl Settings {
    /// Each one-sided CUSUM's in-control average run length: [`CUSUMS`] times
    /// [`DESIGN_UNITS_PER_FALSE_ALARM`].
    pub fn arl0(&self) -> f64 {
        CUSUMS * DESIGN_UNITS_PER_FALSE_ALARM
    }

    /// A CUSUM's reference value and decision interval (standard deviations) for a change of
    /// `shift` standard deviations per unit (`k` held within 0.05 to 2).
    pub fn tuned(&self, shift: f64) -> (f64, f64) {
        let k = (self.k * shift).clamp(0.05, 2.0);
        (k, chart::decision_interval(k, self.arl0()))
    }
}

/// Units of a true head per false alarm the default settings are designed for: the union of
/// [`CUSUMS`] one-sided CUSUMs, each given [`CUSUMS`] times this in-control run length.
pub const DESIGN_UNITS_PER_FALSE_ALARM: f64 = 5000.0;

/// One-sided CUSUMs on the 62-position plan: two per statistic, 122 head angles (α cannot show
/// at β = ±90°) and 6 mount terms.
pub const CUSUMS: f64 = 256.0;

impl Default for Settings {
    /// From the 5th unit (a reference of 4); each angle's CUSUM tuned to 0.5 mrad (103″) of
    /// that angle, each mount term's to 1 mrad, the smallest changes issue 60 names, k = half
    /// the change; h for one false alarm in [`DESIGN_UNITS_PER_FALSE_ALARM`] units of a true
    /// head; no prior of the head's signature (`fleet` gives the head certificate's).
    fn default() -> Settings {
        let mut s = Settings {
            baseline: 4,
            k: 0.5,
            h: 0.0,
            head_u_arcsec: 0.0,
            design_arcsec: 0.5e-3 / ARCSEC,
            design_mount_urad: 1000.0,
        };
        s.h = s.tuned(1.0).1;
        s
    }
}

/// A unit at which the head changed.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ChangePoint {
    /// The unit whose run triggered the flag.
    pub serial: String,
    /// Its run.
    pub run_id: String,
    /// When it started, Unix seconds.
    pub started_unix_s: i64,
    /// Its place among the head's units, from 0.
    pub index: usize,
    /// The rule: the CUSUM and the statistic that passed h.
    pub rule: String,
    /// The estimated shift: arcsec of head angle at a position, µrad of a mount term ([`MOUNT_TERMS`]).
    pub estimate: f64,
    /// The estimate's unit.
    pub unit: &'static str,
}

/// The head's residual pattern at one position.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct PositionSignature {
    /// Commanded α, degrees.
    pub alpha_deg: f64,
    /// Commanded β, degrees.
    pub beta_deg: f64,
    /// Mean residual over the units, m/s².
    pub mean_m_s2: [f64; 3],
    /// Its standard error, m/s².
    pub se_m_s2: [f64; 3],
    /// `|mean|/g` as a head angle, arcsec.
    pub arcsec: f64,
}

/// The head's residual pattern.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Signature {
    /// Units left out: another plan than the first unit's.
    pub other_plan: usize,
    /// Units the signature is the mean of: those since the last change point.
    pub since_last_change: usize,
    /// Per position.
    pub positions: Vec<PositionSignature>,
    /// The mean misalignments over the same units, µrad, in [`CROSS_TERMS`]' order.
    pub misalign_urad: [f64; 6],
    /// The same as [`mount_terms`], µrad, in [`MOUNT_TERMS`]' order.
    pub mount_urad: [f64; 6],
    /// The head's angle setting error as these units measure it ([`measured_angle`]).
    pub measured_angle: Option<MeasuredAngle>,
    /// The tracking's settings.
    pub settings: Settings,
}

impl Head {
    /// The tracking's settings in words, and what it needs before it can flag.
    pub fn settings_line(&self) -> String {
        let s = self.signature.settings;
        if self.units <= s.baseline {
            format!(
                "tracked from unit {}: a reference of {} units, CUSUM k = {}, h = {:.2}",
                s.baseline + 1,
                s.baseline,
                s.k,
                s.h
            )
        } else {
            format!("reference from {} units, CUSUM k = {}, h = {:.2}", s.baseline, s.k, s.h)
        }
    }
}

/// One head's units tracked: how many, its signature, its change points (oldest first).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Head {
    /// Units tracked (those on the first unit's plan).
    pub units: usize,
    /// The signature.
    pub signature: Signature,
    /// The change points, oldest first.
    pub change_points: Vec<ChangePoint>,
}

fn mean_sd(v: &[f64]) -> (f64, f64) {
    let n = v.len().max(1) as f64;
    let m = v.iter().sum::<f64>() / n;
    let sd =
        if v.len() > 1 { (v.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / (n - 1.0)).sqrt() } else { 0.0 };
    (m, sd)
}

/// What the head can do to the cross terms, in [`MOUNT_TERMS`]' order (µrad): the mount's
/// rotation about x, y and z (`(z→y − y→z)/2`, `(x→z − z→x)/2`, `(y→x − x→y)/2`: a rotation ψ of
/// the block about an axis moves the two cross terms of the other axes by ∓ψ, and their half
/// difference by ψ), then the half sums, the block's non-orthogonality as the head sees it, which
/// a rotation leaves alone. An orthogonal change of the six misalignments (scaled by 1/√2): a
/// rotation of the mount shows in one statistic at √2 times its share of the units' own spread.
pub fn mount_terms(m: &[f64; 6]) -> [f64; 6] {
    [
        (m[5] - m[3]) / 2.0,
        (m[1] - m[4]) / 2.0,
        (m[2] - m[0]) / 2.0,
        (m[3] + m[5]) / 2.0,
        (m[1] + m[4]) / 2.0,
        (m[0] + m[2]) / 2.0,
    ]
}

/// The names of [`mount_terms`].
pub const MOUNT_TERMS: [&str; 6] = [
    "the mount's rotation about x",
    "the mount's rotation about y",
    "the mount's rotation about z",
    "the non-orthogonality y–z",
    "the non-orthogonality x–z",
    "the non-orthogonality x–y",
];

/// The directions a plan's head angles move the acceleration: for each position, along `∂a/∂α`
/// then `∂a/∂β`, the unit vector (zero where the angle moves nothing: α at β = ±90°) and the
/// factor from m/s² along it to arcsec of head angle (`1/|∂a/∂θ|`; 0 there). The same for every
/// unit on the plan, so [`track`] derives them once.
fn directions(plan: &[(f64, f64)], g: f64) -> Vec<([f64; 3], f64)> {
    const H: f64 = 1e-6;
    let mut out = Vec::with_capacity(2 * plan.len());
    for &(al, be) in plan {
        for (da, db) in [(H, 0.0), (0.0, H)] {
            let plus = accelcal_shared::gravity(al + da.to_degrees(), be + db.to_degrees(), g);
            let minus = accelcal_shared::gravity(al - da.to_degrees(), be - db.to_degrees(), g);
            let d: [f64; 3] = std::array::from_fn(|j| (plus[j] - minus[j]) / (2.0 * H));
            let norm = d.iter().map(|x| x * x).sum::<f64>().sqrt();
            // |∂a/∂α| = g·|cos β|: nothing to see of α at β = ±90°.
            out.push(if norm > 1e-6 * g {
                (d.map(|x| x / norm), 1.0 / norm / ARCSEC)
            } else {
                ([0.0; 3], 0.0)
            });
        }
    }
    out
}

/// The statistics of a unit on the plan of `dirs` ([`directions`]): at every position, its
/// residual along `∂a/∂α` and along `∂a/∂β` (m/s²: the part of a head angle error model 4 did
/// not absorb, times `|∂a/∂θ|`), then the six [`mount_terms`] (µrad).
fn statistics(u: &UnitObs, dirs: &[([f64; 3], f64)]) -> Vec<f64> {
    let mut out = Vec::with_capacity(dirs.len() + 6);
    for (r, pair) in u.resid_m_s2.iter().zip(dirs.chunks(2)) {
        out.extend(pair.iter().map(|(d, _)| (0..3).map(|j| d[j] * r[j]).sum::<f64>()));
    }
    out.extend(mount_terms(&u.misalign_urad));
    out
}

/// The normal quantile of a Student t value `t` with `nu` degrees of freedom: Wallace's
/// approximation (Ann. Math. Statist. 30, 1959), `z = (8ν + 1)/(8ν + 3)·√(ν·ln(1 + t²/ν))` with
/// the sign of `t`; within 0.02 of the exact transformation for ν ≥ 20 and |t| ≤ 10 (tested
/// against statrs).
fn t_to_normal(t: f64, nu: f64) -> f64 {
    let z = (8.0 * nu + 1.0) / (8.0 * nu + 3.0) * (nu * (t * t / nu).ln_1p()).sqrt();
    z.copysign(t)
}

/// The stated variance of each statistic of a unit ([`statistics`]' order; 0 for a mount term
/// and for an angle a position cannot show): its fit's residual variance per axis, what its
/// least-squares covariance is stated from, without the statistic's own position (the
/// externally studentised residual of regression diagnostics: a head angle knocked off does not
/// inflate the variance it is tested against), `s_j² = (Σ_p r_pj² − r_qj²) / (positions − 4 −
/// (1 − h_qq))`, along the statistic's direction, times the share `1 − h_qq` a residual keeps.
fn stated_variances(u: &UnitObs, dirs: &[([f64; 3], f64)], keep: &[f64]) -> Vec<f64> {
    let dof = u.resid_m_s2.len() as f64 - 4.0;
    let total: [f64; 3] = std::array::from_fn(|j| u.resid_m_s2.iter().map(|r| r[j] * r[j]).sum::<f64>());
    let mut out: Vec<f64> = dirs
        .iter()
        .enumerate()
        .map(|(q, (d, f))| {
            let (p, k) = (q / 2, keep[q / 2]);
            if *f == 0.0 || dof - k <= 0.0 {
                return 0.0;
            }
            let r = u.resid_m_s2[p];
            k * (0..3).map(|j| d[j] * d[j] * (total[j] - r[j] * r[j]) / (dof - k)).sum::<f64>()
        })
        .collect();
    out.extend([0.0; 6]);
    out
}

/// The units of a head on its first unit's plan, with what [`track`] and the study's oracle
/// read of them.
pub(crate) struct Prepared<'a> {
    /// The plan.
    pub plan: Vec<(f64, f64)>,
    /// The units on it, in time order.
    pub on: Vec<&'a UnitObs>,
    /// Per unit, its statistics ([`statistics`]).
    pub stats: Vec<Vec<f64>>,
    /// Per unit, their stated variances ([`stated_variances`]).
    pub vars: Vec<Vec<f64>>,
    /// Per statistic, its factor to its unit: arcsec of head angle (0 where none shows), or 1
    /// for a mount term (µrad).
    pub to_unit: Vec<f64>,
    /// Per statistic, the share of a head angle's change its residual keeps (1 for a mount term).
    pub keep: Vec<f64>,
}

pub(crate) fn prepare(units: &[UnitObs], g: f64) -> Prepared<'_> {
    let plan = units.first().map(|u| u.positions.clone()).unwrap_or_default();
    let same = |u: &&UnitObs| {
        u.positions.len() == plan.len()
            && u.positions
                .iter()
                .zip(&plan)
                .all(|(a, b)| (a.0 - b.0).abs() < 1e-6 && (a.1 - b.1).abs() < 1e-6)
    };
    let on: Vec<&UnitObs> = units.iter().filter(same).collect();
    let dirs = directions(&plan, g);
    let kept = chart::kept_share(&plan, g);
    let stats = on.iter().map(|u| statistics(u, &dirs)).collect();
    let vars = on.iter().map(|u| stated_variances(u, &dirs, &kept)).collect();
    let to_unit = dirs.iter().map(|d| d.1).chain([1.0; 6]).collect();
    let keep = (0..2 * plan.len()).map(|q| kept[q / 2]).chain([1.0; 6]).collect();
    Prepared { plan, on, stats, vars, to_unit, keep }
}

/// A two-sided CUSUM: its upper and lower sums, each with the unit at which it last left 0.
#[derive(Clone, Copy, Default)]
struct Cusum {
    up: (f64, usize),
    down: (f64, usize),
}

/// Tracks the units of one head in time order (the caller's), at gravity `g` (m/s²).
///
/// From unit `baseline + 1` of the head (and of each stretch after a change point) every
/// statistic of each unit is standardised ([`chart`]): an angle statistic by its own stated
/// variance about the head's signature learned from the earlier units (precision-weighted, the
/// certificate's angle uncertainty its prior); a mount term about the earlier units' mean and
/// spread. A reference takes in the units up to `lag` before the one it standardises (at least
/// the stretch's first `baseline`). Each standardised value feeds a two-sided CUSUM; the first
/// unit whose CUSUM passes `h` is a change point, and a new stretch starts at the unit where
/// that CUSUM last left 0.
pub fn track(units: &[UnitObs], g: f64, s: Settings) -> Head {
    let Prepared { plan, on, stats, vars, to_unit, keep } = prepare(units, g);
    let n_pos = plan.len();
    let n_stat = 2 * n_pos + 6;
    let nu = (n_pos as f64 - 5.0).max(1.0);
    let prior: Vec<f64> = (0..n_stat)
        .map(|q| {
            if q < 2 * n_pos && to_unit[q] != 0.0 {
                (keep[q] * s.head_u_arcsec / to_unit[q]).powi(2)
            } else {
                0.0
            }
        })
        .collect();
    // After a change point the certificate no longer speaks for the head: no prior.
    let fresh = |first: bool| {
        prior.iter().map(|&p| chart::Reference::with_prior(if first { p } else { 0.0 })).collect::<Vec<_>>()
    };
    let mut refs = fresh(true);
    let mut sums = vec![Cusum::default(); n_stat];
    // Per angle statistic, its CUSUM's (k, h) for the design change, set at each stretch's
    // first tracked unit from its reference's stated variances.
    let mut tuned = vec![(0.0, f64::INFINITY); n_stat];
    let mut tuned_for = None;
    let mut change_points = Vec::new();
    let (mut start, mut added) = (0, 0);
    let base = s.baseline.max(3);
    for i in 0..on.len() {
        if i < start + base {
            continue;
        }
        while added < i {
            for (q, r) in refs.iter_mut().enumerate() {
                r.add(stats[added][q], vars[added][q]);
            }
            added += 1;
        }
        if tuned_for != Some(start) {
            tuned_for = Some(start);
            for q in (0..2 * n_pos).filter(|&q| to_unit[q] != 0.0) {
                let r = &refs[q];
                let sd = (r.mean_var() + r.weighted().1.min(r.mean_var())).sqrt();
                tuned[q] = s.tuned(keep[q] * s.design_arcsec / to_unit[q] / sd);
            }
        }
        let mut flag: Option<(usize, bool, f64)> = None;
        for q in 0..n_stat {
            let x = stats[i][q];
            let z = if q < 2 * n_pos {
                if to_unit[q] == 0.0 || vars[i][q] <= 0.0 {
                    continue;
                }
                let (m, p) = refs[q].weighted();
                t_to_normal((x - m) / (vars[i][q] + p).sqrt(), nu)
            } else {
                let r = refs[q];
                if r.n < 2.0 || r.sd() <= 0.0 {
                    continue;
                }
                let sd = r.sd() * (1.0 + 1.0 / r.n).sqrt();
                tuned[q] = s.tuned(s.design_mount_urad / sd);
                chart::t_to_normal_exact((x - r.mean) / sd, r.n - 1.0)
            };
            let (k, h) = tuned[q];
            let c = &mut sums[q];
            for (side, dir) in [(&mut c.up, 1.0), (&mut c.down, -1.0)] {
                if side.0 == 0.0 {
                    side.1 = i;
                }
                side.0 = (side.0 + dir * z - k).max(0.0);
            }
            // The CUSUMs compared by how far past their own h they are.
            for (v, is_up) in [(c.up.0 / h, true), (c.down.0 / h, false)] {
                if v > 1.0 && v > flag.map_or(0.0, |f| f.2) {
                    flag = Some((q, is_up, v));
                }
            }
        }
        if let Some((q, is_up, _)) = flag {
            let from = if is_up { sums[q].up.1 } else { sums[q].down.1 };
            let v: Vec<f64> = stats[from..=i].iter().map(|v| v[q]).collect();
            let reference = if q < 2 * n_pos { refs[q].weighted().0 } else { refs[q].mean };
            let estimate = (mean_sd(&v).0 - reference) * to_unit[q] / keep[q];
            let dir = if is_up { "up" } else { "down" };
            let (rule, unit) = if q < 2 * n_pos {
                let p = q / 2;
                let angle = if q % 2 == 0 { "α" } else { "β" };
                (
                    format!(
                        "CUSUM {dir} of the {angle} error at position {} (α {}°, β {}°)",
                        p + 1,
                        plan[p].0,
                        plan[p].1
                    ),
                    "arcsec",
                )
            } else {
                (format!("CUSUM {dir} of {}", MOUNT_TERMS[q - 2 * n_pos]), "µrad")
            };
            let u = on[i];
            change_points.push(ChangePoint {
                serial: u.serial.clone(),
                run_id: u.run_id.clone(),
                started_unix_s: u.started_unix_s,
                index: i,
                rule,
                estimate,
                unit,
            });
            start = from;
            added = start;
            refs = fresh(false);
            sums.iter_mut().for_each(|c| *c = Cusum::default());
        }
    }
    let recent = &stats[start.min(stats.len())..];
    let recent_units = &on[start.min(on.len())..];
    let positions = (0..n_pos)
        .map(|p| {
            let ms: [(f64, f64); 3] = std::array::from_fn(|j| {
                mean_sd(&recent_units.iter().map(|u| u.resid_m_s2[p][j]).collect::<Vec<_>>())
            });
            let n = recent.len().max(1) as f64;
            let mean = ms.map(|x| x.0);
            PositionSignature {
                alpha_deg: plan[p].0,
                beta_deg: plan[p].1,
                mean_m_s2: mean,
                se_m_s2: ms.map(|x| x.1 / n.sqrt()),
                arcsec: mean.iter().map(|x| x * x).sum::<f64>().sqrt() / g / ARCSEC,
            }
        })
        .collect();
    let misalign_urad = std::array::from_fn(|m| {
        mean_sd(&recent_units.iter().map(|u| u.misalign_urad[m]).collect::<Vec<_>>()).0
    });
    let mount_urad =
        std::array::from_fn(|m| mean_sd(&recent.iter().map(|v| v[2 * n_pos + m]).collect::<Vec<_>>()).0);
    Head {
        units: on.len(),
        signature: Signature {
            other_plan: units.len() - on.len(),
            since_last_change: recent.len(),
            positions,
            misalign_urad,
            mount_urad,
            measured_angle: measured_angle(recent, &to_unit[..(2 * n_pos).min(to_unit.len())]),
            settings: s,
        },
        change_points,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_position_knocked_off_at_unit_10_is_flagged_after_it_and_a_true_head_is_not() {
        let g = accelcal_shared::G_STANDARD;
        // A head whose certificate states 3″.
        let s = Settings { head_u_arcsec: 3.0, ..Settings::default() };
        let quiet = simulate_fleet(120, 0, HeadChange::None, 3, 80.0, 100, 0.002);
        let q = track(&quiet, g, s);
        assert!(q.change_points.is_empty(), "{:?}", q.change_points);
        assert_eq!((q.units, q.signature.since_last_change, q.signature.positions.len()), (120, 120, 62));
        let off = simulate_fleet(60, 10, HeadChange::Offset { position: 26, mrad: 0.5 }, 3, 80.0, 100, 0.002);
        let sig = track(&off, g, s);
        let first = sig.change_points.first().expect("flagged");
        // A median of about 20 units on the bench (`accelcal bench-signature`); this fleet 13.
        assert!((10..40).contains(&first.index), "{first:?}");
        assert!(first.rule.contains("α error at position 27 (α 60°, β 0°)"), "{first:?}");
        // 0.5 mrad is 103″: the estimate takes back the share model 4 absorbs; taken when the
        // CUSUM passes h, it is biased up by the noise that helped it there (here 147″).
        assert!((70.0..170.0).contains(&first.estimate), "{first:?}");
        // The signature since the change shows it at that position and nowhere near as much
        // elsewhere.
        let at = sig.signature.positions[26].arcsec;
        let others =
            sig.signature.positions.iter().enumerate().filter(|(p, _)| *p != 26).map(|(_, x)| x.arcsec);
        assert!(at > 60.0 && others.fold(0.0, f64::max) < at / 2.0, "{at}");
    }

    #[test]
    fn tracking_starts_at_the_fifth_unit() {
        let g = accelcal_shared::G_STANDARD;
        let s = Settings { head_u_arcsec: 3.0, ..Settings::default() };
        // 10 mrad from the 5th unit (index 4): flagged by the next (a unit's t with 57 degrees
        // of freedom is at most about 11 standard normal deviations, short of h + k); on the
        // first four units nothing can be.
        let at4 = simulate_fleet(8, 4, HeadChange::Offset { position: 26, mrad: 10.0 }, 4, 80.0, 100, 0.002);
        let first = track(&at4, g, s).change_points.first().cloned().expect("flagged");
        assert!((4..=5).contains(&first.index), "{first:?}");
        let few = track(&at4[..4], g, s);
        assert!(few.change_points.is_empty() && few.settings_line().starts_with("tracked from unit 5"));
    }

    #[test]
    fn a_head_outside_its_certificate_is_flagged_once_then_is_its_own_reference() {
        // Every angle off by a draw of 30″, the certificate stating 3″: the prior is wrong, the
        // largest error is flagged against it (a 3σ draw of 30″), and after that change point
        // the head's own units are the reference, with no further flag in 150 units.
        let g = accelcal_shared::G_STANDARD;
        let s = Settings { head_u_arcsec: 3.0, ..Settings::default() };
        let fleet = simulate_fleet(150, 0, HeadChange::Errors { arcsec: 30.0, seed: 1 }, 1, 80.0, 100, 0.002);
        let head = track(&fleet, g, s);
        assert_eq!(head.change_points.len(), 1, "{:?}", head.change_points);
        let c = &head.change_points[0];
        assert!(c.index < 60 && c.estimate > 60.0, "{c:?}");
        // The same head without a certificate's prior: nothing to flag.
        assert!(track(&fleet, g, Settings::default()).change_points.is_empty());
    }

    #[test]
    fn the_angle_statistics_are_standard_normal_on_a_true_head() {
        // Standardised by each unit's stated variance about the true signature (0): mean 0 and
        // variance 1 over the units and angles, or the CUSUMs' false-alarm rate is not the design's.
        let g = accelcal_shared::G_STANDARD;
        let fleet = simulate_fleet(60, 0, HeadChange::None, 11, 80.0, 100, 0.002);
        let p = prepare(&fleet, g);
        let mut z = Vec::new();
        for (x, v) in p.stats.iter().zip(&p.vars) {
            z.extend((0..2 * p.plan.len()).filter(|&q| v[q] > 0.0).map(|q| x[q] / v[q].sqrt()));
        }
        let (m, sd) = mean_sd(&z);
        assert!(m.abs() < 0.03 && (0.95..1.05).contains(&sd), "{m} {sd} over {}", z.len());
    }

    #[test]
    fn a_mount_rotation_is_named_as_one_with_its_sign_and_size() {
        let g = accelcal_shared::G_STANDARD;
        let fleet = simulate_fleet(400, 250, HeadChange::Mount { mrad: 2.0 }, 5, 80.0, 100, 0.002);
        let head = track(&fleet, g, Settings::default());
        assert!(head.change_points.iter().all(|c| c.index >= 250), "{:?}", head.change_points);
        let first = head.change_points.first().expect("flagged");
        assert!(first.rule.contains("the mount's rotation about z"), "{first:?}");
        assert!((first.index - 250) < 60 && first.estimate > 1000.0, "{first:?}");
        // The terms: a rotation ψ about z is half the difference of y→x and x→y.
        let t = mount_terms(&[-1.0, 2.0, 1.0, -3.0, 4.0, 3.0]);
        assert_eq!(t, [3.0, -1.0, 1.0, 0.0, 3.0, 0.0]);
    }

    #[test]
    fn the_head_s_angle_error_is_measured_across_units() {
        let g = accelcal_shared::G_STANDARD;
        let mut ratios = Vec::new();
        for seed in 1..=4 {
            let fleet =
                simulate_fleet(150, 0, HeadChange::Errors { arcsec: 30.0, seed }, seed, 80.0, 100, 0.002);
            let head = track(&fleet, g, Settings::default());
            assert!(head.change_points.is_empty(), "{:?}", head.change_points);
            let m = head.signature.measured_angle.expect("measured");
            assert_eq!((m.units, m.angles), (150, 2 * 62 - 2), "{m:?}");
            // The draw's own RMS over the plan's angles that show.
            let (mut sum, mut n) = (0.0, 0.0);
            use rand::SeedableRng;
            use rand_distr::{Distribution, Normal};
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
            let e = Normal::new(0.0, 30.0).unwrap();
            for &(_, b) in &crate::sim::Plan::head().positions {
                let (da, db): (f64, f64) = (e.sample(&mut rng), e.sample(&mut rng));
                if b.abs() < 89.0 {
                    sum += da * da;
                    n += 1.0;
                }
                sum += db * db;
                n += 1.0;
            }
            ratios.push(m.rms_arcsec / (sum / n).sqrt());
        }
        let mean = ratios.iter().sum::<f64>() / 4.0;
        assert!(ratios.iter().all(|r| (0.9..1.1).contains(r)) && (0.95..1.05).contains(&mean), "{ratios:?}");
        // A true head measures near nothing.
        let quiet =
            track(&simulate_fleet(150, 0, HeadChange::None, 9, 80.0, 100, 0.002), g, Settings::default());
        assert!(
            quiet.signature.measured_angle.unwrap().rms_arcsec < 3.0,
            "{:?}",
            quiet.signature.measured_angle
        );
        // Too few units since the last change: not stated.
        let few = track(&simulate_fleet(9, 0, HeadChange::None, 9, 80.0, 100, 0.002), g, Settings::default());
        assert_eq!(few.signature.measured_angle, None);
    }
}

#[cfg(test)]
mod t_tests {
    #[test]
    fn wallace_matches_the_exact_t_to_normal_transformation() {
        use statrs::distribution::{ContinuousCDF, Normal, StudentsT};
        let n = Normal::new(0.0, 1.0).unwrap();
        for nu in [20.0, 49.0, 200.0, 5000.0] {
            let t = StudentsT::new(0.0, 1.0, nu).unwrap();
            for k in 1..=100 {
                let x = -(k as f64) / 10.0;
                let exact = n.inverse_cdf(t.cdf(x));
                let approx = super::t_to_normal(x, nu);
                assert!((approx - exact).abs() < 0.02, "ν {nu}, t {x}: {approx} vs {exact}");
                assert_eq!(super::t_to_normal(-x, nu), -approx);
            }
        }
    }
}
