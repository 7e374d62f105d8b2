//! Applying a thermal model-4 calibration: bias and sensitivity that move with temperature,
//! `a = K(t)⁻¹ (u − u0(t))` with `t = temp_c − t_ref`.
//!
//! The model of channel i is `u_i = b_i + b_it·t + b_itt·t² + Σ_j (K_ij + K_ijt·t)·a_j` (codes; the
//! terms `1, t, t^2` and `ax, ay, az, ax*t, ay*t, az*t` of [`crate::terms::BASIS`], any subset of
//! the thermal ones). A node cannot invert `K(t)` per sample set, and need not: the temperature
//! moves slowly. It reads the temperature once per block of sample sets, filters it
//! ([`TempFilter`]) and re-evaluates the calibration at the filtered temperature
//! ([`ThermalCalF32::at`]), in f32, in the same code on the node and on the host, so that a host
//! replay of a node's stream is bit-exact. Per sample set the node then spends what model 4 costs.
//!
//! [`ThermalModel`] is the f64 reference the f32 evaluation is held to.

use crate::linear::{LinearCal, LinearCalF32, LinearCalFixed, LinearError, Model4};
use crate::record::{Record, Thermal};
use crate::terms::{Structure, BASIS, MODEL_4, T_INDEX};
use crate::wire::{BlockTemp, Codes};

/// Sample sets per temperature update: one stream block.
pub const SETS_PER_UPDATE: usize = crate::wire::MAX_BLOCK;

/// Weight of a new block's mean temperature in the node's first-order filter.
pub const FILTER_WEIGHT: f32 = 0.25;

/// The structures a node applies: model 4 with any subset of the thermal terms.
pub fn node_applies(s: Structure) -> bool {
    MODEL_4.is_subset_of(s) && s.without_thermal() == MODEL_4
}

/// A triad's thermal model-4 calibration as fitted, in f64.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ThermalModel {
    /// The record's temperature part (reference, range, input).
    pub thermal: Thermal,
    /// Bias of channel i: `[b, b_t, b_tt]`, codes, codes/°C, codes/°C².
    pub bias: [[f64; 3]; 3],
    /// Sensitivity at the reference temperature, codes per m/s² (row i is channel i).
    pub k: [[f64; 3]; 3],
    /// Change of sensitivity per °C, codes per m/s² per °C.
    pub kt: [[f64; 3]; 3],
}

impl ThermalModel {
    /// The thermal model of a record of model 4 with thermal terms on three channels (`None` for
    /// anything else, model 4 without thermal terms included).
    pub fn of(record: &Record) -> Option<ThermalModel> {
        let thermal = record.thermal?;
        if record.n_channels != 3 || !node_applies(record.structure) {
            return None;
        }
        let mut m = ThermalModel { thermal, bias: [[0.0; 3]; 3], k: [[0.0; 3]; 3], kt: [[0.0; 3]; 3] };
        // Slots by `get`: a term the node cannot hold gives `None`, never a panic path.
        for (n, i) in record.structure.indices().enumerate() {
            // ax*t, ay*t, az*t: the axis is the term's acceleration factor.
            let axis = BASIS.get(i)?.pow.iter().position(|&p| p == 1);
            let channels = m.bias.iter_mut().zip(&mut m.k).zip(&mut m.kt).zip(&record.coefficients);
            for (((bias, k), kt), coefficients) in channels {
                let v = *coefficients.get(n)?;
                let slot = match i {
                    0 => &mut bias[0],
                    1..=3 => k.get_mut(i - 1)?,
                    _ if i == T_INDEX => &mut bias[1],
                    _ if i == T_INDEX + 1 => &mut bias[2],
                    _ => kt.get_mut(axis?)?,
                };
                *slot = v;
            }
        }
        Some(m)
    }

    /// The record of this model for `device_id`, made at `created_unix_s`, with gravity `g_m_s2`:
    /// model 4 with `t`, and with `t^2` and each `ax*t`, `ay*t`, `az*t` whose coefficient is not
    /// zero on some channel ([`ThermalModel::of`] reads it back).
    pub fn to_record(&self, device_id: [u8; 12], created_unix_s: u64, g_m_s2: f64) -> Record {
        let mut idx: heapless::Vec<usize, 8> = heapless::Vec::new();
        let _ = idx.extend_from_slice(&[1, 2, 3, T_INDEX]);
        if self.bias.iter().any(|b| b[2] != 0.0) {
            let _ = idx.push(T_INDEX + 1);
        }
        for axis in 0..3 {
            if self.kt.iter().any(|r| r[axis] != 0.0) {
                let _ = idx.push(T_INDEX + 2 + axis);
            }
        }
        let structure = Structure::from_indices(&idx);
        let mut r = Record {
            device_id,
            created_unix_s,
            structure,
            n_channels: 3,
            coefficients: [[0.0; crate::terms::N_BASIS]; crate::record::MAX_CHANNELS],
            g_m_s2: Some(g_m_s2),
            thermal: Some(self.thermal),
        };
        for (n, i) in structure.indices().enumerate() {
            for c in 0..3 {
                r.coefficients[c][n] = match i {
                    0 => self.bias[c][0],
                    1..=3 => self.k[c][i - 1],
                    _ if i == T_INDEX => self.bias[c][1],
                    _ if i == T_INDEX + 1 => self.bias[c][2],
                    _ => self.kt[c][i - T_INDEX - 2],
                };
            }
        }
        r
    }

    /// The model-4 calibration at temperature `temp_c` (°C), in f64.
    pub fn at(&self, temp_c: f64) -> Model4 {
        let t = temp_c - self.thermal.t_ref_c as f64;
        let mut m = Model4 { u0: [0.0; 3], k: [[0.0; 3]; 3] };
        for i in 0..3 {
            m.u0[i] = self.bias[i][0] + t * (self.bias[i][1] + t * self.bias[i][2]);
            for j in 0..3 {
                m.k[i][j] = self.k[i][j] + self.kt[i][j] * t;
            }
        }
        m
    }

    /// The model in f32, as a node evaluates it.
    pub fn to_f32(&self) -> ThermalCalF32 {
        let f = |a: [[f64; 3]; 3]| a.map(|r| r.map(|v| v as f32));
        ThermalCalF32 { thermal: self.thermal, bias: f(self.bias), k: f(self.k), kt: f(self.kt) }
    }

    /// Whether the node's f32 evaluation ([`ThermalCalF32::at`], which checks the reciprocal
    /// condition) inverts the model at the reference and at 17 temperatures evenly over the
    /// calibrated range, its ends included, with the determinant of `K(t)⁻¹` of one sign at all of
    /// them (the record gate's check: `det K(t)` is a cubic in `t`, so a singular point between
    /// two grid temperatures changes its sign there). f32 only: what the node runs at boot, in
    /// the node's arithmetic, without f64 arithmetic in its flash.
    pub fn invertible(&self) -> Result<(), LinearError> {
        let th = self.thermal;
        let f = self.to_f32();
        let det = |m: &[[f32; 3]; 3]| {
            m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
                - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
                + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
        };
        let sign = det(&f.at(th.t_ref_c)?.m) > 0.0;
        let grid = (0..=16).map(|i| th.t_min_c + (th.t_max_c - th.t_min_c) * i as f32 / 16.0);
        for temp in grid.chain([th.t_ref_c]) {
            if (det(&f.at(temp)?.m) > 0.0) != sign {
                return Err(LinearError::Singular);
            }
        }
        Ok(())
    }
}

/// A thermal calibration in f32: what the firmware evaluates once per block.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ThermalCalF32 {
    /// The record's temperature part.
    pub thermal: Thermal,
    /// See [`ThermalModel::bias`].
    pub bias: [[f32; 3]; 3],
    /// See [`ThermalModel::k`].
    pub k: [[f32; 3]; 3],
    /// See [`ThermalModel::kt`].
    pub kt: [[f32; 3]; 3],
}

impl ThermalCalF32 {
    /// The model-4 calibration at `temp_c` (°C), evaluated and inverted (adjugate over
    /// determinant) in f32. Fails when `K(t)` is singular or badly conditioned there.
    pub fn at(&self, temp_c: f32) -> Result<LinearCalF32, LinearError> {
        let t = temp_c - self.thermal.t_ref_c;
        // Written out element by element (the node runs this once per block; loops here cost
        // their counters): the same operations, in the same order, as the loops they replace.
        let (b, k0, kt) = (&self.bias, &self.k, &self.kt);
        let u = |i: usize| b[i][0] + t * (b[i][1] + t * b[i][2]);
        let u0 = [u(0), u(1), u(2)];
        let row = |i: usize| [k0[i][0] + kt[i][0] * t, k0[i][1] + kt[i][1] * t, k0[i][2] + kt[i][2] * t];
        let k = [row(0), row(1), row(2)];
        let cof = |r0: usize, r1: usize, c0: usize, c1: usize| k[r0][c0] * k[r1][c1] - k[r0][c1] * k[r1][c0];
        // Adjugate: m[j][i] = cofactor(i, j).
        let adj = [
            [cof(1, 2, 1, 2), -cof(0, 2, 1, 2), cof(0, 1, 1, 2)],
            [-cof(1, 2, 0, 2), cof(0, 2, 0, 2), -cof(0, 1, 0, 2)],
            [cof(1, 2, 0, 1), -cof(0, 2, 0, 1), cof(0, 1, 0, 1)],
        ];
        let det = k[0][0] * adj[0][0] + k[0][1] * adj[1][0] + k[0][2] * adj[2][0];
        // Reciprocal condition in the 1-norm, as Model4::invert checks it. Written out (the
        // node runs this once per block): a NaN anywhere fails the finiteness check below.
        let norm1 = |m: &[[f32; 3]; 3]| {
            let col = |j: usize| libm::fabsf(m[0][j]) + libm::fabsf(m[1][j]) + libm::fabsf(m[2][j]);
            let (a, b, c) = (col(0), col(1), col(2));
            let ab = if a > b { a } else { b };
            if ab > c {
                ab
            } else {
                c
            }
        };
        let div = |r: [f32; 3]| [r[0] / det, r[1] / det, r[2] / det];
        let m = [div(adj[0]), div(adj[1]), div(adj[2])];
        let rcond = 1.0 / (norm1(&k) * norm1(&m));
        let fin = |r: &[f32; 3]| r[0].is_finite() && r[1].is_finite() && r[2].is_finite();
        let finite = fin(&m[0]) && fin(&m[1]) && fin(&m[2]) && fin(&u0);
        if !(rcond > 1e-6) || !finite {
            return Err(LinearError::Singular);
        }
        Ok(LinearCalF32 { u0, m })
    }

    /// Whether `temp_c` lies outside the calibrated range (the node flags such output).
    pub fn out_of_range(&self, temp_c: f32) -> bool {
        !(temp_c >= self.thermal.t_min_c && temp_c <= self.thermal.t_max_c)
    }

    /// The f32 evaluation widened to f64, for the fixed-point build ([`LinearCal::to_fixed`]).
    pub fn at_wide(&self, temp_c: f32) -> Result<LinearCal, LinearError> {
        let c = self.at(temp_c)?;
        Ok(LinearCal { u0: c.u0.map(|v| v as f64), m: c.m.map(|r| r.map(|v| v as f64)) })
    }
}

/// The node's temperature filter: the mean temperature of each block of sample sets, smoothed by a
/// first-order filter `y ← y + w·(x − y)` with `w` = [`FILTER_WEIGHT`] (a time constant of about
/// four blocks), started at the first block's mean. f32, the same on the node and in a host replay.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct TempFilter {
    y: Option<f32>,
}

impl TempFilter {
    /// Adds one block's mean temperature (°C) and returns the filtered temperature.
    pub fn push(&mut self, block_mean_c: f32) -> f32 {
        let y = match self.y {
            Some(y) => y + FILTER_WEIGHT * (block_mean_c - y),
            None => block_mean_c,
        };
        self.y = Some(y);
        y
    }

    /// The filtered temperature, once a block has been pushed.
    pub fn value(&self) -> Option<f32> {
        self.y
    }
}

/// A node's thermal calibration at work: fed each sample set's temperature in the order the sets
/// are calibrated, it keeps the calibration to apply. The rule, the same on the node and in a
/// host replay: the first set's temperature starts the filter and the calibration is evaluated
/// there; after every further [`SETS_PER_UPDATE`] sets the filter takes their mean and the
/// calibration is evaluated again at the filtered temperature. Where `K(t)` cannot be inverted
/// the last calibration stays (and the output is flagged, as outside the range).
#[derive(Clone, Copy, Debug)]
pub struct ThermalTracker {
    model: ThermalCalF32,
    filter: TempFilter,
    sum: f32,
    n: usize,
    cal: LinearCalF32,
    failed: bool,
    evaluations: u32,
}

impl ThermalTracker {
    /// A tracker of `model`, applying `start` (the model at its reference temperature, which the
    /// record gate checked) until the first set's temperature arrives.
    pub fn new(model: ThermalCalF32, start: LinearCalF32) -> ThermalTracker {
        ThermalTracker {
            model,
            filter: TempFilter::default(),
            sum: 0.0,
            n: 0,
            cal: start,
            failed: false,
            evaluations: 0,
        }
    }

    fn evaluate(&mut self, temp_c: f32) {
        self.evaluations = self.evaluations.wrapping_add(1);
        match self.model.at(temp_c) {
            Ok(c) => {
                self.cal = c;
                self.failed = false;
            }
            Err(_) => self.failed = true,
        }
    }

    /// Takes the temperature (°C) of the next sample set and returns the calibration to apply to
    /// that set.
    #[inline]
    pub fn on_set(&mut self, temp_c: f32) -> &LinearCalF32 {
        if self.filter.value().is_none() {
            let y = self.filter.push(temp_c);
            self.evaluate(y);
        } else {
            self.sum += temp_c;
            self.n += 1;
            if self.n == SETS_PER_UPDATE {
                let y = self.filter.push(self.sum / SETS_PER_UPDATE as f32);
                self.sum = 0.0;
                self.n = 0;
                self.evaluate(y);
            }
        }
        &self.cal
    }

    /// The filtered temperature the calibration was last evaluated at, °C.
    pub fn applied_c(&self) -> Option<f32> {
        self.filter.value()
    }

    /// Whether the output is flagged: the filtered temperature lies outside the calibrated range,
    /// or the calibration could not be evaluated there.
    pub fn out_of_range(&self) -> bool {
        self.failed || self.filter.value().is_some_and(|y| self.model.out_of_range(y))
    }

    /// The model.
    pub fn model(&self) -> &ThermalCalF32 {
        &self.model
    }

    /// How many times the calibration was evaluated (wrapping): it changes exactly when
    /// [`ThermalTracker::on_set`] re-evaluated the calibration.
    pub fn evaluations(&self) -> u32 {
        self.evaluations
    }

    /// The node's thermal hot path, f32: calibrates `codes` pairwise into `out`, each set with
    /// the calibration [`ThermalTracker::on_set`] returns for its temperature in `temp_c` (sets
    /// without a temperature or an output slot are left alone). Returns whether a set of the block
    /// was calibrated with a flagged calibration ([`ThermalTracker::out_of_range`]).
    ///
    /// The result is exactly that of calling `on_set` set by set (tested), computed in runs: the
    /// sets up to the next re-evaluation share one calibration, which the run keeps in registers
    /// while it adds the sets' temperatures to the block sum in order, so a set costs model 4's
    /// arithmetic and one addition. The firmware and a host replay run this same function, so
    /// their outputs agree bit for bit. The flag is exact for blocks of at most
    /// [`SETS_PER_UPDATE`] sets (the node's blocks): the calibration changes at most once within
    /// such a block, so the first set's state and the last set's state are the only two the
    /// block's sets were calibrated with.
    #[inline(always)]
    pub fn apply_block(&mut self, codes: &[Codes], temp_c: &[f32], out: &mut [[f32; 3]]) -> bool {
        let n = codes.len().min(temp_c.len()).min(out.len());
        let (codes, temp_c, out) = (&codes[..n], &temp_c[..n], &mut out[..n]);
        let mut first = None;
        let mut i = 0;
        while i < n {
            if self.filter.value().is_none() || self.n + 1 == SETS_PER_UPDATE {
                // This set re-evaluates the calibration and is calibrated with the new one.
                out[i] = self.on_set(temp_c[i]).apply(codes[i]);
                i += 1;
            } else {
                // The sets before the next re-evaluation: one calibration, the sum in order.
                let k = (SETS_PER_UPDATE - 1 - self.n).min(n - i);
                let cal = self.cal;
                let mut sum = self.sum;
                for ((u, &t), a) in codes[i..i + k].iter().zip(&temp_c[i..i + k]).zip(&mut out[i..i + k]) {
                    sum += t;
                    *a = cal.apply(*u);
                }
                self.sum = sum;
                self.n += k;
                i += k;
            }
            if first.is_none() {
                first = Some(self.out_of_range());
            }
        }
        first.is_some_and(|f| f || self.out_of_range())
    }

    /// The block's temperature report: the mean of `temp_c` (the block's sets' temperatures), and,
    /// when the tracker's calibration was applied to the block, the temperature it was evaluated
    /// at and `flagged` ([`ThermalTracker::apply_block`]'s result). `None` for an empty block.
    pub fn block_temp(temp_c: &[f32], applied: Option<(&ThermalTracker, bool)>) -> Option<BlockTemp> {
        let mean_c = block_mean(temp_c)?;
        Some(match applied {
            Some((tr, flagged)) => BlockTemp { mean_c, applied_c: tr.applied_c(), out_of_range: flagged },
            None => BlockTemp { mean_c, applied_c: None, out_of_range: false },
        })
    }
}

/// Mean of a block's temperatures, f32, summed in order (`None` for no temperature).
pub fn block_mean(temp_c: &[f32]) -> Option<f32> {
    if temp_c.is_empty() {
        return None;
    }
    Some(temp_c.iter().sum::<f32>() / temp_c.len() as f32)
}

/// A [`ThermalTracker`] for the fixed-point build: the tracker's f32 calibration, re-quantised
/// ([`LinearCal::to_fixed`]) each time the tracker re-evaluates it. Where it does not fit fixed
/// point the last fixed calibration stays and the output is flagged.
#[derive(Clone, Copy, Debug)]
pub struct ThermalTrackerFixed {
    tracker: ThermalTracker,
    fixed: LinearCalFixed,
    seen: u32,
    failed: bool,
}

impl ThermalTrackerFixed {
    /// A tracker of `model`, applying `start` (the model at its reference temperature in fixed
    /// point, which the record gate checked) until the first set's temperature arrives.
    pub fn new(model: ThermalCalF32, start: LinearCalFixed) -> ThermalTrackerFixed {
        let tracker = ThermalTracker::new(model, LinearCalF32 { u0: [0.0; 3], m: [[0.0; 3]; 3] });
        ThermalTrackerFixed { tracker, fixed: start, seen: 0, failed: false }
    }

    /// The fixed-point calibration for the next set at `temp_c` (see [`ThermalTracker::on_set`]).
    #[inline]
    pub fn on_set(&mut self, temp_c: f32) -> &LinearCalFixed {
        let c = *self.tracker.on_set(temp_c);
        if self.tracker.evaluations() != self.seen {
            self.seen = self.tracker.evaluations();
            let wide = LinearCal { u0: c.u0.map(|v| v as f64), m: c.m.map(|r| r.map(|v| v as f64)) };
            match wide.to_fixed() {
                Ok(f) => {
                    self.fixed = f;
                    self.failed = false;
                }
                Err(_) => self.failed = true,
            }
        }
        &self.fixed
    }

    /// [`ThermalTracker::apply_block`] in fixed point (output m/s²·2¹⁶).
    #[inline(always)]
    pub fn apply_block(&mut self, codes: &[Codes], temp_c: &[f32], out: &mut [[i32; 3]]) -> bool {
        let mut sets = codes.iter().zip(temp_c).zip(out.iter_mut());
        let Some(((u, &t), a)) = sets.next() else { return false };
        *a = self.on_set(t).apply(*u);
        let first = self.out_of_range();
        for ((u, &t), a) in sets {
            *a = self.on_set(t).apply(*u);
        }
        first || self.out_of_range()
    }

    /// See [`ThermalTracker::out_of_range`]; also set while the calibration does not fit fixed
    /// point.
    pub fn out_of_range(&self) -> bool {
        self.failed || self.tracker.out_of_range()
    }

    /// The f32 tracker underneath.
    pub fn tracker(&self) -> &ThermalTracker {
        &self.tracker
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::record::{TempSource, MAX_CHANNELS};
    use crate::terms::N_BASIS;

    fn record() -> Record {
        let mut r = Record {
            device_id: *b"QEMU-B-L475E",
            created_unix_s: 1,
            structure: Structure::from_indices(&[1, 2, 3, 20, 21, 22, 23, 24]),
            n_channels: 3,
            coefficients: [[0.0; N_BASIS]; MAX_CHANNELS],
            g_m_s2: Some(9.81),
            thermal: Some(Thermal {
                t_ref_c: 25.0,
                t_min_c: -10.0,
                t_max_c: 50.0,
                source: TempSource::FrontEnd,
            }),
        };
        // 1, ax, ay, az, t, t^2, ax*t, ay*t, az*t
        r.coefficients[0][..9].copy_from_slice(&[32000.0, 1670.0, 3.0, -2.0, 3.0, 0.01, 0.167, 0.0, 0.0]);
        r.coefficients[1][..9].copy_from_slice(&[33000.0, 1.5, 1650.0, 4.0, -2.0, 0.0, 0.0, 0.165, 0.0]);
        r.coefficients[2][..9].copy_from_slice(&[31000.0, -2.5, 0.5, 1690.0, 1.0, 0.0, 0.0, 0.0, 0.169]);
        r
    }

    #[test]
    fn the_model_is_read_from_the_record_term_by_term() {
        let m = ThermalModel::of(&record()).unwrap();
        assert_eq!(m.bias[0], [32000.0, 3.0, 0.01]);
        assert_eq!(m.k[1], [1.5, 1650.0, 4.0]);
        assert_eq!((m.kt[0][0], m.kt[1][1], m.kt[2][2], m.kt[0][1]), (0.167, 0.165, 0.169, 0.0));
        let at35 = m.at(35.0);
        assert_eq!(at35.u0[0], 32000.0 + 30.0 + 1.0);
        assert!((at35.k[0][0] - 1671.67).abs() < 1e-9);
        // At the reference the model is its model-4 part.
        assert_eq!(m.at(25.0).k, m.k);
        let mut plain = record();
        plain.structure = MODEL_4;
        plain.thermal = None;
        assert_eq!(ThermalModel::of(&plain), None);
        let mut quad = record();
        quad.structure = Structure::from_indices(&[1, 2, 3, 4, 20]);
        assert_eq!(ThermalModel::of(&quad), None);
        // The record of a model reads back as the model, with the terms it uses.
        let back = m.to_record(*b"QEMU-B-L475E", 1, 9.81);
        assert_eq!(back, record());
        let mut lin = m;
        lin.bias[0][2] = 0.0;
        lin.kt[2][2] = 0.0;
        let r = lin.to_record(*b"QEMU-B-L475E", 1, 9.81);
        assert_eq!(r.structure, Structure::from_indices(&[1, 2, 3, 20, 22, 23]));
        assert_eq!(ThermalModel::of(&r), Some(lin));
    }

    #[test]
    fn the_f32_evaluation_matches_the_f64_reference() {
        let m = ThermalModel::of(&record()).unwrap();
        let f = m.to_f32();
        for temp in [-10.0f32, 0.0, 25.0, 37.5, 50.0] {
            let exact = m.at(temp as f64).invert().unwrap();
            let node = f.at(temp).unwrap();
            for u in [[0u16, 0, 0], [32000, 33000, 31000], [65535, 20000, 45000]] {
                let a = exact.apply(u.map(|v| v as f64));
                let b = node.apply(u);
                for i in 0..3 {
                    // 2e-5 m/s² over the whole code range: far below one code (~6e-3 m/s²).
                    assert!((a[i] - b[i] as f64).abs() < 2e-5, "{temp} °C {u:?}: {a:?} vs {b:?}");
                }
            }
        }
        assert!(m.invertible().is_ok());
        assert!(f.out_of_range(50.5) && f.out_of_range(f32::NAN) && !f.out_of_range(-10.0));
    }

    #[test]
    fn a_singular_temperature_is_refused() {
        let mut r = record();
        // Channel x's sensitivity row vanishes at t = +20 (45 °C), inside the range.
        r.coefficients[0][6..9].copy_from_slice(&[-83.5, -0.15, 0.1]);
        let m = ThermalModel::of(&r).unwrap();
        assert_eq!(m.to_f32().at(45.0), Err(LinearError::Singular));
        assert!(m.to_f32().at(44.0).is_ok() && m.to_f32().at(50.0).is_ok());
        assert_eq!(m.invertible(), Err(LinearError::Singular));
        r.thermal.as_mut().unwrap().t_max_c = 40.0;
        assert_eq!(ThermalModel::of(&r).unwrap().invertible(), Ok(()));
    }

    #[test]
    fn the_tracker_re_evaluates_every_block_of_sets() {
        let m = ThermalModel::of(&record()).unwrap().to_f32();
        let mut tr = ThermalTracker::new(m, m.at(25.0).unwrap());
        assert_eq!(tr.applied_c(), None);
        assert_eq!(*tr.on_set(40.0), m.at(40.0).unwrap());
        for _ in 0..SETS_PER_UPDATE - 1 {
            assert_eq!(*tr.on_set(44.0), m.at(40.0).unwrap());
        }
        // The 16th set after the first closes a block of mean 44: the filter moves a quarter.
        assert_eq!(*tr.on_set(44.0), m.at(41.0).unwrap());
        assert_eq!(tr.applied_c(), Some(41.0));
        assert!(!tr.out_of_range());
        for _ in 0..SETS_PER_UPDATE * 40 {
            tr.on_set(60.0);
        }
        assert!(tr.out_of_range() && tr.applied_c().unwrap() > 59.9);
    }

    #[test]
    fn a_block_is_calibrated_set_by_set_and_flagged_when_any_set_was() {
        let m = ThermalModel::of(&record()).unwrap().to_f32();
        let start = m.at(25.0).unwrap();
        let (mut block, mut single) = (ThermalTracker::new(m, start), ThermalTracker::new(m, start));
        let codes: std::vec::Vec<Codes> = (0..40u16).map(|i| [32000 + i, 33000, 31000 - i]).collect();
        // A ramp that leaves the range (50 °C) during the third block.
        let temps: std::vec::Vec<f32> = (0..40).map(|i| 20.0 + 5.0 * i as f32).collect();
        let mut out = [[0.0f32; 3]; 40];
        let mut flags = std::vec::Vec::new();
        for ((c, t), o) in codes.chunks(16).zip(temps.chunks(16)).zip(out.chunks_mut(16)) {
            flags.push(block.apply_block(c, t, o));
            let b = ThermalTracker::block_temp(t, Some((&block, *flags.last().unwrap()))).unwrap();
            assert_eq!(b.mean_c, block_mean(t).unwrap());
            assert_eq!(b.applied_c, block.applied_c());
        }
        for i in 0..40 {
            assert_eq!(out[i], single.on_set(temps[i]).apply(codes[i]), "set {i}");
        }
        // Blocks of any length give what set-by-set calibration gives, the block sums included.
        let (mut runs, mut sets) = (ThermalTracker::new(m, start), ThermalTracker::new(m, start));
        let mut at = 0;
        for (k, len) in
            [1usize, 15, 16, 3, 16, 7, 16, 16, 9, 1, 0, 16].into_iter().cycle().take(60).enumerate()
        {
            let t: std::vec::Vec<f32> = (at..at + len).map(|i| 20.0 + 0.37 * (i % 50) as f32).collect();
            let c: std::vec::Vec<Codes> =
                (at..at + len).map(|i| [i as u16, 65535 - i as u16, 32768]).collect();
            let mut o = std::vec![[0.0f32; 3]; len];
            runs.apply_block(&c, &t, &mut o);
            for j in 0..len {
                assert_eq!(o[j], sets.on_set(t[j]).apply(c[j]), "block {k} set {j}");
            }
            assert_eq!(
                (runs.sum, runs.n, runs.applied_c()),
                (sets.sum, sets.n, sets.applied_c()),
                "block {k}"
            );
            at += len;
        }
        // Evaluated at 20, then at 20 + 0.25·(62.5 − 20) = 30.625, then at 58.6, past 50.
        assert_eq!(flags, [false, false, true]);
        assert!(!block.apply_block(&[], &[], &mut []));
        assert_eq!(ThermalTracker::block_temp(&[], None), None);
        let b = ThermalTracker::block_temp(&[20.0, 21.0], None).unwrap();
        assert_eq!(b, BlockTemp { mean_c: 20.5, applied_c: None, out_of_range: false });
    }

    #[test]
    fn the_fixed_point_tracker_requantises_what_the_f32_tracker_evaluates() {
        let m = ThermalModel::of(&record()).unwrap().to_f32();
        let start = m.at_wide(25.0).unwrap().to_fixed().unwrap();
        let mut fx = ThermalTrackerFixed::new(m, start);
        let mut f = ThermalTracker::new(m, m.at(25.0).unwrap());
        for i in 0..100 {
            let t = 10.0 + 0.3 * i as f32;
            let c = *f.on_set(t);
            let wide = LinearCal { u0: c.u0.map(|v| v as f64), m: c.m.map(|r| r.map(|v| v as f64)) };
            assert_eq!(*fx.on_set(t), wide.to_fixed().unwrap(), "set {i}");
            assert_eq!(fx.out_of_range(), f.out_of_range());
            assert_eq!(fx.tracker().applied_c(), f.applied_c());
        }
        assert_eq!(f.evaluations(), 1 + 99 / SETS_PER_UPDATE as u32);
    }

    #[test]
    fn the_filter_starts_at_the_first_block_and_follows() {
        let mut f = TempFilter::default();
        assert_eq!(f.value(), None);
        assert_eq!(f.push(20.0), 20.0);
        assert_eq!(f.push(24.0), 21.0);
        assert_eq!(f.push(24.0), 21.75);
        assert!(node_applies(MODEL_4) && node_applies(Structure::from_indices(&[1, 2, 3, 24])));
        assert!(!node_applies(Structure::from_indices(&[1, 2, 3, 4])));
        assert!(!node_applies(Structure::from_indices(&[1, 2, 20])));
    }
}
