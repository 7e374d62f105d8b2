//! What users read and look at: plots (rendered in memory, written atomically) and number
//! formatting for tables. The JSON documents of each command live beside the command in `cmd`.

pub mod diagnose_plot;
pub mod gravity_plot;
pub mod plot;

/// Formats a number with a fixed number of significant digits for tables.
pub fn sig(v: f64, digits: usize) -> String {
    if !v.is_finite() {
        return "-".into();
    }
    if v == 0.0 {
        return "0".into();
    }
    let mag = v.abs().log10().floor() as i32;
    let decimals = (digits as i32 - 1 - mag).clamp(0, 12) as usize;
    format!("{v:.decimals$}")
}

/// A value with a bound on its error, `v ± u`: the bound to two significant digits when it begins
/// with 1 or 2, else one, and the value to the same decimal place (`9.8105 ± 0.0010`).
pub fn with_uncertainty(v: f64, u: f64) -> String {
    if !(v.is_finite() && u.is_finite() && u > 0.0) {
        return format!("{v}");
    }
    // The exponent and the first digit as `{:e}` prints them (no rounding surprise of log10).
    let e = format!("{u:e}");
    let (mantissa, exp) = e.split_once('e').expect("`{:e}` has an exponent");
    let exp: i32 = exp.parse().expect("an integer exponent");
    let digits = if mantissa.starts_with(['1', '2']) { 2 } else { 1 };
    let decimals = (digits - 1 - exp).max(0) as usize;
    format!("{v:.decimals$} ± {u:.decimals$}")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn values_are_given_to_the_digits_their_uncertainty_supports() {
        assert_eq!(with_uncertainty(9.810547519391731, 0.001), "9.8105 ± 0.0010");
        assert_eq!(with_uncertainty(9.81, 0.005), "9.810 ± 0.005");
        assert_eq!(with_uncertainty(9.81, 0.03), "9.81 ± 0.03");
        assert_eq!(with_uncertainty(9.80665, 5e-6), "9.806650 ± 0.000005");
        assert_eq!(with_uncertainty(1234.4, 25.0), "1234 ± 25");
    }
}
