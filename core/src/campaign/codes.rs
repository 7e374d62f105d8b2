//! The range of a campaign's raw codes ([`CodeRange`]) and the `# codes:` comment line that states
//! it in a file, read before the header row.

use std::io::{BufRead, BufReader, Read};
use std::path::Path;

use super::CampaignError;

/// The range of a campaign's raw codes: what a saturated channel reads and what cannot be a code.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum CodeRange {
    /// A 16-bit ADC: 0..=65535; 0 and 65535 are what a saturated input reads.
    #[default]
    Unsigned16,
    /// The two's-complement counts of a digital MEMS: −32768..=32767; both ends are saturation.
    Signed16,
}

impl CodeRange {
    /// Every range, in the order the help lists them.
    pub const ALL: [CodeRange; 2] = [CodeRange::Unsigned16, CodeRange::Signed16];

    /// The name used in files and on the command line.
    pub fn name(self) -> &'static str {
        match self {
            CodeRange::Unsigned16 => "unsigned16",
            CodeRange::Signed16 => "signed16",
        }
    }

    /// The two rails (saturation codes), low and high.
    pub fn rails(self) -> (f64, f64) {
        match self {
            CodeRange::Unsigned16 => (0.0, 65535.0),
            CodeRange::Signed16 => (-32768.0, 32767.0),
        }
    }

    /// Whether a raw code is usable: strictly between the rails (a code at a rail is saturated,
    /// one beyond them is not a code of this range).
    pub fn usable(self, v: f64) -> bool {
        let (lo, hi) = self.rails();
        v > lo && v < hi
    }

    /// What an unusable code is, for messages: `saturated (0 or 65535) or outside the unsigned16
    /// range`.
    pub fn unusable(self) -> String {
        let (lo, hi) = self.rails();
        format!("saturated ({lo} or {hi}) or outside the {} range", self.name())
    }
}

impl std::fmt::Display for CodeRange {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for CodeRange {
    type Err = String;

    fn from_str(s: &str) -> Result<CodeRange, String> {
        CodeRange::ALL.into_iter().find(|c| c.name() == s).ok_or_else(|| {
            format!(
                "unknown code range `{s}` (expected {})",
                CodeRange::ALL.map(CodeRange::name).join(" or ")
            )
        })
    }
}

/// The comment line that states a campaign's code range: `# codes: signed16`.
pub const CODES_COMMENT: &str = "codes:";
/// The header key of that line.
pub const CODES_KEY: &str = "codes";

/// The code range a `# codes:` line states, and the line.
pub(super) type Stated = Option<(u64, CodeRange)>;

/// What the comment lines before a campaign's header row say.
#[derive(Debug, Default)]
pub(super) struct HeaderComments {
    /// Their bytes, to be read again by the CSV layer so that it counts lines from the start of
    /// the file.
    pub prefix: Vec<u8>,
    /// The code range a `# codes:` line states, with its line.
    pub stated: Stated,
    /// Every `# key: value` line (trimmed), in file order: what `acquire` and `simulate` write
    /// there (device id, serial, firmware, g, plan, ...).
    pub values: Vec<(String, String)>,
}

/// Reads the comment and blank lines before the header row: the one reader of a campaign's
/// header comments, used by the row reader and by [`super::header`]. Nothing past them is
/// consumed. A second line with one of accelcal's keys ([`super::HEADER_KEYS`]: two `# device_id:`
/// or two `# g_m_s2:` lines) is refused, naming both lines: which of them the file means cannot be
/// told, and a header with both was forged or spliced.
pub(super) fn header_comments<R: Read>(
    reader: &mut BufReader<R>,
    path: &Path,
) -> Result<HeaderComments, CampaignError> {
    let io = |cause| CampaignError::Io { path: path.to_owned(), cause };
    let mut out = HeaderComments::default();
    // accelcal's keys seen so far, with their lines.
    let mut lines: Vec<(String, u64)> = Vec::new();
    let mut line = 0u64;
    loop {
        match reader.fill_buf().map_err(io)?.first() {
            Some(b'#' | b'\n' | b'\r') => {}
            _ => return Ok(out),
        }
        let start = out.prefix.len();
        reader.read_until(b'\n', &mut out.prefix).map_err(io)?;
        line += 1;
        let text = String::from_utf8_lossy(&out.prefix[start..]);
        let Some((key, value)) = text.strip_prefix('#').and_then(|c| c.split_once(':')) else {
            continue;
        };
        let (key, value) = (key.trim(), value.trim());
        let at = |msg| CampaignError::Line { path: path.to_owned(), line, msg };
        if super::HEADER_KEYS.contains(&key) {
            if let Some(first) = lines.iter().find(|(k, _)| *k == key).map(|(_, l)| *l) {
                return Err(at(format!("a second `# {key}:` line (the first is line {first})")));
            }
            lines.push((key.to_string(), line));
        }
        out.values.push((key.to_string(), value.to_string()));
        if key != CODES_KEY {
            continue;
        }
        let codes: CodeRange = value.parse().map_err(|e| at(format!("`# {CODES_COMMENT}`: {e}")))?;
        out.stated = Some((line, codes));
    }
}
