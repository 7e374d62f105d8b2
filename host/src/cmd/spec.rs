//! `--spec FILE`: a unit type's product specification and decision rule
//! ([`accelcal_core::conformity`]), read from TOML, for `verify` and the station.

use std::path::Path;

use accelcal_core::conformity::{Specification, VerifyReferences};
use accelcal_core::error::bad;
use accelcal_core::uncertainty::ARCSEC;

/// Reads and checks a specification file; an unknown key, a missing one or a bad value is
/// refused naming the file, the line and the column.
pub fn read(path: &Path) -> anyhow::Result<Specification> {
    let name = path.display();
    let text = std::fs::read_to_string(path).map_err(|e| bad(format!("{name}: cannot read: {e}")))?;
    let spec: Specification = toml::from_str(&text).map_err(|e| toml_error(&name, &text, &e))?;
    spec.check().map_err(|e| bad(format!("{name}: {e}")))?;
    Ok(spec)
}

/// A TOML file's error as one line of bad input: the file, the line and column of the key or
/// value it is about (when the parser knows it), and the parser's message.
pub fn toml_error(name: &dyn std::fmt::Display, text: &str, e: &toml::de::Error) -> anyhow::Error {
    let at = e.span().map(|s| format!(":{}", line_col(text, s.start))).unwrap_or_default();
    bad(format!("{name}{at}: {}", e.message().trim_end()))
}

/// `LINE:COLUMN` (from 1) of the byte `offset` of `text`.
pub fn line_col(text: &str, offset: usize) -> String {
    let before = &text[..text.floor_char_boundary(offset.min(text.len()))];
    let line = before.matches('\n').count() + 1;
    let col = before.chars().count() - before.rfind('\n').map_or(0, |i| before[..=i].chars().count()) + 1;
    format!("{line}:{col}")
}

/// The references' standard uncertainties a verification's errors are measured against: the
/// head's stated ones (arcsec, one sigma) and the standard uncertainty g's source gives it.
/// Also what is not included, in words.
pub fn references(
    gravity: &crate::resolved::Gravity,
    angle_u_arcsec: Option<f64>,
    orthogonality_u_arcsec: Option<f64>,
) -> (VerifyReferences, Vec<String>) {
    let mut missing = Vec::new();
    if angle_u_arcsec.is_none() {
        missing.push("the head's angle setting error (not stated: --head-angle-u)".to_string());
    }
    if orthogonality_u_arcsec.is_none() {
        missing.push("the head's axis orthogonality (not stated: --head-orthogonality-u)".to_string());
    }
    let r = VerifyReferences {
        head_angle_rad: angle_u_arcsec.unwrap_or(0.0) * ARCSEC,
        head_orthogonality_rad: orthogonality_u_arcsec.unwrap_or(0.0) * ARCSEC,
        g_m_s2: gravity.standard_u().0,
    };
    (r, missing)
}
