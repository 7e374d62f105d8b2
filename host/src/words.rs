//! How a failure is printed: the libraries name the settings their messages refer to
//! ([`accelcal_core::error::Setting`]) and this binary words them as its user gives them, its
//! flags. The policy is the same as [`crate::exit`]'s: the facts are the libraries', the words
//! the binary's.

use accelcal_core::error::{Setting, Worded, Wording};

/// This binary's words for the libraries' settings: the flag, or the command line, that gives
/// each.
pub struct Flags;

impl Wording for Flags {
    fn name(&self, s: Setting) -> &'static str {
        match s {
            Setting::G => "--g",
            Setting::Codes => "--codes",
            Setting::Split => "--split",
            Setting::SplitTemp => "--split temp",
            Setting::CriterionLoo => "--criterion loo",
            Setting::TempInput => "--temp-input",
            Setting::Validate => "--validate CAMPAIGN2",
            Setting::FitRecord => "`fit --record`",
            Setting::RefitJson => "run `accelcal fit ... --json` again",
            Setting::RefitWithRecord => "`accelcal fit CAMPAIGN --record R --json F`",
            Setting::SimulateSigned => "`simulate --codes signed16`",
            Setting::DeviceId => "--device-id",
            Setting::FitDeviceId => "`fit --device-id HEX`",
            Setting::Model4Terms => "`--terms ax,ay,az`",
            Setting::MinHold => "--min-hold-s",
            Setting::HoldThreshold => "--threshold",
        }
    }
}

/// Lists the library error types whose messages name settings: [`worded`] tries each.
macro_rules! worded_types {
    ($($t:ty),* $(,)?) => {
        /// The message of one error of a chain in this binary's words, when its type names
        /// settings.
        fn worded(e: &(dyn std::error::Error + 'static)) -> Option<String> {
            $(if let Some(x) = e.downcast_ref::<$t>() {
                return Worded::worded(x, &Flags);
            })*
            None
        }
    };
}

worded_types!(
    accelcal_core::campaign::CampaignError,
    accelcal_core::campaign::identity::IdentityError,
    accelcal_core::gmdh::GmdhError,
    accelcal_core::sim::unit::UnitError,
    accelcal_core::compare::CompareError,
    accelcal_core::calibrate::RecordError,
    accelcal_core::gravity::GravityError,
    accelcal_line::node::flash::FlashError,
);

/// The one line of a failure: each error of the chain, outermost first, joined by `: ` (as
/// `{:#}` prints an `anyhow::Error`), the libraries' settings worded with this binary's flags.
pub fn line(e: &anyhow::Error) -> String {
    e.chain().map(|c| worded(c).unwrap_or_else(|| c.to_string())).collect::<Vec<_>>().join(": ")
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The pure library (`core`) spells no flag of this binary: a message names a setting
    /// ([`Setting`]) and [`Flags`] words it. Every line of its sources outside comments and
    /// tests is read for a `--name`.
    #[test]
    fn the_core_spells_no_flag() {
        let mut found = Vec::new();
        for (path, text) in crate::sources::library_sources(&["core"]) {
            // `legacy.rs`: text older versions wrote into files, read back, never said.
            if path.ends_with("tests.rs") || path.ends_with("g_source/legacy.rs") {
                continue;
            }
            for (n, t) in crate::sources::code_lines(&text) {
                let flag = t.match_indices("--").any(|(at, _)| {
                    t[at + 2..].starts_with(|c: char| c.is_ascii_lowercase())
                        && !t[..at].ends_with(|c: char| c.is_ascii_alphanumeric())
                });
                if flag {
                    found.push(format!("{}:{n}: {t}", path.display()));
                }
            }
        }
        assert!(found.is_empty(), "the core spells flags:\n{}", found.join("\n"));
    }

    /// Each setting is worded differently by the library and by this binary, and this binary's
    /// words name a flag.
    #[test]
    fn every_setting_has_a_flag() {
        use accelcal_core::error::Plain;
        for s in [
            Setting::G,
            Setting::Codes,
            Setting::Split,
            Setting::SplitTemp,
            Setting::CriterionLoo,
            Setting::TempInput,
            Setting::Validate,
            Setting::FitRecord,
            Setting::RefitJson,
            Setting::RefitWithRecord,
            Setting::SimulateSigned,
            Setting::DeviceId,
            Setting::FitDeviceId,
            Setting::Model4Terms,
            Setting::MinHold,
            Setting::HoldThreshold,
        ] {
            assert!(Flags.name(s).contains("--"), "{s:?}");
            assert!(!Plain.name(s).contains("--"), "{s:?}");
        }
    }

    /// A library error in the chain is worded with the flag; its context is kept.
    #[test]
    fn a_chain_is_worded_with_the_flags() {
        let e = anyhow::Error::new(accelcal_core::compare::CompareError::NothingToValidate).context("c.csv");
        assert_eq!(
            line(&e),
            "c.csv: the plan has no positions besides the test-turn ones to validate on; give --validate CAMPAIGN2"
        );
        assert_eq!(
            format!("{e:#}"),
            "c.csv: the plan has no positions besides the test-turn ones to validate on; give a validation campaign"
        );
    }
}
