//! Campaign files: the CSV that the rig (or the simulator) writes and every command reads.
//!
//! A header row names the columns. Required: `t_s` (seconds, non-decreasing), `alpha_deg`,
//! `beta_deg` (commanded head angles); optional `temp_c`; every other column is one ADC channel of
//! raw codes. One row per sample set; consecutive rows with the same angles form one position
//! dwell. Lines starting with `#` are comments.
//!
//! The codes have a stated range ([`CodeRange`]): `unsigned16` (0..=65535, a 16-bit ADC; the default)
//! or `signed16` (−32768..=32767, the two's-complement counts of a digital MEMS). A comment line
//! `# codes: signed16` (or `unsigned16`) before the header row states it in the file; a range the
//! command line gives must agree with it. A file that starts with the gzip magic bytes is
//! decompressed as it is read ([`crate::input::Input`]); its errors name lines of the text.
//!
//! Every check lives in one row parser, `RowReader`, which keeps only the current row; the
//! in-memory reader ([`Campaign::read`]) and the streaming one ([`Campaign::reduce`]) both use it.
//! A row with a code at a rail of its range (saturated) or outside it is skipped and counted in
//! a warning per channel; a dwell that loses every row is refused; single-sample dwells are
//! counted in a warning.

use std::io::{BufReader, Chain, Cursor, Read, Write};
use std::path::{Path, PathBuf};

use accelcal_shared::kinematics;

use crate::input::Input;

mod codes;
mod g_source;
pub mod head_at;
pub mod identity;
pub mod transit;
use crate::error::{Classify, Kind, Plain, Setting, Worded, Wording};
use crate::text::TextError;
use codes::{header_comments, HeaderComments};
pub use codes::{CodeRange, CODES_COMMENT, CODES_KEY};
pub use g_source::GSource;

/// Why a campaign file was refused. Every variant names the file and, where there is one, the
/// line and the column (1-based, counting fields).
#[derive(Debug, thiserror::Error)]
pub enum CampaignError {
    /// The file could not be opened or read (a corrupt gzip stream included).
    #[error("{path}: {cause}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The cause, in the message (not a `source`, so that a chain of causes does not print it
        /// twice).
        cause: std::io::Error,
    },
    /// The CSV layer refused the file (bad UTF-8, unbalanced quotes...).
    #[error("{path}:{line}: {msg}")]
    Csv {
        /// The file.
        path: PathBuf,
        /// Line of the problem.
        line: u64,
        /// What went wrong.
        msg: String,
    },
    /// A problem with one field.
    #[error("{path}:{line}:{column}: {msg}")]
    Field {
        /// The file.
        path: PathBuf,
        /// Line of the field.
        line: u64,
        /// Column (field number, 1-based).
        column: usize,
        /// What was expected.
        msg: String,
    },
    /// A `# codes:` line that contradicts the code range the user stated.
    #[error("{}", self.worded(&Plain).unwrap_or_default())]
    CodesContradict {
        /// The file.
        path: PathBuf,
        /// The line.
        line: u64,
        /// The range the file states.
        file: CodeRange,
        /// The range the user stated.
        user: CodeRange,
    },
    /// A problem with one line as a whole (a header comment).
    #[error("{path}:{line}: {msg}")]
    Line {
        /// The file.
        path: PathBuf,
        /// The line.
        line: u64,
        /// What was expected.
        msg: String,
    },
    /// A problem with the file as a whole.
    #[error("{path}: {msg}")]
    File {
        /// The file.
        path: PathBuf,
        /// What was expected.
        msg: String,
    },
}

impl Worded for CampaignError {
    fn worded(&self, w: &dyn Wording) -> Option<String> {
        match self {
            CampaignError::CodesContradict { path, line, file, user } => Some(format!(
                "{}:{line}: `# {CODES_COMMENT} {file}` contradicts {} {user}",
                path.display(),
                w.name(Setting::Codes)
            )),
            _ => None,
        }
    }
}

impl Classify for CampaignError {
    fn kind(&self) -> Kind {
        Kind::BadInput
    }
}

/// One ADC channel: its name (the column header) and one raw code per row.
#[derive(Clone, Debug, PartialEq)]
pub struct Channel {
    /// Column header.
    pub name: String,
    /// Raw ADC codes, one per row.
    pub codes: Vec<f64>,
}

/// A campaign: rows of commanded angles and raw codes.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct Campaign {
    /// Time of each row, seconds.
    pub t_s: Vec<f64>,
    /// Commanded α of each row, degrees.
    pub alpha_deg: Vec<f64>,
    /// Commanded β of each row, degrees.
    pub beta_deg: Vec<f64>,
    /// Temperature of each row, °C, when the file has a `temp_c` column.
    pub temp_c: Option<Vec<f64>>,
    /// The ADC channels.
    pub channels: Vec<Channel>,
    /// What the reader excluded or could not check (saturated codes, single-sample dwells), one
    /// line each; the commands print them on stderr.
    pub warnings: Vec<String>,
    /// The range of the codes (written as a `# codes:` comment line when it is not the default).
    pub codes: CodeRange,
    /// The gravity the campaign was made at, m/s², written as a `# g_m_s2:` comment line (as
    /// `acquire` writes it; the fitting commands take g from it). Not read back by
    /// [`Campaign::read`]: `accelcal`'s commands read the line themselves.
    pub g_m_s2: Option<f64>,
    /// Where that gravity came from, written as a `# g_source:` line ([`GSource::tag`]) after
    /// the `# g_m_s2:` line; not read back by [`Campaign::read`].
    pub g_source: Option<GSource>,
    /// The unit's serial number, written as a `# serial:` comment line (as `acquire` writes it);
    /// not read back by [`Campaign::read`] ([`identity::CampaignId`] reads it).
    pub serial: Option<String>,
}

/// One position dwell: a run of consecutive rows with the same commanded angles.
#[derive(Clone, Debug, PartialEq)]
pub struct Dwell {
    /// First row.
    pub start: usize,
    /// One past the last row.
    pub end: usize,
    /// Commanded α, degrees.
    pub alpha_deg: f64,
    /// Commanded β, degrees.
    pub beta_deg: f64,
}

impl Dwell {
    /// Number of rows in the dwell.
    pub fn len(&self) -> usize {
        self.end - self.start
    }

    /// Never true: a dwell has at least one row.
    pub fn is_empty(&self) -> bool {
        self.end == self.start
    }

    /// The apparent acceleration the head imposes in this dwell.
    pub fn accel(&self, g: f64) -> [f64; 3] {
        kinematics::gravity(self.alpha_deg, self.beta_deg, g)
    }
}

impl Campaign {
    /// Number of rows.
    pub fn len(&self) -> usize {
        self.t_s.len()
    }

    /// Whether there are no rows.
    pub fn is_empty(&self) -> bool {
        self.t_s.is_empty()
    }

    /// Index of the channel named `name`.
    pub fn channel(&self, name: &str) -> Option<usize> {
        self.channels.iter().position(|c| c.name == name)
    }

    /// The position dwells, in file order.
    pub fn dwells(&self) -> Vec<Dwell> {
        let mut out: Vec<Dwell> = Vec::new();
        for i in 0..self.len() {
            let (a, b) = (self.alpha_deg[i], self.beta_deg[i]);
            match out.last_mut() {
                Some(d) if d.alpha_deg == a && d.beta_deg == b => d.end = i + 1,
                _ => out.push(Dwell { start: i, end: i + 1, alpha_deg: a, beta_deg: b }),
            }
        }
        out
    }

    /// Reads and checks a campaign file (plain or gzip), in the code range its `# codes:` line
    /// states (default `unsigned16`).
    pub fn read(path: &Path) -> Result<Campaign, CampaignError> {
        Campaign::read_with(path, None)
    }

    /// [`Campaign::read`] with the code range the user declared, which the file's `# codes:` line
    /// must not contradict.
    pub fn read_with(path: &Path, declared: Option<CodeRange>) -> Result<Campaign, CampaignError> {
        Campaign::from_reader_with(open(path)?, path, declared)
    }

    /// Reads and checks a campaign from any reader; `path` names it in errors.
    pub fn from_reader<R: Read>(reader: R, path: &Path) -> Result<Campaign, CampaignError> {
        Campaign::from_reader_with(reader, path, None)
    }

    /// [`Campaign::from_reader`] with the code range the user declared.
    pub fn from_reader_with<R: Read>(
        reader: R,
        path: &Path,
        declared: Option<CodeRange>,
    ) -> Result<Campaign, CampaignError> {
        let mut rows = RowReader::new(reader, path, declared)?;
        let mut c = Campaign {
            codes: rows.codes(),
            temp_c: rows.has_temp().then(Vec::new),
            channels: rows
                .channel_names()
                .into_iter()
                .map(|name| Channel { name, codes: Vec::new() })
                .collect(),
            ..Campaign::default()
        };
        let mut row = Row::default();
        while rows.next_row(&mut row)? {
            c.t_s.push(row.t);
            c.alpha_deg.push(row.alpha);
            c.beta_deg.push(row.beta);
            if let (Some(v), Some(t)) = (c.temp_c.as_mut(), row.temp) {
                v.push(t);
            }
            for (ch, &v) in c.channels.iter_mut().zip(&row.codes) {
                ch.codes.push(v);
            }
        }
        c.warnings = rows.finish()?;
        Ok(c)
    }

    /// Writes the campaign as CSV (a `# serial:` line when it has one, a `# g_m_s2:` line when it
    /// states its g, a `# codes:` line unless the codes are `unsigned16`, the header, then one row
    /// per sample set). A serial that cannot be a header line's value ([`header_line`]) is
    /// refused before anything is written.
    pub fn write<W: Write>(&self, mut w: W) -> Result<(), WriteError> {
        let mut head = String::new();
        if let Some(s) = &self.serial {
            head += &header_line(identity::SERIAL_KEY, s)?;
        }
        if let Some(g) = self.g_m_s2 {
            head += &header_line(identity::G_KEY, &g.to_string())?;
            if let Some(source) = &self.g_source {
                head += &header_line(identity::G_SOURCE_KEY, &source.tag())?;
            }
        }
        if self.codes != CodeRange::default() {
            head += &header_line(CODES_KEY, self.codes.name())?;
        }
        w.write_all(head.as_bytes()).map_err(|e| WriteError::Csv { cause: e.into() })?;
        self.write_rows(w).map_err(|cause| WriteError::Csv { cause })
    }

    /// The CSV part of [`Campaign::write`]: the header row and the rows.
    fn write_rows<W: Write>(&self, w: W) -> Result<(), csv::Error> {
        let mut wr = csv::Writer::from_writer(w);
        let mut head = vec!["t_s".to_string(), "alpha_deg".into(), "beta_deg".into()];
        if self.temp_c.is_some() {
            head.push("temp_c".into());
        }
        head.extend(self.channels.iter().map(|c| c.name.clone()));
        wr.write_record(&head)?;
        let mut row: Vec<String> = Vec::with_capacity(head.len());
        for i in 0..self.len() {
            row.clear();
            row.push(format!("{}", self.t_s[i]));
            row.push(format!("{}", self.alpha_deg[i]));
            row.push(format!("{}", self.beta_deg[i]));
            if let Some(t) = &self.temp_c {
                row.push(format!("{:.3}", t[i]));
            }
            for c in &self.channels {
                row.push(format!("{}", c.codes[i]));
            }
            wr.write_record(&row)?;
        }
        wr.flush()?;
        Ok(())
    }
}

/// Why [`Campaign::write`] failed.
#[derive(Debug, thiserror::Error)]
pub enum WriteError {
    /// A header value that would not be one `# key: value` line ([`header_line`]).
    #[error(transparent)]
    Header(#[from] TextError),
    /// The writer failed.
    #[error("{cause}")]
    Csv {
        /// The cause, in the message.
        cause: csv::Error,
    },
}

impl Classify for WriteError {
    fn kind(&self) -> Kind {
        match self {
            WriteError::Header(e) => e.kind(),
            WriteError::Csv { .. } => Kind::Environment,
        }
    }
}

/// The keys accelcal writes into a campaign's header (`simulate`, `acquire`) and reads back from
/// it; a header may state each of them once (a second line with one of them is refused by every
/// reader: a forged or spliced header). Other `# key: value` comments are free text and may repeat.
pub const HEADER_KEYS: &[&str] = &[
    "acquired_by",
    identity::DEVICE_ID_KEY,
    identity::SERIAL_KEY,
    "firmware",
    identity::G_KEY,
    identity::G_SOURCE_KEY,
    "plan",
    "chamber",
    "samples",
    "rate_hz",
    "static_rule",
    "date",
    CODES_KEY,
];

/// One `# key: value` header line, with its line feed: the one writer of a campaign's header
/// lines. A value that is not one line of text, or that the reader would not read back as it is
/// (white space at either end), is refused ([`crate::text::header_value`]), so that no value can
/// add a header line of its own.
pub fn header_line(key: &str, value: &str) -> Result<String, TextError> {
    crate::text::header_value(key, value)?;
    Ok(format!("# {key}: {value}\n"))
}

/// The campaign readers' warnings (excluded samples, single-sample dwells), collected while a
/// command runs so that its front end can report them once it ends (after a success, or folded
/// into the line of a failure, which they may explain), and notes about a result (what was
/// assumed), reported after a success only.
#[derive(Debug, Default, Clone, PartialEq)]
pub struct Warnings(Vec<String>, Vec<String>);

impl Warnings {
    /// Adds a reader's warnings, one line each.
    pub fn extend(&mut self, lines: &[String]) {
        self.0.extend_from_slice(lines);
    }

    /// The warnings, one line each, in the order they came.
    pub fn lines(&self) -> &[String] {
        &self.0
    }

    /// Adds a note about the result (e.g. a default that was assumed), one line.
    pub fn note(&mut self, line: String) {
        self.1.push(line);
    }

    /// The notes, one line each.
    pub fn notes(&self) -> &[String] {
        &self.1
    }
}

/// Reads a campaign into memory, in the code range `declared` (the file's `# codes:` line
/// otherwise); its warnings go to `warnings`, its errors are bad input.
pub fn read_campaign(
    path: &Path,
    declared: Option<CodeRange>,
    warnings: &mut Warnings,
) -> anyhow::Result<Campaign> {
    use anyhow::Context;
    let c = Campaign::read_with(path, declared).context("reading the campaign")?;
    warnings.extend(&c.warnings);
    Ok(c)
}

/// The `# key: value` comment lines before a campaign's header row (what `acquire` and
/// `simulate` write there: device id, serial, firmware, g, plan, ...), in file order. Read as the
/// rows are ([`open`]: a gzip file is decompressed), so a header line means the same in a plain
/// and in a gzipped copy; a bad `# codes:` line is refused as every reader refuses it.
pub fn header(path: &Path) -> Result<Vec<(String, String)>, CampaignError> {
    let mut reader = BufReader::new(open(path)?);
    Ok(header_comments(&mut reader, path)?.values)
}

/// Opens a campaign file, decompressing it when it is gzip.
pub(crate) fn open(path: &Path) -> Result<Input, CampaignError> {
    Input::open(path).map_err(|cause| CampaignError::Io { path: path.to_owned(), cause })
}

/// One checked row whose codes are all usable.
#[derive(Clone, Debug, Default)]
pub struct Row {
    /// Time, s.
    pub t: f64,
    /// Commanded α, degrees.
    pub alpha: f64,
    /// Commanded β, degrees.
    pub beta: f64,
    /// Temperature, °C, when the file has `temp_c`.
    pub temp: Option<f64>,
    /// One code per channel.
    pub codes: Vec<f64>,
    /// Line of the row in the file (1-based; 0 for rows that never came from a file).
    pub line: u64,
}

/// The dwell being read: its angles, where it began, and how many of its rows were kept.
struct DwellTrack {
    alpha: f64,
    beta: f64,
    first_line: u64,
    kept: u64,
    /// The first channel that cost this dwell a row.
    lost_to: Option<usize>,
}

/// A run of excluded samples or single-sample dwells: how many, and the first line.
#[derive(Clone, Copy, Default)]
struct Tally {
    count: u64,
    first_line: u64,
}

impl Tally {
    fn add(&mut self, line: u64) {
        if self.count == 0 {
            self.first_line = line;
        }
        self.count += 1;
    }
}

/// The one campaign parser: reads a CSV row by row with every check, keeping nothing but the
/// current row, so the in-memory reader ([`Campaign::read`]) and the streaming one
/// ([`Campaign::reduce`]) refuse the same files with the same messages.
///
/// Rows with a channel code saturated or outside the code range are skipped (and counted per
/// channel for a warning); a dwell that loses every row is refused.
pub struct RowReader<R: Read> {
    rdr: csv::Reader<Chain<Cursor<Vec<u8>>, BufReader<R>>>,
    path: PathBuf,
    codes: CodeRange,
    header: csv::StringRecord,
    cols: [usize; 3],
    temp: Option<usize>,
    chans: Vec<usize>,
    rec: csv::StringRecord,
    prev_t: Option<f64>,
    rows: u64,
    excluded: Vec<Tally>,
    dwell: Option<DwellTrack>,
    single: Tally,
}

impl<R: Read> RowReader<R> {
    /// Reads the comment lines before the header (a `# codes:` line states the code range, which
    /// must agree with `declared`, the user's) and checks the header.
    pub fn new(reader: R, path: &Path, declared: Option<CodeRange>) -> Result<RowReader<R>, CampaignError> {
        let p = || path.to_owned();
        let mut reader = BufReader::new(reader);
        let HeaderComments { prefix, stated, .. } = header_comments(&mut reader, path)?;
        let codes = match (stated, declared) {
            (Some((line, file)), Some(user)) if file != user => {
                return Err(CampaignError::CodesContradict { path: p(), line, file, user })
            }
            (Some((_, file)), _) => file,
            (None, user) => user.unwrap_or_default(),
        };
        let mut rdr = csv::ReaderBuilder::new()
            .comment(Some(b'#'))
            .trim(csv::Trim::All)
            .flexible(true)
            .from_reader(Cursor::new(prefix).chain(reader));
        let header = rdr.headers().map_err(|e| csv_error(e, path))?.clone();
        let header_line = header.position().map(|p| p.line()).unwrap_or(1);
        if header.is_empty() || header.iter().all(|h| h.is_empty()) {
            return Err(CampaignError::File {
                path: p(),
                msg: "empty file: expected a header row with t_s,alpha_deg,beta_deg and channel columns"
                    .into(),
            });
        }
        let mut seen = std::collections::HashSet::new();
        for (i, h) in header.iter().enumerate() {
            let msg = if h.is_empty() {
                "empty column name".to_string()
            } else if !seen.insert(h) {
                format!("duplicate column `{h}`")
            } else {
                continue;
            };
            return Err(CampaignError::Field { path: p(), line: header_line, column: i + 1, msg });
        }
        let find = |name: &str| header.iter().position(|h| h == name);
        let need = |name: &str| {
            find(name).ok_or_else(|| CampaignError::File {
                path: p(),
                msg: format!(
                    "missing required column `{name}` (header has: {})",
                    header.iter().collect::<Vec<_>>().join(",")
                ),
            })
        };
        let cols = [need("t_s")?, need("alpha_deg")?, need("beta_deg")?];
        let temp = find("temp_c");
        let chans: Vec<usize> =
            (0..header.len()).filter(|&i| !cols.contains(&i) && Some(i) != temp).collect();
        if chans.is_empty() {
            return Err(CampaignError::File { path: p(), msg: "no ADC channel column (every column besides t_s, alpha_deg, beta_deg, temp_c is a channel)".into() });
        }
        Ok(RowReader {
            rdr,
            path: p(),
            codes,
            excluded: vec![Tally::default(); chans.len()],
            header,
            cols,
            temp,
            chans,
            rec: csv::StringRecord::new(),
            prev_t: None,
            rows: 0,
            dwell: None,
            single: Tally::default(),
        })
    }

    /// The channel names, in column order.
    pub fn channel_names(&self) -> Vec<String> {
        self.chans.iter().map(|&i| self.header[i].to_string()).collect()
    }

    /// The file column (1-based, counting fields) of each channel.
    pub fn channel_columns(&self) -> Vec<usize> {
        self.chans.iter().map(|&i| i + 1).collect()
    }

    /// Whether the file has a `temp_c` column.
    pub fn has_temp(&self) -> bool {
        self.temp.is_some()
    }

    /// The range of the codes.
    pub fn codes(&self) -> CodeRange {
        self.codes
    }

    fn field_error(&self, line: u64, column: usize, msg: String) -> CampaignError {
        CampaignError::Field { path: self.path.clone(), line, column, msg }
    }

    fn num(&self, line: u64, i: usize) -> Result<f64, CampaignError> {
        let (s, name) = (&self.rec[i], &self.header[i]);
        let Ok(v) = s.parse::<f64>() else {
            let msg = if s.is_empty() {
                format!("expected a number in `{name}`, found an empty field")
            } else {
                format!("expected a number in `{name}`, found `{s}`")
            };
            return Err(self.field_error(line, i + 1, msg));
        };
        if !v.is_finite() {
            return Err(self.field_error(line, i + 1, format!("`{name}` must be finite, found `{s}`")));
        }
        Ok(v)
    }

    /// Reads the next row whose codes are all usable into `row`; `false` at the end of the file.
    pub fn next_row(&mut self, row: &mut Row) -> Result<bool, CampaignError> {
        loop {
            if !self.rdr.read_record(&mut self.rec).map_err(|e| csv_error(e, &self.path))? {
                return Ok(false);
            }
            let line = self.rec.position().map(|p| p.line()).unwrap_or(0);
            if self.rec.len() != self.header.len() {
                let msg = format!("expected {} fields, found {}", self.header.len(), self.rec.len());
                return Err(self.field_error(line, self.rec.len().min(self.header.len()) + 1, msg));
            }
            self.rows += 1;
            let [ti, ai, bi] = self.cols;
            let t = self.num(line, ti)?;
            if let Some(prev) = self.prev_t.filter(|&prev| t < prev) {
                return Err(self.field_error(
                    line,
                    ti + 1,
                    format!("t_s must not decrease ({t} after {prev})"),
                ));
            }
            self.prev_t = Some(t);
            row.line = line;
            row.t = t;
            row.alpha = self.num(line, ai)?;
            row.beta = self.num(line, bi)?;
            row.temp = self.temp.map(|i| self.num(line, i)).transpose()?;
            if !self.dwell.as_ref().is_some_and(|d| d.alpha == row.alpha && d.beta == row.beta) {
                self.close_dwell()?;
                self.dwell = Some(DwellTrack {
                    alpha: row.alpha,
                    beta: row.beta,
                    first_line: line,
                    kept: 0,
                    lost_to: None,
                });
            }
            row.codes.clear();
            let mut usable = true;
            for k in 0..self.chans.len() {
                let v = self.num(line, self.chans[k])?;
                if !self.codes.usable(v) {
                    usable = false;
                    self.excluded[k].add(line);
                    let d = self.dwell.as_mut().expect("a dwell is open");
                    d.lost_to = d.lost_to.or(Some(k));
                }
                row.codes.push(v);
            }
            if usable {
                self.dwell.as_mut().expect("a dwell is open").kept += 1;
                return Ok(true);
            }
        }
    }

    /// Ends the current dwell: refused when it lost every row, counted when it kept one.
    fn close_dwell(&mut self) -> Result<(), CampaignError> {
        let Some(d) = self.dwell.take() else { return Ok(()) };
        match (d.kept, d.lost_to) {
            (0, Some(k)) => {
                let name = &self.header[self.chans[k]];
                Err(self.field_error(
                    d.first_line,
                    self.chans[k] + 1,
                    format!(
                        "every sample of the dwell at alpha_deg {}, beta_deg {} has channel `{name}` {}: nothing left to average",
                        d.alpha,
                        d.beta,
                        self.codes.unusable()
                    ),
                ))
            }
            (1, _) => {
                self.single.add(d.first_line);
                Ok(())
            }
            _ => Ok(()),
        }
    }

    /// Checks the end of the file and returns the warnings (one line each, without a prefix).
    pub fn finish(mut self) -> Result<Vec<String>, CampaignError> {
        self.close_dwell()?;
        if self.rows == 0 {
            return Err(CampaignError::File { path: self.path, msg: "header only: no data rows".into() });
        }
        let path = self.path.display();
        let mut out = Vec::new();
        for (k, x) in self.excluded.iter().enumerate().filter(|(_, x)| x.count > 0) {
            out.push(format!(
                "{path}:{}:{}: excluded {} of {} samples where channel `{}` is {} (first at this line)",
                x.first_line,
                self.chans[k] + 1,
                x.count,
                self.rows,
                &self.header[self.chans[k]],
                self.codes.unusable()
            ));
        }
        if self.single.count > 0 {
            out.push(format!(
                "{path}:{}: {} dwell(s) with a single sample (first at this line): their scatter is unknown",
                self.single.first_line, self.single.count
            ));
        }
        Ok(out)
    }
}

/// Turns an error of the CSV layer into a [`CampaignError`] naming the file and the line (a read
/// error, such as a corrupt gzip stream, has no line: it names the file).
fn csv_error(e: csv::Error, path: &Path) -> CampaignError {
    let line = e.position().map(|p| p.line()).unwrap_or(0);
    let msg = match e.kind() {
        csv::ErrorKind::Utf8 { .. } => "not UTF-8 text (is this a binary file?)".to_string(),
        csv::ErrorKind::Io(_) => match e.into_kind() {
            csv::ErrorKind::Io(cause) => return CampaignError::Io { path: path.to_owned(), cause },
            _ => "read error".to_string(),
        },
        _ => e.to_string(),
    };
    CampaignError::Csv { path: path.to_owned(), line, msg }
}

#[cfg(test)]
mod tests;
