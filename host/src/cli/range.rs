//! The ranges an option's number must lie in, each written once: the option's clap value parser
//! checks it as the command line is parsed ([`Real`], [`Count`]), and the station's settings file
//! checks its keys with the same [`Range::check`] (`settings::station_config`), so a value is
//! refused with the same words wherever it comes from.
//!
//! A refusal is one line that names the option and the value: `--timeout-s must be a positive
//! number of seconds, got 0` (exit code 2, printed by `main` as one line like every other bad
//! input).

use std::ffi::OsStr;

use clap::builder::TypedValueParser;
use clap::error::ErrorKind;

/// The longest duration any option takes, seconds: a day. No wait of the line is longer, and a
/// `Duration` built from a checked number cannot overflow (`Duration::from_secs_f64` panics past
/// about 1.8e19 s: `info --timeout-s 1e20` did).
pub const DAY_S: f64 = 86_400.0;

/// A range of values, with the words that say it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Range {
    /// A positive number of seconds up to a day, [`DAY_S`] (a timeout, a settling time).
    Seconds,
    /// At least 2 sample sets per position (a mean and a spread).
    Sets,
    /// A window of at least 2 sample sets.
    Window,
    /// A finite number > 0, of the option's unit.
    Positive,
    /// At least 1 (a count).
    AtLeast1,
    /// A number of seconds from 0 to a day, [`DAY_S`] (a soak, a lag, a move).
    SecondsOrZero,
    /// A climatic chamber's setpoint: the emulated head's range,
    /// [`accelcal_line::head::CHAMBER_RANGE_C`], °C.
    Chamber,
    /// The reference temperature of the thermal terms: -100..=200 °C.
    TRef,
    /// A positive, finite number of m/s² (a tolerance).
    MetresPerS2,
    /// A positive, finite number of degrees per second.
    DegreesPerS,
    /// A stated one-sigma uncertainty: a finite number ≥ 0.
    Sigma,
    /// A number of codes ≥ 0.
    Codes,
    /// A coverage factor: a number ≥ 1.
    Coverage,
    /// Arcseconds of a dividing head's angle: 0..=3600.
    Arcsec,
    /// A factor on the emulated node's rate: (0, 100].
    RateFactor,
    /// Degrees per microstep of a rotary stage: (0, 1).
    DegPerStep,
}

impl Range {
    /// `v` when it lies in the range; otherwise what the value must be and what it was
    /// (`must be a positive number of seconds, got 0`), for the caller to put after the option's
    /// name.
    pub fn check(self, v: f64) -> Result<f64, String> {
        let (ok, must) = match self {
            Range::Seconds => {
                (v > 0.0 && v <= DAY_S, "must be a positive number of seconds up to 86400 (a day)")
            }
            Range::Sets => (v >= 2.0, "must be at least 2 sets per position"),
            Range::Window => (v >= 2.0, "must be at least 2 sets"),
            Range::Positive => (v.is_finite() && v > 0.0, "must be a positive number"),
            Range::AtLeast1 => (v >= 1.0, "must be at least 1"),
            Range::SecondsOrZero => {
                ((0.0..=DAY_S).contains(&v), "must be a number of seconds from 0 to 86400 (a day)")
            }
            Range::Chamber => {
                (accelcal_line::head::CHAMBER_RANGE_C.contains(&v), "must be a temperature in -60..=150 °C")
            }
            Range::TRef => {
                (v.is_finite() && (-100.0..=200.0).contains(&v), "must be a temperature in -100..=200 °C")
            }
            Range::MetresPerS2 => (v.is_finite() && v > 0.0, "must be a positive number of m/s²"),
            Range::DegreesPerS => {
                (v.is_finite() && v > 0.0, "must be a positive number of degrees per second")
            }
            Range::Sigma => (v.is_finite() && v >= 0.0, "must be a finite number ≥ 0"),
            Range::Codes => (v.is_finite() && v >= 0.0, "must be a number of codes >= 0"),
            Range::Coverage => (v.is_finite() && v >= 1.0, "must be a number >= 1"),
            Range::Arcsec => {
                (v.is_finite() && (0.0..=3600.0).contains(&v), "must be a number of arcseconds in 0..=3600")
            }
            Range::RateFactor => (v.is_finite() && v > 0.0 && v <= 100.0, "must be in (0, 100]"),
            Range::DegPerStep => {
                (v.is_finite() && v > 0.0 && v < 1.0, "must be a number of degrees per microstep in (0, 1)")
            }
        };
        if ok {
            Ok(v)
        } else {
            Err(format!("{must}, got {}", shown(v)))
        }
    }

    /// [`Range::check`] for a count.
    pub fn count(self, n: usize) -> Result<usize, String> {
        self.check(n as f64).map(|_| n)
    }
}

/// A refused number as the message shows it: as written for the everyday sizes, in exponent form
/// past 1e15 (`1e20`, not twenty-one digits; `1e300`, not three hundred).
fn shown(v: f64) -> String {
    if v.is_finite() && v.abs() >= 1e15 {
        format!("{v:e}")
    } else {
        v.to_string()
    }
}

/// The value parser of a number (`f64`) in a [`Range`].
#[derive(Debug, Clone, Copy)]
pub struct Real(pub Range);

/// The value parser of a count (`usize`) in a [`Range`].
#[derive(Debug, Clone, Copy)]
pub struct Count(pub Range);

/// The option's name for a message: `--timeout-s`, or the value name of an argument.
fn option(arg: Option<&clap::Arg>) -> String {
    match arg {
        Some(a) => match a.get_long() {
            Some(l) => format!("--{l}"),
            None => a.get_value_names().and_then(|v| v.first()).map(|v| v.to_string()).unwrap_or_default(),
        },
        None => "the value".into(),
    }
}

/// `value` as a number of type `T`, or clap's refusal that names the option and shows the value
/// escaped (it may hold a control character).
fn number<T: std::str::FromStr>(
    cmd: &clap::Command,
    arg: Option<&clap::Arg>,
    value: &OsStr,
) -> Result<T, clap::Error>
where
    T::Err: std::fmt::Display,
{
    let text = value.to_string_lossy();
    text.trim().parse::<T>().map_err(|e| {
        let shown = text.escape_debug();
        clap::Error::raw(ErrorKind::ValueValidation, format!("{} `{shown}`: {e}", option(arg))).with_cmd(cmd)
    })
}

/// The refusal of a number out of its range, as clap's error (printed by `main` as one line).
fn out_of_range(cmd: &clap::Command, arg: Option<&clap::Arg>, why: String) -> clap::Error {
    clap::Error::raw(ErrorKind::ValueValidation, format!("{} {why}", option(arg))).with_cmd(cmd)
}

impl TypedValueParser for Real {
    type Value = f64;

    fn parse_ref(
        &self,
        cmd: &clap::Command,
        arg: Option<&clap::Arg>,
        value: &OsStr,
    ) -> Result<f64, clap::Error> {
        let v: f64 = number(cmd, arg, value)?;
        self.0.check(v).map_err(|why| out_of_range(cmd, arg, why))
    }
}

impl TypedValueParser for Count {
    type Value = usize;

    fn parse_ref(
        &self,
        cmd: &clap::Command,
        arg: Option<&clap::Arg>,
        value: &OsStr,
    ) -> Result<usize, clap::Error> {
        let n: usize = number(cmd, arg, value)?;
        self.0.count(n).map_err(|why| out_of_range(cmd, arg, why))
    }
}

/// The value parser of a node's sampling rate, Hz: the rates the node accepts
/// ([`accelcal_shared::wire::check_rate`], the node's own rule), refused before any port is opened.
#[derive(Debug, Clone, Copy)]
pub struct RateHz;

/// Why the node would refuse `hz`, for the caller to put after the option's name.
pub fn rate_hz(hz: u32) -> Result<u32, String> {
    accelcal_shared::wire::check_rate(hz).map(|()| hz).map_err(|r| format!(": {r}"))
}

impl TypedValueParser for RateHz {
    type Value = u32;

    fn parse_ref(
        &self,
        cmd: &clap::Command,
        arg: Option<&clap::Arg>,
        value: &OsStr,
    ) -> Result<u32, clap::Error> {
        let hz: u32 = number(cmd, arg, value)?;
        rate_hz(hz).map_err(|why| {
            clap::Error::raw(ErrorKind::ValueValidation, format!("{}{why}", option(arg))).with_cmd(cmd)
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Each range's edges, and the words of a refusal.
    #[test]
    fn edges_and_words() {
        let cases: &[(Range, f64, bool)] = &[
            (Range::Seconds, 0.0, false),
            (Range::Seconds, 1e-9, true),
            (Range::Seconds, f64::INFINITY, false),
            (Range::Seconds, f64::NAN, false),
            (Range::Seconds, 86_400.0, true),
            (Range::Seconds, 86_400.5, false),
            (Range::Seconds, 1e20, false),
            (Range::SecondsOrZero, 0.0, true),
            (Range::SecondsOrZero, -0.0, true),
            (Range::SecondsOrZero, -1.0, false),
            (Range::SecondsOrZero, 86_400.0, true),
            (Range::SecondsOrZero, 1e300, false),
            (Range::SecondsOrZero, f64::NAN, false),
            (Range::Sets, 1.0, false),
            (Range::Sets, 2.0, true),
            (Range::Sigma, 0.0, true),
            (Range::Sigma, -0.1, false),
            (Range::Sigma, f64::NAN, false),
            (Range::Codes, 0.0, true),
            (Range::Coverage, 0.99, false),
            (Range::Coverage, 1.0, true),
            (Range::Arcsec, 3600.0, true),
            (Range::Arcsec, 3600.1, false),
            (Range::RateFactor, 100.0, true),
            (Range::RateFactor, 0.0, false),
        ];
        for &(r, v, ok) in cases {
            assert_eq!(r.check(v).is_ok(), ok, "{r:?} {v}");
        }
        assert_eq!(
            Range::Seconds.check(0.0).unwrap_err(),
            "must be a positive number of seconds up to 86400 (a day), got 0"
        );
        assert_eq!(
            Range::Seconds.check(1e20).unwrap_err(),
            "must be a positive number of seconds up to 86400 (a day), got 1e20"
        );
        assert_eq!(Range::Sets.check(1.0).unwrap_err(), "must be at least 2 sets per position, got 1");
        // The chamber's words state the emulated head's range.
        assert_eq!(accelcal_line::head::CHAMBER_RANGE_C, -60.0..=150.0);
    }

    /// clap's error names the option and says the range (the message `main` prints).
    #[test]
    fn the_parser_names_the_option() {
        let cmd = clap::Command::new("t")
            .arg(clap::Arg::new("timeout_s").long("timeout-s").value_parser(Real(Range::Seconds)))
            .arg(clap::Arg::new("samples").long("samples").value_parser(Count(Range::Sets)));
        let e = cmd.clone().try_get_matches_from(["t", "--timeout-s", "0"]).unwrap_err();
        assert_eq!(e.kind(), ErrorKind::ValueValidation);
        assert!(
            e.to_string()
                .contains("--timeout-s must be a positive number of seconds up to 86400 (a day), got 0"),
            "{e}"
        );
        let e = cmd.clone().try_get_matches_from(["t", "--samples", "1"]).unwrap_err();
        assert!(e.to_string().contains("--samples must be at least 2 sets per position, got 1"), "{e}");
        let m = cmd.try_get_matches_from(["t", "--timeout-s", "2.5", "--samples", "3"]).unwrap();
        assert_eq!(m.get_one::<f64>("timeout_s"), Some(&2.5));
        assert_eq!(m.get_one::<usize>("samples"), Some(&3));
    }
}
