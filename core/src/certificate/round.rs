//! Numbers as a certificate states them: a fixed number of significant digits, and ILAC-P14's
//! rounding of a value with its expanded uncertainty. Defined once, here,
//! for the certificate and every table that prints such numbers.

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

/// A value and its expanded uncertainty as ILAC-P14:09/2020 §5.3 and GUM 7.2.6 ask a certificate
/// to state them: U to two significant digits, rounded up (never understated), and the value
/// rounded to U's last digit. `None` when U is not a positive finite number (the caller shows the
/// value as it is, without a `±`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ilac {
    /// The value, rounded.
    pub value: f64,
    /// U, rounded up.
    pub u: f64,
    /// Decimal places of both.
    pub decimals: usize,
}

impl Ilac {
    /// `v` with its expanded uncertainty `u`.
    pub fn of(v: f64, u: f64) -> Option<Ilac> {
        if !(v.is_finite() && u.is_finite() && u > 0.0) {
            return None;
        }
        // U's exponent as `{:e}` prints it (no rounding surprise of log10).
        let e = format!("{u:e}");
        let exp: i32 = e.split_once('e').and_then(|(_, x)| x.parse().ok())?;
        let mut place = exp - 1;
        // Rounded up at the second digit, less a hair for the binary representation of values
        // that are exact in decimal (0.35 is 0.34999… or 0.35000…1).
        let mut digits = (u / 10f64.powi(place) * (1.0 - 1e-12)).ceil();
        if digits >= 100.0 {
            digits = 10.0;
            place += 1;
        }
        let unit = 10f64.powi(place);
        let value = (v / unit).round() * unit;
        // No "-0".
        let value = if value == 0.0 { 0.0 } else { value };
        Some(Ilac { value, u: digits * unit, decimals: (-place).max(0) as usize })
    }

    /// The value, with its sign when `signed`.
    pub fn value(&self, signed: bool) -> String {
        let d = self.decimals;
        if signed {
            format!("{:+.d$}", self.value)
        } else {
            format!("{:.d$}", self.value)
        }
    }

    /// U.
    pub fn u(&self) -> String {
        let d = self.decimals;
        format!("{:.d$}", self.u)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// ILAC-P14: the example ("+230.1678 µrad ± 350.6856") and the edges of rounding up.
    #[test]
    fn certificate_values_follow_ilac_p14() {
        let show = |v, u| Ilac::of(v, u).map(|r| (r.value(true), r.u()));
        let pair = |a: &str, b: &str| Some((a.to_string(), b.to_string()));
        assert_eq!(show(230.1678, 350.6856), pair("+230", "360"));
        assert_eq!(show(-0.0123456, 0.00123), pair("-0.0123", "0.0013"));
        assert_eq!(show(1651.3474, 0.35), pair("+1651.35", "0.35"));
        assert_eq!(show(3.0, 0.0991), pair("+3.00", "0.10"));
        assert_eq!(show(12.5, 99.01), pair("+10", "100"));
        assert_eq!(show(-0.004, 0.1), pair("+0.00", "0.10"));
        assert_eq!(show(1.0, 0.0), None);
        assert_eq!(show(f64::NAN, 1.0), None);
    }
}
