//! Where a gravity value came from, typed once ([`GSource`]): what a campaign's `# g_source:`
//! line, a run's `g_source` in the database and a fit's identity store, as a tagged form that
//! parses back exactly ([`GSource::tag`], [`GSource::parse`]), and the standard uncertainty that
//! each source gives g ([`GSource::standard_u`]).
//!
//! The tagged forms:
//!
//! | source | tag |
//! |---|---|
//! | a value typed, taken as rounded | `given` |
//! | a value typed with its standard uncertainty | `given u=2e-6` |
//! | WGS84 normal gravity at a site | `normal latitude=50.45 height=180` |
//! | a registered survey (a `gravity` asset) | `survey u=2e-6 asset=G-1 certificate=PTB 2024/17` |
//! | nobody stated it: the standard 9.81 m/s² | `assumed` |
//! | a number whose source was not recorded | `unstated` |
//!
//! A survey's certificate number comes last and takes the rest of the line, so that it may hold
//! spaces. Text written before the tags (`--g`, `WGS84 normal gravity at latitude … deg, height …
//! m`, `default 9.81 m/s² (no --g or --latitude given)` and the database's `the campaign's
//! `# g_m_s2:`` forms) is read as the source it names, matched whole; any other text is a number
//! whose source was not recorded.

use core::fmt::Write as _;

mod legacy;

/// Where a gravity value came from.
#[derive(Clone, Debug, PartialEq)]
pub enum GSource {
    /// A value typed (`--g`, a settings file's `g`): with its standard uncertainty, m/s², when
    /// one was given, else taken as rounded.
    Given {
        /// Its standard uncertainty, m/s².
        u_m_s2: Option<f64>,
    },
    /// WGS84 normal gravity with the free-air correction at a site.
    Normal {
        /// Geodetic latitude, degrees.
        latitude_deg: f64,
        /// Height above the ellipsoid, m.
        height_m: f64,
    },
    /// A registered survey of the site: a `gravity` asset's value under one of its certificates.
    Survey {
        /// The asset's id.
        asset: String,
        /// Its certificate in force when used.
        certificate: String,
        /// The survey's standard uncertainty, m/s².
        u_m_s2: f64,
    },
    /// Nobody stated it: the standard 9.81 m/s².
    Assumed,
    /// A number whose source was not recorded (taken as rounded).
    Unstated,
}

/// The bound of normal gravity's error: the local anomaly it leaves out (typically within
/// 100 mGal), m/s².
const NORMAL_BOUND: f64 = 1e-3;
/// The bound of the assumed 9.81 m/s²'s error anywhere at sea level, m/s².
const ASSUMED_BOUND: f64 = 0.03;

impl GSource {
    /// The tagged form, which [`GSource::parse`] reads back as this value.
    pub fn tag(&self) -> String {
        let mut s = String::new();
        // Writing to a String cannot fail.
        let _ = match self {
            GSource::Given { u_m_s2: None } => write!(s, "given"),
            GSource::Given { u_m_s2: Some(u) } => write!(s, "given u={u:e}"),
            GSource::Normal { latitude_deg, height_m } => {
                write!(s, "normal latitude={latitude_deg} height={height_m}")
            }
            GSource::Survey { asset, certificate, u_m_s2 } => {
                write!(s, "survey u={u_m_s2:e} asset={asset} certificate={certificate}")
            }
            GSource::Assumed => write!(s, "assumed"),
            GSource::Unstated => write!(s, "unstated"),
        };
        s
    }

    /// The source a stored text names: a tag, a text written before the tags (matched whole),
    /// else [`GSource::Unstated`]. Never fails: a text nobody can read is a source not recorded.
    pub fn parse(text: &str) -> GSource {
        let text = text.trim();
        Self::tagged(text).or_else(|| legacy::parse(text)).unwrap_or(GSource::Unstated)
    }

    fn tagged(text: &str) -> Option<GSource> {
        let (word, rest) = text.split_once(' ').unwrap_or((text, ""));
        let num = |v: &str| v.parse::<f64>().ok().filter(|x| x.is_finite());
        let positive = |v: &str| num(v).filter(|x| *x > 0.0);
        match (word, rest) {
            ("given", "") => Some(GSource::Given { u_m_s2: None }),
            ("given", rest) => Some(GSource::Given { u_m_s2: Some(positive(rest.strip_prefix("u=")?)?) }),
            ("normal", rest) => {
                let (lat, height) = rest.strip_prefix("latitude=")?.split_once(" height=")?;
                let (latitude_deg, height_m) = (num(lat)?, num(height)?);
                (-90.0..=90.0).contains(&latitude_deg).then_some(GSource::Normal { latitude_deg, height_m })
            }
            ("survey", rest) => {
                let (u, rest) = rest.strip_prefix("u=")?.split_once(" asset=")?;
                let (asset, certificate) = rest.split_once(" certificate=")?;
                if asset.is_empty() || asset.contains(' ') || certificate.is_empty() {
                    return None;
                }
                Some(GSource::Survey {
                    asset: asset.into(),
                    certificate: certificate.into(),
                    u_m_s2: positive(u)?,
                })
            }
            ("assumed", "") => Some(GSource::Assumed),
            ("unstated", "") => Some(GSource::Unstated),
            _ => None,
        }
    }

    /// The standard uncertainty this source gives the value `g` (m/s²), and why, in words: a
    /// survey's or a typed one as stated; normal gravity and the assumed 9.81 m/s² from the bound
    /// of their error taken as rectangular (bound/√3); a value typed without one, or whose source
    /// was not recorded, as rounded: half a unit of its last digit, rectangular.
    pub fn standard_u(&self, g: f64) -> (f64, String) {
        const SQRT3: f64 = 1.732_050_807_568_877_2;
        let rect = |bound: f64, why: &str| {
            (bound / SQRT3, format!("{why}; bound {bound:.1e} m/s², rectangular: u = bound/√3"))
        };
        match self {
            GSource::Given { u_m_s2: Some(u) } => (*u, format!("as stated with the value: u = {u:.1e} m/s²")),
            GSource::Survey { asset, certificate, u_m_s2 } => {
                (*u_m_s2, format!("survey {asset}, certificate {certificate}: u = {u_m_s2:.1e} m/s² as certified"))
            }
            GSource::Normal { .. } => rect(
                NORMAL_BOUND,
                "normal gravity: the local anomaly it leaves out is typically within 0.001 m/s² (100 mGal), more in mountains",
            ),
            GSource::Assumed => rect(ASSUMED_BOUND, "assumed, the site unknown: g at sea level lies within 9.78 to 9.84 m/s²"),
            GSource::Given { u_m_s2: None } | GSource::Unstated => {
                rect(rounding_bound(g), "as given, taken as rounded: half a unit of its last digit")
            }
        }
    }

    /// Where the value came from, for people (a certificate, a command's first line).
    pub fn words(&self) -> String {
        match self {
            GSource::Given { u_m_s2: None } => "the value the operator stated".into(),
            GSource::Given { u_m_s2: Some(_) } => {
                "the value the operator stated, with its uncertainty".into()
            }
            GSource::Normal { latitude_deg, height_m } => {
                format!("WGS84 normal gravity at latitude {latitude_deg} deg, height {height_m} m")
            }
            GSource::Survey { asset, certificate, .. } => {
                format!("gravity survey {asset}, calibration certificate {certificate}")
            }
            GSource::Assumed => "the standard 9.81 m/s², assumed: no gravity was stated".into(),
            GSource::Unstated => "a value whose source was not recorded".into(),
        }
    }
}

/// Stored as its tag (a fit's identity).
impl serde::Serialize for GSource {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(&self.tag())
    }
}

impl<'de> serde::Deserialize<'de> for GSource {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<GSource, D::Error> {
        let text = <std::borrow::Cow<'de, str>>::deserialize(d)?;
        Ok(GSource::parse(&text))
    }
}

/// Half a unit of the last digit of `g` as written shortest.
fn rounding_bound(g: f64) -> f64 {
    let mut text = String::new();
    let _ = write!(text, "{g}");
    let decimals = text.split_once('.').map_or(0, |(_, f)| f.len()) as i32;
    0.5 * 10f64.powi(-decimals)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn every() -> Vec<GSource> {
        vec![
            GSource::Given { u_m_s2: None },
            GSource::Given { u_m_s2: Some(2.5e-6) },
            GSource::Normal { latitude_deg: -33.9, height_m: 120.5 },
            GSource::Survey { asset: "G-1".into(), certificate: "PTB 2024/17 rev. 2".into(), u_m_s2: 1e-7 },
            GSource::Assumed,
            GSource::Unstated,
        ]
    }

    #[test]
    fn every_tag_parses_back_exactly() {
        for s in every() {
            assert_eq!(GSource::parse(&s.tag()), s, "{}", s.tag());
        }
        assert_eq!(GSource::Given { u_m_s2: Some(2.5e-6) }.tag(), "given u=2.5e-6");
        assert_eq!(
            GSource::Normal { latitude_deg: 50.45, height_m: 180.0 }.tag(),
            "normal latitude=50.45 height=180"
        );
    }

    #[test]
    fn the_words_before_the_tags_are_read_whole() {
        assert_eq!(GSource::parse("--g"), GSource::Given { u_m_s2: None });
        assert_eq!(
            GSource::parse("WGS84 normal gravity at latitude 50.45 deg, height 180 m"),
            GSource::Normal { latitude_deg: 50.45, height_m: 180.0 }
        );
        assert_eq!(GSource::parse("default 9.81 m/s² (no --g or --latitude given)"), GSource::Assumed);
        assert_eq!(GSource::parse("the campaign's `# g_m_s2:` (--g)"), GSource::Given { u_m_s2: None });
        // Not a prefix match: free text that begins like a source is a source not recorded.
        assert_eq!(GSource::parse("WGS84 normal gravity, roughly"), GSource::Unstated);
        assert_eq!(GSource::parse("given u=abc"), GSource::Unstated);
        assert_eq!(GSource::parse("given u=-1e-6"), GSource::Unstated);
        assert_eq!(GSource::parse("survey u=1e-6 asset=A B certificate=C"), GSource::Unstated);
        assert_eq!(GSource::parse("normal latitude=91 height=0"), GSource::Unstated);
        assert_eq!(GSource::parse(""), GSource::Unstated);
    }

    #[test]
    fn each_source_gives_its_uncertainty() {
        let u = |s: GSource, g: f64| s.standard_u(g).0;
        let sqrt3 = 3f64.sqrt();
        assert!(
            (u(GSource::Normal { latitude_deg: 50.0, height_m: 0.0 }, 9.81) - 1e-3 / sqrt3).abs() < 1e-15
        );
        assert!((u(GSource::Assumed, 9.81) - 0.03 / sqrt3).abs() < 1e-15);
        assert!((u(GSource::Given { u_m_s2: None }, 9.81) - 0.005 / sqrt3).abs() < 1e-15);
        assert!((u(GSource::Unstated, 9.80665) - 5e-6 / sqrt3).abs() < 1e-18);
        assert!((u(GSource::Unstated, 10.0) - 0.5 / sqrt3).abs() < 1e-15);
        assert_eq!(u(GSource::Given { u_m_s2: Some(3e-6) }, 9.810547), 3e-6);
        let survey = GSource::Survey { asset: "G-1".into(), certificate: "C".into(), u_m_s2: 2e-7 };
        assert_eq!(u(survey.clone(), 9.8), 2e-7);
        assert!(survey.standard_u(9.8).1.contains("survey G-1, certificate C"));
    }
}
