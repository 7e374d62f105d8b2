//! Campaign files: the CSV that the rig (or the simulator) writes and every command reads.
//!
//! A header row names the columns. Required: `t_s` (seconds, non-decreasing), `alpha_deg`,
//! `beta_deg` (commanded head angles); optional `temp_c`; every other column is one ADC channel of
//! raw codes. One row per sample set; consecutive rows with the same angles form one position
//! dwell. Lines starting with `#` are comments.

use std::io::{Read, Write};
use std::path::{Path, PathBuf};

use accelcal_shared::kinematics;

/// The largest raw code of the 16-bit ADC.
pub const ADC_MAX: f64 = 65535.0;

/// Why a campaign file was refused. Every variant names the file and, where there is one, the
/// line and the column (1-based, counting fields).
#[derive(Debug, thiserror::Error)]
pub enum CampaignError {
    /// The file could not be opened or read.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
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
    /// A problem with the file as a whole.
    #[error("{path}: {msg}")]
    File {
        /// The file.
        path: PathBuf,
        /// What was expected.
        msg: String,
    },
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

    /// Reads and checks a campaign file.
    pub fn read(path: &Path) -> Result<Campaign, CampaignError> {
        let file = std::fs::File::open(path)
            .map_err(|source| CampaignError::Io { path: path.to_owned(), source })?;
        Campaign::from_reader(std::io::BufReader::new(file), path)
    }

    /// Reads and checks a campaign from any reader; `path` names it in errors.
    pub fn from_reader<R: Read>(reader: R, path: &Path) -> Result<Campaign, CampaignError> {
        let p = || path.to_owned();
        let mut rdr = csv::ReaderBuilder::new()
            .comment(Some(b'#'))
            .trim(csv::Trim::All)
            .flexible(true)
            .from_reader(reader);
        let csv_err = |e: csv::Error| {
            let line = e.position().map(|p| p.line()).unwrap_or(0);
            let msg = match e.kind() {
                csv::ErrorKind::Utf8 { .. } => "not UTF-8 text (is this a binary file?)".to_string(),
                csv::ErrorKind::Io(io) => io.to_string(),
                _ => e.to_string(),
            };
            CampaignError::Csv { path: p(), line, msg }
        };
        let header = rdr.headers().map_err(csv_err)?.clone();
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
            if h.is_empty() {
                return Err(CampaignError::Field {
                    path: p(),
                    line: header_line,
                    column: i + 1,
                    msg: "empty column name".into(),
                });
            }
            if !seen.insert(h) {
                return Err(CampaignError::Field {
                    path: p(),
                    line: header_line,
                    column: i + 1,
                    msg: format!("duplicate column `{h}`"),
                });
            }
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
        let (ti, ai, bi) = (need("t_s")?, need("alpha_deg")?, need("beta_deg")?);
        let temp_i = find("temp_c");
        let chan_cols: Vec<usize> =
            (0..header.len()).filter(|&i| i != ti && i != ai && i != bi && Some(i) != temp_i).collect();
        if chan_cols.is_empty() {
            return Err(CampaignError::File { path: p(), msg: "no ADC channel column (every column besides t_s, alpha_deg, beta_deg, temp_c is a channel)".into() });
        }
        let mut c = Campaign {
            temp_c: temp_i.map(|_| Vec::new()),
            channels: chan_cols
                .iter()
                .map(|&i| Channel { name: header[i].to_string(), codes: Vec::new() })
                .collect(),
            ..Campaign::default()
        };
        let mut rec = csv::StringRecord::new();
        while rdr.read_record(&mut rec).map_err(csv_err)? {
            let line = rec.position().map(|p| p.line()).unwrap_or(0);
            if rec.len() != header.len() {
                return Err(CampaignError::Field {
                    path: p(),
                    line,
                    column: rec.len().min(header.len()) + 1,
                    msg: format!("expected {} fields, found {}", header.len(), rec.len()),
                });
            }
            let num = |i: usize| -> Result<f64, CampaignError> {
                let s = &rec[i];
                let v: f64 = s.parse().map_err(|_| CampaignError::Field {
                    path: p(),
                    line,
                    column: i + 1,
                    msg: if s.is_empty() {
                        format!("expected a number in `{}`, found an empty field", &header[i])
                    } else {
                        format!("expected a number in `{}`, found `{s}`", &header[i])
                    },
                })?;
                if !v.is_finite() {
                    return Err(CampaignError::Field {
                        path: p(),
                        line,
                        column: i + 1,
                        msg: format!("`{}` must be finite, found `{s}`", &header[i]),
                    });
                }
                Ok(v)
            };
            let t = num(ti)?;
            if let Some(&prev) = c.t_s.last() {
                if t < prev {
                    return Err(CampaignError::Field {
                        path: p(),
                        line,
                        column: ti + 1,
                        msg: format!("t_s must not decrease ({t} after {prev})"),
                    });
                }
            }
            c.t_s.push(t);
            c.alpha_deg.push(num(ai)?);
            c.beta_deg.push(num(bi)?);
            if let (Some(i), Some(v)) = (temp_i, c.temp_c.as_mut()) {
                v.push(num(i)?);
            }
            for (k, &i) in chan_cols.iter().enumerate() {
                let v = num(i)?;
                if !(0.0..=ADC_MAX).contains(&v) {
                    return Err(CampaignError::Field {
                        path: p(),
                        line,
                        column: i + 1,
                        msg: format!(
                            "code {v} of channel `{}` is outside the 16-bit ADC range 0..=65535",
                            &header[i]
                        ),
                    });
                }
                c.channels[k].codes.push(v);
            }
        }
        if c.is_empty() {
            return Err(CampaignError::File { path: p(), msg: "header only: no data rows".into() });
        }
        Ok(c)
    }

    /// Writes the campaign as CSV (header, then one row per sample set).
    pub fn write<W: Write>(&self, w: W) -> Result<(), csv::Error> {
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

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(s: &str) -> Result<Campaign, CampaignError> {
        Campaign::from_reader(s.as_bytes(), Path::new("c.csv"))
    }

    #[test]
    fn reads_comments_dwells_and_channels() {
        let c = parse(
            "# rig A\nt_s,alpha_deg,beta_deg,x,y\n0,0,0,100,200\n0.01,0,0,101,201\n# moved\n1,90,0,300,400\n",
        )
        .unwrap();
        assert_eq!(c.len(), 3);
        assert_eq!(c.channels[1].name, "y");
        assert_eq!(c.channels[1].codes, vec![200.0, 201.0, 400.0]);
        let d = c.dwells();
        assert_eq!(d.len(), 2);
        assert_eq!((d[0].start, d[0].end, d[1].alpha_deg), (0, 2, 90.0));
    }

    #[test]
    fn errors_name_line_and_column() {
        let e = parse("t_s,alpha_deg,beta_deg,x\n0,0,0,1\n1,0,zero,2\n").unwrap_err().to_string();
        assert_eq!(e, "c.csv:3:3: expected a number in `beta_deg`, found `zero`");
        let e = parse("t_s,alpha_deg,beta_deg,x\n1,0,0,1\n0,0,0,2\n").unwrap_err().to_string();
        assert!(e.starts_with("c.csv:3:1: t_s must not decrease"), "{e}");
        let e = parse("t_s,alpha_deg,x\n1,0,1\n").unwrap_err().to_string();
        assert!(e.starts_with("c.csv: missing required column `beta_deg`"), "{e}");
        let e = parse("t_s,alpha_deg,beta_deg,x,x\n").unwrap_err().to_string();
        assert_eq!(e, "c.csv:1:5: duplicate column `x`");
        let e = parse("t_s,alpha_deg,beta_deg,x\n0,0,0\n").unwrap_err().to_string();
        assert_eq!(e, "c.csv:2:4: expected 4 fields, found 3");
        let e = parse("t_s,alpha_deg,beta_deg,x\n0,0,NaN,1\n").unwrap_err().to_string();
        assert_eq!(e, "c.csv:2:3: `beta_deg` must be finite, found `NaN`");
        let e = parse("t_s,alpha_deg,beta_deg,x\n").unwrap_err().to_string();
        assert_eq!(e, "c.csv: header only: no data rows");
        assert!(parse("").unwrap_err().to_string().contains("empty file"));
        let e = parse("t_s,alpha_deg,beta_deg,x\n0,0,0,70000\n").unwrap_err().to_string();
        assert!(e.starts_with("c.csv:2:4: code 70000"), "{e}");
    }

    #[test]
    fn write_then_read_is_identity() {
        let c = parse("t_s,alpha_deg,beta_deg,temp_c,x\n0,0,0,25.5,100\n0.5,30,-60,25.5,101\n").unwrap();
        let mut buf = Vec::new();
        c.write(&mut buf).unwrap();
        assert_eq!(parse(std::str::from_utf8(&buf).unwrap()).unwrap(), c);
    }
}
