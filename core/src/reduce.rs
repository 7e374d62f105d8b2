//! Streaming reduction of a campaign: one pass over the file keeps, per dwell, the row count, the
//! angles and each channel's running mean and within-dwell sum of squares, never the rows, so a
//! campaign of any length is read in bounded memory. It is all that the position-level fits
//! (least squares and test turns) need.
//!
//! The same row parser as the in-memory reader (`campaign::RowReader`), each row folded into its
//! dwell's statistics at once. [`DwellRows`] gives the rows one at a time with their dwell index;
//! `Reread` is the second pass of `compare` and `diagnose` over it, refusing a file whose
//! channels, dwells or row counts changed since the first; `Campaign::for_each_row` does the same
//! walk for an in-memory campaign.

use std::io::Read;
use std::path::Path;

use crate::campaign::{Campaign, CampaignError, CodeRange, Dwell, Row, RowReader};
use crate::input::Input;
use crate::positions::{ChannelStats, DwellAcc, Positions};

/// Reduces a campaign file (plain or gzip) to its dwells in one streaming pass (bounded memory),
/// in the code range `declared` (the file's `# codes:` line otherwise); its warnings go to
/// `warnings`, its errors are bad input.
pub fn reduce_campaign(
    path: &Path,
    declared: Option<CodeRange>,
    warnings: &mut crate::campaign::Warnings,
) -> anyhow::Result<Reduced> {
    use anyhow::Context;
    let r = Campaign::reduce_with(path, declared).context("reading the campaign")?;
    warnings.extend(&r.warnings);
    Ok(r)
}

/// A campaign reduced to its dwells.
#[derive(Clone, Debug)]
pub struct Reduced {
    /// Channel names, in column order.
    pub channels: Vec<String>,
    /// The dwells, in file order; `start`/`end` count the rows kept.
    pub dwells: Vec<Dwell>,
    /// Per channel, the statistics of each dwell: `accs[channel][dwell]`.
    pub accs: Vec<Vec<DwellAcc>>,
    /// Rows kept.
    pub rows: usize,
    /// First and last time, s.
    pub t_range: (f64, f64),
    /// Warnings of the reader (excluded samples, single-sample dwells), one line each.
    pub warnings: Vec<String>,
    /// The range of the codes.
    pub codes: CodeRange,
    /// The temperature of each dwell, °C, when the file has a `temp_c` column.
    pub temp: Option<Vec<DwellAcc>>,
}

impl Reduced {
    /// The positions for gravity `g`, with the dwells' mean temperatures.
    pub fn positions(&self, g: f64) -> Positions {
        let mut pos = Positions::from_dwells(self.dwells.clone(), g);
        pos.temp_c = self.temp.as_ref().map(|t| t.iter().map(DwellAcc::mean).collect());
        pos
    }

    /// The dwell statistics of every channel.
    pub fn channel_stats(&self) -> Vec<ChannelStats> {
        self.channels.iter().zip(&self.accs).map(|(n, a)| ChannelStats::from_accs(n, a)).collect()
    }
}

impl Campaign {
    /// Reads a campaign file in one pass, in bounded memory, with the checks and messages of
    /// [`Campaign::read`].
    pub fn reduce(path: &Path) -> Result<Reduced, CampaignError> {
        Campaign::reduce_with(path, None)
    }

    /// [`Campaign::reduce`] with the code range the user declared, which the file's `# codes:`
    /// line must not contradict.
    pub fn reduce_with(path: &Path, declared: Option<CodeRange>) -> Result<Reduced, CampaignError> {
        Campaign::reduce_rows(DwellRows::open(path, declared)?)
    }

    /// [`Campaign::reduce`] on any reader; `path` names it in errors.
    pub fn reduce_reader<R: Read>(reader: R, path: &Path) -> Result<Reduced, CampaignError> {
        Campaign::reduce_rows(DwellRows::new(reader, path, None)?)
    }

    fn reduce_rows<R: Read>(mut rows: DwellRows<R>) -> Result<Reduced, CampaignError> {
        let channels = rows.channel_names();
        let mut r = Reduced {
            accs: vec![Vec::new(); channels.len()],
            channels,
            dwells: Vec::new(),
            rows: 0,
            t_range: (f64::NAN, f64::NAN),
            warnings: Vec::new(),
            codes: rows.codes(),
            temp: rows.has_temp().then(Vec::new),
        };
        while let Some((k, row)) = rows.next_row()? {
            let i = r.rows;
            if k == r.dwells.len() {
                r.dwells.push(Dwell { start: i, end: i, alpha_deg: row.alpha, beta_deg: row.beta });
                r.accs.iter_mut().for_each(|a| a.push(DwellAcc::default()));
                if let Some(t) = r.temp.as_mut() {
                    t.push(DwellAcc::default());
                }
            }
            if let (Some(t), Some(v)) = (r.temp.as_mut(), row.temp) {
                t[k].push(v);
            }
            r.dwells[k].end = i + 1;
            for (a, &v) in r.accs.iter_mut().zip(&row.codes) {
                a[k].push(v);
            }
            if i == 0 {
                r.t_range.0 = row.t;
            }
            r.t_range.1 = row.t;
            r.rows += 1;
        }
        r.warnings = rows.finish()?;
        Ok(r)
    }

    /// Calls `f(dwell, row)` for every row in file order, `dwell` numbering the dwells as
    /// [`Campaign::dwells`] does: what [`DwellRows`] gives for the file this campaign was read
    /// from, so that one code serves the in-memory and the streaming paths.
    pub(crate) fn for_each_row(&self, mut f: impl FnMut(usize, &Row)) {
        let mut row = Row { temp: None, codes: vec![0.0; self.channels.len()], ..Row::default() };
        for (k, d) in self.dwells().iter().enumerate() {
            for i in d.start..d.end {
                row.t = self.t_s[i];
                row.alpha = self.alpha_deg[i];
                row.beta = self.beta_deg[i];
                row.temp = self.temp_c.as_ref().map(|t| t[i]);
                for (v, ch) in row.codes.iter_mut().zip(&self.channels) {
                    *v = ch.codes[i];
                }
                f(k, &row);
            }
        }
    }
}

/// The rows of a campaign file, read one at a time with every check of [`RowReader`], each with
/// the index of its dwell (consecutive kept rows with the same angles, as [`Campaign::dwells`]
/// counts them). Keeps only the current row.
pub struct DwellRows<R: Read> {
    rows: RowReader<R>,
    row: Row,
    dwell: Option<usize>,
}

impl DwellRows<Input> {
    /// Opens a campaign file (plain or gzip) and checks its header; `declared` is the user's code
    /// range (see [`RowReader::new`]).
    pub fn open(path: &Path, declared: Option<CodeRange>) -> Result<Self, CampaignError> {
        DwellRows::new(crate::campaign::open(path)?, path, declared)
    }
}

impl<R: Read> DwellRows<R> {
    /// Reads and checks the header; `path` names the reader in errors.
    pub fn new(reader: R, path: &Path, declared: Option<CodeRange>) -> Result<Self, CampaignError> {
        Ok(DwellRows { rows: RowReader::new(reader, path, declared)?, row: Row::default(), dwell: None })
    }

    /// The range of the codes.
    pub fn codes(&self) -> CodeRange {
        self.rows.codes()
    }

    /// The channel names, in column order.
    pub fn channel_names(&self) -> Vec<String> {
        self.rows.channel_names()
    }

    /// The file column (1-based) of each channel.
    pub fn channel_columns(&self) -> Vec<usize> {
        self.rows.channel_columns()
    }

    /// Whether the file has a `temp_c` column.
    pub fn has_temp(&self) -> bool {
        self.rows.has_temp()
    }

    /// The next kept row and the index of its dwell; `None` at the end of the file.
    pub fn next_row(&mut self) -> Result<Option<(usize, &Row)>, CampaignError> {
        let (alpha, beta) = (self.row.alpha, self.row.beta);
        if !self.rows.next_row(&mut self.row)? {
            return Ok(None);
        }
        let k = match self.dwell {
            Some(k) if self.row.alpha == alpha && self.row.beta == beta => k,
            Some(k) => k + 1,
            None => 0,
        };
        self.dwell = Some(k);
        Ok(Some((k, &self.row)))
    }

    /// Checks the end of the file and returns the warnings (see [`RowReader::finish`]).
    pub fn finish(self) -> Result<Vec<String>, CampaignError> {
        self.rows.finish()
    }
}

/// A second pass over a campaign file: its rows with their dwells, each checked to continue the
/// dwells (angles and row counts), channels and code range of the first pass, so that a file
/// changed between the passes is refused instead of mixed. Errors read `changed while it was
/// read: …`.
pub(crate) struct Reread<'d, R: Read> {
    rows: DwellRows<R>,
    dwells: &'d [Dwell],
    path: std::path::PathBuf,
    /// The dwell being read and how many of its rows came so far.
    at: (usize, usize),
}

fn changed(path: &Path, msg: String) -> CampaignError {
    CampaignError::File { path: path.to_owned(), msg: format!("changed while it was read: {msg}") }
}

impl<'d> Reread<'d, Input> {
    /// Opens a campaign file for its second pass, given the user's code range (as for the first
    /// pass) and what the first pass found.
    pub fn open(path: &Path, declared: Option<CodeRange>, first: &'d Reduced) -> Result<Self, CampaignError> {
        Reread::new(DwellRows::open(path, declared)?, first, path)
    }
}

impl<'d, R: Read> Reread<'d, R> {
    /// The second pass over `rows`, given what the first pass found; `path` names it in errors.
    pub fn new(rows: DwellRows<R>, first: &'d Reduced, path: &Path) -> Result<Self, CampaignError> {
        let r = Reread { rows, dwells: &first.dwells, path: path.to_owned(), at: (0, 0) };
        if r.rows.channel_names() != first.channels {
            return Err(changed(path, "other channels than before".into()));
        }
        if r.rows.codes() != first.codes {
            return Err(changed(path, format!("codes {} where they were {}", r.rows.codes(), first.codes)));
        }
        Ok(r)
    }

    /// Whether the file has a `temp_c` column.
    pub fn has_temp(&self) -> bool {
        self.rows.has_temp()
    }

    /// The channel names, in column order (those of the first pass).
    pub fn channel_names(&self) -> Vec<String> {
        self.rows.channel_names()
    }

    /// The dwells of the first pass.
    pub fn dwells(&self) -> &'d [Dwell] {
        self.dwells
    }

    /// The next kept row and the index of its dwell; `None` at the end of the file.
    pub fn next_row(&mut self) -> Result<Option<(usize, &Row)>, CampaignError> {
        let (dwells, (pos, seen)) = (self.dwells, self.at);
        let len = |i: usize| dwells.get(i).map_or(0, Dwell::len);
        let Some((k, row)) = self.rows.next_row()? else { return Ok(None) };
        let msg = if k == pos && seen < len(pos) || k == pos + 1 && seen == len(pos) && k < dwells.len() {
            if (row.alpha, row.beta) == (dwells[k].alpha_deg, dwells[k].beta_deg) {
                self.at = (k, if k == pos { seen + 1 } else { 1 });
                return Ok(Some((k, row)));
            }
            format!("dwell {} has other angles than before", k + 1)
        } else if k == pos {
            format!("dwell {} has more rows than before", k + 1)
        } else if seen < len(pos) {
            format!("dwell {} has fewer rows than before", pos + 1)
        } else {
            format!("more than the {} dwells read before", dwells.len())
        };
        Err(changed(&self.path, msg))
    }

    /// Checks that every dwell was read whole and returns the reader's warnings.
    pub fn finish(self) -> Result<Vec<String>, CampaignError> {
        let (pos, seen) = self.at;
        let whole = match self.dwells.last() {
            None => seen == 0,
            Some(last) => pos + 1 == self.dwells.len() && seen == last.len(),
        };
        if !whole {
            let read = if seen == 0 { 0 } else { pos + 1 };
            let msg = format!("{read} dwells where {} were read before", self.dwells.len());
            return Err(changed(&self.path, msg));
        }
        self.rows.finish()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const TEXT: &str = "t_s,alpha_deg,beta_deg,temp_c,x,y\n\
        0,0,0,25,100.5,200\n0.1,0,0,25,101,65535\n0.2,0,0,25,102.25,201\n\
        1,90,0,25,300,400\n\
        2,180,0,25,500,0\n2.1,180,0,25,501,600\n2.2,180,0,25,503,601\n";

    #[test]
    fn streaming_and_in_memory_statistics_agree_to_the_bit() {
        let p = Path::new("c.csv");
        let c = Campaign::from_reader(TEXT.as_bytes(), p).unwrap();
        let r = Campaign::reduce_reader(TEXT.as_bytes(), p).unwrap();
        let pos = Positions::new(&c, 9.81);
        assert_eq!(pos.dwells, r.dwells);
        assert_eq!(r.rows, c.len());
        assert_eq!(r.t_range, (0.0, 2.2));
        assert_eq!(r.warnings, c.warnings);
        for (a, b) in pos.channel_stats(&c).iter().zip(r.channel_stats()) {
            assert_eq!(a.name, b.name);
            assert_eq!(a.mean, b.mean);
            assert_eq!(a.within_ss, b.within_ss);
        }
    }

    #[test]
    fn saturated_rows_are_excluded_with_one_warning_per_channel() {
        let r = Campaign::reduce_reader(TEXT.as_bytes(), Path::new("c.csv")).unwrap();
        assert_eq!(r.rows, 5);
        assert_eq!(r.dwells.iter().map(Dwell::len).collect::<Vec<_>>(), vec![2, 1, 2]);
        assert_eq!(r.accs[0][0].mean(), 101.375);
        assert_eq!(
            r.warnings,
            vec![
                "c.csv:3:6: excluded 2 of 7 samples where channel `y` is saturated (0 or 65535) or outside the unsigned16 range (first at this line)",
                "c.csv:5: 1 dwell(s) with a single sample (first at this line): their scatter is unknown",
            ]
        );
        let lost = "t_s,alpha_deg,beta_deg,x\n0,0,0,100\n1,90,0,0\n1.1,90,0,70000\n2,0,0,5\n";
        let e = Campaign::reduce_reader(lost.as_bytes(), Path::new("c.csv")).unwrap_err().to_string();
        assert!(
            e.starts_with("c.csv:3:4: every sample of the dwell at alpha_deg 90, beta_deg 0 has channel `x`"),
            "{e}"
        );
    }

    /// A second pass refuses, with what changed, every way a file can differ from its first pass.
    #[test]
    fn a_reread_refuses_a_file_changed_between_the_passes() {
        let head = "t_s,alpha_deg,beta_deg,x\n";
        let text = format!("{head}0,0,0,100\n0.1,0,0,101\n1,90,0,300\n");
        let p = Path::new("c.csv");
        let first = Campaign::reduce_reader(text.as_bytes(), p).unwrap();
        let reread = |t: &str| -> Result<usize, CampaignError> {
            let rows = DwellRows::new(t.as_bytes(), p, None)?;
            let mut r = Reread::new(rows, &first, p)?;
            let mut n = 0;
            while r.next_row()?.is_some() {
                n += 1;
            }
            r.finish()?;
            Ok(n)
        };
        assert_eq!(reread(&text).unwrap(), 3);
        for (changed, what) in [
            ("t_s,alpha_deg,beta_deg,y\n0,0,0,100\n", "other channels than before"),
            (&format!("# codes: signed16\n{text}"), "codes signed16 where they were unsigned16"),
            (&format!("{head}0,0,0,100\n0.1,0,0,101\n0.2,0,0,102\n1,90,0,300\n"), "dwell 1 has more rows"),
            (&format!("{head}0,0,0,100\n1,90,0,300\n"), "dwell 1 has fewer rows"),
            (&format!("{head}0,0,0,100\n0.1,0,0,101\n1,45,0,300\n"), "dwell 2 has other angles"),
            (&format!("{text}2,0,0,5\n"), "more than the 2 dwells read before"),
            (&format!("{head}0,0,0,100\n0.1,0,0,101\n"), "1 dwells where 2 were read before"),
        ] {
            let e = reread(changed).unwrap_err().to_string();
            assert!(e.starts_with("c.csv: changed while it was read: ") && e.contains(what), "{e}");
        }
    }
}
