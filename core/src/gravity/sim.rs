//! Seeded simulation of a hand-placed multi-position session, written in the imu_tk format with its truth.
//!
//! The session starts with a rest, then alternates hand movements and static holds. Each hold has a
//! gravity direction drawn uniformly on the unit sphere (in the sensor frame). During a movement the
//! direction turns from one hold's to the next along the great circle (smoothstep in time) while the
//! hand adds a linear acceleration `A sin(2πτ) e` (τ ∈ [0, 1] the movement phase, `e` a random unit
//! vector), the acceleration of a displacement that starts and ends at rest. The raw output is
//! `u = raw_from_specific_force(g d + a_hand)` of the true [`TriadModel`], plus white Gaussian noise,
//! rounded to integer codes and clamped to the 16-bit range, like the real Xsens recording.

use std::io;
use std::path::{Path, PathBuf};

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal, StandardNormal};

use super::fit::TriadModel;
use super::imutk::{self, Recording};

/// Settings of a simulated session.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SessionConfig {
    /// Seed of the random generator (ChaCha8).
    pub seed: u64,
    /// True model of the sensor.
    pub truth: TriadModel,
    /// Gravity magnitude, in m/s².
    pub g: f64,
    /// Sampling rate, in Hz.
    pub rate_hz: f64,
    /// Duration of the initial rest, in seconds.
    pub rest_s: f64,
    /// Number of holds after the initial rest.
    pub holds: usize,
    /// Range of hold durations, in seconds (uniform).
    pub hold_s: (f64, f64),
    /// Range of movement durations, in seconds (uniform).
    pub move_s: (f64, f64),
    /// Peak linear acceleration of the hand during a movement, in m/s².
    pub hand_m_s2: f64,
    /// Standard deviation of the white output noise, in codes.
    pub noise_codes: f64,
}

impl Default for SessionConfig {
    /// A session like the real Xsens recording: 16-bit codes centred near 33000, about 414 codes per
    /// m/s², misalignments of a few mrad, 3.3 codes of noise, 50 s of rest and 38 holds of 4–11 s.
    fn default() -> Self {
        Self {
            seed: 1,
            truth: TriadModel {
                bias: [33120.0, 33280.0, 32360.0],
                scale: [414.4, 412.0, 414.6],
                alpha: [3.4e-3, -9.2e-3, 21.4e-3],
                quad: [0.0; 3],
            },
            g: 9.81744,
            rate_hz: 100.0,
            rest_s: 50.0,
            holds: 38,
            hold_s: (4.0, 11.0),
            move_s: (2.5, 5.0),
            hand_m_s2: 4.0,
            noise_codes: 3.3,
        }
    }
}

/// A simulated session and its truth.
#[derive(Debug, Clone)]
pub struct SimSession {
    /// Settings used.
    pub config: SessionConfig,
    /// The raw recording.
    pub recording: Recording,
    /// True static intervals `[start, end)` in samples, the initial rest first.
    pub holds: Vec<(usize, usize)>,
    /// True gravity direction of each static interval (unit vectors in the calibrated frame).
    pub directions: Vec<[f64; 3]>,
}

/// Truth file written next to a simulated recording.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct SimTruth {
    /// Settings used, including the true model.
    pub config: SessionConfig,
    /// True static intervals `[start, end)` in samples.
    pub holds: Vec<(usize, usize)>,
    /// True gravity direction of each static interval.
    pub directions: Vec<[f64; 3]>,
}

/// Simulates a session.
pub fn simulate(cfg: &SessionConfig) -> SimSession {
    let mut rng = ChaCha8Rng::seed_from_u64(cfg.seed);
    let noise = Normal::new(0.0, cfg.noise_codes.max(0.0)).unwrap_or_else(|_| Normal::new(0.0, 0.0).unwrap());
    let dt = 1.0 / cfg.rate_hz;
    let mut rec = Recording::default();
    let mut holds = Vec::new();
    let mut directions = Vec::new();

    let emit = |rec: &mut Recording, f: [f64; 3], rng: &mut ChaCha8Rng| {
        let clean = cfg.truth.raw_from_specific_force(f).unwrap_or(cfg.truth.bias);
        let u = clean.map(|c| (c + noise.sample(rng)).round().clamp(0.0, 65535.0));
        rec.t.push(rec.t.len() as f64 * dt);
        rec.codes.push(u);
    };

    // The initial rest: the block lies on its base, as it usually does.
    let mut dir = [0.0, 0.0, 1.0];
    let samples = |s: f64| (s * cfg.rate_hz).round().max(1.0) as usize;
    let mut start = 0;
    for _ in 0..samples(cfg.rest_s) {
        emit(&mut rec, dir.map(|d| cfg.g * d), &mut rng);
    }
    holds.push((start, rec.len()));
    directions.push(dir);
    for _ in 0..cfg.holds {
        let next = random_unit(&mut rng);
        let hand = random_unit(&mut rng);
        let n_move = samples(rng.random_range(cfg.move_s.0..=cfg.move_s.1));
        for k in 0..n_move {
            let tau = (k as f64 + 0.5) / n_move as f64;
            let d = slerp(dir, next, tau * tau * (3.0 - 2.0 * tau));
            let lin = cfg.hand_m_s2 * (2.0 * std::f64::consts::PI * tau).sin();
            emit(&mut rec, std::array::from_fn(|i| cfg.g * d[i] + lin * hand[i]), &mut rng);
        }
        dir = next;
        start = rec.len();
        for _ in 0..samples(rng.random_range(cfg.hold_s.0..=cfg.hold_s.1)) {
            emit(&mut rec, dir.map(|d| cfg.g * d), &mut rng);
        }
        holds.push((start, rec.len()));
        directions.push(dir);
    }
    SimSession { config: cfg.clone(), recording: rec, holds, directions }
}

impl SimSession {
    /// Writes `<stem>.txt` (imu_tk format) and `<stem>.truth.json` in `dir`; returns both paths.
    pub fn write(&self, dir: &Path, stem: &str) -> io::Result<(PathBuf, PathBuf)> {
        let data = dir.join(format!("{stem}.txt"));
        let truth = dir.join(format!("{stem}.truth.json"));
        imutk::write(&self.recording, io::BufWriter::new(std::fs::File::create(&data)?))?;
        let t = SimTruth {
            config: self.config.clone(),
            holds: self.holds.clone(),
            directions: self.directions.clone(),
        };
        std::fs::write(&truth, serde_json::to_string_pretty(&t).map_err(io::Error::other)?)?;
        Ok((data, truth))
    }
}

fn random_unit(rng: &mut ChaCha8Rng) -> [f64; 3] {
    loop {
        let v: [f64; 3] = std::array::from_fn(|_| StandardNormal.sample(rng));
        let n = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        if n > 1e-6 {
            return v.map(|x| x / n);
        }
    }
}

/// Spherical interpolation between unit vectors (falls back to a normalised lerp when nearly parallel
/// or antiparallel, where the great circle is undefined or ill-conditioned).
fn slerp(a: [f64; 3], b: [f64; 3], s: f64) -> [f64; 3] {
    let dot = (a[0] * b[0] + a[1] * b[1] + a[2] * b[2]).clamp(-1.0, 1.0);
    let omega = dot.acos();
    let v: [f64; 3] = if omega.sin().abs() < 1e-3 {
        std::array::from_fn(|i| a[i] * (1.0 - s) + b[i] * s)
    } else {
        let (wa, wb) = (((1.0 - s) * omega).sin() / omega.sin(), (s * omega).sin() / omega.sin());
        std::array::from_fn(|i| wa * a[i] + wb * b[i])
    };
    let n = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    if n > 1e-9 {
        v.map(|x| x / n)
    } else {
        b
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn simulation_is_deterministic_and_static_intervals_match_gravity() {
        let cfg = SessionConfig { holds: 5, ..Default::default() };
        let a = simulate(&cfg);
        let b = simulate(&cfg);
        assert_eq!(a.recording, b.recording);
        assert_eq!(a.holds.len(), 6);
        // Within each static interval the noise-free model output has norm g: check the mean.
        for &(s, e) in &a.holds {
            let n = (e - s) as f64;
            let mean: [f64; 3] =
                std::array::from_fn(|i| a.recording.codes[s..e].iter().map(|c| c[i]).sum::<f64>() / n);
            let f = cfg.truth.apply(mean);
            let norm = (f[0] * f[0] + f[1] * f[1] + f[2] * f[2]).sqrt();
            assert!((norm - cfg.g).abs() < 0.01, "norm {norm}");
        }
        let other = simulate(&SessionConfig { seed: 2, ..cfg });
        assert_ne!(other.recording, a.recording);
    }

    #[test]
    fn directions_are_spread_over_the_sphere() {
        let s = simulate(&SessionConfig {
            holds: 400,
            hold_s: (0.1, 0.1),
            move_s: (0.1, 0.1),
            rest_s: 0.1,
            ..Default::default()
        });
        let mean: [f64; 3] = std::array::from_fn(|i| s.directions.iter().map(|d| d[i]).sum::<f64>() / 401.0);
        for m in mean {
            assert!(m.abs() < 0.1, "{mean:?}");
        }
        let zz = s.directions.iter().map(|d| d[2] * d[2]).sum::<f64>() / 401.0;
        assert!((zz - 1.0 / 3.0).abs() < 0.05, "E[z²] = {zz}");
    }

    #[test]
    fn slerp_ends_and_midpoint() {
        let a = [1.0, 0.0, 0.0];
        let b = [0.0, 1.0, 0.0];
        assert_eq!(slerp(a, b, 0.0), a);
        let m = slerp(a, b, 0.5);
        assert!((m[0] - m[1]).abs() < 1e-12 && (m[0] - 0.5f64.sqrt()).abs() < 1e-12);
        let e = slerp(a, b, 1.0);
        assert!((e[1] - 1.0).abs() < 1e-12);
    }
}
