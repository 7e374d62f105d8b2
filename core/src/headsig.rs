//! The dividing head's signature across units (the line-level sim-to-real diagnosis): a head
//! error is the same for every unit calibrated on it, so it leaves the same pattern in every
//! unit's model-4 residuals (the part of a position's angle error that the linear model cannot
//! absorb), and a rotation of the mount, which model 4 absorbs, shifts the population of the
//! cross terms. Each single unit's verification on that head passes; the population does not.
//!
//! Per unit ([`observe`]): at each position the residual of the dwell means about the unit's
//! model-4 fit, as an acceleration (`K⁻¹·r`, m/s²), and its six misalignments δ (µrad). Across
//! units in time order ([`track`]): each position's residual read along `∂a/∂α` and `∂a/∂β`
//! (the head-angle errors model 4 left), and the misalignments as the mount's three rotations and
//! the block's three non-orthogonalities ([`mount_terms`]), each followed by a two-sided CUSUM
//! (Page 1954; reference value `k`, decision interval `h`, in standard deviations). The CUSUMs
//! are self-starting (Hawkins 1987): each unit is standardised by the mean and standard
//! deviation of that statistic over every unit before it since the last change point (at least
//! `baseline` of them), and its Student t taken to the normal quantile, so that while the head is
//! in control each CUSUM sees independent N(0, 1) values however few units came before. (A
//! baseline estimated once from its first 50 units biased every later value of a statistic by
//! that estimate's error; over 130 statistics some were biased enough that a true head was
//! flagged about once in 290 units.) The first unit whose CUSUM passes `h` is a change point,
//! with the statistic that passed and the estimated shift (the mean since its CUSUM last left
//! zero less the baseline's: arcsec of head angle at a position, µrad of a mount term). The
//! CUSUMs then start again with a new baseline. Because the baseline takes in every unit, a
//! change early in a head's history is partly absorbed before it is flagged (a change at the
//! 100th unit is half the baseline's after 100 more). [`Signature`] is the mean residual pattern
//! of the units since the last change point, with its standard error, per position.

use accelcal_shared::terms::MODEL_4;
use serde::Serialize;

use crate::calibrate::{fit_positions, Method};
use crate::compare::own_axis;
use crate::positions::{ChannelStats, Positions};

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
    /// Units before the first that is tracked (the self-starting baseline's least size).
    pub baseline: usize,
    /// CUSUM reference value, standard deviations.
    pub k: f64,
    /// CUSUM decision interval, standard deviations.
    pub h: f64,
}

impl Default for Settings {
    /// 50 units of baseline, k = 0.5, h = 14 (`accelcal bench-signature` measures the false
    /// alarms and the delays it gives: about one false alarm in 10,000 units of a true head, a
    /// union over the 260 one-sided CUSUMs).
    fn default() -> Settings {
        Settings { baseline: 50, k: 0.5, h: 14.0 }
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
                "tracked from unit {}: a baseline of {} units, CUSUM k = {}, h = {}",
                s.baseline + 1,
                s.baseline,
                s.k,
                s.h
            )
        } else {
            format!("baseline {} units, CUSUM k = {}, h = {}", s.baseline, s.k, s.h)
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

/// A running mean and standard deviation (Welford 1962).
#[derive(Clone, Copy, Default)]
struct Welford {
    n: f64,
    mean: f64,
    m2: f64,
}

impl Welford {
    fn add(&mut self, x: f64) {
        self.n += 1.0;
        let d = x - self.mean;
        self.mean += d / self.n;
        self.m2 += d * (x - self.mean);
    }

    fn sd(&self) -> f64 {
        if self.n > 1.0 {
            (self.m2 / (self.n - 1.0)).sqrt()
        } else {
            0.0
        }
    }
}

/// The normal quantile of a Student t value `t` with `nu` degrees of freedom: Wallace's
/// approximation (Ann. Math. Statist. 30, 1959), `z = (8ν + 1)/(8ν + 3)·√(ν·ln(1 + t²/ν))` with
/// the sign of `t`; within 0.02 of the exact transformation for ν ≥ 20 and |t| ≤ 10 (tested
/// against statrs).
fn t_to_normal(t: f64, nu: f64) -> f64 {
    let z = (8.0 * nu + 1.0) / (8.0 * nu + 3.0) * (nu * (t * t / nu).ln_1p()).sqrt();
    z.copysign(t)
}

/// Tracks the units of one head in time order (the caller's), at gravity `g` (m/s²).
pub fn track(units: &[UnitObs], g: f64, s: Settings) -> Head {
    let plan = units.first().map(|u| u.positions.clone()).unwrap_or_default();
    let same = |u: &&UnitObs| {
        u.positions.len() == plan.len()
            && u.positions
                .iter()
                .zip(&plan)
                .all(|(a, b)| (a.0 - b.0).abs() < 1e-6 && (a.1 - b.1).abs() < 1e-6)
    };
    let on: Vec<&UnitObs> = units.iter().filter(same).collect();
    let n_pos = plan.len();
    let n_stat = 2 * n_pos + 6;
    let mut change_points = Vec::new();
    let mut start = 0;
    let dirs = directions(&plan, g);
    let stats: Vec<Vec<f64>> = on.iter().map(|u| statistics(u, &dirs)).collect();
    // Each statistic's factor to its unit: arcsec of head angle, or 1 for a mount term (µrad).
    let to_unit: Vec<f64> = dirs.iter().map(|d| d.1).chain([1.0; 6]).collect();
    let base = s.baseline.max(3);
    // Self-starting (Hawkins 1987): each unit is standardised by the units since the last change
    // point that end `base` units before it (at least the first `base`), per statistic, so the
    // baseline grows as the head stays in control and a change reaches it only after the CUSUM
    // has had `base` units to see it; the Student t of the standardised value, with the
    // baseline's degrees of freedom, is taken to the normal quantile, so each CUSUM sees N(0, 1)
    // while the head is in control whatever the baseline's size. Up and down, with the index
    // each last left 0.
    let mut up = vec![(0.0, 0usize); n_stat];
    let mut down = vec![(0.0, 0usize); n_stat];
    let mut window = vec![Welford::default(); n_stat];
    let mut added = 0;
    for i in 0..on.len() {
        if i < start + base {
            continue;
        }
        // The baseline: every unit since the last change point before this one.
        while added < i {
            for (w, &x) in window.iter_mut().zip(&stats[added]) {
                w.add(x);
            }
            added += 1;
        }
        let b: Vec<(f64, f64)> = window.iter().map(|w| (w.mean, w.sd())).collect();
        let n = window.first().map_or(0.0, |w| w.n);
        // A new unit about a mean of n: its variance is σ²·(1 + 1/n).
        let inflate = (1.0 + 1.0 / n).sqrt();
        let mut flag: Option<(usize, bool)> = None;
        for q in 0..n_stat {
            let (m, sd) = b[q];
            if sd <= 0.0 || to_unit[q] == 0.0 {
                continue;
            }
            let z = t_to_normal((stats[i][q] - m) / (inflate * sd), n - 1.0);
            for (c, dir) in [(&mut up[q], 1.0), (&mut down[q], -1.0)] {
                if c.0 == 0.0 {
                    c.1 = i;
                }
                c.0 = (c.0 + dir * z - s.k).max(0.0);
            }
            for (c, is_up) in [(up[q], true), (down[q], false)] {
                let worst = flag.map_or(0.0, |(f, u)| if u { up[f].0 } else { down[f].0 });
                if c.0 > s.h && c.0 > worst {
                    flag = Some((q, is_up));
                }
            }
        }
        if let Some((q, is_up)) = flag {
            let from = if is_up { up[q].1 } else { down[q].1 };
            let v: Vec<f64> = stats[from..=i].iter().map(|v| v[q]).collect();
            let estimate = (mean_sd(&v).0 - b[q].0) * to_unit[q];
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
            start = i;
            up.iter_mut().chain(down.iter_mut()).for_each(|c| *c = (0.0, i));
            window.iter_mut().for_each(|w| *w = Welford::default());
            added = i;
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

/// A change of the head introduced into a simulated fleet.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
#[serde(rename_all = "snake_case", tag = "kind")]
pub enum HeadChange {
    /// None: every unit on a true head.
    None,
    /// One position's α off by `mrad` (the head reaches α + offset, the campaign says α).
    Offset {
        /// The position's index in the plan.
        position: usize,
        /// The offset, mrad.
        mrad: f64,
    },
    /// The block's mount rotated by `mrad` about z: every unit sees `R·a` for `a`.
    Mount {
        /// The rotation, mrad.
        mrad: f64,
    },
    /// Every position's α and β off by a draw of N(0, `arcsec`²), the same for every unit (a
    /// head whose setting errors are its own, drawn from seed `seed`).
    Errors {
        /// The errors' standard deviation, arcsec.
        arcsec: f64,
        /// The draw's seed.
        seed: u64,
    },
}

/// A simulated fleet on one head: `units` triads (the simulator's spread of biases, scale
/// factors and misalignments, `misalign_sd` rad, white noise `noise` codes, `samples` sets per
/// position of the 62-position plan), the head changed by `change` from unit `change_at` on.
pub fn simulate_fleet(
    units: usize,
    change_at: usize,
    change: HeadChange,
    seed: u64,
    noise: f64,
    samples: usize,
    misalign_sd: f64,
) -> Vec<UnitObs> {
    use crate::sim::{simulate, Plan, SimConfig};
    let g = accelcal_shared::G_STANDARD;
    (0..units)
        .map(|u| {
            let changed = u >= change_at;
            let nominal = Plan::head();
            let mut plan = nominal.clone();
            if let (true, HeadChange::Offset { position, mrad }) = (changed, change) {
                plan.positions[position].0 += (mrad * 1e-3).to_degrees();
            }
            if let (true, HeadChange::Errors { arcsec, seed }) = (changed, change) {
                use rand::SeedableRng;
                use rand_distr::{Distribution, Normal};
                let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
                let e = Normal::new(0.0, arcsec / 3600.0).expect("a finite standard deviation");
                for p in &mut plan.positions {
                    p.0 += e.sample(&mut rng);
                    p.1 += e.sample(&mut rng);
                }
            }
            let cfg = SimConfig {
                seed: seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ (u as u64 + 1),
                plan,
                samples,
                noise,
                misalign_sd,
                g,
                ..SimConfig::default()
            };
            let (mut c, truth) = simulate(&cfg);
            // The campaign states the commanded angles (the simulator writes `samples` rows per
            // position, in the plan's order).
            for (row, (a, b)) in c.alpha_deg.iter_mut().zip(c.beta_deg.iter_mut()).enumerate() {
                (*a, *b) = nominal.positions[row / samples];
            }
            if let (true, HeadChange::Mount { mrad }) = (changed, change) {
                // u = bias + K·R·a: each row gains K·(R − I)·a, R a rotation about z.
                let psi = mrad * 1e-3;
                for row in 0..c.alpha_deg.len() {
                    let a = accelcal_shared::gravity(c.alpha_deg[row], c.beta_deg[row], g);
                    let ra = [a[0] * psi.cos() - a[1] * psi.sin(), a[0] * psi.sin() + a[1] * psi.cos(), a[2]];
                    for (ch, t) in c.channels.iter_mut().zip(&truth.channels) {
                        let d: f64 = (0..3).map(|j| t.k[j] * (ra[j] - a[j])).sum();
                        ch.codes[row] = (ch.codes[row] + d).round();
                    }
                }
            }
            let pos = Positions::new(&c, g);
            let stats = pos.channel_stats(&c);
            UnitObs {
                serial: format!("SIM-{u:05}"),
                run_id: format!("sim-{u}"),
                started_unix_s: u as i64 * 3600,
                ..observe(&pos, &stats).expect("a simulated triad")
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_position_knocked_off_is_flagged_after_the_change_and_a_true_head_is_not() {
        let g = accelcal_shared::G_STANDARD;
        let s = Settings::default();
        let quiet = simulate_fleet(120, 0, HeadChange::None, 3, 80.0, 100, 0.002);
        let q = track(&quiet, g, s);
        assert!(q.change_points.is_empty(), "{:?}", q.change_points);
        assert_eq!((q.units, q.signature.since_last_change, q.signature.positions.len()), (120, 120, 62));
        let off =
            simulate_fleet(120, 60, HeadChange::Offset { position: 26, mrad: 1.0 }, 3, 80.0, 100, 0.002);
        let sig = track(&off, g, s);
        let first = sig.change_points.first().expect("flagged");
        assert!((60..80).contains(&first.index), "{first:?}");
        assert!(first.rule.contains("α error at position 27 (α 60°, β 0°)"), "{first:?}");
        // 1 mrad is 206 arcsec; model 4 absorbs a part of it.
        assert!((120.0..260.0).contains(&first.estimate), "{first:?}");
        // The signature since the change shows it at that position and nowhere near as much
        // elsewhere.
        let at = sig.signature.positions[26].arcsec;
        let others =
            sig.signature.positions.iter().enumerate().filter(|(p, _)| *p != 26).map(|(_, x)| x.arcsec);
        assert!(at > 120.0 && others.fold(0.0, f64::max) < at / 2.0, "{at}");
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

/// One case of [`study`]: how often, how soon and how near a change is flagged.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct StudyRow {
    /// The change.
    pub change: HeadChange,
    /// Fleets simulated.
    pub fleets: usize,
    /// Per fleet, units after the change until the first flag at or after it (`None`: none in
    /// the fleet's remaining units).
    pub delays: Vec<Option<usize>>,
    /// Per flagged fleet, the estimate of that flag (arcsec or µrad).
    pub estimates: Vec<f64>,
    /// Flags before the change (false alarms), over the fleets.
    pub false_alarms: usize,
}

/// Simulates `fleets` fleets of `units` units for each change, introduced at unit `change_at`
/// (the tracking is not told), and tracks each: the measure of [`track`]'s power and false alarms.
pub fn study(
    changes: &[HeadChange],
    fleets: usize,
    units: usize,
    change_at: usize,
    s: Settings,
) -> Vec<StudyRow> {
    use rayon::prelude::*;
    let g = accelcal_shared::G_STANDARD;
    changes
        .iter()
        .map(|&change| {
            let tracked: Vec<Head> = (0..fleets)
                .into_par_iter()
                .map(|f| {
                    track(&simulate_fleet(units, change_at, change, f as u64 + 1, 80.0, 100, 0.002), g, s)
                })
                .collect();
            let first = |sig: &Head| sig.change_points.iter().find(|c| c.index >= change_at).cloned();
            StudyRow {
                change,
                fleets,
                delays: tracked.iter().map(|t| first(t).map(|c| c.index - change_at)).collect(),
                estimates: tracked.iter().filter_map(|t| first(t).map(|c| c.estimate)).collect(),
                false_alarms: tracked
                    .iter()
                    .map(|t| t.change_points.iter().filter(|c| c.index < change_at).count())
                    .sum(),
            }
        })
        .collect()
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
