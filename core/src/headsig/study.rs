//! Simulated fleets on one head and the study of the tracking on them (`accelcal bench-signature`):
//! how often, how soon and how near a change is flagged, beside an oracle CUSUM that knows the
//! change, and how often a true head is flagged.

use serde::Serialize;

use super::*;

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

/// The simulated fleets' misalignment spread, rad (each cross term's standard deviation).
pub const MISALIGN_SD: f64 = 0.002;

/// One case of [`study`]: how often, how soon and how near a change is flagged.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct StudyRow {
    /// The change.
    pub change: HeadChange,
    /// The unit (from 0) at which it comes.
    pub change_at: usize,
    /// Fleets simulated.
    pub fleets: usize,
    /// Units per fleet.
    pub units: usize,
    /// Per fleet, units after the change until the first flag at or after it (`None`: none in
    /// the fleet's remaining units).
    pub delays: Vec<Option<usize>>,
    /// Per flagged fleet, the estimate of that flag (arcsec or µrad).
    pub estimates: Vec<f64>,
    /// The change's true size in the estimate's unit (0 for none).
    pub true_change: f64,
    /// Flags before the change (false alarms), over the fleets; for no change, every flag.
    pub false_alarms: usize,
    /// The oracle's delays on the same fleets (empty for no change).
    pub oracle_delays: Vec<Option<usize>>,
    /// The oracle's CUSUM.
    pub oracle: Option<Oracle>,
}

/// The oracle detector of a change: a one-sided CUSUM on the one statistic the change moves,
/// told the statistic's in-control mean (0) and standard deviation (a unit's stated one for a
/// head angle, the simulated misalignment spread for a mount term) and the change's size and
/// sign, with `k` half the change in standard deviations and `h` for the same units per false
/// alarm as the tracking is designed for ([`super::DESIGN_UNITS_PER_FALSE_ALARM`]). It is the
/// limit the data allow a detector that knows where and how much to look for.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Oracle {
    /// The statistic's index ([`super::track`]'s order).
    pub statistic: usize,
    /// The change in it, in its standard deviations per unit (the mean over the units).
    pub shift_sd: f64,
    /// CUSUM reference value.
    pub k: f64,
    /// CUSUM decision interval.
    pub h: f64,
}

/// The statistic a change moves and by how much (in the statistic's own unit: m/s² for a head
/// angle's residual, µrad for a mount term), with the standard deviation the oracle is told
/// for a mount term; `None` for no change or a change of every angle.
fn moved(change: HeadChange, p: &Prepared<'_>) -> Option<(usize, f64, Option<f64>)> {
    let n_pos = p.plan.len();
    match change {
        HeadChange::Offset { position, mrad } => {
            let q = 2 * position;
            let arcsec = mrad * 1e-3 / ARCSEC;
            Some((q, p.keep[q] * arcsec / p.to_unit[q], None))
        }
        HeadChange::Mount { mrad } => {
            Some((2 * n_pos + 2, mrad * 1e3, Some(MISALIGN_SD * 1e6 / std::f64::consts::SQRT_2)))
        }
        HeadChange::None | HeadChange::Errors { .. } => None,
    }
}

/// The oracle of one fleet and its delay (`None`: not flagged).
type OracleRun = (Oracle, Option<usize>);

/// The oracle's delay on one fleet ([`Oracle`]).
fn oracle_delay(p: &Prepared<'_>, change: HeadChange, change_at: usize) -> Option<OracleRun> {
    let (q, delta, pop_sd) = moved(change, p)?;
    let sd = |i: usize| pop_sd.unwrap_or_else(|| p.vars[i][q].sqrt());
    let n = p.stats.len().max(1) as f64;
    let shift_sd = (0..p.stats.len()).map(|i| delta.abs() / sd(i)).sum::<f64>() / n;
    let k = shift_sd / 2.0;
    let h = super::chart::decision_interval(k, super::DESIGN_UNITS_PER_FALSE_ALARM);
    let mut c = 0.0;
    let mut delay = None;
    for i in 0..p.stats.len() {
        c = (c + delta.signum() * p.stats[i][q] / sd(i) - k).max(0.0);
        if c > h {
            if i >= change_at {
                delay = Some(i - change_at);
                break;
            }
            c = 0.0;
        }
    }
    Some((Oracle { statistic: q, shift_sd, k, h }, delay))
}

/// The change's true size in its estimate's unit (arcsec of head angle, µrad of mount rotation).
fn true_change(change: HeadChange) -> f64 {
    match change {
        HeadChange::Offset { mrad, .. } => mrad * 1e-3 / ARCSEC,
        HeadChange::Mount { mrad } => mrad * 1e3,
        HeadChange::None | HeadChange::Errors { .. } => 0.0,
    }
}

/// Simulates `fleets` fleets of `units` units for each change, introduced at unit `change_at`
/// (the tracking is not told), and tracks each beside the change's oracle ([`Oracle`]): the
/// measure of [`track`]'s power, estimates and false alarms. Fleet `f` has seed `f + 1`.
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
            let at = if change == HeadChange::None { units } else { change_at };
            let runs: Vec<(Head, Option<OracleRun>)> = (0..fleets)
                .into_par_iter()
                .map(|f| {
                    let fleet = simulate_fleet(units, at, change, f as u64 + 1, 80.0, 100, MISALIGN_SD);
                    let oracle = oracle_delay(&prepare(&fleet, g), change, at);
                    (track(&fleet, g, s), oracle)
                })
                .collect();
            let first = |sig: &Head| sig.change_points.iter().find(|c| c.index >= at).cloned();
            StudyRow {
                change,
                change_at: at,
                fleets,
                units,
                delays: runs.iter().map(|(t, _)| first(t).map(|c| c.index - at)).collect(),
                estimates: runs.iter().filter_map(|(t, _)| first(t).map(|c| c.estimate)).collect(),
                true_change: true_change(change),
                false_alarms: runs
                    .iter()
                    .map(|(t, _)| t.change_points.iter().filter(|c| c.index < at).count())
                    .sum(),
                oracle_delays: runs.iter().filter_map(|(_, o)| o.map(|o| o.1)).collect(),
                oracle: runs.iter().find_map(|(_, o)| o.map(|o| o.0)),
            }
        })
        .collect()
}
