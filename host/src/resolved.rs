//! What the settings' checks resolve besides the parsed command line, handed to the commands with
//! it (so that no field of a clap struct is set after parsing).

use accelcal_core::campaign::identity::{G_SOURCE_ASSUMED, G_SOURCE_NORMAL};
use accelcal_core::error::bad;

/// What the settings' checks resolved besides the parsed command line: the gravity the user
/// stated (`--g`, `--latitude`: a campaign's `# g_m_s2:` line then does not apply), and what a
/// station's settings file gave.
#[derive(Debug, Default)]
pub struct Resolved {
    /// The gravity `--g` or `--latitude`/`--height` gave, checked; `None` when not given.
    pub gravity: Option<Gravity>,
    /// `station --config`: the file's keys, and those the command line overrode.
    pub config: Option<ConfigUse>,
}

/// What a station's settings file gave, for the station's first line.
#[derive(Debug, Default)]
pub struct ConfigUse {
    /// The file.
    pub path: std::path::PathBuf,
    /// The keys it gave, in the file's order.
    pub keys: Vec<String>,
    /// Its keys the command line overrode.
    pub overridden: Vec<String>,
}

/// Gravity at the rig, m/s², and where it came from.
#[derive(Clone, Debug, PartialEq)]
pub struct Gravity {
    /// m/s².
    pub g: f64,
    /// Where it came from.
    pub source: Source,
}

/// Where a command's gravity came from.
#[derive(Clone, Debug, PartialEq)]
pub enum Source {
    /// `--g` (or a station settings file's `g`).
    Flag,
    /// `--latitude` and `--height` (m, 0 when not given): WGS84 normal gravity with the free-air
    /// correction.
    Site { latitude: f64, height: f64 },
    /// The command's documented default `--g` (`plan`, `simulate`), not given.
    Default,
    /// A campaign's `# g_m_s2:` line; its `# g_source:` line when it has one.
    Campaign { g_source: Option<String> },
    /// The fit's identity, `what` naming the fit: where the unit was calibrated (`verify --fit`).
    Fit { what: String },
    /// Nobody stated it: the standard 9.81 m/s², announced.
    Assumed,
}

impl Gravity {
    /// The standard value, assumed because nobody stated one.
    pub fn assumed() -> Gravity {
        Gravity { g: accelcal_shared::G_STANDARD, source: Source::Assumed }
    }

    /// What the user stated, else the command's documented default `g` (`plan`, `simulate`).
    pub fn default_of(stated: Option<&Gravity>, g: f64) -> Gravity {
        stated.cloned().unwrap_or(Gravity { g, source: Source::Default })
    }

    /// Where it came from, in words: a campaign's `# g_source:`, a run's `g_source` in the
    /// database, and what [`accelcal_core::campaign::identity::g_uncertainty`] reads the bound
    /// of its error from (`None`: a number whose source is not known, taken as rounded).
    pub fn words(&self) -> Option<String> {
        match &self.source {
            Source::Flag => Some("--g".into()),
            Source::Site { latitude, height } => {
                Some(format!("{G_SOURCE_NORMAL} at latitude {latitude} deg, height {height} m"))
            }
            Source::Default => None,
            Source::Campaign { g_source } => g_source.clone(),
            Source::Fit { what } => Some(format!("the fit's, {what}")),
            Source::Assumed => Some(format!("{G_SOURCE_ASSUMED} (no --g or --latitude given)")),
        }
    }

    /// Where it came from as a run in the database keeps it: its [`Gravity::words`], or for a
    /// campaign's line without a `# g_source:` and a command's default, which line or default.
    pub fn stored(&self) -> String {
        match (&self.source, self.words()) {
            (Source::Campaign { g_source: Some(s) }, _) => format!("the campaign's `# g_m_s2:` ({s})"),
            (Source::Campaign { g_source: None }, _) => "the campaign's `# g_m_s2:`".into(),
            (_, Some(words)) => words,
            (_, None) => "the default --g".into(),
        }
    }

    /// How a clash with a file's g names this one: `--g 9.8`, or `--latitude (g = ... m/s²)`.
    pub fn option(&self) -> String {
        match self.source {
            Source::Site { .. } => format!("--latitude (g = {} m/s²)", self.g),
            _ => format!("--g {}", self.g),
        }
    }
}

/// The one announcement of the 9.81 m/s² fallback (without the `note: ` prefix), with why it
/// applies: `select`/`fit`/`compare`/`diagnose` and `acquire`/`verify` (a station's steps too) say it so.
pub fn fallback_note(why: &str) -> String {
    format!("g = {} m/s² assumed: {why}", accelcal_shared::G_STANDARD)
}

/// Refuses a `--g` that is not a positive number of m/s².
pub fn check_g(g: f64) -> anyhow::Result<()> {
    if !(g.is_finite() && g > 0.0) {
        return Err(bad(format!("--g must be a positive number of m/s², got {g}")));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use accelcal_core::campaign::identity::g_uncertainty;

    #[test]
    fn each_source_s_words_carry_the_bound_of_its_error() {
        let bound = |g: &Gravity| g_uncertainty(g.g, g.words().as_deref()).0;
        let site = Gravity { g: 9.81, source: Source::Site { latitude: 50.45, height: 180.0 } };
        assert_eq!(bound(&site), 1e-3);
        assert_eq!(bound(&Gravity::assumed()), 0.03);
        assert!((bound(&Gravity { g: 9.8174, source: Source::Flag }) - 5e-5).abs() < 1e-12);
        assert!((bound(&Gravity { g: 9.81, source: Source::Default }) - 5e-3).abs() < 1e-12);
        let from_campaign = Gravity { g: 9.81, source: Source::Campaign { g_source: site.words() } };
        assert_eq!(bound(&from_campaign), 1e-3);
    }
}
