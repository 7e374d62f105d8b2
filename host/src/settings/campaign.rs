//! The settings of the commands on simulated or recorded campaigns that need no link to a node
//! (`demo`, `compare`, `diagnose`, `bench-diagnose`, `bench-signature`, `uncertainty-check`):
//! their command line checked and resolved into plain values before anything is opened.

use std::path::PathBuf;

use accelcal_core::campaign::CodeRange;
use accelcal_core::error::bad;

use crate::cli::{
    BenchDiagnoseArgs, BenchSignatureArgs, CompareArgs, DemoArgs, DiagnoseArgs, UncertaintyCheckArgs,
};

/// `accelcal demo`, settled.
#[derive(Clone, Debug, PartialEq)]
pub struct Demo {
    /// `--out`: the directory of the demo's files.
    pub out: PathBuf,
    /// `--seed` of the simulated unit.
    pub seed: u64,
}

/// `demo`'s settings.
pub fn demo(a: &DemoArgs) -> Demo {
    Demo { out: a.out.clone(), seed: a.seed }
}

/// What `compare` and `diagnose` read: the campaign, its range of codes, and where the JSON goes.
#[derive(Clone, Debug, PartialEq)]
pub struct Campaign {
    /// The campaign file.
    pub path: PathBuf,
    /// `--codes` (`None`: the campaign's `# codes:` line, else unsigned16).
    pub codes: Option<CodeRange>,
    /// `--json`.
    pub json: Option<PathBuf>,
}

/// `accelcal compare`, settled.
#[derive(Clone, Debug, PartialEq)]
pub struct Compare {
    pub campaign: Campaign,
    /// `--validate`: a second campaign the fits are judged on.
    pub validate: Option<PathBuf>,
    /// `--plot`.
    pub plot: Option<PathBuf>,
}

/// `compare`'s settings (its files' distinctness is checked by `settings::check`).
pub fn compare(a: &CompareArgs) -> Compare {
    Compare {
        campaign: Campaign { path: a.campaign.clone(), codes: a.common.codes, json: a.common.json.clone() },
        validate: a.validate.clone(),
        plot: a.plot.clone(),
    }
}

/// `accelcal diagnose`, settled.
#[derive(Clone, Debug, PartialEq)]
pub struct Diagnose {
    pub campaign: Campaign,
    /// `--terms`: the model's terms.
    pub terms: accelcal_shared::Structure,
    /// `--plot`.
    pub plot: Option<PathBuf>,
}

/// `diagnose`'s settings (its files' distinctness is checked by `settings::check`).
pub fn diagnose(a: &DiagnoseArgs) -> anyhow::Result<Diagnose> {
    Ok(Diagnose {
        campaign: Campaign { path: a.campaign.clone(), codes: a.common.codes, json: a.common.json.clone() },
        terms: accelcal_core::lsq::parse_terms(&a.terms).map_err(|e| bad(format!("--terms {e}")))?,
        plot: a.plot.clone(),
    })
}

/// `accelcal bench-diagnose`, settled.
#[derive(Clone, Debug, PartialEq)]
pub struct BenchDiagnose {
    /// `--campaigns`, at least one.
    pub campaigns: usize,
    /// `--seed`: the master seed.
    pub seed: u64,
    /// `--magnitude LO:HI`, times the per-position noise: 0 < LO ≤ HI.
    pub magnitude: (f64, f64),
    /// `--json`.
    pub json: Option<PathBuf>,
}

/// `bench-diagnose`'s settings.
pub fn bench_diagnose(a: &BenchDiagnoseArgs) -> anyhow::Result<BenchDiagnose> {
    if a.campaigns == 0 {
        return Err(bad("--campaigns must be >= 1"));
    }
    let v: Vec<Option<f64>> = a.magnitude.split(':').map(|x| x.trim().parse::<f64>().ok()).collect();
    let magnitude = match v[..] {
        [Some(lo), Some(hi)] if lo.is_finite() && hi.is_finite() && lo > 0.0 && hi >= lo => (lo, hi),
        _ => return Err(bad(format!("--magnitude `{}`: expected LO:HI with 0 < LO <= HI", a.magnitude))),
    };
    Ok(BenchDiagnose { campaigns: a.campaigns, seed: a.seed, magnitude, json: a.json.clone() })
}

/// `accelcal bench-signature`, settled.
#[derive(Clone, Debug, PartialEq)]
pub struct BenchSignature {
    /// `--fleets`, `--units` per fleet, `--change-at`: the unit at which the head changes, after
    /// the tracking's baseline and before the last unit.
    pub fleets: u32,
    pub units: u32,
    pub change_at: u32,
    /// `--json`.
    pub json: Option<PathBuf>,
}

/// `bench-signature`'s settings.
pub fn bench_signature(a: &BenchSignatureArgs) -> anyhow::Result<BenchSignature> {
    if a.change_at >= a.units {
        return Err(bad(format!("--change-at {} is not before --units {}", a.change_at, a.units)));
    }
    let baseline = accelcal_core::headsig::Settings::default().baseline;
    if (a.change_at as usize) < baseline {
        return Err(bad(format!(
            "--change-at {} is inside the tracking's baseline of {baseline} units",
            a.change_at
        )));
    }
    Ok(BenchSignature { fleets: a.fleets, units: a.units, change_at: a.change_at, json: a.json.clone() })
}

/// `accelcal uncertainty-check`, settled.
#[derive(Clone, Debug, PartialEq)]
pub struct UncertaintyCheck {
    /// `--units` per scenario, `--samples` per position, `--orientations` of the head, `--seed`.
    pub units: u32,
    pub samples: u32,
    pub orientations: u32,
    pub seed: u64,
    /// `--json`.
    pub json: Option<PathBuf>,
}

/// `uncertainty-check`'s settings.
pub fn uncertainty_check(a: &UncertaintyCheckArgs) -> UncertaintyCheck {
    UncertaintyCheck {
        units: a.units,
        samples: a.samples,
        orientations: a.orientations,
        seed: a.seed,
        json: a.json.clone(),
    }
}
