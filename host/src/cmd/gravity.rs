//! `accelcal fit INPUT --method gravity-norm`: human report, JSON and plots of the gravity-norm
//! calibration (the computation is `accelcal_core::gravity`). The JSON written by `--json` has the required keys `channels`, `misalignment`, `holds` and
//! `residual_rms` exactly as in the issue, plus extra keys documented on [`JsonReport`].

use std::path::Path;

use accelcal_core::calibrate::{gate, record_bytes, record_crc_hex, write_record};
use accelcal_core::campaign::identity::{content_sha256, Identity};
use accelcal_core::error::bad;
use accelcal_core::gravity::{self, fit::GravityStructure, fit::TriadModel, holds::ThresholdSource};
use accelcal_core::gravity::{imutk, Calibration};
use accelcal_core::output::{write_atomic, write_atomic_with, write_json};
use accelcal_line::node::session::device_id_hex;
use accelcal_shared::record::Record;
use anyhow::Context;
use serde::Serialize;

use crate::report::gravity_plot as plot;
use crate::settings::campaign::GravityNormFit;

/// One channel of the JSON report.
#[derive(Debug, Clone, Serialize)]
pub struct JsonChannel {
    /// Channel name (`x`, `y`, `z`).
    pub channel: String,
    /// Bias, in codes.
    pub bias: f64,
    /// Scale, in codes per m/s².
    pub scale: f64,
}

/// Standard errors of the JSON report.
#[derive(Debug, Clone, Serialize)]
pub struct JsonUncertainties {
    /// Standard errors of bias (codes) and scale (codes per m/s²) per channel.
    pub channels: Vec<JsonChannel>,
    /// Standard errors of `[α_yz, α_zy, α_zx]`, in radians.
    pub alpha: [f64; 3],
    /// Standard errors of the quadratic coefficients, in 1/(m/s²).
    pub quadratic: [f64; 3],
}

/// One hold in the JSON report.
#[derive(Debug, Clone, Serialize)]
pub struct JsonHold {
    /// Time of the first sample, in seconds.
    pub t_start: f64,
    /// Time of the last sample, in seconds.
    pub t_end: f64,
    /// Number of samples.
    pub samples: usize,
    /// Mean raw output, in codes.
    pub mean: [f64; 3],
    /// `|a| − g` at the solution, in m/s².
    pub residual: f64,
}

/// A rejected quiet run in the JSON report.
#[derive(Debug, Clone, Serialize)]
pub struct JsonRejected {
    /// Time of the first sample, in seconds.
    pub t_start: f64,
    /// Time of the last sample, in seconds.
    pub t_end: f64,
    /// Why it was rejected.
    pub reason: String,
}

/// Detector settings and findings in the JSON report.
#[derive(Debug, Clone, Serialize)]
pub struct JsonDetector {
    /// Window length, in samples.
    pub window_samples: usize,
    /// Noise floor (lower quartile of the trace), in codes².
    pub floor: f64,
    /// Threshold used, in codes².
    pub threshold: f64,
    /// `data` (derived) or `user` (given by `--threshold`).
    pub threshold_source: String,
    /// Quiet runs that were rejected.
    pub rejected: Vec<JsonRejected>,
}

/// A structure score in the JSON report.
#[derive(Debug, Clone, Serialize)]
pub struct JsonScore {
    /// Structure name.
    pub structure: String,
    /// Number of parameters.
    pub params: usize,
    /// RMS of `|a| − g` fitted on all holds, in m/s².
    pub fit_rms: f64,
    /// RMS of `|a| − g` on withheld alternate holds, in m/s² (`null` if it could not be computed).
    pub cv_rms: Option<f64>,
}

/// The JSON written by `--json`: the required keys first, then extras.
#[derive(Debug, Clone, Serialize)]
pub struct JsonReport {
    /// Bias (codes) and scale (codes per m/s²) per channel.
    pub channels: Vec<JsonChannel>,
    /// Misalignment matrix `T` (row-major), `a = T · w` (see the `fit` module).
    pub misalignment: [[f64; 3]; 3],
    /// Number of holds used in the fit.
    pub holds: usize,
    /// RMS of `|a| − g` over the holds, in m/s².
    pub residual_rms: f64,
    /// Method name (`gravity-norm`).
    pub method: String,
    /// Structure fitted.
    pub structure: String,
    /// Gravity magnitude used, in m/s².
    pub g: f64,
    /// Misalignment angles `[α_yz, α_zy, α_zx]`, in radians.
    pub alpha: [f64; 3],
    /// Quadratic coefficients `q` (1/(m/s²)); zero unless the quadratic structure was fitted.
    pub quadratic: [f64; 3],
    /// Standard errors.
    pub uncertainties: JsonUncertainties,
    /// Residual standard deviation `sqrt(Σr²/(holds − params))`, in m/s².
    pub residual_sigma: f64,
    /// Detector settings and rejected runs.
    pub detector: JsonDetector,
    /// Per-hold means and residuals.
    pub per_hold: Vec<JsonHold>,
    /// GMDH-style scores of all structures.
    pub structures: Vec<JsonScore>,
    /// Structure selected on withheld holds (see `fit::select`).
    pub selected_structure: Option<String>,
    /// `--structure auto` could not select on withheld holds (too few holds), so the simplest
    /// structure (bias-scale) was fitted.
    pub structure_fallback: bool,
    /// Axes no hold points within 30° of ±g: their scale is weakly identified.
    pub weak_axes: Vec<JsonWeakAxis>,
    /// Whose fit it is, as `fit --method lsq` states it: device id (with `--record`), serial
    /// (none in a raw recording), g, the recording's SHA-256, the record's CRC.
    #[serde(flatten)]
    pub identity: Identity,
}

/// An axis no hold points near ±g (`weak_axes`).
#[derive(Debug, Clone, Serialize)]
pub struct JsonWeakAxis {
    /// `x`, `y` or `z`.
    pub axis: String,
    /// The largest |a| along it over the holds, as a fraction of g.
    pub largest_fraction_of_g: f64,
    /// Its scale, codes/(m/s²).
    pub scale: f64,
    /// The scale's standard error, codes/(m/s²).
    pub scale_std_err: f64,
}

const CHANNELS: [&str; 3] = ["x", "y", "z"];

fn channels(m: &TriadModel) -> Vec<JsonChannel> {
    CHANNELS
        .iter()
        .enumerate()
        .map(|(i, c)| JsonChannel { channel: c.to_string(), bias: m.bias[i], scale: m.scale[i] })
        .collect()
}

/// Builds the JSON report of a calibration.
pub fn json_report(cal: &Calibration, identity: Identity) -> JsonReport {
    let f = &cal.fit;
    let d = &cal.detection;
    JsonReport {
        channels: channels(&f.model),
        misalignment: f.model.misalignment(),
        holds: d.holds.len(),
        residual_rms: f.rms,
        method: "gravity-norm".into(),
        structure: f.structure.name().into(),
        g: f.g,
        alpha: f.model.alpha,
        quadratic: f.model.quad,
        uncertainties: JsonUncertainties {
            channels: channels(&f.std_err),
            alpha: f.std_err.alpha,
            quadratic: f.std_err.quad,
        },
        residual_sigma: f.sigma,
        detector: JsonDetector {
            window_samples: d.window,
            floor: d.floor,
            threshold: d.threshold,
            threshold_source: match d.source {
                ThresholdSource::Data => "data".into(),
                ThresholdSource::User => "user".into(),
            },
            rejected: d
                .rejected
                .iter()
                .map(|r| JsonRejected { t_start: r.t_start, t_end: r.t_end, reason: r.reason.to_string() })
                .collect(),
        },
        per_hold: d
            .holds
            .iter()
            .zip(&f.residuals)
            .map(|(h, &r)| JsonHold {
                t_start: h.t_start,
                t_end: h.t_end,
                samples: h.len(),
                mean: h.mean,
                residual: r,
            })
            .collect(),
        structures: cal
            .scores
            .iter()
            .map(|s| JsonScore {
                structure: s.structure.name().into(),
                params: s.structure.n_params(),
                fit_rms: s.fit_rms,
                cv_rms: s.cv_rms,
            })
            .collect(),
        selected_structure: cal.selected.map(|s| s.name().to_string()),
        structure_fallback: cal.fallback,
        weak_axes: cal
            .weak_axes
            .iter()
            .map(|w| JsonWeakAxis {
                axis: w.axis.to_string(),
                largest_fraction_of_g: w.largest_fraction_of_g,
                scale: w.scale.0,
                scale_std_err: w.scale.1,
            })
            .collect(),
        identity,
    }
}

/// Reads the input, detects the holds and fits, without printing anything.
pub fn calibrate_file(a: &GravityNormFit, g: f64) -> anyhow::Result<(imutk::Recording, Calibration)> {
    gravity::calibrate_path(&a.input, g, &a.detector, a.structure)
}

/// Runs `accelcal fit --method gravity-norm`: prints the report, writes the JSON, the plots and
/// the holds as a campaign if asked.
pub fn run(a: &GravityNormFit, g: &super::Gravity) -> anyhow::Result<()> {
    let device_id = a.device_id;
    let (rec, cal) = calibrate_file(a, g.g)?;
    // The record is built and checked first: a record a node would refuse writes nothing.
    let record = match &a.record {
        Some(path) => {
            accelcal_core::calibrate::check_record_g(g.g)?;
            let r = model4_record(&cal.fit.model, device_id.unwrap_or_default(), super::created(a.created))
                .map(|mut r| {
                    r.g_m_s2 = Some(g.g);
                    r
                })
                .ok_or_else(|| {
                    bad(format!(
                        "{}: the {} structure is not model 4 (its quadratic terms make it nonlinear in the codes), \
                         the node cannot apply it: fit with --structure imu-tk or bias-scale for a record",
                        path.display(),
                        cal.fit.structure.name()
                    ))
                })?;
            gate(path, &r)?;
            Some((path, r))
        }
        None => None,
    };
    out!("{}", human_report(&a.input, rec.len(), &cal))?;
    for w in &cal.weak_axes {
        errln!("warning: {}", weak_words(w));
    }
    if let Some(path) = &a.json {
        let crc = record.as_ref().map(|(_, r)| record_bytes(r).map(|b| record_crc_hex(&b))).transpose()?;
        let identity = Identity {
            device_id: record.as_ref().map(|(_, r)| device_id_hex(&r.device_id)),
            serial: None,
            g_m_s2: g.g,
            g_source: None,
            campaign_sha256: content_sha256(&a.input)?,
            record_crc: crc,
        };
        write_json(path, &json_report(&cal, identity))?;
        outln!("wrote {}", path.display())?;
    }
    if let Some(dir) = &a.plot {
        write_plots(dir, &rec.t, &cal)?;
    }
    if let Some(path) = &a.campaign_out {
        let c = gravity::holds_campaign(&rec, &cal);
        write_atomic_with(path, |w| c.write(w).context("writing CSV"))?;
        outln!("wrote {} ({} holds as position dwells)", path.display(), cal.detection.holds.len())?;
    }
    if let Some((path, r)) = record {
        write_record(path, &r)?;
        outln!(
            "record: {} ({} bytes, model 4 from {}: u0 = bias, K = S·T⁻¹)",
            path.display(),
            r.len(),
            cal.fit.structure.name()
        )?;
    }
    Ok(())
}

/// The model-4 record equivalent to a gravity-norm model ([`TriadModel::model4`]), or `None` for
/// a model with quadratic terms.
pub fn model4_record(m: &TriadModel, device_id: [u8; 12], created_unix_s: u64) -> Option<Record> {
    m.model4().map(|m4| Record::from_model4(device_id, created_unix_s, &m4))
}

/// Writes `gravity-residuals.svg` and `gravity-detector.svg` into `dir` (created if missing).
pub fn write_plots(dir: &Path, t: &[f64], cal: &Calibration) -> anyhow::Result<()> {
    let res = dir.join("gravity-residuals.svg");
    write_atomic(&res, plot::residuals_svg(cal)?.as_bytes())?;
    let det = dir.join("gravity-detector.svg");
    write_atomic(&det, plot::detector_svg(t, &cal.detection)?.as_bytes())?;
    outln!("wrote {}\nwrote {}", res.display(), det.display())?;
    Ok(())
}

/// A weakly excited axis in words.
fn weak_words(w: &accelcal_core::gravity::WeakAxis) -> String {
    format!(
        "no hold has axis {0} within 30° of ±g (the largest |a_{0}| is {1:.2} g): its scale {2:.3} ± {3:.3} \
         codes/(m/s²) is weakly identified; add holds with {0} up and down",
        w.axis, w.largest_fraction_of_g, w.scale.0, w.scale.1
    )
}

/// The human-readable report printed by [`run`].
pub fn human_report(input: &Path, samples: usize, cal: &Calibration) -> String {
    use std::fmt::Write;
    let f = &cal.fit;
    let d = &cal.detection;
    let (m, s) = (&f.model, &f.std_err);
    let mut o = String::new();
    let _ = writeln!(
        o,
        "gravity-norm calibration of {} ({} samples, dt {:.4} s)",
        input.display(),
        samples,
        d.dt
    );
    let src = match d.source {
        ThresholdSource::Data => "4 x lower quartile of the trace",
        ThresholdSource::User => "given by --threshold",
    };
    let _ = writeln!(
        o,
        "detector: {}-sample window, noise floor {:.2} codes², threshold {:.2} codes² ({src})",
        d.window, d.floor, d.threshold
    );
    let _ = writeln!(o, "holds: {} kept, {} rejected", d.holds.len(), d.rejected.len());
    for r in &d.rejected {
        let _ = writeln!(o, "  rejected {:8.2}–{:8.2} s: {}", r.t_start, r.t_end, r.reason);
    }
    let _ = writeln!(
        o,
        "model: {} ({} parameters), g = {} m/s², solver: {}",
        f.structure.name(),
        f.structure.n_params(),
        f.g,
        f.termination
    );
    if cal.fallback {
        let _ = writeln!(
            o,
            "structure: --structure auto could not select (too few holds to test a structure on withheld holds): \
             fitted {}, the simplest ({} parameters)",
            f.structure.name(),
            f.structure.n_params()
        );
    }
    let _ = writeln!(o, "  axis        bias [codes]          scale [codes/(m/s²)]");
    for (i, c) in CHANNELS.iter().enumerate() {
        let _ = writeln!(
            o,
            "  {c}    {:12.3} ± {:<8.3}  {:12.5} ± {:.5}",
            m.bias[i], s.bias[i], m.scale[i], s.scale[i]
        );
    }
    for (k, name) in ["alpha_yz", "alpha_zy", "alpha_zx"].iter().enumerate() {
        let _ = writeln!(o, "  {name}  {:+.6} ± {:.6} rad", m.alpha[k], s.alpha[k]);
    }
    if f.structure == GravityStructure::ImuTkQuadratic {
        for (i, c) in CHANNELS.iter().enumerate() {
            let _ = writeln!(o, "  quad_{c}    {:+.3e} ± {:.3e} 1/(m/s²)", m.quad[i], s.quad[i]);
        }
    }
    let t = m.misalignment();
    let _ = writeln!(
        o,
        "  T = [{:+.6} {:+.6} {:+.6}; {:+.6} {:+.6} {:+.6}; {:+.6} {:+.6} {:+.6}]",
        t[0][0], t[0][1], t[0][2], t[1][0], t[1][1], t[1][2], t[2][0], t[2][1], t[2][2]
    );
    let max = f.residuals.iter().fold(0.0f64, |a, r| a.max(r.abs()));
    let _ = writeln!(
        o,
        "|a| - g per hold: RMS {:.6} m/s², max |r| {:.6} m/s², sigma {:.6} m/s²",
        f.rms, max, f.sigma
    );
    let _ = writeln!(o, "  hold   t_start    t_end  samples   residual [m/s²]");
    for (k, (h, r)) in d.holds.iter().zip(&f.residuals).enumerate() {
        let _ = writeln!(o, "  {k:4} {:9.2} {:8.2} {:8} {:+14.6}", h.t_start, h.t_end, h.len(), r);
    }
    let _ = writeln!(o, "structure selection (fit on all holds / on alternate holds, tested on the others):");
    for sc in &cal.scores {
        let cv = sc.cv_rms.map_or("n/a".to_string(), |v| format!("{v:.6}"));
        let mark = if Some(sc.structure) == cal.selected { "  <- selected" } else { "" };
        let _ = writeln!(
            o,
            "  {:34} {:2} params  fit RMS {:.6}  withheld RMS {cv}{mark}",
            sc.structure.name(),
            sc.structure.n_params(),
            sc.fit_rms
        );
    }
    o
}
