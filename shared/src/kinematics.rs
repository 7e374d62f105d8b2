//! Dividing-head kinematics: the apparent acceleration in the block's axes for head angles α, β.
//!
//! From the paper: `ax = -g·cosβ·sinα`, `ay = -g·sinβ`, `az = -g·cosα·cosβ`, angles in degrees.

/// The paper's value of g, m/s².
pub const G_STANDARD: f64 = 9.81;

/// Sine and cosine of an angle in degrees, exact at multiples of 90°.
///
/// Exactness at the quarter turns matters: test-turn positions must give exactly ±g and 0, so
/// that pairs 180° apart cancel to the last bit.
pub fn sin_cos_deg(deg: f64) -> (f64, f64) {
    let r = deg % 360.0;
    let r = if r < 0.0 { r + 360.0 } else { r };
    if r == 0.0 {
        (0.0, 1.0)
    } else if r == 90.0 {
        (1.0, 0.0)
    } else if r == 180.0 {
        (0.0, -1.0)
    } else if r == 270.0 {
        (-1.0, 0.0)
    } else {
        let rad = r * (core::f64::consts::PI / 180.0);
        (libm::sin(rad), libm::cos(rad))
    }
}

/// Apparent acceleration `[ax, ay, az]` (m/s²) in the block's axes at head angles `alpha_deg`,
/// `beta_deg` for gravity `g` (m/s²).
pub fn gravity(alpha_deg: f64, beta_deg: f64, g: f64) -> [f64; 3] {
    let (sa, ca) = sin_cos_deg(alpha_deg);
    let (sb, cb) = sin_cos_deg(beta_deg);
    [-g * cb * sa, -g * sb, -g * ca * cb]
}

/// Normal gravity (m/s²) at geodetic latitude `latitude_deg` and height `height_m` above the
/// ellipsoid: the WGS84 normal gravity on the ellipsoid by Somigliana's closed formula,
/// `γ = γ_e (1 + k sin²φ) / √(1 − e² sin²φ)`, less the free-air gradient 3.086e-6 m/s² per metre.
/// (NIMA TR8350.2, 3rd ed., eq. 4-1 and table 3.4.) Without a gravity survey it is good to about
/// 1e-3 m/s²: local anomalies are not modelled.
pub fn normal_gravity(latitude_deg: f64, height_m: f64) -> f64 {
    /// Normal gravity at the equator, m/s².
    const GAMMA_E: f64 = 9.780_325_335_9;
    /// Somigliana's constant k.
    const K: f64 = 0.001_931_852_652_41;
    /// First eccentricity squared e².
    const E2: f64 = 0.006_694_379_990_13;
    /// Free-air gradient, m/s² per metre.
    const FREE_AIR: f64 = 3.086e-6;
    let s = libm::sin(latitude_deg.to_radians());
    let s2 = s * s;
    GAMMA_E * (1.0 + K * s2) / libm::sqrt(1.0 - E2 * s2) - FREE_AIR * height_m
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: [f64; 3], b: [f64; 3]) {
        for i in 0..3 {
            assert!((a[i] - b[i]).abs() < 1e-12, "{a:?} != {b:?}");
        }
    }

    #[test]
    fn hand_values() {
        let g = G_STANDARD;
        close(gravity(0.0, 0.0, g), [0.0, 0.0, -g]);
        close(gravity(90.0, 0.0, g), [-g, 0.0, 0.0]);
        close(gravity(180.0, 0.0, g), [0.0, 0.0, g]);
        close(gravity(-90.0, 0.0, g), [g, 0.0, 0.0]);
        close(gravity(0.0, 90.0, g), [0.0, -g, 0.0]);
        close(gravity(0.0, -90.0, g), [0.0, g, 0.0]);
        // α = 30°, β = 60°: cosβ = 1/2, sinα = 1/2, cosα = √3/2, sinβ = √3/2.
        let h = 3f64.sqrt() / 2.0;
        close(gravity(30.0, 60.0, g), [-g * 0.25, -g * h, -g * h * 0.5]);
        // 45°, 45°: ax = az = -g/2, ay = -g/√2.
        close(gravity(45.0, 45.0, 2.0), [-1.0, -2f64.sqrt(), -1.0]);
    }

    #[test]
    fn norm_is_g_everywhere() {
        for a in (-360..=360).step_by(15) {
            for b in (-90..=90).step_by(10) {
                let v = gravity(a as f64, b as f64, 9.80665);
                let n = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
                assert!((n - 9.80665).abs() < 1e-12);
            }
        }
    }

    #[test]
    fn quarter_turns_are_exact() {
        assert_eq!(gravity(180.0, 0.0, 9.81), [-0.0 * 9.81, -0.0, 9.81]);
        assert_eq!(gravity(450.0, 0.0, 9.81)[0], -9.81);
        assert_eq!(gravity(-270.0, 0.0, 9.81)[0], -9.81);
    }

    #[test]
    fn normal_gravity_matches_published_values() {
        // WGS84 normal gravity: equator 9.7803253359, pole 9.8321849378 (TR8350.2 table 3.4);
        // 45° at sea level 9.80620 to 5 decimals.
        assert!((normal_gravity(0.0, 0.0) - 9.780_325_335_9).abs() < 1e-10);
        assert!((normal_gravity(90.0, 0.0) - 9.832_184_937_8).abs() < 1e-9);
        assert!((normal_gravity(-90.0, 0.0) - 9.832_184_937_8).abs() < 1e-9);
        assert!((normal_gravity(45.0, 0.0) - 9.806_20).abs() < 5e-6, "{}", normal_gravity(45.0, 0.0));
        // Free air: 1000 m up is 3.086 mm/s² less.
        assert!((normal_gravity(45.0, 0.0) - normal_gravity(45.0, 1000.0) - 3.086e-3).abs() < 1e-12);
    }
}
