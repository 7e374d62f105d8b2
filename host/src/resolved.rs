//! What the settings' checks resolve besides the parsed command line, handed to the commands with
//! it (so that no field of a clap struct is set after parsing).

use accelcal_core::campaign::GSource;
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
    /// `station --plan FILE`: the dwell its header states, checked against the station's
    /// settings; `None` for a built-in plan.
    pub plan: Option<PlanDwell>,
}

/// The dwell a station's plan file states in its header (`# samples:`, `# rate_hz:`), which the
/// station takes; either may be absent (a plan file written before, or by hand).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PlanDwell {
    /// The plan file.
    pub path: std::path::PathBuf,
    /// Sample sets per position.
    pub samples: Option<usize>,
    /// The node's rate, Hz.
    pub rate_hz: Option<u32>,
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
    /// The command line or the settings file: `--g` (with `--g-u`), `--latitude`/`--height`, or
    /// a survey read from the register (`--gravity-asset`, once [`crate::app::gravity`] read it).
    Stated(GSource),
    /// `--gravity-asset ID`, before the command read the survey from its database: `g` is not
    /// known yet ([`crate::app::gravity::resolve`] turns it into a [`Source::Stated`] survey).
    Asset {
        /// The asset's id.
        id: String,
    },
    /// The command's documented default `--g` (`plan`, `simulate`), not given.
    Default,
    /// A campaign's `# g_m_s2:` line, with its `# g_source:` when it has one.
    Campaign(Option<GSource>),
    /// The fit's identity, `what` naming the fit: where the unit was calibrated (`verify --fit`),
    /// with where the fit's g came from when it says.
    Fit {
        /// The fit.
        what: String,
        /// Its identity's `g_source`.
        g_source: Option<GSource>,
    },
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

    /// Where the value came from, typed: what a campaign's `# g_source:`, a run in the database
    /// and a fit's identity store (its tag), and what gives g its uncertainty
    /// ([`GSource::standard_u`]). A command's default is as if typed; a campaign or fit that does
    /// not say is a value whose source was not recorded.
    pub fn provenance(&self) -> GSource {
        match &self.source {
            Source::Stated(s) => s.clone(),
            Source::Campaign(Some(s)) | Source::Fit { g_source: Some(s), .. } => s.clone(),
            Source::Assumed => GSource::Assumed,
            // The documented default of `--g` (`plan`, `simulate`), as if typed.
            Source::Default => GSource::Given { u_m_s2: None },
            Source::Asset { .. } | Source::Campaign(None) | Source::Fit { g_source: None, .. } => {
                GSource::Unstated
            }
        }
    }

    /// Where it came from, as a run in the database and a campaign's `# g_source:` keep it: the
    /// tag of its [`Gravity::provenance`].
    pub fn stored(&self) -> String {
        self.provenance().tag()
    }

    /// Where it came from, for a command's first line: the provenance's words, and which file
    /// gave the value when a file did.
    pub fn words(&self) -> String {
        let p = self.provenance().words();
        match &self.source {
            Source::Campaign(_) => format!("the campaign's `# g_m_s2:`, {p}"),
            Source::Fit { what, .. } => format!("the fit's, {what}: {p}"),
            Source::Default => "the default --g".into(),
            Source::Asset { id } => format!("gravity asset {id}, not yet read"),
            _ => p,
        }
    }

    /// Its standard uncertainty, m/s², and why ([`GSource::standard_u`]).
    pub fn standard_u(&self) -> (f64, String) {
        self.provenance().standard_u(self.g)
    }

    /// How a clash with a file's g names this one: `--g 9.8`, or `--latitude (g = ... m/s²)`.
    pub fn option(&self) -> String {
        match &self.source {
            Source::Stated(GSource::Normal { .. }) => format!("--latitude (g = {} m/s²)", self.g),
            Source::Stated(GSource::Survey { asset, .. }) => {
                format!("--gravity-asset {asset} (g = {} m/s²)", self.g)
            }
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

    #[test]
    fn each_source_gives_g_its_uncertainty_and_stores_its_tag() {
        let u = |g: &Gravity| g.standard_u().0 * 3f64.sqrt();
        let normal = GSource::Normal { latitude_deg: 50.45, height_m: 180.0 };
        let site = Gravity { g: 9.81, source: Source::Stated(normal.clone()) };
        assert!((u(&site) - 1e-3).abs() < 1e-15);
        assert!((u(&Gravity::assumed()) - 0.03).abs() < 1e-15);
        let typed = Gravity { g: 9.8174, source: Source::Stated(GSource::Given { u_m_s2: None }) };
        assert!((u(&typed) - 5e-5).abs() < 1e-12);
        assert!((u(&Gravity { g: 9.81, source: Source::Default }) - 5e-3).abs() < 1e-12);
        let from_campaign = Gravity { g: 9.81, source: Source::Campaign(Some(normal.clone())) };
        assert!((u(&from_campaign) - 1e-3).abs() < 1e-15);
        assert_eq!(from_campaign.stored(), normal.tag());
        let with_u = Gravity { g: 9.810547, source: Source::Stated(GSource::Given { u_m_s2: Some(2e-6) }) };
        assert_eq!(with_u.standard_u().0, 2e-6);
        assert_eq!(GSource::parse(&with_u.stored()), with_u.provenance());
    }
}
