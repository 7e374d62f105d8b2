//! The one escaper of `serve`'s pages (`host/askama.toml` names it for every `.html` template):
//! askama's HTML escaping, and no control character (C0, DEL, C1) nor Unicode format character
//! (zero-width, bidi controls: general category Cf) nor line or paragraph separator reaches a
//! page. Each is written as the visible text `\u{1b}`, so a serial or a URL that holds one is
//! shown as what it is rather than acted upon by a browser or a terminal that a page is piped to.
//! The charts' SVG (`|safe`) and a stored certificate (served as issued) go through [`markup`].

use std::fmt::{self, Write};

use unicode_properties::{GeneralCategory, UnicodeGeneralCategory};

/// Whether `c` may not be written into a page as it is.
pub fn hidden(c: char) -> bool {
    c.is_control()
        || matches!(
            c.general_category(),
            GeneralCategory::Format | GeneralCategory::LineSeparator | GeneralCategory::ParagraphSeparator
        )
}

/// askama's HTML escaper with every [`hidden`] character written as `\u{…}`.
#[derive(Debug, Clone, Copy, Default)]
pub struct Html;

impl askama::filters::Escaper for Html {
    fn write_escaped_str<W: Write>(&self, mut dest: W, string: &str) -> fmt::Result {
        let mut rest = string;
        while let Some(at) = rest.find(hidden) {
            askama::filters::Html.write_escaped_str(&mut dest, &rest[..at])?;
            let c = rest[at..].chars().next().unwrap_or_default();
            write!(dest, "\\u{{{:x}}}", u32::from(c))?;
            rest = &rest[at + c.len_utf8()..];
        }
        askama::filters::Html.write_escaped_str(dest, rest)
    }
}

/// Markup served as it was written: a chart's SVG, which plotters wrote (escaping its text) and a
/// template writes as it is, and a stored certificate (its customer's name, its serial, …, were
/// escaped when the page was made, but not of control characters). Every [`hidden`] character
/// but the tab, line feed and carriage return of its layout written as `\u{…}`.
pub fn markup(s: String) -> String {
    if !s.chars().any(|c| hidden(c) && !matches!(c, '\t' | '\n' | '\r')) {
        return s;
    }
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        if hidden(c) && !matches!(c, '\t' | '\n' | '\r') {
            let _ = write!(out, "\\u{{{:x}}}", u32::from(c));
        } else {
            out.push(c);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use askama::filters::Escaper;

    fn escaped(s: &str) -> String {
        let mut out = String::new();
        Html.write_escaped_str(&mut out, s).unwrap();
        out
    }

    #[test]
    fn controls_and_format_characters_are_shown_as_text() {
        assert_eq!(escaped("no unit `\0`"), "no unit `\\u{0}`");
        assert_eq!(escaped("\u{1b}[2J<b>"), "\\u{1b}[2J&#60;b&#62;");
        assert_eq!(escaped("A\u{200b}B\u{202e}C\u{85}D\u{2028}"), "A\\u{200b}B\\u{202e}C\\u{85}D\\u{2028}");
        assert_eq!(escaped("tab\there\nline\u{7f}"), "tab\\u{9}here\\u{a}line\\u{7f}");
        assert_eq!(escaped("Müller & Söhne 名前"), "Müller &#38; Söhne 名前");
    }

    #[test]
    fn an_svg_keeps_its_layout_and_loses_its_controls() {
        let s = "<svg>\n\t<text>A\u{1b}B\u{feff}</text>\r\n</svg>".to_string();
        assert_eq!(markup(s), "<svg>\n\t<text>A\\u{1b}B\\u{feff}</text>\r\n</svg>");
        assert_eq!(markup("<svg/>".into()), "<svg/>");
    }
}
