//! Reader and writer for the imu_tk text format: whitespace-separated `t x y z` rows, optionally gzip-compressed.
//!
//! The format has no header and no angles: column 1 is the time in seconds, columns 2–4 are the raw
//! accelerometer outputs (ADC codes, written as floats). Blank lines and lines starting with `#` or `%`
//! are skipped. The reader never panics on bad input; every error names the file, the 1-based line and
//! the 1-based column (in characters) where the problem starts.

use crate::error::{Classify, Kind};
use std::io::{self, BufRead, Write};
use std::path::Path;

/// A recording of a 3-axis sensor: time stamps and raw outputs, one row per sample.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Recording {
    /// Time of each sample, in seconds.
    pub t: Vec<f64>,
    /// Raw output of each sample, `[x, y, z]`, in codes.
    pub codes: Vec<[f64; 3]>,
}

impl Recording {
    /// Number of samples.
    pub fn len(&self) -> usize {
        self.t.len()
    }

    /// Whether the recording holds no sample.
    pub fn is_empty(&self) -> bool {
        self.t.is_empty()
    }

    /// Median sampling interval in seconds, or `None` with fewer than two samples or a
    /// non-positive median interval.
    pub fn median_dt(&self) -> Option<f64> {
        if self.t.len() < 2 {
            return None;
        }
        let mut dts: Vec<f64> = self.t.windows(2).map(|w| w[1] - w[0]).collect();
        dts.sort_by(f64::total_cmp);
        let m = dts[dts.len() / 2];
        (m.is_finite() && m > 0.0).then_some(m)
    }
}

/// What is wrong with a field or a row of an imu_tk file.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RowProblem {
    /// The field is not a number.
    #[error("expected a number, found `{0}`")]
    NotANumber(String),
    /// The field is a number but not finite (NaN or infinite).
    #[error("value `{0}` is not finite")]
    NotFinite(String),
    /// The row has the wrong number of fields.
    #[error("expected 4 fields (t x y z), found {0}")]
    FieldCount(usize),
    /// The time stamp does not increase.
    #[error("time {now} does not increase (previous row has {prev})")]
    TimeNotIncreasing {
        /// Time stamp of the previous row.
        prev: f64,
        /// Time stamp of this row.
        now: f64,
    },
}

impl Classify for RowProblem {
    fn kind(&self) -> Kind {
        Kind::BadInput
    }
}

/// Errors of the imu_tk reader.
#[derive(Debug, thiserror::Error)]
pub enum ImuTkError {
    /// The file cannot be opened or read (including a corrupt gzip stream).
    #[error("{file}: cannot read")]
    Io {
        /// File name as given.
        file: String,
        /// Underlying error.
        #[source]
        source: io::Error,
    },
    /// A line is not valid UTF-8.
    #[error("{file}:{line}:1: line is not valid UTF-8")]
    NotUtf8 {
        /// File name as given.
        file: String,
        /// 1-based line number.
        line: usize,
    },
    /// A row is malformed.
    #[error("{file}:{line}:{column}: {problem}")]
    Row {
        /// File name as given.
        file: String,
        /// 1-based line number.
        line: usize,
        /// 1-based column (in characters) of the offending field, or 1 for whole-row problems.
        column: usize,
        /// What is wrong.
        problem: RowProblem,
    },
    /// The file holds no data row.
    #[error("{file}: no data rows")]
    Empty {
        /// File name as given.
        file: String,
    },
}

impl Classify for ImuTkError {
    fn kind(&self) -> Kind {
        Kind::BadInput
    }
}

/// Reads an imu_tk file from `path`; gzip input is recognised by its magic bytes, whatever the name
/// ([`crate::input::Input`]).
pub fn read_path(path: &Path) -> Result<Recording, ImuTkError> {
    let file = path.display().to_string();
    let io_err = |source| ImuTkError::Io { file: file.clone(), source };
    parse(crate::input::Input::open(path).map_err(io_err)?, &file)
}

/// Parses imu_tk text from a reader; `file` is used only in error messages.
pub fn parse<R: BufRead>(mut reader: R, file: &str) -> Result<Recording, ImuTkError> {
    let mut rec = Recording::default();
    let mut buf = Vec::new();
    let mut line_no = 0usize;
    loop {
        buf.clear();
        let n = reader
            .read_until(b'\n', &mut buf)
            .map_err(|source| ImuTkError::Io { file: file.to_string(), source })?;
        if n == 0 {
            break;
        }
        line_no += 1;
        let text = std::str::from_utf8(&buf)
            .map_err(|_| ImuTkError::NotUtf8 { file: file.to_string(), line: line_no })?;
        let row_err =
            |column, problem| ImuTkError::Row { file: file.to_string(), line: line_no, column, problem };
        let trimmed = text.trim();
        if trimmed.is_empty() || trimmed.starts_with('#') || trimmed.starts_with('%') {
            continue;
        }
        let mut values = [0.0f64; 4];
        let mut count = 0usize;
        for (column, field) in fields(text) {
            if count < 4 {
                values[count] = parse_field(field).map_err(|p| row_err(column, p))?;
            }
            count += 1;
        }
        if count != 4 {
            return Err(row_err(1, RowProblem::FieldCount(count)));
        }
        if let Some(&prev) = rec.t.last() {
            if values[0] <= prev {
                let column = fields(text).next().map_or(1, |(c, _)| c);
                return Err(row_err(column, RowProblem::TimeNotIncreasing { prev, now: values[0] }));
            }
        }
        rec.t.push(values[0]);
        rec.codes.push([values[1], values[2], values[3]]);
    }
    if rec.is_empty() {
        return Err(ImuTkError::Empty { file: file.to_string() });
    }
    Ok(rec)
}

/// Splits a line into whitespace-separated fields with their 1-based character columns.
fn fields(line: &str) -> impl Iterator<Item = (usize, &str)> {
    let mut rest = line;
    let mut column = 1usize;
    std::iter::from_fn(move || {
        let skipped = rest.len() - rest.trim_start().len();
        column += rest[..skipped].chars().count();
        rest = &rest[skipped..];
        if rest.is_empty() {
            return None;
        }
        let end = rest.find(char::is_whitespace).unwrap_or(rest.len());
        let field = &rest[..end];
        let at = column;
        column += field.chars().count();
        rest = &rest[end..];
        Some((at, field))
    })
}

fn parse_field(field: &str) -> Result<f64, RowProblem> {
    let v: f64 = field.parse().map_err(|_| RowProblem::NotANumber(field.to_string()))?;
    if v.is_finite() {
        Ok(v)
    } else {
        Err(RowProblem::NotFinite(field.to_string()))
    }
}

/// Writes a recording in the imu_tk text format (the same layout as the imu_tk test data).
pub fn write<W: Write>(rec: &Recording, mut out: W) -> io::Result<()> {
    for (t, c) in rec.t.iter().zip(&rec.codes) {
        writeln!(out, "{t:.7e} {:.7e} {:.7e} {:.7e}", c[0], c[1], c[2])?;
    }
    out.flush()
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::fs::File;

    fn parse_str(s: &str) -> Result<Recording, ImuTkError> {
        parse(s.as_bytes(), "mem.txt")
    }

    #[test]
    fn reads_rows_comments_and_blank_lines() {
        let rec = parse_str("# header\n\n 0.01  1.0e+00 2 3\n0.02\t4 5 6\r\n").unwrap();
        assert_eq!(rec.t, vec![0.01, 0.02]);
        assert_eq!(rec.codes, vec![[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]]);
        assert!((rec.median_dt().unwrap() - 0.01).abs() < 1e-12);
    }

    #[test]
    fn reports_line_and_column_of_a_bad_field() {
        let err = parse_str("0 1 2 3\n1   4 x5 6\n").unwrap_err();
        assert_eq!(err.to_string(), "mem.txt:2:7: expected a number, found `x5`");
    }

    #[test]
    fn reports_field_count_non_finite_and_time_order() {
        let err = parse_str("0 1 2\n").unwrap_err();
        assert_eq!(err.to_string(), "mem.txt:1:1: expected 4 fields (t x y z), found 3");
        let err = parse_str("0 1 2 3 4\n").unwrap_err();
        assert!(err.to_string().ends_with("found 5"), "{err}");
        let err = parse_str("0 1 NaN 3\n").unwrap_err();
        assert_eq!(err.to_string(), "mem.txt:1:5: value `NaN` is not finite");
        let err = parse_str("0 1 2 3\n0 1 2 3\n").unwrap_err();
        assert!(matches!(
            err,
            ImuTkError::Row { line: 2, column: 1, problem: RowProblem::TimeNotIncreasing { .. }, .. }
        ));
    }

    #[test]
    fn rejects_empty_and_non_utf8_input() {
        assert!(matches!(parse_str("# nothing\n"), Err(ImuTkError::Empty { .. })));
        let err = parse(&b"0 1 2 3\n\xff\xfe\n"[..], "bin").unwrap_err();
        assert!(matches!(err, ImuTkError::NotUtf8 { line: 2, .. }));
    }

    #[test]
    fn write_then_read_round_trips_and_gzip_is_detected() {
        let rec = Recording {
            t: vec![0.0, 0.01, 0.02],
            codes: vec![[1.0, 2.0, 3.0], [32768.0, 0.0, 65535.0], [5.0, 6.0, 7.0]],
        };
        let dir = tempfile::tempdir().unwrap();
        let plain = dir.path().join("a.txt");
        write(&rec, File::create(&plain).unwrap()).unwrap();
        assert_eq!(read_path(&plain).unwrap(), rec);
        let gz = dir.path().join("a.data");
        let enc = flate2::write::GzEncoder::new(File::create(&gz).unwrap(), flate2::Compression::fast());
        write(&rec, enc).unwrap();
        assert_eq!(read_path(&gz).unwrap(), rec);
        let missing = dir.path().join("missing.txt");
        assert!(read_path(&missing).unwrap_err().to_string().contains("missing.txt: cannot read"));
    }

    #[test]
    fn corrupt_gzip_is_an_error_not_a_panic() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("bad.gz");
        std::fs::write(&p, [0x1f, 0x8b, 8, 0, 0, 0, 0, 0, 0, 0, 1, 2, 3, 4]).unwrap();
        assert!(matches!(read_path(&p), Err(ImuTkError::Io { .. })));
    }
}
