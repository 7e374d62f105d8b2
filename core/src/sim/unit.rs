//! A simulated unit sampled one set at a time: the truth of a simulation ([`Truth`], what
//! `accelcal simulate --truth` writes) rebuilt into a [`Unit`], and the per-sample model that
//! [`super::simulate`] and the emulated front end (`crate::emulate`) both call.
//!
//! Invariants:
//! - One code path computes a sample set: [`sample_set`] (signal `k·a`, the effects' outputs,
//!   white noise, rounding and clipping to unsigned 16-bit codes), and one computes the acceleration
//!   the block sees at a standing position: [`position_kinematics`] (the head's kinematic effects,
//!   else the exact kinematics of `accelcal_shared::gravity`). `simulate` and the front end use
//!   them; nothing else does this arithmetic, so both give bit-identical codes for the same inputs.
//! - The noise of a set is drawn channel by channel, in channel order, from the caller's RNG.
//! - A [`Unit`] is rebuilt from a truth file through the effect registry's parser
//!   ([`super::effects::from_description`]), so its effects are those the simulator would build
//!   from the same parameters.

use std::path::Path;

use rand::Rng;
use rand_distr::{Distribution, Normal};
use serde::Serialize;

use super::effects::{self, Effect, Kinematics, SampleCtx};
use crate::campaign::CodeRange;
use crate::error::{Classify, Kind, Plain, Setting, Worded, Wording};

/// The truth behind a simulated campaign, written beside it as JSON.
#[derive(Clone, Debug, Serialize, serde::Deserialize)]
pub struct Truth {
    /// Seed used.
    pub seed: u64,
    /// Gravity, m/s².
    pub g: f64,
    /// Noise per sample, codes.
    pub noise: f64,
    /// Each channel's linear model.
    pub channels: Vec<ChannelTruth>,
    /// The effects, with their parameters.
    pub effects: Vec<serde_json::Value>,
}

/// One channel's true linear model `u = bias + k·a` (before effects, noise and quantisation).
#[derive(Clone, Debug, Serialize, serde::Deserialize)]
pub struct ChannelTruth {
    /// Channel name.
    pub name: String,
    /// Nominal sensitive axis (0 = x, 1 = y, 2 = z).
    pub axis: usize,
    /// Zero offset, codes.
    pub bias: f64,
    /// Sensitivity to ax, ay, az, codes per m/s².
    pub k: [f64; 3],
}

/// What one sample set depends on, common to every channel.
#[derive(Clone, Copy, Debug)]
pub struct SetCtx {
    /// Time, s.
    pub t_s: f64,
    /// Index of the position (in `simulate`, of the plan; in the emulator, the moves completed).
    pub position: usize,
    /// Index of the set within the dwell.
    pub sample: usize,
    /// Apparent acceleration the block sees, m/s².
    pub accel: [f64; 3],
    /// Time since the head stopped, s.
    pub t_in_dwell_s: f64,
    /// Temperature, °C (NaN when there is none).
    pub temp_c: f64,
    /// Acceleration at the previous standing position (None at the first).
    pub prev_accel: Option<[f64; 3]>,
}

/// The kinematics of a standing position after the effects' changes: `position` is the index
/// the effects' per-position draws use, `alpha_deg`/`beta_deg` the commanded angles.
pub fn position_kinematics(
    effects: &[Box<dyn Effect>],
    seed: u64,
    position: usize,
    alpha_deg: f64,
    beta_deg: f64,
) -> Kinematics {
    let mut kin = Kinematics {
        position,
        seed,
        alpha_rad: alpha_deg.to_radians(),
        beta_rad: beta_deg.to_radians(),
        r: effects::rotation([0.0; 3]),
        changed: false,
    };
    for e in effects {
        e.kinematics(&mut kin);
    }
    kin
}

/// The acceleration the block sees at a standing position, m/s² (the kinematic effects applied;
/// without any, exactly `accelcal_shared::gravity`).
pub fn standing_accel(
    effects: &[Box<dyn Effect>],
    seed: u64,
    position: usize,
    (alpha_deg, beta_deg): (f64, f64),
    g: f64,
) -> [f64; 3] {
    let kin = position_kinematics(effects, seed, position, alpha_deg, beta_deg);
    if kin.changed {
        kin.accel(g)
    } else {
        accelcal_shared::gravity(alpha_deg, beta_deg, g)
    }
}

/// One sample set: for each channel in order, `bias + k·a + Σ effects + noise`, rounded and
/// clipped to the unsigned 16-bit ADC range when `quantize`; `emit(channel, code)` receives it.
/// The noise is drawn from `rng` once per channel, in channel order.
pub fn sample_set<R: Rng + ?Sized>(
    channels: &[ChannelTruth],
    effects: &[Box<dyn Effect>],
    set: &SetCtx,
    noise: &Normal<f64>,
    rng: &mut R,
    quantize: bool,
    mut emit: impl FnMut(usize, f64),
) {
    let (lo, hi) = CodeRange::Unsigned16.rails();
    for (ch, truth) in channels.iter().enumerate() {
        let signal = (0..3).map(|j| truth.k[j] * set.accel[j]).sum::<f64>();
        let ctx = SampleCtx {
            t_s: set.t_s,
            position: set.position,
            sample: set.sample,
            accel: set.accel,
            channel: ch,
            axis: truth.axis,
            t_in_dwell_s: set.t_in_dwell_s,
            temp_c: set.temp_c,
            prev_accel: set.prev_accel,
            signal,
        };
        let mut u = truth.bias + signal;
        for e in effects {
            u += e.output(&ctx);
        }
        u += noise.sample(rng);
        emit(ch, if quantize { u.round().clamp(lo, hi) } else { u });
    }
}

/// The white-noise distribution of a given one-sigma (codes).
pub fn noise_distribution(sd: f64) -> Normal<f64> {
    Normal::new(0.0, sd.abs()).expect("finite standard deviation")
}

/// Why a truth file cannot be turned into a unit.
#[derive(Debug, thiserror::Error)]
pub enum UnitError {
    /// The file could not be read.
    #[error("{path}: {cause}")]
    Read {
        /// The file.
        path: String,
        /// The cause.
        cause: std::io::Error,
    },
    /// The file is not a truth document.
    #[error("{path}: not a truth file of `accelcal simulate`: {cause}")]
    Json {
        /// The file.
        path: String,
        /// The cause.
        cause: serde_json::Error,
    },
    /// A value of the truth is out of range.
    #[error("{0}")]
    Invalid(String),
    /// A bias outside the node's unsigned 16-bit codes.
    #[error("{}", self.worded(&Plain).unwrap_or_default())]
    SignedBias {
        /// The channel.
        channel: String,
        /// Its bias, codes.
        bias: f64,
    },
    /// What is wrong with a truth file.
    #[error("{path}: {cause}")]
    InFile {
        /// The file.
        path: String,
        /// What is wrong.
        cause: Box<UnitError>,
    },
    /// An effect cannot be rebuilt from its description.
    #[error("effects[{index}]: {message}")]
    Effect {
        /// Its index in the truth's `effects`.
        index: usize,
        /// Why.
        message: String,
    },
    /// The unit is not a triad `x`, `y`, `z` along axes 0, 1, 2 (what the emulated node samples).
    #[error("the emulated node samples a triad: expected channels x, y, z along axes 0, 1, 2, got {0}")]
    NotATriad(String),
}

impl Worded for UnitError {
    fn worded(&self, w: &dyn Wording) -> Option<String> {
        match self {
            UnitError::SignedBias { channel, bias } => Some(format!(
                "channel `{channel}`: bias {bias} is outside the node's unsigned 16-bit codes 0..=65535 (a truth of {}?)",
                w.name(Setting::SimulateSigned)
            )),
            UnitError::InFile { path, cause } => {
                Some(format!("{path}: {}", cause.worded(w).unwrap_or_else(|| cause.to_string())))
            }
            _ => None,
        }
    }
}

impl Classify for UnitError {
    fn kind(&self) -> Kind {
        Kind::BadInput
    }
}

/// A simulated unit: its channels' linear models, its effects, gravity and noise, sampled one set
/// at a time with [`Unit::sample`] (the same arithmetic as [`super::simulate`]).
pub struct Unit {
    /// Seed of the simulation it comes from (the effects' per-position draws use it).
    pub seed: u64,
    /// Gravity, m/s².
    pub g: f64,
    /// Noise per sample, codes (one sigma).
    pub noise: f64,
    /// The channels.
    pub channels: Vec<ChannelTruth>,
    /// The effects, rebuilt from their descriptions.
    pub effects: Vec<Box<dyn Effect>>,
}

impl std::fmt::Debug for Unit {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Unit")
            .field("seed", &self.seed)
            .field("g", &self.g)
            .field("noise", &self.noise)
            .field("channels", &self.channels)
            .field("effects", &self.effects.iter().map(|e| e.describe()).collect::<Vec<_>>())
            .finish()
    }
}

impl Unit {
    /// Rebuilds a unit from its truth (any channel layout). Refuses non-finite or out-of-range
    /// numbers and effects the registry cannot rebuild, naming the entry.
    pub fn from_truth(t: &Truth) -> Result<Unit, UnitError> {
        if !(t.g.is_finite() && t.g > 0.0) {
            return Err(UnitError::Invalid(format!("g must be a finite number > 0, got {}", t.g)));
        }
        if !(t.noise.is_finite() && t.noise >= 0.0) {
            return Err(UnitError::Invalid(format!("noise must be a finite number >= 0, got {}", t.noise)));
        }
        if t.channels.is_empty() {
            return Err(UnitError::Invalid("no channels".into()));
        }
        for (i, c) in t.channels.iter().enumerate() {
            if c.axis > 2 || !c.bias.is_finite() || !c.k.iter().all(|k| k.is_finite()) {
                return Err(UnitError::Invalid(format!(
                    "channels[{i}] (`{}`): expected axis 0..=2 and finite bias and k",
                    c.name
                )));
            }
        }
        let effects = t
            .effects
            .iter()
            .enumerate()
            .map(|(index, d)| {
                effects::from_description(d).map_err(|message| UnitError::Effect { index, message })
            })
            .collect::<Result<Vec<_>, _>>()?;
        Ok(Unit { seed: t.seed, g: t.g, noise: t.noise, channels: t.channels.clone(), effects })
    }

    /// Rebuilds a unit for the emulated node: [`Unit::from_truth`], and exactly three channels
    /// `x`, `y`, `z` along axes 0, 1, 2. Effects needing a temperature see the sensor's
    /// temperature in the bench's thermal chamber. Biases are the node's unsigned 16-bit codes, so
    /// one outside 0..=65535 is refused (a truth of `simulate --codes signed16` holds biases less
    /// mid-scale).
    pub fn for_node(t: &Truth) -> Result<Unit, UnitError> {
        let u = Unit::from_truth(t)?;
        u.check_triad()?;
        let (lo, hi) = CodeRange::Unsigned16.rails();
        if let Some(c) = u.channels.iter().find(|c| !(lo..=hi).contains(&c.bias)) {
            return Err(UnitError::SignedBias { channel: c.name.clone(), bias: c.bias });
        }
        Ok(u)
    }

    /// Checks that the unit is a triad: exactly three channels `x`, `y`, `z` along axes 0, 1, 2.
    pub fn check_triad(&self) -> Result<(), UnitError> {
        let triad = self.channels.len() == 3
            && self
                .channels
                .iter()
                .zip(["x", "y", "z"])
                .enumerate()
                .all(|(i, (c, n))| c.name == n && c.axis == i);
        if triad {
            return Ok(());
        }
        let got: Vec<String> =
            self.channels.iter().map(|c| format!("{} (axis {})", c.name, c.axis)).collect();
        Err(UnitError::NotATriad(got.join(", ")))
    }

    /// Reads a truth file (`accelcal simulate --truth`) and rebuilds the unit for the emulated
    /// node ([`Unit::for_node`]); errors name the file.
    pub fn read_for_node(path: &Path) -> Result<Unit, UnitError> {
        let p = path.display().to_string();
        let text =
            std::fs::read_to_string(path).map_err(|cause| UnitError::Read { path: p.clone(), cause })?;
        let t: Truth =
            serde_json::from_str(&text).map_err(|cause| UnitError::Json { path: p.clone(), cause })?;
        Unit::for_node(&t).map_err(|e| UnitError::InFile { path: p, cause: Box::new(e) })
    }

    /// The acceleration the block sees standing at `angles` (degrees) as position `position`.
    pub fn standing_accel(&self, position: usize, angles: (f64, f64)) -> [f64; 3] {
        standing_accel(&self.effects, self.seed, position, angles, self.g)
    }

    /// The kinematics of a standing position (see [`position_kinematics`]).
    pub fn kinematics(&self, position: usize, (alpha_deg, beta_deg): (f64, f64)) -> Kinematics {
        position_kinematics(&self.effects, self.seed, position, alpha_deg, beta_deg)
    }

    /// The noise distribution of the unit.
    pub fn noise_distribution(&self) -> Normal<f64> {
        noise_distribution(self.noise)
    }

    /// One quantised sample set into `out` (one code per channel), noise from `rng`.
    pub fn sample<R: Rng + ?Sized>(&self, set: &SetCtx, noise: &Normal<f64>, rng: &mut R, out: &mut [f64]) {
        sample_set(&self.channels, &self.effects, set, noise, rng, true, |ch, u| out[ch] = u);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::{simulate, Layout, SimConfig};
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;
    use rand_distr::StandardNormal;

    const SPECS: [&str; 6] = [
        "settling=gain:3.5,tau:0.25",
        "hysteresis=h:7",
        "nonlinearity=k2:0.4,ax*ay:0.125,ax*ay*az:1e-3",
        "bias_drift=rate:0.3",
        "angle_error=sd_mrad:2",
        "head_misalignment=rx_mrad:1.5,rz_mrad:-0.7",
    ];

    fn config(seed: u64, samples: usize) -> SimConfig {
        SimConfig {
            seed,
            samples,
            effects: SPECS.iter().map(|s| super::effects::parse(s).unwrap()).collect(),
            ..SimConfig::default()
        }
    }

    #[test]
    fn the_unit_reproduces_simulate_bit_for_bit() {
        let cfg = config(7, 12);
        let (c, truth) = simulate(&cfg);
        let unit = Unit::from_truth(&truth).unwrap();
        // `simulate` draws 4 normals per channel (bias, scale, two misalignments) before the noise.
        let mut rng = ChaCha8Rng::seed_from_u64(cfg.seed);
        for _ in 0..4 * unit.channels.len() {
            let _: f64 = rng.sample(StandardNormal);
        }
        let noise = unit.noise_distribution();
        let dt = 1.0 / cfg.rate_hz;
        let (mut t, mut row, mut prev_accel) = (0.0f64, 0, None);
        for (p, &angles) in cfg.plan.positions.iter().enumerate() {
            let accel = unit.standing_accel(p, angles);
            for s in 0..cfg.samples {
                let set = SetCtx {
                    t_s: t,
                    position: p,
                    sample: s,
                    accel,
                    t_in_dwell_s: s as f64 * dt,
                    temp_c: f64::NAN,
                    prev_accel,
                };
                let mut out = [0.0; 3];
                unit.sample(&set, &noise, &mut rng, &mut out);
                for ch in 0..3 {
                    assert_eq!(
                        out[ch].to_bits(),
                        c.channels[ch].codes[row].to_bits(),
                        "position {p} sample {s}"
                    );
                }
                row += 1;
                t += dt;
            }
            prev_accel = Some(accel);
            t += cfg.move_s;
        }
        assert_eq!(row, c.len());
    }

    #[test]
    fn descriptions_rebuild_the_same_effects() {
        let mut specs: Vec<String> = SPECS.iter().map(|s| s.to_string()).collect();
        specs.extend(crate::effects::names().map(String::from));
        specs.push("temperature=bias:0.1,scale:-35.25,t_ref:20".into());
        specs.push("bias_drift=rate:1e-300".into());
        for s in &specs {
            let e = super::effects::parse(s).unwrap();
            let d = e.describe();
            let rebuilt = super::effects::from_description(&d).unwrap();
            assert_eq!(rebuilt.name(), e.name());
            assert_eq!(rebuilt.describe(), d, "{s}");
        }
    }

    #[test]
    fn bad_entries_and_layouts_are_named() {
        let (_, mut truth) = simulate(&SimConfig { samples: 1, ..config(3, 1) });
        assert_eq!(Unit::for_node(&truth).unwrap().effects.len(), SPECS.len());
        truth.effects.push(serde_json::json!({"name": "settling", "tau": "long"}));
        let e = Unit::from_truth(&truth).unwrap_err().to_string();
        assert!(e.starts_with("effects[6]: effect `settling`: `tau` must be a number"), "{e}");
        truth.effects[6] = serde_json::json!({"name": "wobble", "a": 1});
        let e = Unit::from_truth(&truth).unwrap_err().to_string();
        assert!(e.contains("effects[6]") && e.contains("unknown effect `wobble`"), "{e}");
        truth.effects[6] = serde_json::json!("settling");
        assert!(Unit::from_truth(&truth).unwrap_err().to_string().contains("effects[6]: expected an object"));
        // The emulated bench has a thermal chamber: a temperature effect is taken.
        truth.effects[6] = serde_json::json!({"name": "temperature", "bias": 1.0});
        assert!(Unit::from_truth(&truth).is_ok());
        assert_eq!(Unit::for_node(&truth).unwrap().effects.len(), SPECS.len() + 1);

        let (_, block) =
            simulate(&SimConfig { samples: 1, layout: Layout::Block(3), ..SimConfig::default() });
        assert!(Unit::from_truth(&block).is_ok());
        let e = Unit::for_node(&block).unwrap_err().to_string();
        assert!(e.contains("expected channels x, y, z along axes 0, 1, 2, got a1 (axis 0)"), "{e}");
        let (_, mut swapped) = simulate(&SimConfig { samples: 1, ..SimConfig::default() });
        let mut signed = swapped.clone();
        signed.channels[1].bias = -120.0;
        let e = Unit::for_node(&signed).unwrap_err().to_string();
        assert!(e.contains("channel `y`: bias -120 is outside"), "{e}");
        swapped.channels.swap(0, 1);
        assert!(matches!(Unit::for_node(&swapped), Err(UnitError::NotATriad(_))));
        swapped.channels.pop();
        assert!(matches!(Unit::for_node(&swapped), Err(UnitError::NotATriad(_))));
    }

    #[test]
    fn truth_files_are_read_and_their_errors_name_the_file() {
        let dir = tempfile::tempdir().unwrap();
        let (_, truth) = simulate(&config(4, 1));
        let p = dir.path().join("unit.json");
        std::fs::write(&p, serde_json::to_string_pretty(&truth).unwrap()).unwrap();
        let u = Unit::read_for_node(&p).unwrap();
        assert_eq!(u.channels.len(), 3);
        std::fs::write(&p, "{}").unwrap();
        let e = Unit::read_for_node(&p).unwrap_err().to_string();
        assert!(e.starts_with(&format!("{}: not a truth file", p.display())), "{e}");
        let mut bad = truth.clone();
        bad.g = f64::NAN;
        std::fs::write(&p, serde_json::to_string(&bad).unwrap().replace("NaN", "null")).unwrap();
        assert!(Unit::read_for_node(&p).is_err());
        bad.g = -1.0;
        std::fs::write(&p, serde_json::to_string(&bad).unwrap()).unwrap();
        let e = Unit::read_for_node(&p).unwrap_err().to_string();
        assert!(e.contains("unit.json: g must be a finite number > 0"), "{e}");
    }
}
