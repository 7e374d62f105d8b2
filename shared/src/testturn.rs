//! The test-turn technique: turn the sensitive axis onto gravity and 180° away.
//!
//! Two positions for one sensor: `u(+g) = u0 + k·g`, `u(−g) = u0 − k·g`, hence
//! `u0 = (u(+g) + u(−g))/2` and `k = (u(+g) − u(−g))/(2g)`. (The paper writes `u↓` for the position
//! where the axis sees +g and `u↑` for the one where it sees −g.) Six positions (each axis of the
//! block along +g and −g) give, for every channel, its bias and its full sensitivity row, hence the
//! 3×3 sensitivity matrix of a triad.
//!
//! A second-order term `K2·a_own²` is even in the input, so the two-position half-sum absorbs it:
//! the test-turn bias is `u0 + K2·g²`, not `u0`.

/// Zero offset and scale factor from the two outputs 180° apart: `u_plus` with the sensitive axis
/// seeing `+g`, `u_minus` with it seeing `−g`. Returns `(u0, k)` in codes and codes per m/s².
pub fn two_position(u_plus: f64, u_minus: f64, g: f64) -> (f64, f64) {
    ((u_plus + u_minus) / 2.0, (u_plus - u_minus) / (2.0 * g))
}

/// Outputs of one channel in the six positions, the block's axis `j` seeing `+g` (`plus[j]`) and
/// `−g` (`minus[j]`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SixPositions {
    /// Output with axis x, y, z seeing +g.
    pub plus: [f64; 3],
    /// Output with axis x, y, z seeing −g.
    pub minus: [f64; 3],
}

/// One channel's linear calibration from six positions: `u = u0 + Σ_j k[j]·a_j`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ChannelRow {
    /// Zero offset, codes: the half-sum of the pair along the channel's own axis.
    pub u0: f64,
    /// Sensitivities to ax, ay, az, codes per m/s².
    pub k: [f64; 3],
    /// The channel's own (sensitive) axis: the one with the largest |k|.
    pub own_axis: usize,
}

/// Six-position calibration of one channel. The bias is the half-sum of the pair along the
/// channel's own axis (the axis with the largest half-difference), as in the two-position method;
/// the sensitivities are the half-differences of the three pairs divided by g.
pub fn six_position(p: &SixPositions, g: f64) -> ChannelRow {
    let mut k = [0.0; 3];
    for j in 0..3 {
        k[j] = (p.plus[j] - p.minus[j]) / (2.0 * g);
    }
    let mut own = 0;
    for j in 1..3 {
        if libm::fabs(k[j]) > libm::fabs(k[own]) {
            own = j;
        }
    }
    ChannelRow { u0: (p.plus[own] + p.minus[own]) / 2.0, k, own_axis: own }
}

/// Six-position calibration of a triad: bias vector and the full 3×3 sensitivity matrix (row i is
/// channel i) from the six-position outputs of each channel.
pub fn six_position_triad(p: &[SixPositions; 3], g: f64) -> ([f64; 3], [[f64; 3]; 3]) {
    let mut bias = [0.0; 3];
    let mut k = [[0.0; 3]; 3];
    for i in 0..3 {
        let row = six_position(&p[i], g);
        bias[i] = row.u0;
        k[i] = row.k;
    }
    (bias, k)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn two_position_recovers_linear_sensor() {
        let (u0, k, g) = (32768.0, 1670.5, 9.81);
        let (e0, ek) = two_position(u0 + k * g, u0 - k * g, g);
        assert!((e0 - u0).abs() < 1e-9 && (ek - k).abs() < 1e-12);
    }

    #[test]
    fn k2_is_absorbed_into_the_bias() {
        let (u0, k, k2, g) = (30000.0, 1600.0, 3.5, 9.81);
        let out = |a: f64| u0 + k * a + k2 * a * a;
        let (e0, ek) = two_position(out(g), out(-g), g);
        assert!((e0 - (u0 + k2 * g * g)).abs() < 1e-9);
        assert!((ek - k).abs() < 1e-12);
    }

    #[test]
    fn six_positions_give_the_full_matrix() {
        let g = 9.81;
        let bias = [30000.0, 31000.0, 29000.0];
        let k = [[1600.0, 12.0, -7.0], [5.0, 1700.0, 3.0], [-9.0, 4.0, 1650.0]];
        let mut p = [SixPositions { plus: [0.0; 3], minus: [0.0; 3] }; 3];
        for i in 0..3 {
            for j in 0..3 {
                p[i].plus[j] = bias[i] + k[i][j] * g;
                p[i].minus[j] = bias[i] - k[i][j] * g;
            }
        }
        let (b, m) = six_position_triad(&p, g);
        for i in 0..3 {
            assert!((b[i] - bias[i]).abs() < 1e-9);
            for j in 0..3 {
                assert!((m[i][j] - k[i][j]).abs() < 1e-9);
            }
            assert_eq!(six_position(&p[i], g).own_axis, i);
        }
    }
}
