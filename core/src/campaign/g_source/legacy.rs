//! The words accelcal wrote for a gravity's source before the tags: in campaigns' `# g_source:`
//! lines and runs' `g_source` in databases made then. They are data to read back, each matched
//! whole, not words this version says: the only text of the core that spells an option, which
//! `words::tests::the_core_spells_no_flag` allows in this file.

use super::GSource;

/// The source a text written before the tags names, when it is one of them.
pub(super) fn parse(text: &str) -> Option<GSource> {
    // The database kept a campaign's source inside these words.
    if let Some(inner) = text.strip_prefix("the campaign's `# g_m_s2:` (").and_then(|t| t.strip_suffix(')')) {
        return Some(GSource::parse(inner));
    }
    match text {
        "--g" => Some(GSource::Given { u_m_s2: None }),
        "default 9.81 m/s² (no --g or --latitude given)" => Some(GSource::Assumed),
        _ => {
            let site = text.strip_prefix("WGS84 normal gravity at latitude ")?.strip_suffix(" m")?;
            let (lat, height) = site.split_once(" deg, height ")?;
            Some(GSource::Normal { latitude_deg: lat.parse().ok()?, height_m: height.parse().ok()? })
        }
    }
}
