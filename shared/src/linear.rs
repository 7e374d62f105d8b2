//! Applying a linear (model 4) calibration: `a = K⁻¹ (u − u0)` for a triad, in f64 (reference),
//! f32 (the firmware's FPU path) and fixed point (for FPU-less parts), with stated error bounds.
//!
//! The model of channel i is `u_i = u0_i + Σ_j K_ij·a_j` (codes; K in codes per m/s²). The firmware
//! inverts K once at boot and then spends 3 subtractions and 9 multiply-adds per sample set.

use nalgebra::Matrix3;

/// A triad's model-4 calibration as fitted: bias `u0` (codes) and sensitivity matrix `k` (row i is
/// channel i: codes per m/s² of ax, ay, az).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Model4 {
    /// Zero offsets, codes.
    pub u0: [f64; 3],
    /// Sensitivity matrix, codes per m/s².
    pub k: [[f64; 3]; 3],
}

/// Why a model-4 calibration cannot be applied.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LinearError {
    /// The sensitivity matrix is singular or badly conditioned (reciprocal condition below 1e-9),
    /// or holds a non-finite value.
    Singular,
    /// The inverse is too large for the fixed-point format.
    FixedPointRange,
}

impl core::fmt::Display for LinearError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            LinearError::Singular => "sensitivity matrix is singular or not finite",
            LinearError::FixedPointRange => "calibration does not fit the fixed-point format",
        })
    }
}

#[cfg(feature = "std")]
impl std::error::Error for LinearError {}

/// The inverted calibration in f64: `a = m (u − u0)`. The reference the other paths are held to.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LinearCal {
    /// Zero offsets, codes.
    pub u0: [f64; 3],
    /// `K⁻¹`, m/s² per code.
    pub m: [[f64; 3]; 3],
}

impl Model4 {
    /// Inverts the sensitivity matrix.
    pub fn invert(&self) -> Result<LinearCal, LinearError> {
        let k = Matrix3::from_fn(|i, j| self.k[i][j]);
        if !k.iter().all(|v| v.is_finite()) || !self.u0.iter().all(|v| v.is_finite()) {
            return Err(LinearError::Singular);
        }
        let inv = k.try_inverse().ok_or(LinearError::Singular)?;
        // The inverse as columns (nalgebra's storage order): no indexing, so no panic path.
        let cols: [[f64; 3]; 3] = inv.into();
        let m: [[f64; 3]; 3] = core::array::from_fn(|i| core::array::from_fn(|j| cols[j][i]));
        // Reciprocal condition number in the 1-norm: the largest column sum of absolute values.
        let norm1 = |cols: [[f64; 3]; 3]| {
            cols.iter().map(|c| c.iter().map(|v| libm::fabs(*v)).sum::<f64>()).fold(0.0, f64::max)
        };
        let k_cols: [[f64; 3]; 3] = core::array::from_fn(|j| core::array::from_fn(|i| self.k[i][j]));
        let rcond = 1.0 / (norm1(k_cols) * norm1(cols));
        if !(rcond > 1e-9) || !cols.iter().flatten().all(|v| v.is_finite()) {
            return Err(LinearError::Singular);
        }
        Ok(LinearCal { u0: self.u0, m })
    }
}

impl LinearCal {
    /// Calibrated acceleration (m/s²) from raw codes, in f64.
    pub fn apply(&self, u: [f64; 3]) -> [f64; 3] {
        let d = [u[0] - self.u0[0], u[1] - self.u0[1], u[2] - self.u0[2]];
        let mut a = [0.0; 3];
        for (i, ai) in a.iter_mut().enumerate() {
            *ai = self.m[i][0] * d[0] + self.m[i][1] * d[1] + self.m[i][2] * d[2];
        }
        a
    }

    /// The same calibration rounded to f32.
    pub fn to_f32(&self) -> LinearCalF32 {
        let mut out = LinearCalF32 { u0: [0.0; 3], m: [[0.0; 3]; 3] };
        for i in 0..3 {
            out.u0[i] = self.u0[i] as f32;
            for j in 0..3 {
                out.m[i][j] = self.m[i][j] as f32;
            }
        }
        out
    }

    /// The same calibration in fixed point (see [`LinearCalFixed`]).
    pub fn to_fixed(&self) -> Result<LinearCalFixed, LinearError> {
        LinearCalFixed::new(self)
    }

    /// Bound on `|apply_f32(u) − apply(u)|` for each axis, for codes `u` in 0..=65535.
    ///
    /// Rounding u0 and m to f32 and the 3 subtractions and 5 operations of each dot product each
    /// add at most one unit roundoff `ε = 2⁻²⁴` relative to their operands, so
    /// `|err_i| ≤ Σ_j |m_ij| (|u0_j| + 5·|d_j|_max)·ε·(1 + 10ε)` with `|d_j|_max = max(|u0_j|,
    /// 65535 − u0_j)`.
    pub fn f32_error_bound(&self) -> [f64; 3] {
        let eps = libm::ldexp(1.0, -24);
        let mut b = [0.0; 3];
        for (i, bi) in b.iter_mut().enumerate() {
            for j in 0..3 {
                let u0 = libm::fabs(self.u0[j]);
                let dmax = libm::fmax(u0, libm::fabs(65535.0 - self.u0[j]));
                *bi += libm::fabs(self.m[i][j]) * (u0 + 5.0 * dmax) * eps;
            }
            *bi *= 1.0 + 10.0 * eps;
        }
        b
    }
}

/// A model-4 calibration in f32: what the firmware runs on the Cortex-M4F.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LinearCalF32 {
    /// Zero offsets, codes.
    pub u0: [f32; 3],
    /// `K⁻¹`, m/s² per code.
    pub m: [[f32; 3]; 3],
}

impl LinearCalF32 {
    /// Calibrated acceleration (m/s²) from raw 16-bit codes.
    #[inline]
    pub fn apply(&self, u: [u16; 3]) -> [f32; 3] {
        let d = [u[0] as f32 - self.u0[0], u[1] as f32 - self.u0[1], u[2] as f32 - self.u0[2]];
        [
            self.m[0][0] * d[0] + self.m[0][1] * d[1] + self.m[0][2] * d[2],
            self.m[1][0] * d[0] + self.m[1][1] * d[1] + self.m[1][2] * d[2],
            self.m[2][0] * d[0] + self.m[2][1] * d[1] + self.m[2][2] * d[2],
        ]
    }
}

/// Fractional bits of the fixed-point offset (codes · 2⁸).
pub const FIXED_U0_FRAC: u32 = 8;
/// Fractional bits of the fixed-point output: acceleration in m/s² · 2¹⁶ (Q15.16).
pub const FIXED_OUT_FRAC: u32 = 16;

/// A model-4 calibration in fixed point: offsets in codes·2⁸ (i32), `K⁻¹` scaled by `2^shift`
/// (i32, chosen so the largest entry uses 30 bits), products accumulated in i64, output in
/// m/s²·2¹⁶ (i32).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LinearCalFixed {
    /// Zero offsets, codes · 2⁸.
    pub u0_q: [i32; 3],
    /// `K⁻¹ · 2^shift`.
    pub m_q: [[i32; 3]; 3],
    /// Scale exponent of `m_q`.
    pub shift: u32,
}

impl LinearCalFixed {
    /// Quantises a calibration; the largest |K⁻¹| entry gets 30 significant bits.
    pub fn new(cal: &LinearCal) -> Result<LinearCalFixed, LinearError> {
        let mut mmax: f64 = 0.0;
        for row in &cal.m {
            for &v in row {
                mmax = libm::fmax(mmax, libm::fabs(v));
            }
        }
        if !(mmax > 0.0) || !mmax.is_finite() {
            return Err(LinearError::Singular);
        }
        // Largest shift with mmax · 2^shift < 2^30.
        let e = libm::floor(libm::log2(mmax)) as i32;
        let shift = 29 - e;
        // The output shift (shift + 8 − 16) must stay in 1..=62 for the i64 arithmetic.
        if !(9..=70).contains(&shift) {
            return Err(LinearError::FixedPointRange);
        }
        let shift = shift as u32;
        let mut out = LinearCalFixed { u0_q: [0; 3], m_q: [[0; 3]; 3], shift };
        for i in 0..3 {
            let u0 = libm::round(cal.u0[i] * (1u32 << FIXED_U0_FRAC) as f64);
            if !(u0.abs() < 2147483647.0) {
                return Err(LinearError::FixedPointRange);
            }
            out.u0_q[i] = u0 as i32;
            for j in 0..3 {
                let m = libm::round(libm::ldexp(cal.m[i][j], shift as i32));
                if !(m.abs() < 2147483647.0) {
                    return Err(LinearError::FixedPointRange);
                }
                out.m_q[i][j] = m as i32;
            }
        }
        Ok(out)
    }

    /// Calibrated acceleration in m/s² · 2¹⁶ (rounded to nearest) from raw 16-bit codes.
    #[inline]
    pub fn apply(&self, u: [u16; 3]) -> [i32; 3] {
        let d = [
            ((u[0] as i64) << FIXED_U0_FRAC) - self.u0_q[0] as i64,
            ((u[1] as i64) << FIXED_U0_FRAC) - self.u0_q[1] as i64,
            ((u[2] as i64) << FIXED_U0_FRAC) - self.u0_q[2] as i64,
        ];
        // Σ m_q·d carries 2^(shift + 8); the output wants 2^16.
        let down = self.shift + FIXED_U0_FRAC - FIXED_OUT_FRAC;
        let half = 1i64 << (down - 1);
        let mut a = [0i32; 3];
        for (i, ai) in a.iter_mut().enumerate() {
            let acc =
                self.m_q[i][0] as i64 * d[0] + self.m_q[i][1] as i64 * d[1] + self.m_q[i][2] as i64 * d[2];
            *ai = ((acc + half) >> down).clamp(i32::MIN as i64, i32::MAX as i64) as i32;
        }
        a
    }

    /// Bound on `|apply_fixed(u)/2¹⁶ − reference(u)|` (m/s²) for each axis, codes in 0..=65535,
    /// where the reference is the f64 calibration this was quantised from.
    ///
    /// Quantising m costs `|d_j|·2^−(shift+1)` per term, quantising u0 costs `|m_ij|·2⁻⁹`, and the
    /// final rounding `2⁻¹⁷`.
    pub fn error_bound(&self, cal: &LinearCal) -> [f64; 3] {
        let mut b = [0.0; 3];
        for (i, bi) in b.iter_mut().enumerate() {
            for j in 0..3 {
                let dmax = libm::fmax(libm::fabs(cal.u0[j]), libm::fabs(65535.0 - cal.u0[j])) + 1.0;
                *bi += dmax * libm::ldexp(1.0, -(self.shift as i32) - 1)
                    + libm::fabs(cal.m[i][j]) * libm::ldexp(1.0, -(FIXED_U0_FRAC as i32) - 1);
            }
            *bi += libm::ldexp(1.0, -(FIXED_OUT_FRAC as i32) - 1);
            *bi *= 1.0 + 1e-12;
        }
        b
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample_model() -> Model4 {
        Model4 {
            u0: [32100.5, 33012.25, 31877.75],
            k: [[1671.2, 8.5, -3.25], [-4.0, 1650.75, 6.5], [2.5, -7.75, 1689.0]],
        }
    }

    /// A small deterministic generator (xorshift) so the test needs no dependency.
    fn codes(n: usize) -> impl Iterator<Item = [u16; 3]> {
        let mut s = 0x9E37_79B9_7F4A_7C15u64;
        (0..n).map(move |_| {
            let mut c = [0u16; 3];
            for v in &mut c {
                s ^= s << 13;
                s ^= s >> 7;
                s ^= s << 17;
                *v = (s >> 48) as u16;
            }
            c
        })
    }

    #[test]
    fn inverse_round_trips_the_model() {
        let model = sample_model();
        let cal = model.invert().unwrap();
        let a = [1.25, -3.5, 9.0];
        let mut u = [0.0; 3];
        for i in 0..3 {
            u[i] = model.u0[i] + (0..3).map(|j| model.k[i][j] * a[j]).sum::<f64>();
        }
        let back = cal.apply(u);
        for i in 0..3 {
            assert!((back[i] - a[i]).abs() < 1e-12);
        }
    }

    #[test]
    fn singular_matrix_is_refused() {
        let mut m = sample_model();
        m.k[2] = m.k[1];
        assert_eq!(m.invert(), Err(LinearError::Singular));
        m.k[2][0] = f64::NAN;
        assert_eq!(m.invert(), Err(LinearError::Singular));
    }

    #[test]
    fn f32_and_fixed_point_stay_within_their_bounds() {
        let cal = sample_model().invert().unwrap();
        let f = cal.to_f32();
        let q = cal.to_fixed().unwrap();
        let bf = cal.f32_error_bound();
        let bq = q.error_bound(&cal);
        let (mut worst_f, mut worst_q) = (0.0f64, 0.0f64);
        let extremes = [[0, 0, 0], [65535, 65535, 65535], [0, 65535, 0], [65535, 0, 65535]];
        for u in codes(200_000).chain(extremes) {
            let r = cal.apply([u[0] as f64, u[1] as f64, u[2] as f64]);
            let af = f.apply(u);
            let aq = q.apply(u);
            for i in 0..3 {
                let ef = (af[i] as f64 - r[i]).abs();
                let eq = (aq[i] as f64 / 65536.0 - r[i]).abs();
                assert!(ef <= bf[i], "f32 axis {i}: {ef} > {}", bf[i]);
                assert!(eq <= bq[i], "fixed axis {i}: {eq} > {}", bq[i]);
                worst_f = worst_f.max(ef / bf[i]);
                worst_q = worst_q.max(eq / bq[i]);
            }
        }
        // The bounds are not vacuous: both paths come within a factor 20 of them.
        assert!(worst_f > 0.05 && worst_q > 0.05, "{worst_f} {worst_q}");
        // And in absolute terms both are far below one code's worth of acceleration (~6e-4 m/s²).
        assert!(bf.iter().all(|&b| b < 1e-4) && bq.iter().all(|&b| b < 1e-4), "{bf:?} {bq:?}");
    }
}
