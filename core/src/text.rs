//! Text values that are written into a line of a file or into the database (a serial number, an
//! operator, a station's name, a head, a path): what "a single-line text value" is, defined once.
//!
//! A value is one line of text when it holds no control character (`char::is_control`: NUL, tab,
//! line feed, carriage return, ESC, DEL, the C1 range with NEL) and no Unicode line or paragraph
//! separator (U+2028, U+2029). Such a value cannot end the line it is written into, so it cannot
//! add a line of its own (`--serial $'A\n# g_m_s2: 9.0'` would otherwise write a second
//! `# g_m_s2:` line into a campaign's header), nor send a terminal escape sequence when a message
//! or a table prints it.
//!
//! [`single_line`] is the check for any such value; [`header_value`] is the stricter one for the
//! value of a campaign's `# key: value` header line, which also refuses white space at either
//! end: the header reader trims the value (`#serial:U-1`, `# serial:  U-1 ` both say `U-1`), so a
//! padded value would not read back as written and `U-1 ` and `U-1` would be two units in the
//! database but one in the campaign. Every writer of such a value calls one of them (the command
//! line's values in `accelcal`'s settings, the campaign header writers
//! [`crate::campaign::header_line`], the database's run fields), and so must a reader of a
//! station configuration file.

use crate::error::{Classify, Kind};

/// A text value that cannot be written where it was meant to go. The message names the field,
/// shows the value escaped (`"A\n# g_m_s2: 9.0"`) and where the offending character is.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum TextError {
    /// The value holds a control character or a line separator.
    #[error(
        "{field}: {value:?} holds a control character (U+{code:04X}) at character {at}: a text value must be \
         one line without control characters",
        code = u32::from(*ch)
    )]
    Control {
        /// The field (an option as it is spelled, a header key, a column).
        field: String,
        /// The whole value.
        value: String,
        /// The offending character.
        ch: char,
        /// Its position, in characters from 1.
        at: usize,
    },
    /// The value holds a Unicode format character (general category Cf: a zero-width character,
    /// a bidi control), which displays as nothing or reorders the text around it.
    #[error(
        "{field}: {value:?} holds the invisible format character U+{code:04X} at character {at} (zero-width \
         characters and bidi controls are refused: two values that differ would display the same)",
        code = u32::from(*ch)
    )]
    Format {
        /// The field.
        field: String,
        /// The whole value.
        value: String,
        /// The offending character.
        ch: char,
        /// Its position, in characters from 1.
        at: usize,
    },
    /// A header value with white space at one end, which the header reader would not keep.
    #[error(
        "{field}: {value:?} begins or ends with white space, which a campaign's `# key: value` line does not \
         keep (it would read back as {trimmed:?})",
        trimmed = value.trim()
    )]
    Padded {
        /// The field.
        field: String,
        /// The whole value.
        value: String,
    },
}

impl Classify for TextError {
    fn kind(&self) -> Kind {
        Kind::BadInput
    }
}

/// Whether `c` would end or break a line: a control character or a line/paragraph separator.
fn breaks_line(c: char) -> bool {
    c.is_control() || c == '\u{2028}' || c == '\u{2029}'
}

/// `value`, when it is one line of text (no control character, no line separator) without a
/// Unicode format character ([`is_format`]: zero-width characters, bidi controls); otherwise a
/// [`TextError::Control`] or [`TextError::Format`] naming `field`, the value escaped and the
/// first offending character.
pub fn single_line<'v>(field: &str, value: &'v str) -> Result<&'v str, TextError> {
    let (field, owned) = (field.to_string(), value.to_string());
    match value.chars().enumerate().find(|&(_, c)| breaks_line(c) || is_format(c)) {
        None => Ok(value),
        Some((i, ch)) if breaks_line(ch) => Err(TextError::Control { field, value: owned, ch, at: i + 1 }),
        Some((i, ch)) => Err(TextError::Format { field, value: owned, ch, at: i + 1 }),
    }
}

/// `value`, when it can be the value of a campaign's `# key: value` header line: [`single_line`]
/// and no white space at either end (the reader trims it; see the module's documentation).
pub fn header_value<'v>(field: &str, value: &'v str) -> Result<&'v str, TextError> {
    single_line(field, value)?;
    if value.trim() != value {
        return Err(TextError::Padded { field: field.to_string(), value: value.to_string() });
    }
    Ok(value)
}

/// Bytes a peer sent (a head's reply, a GDB server's answer), as text that is safe to put into a
/// message or print: shown as they are, except an ASCII control character or a backslash as its
/// escape (`\x1b`, `\n`, `\\`), any other control character, line separator or format character
/// (a zero-width space, a bidi override) as `\u{202e}`, and a byte that is not UTF-8 as `\xNN`.
/// A peer cannot retitle or clear the operator's terminal, nor break the message's line.
pub fn escape_peer(bytes: &[u8]) -> String {
    use std::fmt::Write;
    let mut out = String::with_capacity(bytes.len());
    for chunk in bytes.utf8_chunks() {
        for c in chunk.valid().chars() {
            if c.is_ascii_control() || c == '\\' {
                out.extend(std::ascii::escape_default(c as u8).map(char::from));
            } else if breaks_line(c) || is_format(c) {
                out.extend(c.escape_unicode());
            } else {
                out.push(c);
            }
        }
        for b in chunk.invalid() {
            let _ = write!(out, "\\x{b:02x}");
        }
    }
    out
}

/// Whether `c` is a Unicode format character (general category Cf: the zero-width characters,
/// the bidi controls, the soft hyphen, the byte order mark...): invisible, or reordering the text
/// around it, so that two values that differ display the same.
pub fn is_format(c: char) -> bool {
    use unicode_properties::{GeneralCategory, UnicodeGeneralCategory};
    c.general_category() == GeneralCategory::Format
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_peer_s_bytes_are_shown_escaped() {
        assert_eq!(escape_peer(b"OK 1.5 -90"), "OK 1.5 -90");
        assert_eq!(escape_peer("Müller 名前".as_bytes()), "Müller 名前");
        let shown = escape_peer(b"\x1b]0;pwned\x07\x1b[2J");
        assert_eq!(shown, r"\x1b]0;pwned\x07\x1b[2J");
        assert!(!shown.contains('\u{1b}'));
        assert_eq!(escape_peer(b"a\r\nb\t\\"), r"a\r\nb\t\\");
        assert_eq!(escape_peer(b"\x00\x7f"), r"\x00\x7f");
        assert_eq!(escape_peer(b"A\xff\xfeB\xc3"), r"A\xff\xfeB\xc3");
        assert_eq!(
            escape_peer("a\u{202e}b\u{200b}c\u{9b}d\u{2028}".as_bytes()),
            r"a\u{202e}b\u{200b}c\u{9b}d\u{2028}"
        );
    }

    #[test]
    fn one_line_of_text_is_accepted_as_it_is() {
        for v in ["U-1", "", "Müller & Söhne: rig 2", "/tmp/a b/c.csv", "  padded  ", "名前"] {
            assert_eq!(single_line("--serial", v), Ok(v));
        }
        assert_eq!(header_value("serial", "U 1: A"), Ok("U 1: A"));
    }

    #[test]
    fn control_characters_and_line_separators_are_refused_naming_field_value_and_place() {
        let cases: &[(&str, char, usize)] = &[
            ("A\n# g_m_s2: 9.0", '\n', 2),
            ("A\r", '\r', 2),
            ("\tA", '\t', 1),
            ("A\0", '\0', 2),
            ("ab\u{1b}[31m", '\u{1b}', 3),
            ("A\u{7f}", '\u{7f}', 2),
            ("A\u{85}B", '\u{85}', 2),
            ("A\u{9b}B", '\u{9b}', 2),
            ("A\u{2028}B", '\u{2028}', 2),
            ("A\u{2029}B", '\u{2029}', 2),
        ];
        for &(v, ch, at) in cases {
            let e = single_line("--serial", v).unwrap_err();
            assert_eq!(e, TextError::Control { field: "--serial".into(), value: v.into(), ch, at });
            assert_eq!(header_value("--serial", v).unwrap_err(), e);
            assert_eq!(e.kind(), Kind::BadInput);
        }
        let e = single_line("--serial", "A\n# g_m_s2: 9.0").unwrap_err().to_string();
        assert_eq!(
            e,
            "--serial: \"A\\n# g_m_s2: 9.0\" holds a control character (U+000A) at character 2: a text value \
             must be one line without control characters"
        );
        assert_eq!(e.lines().count(), 1);
        // An escape sequence is shown escaped, never sent to the terminal.
        let e = single_line("--operator", "\u{1b}]0;x\u{7}").unwrap_err().to_string();
        assert!(e.contains(r#""\u{1b}]0;x\u{7}""#) && !e.contains('\u{1b}'), "{e}");
        let e = single_line("--station", "a\u{2028}b").unwrap_err().to_string();
        assert!(e.contains(r#""a\u{2028}b""#) && e.contains("U+2028"), "{e}");
    }

    /// Zero-width characters and bidi controls (general category Cf) are refused, naming the
    /// field and the character as U+XXXX; a visible non-ASCII character is not.
    #[test]
    fn format_characters_are_refused_naming_field_and_code_point() {
        let refused = [
            '\u{200b}', '\u{200c}', '\u{200d}', '\u{2060}', '\u{feff}', '\u{202a}', '\u{202b}', '\u{202c}',
            '\u{202d}', '\u{202e}', '\u{2066}', '\u{2067}', '\u{2068}', '\u{2069}', '\u{200e}', '\u{200f}',
            '\u{61c}', '\u{ad}',
        ];
        for ch in refused {
            let v = format!("SN{ch}1");
            let e = single_line("--serial", &v).unwrap_err();
            assert_eq!(e, TextError::Format { field: "--serial".into(), value: v.clone(), ch, at: 3 });
            assert_eq!(header_value("serial", &v).unwrap_err().kind(), Kind::BadInput);
            let words = e.to_string();
            assert!(
                words.starts_with("--serial: ") && words.contains(&format!("U+{:04X}", u32::from(ch))),
                "{words}"
            );
            assert!(!words.contains(ch), "{words}");
        }
        let e = single_line("--operator", "ana\u{202e}gnp.exe").unwrap_err().to_string();
        assert_eq!(
            e,
            "--operator: \"ana\\u{202e}gnp.exe\" holds the invisible format character U+202E at character 4 \
             (zero-width characters and bidi controls are refused: two values that differ would display the same)"
        );
        for v in ["Müller", "名前", "مختبر", "SN-1 ✓"] {
            assert_eq!(single_line("--operator", v), Ok(v));
        }
    }

    #[test]
    fn a_header_value_must_read_back_as_written() {
        for v in [" U-1", "U-1 ", "\u{a0}U-1"] {
            let e = header_value("serial", v).unwrap_err();
            assert_eq!(e, TextError::Padded { field: "serial".into(), value: v.into() });
            assert!(e.to_string().contains(r#"it would read back as "U-1""#), "{e}");
        }
    }
}
