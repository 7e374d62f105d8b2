//! Error effects of the simulator: parametric additions to a channel's ideal output.
//!
//! An effect is named, carries its parameters, and adds codes to one sample given the sample's
//! context; effects of the head (`head_misalignment`, `angle_error`) instead change the
//! acceleration the sensors see through [`Effect::kinematics`] (the commanded angles written to
//! the campaign stay as they were). `accelcal simulate --effect NAME=PARAMS` builds them through
//! [`parse`]. Names, keys, units and defaults are those of the registry, [`crate::effects`].

use accelcal_shared::Term;

use crate::effects::EffectKind;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
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
    /// Apparent acceleration the block sees, m/s² (after the head's kinematic effects).
    pub accel: [f64; 3],
    /// Channel index.
    pub channel: usize,
    /// The channel's nominal sensitive axis.
    pub axis: usize,
    /// Time since the dwell began, s.
    pub t_in_dwell_s: f64,
    /// Temperature, °C (NaN when the simulation has no temperature profile).
    pub temp_c: f64,
    /// Acceleration the block saw at the previous position (None at the first).
    pub prev_accel: Option<[f64; 3]>,
    /// The channel's ideal linear signal `k·a` (output minus zero offset), codes.
    pub signal: f64,
}

impl SampleCtx {
    /// A context with only the acceleration and the channel set (tests and simple callers).
    pub fn basic(accel: [f64; 3], channel: usize, axis: usize) -> SampleCtx {
        SampleCtx {
            t_s: 0.0,
            position: 0,
            sample: 0,
            accel,
            channel,
            axis,
            t_in_dwell_s: 0.0,
            temp_c: f64::NAN,
            prev_accel: None,
            signal: 0.0,
        }
    }

    /// Change of the sensitive-axis input since the previous position (0 at the first).
    pub fn step(&self) -> f64 {
        self.prev_accel.map(|p| self.accel[self.axis] - p[self.axis]).unwrap_or(0.0)
    }
}

/// The head's state for one position, which kinematic effects may change: the angles the head
/// really reached and a rotation `r` between its α and β stages. The block sees
/// `a = −g·Ry(α)·r·Rx(−β)·e_z`.
#[derive(Clone, Copy, Debug)]
pub struct Kinematics {
    /// Index of the position in the plan.
    pub position: usize,
    /// Seed of the simulation (for per-position random draws).
    pub seed: u64,
    /// α actually reached, rad.
    pub alpha_rad: f64,
    /// β actually reached, rad.
    pub beta_rad: f64,
    /// Rotation between the stages.
    pub r: [[f64; 3]; 3],
    /// Whether an effect changed anything (else the exact kinematics of `shared` apply).
    pub changed: bool,
}

impl Kinematics {
    /// The acceleration the block sees, m/s².
    pub fn accel(&self, g: f64) -> [f64; 3] {
        let (sb, cb) = self.beta_rad.sin_cos();
        let v = [0.0, sb, cb]; // Rx(−β)·e_z
        let w = mat_vec(&self.r, v);
        let (sa, ca) = self.alpha_rad.sin_cos();
        [-g * (ca * w[0] + sa * w[2]), -g * w[1], -g * (-sa * w[0] + ca * w[2])]
    }
}

/// The term variables of an acceleration: a nonlinearity's terms are in acceleration only.
fn accel4(a: [f64; 3]) -> [f64; 4] {
    [a[0], a[1], a[2], 0.0]
}

fn mat_vec(m: &[[f64; 3]; 3], v: [f64; 3]) -> [f64; 3] {
    [0, 1, 2].map(|i| (0..3).map(|j| m[i][j] * v[j]).sum())
}

/// The rotation by the vector `w` (rad), Rodrigues' formula.
pub fn rotation(w: [f64; 3]) -> [[f64; 3]; 3] {
    let th = (w[0] * w[0] + w[1] * w[1] + w[2] * w[2]).sqrt();
    let mut r = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    if th == 0.0 {
        return r;
    }
    let k = w.map(|x| x / th);
    let (s, c) = th.sin_cos();
    let kx = [[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]];
    for i in 0..3 {
        for j in 0..3 {
            r[i][j] = c * r[i][j] + s * kx[i][j] + (1.0 - c) * k[i] * k[j];
        }
    }
    r
}

/// A parametric error effect.
pub trait Effect: Send + Sync {
    /// The effect's interface name.
    fn name(&self) -> &'static str;
    /// Name and parameters as JSON (for the truth file).
    fn describe(&self) -> serde_json::Value;
    /// Codes added to the ideal output of one sample.
    fn output(&self, ctx: &SampleCtx) -> f64;
    /// Changes the head's kinematics for one position (default: none).
    fn kinematics(&self, _k: &mut Kinematics) {}
    /// Whether the effect needs a temperature profile.
    fn needs_temperature(&self) -> bool {
        false
    }
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
        EffectKind::Nonlinearity.name()
    }
    fn describe(&self) -> serde_json::Value {
        let terms: serde_json::Map<_, _> =
            self.terms.iter().map(|(t, c)| (t.to_string(), json!(c))).collect();
        json!({"name": self.name(), "k2": self.k2, "terms": terms})
    }
    fn output(&self, ctx: &SampleCtx) -> f64 {
        let own = ctx.accel[ctx.axis];
        self.k2 * own * own + self.terms.iter().map(|(t, c)| c * t.eval(accel4(ctx.accel))).sum::<f64>()
    }
}

/// A linear drift of every channel's output with time: `rate·t` codes.
#[derive(Clone, Debug, PartialEq)]
pub struct BiasDrift {
    /// Codes per second.
    pub rate: f64,
}

impl Effect for BiasDrift {
    fn name(&self) -> &'static str {
        EffectKind::BiasDrift.name()
    }
    fn describe(&self) -> serde_json::Value {
        json!({"name": self.name(), "rate": self.rate})
    }
    fn output(&self, ctx: &SampleCtx) -> f64 {
        self.rate * ctx.t_s
    }
}

/// Temperature dependence: `(bias + scale·1e-6·signal)·(T − t_ref)` codes.
#[derive(Clone, Debug, PartialEq)]
pub struct Temperature {
    /// Zero-offset coefficient, codes per °C.
    pub bias: f64,
    /// Scale-factor coefficient, ppm per °C.
    pub scale: f64,
    /// Reference temperature, °C.
    pub t_ref: f64,
}

impl Effect for Temperature {
    fn name(&self) -> &'static str {
        EffectKind::Temperature.name()
    }
    fn describe(&self) -> serde_json::Value {
        json!({"name": self.name(), "bias": self.bias, "scale": self.scale, "t_ref": self.t_ref})
    }
    fn output(&self, ctx: &SampleCtx) -> f64 {
        if !ctx.temp_c.is_finite() {
            return 0.0;
        }
        (self.bias + self.scale * 1e-6 * ctx.signal) * (ctx.temp_c - self.t_ref)
    }
    fn needs_temperature(&self) -> bool {
        true
    }
}

/// A constant rotation between the α and β stages (vector in mrad). A rotation about y commutes
/// with the α stage and only turns the whole block, which model 4 absorbs.
#[derive(Clone, Debug, PartialEq)]
pub struct HeadMisalignment {
    /// Rotation vector, mrad.
    pub r_mrad: [f64; 3],
}

impl Effect for HeadMisalignment {
    fn name(&self) -> &'static str {
        EffectKind::HeadMisalignment.name()
    }
    fn describe(&self) -> serde_json::Value {
        let [x, y, z] = self.r_mrad;
        json!({"name": self.name(), "rx_mrad": x, "ry_mrad": y, "rz_mrad": z})
    }
    fn output(&self, _: &SampleCtx) -> f64 {
        0.0
    }
    fn kinematics(&self, k: &mut Kinematics) {
        let r = rotation(self.r_mrad.map(|v| v * 1e-3));
        let mut out = [[0.0; 3]; 3];
        for i in 0..3 {
            for j in 0..3 {
                out[i][j] = (0..3).map(|m| k.r[i][m] * r[m][j]).sum();
            }
        }
        k.r = out;
        k.changed = true;
    }
}

/// Output depends on the direction of approach: `h·sign(Δa)` with Δa the change of the
/// sensitive-axis input since the previous position.
#[derive(Clone, Debug, PartialEq)]
pub struct Hysteresis {
    /// Codes.
    pub h: f64,
}

impl Effect for Hysteresis {
    fn name(&self) -> &'static str {
        EffectKind::Hysteresis.name()
    }
    fn describe(&self) -> serde_json::Value {
        json!({"name": self.name(), "h": self.h})
    }
    fn output(&self, ctx: &SampleCtx) -> f64 {
        let d = ctx.step();
        if d.abs() < 1e-6 {
            0.0
        } else {
            self.h * d.signum()
        }
    }
}

/// A transient after each rotation: `gain·Δa·exp(−t_in_dwell/tau)`.
#[derive(Clone, Debug, PartialEq)]
pub struct Settling {
    /// Codes per m/s² of sensitive-axis step.
    pub gain: f64,
    /// Time constant, s.
    pub tau: f64,
}

impl Effect for Settling {
    fn name(&self) -> &'static str {
        EffectKind::Settling.name()
    }
    fn describe(&self) -> serde_json::Value {
        json!({"name": self.name(), "gain": self.gain, "tau": self.tau})
    }
    fn output(&self, ctx: &SampleCtx) -> f64 {
        self.gain * ctx.step() * (-ctx.t_in_dwell_s / self.tau).exp()
    }
}

/// Random setting errors of α and β, independent per position, common to all channels.
#[derive(Clone, Debug, PartialEq)]
pub struct AngleError {
    /// One sigma, mrad.
    pub sd_mrad: f64,
}

impl AngleError {
    /// The errors (δα, δβ) in rad drawn for a position.
    pub fn draw(&self, seed: u64, position: usize) -> (f64, f64) {
        let s = seed ^ 0x616e_676c_655f_6572 ^ (position as u64 + 1).wrapping_mul(0x9E37_79B9_7F4A_7C15);
        let mut rng = ChaCha8Rng::seed_from_u64(s);
        let n = Normal::new(0.0, self.sd_mrad.abs() * 1e-3).expect("finite sd");
        (n.sample(&mut rng), n.sample(&mut rng))
    }
}

impl Effect for AngleError {
    fn name(&self) -> &'static str {
        EffectKind::AngleError.name()
    }
    fn describe(&self) -> serde_json::Value {
        json!({"name": self.name(), "sd_mrad": self.sd_mrad})
    }
    fn output(&self, _: &SampleCtx) -> f64 {
        0.0
    }
    fn kinematics(&self, k: &mut Kinematics) {
        let (da, db) = self.draw(k.seed, k.position);
        k.alpha_rad += da;
        k.beta_rad += db;
        k.changed = true;
    }
}

/// Takes `key` from the list (default when absent).
/// The value of `key` given in `kv` (removed from it), or the registry's default.
fn take(kv: &mut Vec<(String, f64)>, kind: EffectKind, key: &str) -> f64 {
    match kv.iter().position(|(k, _)| k == key) {
        Some(i) => kv.remove(i).1,
        None => kind.spec().params.iter().find(|p| p.key == key).map_or(0.0, |p| p.default),
    }
}

fn no_more(kind: EffectKind, kv: &[(String, f64)]) -> Result<(), String> {
    match kv.first() {
        Some((k, _)) => {
            let known: Vec<&str> = kind.spec().params.iter().map(|p| p.key).collect();
            Err(format!("effect `{}`: unknown parameter `{k}` (known: {})", kind.name(), known.join(", ")))
        }
        None => Ok(()),
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
    let kind = EffectKind::from_name(name).ok_or_else(|| {
        format!("unknown effect `{name}` (known: {})", crate::effects::names().collect::<Vec<_>>().join(", "))
    })?;
    let e: Box<dyn Effect> = match kind {
        EffectKind::Nonlinearity => {
            let mut e = Nonlinearity { k2: 0.0, terms: Vec::new() };
            for (k, v) in kv.drain(..) {
                if k == "k2" {
                    e.k2 = v;
                } else {
                    let t = Term::parse(&k).map_err(|err| format!("effect `nonlinearity`: `{k}`: {err}"))?;
                    if t.is_thermal() {
                        return Err(format!(
                            "effect `nonlinearity`: `{k}` is a term in temperature (use the `temperature` effect)"
                        ));
                    }
                    e.terms.push((t, v));
                }
            }
            Box::new(e)
        }
        EffectKind::BiasDrift => Box::new(BiasDrift { rate: take(&mut kv, kind, "rate") }),
        EffectKind::Temperature => Box::new(Temperature {
            bias: take(&mut kv, kind, "bias"),
            scale: take(&mut kv, kind, "scale"),
            t_ref: take(&mut kv, kind, "t_ref"),
        }),
        EffectKind::HeadMisalignment => Box::new(HeadMisalignment {
            r_mrad: [
                take(&mut kv, kind, "rx_mrad"),
                take(&mut kv, kind, "ry_mrad"),
                take(&mut kv, kind, "rz_mrad"),
            ],
        }),
        EffectKind::Hysteresis => Box::new(Hysteresis { h: take(&mut kv, kind, "h") }),
        EffectKind::Settling => {
            let e = Settling { gain: take(&mut kv, kind, "gain"), tau: take(&mut kv, kind, "tau") };
            if !(e.tau > 0.0) {
                return Err("effect `settling`: tau must be > 0 s".into());
            }
            Box::new(e)
        }
        EffectKind::AngleError => Box::new(AngleError { sd_mrad: take(&mut kv, kind, "sd_mrad") }),
    };
    no_more(kind, &kv)?;
    Ok(e)
}

/// The registry spec (`NAME=KEY:VALUE,...`, what [`parse`] reads) of an effect's description
/// ([`Effect::describe`]: an object with `name`, numeric parameters, and the nonlinearity's
/// `terms` object of term → coefficient). Numbers are written in Rust's shortest round-trip form,
/// so the rebuilt effect has exactly the described parameters.
pub fn spec_of_description(d: &serde_json::Value) -> Result<String, String> {
    let obj = d.as_object().ok_or_else(|| format!("expected an object with a `name`, got `{d}`"))?;
    let name = obj
        .get("name")
        .and_then(|n| n.as_str())
        .ok_or_else(|| format!("expected a string `name` in `{d}`"))?;
    let number = |key: &str, v: &serde_json::Value| -> Result<String, String> {
        if key.is_empty() || key.contains([',', ':', '=']) {
            return Err(format!("effect `{name}`: bad parameter name `{key}`"));
        }
        let x = v.as_f64().ok_or_else(|| format!("effect `{name}`: `{key}` must be a number, got `{v}`"))?;
        Ok(format!("{key}:{x:?}"))
    };
    let mut params = Vec::new();
    for (key, v) in obj.iter().filter(|(k, _)| k.as_str() != "name") {
        match v.as_object() {
            Some(terms) if key == "terms" => {
                for (t, c) in terms {
                    params.push(number(t, c)?);
                }
            }
            _ => params.push(number(key, v)?),
        }
    }
    Ok(if params.is_empty() { name.to_string() } else { format!("{name}={}", params.join(",")) })
}

/// Rebuilds an effect from its description ([`Effect::describe`], as a truth file holds it)
/// through the registry's parser, [`parse`]: the one path from parameters to an effect.
pub fn from_description(d: &serde_json::Value) -> Result<Box<dyn Effect>, String> {
    parse(&spec_of_description(d)?)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nonlinearity_parses_and_evaluates() {
        let e = parse("nonlinearity=k2:2,ax*ay:0.5").unwrap();
        let ctx = SampleCtx::basic([1.0, 2.0, 3.0], 0, 2);
        assert_eq!(e.output(&ctx), 2.0 * 9.0 + 0.5 * 2.0);
        assert_eq!(e.describe()["terms"]["ax*ay"], 0.5);
        assert!(parse("nonlinearity=k2").is_err());
        assert!(parse("wobble=a:1").err().unwrap().contains("unknown effect"));
    }

    #[test]
    fn every_name_parses_and_unknown_keys_are_refused() {
        for n in crate::effects::names() {
            assert_eq!(parse(n).unwrap().name(), n);
        }
        assert!(parse("hysteresis=k:1").err().unwrap().contains("unknown parameter `k`"));
        assert!(parse("settling=gain:1,tau:0").is_err());
    }

    #[test]
    fn output_effects_follow_their_formulas() {
        let mut ctx = SampleCtx::basic([0.0, 0.0, 9.81], 2, 2);
        ctx.prev_accel = Some([0.0, 0.0, -9.81]);
        ctx.t_s = 10.0;
        ctx.t_in_dwell_s = 0.5;
        ctx.temp_c = 30.0;
        ctx.signal = 16384.0;
        assert_eq!(parse("bias_drift=rate:0.5").unwrap().output(&ctx), 5.0);
        assert_eq!(parse("hysteresis=h:3").unwrap().output(&ctx), 3.0);
        let s = parse("settling=gain:2,tau:0.5").unwrap().output(&ctx);
        assert!((s - 2.0 * 19.62 * (-1.0f64).exp()).abs() < 1e-9);
        let t = parse("temperature=bias:2,scale:100,t_ref:25").unwrap().output(&ctx);
        assert!((t - (2.0 + 100e-6 * 16384.0) * 5.0).abs() < 1e-9);
        ctx.temp_c = f64::NAN;
        assert_eq!(parse("temperature=bias:2").unwrap().output(&ctx), 0.0);
    }

    #[test]
    fn kinematics_match_the_paper_and_y_rotation_turns_the_block() {
        let g = 9.81;
        for (a, b) in [(30.0f64, -60.0f64), (210.0, 30.0), (0.0, 90.0)] {
            let k = Kinematics {
                position: 0,
                seed: 1,
                alpha_rad: a.to_radians(),
                beta_rad: b.to_radians(),
                r: rotation([0.0; 3]),
                changed: false,
            };
            let exact = accelcal_shared::gravity(a, b, g);
            let got = k.accel(g);
            assert!((0..3).all(|i| (got[i] - exact[i]).abs() < 1e-12), "{got:?} {exact:?}");
            // A rotation about y between the stages = the same rotation of the whole block.
            let mut k2 = k;
            parse("head_misalignment=ry_mrad:10").unwrap().kinematics(&mut k2);
            let whole = mat_vec(&rotation([0.0, 0.01, 0.0]), exact);
            let got = k2.accel(g);
            assert!((0..3).all(|i| (got[i] - whole[i]).abs() < 1e-12));
        }
        let e = AngleError { sd_mrad: 1.0 };
        assert_eq!(e.draw(5, 3), e.draw(5, 3));
        assert_ne!(e.draw(5, 3), e.draw(5, 4));
    }
}
