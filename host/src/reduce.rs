//! Streaming reduction of a campaign: one pass over the file keeps, per dwell, the row count, the
//! angles and each channel's running mean and within-dwell sum of squares, never the rows, so a
//! campaign of any length is read in bounded memory. It is all that the position-level fits
//! (least squares and test turns) need.

use std::io::Read;
use std::path::Path;

use crate::campaign::{Campaign, CampaignError, Dwell, Row, RowReader};
use crate::positions::{ChannelStats, DwellAcc, Positions};

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
}

impl Reduced {
    /// The positions for gravity `g`.
    pub fn positions(&self, g: f64) -> Positions {
        Positions::from_dwells(self.dwells.clone(), g)
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
        let file = std::fs::File::open(path)
            .map_err(|source| CampaignError::Io { path: path.to_owned(), source })?;
        Campaign::reduce_reader(std::io::BufReader::new(file), path)
    }

    /// [`Campaign::reduce`] on any reader; `path` names it in errors.
    pub fn reduce_reader<R: Read>(reader: R, path: &Path) -> Result<Reduced, CampaignError> {
        let mut rows = RowReader::new(reader, path)?;
        let channels = rows.channel_names();
        let mut r = Reduced {
            accs: vec![Vec::new(); channels.len()],
            channels,
            dwells: Vec::new(),
            rows: 0,
            t_range: (f64::NAN, f64::NAN),
            warnings: Vec::new(),
        };
        let mut row = Row::default();
        while rows.next_row(&mut row)? {
            let i = r.rows;
            match r.dwells.last_mut() {
                Some(d) if d.alpha_deg == row.alpha && d.beta_deg == row.beta => d.end = i + 1,
                _ => {
                    r.dwells.push(Dwell { start: i, end: i + 1, alpha_deg: row.alpha, beta_deg: row.beta });
                    r.accs.iter_mut().for_each(|a| a.push(DwellAcc::default()));
                }
            }
            for (a, &v) in r.accs.iter_mut().zip(&row.codes) {
                a.last_mut().expect("a dwell is open").push(v);
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
                "c.csv:3:6: excluded 2 of 7 samples where channel `y` is saturated (0 or 65535) or outside the ADC range (first at this line)",
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
}
