//! Command-line front end of the gravity-norm fit: arguments, human report, JSON and plots.
//!
//! The binary wires [`GravityFitArgs`] as `accelcal fit INPUT --method gravity-norm ...` and calls
//! [`run`]. The JSON written by `--json` has the required keys `channels`, `misalignment`, `holds` and
//! `residual_rms` exactly as in the issue, plus extra keys documented on [`JsonReport`].

use std::path::{Path, PathBuf};

use anyhow::Context;
use serde::Serialize;

use super::fit::{Structure, TriadModel};
use super::holds::{DetectorConfig, ThresholdSource};
use super::{imutk, plot, Calibration, StructureChoice};
use crate::error::bad;
use crate::output::{write_atomic, write_atomic_with, write_json};

/// Input file formats accepted by the gravity-norm fit.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum InputFormat {
    /// imu_tk text: whitespace-separated `t x y z` rows, raw codes, optionally gzip-compressed.
    #[value(name = "imu-tk")]
    ImuTk,
}

/// Model structure requested on the command line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum StructureArg {
    /// Bias and scale only (6 parameters).
    #[value(name = "bias-scale")]
    BiasScale,
    /// imu_tk: bias, scale, 3 misalignment angles (9 parameters).
    #[value(name = "imu-tk")]
    ImuTk,
    /// imu_tk plus a per-axis quadratic term (12 parameters).
    #[value(name = "quadratic")]
    Quadratic,
    /// The structure with the smallest residual on withheld holds (GMDH selection).
    #[value(name = "auto")]
    Auto,
}

/// Options of the gravity-norm fit other than the input, `--g` and `--json`; flattened into
/// `accelcal fit` (they apply to `--method gravity-norm` only).
#[derive(Debug, Clone, clap::Args)]
#[command(next_help_heading = "Gravity-norm options (--method gravity-norm)")]
pub struct GravityOptions {
    /// Format of the raw recording.
    #[arg(long, value_enum, default_value = "imu-tk")]
    pub format: InputFormat,
    /// Write SVG plots (residual per hold, detector trace) into this directory.
    #[arg(long, value_name = "DIR")]
    pub plot: Option<PathBuf>,
    /// Shortest accepted static hold, in seconds.
    #[arg(long, default_value_t = 2.0)]
    pub min_hold_s: f64,
    /// Detector threshold in codes² (sum of the three axis variances) [default: 4 x the lower
    /// quartile of the detector trace].
    #[arg(long)]
    pub threshold: Option<f64>,
    /// Length of the detector's sliding window, in seconds.
    #[arg(long, default_value_t = 1.0)]
    pub window_s: f64,
    /// Model structure to fit (`auto`: selected on withheld holds).
    #[arg(long, value_enum, default_value = "imu-tk")]
    pub structure: StructureArg,
    /// Also write the holds as a campaign CSV (the samples of every accepted hold, with the head
    /// angles alpha_deg, beta_deg of the hold's calibrated gravity direction), so that `accelcal
    /// diagnose` can examine a recording made without a dividing head.
    #[arg(long, value_name = "FILE")]
    pub campaign_out: Option<PathBuf>,
}

/// Arguments of `accelcal fit INPUT --method gravity-norm`.
#[derive(Debug, Clone, clap::Args)]
pub struct GravityFitArgs {
    /// Raw recording (imu_tk text `t x y z`, plain or gzip).
    #[arg(value_name = "INPUT")]
    pub input: PathBuf,
    /// Local magnitude of gravity, in m/s².
    #[arg(long, default_value_t = 9.81)]
    pub g: f64,
    /// Write the calibration as JSON to this file.
    #[arg(long, value_name = "FILE")]
    pub json: Option<PathBuf>,
    /// The other options.
    #[command(flatten)]
    pub options: GravityOptions,
}

impl GravityFitArgs {
    /// Checks the numeric arguments before any I/O; errors are bad input (exit code 2).
    pub fn validate(&self) -> anyhow::Result<()> {
        let o = &self.options;
        if !(self.g.is_finite() && self.g > 0.0) {
            return Err(bad(format!("--g must be a positive number of m/s², got {}", self.g)));
        }
        if !(o.min_hold_s.is_finite() && o.min_hold_s >= 0.0) {
            return Err(bad(format!("--min-hold-s must be non-negative, got {}", o.min_hold_s)));
        }
        if !(o.window_s.is_finite() && o.window_s > 0.0) {
            return Err(bad(format!("--window-s must be positive, got {}", o.window_s)));
        }
        if let Some(th) = o.threshold.filter(|th| !(th.is_finite() && *th > 0.0)) {
            return Err(bad(format!("--threshold must be positive, got {th}")));
        }
        Ok(())
    }

    fn detector(&self) -> DetectorConfig {
        DetectorConfig {
            window_s: self.options.window_s,
            min_hold_s: self.options.min_hold_s,
            threshold: self.options.threshold,
            ..DetectorConfig::default()
        }
    }

    fn structure_choice(&self) -> StructureChoice {
        match self.options.structure {
            StructureArg::BiasScale => StructureChoice::Fixed(Structure::BiasScale),
            StructureArg::ImuTk => StructureChoice::Fixed(Structure::ImuTk),
            StructureArg::Quadratic => StructureChoice::Fixed(Structure::ImuTkQuadratic),
            StructureArg::Auto => StructureChoice::Auto,
        }
    }
}

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
pub fn json_report(cal: &Calibration) -> JsonReport {
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
    }
}

/// Reads the input, detects the holds and fits, without printing anything.
pub fn calibrate_file(args: &GravityFitArgs) -> anyhow::Result<(imutk::Recording, Calibration)> {
    args.validate()?;
    let rec = match args.options.format {
        InputFormat::ImuTk => imutk::read_path(&args.input)?,
    };
    let cal = super::calibrate(&rec.t, &rec.codes, args.g, &args.detector(), args.structure_choice())
        .with_context(|| format!("{}: gravity-norm calibration failed", args.input.display()))?;
    Ok((rec, cal))
}

/// Runs the gravity-norm fit: prints the report, writes the JSON and the plots if asked.
pub fn run(args: &GravityFitArgs) -> anyhow::Result<()> {
    let (rec, cal) = calibrate_file(args)?;
    print!("{}", human_report(&args.input, rec.len(), &cal));
    if let Some(path) = &args.json {
        write_json(path, &json_report(&cal))?;
        println!("wrote {}", path.display());
    }
    if let Some(dir) = &args.options.plot {
        write_plots(dir, &rec.t, &cal)?;
    }
    if let Some(path) = &args.options.campaign_out {
        let c = holds_campaign(&rec, &cal);
        write_atomic_with(path, |w| c.write(w).context("writing CSV"))?;
        println!("wrote {} ({} holds as position dwells)", path.display(), cal.detection.holds.len());
    }
    Ok(())
}

/// The accepted holds of a recording as a campaign: every sample of each hold, channels `x, y, z`,
/// and as head angles those of the hold's calibrated gravity direction `a` under the dividing-head
/// kinematics (`β = asin(−a_y/|a|)`, `α = atan2(−a_x, −a_z)`).
pub fn holds_campaign(rec: &imutk::Recording, cal: &Calibration) -> crate::campaign::Campaign {
    use crate::campaign::{Campaign, Channel};
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

/// Writes `gravity-residuals.svg` and `gravity-detector.svg` into `dir` (created if missing).
pub fn write_plots(dir: &Path, t: &[f64], cal: &Calibration) -> anyhow::Result<()> {
    let res = dir.join("gravity-residuals.svg");
    write_atomic(&res, plot::residuals_svg(cal)?.as_bytes())?;
    let det = dir.join("gravity-detector.svg");
    write_atomic(&det, plot::detector_svg(t, &cal.detection)?.as_bytes())?;
    println!("wrote {}\nwrote {}", res.display(), det.display());
    Ok(())
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
    if f.structure == Structure::ImuTkQuadratic {
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
