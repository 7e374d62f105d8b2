//! The head's line protocol, version [`VERSION`]: one ASCII line per request and per reply. The
//! emulated head serves it over TCP (`sim:HOST:PORT`), an adapter on its standard input and output
//! (`exec:COMMAND`); both ends use these types. The guide's reference page
//! (`docs/src/line/heads.md`, "The head protocol") says the same for adapter authors.
//!
//! | request | reply |
//! |---|---|
//! | `HELLO` | `HELLO <version> <identification…>`: the protocol version the head speaks and what it is (free text to the line end) |
//! | `HOME` | `OK <alpha_deg> <beta_deg>` once every axis that needs it is homed and the head stands still |
//! | `MOVE <alpha_deg> <beta_deg>` | `OK <alpha_deg> <beta_deg>` once the head stands still at the new angles |
//! | `WHERE` | `AT <alpha_deg> <beta_deg> STILL` or `AT … MOVING` (the angles it is passing) |
//! | `CHAMBER <temp_c>` | `TEMP <setpoint_c>`: the rig's thermal chamber now heads for this temperature (°C, −60..=150) |
//! | `TEMP` | `TEMP <setpoint_c>`: the chamber's setpoint |
//! | `STOP` | `OK <alpha_deg> <beta_deg>`: every axis stopped; the angles it stands at |
//!
//! Requests are answered in order, one reply each. `STOP` may be sent while a `MOVE` waits for its
//! reply: the head stops at once, answers the `MOVE` with `OK` and the angles where it stopped,
//! then the `STOP`. Any request the head cannot carry out is answered `ERR <reason>`; the tool
//! ends the command with the reason (exit code 3) and records nothing of the position. Angles are degrees in the
//! paper's convention (α about the spindle, β the tilt; `accelcal_shared::kinematics`).

use accelcal_core::text::escape_peer;

/// The protocol version this build speaks (1: `MOVE`, `WHERE`, `CHAMBER`, `TEMP`; 2 adds `HELLO`,
/// `HOME` and `STOP`).
pub const VERSION: u32 = 2;

/// The longest identification a head may give in its `HELLO`, characters; the rest is cut.
pub const MAX_IDENT: usize = 120;

/// A request to a head.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Request {
    /// Which protocol version, and which head?
    Hello,
    /// Home the axes that need it.
    Home,
    /// Stop every axis now.
    Stop,
    /// Turn to these angles, degrees.
    Move {
        /// α, degrees.
        alpha_deg: f64,
        /// β, degrees.
        beta_deg: f64,
    },
    /// Where is the head now?
    Where,
    /// Set the thermal chamber to this temperature, °C.
    Chamber {
        /// Setpoint, °C.
        temp_c: f64,
    },
    /// What is the chamber's setpoint?
    Temp,
}

/// The chamber setpoints the protocol accepts, °C.
pub const CHAMBER_RANGE_C: std::ops::RangeInclusive<f64> = -60.0..=150.0;

/// A head's reply.
#[derive(Clone, Debug, PartialEq)]
pub enum Reply {
    /// The protocol version the head speaks and its identification.
    Hello {
        /// The version.
        version: u32,
        /// What the head is (make, model, serial, firmware: free text, escaped when parsed).
        ident: String,
    },
    /// The move is done: the head stands at these angles.
    Ok {
        /// α, degrees.
        alpha_deg: f64,
        /// β, degrees.
        beta_deg: f64,
    },
    /// The head's angles now, and whether it is moving.
    At {
        /// α, degrees.
        alpha_deg: f64,
        /// β, degrees.
        beta_deg: f64,
        /// True while a move is under way.
        moving: bool,
    },
    /// The chamber's setpoint, °C.
    Temp {
        /// Setpoint, °C.
        setpoint_c: f64,
    },
    /// The request was refused.
    Err(String),
}

fn angles<'a>(mut words: impl Iterator<Item = &'a str>, what: &str) -> Result<(f64, f64), String> {
    let mut num = |name: &str| -> Result<f64, String> {
        words
            .next()
            .and_then(|w| w.parse::<f64>().ok())
            .filter(|v| v.is_finite())
            .ok_or_else(|| format!("{what}: expected {name} in degrees, a finite number"))
    };
    Ok((num("alpha")?, num("beta")?))
}

impl Request {
    /// The request's line, without the newline.
    pub fn line(&self) -> String {
        match *self {
            Request::Move { alpha_deg, beta_deg } => format!("MOVE {alpha_deg} {beta_deg}"),
            Request::Where => "WHERE".into(),
            Request::Chamber { temp_c } => format!("CHAMBER {temp_c}"),
            Request::Temp => "TEMP".into(),
            Request::Hello => "HELLO".into(),
            Request::Home => "HOME".into(),
            Request::Stop => "STOP".into(),
        }
    }

    /// Parses a request line (surrounding white space ignored).
    pub fn parse(line: &str) -> Result<Request, String> {
        let mut words = line.split_whitespace();
        match words.next() {
            Some("MOVE") => {
                let (alpha_deg, beta_deg) = angles(words, "MOVE")?;
                Ok(Request::Move { alpha_deg, beta_deg })
            }
            Some("WHERE") => Ok(Request::Where),
            Some("TEMP") => Ok(Request::Temp),
            Some("HELLO") => Ok(Request::Hello),
            Some("HOME") => Ok(Request::Home),
            Some("STOP") => Ok(Request::Stop),
            Some("CHAMBER") => match words.next().and_then(|w| w.parse::<f64>().ok()) {
                Some(temp_c) if CHAMBER_RANGE_C.contains(&temp_c) => Ok(Request::Chamber { temp_c }),
                _ => Err("CHAMBER: expected a temperature in -60..=150 °C".into()),
            },
            _ => Err(format!(
                "unknown request `{}` (expected HELLO, HOME, MOVE <alpha> <beta>, WHERE, STOP, CHAMBER <temp_c> or TEMP)",
                escape_peer(line.trim().as_bytes())
            )),
        }
    }
}

impl Reply {
    /// The reply's line, without the newline.
    pub fn line(&self) -> String {
        match self {
            Reply::Ok { alpha_deg, beta_deg } => format!("OK {alpha_deg} {beta_deg}"),
            Reply::At { alpha_deg, beta_deg, moving } => {
                format!("AT {alpha_deg} {beta_deg} {}", if *moving { "MOVING" } else { "STILL" })
            }
            Reply::Temp { setpoint_c } => format!("TEMP {setpoint_c}"),
            Reply::Hello { version, ident } => format!("HELLO {version} {}", ident.replace('\n', " ")),
            Reply::Err(m) => format!("ERR {}", m.replace('\n', " ")),
        }
    }

    /// Parses a reply line. What the head sent is shown escaped in a refusal's words and in an
    /// `ERR`'s message ([`escape_peer`]): a reply cannot send escape sequences to the terminal.
    pub fn parse(line: &str) -> Result<Reply, String> {
        let line = line.trim();
        if let Some(m) = line.strip_prefix("ERR") {
            return Ok(Reply::Err(escape_peer(m.trim().as_bytes())));
        }
        let shown = escape_peer(line.as_bytes());
        let mut words = line.split_whitespace();
        match words.next() {
            Some("OK") => {
                let (alpha_deg, beta_deg) = angles(words, "OK")?;
                Ok(Reply::Ok { alpha_deg, beta_deg })
            }
            Some("HELLO") => {
                let version = words.next().and_then(|w| w.parse::<u32>().ok());
                let Some(version) = version else {
                    return Err(format!("`{shown}`: expected HELLO <version> <identification>"));
                };
                let ident = words.collect::<Vec<_>>().join(" ");
                let ident: String = escape_peer(ident.as_bytes()).chars().take(MAX_IDENT).collect();
                Ok(Reply::Hello { version, ident })
            }
            Some("TEMP") => {
                match words.next().and_then(|w| w.parse::<f64>().ok()).filter(|v| v.is_finite()) {
                    Some(setpoint_c) => Ok(Reply::Temp { setpoint_c }),
                    None => Err(format!("`{shown}`: expected TEMP <setpoint_c>")),
                }
            }
            Some("AT") => {
                let rest: Vec<&str> = words.collect();
                let moving = match rest.get(2) {
                    Some(&"MOVING") => true,
                    Some(&"STILL") => false,
                    _ => return Err(format!("`{shown}`: expected AT <alpha> <beta> MOVING|STILL")),
                };
                let (alpha_deg, beta_deg) = angles(rest.into_iter(), "AT")?;
                Ok(Reply::At { alpha_deg, beta_deg, moving })
            }
            _ => Err(format!("unexpected reply `{shown}` from the head")),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lines_round_trip() {
        for r in [
            Request::Move { alpha_deg: 30.0, beta_deg: -90.0 },
            Request::Where,
            Request::Chamber { temp_c: -10.5 },
            Request::Temp,
            Request::Hello,
            Request::Home,
            Request::Stop,
        ] {
            assert_eq!(Request::parse(&r.line()), Ok(r));
        }
        for r in [
            Reply::Ok { alpha_deg: 0.0, beta_deg: 60.5 },
            Reply::At { alpha_deg: 12.25, beta_deg: -3.0, moving: true },
            Reply::At { alpha_deg: 0.0, beta_deg: 0.0, moving: false },
            Reply::Err("no such angle".into()),
            Reply::Temp { setpoint_c: 50.0 },
            Reply::Hello { version: 2, ident: "accelcal emulated head 0.1".into() },
        ] {
            assert_eq!(Reply::parse(&r.line()), Ok(r));
        }
        assert!(Request::parse("MOVE 1 nan").is_err());
        assert!(Request::parse("JUMP").is_err());
        assert!(Request::parse("CHAMBER 400").is_err() && Request::parse("CHAMBER").is_err());
        assert!(Reply::parse("AT 1 2").is_err());
        assert!(Reply::parse("HELLO two").is_err());
        // An identification is shown escaped and cut.
        let long = format!("HELLO 2 evil\x1b[2J{}", "x".repeat(500));
        match Reply::parse(&long) {
            Ok(Reply::Hello { version: 2, ident }) => {
                assert!(ident.starts_with(r"evil\x1b[2J") && ident.chars().count() == MAX_IDENT, "{ident}")
            }
            r => panic!("{r:?}"),
        }
    }
}
