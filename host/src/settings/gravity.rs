//! Gravity, resolved once: the value a command calibrates, plans or checks at and where it came
//! from, as one value ([`Gravity`], in [`crate::resolved`]) that the commands take instead of
//! reading clap's `--g`, `--latitude` and `--height` themselves.
//!
//! The command line is resolved here, before any I/O ([`stated`]): `--g` (with `--g-u`, its
//! standard uncertainty), or `--latitude` (and `--height`) for WGS84 normal gravity, or
//! `--gravity-asset` (a registered survey, read once the command has its database:
//! `app::gravity::resolve`); two sources at once, `--height` alone or `--g-u` alone are refused.
//! What the user did not state is resolved by the command from its input, in one place each: a
//! campaign's `# g_m_s2:` line (`cmd::campaign_g`), a fit's identity (`verify --fit`), the
//! documented default of `plan` and `simulate` ([`Gravity::default_of`]), or the standard value,
//! announced ([`Gravity::assumed`]).
//!
//! Where it came from is typed once ([`GSource`], [`Gravity::provenance`]): its tag is what a
//! campaign's `# g_source:`, a run in the database and a fit JSON store, and it gives g its
//! standard uncertainty ([`GSource::standard_u`]): a survey's or a stated one as given; normal
//! gravity leaves out the local anomaly, the assumed 9.81 m/s² is within 0.03 m/s² anywhere at
//! sea level, a number typed without `--g-u` is taken as rounded.

use accelcal_core::campaign::GSource;
use accelcal_core::error::bad;

use super::Given;
use crate::cli::{Command, LocalGravity};
use crate::resolved::{check_g, Gravity, Source};

/// The gravity the command line states (`--g`, `--latitude`/`--height`), checked: `None` when it
/// states none, or the command takes none. `--g` and `--latitude` together are refused, as is
/// `--height` without `--latitude`, a latitude outside ±90°, a height beyond ±100 km and a `--g`
/// that is not a positive number.
pub fn stated(command: &Command, given: &Given) -> anyhow::Result<Option<Gravity>> {
    let (g, local, asset) = match command {
        Command::Fit(a) => (Some(a.common.g), &a.common.local, a.gravity_asset.as_deref()),
        Command::Select(a) => (Some(a.common.g), &a.common.local, None),
        Command::Compare(a) => (Some(a.common.g), &a.common.local, None),
        Command::Diagnose(a) => (Some(a.common.g), &a.common.local, None),
        Command::Plan(a) => (Some(a.g), &a.local, None),
        Command::Simulate(a) => (Some(a.g), &a.local, None),
        Command::Acquire(a) => (a.g, &a.local, None),
        Command::Verify(a) => (a.g, &a.local, a.gravity_asset.as_deref()),
        Command::Station(a) => (a.g, &a.local, a.gravity_asset.as_deref()),
        _ => return Ok(None),
    };
    if given.has("g") && given.has("latitude") {
        return Err(bad("--g and --latitude both give gravity: give one of them"));
    }
    if given.has("height") && !given.has("latitude") {
        return Err(bad("--height needs --latitude (it corrects the normal gravity there)"));
    }
    if given.has("g_u") && !given.has("g") {
        return Err(bad("--g-u needs --g: it is the standard uncertainty of the g typed there"));
    }
    if let Some(id) = asset {
        if let Some(other) = ["g", "latitude", "g_u"].into_iter().find(|o| given.has(o)) {
            return Err(bad(format!(
                "--gravity-asset and --{} both give gravity: give one of them",
                other.replace('_', "-")
            )));
        }
        // The survey's value is read with the command's database (`app::gravity::resolve`).
        return Ok(Some(Gravity { g: f64::NAN, source: Source::Asset { id: id.to_string() } }));
    }
    if let Some(site) = site(local)? {
        return Ok(Some(site));
    }
    match g.filter(|_| given.has("g")) {
        Some(g) => {
            check_g(g)?;
            let u_m_s2 = match local.g_u {
                Some(u) if !(u.is_finite() && u > 0.0 && u < 0.1) => {
                    return Err(bad(format!(
                        "--g-u must be a standard uncertainty in (0, 0.1) m/s², got {u}"
                    )))
                }
                u => u,
            };
            Ok(Some(Gravity { g, source: Source::Stated(GSource::Given { u_m_s2 }) }))
        }
        None => Ok(None),
    }
}

/// Normal gravity at `--latitude`/`--height`, checked; `None` without `--latitude`.
fn site(local: &LocalGravity) -> anyhow::Result<Option<Gravity>> {
    let Some(latitude) = local.latitude else { return Ok(None) };
    if !(latitude.is_finite() && (-90.0..=90.0).contains(&latitude)) {
        return Err(bad(format!("--latitude must be in -90..=90 degrees, got {latitude}")));
    }
    let height = local.height.unwrap_or(0.0);
    if !(height.is_finite() && height.abs() <= 100_000.0) {
        return Err(bad(format!("--height must be within ±100000 m, got {height}")));
    }
    Ok(Some(Gravity {
        g: accelcal_shared::normal_gravity(latitude, height),
        source: Source::Stated(GSource::Normal { latitude_deg: latitude, height_m: height }),
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_site_out_of_range_is_refused() {
        let at = |latitude, height| {
            site(&LocalGravity { latitude: Some(latitude), height: Some(height), g_u: None })
        };
        assert!(at(91.0, 0.0).is_err());
        assert!(at(f64::NAN, 0.0).is_err());
        assert!(at(45.0, 2e5).is_err());
        let g = at(45.0, 0.0).unwrap().unwrap();
        assert!((g.g - 9.806).abs() < 1e-3, "{g:?}");
    }
}
