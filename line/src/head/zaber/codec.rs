//! Zaber's ASCII protocol, the messages both ends of this crate speak: the driver
//! ([`super::ZaberHead`]) and the emulated stage (`crate::emulate::zaber`). Section names are those
//! of Zaber's *ASCII Protocol Manual* (firmware 7; the firmware 6 manual has the same message
//! format).
//!
//! - *Message Format § Commands*: `/D A command data` (device 1..=99, 0 all; axis 0..=9, 0 the
//!   device), ended by a line feed (a carriage return before it is allowed).
//! - *Message Format § Replies*: `@DD A [ID] FLAG STATUS WARNING DATA`: `FLAG` `OK` or `RJ`
//!   (rejected, `DATA` says why), `STATUS` `IDLE` or `BUSY`, `WARNING` the axis's most severe
//!   warning flag or `--`. *§ Info Messages* (`#DD A …`) and *§ Alerts* (`!DD A STATUS
//!   WARNING`) come unasked; the driver skips them.
//! - *Message Format § Checksums*: an optional `:XX` after the message, two hexadecimal digits:
//!   the two's complement of the sum, modulo 256, of the bytes after the message's type character
//!   and before the colon, so that the sum plus the checksum is 0 modulo 256.
//! - *Warning Flags*: two letters, the first the class: `F` a fault (the axis cannot be trusted
//!   to move: stall, driver disabled, encoder error…), `W` a warning, `N` a notice.
//!
//! Parsing takes any bytes and never panics: what a peer sent is shown escaped
//! ([`escape_peer`]) in every refusal.

use accelcal_core::text::escape_peer;

/// An axis on a chain of Zaber devices: device number (1..=99) and axis number (1..=9), written
/// `D/A`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Address {
    /// Device number, 1..=99 (*Message Format § Commands*).
    pub device: u8,
    /// Axis number on the device, 1..=9 (0 is the device itself).
    pub axis: u8,
}

impl std::str::FromStr for Address {
    type Err = String;
    fn from_str(s: &str) -> Result<Address, String> {
        let bad = || format!("`{s}`: expected DEVICE/AXIS, a device 1..=99 and an axis 1..=9 (as `1/1`)");
        let (d, a) = s.split_once('/').ok_or_else(bad)?;
        let device = d.parse::<u8>().ok().filter(|d| (1..=99).contains(d)).ok_or_else(bad)?;
        let axis = a.parse::<u8>().ok().filter(|a| (1..=9).contains(a)).ok_or_else(bad)?;
        Ok(Address { device, axis })
    }
}

impl std::fmt::Display for Address {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}/{}", self.device, self.axis)
    }
}

/// The checksum of a message's body (*Message Format § Checksums*).
pub fn checksum(body: &[u8]) -> u8 {
    let sum = body.iter().fold(0u8, |s, &b| s.wrapping_add(b));
    sum.wrapping_neg()
}

/// A command's line to `device`/`axis` (axis 0: the device), with its newline.
pub fn command(device: u8, axis: u8, text: &str) -> String {
    if text.is_empty() {
        format!("/{device} {axis}\n")
    } else {
        format!("/{device} {axis} {text}\n")
    }
}

/// A command as a device receives it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Command {
    /// Device number, 0 for all.
    pub device: u8,
    /// Axis number, 0 for the device (or all its axes).
    pub axis: u8,
    /// Message id, when given.
    pub id: Option<u8>,
    /// The command's words (`move abs 1000`), empty for a status poll.
    pub text: String,
}

/// Whether the reply accepts the command.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Flag {
    /// `OK`.
    Ok,
    /// `RJ`: rejected.
    Rejected,
}

/// A reply's (or alert's) axis status.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Status {
    /// `IDLE`: not moving.
    Idle,
    /// `BUSY`: moving.
    Busy,
}

/// A message from a device.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Message {
    /// `@`: the reply to a command.
    Reply(Reply),
    /// `#`: an info message (a command's extra lines, `help`'s text).
    Info {
        /// Device number.
        device: u8,
        /// Axis number.
        axis: u8,
    },
    /// `!`: an alert (a move finished while `comm.alert` is on).
    Alert {
        /// Device number.
        device: u8,
        /// Axis number.
        axis: u8,
    },
}

/// A reply (*Message Format § Replies*).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Reply {
    /// Device number.
    pub device: u8,
    /// Axis number (0 for the device).
    pub axis: u8,
    /// Message id, when the command had one.
    pub id: Option<u8>,
    /// `OK` or `RJ`.
    pub flag: Flag,
    /// `IDLE` or `BUSY`.
    pub status: Status,
    /// The most severe warning flag (two letters), None for `--`.
    pub warning: Option<[u8; 2]>,
    /// The data: the answer to `get`, the reason of an `RJ`, `0` otherwise.
    pub data: String,
}

impl Reply {
    /// The reply's line, with `\r\n` (and a checksum when `with_checksum`).
    pub fn line(&self, with_checksum: bool) -> String {
        let flag = match self.flag {
            Flag::Ok => "OK",
            Flag::Rejected => "RJ",
        };
        let status = match self.status {
            Status::Idle => "IDLE",
            Status::Busy => "BUSY",
        };
        let warning = self.warning.map(|w| String::from_utf8_lossy(&w).into_owned()).unwrap_or("--".into());
        let id = self.id.map(|i| format!(" {i}")).unwrap_or_default();
        let body = format!("{:02} {}{id} {flag} {status} {warning} {}", self.device, self.axis, self.data);
        if with_checksum {
            format!("@{body}:{:02X}\r\n", checksum(body.as_bytes()))
        } else {
            format!("@{body}\r\n")
        }
    }

    /// The warning flag as text (`--` for none).
    pub fn warning_text(&self) -> String {
        self.warning.map(|w| String::from_utf8_lossy(&w).into_owned()).unwrap_or_else(|| "--".into())
    }
}

/// Splits off and checks a trailing `:XX` checksum (the body is the message after its type
/// character).
fn strip_checksum<'a>(body: &'a str, shown: &str) -> Result<&'a str, String> {
    let Some((msg, cs)) = body.rsplit_once(':') else { return Ok(body) };
    let ok_digits = cs.len() == 2 && cs.bytes().all(|b| b.is_ascii_hexdigit());
    let Some(cs) = ok_digits.then(|| u8::from_str_radix(cs, 16).ok()).flatten() else {
        return Err(format!("`{shown}`: a checksum must be two hexadecimal digits after `:`"));
    };
    if checksum(msg.as_bytes()) != cs {
        return Err(format!("`{shown}`: bad checksum (expected {:02X})", checksum(msg.as_bytes())));
    }
    Ok(msg)
}

fn number<T: std::str::FromStr>(w: Option<&str>, what: &str, shown: &str) -> Result<T, String> {
    w.filter(|w| w.bytes().all(|b| b.is_ascii_digit()))
        .and_then(|w| w.parse::<T>().ok())
        .ok_or_else(|| format!("`{shown}`: expected the {what} number"))
}

/// Parses one line a device sent (its line end removed or not): a reply, an info message or an
/// alert.
pub fn parse_message(line: &[u8]) -> Result<Message, String> {
    let shown = escape_peer(line.trim_ascii());
    let Ok(text) = std::str::from_utf8(line.trim_ascii()) else {
        return Err(format!("`{shown}`: not ASCII text"));
    };
    if !text.is_ascii() || text.bytes().any(|b| b.is_ascii_control() && b != b'\t') {
        return Err(format!("`{shown}`: not printable ASCII text"));
    }
    let mut chars = text.chars();
    let kind = chars.next();
    let body = strip_checksum(chars.as_str(), &shown)?;
    let mut words = body.split_ascii_whitespace();
    let device: u8 = number(words.next(), "device", &shown)?;
    let axis: u8 = number(words.next(), "axis", &shown)?;
    match kind {
        Some('#') => Ok(Message::Info { device, axis }),
        Some('!') => Ok(Message::Alert { device, axis }),
        Some('@') => {
            let mut next = words.next();
            // An optional message id before the flag.
            let id = match next {
                Some(w) if w.bytes().all(|b| b.is_ascii_digit()) => {
                    let id = number::<u8>(Some(w), "message id", &shown)?;
                    next = words.next();
                    Some(id)
                }
                _ => None,
            };
            let flag = match next {
                Some("OK") => Flag::Ok,
                Some("RJ") => Flag::Rejected,
                _ => return Err(format!("`{shown}`: expected the reply flag OK or RJ")),
            };
            let status = match words.next() {
                Some("IDLE") => Status::Idle,
                Some("BUSY") => Status::Busy,
                _ => return Err(format!("`{shown}`: expected the status IDLE or BUSY")),
            };
            let warning = match words.next() {
                Some("--") => None,
                Some(w) if w.len() == 2 && w.bytes().all(|b| b.is_ascii_uppercase()) => {
                    Some([w.as_bytes()[0], w.as_bytes()[1]])
                }
                _ => return Err(format!("`{shown}`: expected a warning flag (two capitals or --)")),
            };
            let data = words.collect::<Vec<_>>().join(" ");
            Ok(Message::Reply(Reply { device, axis, id, flag, status, warning, data }))
        }
        _ => Err(format!("`{shown}`: not a Zaber reply (`@`), info (`#`) or alert (`!`)")),
    }
}

/// Parses a command line as a device receives it (*Message Format § Commands*): `/`, then
/// optionally the device, the axis and a message id, then the command's words; an optional
/// checksum is checked.
pub fn parse_command(line: &[u8]) -> Result<Command, String> {
    let shown = escape_peer(line.trim_ascii());
    let printable = |t: &&str| t.is_ascii() && !t.bytes().any(|b| b.is_ascii_control() && b != b'\t');
    let Some(text) = std::str::from_utf8(line.trim_ascii()).ok().filter(printable) else {
        return Err(format!("`{shown}`: not ASCII text"));
    };
    let Some(body) = text.strip_prefix('/') else {
        return Err(format!("`{shown}`: a command begins with `/`"));
    };
    let body = strip_checksum(body, &shown)?;
    let mut words = body.split_ascii_whitespace().peekable();
    let mut nums = Vec::new();
    while nums.len() < 3 {
        match words.peek() {
            Some(w) if w.bytes().all(|b| b.is_ascii_digit()) => {
                nums.push(number::<u8>(words.next(), "device, axis or message id", &shown)?);
            }
            _ => break,
        }
    }
    let text = words.collect::<Vec<_>>().join(" ");
    let (device, axis, id) = match nums[..] {
        [] => (0, 0, None),
        [d] => (d, 0, None),
        [d, a] => (d, a, None),
        [d, a, i] => (d, a, Some(i)),
        _ => unreachable!("at most three numbers are taken"),
    };
    Ok(Command { device, axis, id, text })
}

/// What a warning flag means for a move (*Warning Flags*).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Severity {
    /// The axis cannot be trusted: every `F` flag, and `WL` (a limit sensor stopped a move).
    Fault,
    /// `WH`/`WR`: the axis has no reference position; it must be homed.
    NotHomed,
    /// Anything else: a warning or a notice the move can live with (`NI`: a command was
    /// interrupted, as a `stop` does; `WT`: the controller runs warm).
    Benign,
}

/// The flag's class and its meaning in words (*Warning Flags*).
pub fn warning(flag: [u8; 2]) -> (Severity, &'static str) {
    match &flag {
        b"FD" => (Severity::Fault, "driver disabled"),
        b"FQ" => (Severity::Fault, "encoder error"),
        b"FS" => (Severity::Fault, "stalled and stopped"),
        b"FT" => (Severity::Fault, "excessive twist"),
        b"FB" => (Severity::Fault, "stream bounds error"),
        b"FP" => (Severity::Fault, "interpolated path deviation"),
        b"FE" => (Severity::Fault, "limit error"),
        b"FM" => (Severity::Fault, "unexpected limit trigger"),
        b"FO" => (Severity::Fault, "driver overheated or voltage out of range"),
        b"FH" => (Severity::Fault, "hardware emergency stop"),
        b"FV" => (Severity::Fault, "current inrush error"),
        b"FF" => (Severity::Fault, "critical system error"),
        b"WL" => (Severity::Fault, "unexpected limit trigger: a limit sensor stopped the move"),
        b"WH" => (Severity::NotHomed, "not homed"),
        b"WR" => (Severity::NotHomed, "no reference position"),
        [b'F', _] => (Severity::Fault, "a fault"),
        [b'W', _] => (Severity::Benign, "a warning"),
        _ => (Severity::Benign, "a notice"),
    }
}

/// The flag in words for a message: `FS (stalled and stopped)`.
pub fn warning_words(flag: [u8; 2]) -> String {
    format!("{} ({})", escape_peer(&flag), warning(flag).1)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn reply(line: &str) -> Reply {
        match parse_message(line.as_bytes()) {
            Ok(Message::Reply(r)) => r,
            other => panic!("{line}: {other:?}"),
        }
    }

    #[test]
    fn replies_parse_with_and_without_id_and_checksum() {
        let r = reply("@01 1 OK IDLE -- 0\r\n");
        assert_eq!(
            r,
            Reply {
                device: 1,
                axis: 1,
                id: None,
                flag: Flag::Ok,
                status: Status::Idle,
                warning: None,
                data: "0".into()
            }
        );
        let r = reply("@02 1 12 RJ BUSY WH BADDATA");
        assert_eq!(
            (r.device, r.axis, r.id, r.flag, r.status),
            (2, 1, Some(12), Flag::Rejected, Status::Busy)
        );
        assert_eq!((r.warning, r.data.as_str()), (Some(*b"WH"), "BADDATA"));
        let r = reply("@01 0 OK IDLE -- 30341");
        assert_eq!((r.axis, r.data.as_str()), (0, "30341"));
        // The manual's warnings list: a count and the flags.
        assert_eq!(reply("@01 1 OK IDLE WH 02 WH NI").data, "02 WH NI");
        assert!(matches!(parse_message(b"#01 1 some help text"), Ok(Message::Info { device: 1, axis: 1 })));
        assert!(matches!(parse_message(b"!02 1 IDLE --"), Ok(Message::Alert { device: 2, axis: 1 })));
    }

    #[test]
    fn checksums_round_trip_and_bad_ones_are_refused() {
        for r in [
            reply("@01 1 OK IDLE -- 0"),
            reply("@02 1 3 RJ BUSY FS BADDATA"),
            reply("@01 1 OK IDLE WH 02 WH NI"),
        ] {
            let line = r.line(true);
            let (body, cs) = line.trim_end()[1..].rsplit_once(':').unwrap();
            let sum = body.bytes().fold(0u32, |s, b| s + b as u32) + u32::from_str_radix(cs, 16).unwrap();
            assert_eq!(sum % 256, 0, "{line}");
            assert_eq!(reply(&line), r);
            assert_eq!(reply(&r.line(false)), r);
        }
        let e = parse_message(b"@01 1 OK IDLE -- 0:00").unwrap_err();
        assert!(e.contains("bad checksum"), "{e}");
        assert!(parse_message(b"@01 1 OK IDLE -- 0:G1").unwrap_err().contains("two hexadecimal digits"));
        let c = parse_command(format!("/1 1 move abs 10:{:02X}", checksum(b"1 1 move abs 10")).as_bytes());
        assert_eq!(c.unwrap().text, "move abs 10");
        assert!(parse_command(b"/1 1 move abs 10:00").is_err());
    }

    #[test]
    fn commands_parse_device_axis_and_id() {
        let c = |s: &str| parse_command(s.as_bytes()).unwrap();
        assert_eq!(
            c("/1 1 move abs 1000\n"),
            Command { device: 1, axis: 1, id: None, text: "move abs 1000".into() }
        );
        assert_eq!(c("/2 1\r\n"), Command { device: 2, axis: 1, id: None, text: String::new() });
        assert_eq!(c("/"), Command { device: 0, axis: 0, id: None, text: String::new() });
        assert_eq!(
            c("/1 get device.id"),
            Command { device: 1, axis: 0, id: None, text: "get device.id".into() }
        );
        assert_eq!(c("/1 1 7 get pos").id, Some(7));
        assert_eq!(command(1, 1, "home"), "/1 1 home\n");
        assert_eq!(command(2, 1, ""), "/2 1\n");
    }

    #[test]
    fn warning_flags_are_classed() {
        assert_eq!(warning(*b"FS").0, Severity::Fault);
        assert_eq!(warning(*b"FX").0, Severity::Fault);
        assert_eq!(warning(*b"WL").0, Severity::Fault);
        assert_eq!(warning(*b"WH").0, Severity::NotHomed);
        assert_eq!(warning(*b"NI").0, Severity::Benign);
        assert_eq!(warning_words(*b"FD"), "FD (driver disabled)");
    }

    #[test]
    fn bad_bytes_are_refused_escaped_and_never_panic() {
        for line in [
            &b""[..],
            b"@",
            b"@01",
            b"@01 1",
            b"@01 1 OK",
            b"@01 1 OK IDLE",
            b"@01 1 OK IDLE W",
            b"@1000 1 OK IDLE -- 0",
            b"@01 1 999 OK IDLE -- 0",
            b"@01 1 MAYBE IDLE -- 0",
            b"@01 1 OK NAP -- 0",
            b"@01 1 OK IDLE wh 0",
            b"@01 1 OK IDLE -- 0:",
            b"@01 1 OK IDLE -- 0:\xff\xff",
            b"\x1b]0;pwned\x07",
            b"@01 1 OK IDLE \xc3\xa9\xc3\xa9 0",
            b"@01 \xff OK IDLE -- 0",
            b"::::",
            b"/1 1",
        ] {
            let e = parse_message(line).unwrap_err();
            assert!(!e.contains(['\u{1b}', '\u{7}']), "{e}");
        }
        // Arbitrary bytes, every prefix of a good reply with noise: no panic.
        let good = b"@01 1 12 OK IDLE WH 02 WH NI:00";
        for cut in 0..=good.len() {
            for noise in [0u8, b':', b' ', 0xff, b'@', b'/'] {
                let mut l = good[..cut].to_vec();
                l.push(noise);
                let _ = parse_message(&l);
                let _ = parse_command(&l);
            }
        }
        assert!(parse_command(b"/1 1 300 get pos").is_err());
        assert!(parse_command(b"move").is_err());
    }
}
