//! The paper's Table 2: error of the calibrated acceleration after calibration by LSQ and by test
//! turns, on validation positions that neither fit used.
//!
//! Calibrated acceleration: when the channels form a triad (three channels whose sensitive axes
//! are x, y and z), the joint inversion `a = K⁻¹(u − u0)` the node computes; otherwise each channel
//! alone, `a_own = (u − u0 − Σ_{j≠own} k_j·a_j)/k_own`, with the cross-axis components taken from
//! the rig. The error of a channel is its calibrated acceleration along its own axis minus the
//! rig's, over every row of the validation positions. The rows are folded in one at a time
//! ([`ErrorAcc`]), so a campaign file can be streamed.

use std::path::Path;

use accelcal_shared::linear::{LinearCal, Model4};
use accelcal_shared::terms::MODEL_4;
use anyhow::Context;
use serde::Serialize;

use crate::campaign::{Campaign, CodeRange, Row, Warnings};
use crate::error::{bad, Classify, Kind, Plain, Setting, Worded, Wording};
use crate::lsq::{self, LsqFit};
use crate::positions::{ChannelStats, DwellAcc, Positions};
use crate::reduce::Reread;
use crate::testturn;

/// Mean and standard deviation of the acceleration error, m/s².
#[derive(Clone, Copy, Debug, Serialize, PartialEq)]
pub struct ErrorStats {
    /// Mean error, m/s².
    pub mean_error: f64,
    /// Standard deviation of the error, m/s².
    pub std_error: f64,
}

/// How calibrated acceleration is computed from the channels.
#[derive(Clone, Copy, Debug, Serialize, PartialEq, Eq)]
#[serde(rename_all = "kebab-case")]
pub enum Inversion {
    /// Joint `K⁻¹` of a triad.
    Triad,
    /// Each channel alone with the rig's cross-axis components.
    PerChannel,
}

/// Own axis of a fitted model-4 row: the largest |k|.
pub fn own_axis(fit: &LsqFit) -> usize {
    let k = &fit.coefficients[1..4];
    (0..3).max_by(|&a, &b| k[a].abs().total_cmp(&k[b].abs())).expect("three axes")
}

/// Calibrates rows with one model-4 fit per channel.
#[derive(Clone, Debug)]
pub struct Calibrator {
    /// Own axis of each channel.
    axes: Vec<usize>,
    /// Coefficients `[u0, kx, ky, kz]` of each channel.
    coefficients: Vec<[f64; 4]>,
    /// The joint inversion, when the channels form an invertible triad.
    inv: Option<LinearCal>,
}

impl Calibrator {
    /// The calibration of a set of model-4 fits (triad `K⁻¹` when the channels form one).
    pub fn new(fits: &[LsqFit]) -> Calibrator {
        let axes: Vec<usize> = fits.iter().map(own_axis).collect();
        let triad = fits.len() == 3 && {
            let mut s = axes.clone();
            s.sort_unstable();
            s == [0, 1, 2]
        };
        let inv = if triad {
            let mut m = Model4 { u0: [0.0; 3], k: [[0.0; 3]; 3] };
            // Row of K for axis j comes from the channel whose own axis is j.
            for (ci, f) in fits.iter().enumerate() {
                m.u0[axes[ci]] = f.coefficients[0];
                m.k[axes[ci]] = [f.coefficients[1], f.coefficients[2], f.coefficients[3]];
            }
            m.invert().ok()
        } else {
            None
        };
        let coefficients = fits.iter().map(|f| std::array::from_fn(|i| f.coefficients[i])).collect();
        Calibrator { axes, coefficients, inv }
    }

    /// How the calibrated acceleration is computed.
    pub fn inversion(&self) -> Inversion {
        if self.inv.is_some() {
            Inversion::Triad
        } else {
            Inversion::PerChannel
        }
    }

    /// The error of each channel's calibrated acceleration along its own axis, for one row with
    /// raw `codes` where the rig imposes `a`, into `out` (one per channel).
    pub fn errors(&self, a: [f64; 3], codes: &[f64], out: &mut [f64]) {
        if let Some(cal) = &self.inv {
            let mut u = [0.0; 3];
            for (ci, &ax) in self.axes.iter().enumerate() {
                u[ax] = codes[ci];
            }
            let ahat = cal.apply(u);
            for (ci, &ax) in self.axes.iter().enumerate() {
                out[ci] = ahat[ax] - a[ax];
            }
        } else {
            for (ci, c) in self.coefficients.iter().enumerate() {
                let own = self.axes[ci];
                let cross: f64 = (0..3).filter(|&j| j != own).map(|j| c[1 + j] * a[j]).sum();
                out[ci] = (codes[ci] - c[0] - cross) / c[1 + own] - a[own];
            }
        }
    }
}

/// The errors of one channel, folded in row by row: per validation position their sum (in row
/// order) and scatter, and their sum over all rows, so that the rows need not be kept.
#[derive(Clone, Debug, Default)]
pub struct ErrorAcc {
    total: f64,
    sums: Vec<f64>,
    accs: Vec<DwellAcc>,
}

impl ErrorAcc {
    /// Adds the error of one row of validation position `p` (positions numbered from 0 in the
    /// order their rows come).
    pub fn push(&mut self, p: usize, e: f64) {
        if p >= self.accs.len() {
            self.sums.resize(p + 1, 0.0);
            self.accs.resize(p + 1, DwellAcc::default());
        }
        self.total += e;
        self.sums[p] += e;
        self.accs[p].push(e);
    }

    /// Rows added.
    pub fn rows(&self) -> usize {
        self.accs.iter().map(DwellAcc::len).sum()
    }

    /// Mean error at each validation position.
    pub fn per_position(&self) -> Vec<f64> {
        self.sums.iter().zip(&self.accs).map(|(s, a)| s / a.len() as f64).collect()
    }

    /// Mean and sample standard deviation over all rows (the sum of squares pooled from the
    /// positions' scatter and their means' spread).
    pub fn stats(&self) -> ErrorStats {
        let n = self.rows() as f64;
        let mean = self.total / n;
        let ss: f64 = self
            .per_position()
            .iter()
            .zip(&self.accs)
            .map(|(m, a)| a.within_ss() + a.len() as f64 * (m - mean) * (m - mean))
            .sum();
        ErrorStats { mean_error: mean, std_error: (ss / (n - 1.0).max(1.0)).sqrt() }
    }
}

/// One channel's row of Table 2.
#[derive(Serialize, Clone, Debug)]
pub struct CompareChannel {
    /// Channel name.
    pub channel: String,
    /// Errors after the LSQ calibration.
    pub lsq: ErrorStats,
    /// Errors after the test-turn calibration.
    pub test_turns: ErrorStats,
}

/// The outcome of a comparison (its JSON is what `accelcal compare --json` writes).
#[derive(Serialize, Clone, Debug)]
pub struct Comparison {
    /// How calibrated acceleration was computed.
    pub inversion: Inversion,
    /// Number of validation positions.
    pub validation_positions: usize,
    /// Number of validation rows.
    pub validation_rows: usize,
    /// Table 2, one row per channel.
    pub channels: Vec<CompareChannel>,
    /// Mean error at each validation position, per method and channel (for the plots).
    #[serde(skip)]
    pub per_position: PerMethod<Vec<(String, Vec<f64>)>>,
}

/// One value for each of the two methods compared.
#[derive(Clone, Debug, PartialEq)]
pub struct PerMethod<T> {
    /// Least squares.
    pub lsq: T,
    /// Test turns.
    pub test_turns: T,
}

/// The two fits of a comparison and where they are validated.
struct Plan {
    /// The LSQ and the test-turn calibrations.
    cals: [Calibrator; 2],
    /// Without `--validate`: for each position of the campaign, its index among the validation
    /// positions, if it is one. With it: `None`, every position of the validation campaign is one.
    held: Option<Vec<Option<usize>>>,
}

/// Why two campaigns cannot be compared as asked.
#[derive(Debug, thiserror::Error)]
pub enum CompareError {
    /// A plan whose positions are all test-turn ones, with no validation campaign.
    #[error("{}", self.worded(&Plain).unwrap_or_default())]
    NothingToValidate,
    /// The validation campaign's code range is not the campaign's.
    #[error("{}", self.worded(&Plain).unwrap_or_default())]
    CodesDiffer {
        /// The campaign's range.
        codes: CodeRange,
        /// The validation campaign's.
        vcodes: CodeRange,
    },
}

impl Worded for CompareError {
    fn worded(&self, w: &dyn Wording) -> Option<String> {
        Some(match self {
            CompareError::NothingToValidate => format!(
                "the plan has no positions besides the test-turn ones to validate on; give {}",
                w.name(Setting::Validate)
            ),
            CompareError::CodesDiffer { codes, vcodes } => format!(
                "the validation campaign's codes are {vcodes}, the campaign's {codes} (state the range with a \
                 `# codes:` line or {})",
                w.name(Setting::Codes)
            ),
        })
    }
}

impl Classify for CompareError {
    fn kind(&self) -> Kind {
        Kind::BadInput
    }
}

impl Plan {
    /// Fits both methods on the dwell statistics. Without `validate`, the validation positions
    /// are every other position outside the test-turn positions, and the LSQ fit uses the rest.
    fn new(pos: &Positions, stats: &[ChannelStats], validate: bool) -> anyhow::Result<Plan> {
        let pairs = testturn::Pairs::find(pos)?;
        let used = pairs.used();
        let (fit_idx, held): (Vec<usize>, _) = if validate {
            ((0..pos.len()).collect(), None)
        } else {
            let others: Vec<usize> = (0..pos.len()).filter(|i| !used.contains(i)).collect();
            let held: Vec<usize> = others.iter().copied().skip(1).step_by(2).collect();
            if held.is_empty() {
                return Err(CompareError::NothingToValidate.into());
            }
            let fit_idx = (0..pos.len()).filter(|i| !held.contains(i)).collect();
            (fit_idx, Some((0..pos.len()).map(|i| held.iter().position(|&h| h == i)).collect()))
        };
        let lsq_fits: Vec<LsqFit> = stats
            .iter()
            .map(|s| {
                lsq::fit(pos, s, MODEL_4, Some(&fit_idx))
                    .map_err(|e| bad(format!("channel `{}`: {e}", s.name)))
            })
            .collect::<anyhow::Result<_>>()?;
        let tt_fits: Vec<LsqFit> = stats.iter().map(|s| testturn::fit(pos, s, &pairs)).collect();
        Ok(Plan { cals: [Calibrator::new(&lsq_fits), Calibrator::new(&tt_fits)], held })
    }

    /// Checks that the validation campaign has the campaign's channels.
    fn check_channels(names: &[String], vnames: &[String]) -> anyhow::Result<()> {
        if names != vnames {
            return Err(bad(format!(
                "the validation campaign's channels {vnames:?} differ from the campaign's {names:?}"
            )));
        }
        Ok(())
    }

    /// Checks that the validation campaign's codes have the campaign's range: the fits of one
    /// range are meaningless on codes of the other.
    fn check_codes(codes: CodeRange, vcodes: CodeRange) -> anyhow::Result<()> {
        if codes != vcodes {
            return Err(CompareError::CodesDiffer { codes, vcodes }.into());
        }
        Ok(())
    }
}

/// The errors of both methods on the validation rows, folded in one row at a time.
struct Validation {
    plan: Plan,
    g: f64,
    /// Per method, per channel.
    errors: [Vec<ErrorAcc>; 2],
    buf: Vec<f64>,
}

impl Validation {
    fn new(plan: Plan, nch: usize, g: f64) -> Validation {
        let errors = [vec![ErrorAcc::default(); nch], vec![ErrorAcc::default(); nch]];
        Validation { plan, g, errors, buf: vec![0.0; nch] }
    }

    /// Adds one row of the validation campaign (dwell `k`).
    fn push(&mut self, k: usize, row: &Row) {
        let p = match &self.plan.held {
            Some(held) => match held[k] {
                Some(p) => p,
                None => return,
            },
            None => k,
        };
        let a = accelcal_shared::gravity(row.alpha, row.beta, self.g);
        for (cal, errs) in self.plan.cals.iter().zip(&mut self.errors) {
            cal.errors(a, &row.codes, &mut self.buf);
            errs.iter_mut().zip(&self.buf).for_each(|(acc, &e)| acc.push(p, e));
        }
    }

    fn finish(self, names: &[String]) -> Comparison {
        let [lsq, tt] = &self.errors;
        let per_pos = |e: &[ErrorAcc]| -> Vec<(String, Vec<f64>)> {
            names.iter().zip(e).map(|(n, acc)| (n.clone(), acc.per_position())).collect()
        };
        Comparison {
            inversion: self.plan.cals[0].inversion(),
            validation_positions: lsq[0].per_position().len(),
            validation_rows: lsq[0].rows(),
            channels: names
                .iter()
                .enumerate()
                .map(|(i, n)| CompareChannel {
                    channel: n.clone(),
                    lsq: lsq[i].stats(),
                    test_turns: tt[i].stats(),
                })
                .collect(),
            per_position: PerMethod { lsq: per_pos(lsq), test_turns: per_pos(tt) },
        }
    }
}

/// Fits both methods on an in-memory campaign and measures their errors on `validate`, or
/// without it on every other position outside the test-turn positions (left out of the LSQ fit).
pub fn compute(c: &Campaign, validate: Option<&Campaign>, g: f64) -> anyhow::Result<Comparison> {
    let pos = Positions::new(c, g);
    let names: Vec<String> = c.channels.iter().map(|ch| ch.name.clone()).collect();
    let plan = Plan::new(&pos, &pos.channel_stats(c), validate.is_some())?;
    if let Some(v) = validate {
        Plan::check_channels(&names, &v.channels.iter().map(|ch| ch.name.clone()).collect::<Vec<_>>())?;
        Plan::check_codes(c.codes, v.codes)?;
    }
    let mut val = Validation::new(plan, names.len(), g);
    validate.unwrap_or(c).for_each_row(|k, row| val.push(k, row));
    Ok(val.finish(&names))
}

/// [`compute`] on campaign files, streamed in bounded memory: the fits from the dwell statistics
/// of one pass over `campaign`, the errors from a second pass over the validation rows (of
/// `validate`, or of `campaign` again). A `validate` file is checked in a pass of its own first,
/// so that, as with the in-memory reader, every file is refused before anything is fitted.
/// Both files are read in the code range `declared` (each file's `# codes:` line otherwise). The
/// readers' warnings go to `warnings`.
pub fn compute_files(
    campaign: &Path,
    validate: Option<&Path>,
    declared: Option<CodeRange>,
    g: f64,
    warnings: &mut Warnings,
) -> anyhow::Result<Comparison> {
    let r = crate::reduce::reduce_campaign(campaign, declared, warnings)?;
    let vr = validate.map(|v| crate::reduce::reduce_campaign(v, declared, warnings)).transpose()?;
    let first_pass = vr.as_ref().unwrap_or(&r);
    let ctx = || campaign.display().to_string();
    Plan::check_channels(&r.channels, &first_pass.channels).with_context(ctx)?;
    Plan::check_codes(r.codes, first_pass.codes).with_context(ctx)?;
    let plan = Plan::new(&r.positions(g), &r.channel_stats(), validate.is_some()).with_context(ctx)?;
    let vpath = validate.unwrap_or(campaign);
    let mut rows = Reread::open(vpath, declared, first_pass).context("reading the campaign")?;
    let mut val = Validation::new(plan, r.channels.len(), g);
    while let Some((k, row)) = rows.next_row().context("reading the campaign")? {
        val.push(k, row);
    }
    rows.finish().context("reading the campaign")?;
    Ok(val.finish(&r.channels))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::{simulate, SimConfig};

    /// A small campaign file with a few saturated rows (skipped by both readers).
    fn campaign_file(seed: u64) -> (Campaign, tempfile::NamedTempFile) {
        let (mut c, _) = simulate(&SimConfig { samples: 9, seed, ..SimConfig::default() });
        for i in [3, 100, 101, 250] {
            c.channels[i % 3].codes[i] = 65535.0;
        }
        let f = tempfile::NamedTempFile::new().unwrap();
        c.write(std::fs::File::create(f.path()).unwrap()).unwrap();
        (Campaign::read(f.path()).unwrap(), f)
    }

    #[test]
    fn streaming_compare_matches_the_in_memory_compare() {
        let (c, f) = campaign_file(3);
        let (v, vf) = campaign_file(4);
        let json = |r: &Comparison| serde_json::to_value(r).unwrap();
        let cases = [(compute(&c, None, 9.81), None), (compute(&c, Some(&v), 9.81), Some(vf.path()))];
        for (mem, validate) in cases {
            let (mem, streamed) = (
                mem.unwrap(),
                compute_files(f.path(), validate, None, 9.81, &mut Default::default()).unwrap(),
            );
            assert_eq!(json(&mem), json(&streamed));
            assert_eq!(mem.per_position, streamed.per_position);
            assert!(mem.validation_rows > 0);
        }
    }
}
