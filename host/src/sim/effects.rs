//! Error effects of the simulator: parametric additions to a channel's ideal output.
//!
//! An effect is named, carries its parameters, and adds codes to one sample given the sample's
//! context. `accelcal simulate --effect NAME=PARAMS` builds them through [`parse`]. The diagnosis
//! issue extends this library; the calibration core ships `nonlinearity`.

use accelcal_shared::Term;
use serde_json::json;

/// What an effect may depend on for one sample of one channel.
#[derive(Clone, Copy, Debug)]
pub struct SampleCtx {
    /// Time, s.
    pub t_s: f64,
    /// Index of the position in the plan.
    pub position: usize,
    /// Index of the sample within the dwell.
    pub sample: usize,
    /// Apparent acceleration imposed by the head, m/s².
    pub accel: [f64; 3],
    /// Channel index.
    pub channel: usize,
    /// The channel's nominal sensitive axis.
    pub axis: usize,
}

/// A parametric error effect.
pub trait Effect: Send + Sync {
    /// The effect's interface name.
    fn name(&self) -> &'static str;
    /// Name and parameters as JSON (for the truth file).
    fn describe(&self) -> serde_json::Value;
    /// Codes added to the ideal output of one sample.
    fn output(&self, ctx: &SampleCtx) -> f64;
}

/// Second-order (or third-order) terms of the input acceleration: `k2` times the square of the
/// acceleration along the channel's sensitive axis, plus any basis term with its coefficient
/// (codes per (m/s²)ⁿ), on every channel.
#[derive(Clone, Debug, PartialEq)]
pub struct Nonlinearity {
    /// Coefficient of the squared sensitive-axis acceleration.
    pub k2: f64,
    /// Extra terms and coefficients.
    pub terms: Vec<(Term, f64)>,
}

impl Effect for Nonlinearity {
    fn name(&self) -> &'static str {
        "nonlinearity"
    }
    fn describe(&self) -> serde_json::Value {
        let terms: serde_json::Map<_, _> =
            self.terms.iter().map(|(t, c)| (t.to_string(), json!(c))).collect();
        json!({"name": self.name(), "k2": self.k2, "terms": terms})
    }
    fn output(&self, ctx: &SampleCtx) -> f64 {
        let own = ctx.accel[ctx.axis];
        self.k2 * own * own + self.terms.iter().map(|(t, c)| c * t.eval(ctx.accel)).sum::<f64>()
    }
}

/// Parses `NAME=KEY:VALUE,KEY:VALUE...`.
pub fn parse(spec: &str) -> Result<Box<dyn Effect>, String> {
    let (name, params) = spec.split_once('=').unwrap_or((spec, ""));
    let mut kv = Vec::new();
    for p in params.split(',').map(str::trim).filter(|p| !p.is_empty()) {
        let (k, v) =
            p.split_once(':').ok_or_else(|| format!("effect `{name}`: parameter `{p}` is not KEY:VALUE"))?;
        let v: f64 = v
            .trim()
            .parse()
            .ok()
            .filter(|v: &f64| v.is_finite())
            .ok_or_else(|| format!("effect `{name}`: `{p}` needs a finite number"))?;
        kv.push((k.trim().to_string(), v));
    }
    match name {
        "nonlinearity" => {
            let mut e = Nonlinearity { k2: 0.0, terms: Vec::new() };
            for (k, v) in kv {
                if k == "k2" {
                    e.k2 = v;
                } else {
                    let t = Term::parse(&k).map_err(|err| format!("effect `nonlinearity`: `{k}`: {err}"))?;
                    e.terms.push((t, v));
                }
            }
            Ok(Box::new(e))
        }
        _ => Err(format!("unknown effect `{name}` (known: nonlinearity)")),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nonlinearity_parses_and_evaluates() {
        let e = parse("nonlinearity=k2:2,ax*ay:0.5").unwrap();
        let ctx = SampleCtx { t_s: 0.0, position: 0, sample: 0, accel: [1.0, 2.0, 3.0], channel: 0, axis: 2 };
        assert_eq!(e.output(&ctx), 2.0 * 9.0 + 0.5 * 2.0);
        assert_eq!(e.describe()["terms"]["ax*ay"], 0.5);
        assert!(parse("nonlinearity=k2").is_err());
        assert!(parse("wobble=a:1").err().unwrap().contains("unknown effect"));
    }
}
