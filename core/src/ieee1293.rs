//! Model 4's coefficients under IEEE Std 1293's names and units, as the certificate and the
//! fleet's statistics state them: for channel c with `u_c = u0_c + Σ_j k_cj·a_j` (codes), the
//! scale factor `K1 = k_cc·g_n` (codes/g), the bias `K0 = (u0_c − mid-scale)/k_cc` (the input at
//! which the output is the converter's mid-scale, in mg) and the input-axis misalignment toward
//! axis j, `δ_cj = k_cj/k_cc` (µrad).

/// The ADC code of zero input: the node's 16-bit converter at mid-scale, where K0 is measured
/// from.
pub const MID_SCALE_CODES: f64 = 32768.0;

/// Standard gravity g_n (the CGPM's 9.80665 m/s²): K0 in mg and K1 per g.
pub const G_N: f64 = 9.80665;

/// One channel's parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Parameters {
    /// Bias K0, mg.
    pub k0_mg: f64,
    /// Scale factor K1, codes/g.
    pub k1_codes_per_g: f64,
    /// Misalignment toward each axis, µrad (0 toward its own).
    pub delta_urad: [f64; 3],
}

impl Parameters {
    /// Channel `c`'s parameters from its model-4 row `[u0, kx, ky, kz]` (codes, codes/(m/s²)).
    pub fn of(c: usize, row: [f64; 4]) -> Parameters {
        let kc = row[c + 1];
        Parameters {
            k0_mg: (row[0] - MID_SCALE_CODES) / kc / G_N * 1e3,
            k1_codes_per_g: kc * G_N,
            delta_urad: std::array::from_fn(|j| if j == c { 0.0 } else { row[j + 1] / kc * 1e6 }),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_row_gives_its_parameters() {
        // 1640 codes/(m/s²) on y, 10 codes/(m/s²) toward x, 16.4 codes above mid-scale.
        let p = Parameters::of(1, [MID_SCALE_CODES + 16.4, 10.0, 1640.0, 0.0]);
        assert!((p.k1_codes_per_g - 1640.0 * G_N).abs() < 1e-9);
        assert!((p.k0_mg - 16.4 / 1640.0 / G_N * 1e3).abs() < 1e-12);
        assert_eq!(p.delta_urad, [10.0 / 1640.0 * 1e6, 0.0, 0.0]);
    }
}
