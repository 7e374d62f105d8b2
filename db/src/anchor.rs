//! Anchors: chain heads kept outside the database, so that a database rewritten or cut short
//! behind accelcal's back is found. The hash chain alone ([`crate::chain`]) holds against an
//! edit of any row, but not against someone who rewrites the ledger from a row on, or deletes
//! its newest entries with their rows: what was there is then seen only against a chain value
//! kept elsewhere.
//!
//! One written form, [`Anchor::text`] (`accelcal-anchor seq=N chain_sha256=HEX`), is what every
//! place that keeps one writes: an anchor log (`--anchor-log FILE`, a line per new chain head
//! with its time), a certificate (the chain head at its issue), the station's journal. [`scan`]
//! finds it in any of those files, and `db verify --anchors` checks each against the ledger
//! ([`crate::Db::check_anchors`]).

use std::io::Write;
use std::path::{Path, PathBuf};

use serde::Serialize;

/// What marks an anchor in a text.
pub const MARK: &str = "accelcal-anchor";

/// A chain head: a ledger entry and its chain value.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct Anchor {
    /// The ledger entry.
    pub seq: i64,
    /// Its chain value (64 lower-case hex digits).
    pub chain_sha256: String,
}

impl Anchor {
    /// The written form, one token sequence without spaces but the two separators.
    pub fn text(&self) -> String {
        format!("{MARK} seq={} chain_sha256={}", self.seq, self.chain_sha256)
    }
}

/// Every anchor written in `text`, in order. A mark followed by anything but a well-formed
/// anchor is skipped (prose that names the mark, a line cut short).
pub fn scan(text: &str) -> Vec<Anchor> {
    let mut out = Vec::new();
    let mut rest = text;
    while let Some(i) = rest.find(MARK) {
        rest = &rest[i + MARK.len()..];
        if let Some(a) = parse_after_mark(rest) {
            out.push(a);
        }
    }
    out
}

fn parse_after_mark(s: &str) -> Option<Anchor> {
    let s = s.strip_prefix(" seq=")?;
    let digits = s.bytes().take_while(u8::is_ascii_digit).count();
    if digits == 0 || digits > 18 {
        return None;
    }
    let seq: i64 = s[..digits].parse().ok()?;
    let s = s[digits..].strip_prefix(" chain_sha256=")?;
    let hex = s.get(..64)?;
    if !hex.bytes().all(|b| b.is_ascii_digit() || (b'a'..=b'f').contains(&b)) {
        return None;
    }
    // The value ends there: a longer run of hex digits is not a SHA-256.
    if s[64..].bytes().next().is_some_and(|b| b.is_ascii_hexdigit()) {
        return None;
    }
    (seq > 0).then(|| Anchor { seq, chain_sha256: hex.to_string() })
}

/// An anchor log: a file a writing command appends each new chain head to.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct AnchorLog {
    path: PathBuf,
}

/// A failure to read or append to an anchor log.
#[derive(Debug, thiserror::Error)]
#[error("anchor log {}: {cause}", path.display())]
pub struct AnchorLogError {
    /// The log.
    pub path: PathBuf,
    /// What failed.
    pub cause: String,
}

impl accelcal_core::error::Classify for AnchorLogError {
    fn kind(&self) -> accelcal_core::error::Kind {
        accelcal_core::error::Kind::Environment
    }
}

impl AnchorLog {
    /// The log at `path` (created by the first append).
    pub fn new(path: impl Into<PathBuf>) -> AnchorLog {
        AnchorLog { path: path.into() }
    }

    /// Its path.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The anchors it holds, oldest first (none when the file does not exist yet).
    pub fn read(&self) -> Result<Vec<Anchor>, AnchorLogError> {
        match std::fs::read(&self.path) {
            Ok(b) => Ok(scan(&String::from_utf8_lossy(&b))),
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(Vec::new()),
            Err(e) => Err(self.failed(e)),
        }
    }

    /// Appends `a` with its time (UTC, RFC 3339) as one line, and syncs it to the disk.
    pub fn append(&self, a: &Anchor, unix_s: i64) -> Result<(), AnchorLogError> {
        let time = jiff::Timestamp::from_second(unix_s).map(|t| t.to_string()).unwrap_or_default();
        let mut f = std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .open(&self.path)
            .map_err(|e| self.failed(e))?;
        f.write_all(format!("{time} {}\n", a.text()).as_bytes())
            .and_then(|()| f.sync_data())
            .map_err(|e| self.failed(e))
    }

    fn failed(&self, e: std::io::Error) -> AnchorLogError {
        AnchorLogError { path: self.path.clone(), cause: e.to_string() }
    }
}

/// What [`crate::Db::check_anchors`] found of one anchor.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct AnchorFinding {
    /// Where the anchor was read.
    pub source: String,
    /// The anchor.
    pub anchor: Anchor,
    /// `None` when the ledger holds it at its place; else what is wrong.
    pub problem: Option<String>,
}

#[cfg(test)]
mod tests {
    use super::*;

    const H: &str = "0123456789abcdef0123456789abcdef0123456789abcdef0123456789abcdef";

    #[test]
    fn the_written_form_is_found_again_in_any_text() {
        let a = Anchor { seq: 42, chain_sha256: H.into() };
        let html = format!("<p>Ledger: <code>{}</code></p>\n2026-12-07T04:00:00Z {}\n", a.text(), a.text());
        assert_eq!(scan(&html), vec![a.clone(), a]);
    }

    #[test]
    fn malformed_anchors_are_skipped() {
        for t in [
            "accelcal-anchor",
            "accelcal-anchor seq= chain_sha256=",
            &format!("accelcal-anchor seq=0 chain_sha256={H}"),
            &format!("accelcal-anchor seq=1 chain_sha256={}", &H[..63]),
            &format!("accelcal-anchor seq=1 chain_sha256={H}0"),
            &format!("accelcal-anchor seq=1 chain_sha256={}", H.to_uppercase()),
            &format!("accelcal-anchor seq=99999999999999999999 chain_sha256={H}"),
        ] {
            assert!(scan(t).is_empty(), "{t}");
        }
    }

    #[test]
    fn a_log_appends_lines_and_reads_them_back() {
        let d = tempfile::tempdir().unwrap();
        let log = AnchorLog::new(d.path().join("anchors.log"));
        assert!(log.read().unwrap().is_empty());
        let a = Anchor { seq: 1, chain_sha256: H.into() };
        let b = Anchor { seq: 7, chain_sha256: H.replace('0', "f") };
        log.append(&a, 1_767_225_600).unwrap();
        log.append(&b, 1_767_225_601).unwrap();
        let text = std::fs::read_to_string(log.path()).unwrap();
        assert!(text.starts_with("2026-01-01T00:00:00Z accelcal-anchor seq=1 "), "{text}");
        assert_eq!(log.read().unwrap(), vec![a, b]);
    }
}
