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
