//! Gravity-norm calibration of an accelerometer triad from hand-placed static holds (no dividing head).
//!
//! The pipeline is: read a raw recording ([`imutk`]), find the static holds ([`holds`]), fit the
//! 9-parameter imu_tk model on `|a| = g` ([`fit`]); the `accelcal` binary reports. [`sim`] simulates
//! a hand-placed session with a known truth so that the whole chain is tested where the answer is known.
//! See `README-gravity.md` next to this file for the method and the results on a real recording.

pub mod fit;
pub mod holds;
pub mod imutk;
pub mod sim;
mod solver;

use fit::{FitError, GravityFit, GravityStructure, StructureScore};
use holds::{Detection, DetectorConfig, HoldError};

use crate::campaign::{Campaign, Channel};
use crate::error::{Classify, Kind};

/// Errors of the gravity-norm calibration pipeline.
#[derive(Debug, thiserror::Error)]
pub enum GravityError {
    /// The hold detector failed.
    #[error("hold detection failed")]
    Holds(#[from] HoldError),
    /// The fit failed.
    #[error("gravity-norm fit on {holds} holds failed; the detector: {}", detected.words(&crate::error::Plain))]
    Fit {
        /// Number of holds given to the fit.
        holds: usize,
        /// What the detector kept and dropped ([`Detection::summary`]).
        detected: holds::Summary,
        /// Underlying error.
        #[source]
        source: FitError,
    },
}

impl crate::error::Worded for GravityError {
    fn worded(&self, w: &dyn crate::error::Wording) -> Option<String> {
        match self {
            GravityError::Fit { holds, detected, .. } => {
                Some(format!("gravity-norm fit on {holds} holds failed; the detector: {}", detected.words(w)))
            }
            GravityError::Holds(_) => None,
        }
    }
}

impl Classify for GravityError {
    fn kind(&self) -> Kind {
        Kind::BadInput
    }
}

/// Which model structure to fit.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StructureChoice {
    /// A fixed structure.
    Fixed(GravityStructure),
    /// The structure selected on withheld holds (GMDH external criterion, see [`fit::select`]).
    Auto,
}

/// Everything the pipeline found on a recording.
#[derive(Debug, Clone)]
pub struct Calibration {
    /// Hold detection (trace, threshold, accepted and rejected holds).
    pub detection: Detection,
    /// The fit of the chosen structure on all accepted holds.
    pub fit: GravityFit,
    /// Scores of all structures on the same holds (fit and withheld-hold RMS).
    pub scores: Vec<StructureScore>,
    /// Structure selected on withheld holds (see [`fit::select`]), if any could be scored.
    pub selected: Option<GravityStructure>,
    /// `auto` could not select (no structure scored on withheld holds), so the simplest
    /// structure, bias-scale, was fitted.
    pub fallback: bool,
    /// Axes no hold points near ±g ([`EXCITED`]).
    pub weak_axes: Vec<WeakAxis>,
}

/// Detects the holds of a recording and fits the gravity-norm model on their means.
pub fn calibrate(
    t: &[f64],
    codes: &[[f64; 3]],
    g: f64,
    detector: &DetectorConfig,
    structure: StructureChoice,
) -> Result<Calibration, GravityError> {
    let detection = holds::detect(t, codes, detector)?;
    let means: Vec<[f64; 3]> = detection.holds.iter().map(|h| h.mean).collect();
    let scores = fit::score_structures(&means, g);
    let selected = fit::select(&scores);
    // `auto` that cannot select (too few holds to withhold half) fits the simplest structure,
    // and says so: never the richest in silence.
    let (chosen, fallback) = match (structure, selected) {
        (StructureChoice::Fixed(s), _) => (s, false),
        (StructureChoice::Auto, Some(s)) => (s, false),
        (StructureChoice::Auto, None) => (GravityStructure::BiasScale, true),
    };
    let fit = fit::fit(&means, g, chosen).map_err(|source| GravityError::Fit {
        holds: means.len(),
        detected: detection.summary(),
        source,
    })?;
    let weak_axes = weak_axes(&fit, &means);
    Ok(Calibration { detection, fit, scores, selected, fallback, weak_axes })
}

/// An axis no hold points near ±g: its scale is weakly identified.
#[derive(Debug, Clone, PartialEq)]
pub struct WeakAxis {
    /// `x`, `y` or `z`.
    pub axis: char,
    /// The largest |a| along it over the holds, as a fraction of g.
    pub largest_fraction_of_g: f64,
    /// Its scale and the scale's standard error, codes/(m/s²).
    pub scale: (f64, f64),
}

/// An axis counts as excited when some hold has |a| along it of at least this fraction of g
/// (cos 30°: within 30° of ±g).
pub const EXCITED: f64 = 0.866;

fn weak_axes(fit: &GravityFit, means: &[[f64; 3]]) -> Vec<WeakAxis> {
    let applied: Vec<[f64; 3]> = means.iter().map(|m| fit.model.apply(*m)).collect();
    (0..3)
        .filter_map(|i| {
            let largest = applied.iter().map(|a| a[i].abs() / fit.g).fold(0.0, f64::max);
            (largest < EXCITED).then(|| WeakAxis {
                axis: ['x', 'y', 'z'][i],
                largest_fraction_of_g: largest,
                scale: (fit.model.scale[i], fit.std_err.scale[i]),
            })
        })
        .collect()
}

/// Reads a recording (imu_tk text, plain or gzip), detects its holds and fits.
pub fn calibrate_path(
    input: &std::path::Path,
    g: f64,
    detector: &DetectorConfig,
    structure: StructureChoice,
) -> anyhow::Result<(imutk::Recording, Calibration)> {
    use anyhow::Context;
    let rec = imutk::read_path(input)?;
    let cal = calibrate(&rec.t, &rec.codes, g, detector, structure)
        .with_context(|| format!("{}: gravity-norm calibration failed", input.display()))?;
    Ok((rec, cal))
}

/// The accepted holds of a recording as a campaign: every sample of each hold, channels `x, y, z`,
/// and as head angles those of the hold's calibrated gravity direction `a` under the dividing-head
/// kinematics (`β = asin(−a_y/|a|)`, `α = atan2(−a_x, −a_z)`).
pub fn holds_campaign(rec: &imutk::Recording, cal: &Calibration) -> Campaign {
    let mut c = Campaign {
        channels: ["x", "y", "z"].map(|n| Channel { name: n.into(), codes: Vec::new() }).to_vec(),
        ..Campaign::default()
    };
    for h in &cal.detection.holds {
        let a = cal.fit.model.apply(h.mean);
        let norm = (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt();
        let beta = (-a[1] / norm).clamp(-1.0, 1.0).asin().to_degrees();
        let alpha = (-a[0]).atan2(-a[2]).to_degrees();
        for i in h.start..h.end {
            c.t_s.push(rec.t[i]);
            c.alpha_deg.push(alpha);
            c.beta_deg.push(beta);
            for (ch, &v) in c.channels.iter_mut().zip(&rec.codes[i]) {
                ch.codes.push(v);
            }
        }
    }
    c
}
