//! Where the pages link: a unit, a run, a certificate, a head's or a station's charts, an asset
//! of the register. Every part of a path taken from the database is percent-encoded here.

use crate::app::attention::Page;

/// `s` as one segment of a path or a query's value: every byte but the unreserved characters of
/// RFC 3986 (letters, digits, `-`, `.`, `_`, `~`) percent-encoded.
pub fn segment(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for b in s.bytes() {
        if b.is_ascii_alphanumeric() || matches!(b, b'-' | b'.' | b'_' | b'~') {
            out.push(char::from(b));
        } else {
            out.push_str(&format!("%{b:02X}"));
        }
    }
    out
}

/// A unit's page, by its serial or device id.
pub fn unit(key: &str) -> String {
    format!("/unit/{}", segment(key))
}

/// A run's page: its row on its unit's page.
pub fn run(id: &str) -> String {
    format!("/run/{}", segment(id))
}

/// A certificate, by its number.
pub fn certificate(number: &str) -> String {
    format!("/certificate/{}", segment(number))
}

/// Where `page` is; a page of charts over `period` (`since=…&until=…`).
pub fn href(page: &Page, period: &str) -> String {
    match page {
        Page::Asset(id) => format!("/#asset-{}", segment(id)),
        Page::HeadCharts(id) => format!("/charts?{period}&head_asset={}", segment(id)),
        Page::StationCharts(name) => format!("/charts?{period}&station={}", segment(name)),
        Page::Run(id) => run(id),
        Page::Certificate(n) => certificate(n),
        Page::Assets => "/#assets".into(),
        Page::Charts => format!("/charts?{period}"),
        Page::Fleet => format!("/fleet?{period}"),
        Page::Recalls => "/#recalls".into(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_segment_keeps_only_unreserved_characters() {
        assert_eq!(segment("SN-A1_x.y~"), "SN-A1_x.y~");
        assert_eq!(segment("a/b c?d#e&f"), "a%2Fb%20c%3Fd%23e%26f");
        assert_eq!(segment("<é>"), "%3C%C3%A9%3E");
        assert_eq!(href(&Page::StationCharts("st 1".into()), "since=a"), "/charts?since=a&station=st%201");
        assert_eq!(href(&Page::Asset("HEAD-1".into()), ""), "/#asset-HEAD-1");
    }
}
