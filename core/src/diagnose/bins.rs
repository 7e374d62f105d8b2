//! The campaign reduced to bins: each dwell cut into up to [`BINS`] consecutive runs of samples,
//! each run kept as sums (its samples, mean time, temperature, the time span it covers, and per
//! channel its mean code and within-bin sum of squares). Built row by row, so a campaign file is
//! read in memory bounded by dwells × bins: one pass to learn each dwell's length
//! ([`Campaign::reduce`]), a second to fill the bins ([`Binned::read`]). The in-memory campaign
//! goes through the same [`Binner`] ([`Binned::from_campaign`]), so both agree to the bit.

use std::io::Read;
use std::path::Path;

use crate::campaign::{Campaign, CampaignError, CodeRange, Dwell, Row};
use crate::positions::DwellAcc;
use crate::reduce::Reread;

/// Bins per dwell (fewer when a dwell has fewer samples).
pub const BINS: usize = 8;

/// One bin: a run of consecutive samples inside one dwell.
#[derive(Clone, Debug, PartialEq)]
pub struct Bin {
    /// Position (dwell) index.
    pub pos: usize,
    /// Bin index within the dwell.
    pub bin: usize,
    /// Samples in the bin.
    pub n: f64,
    /// Mean time, s.
    pub t: f64,
    /// Mean time since the dwell began, s.
    pub t_in_dwell: f64,
    /// Time since the dwell began of the bin's first and last samples, s.
    pub span: (f64, f64),
}

impl Bin {
    /// Mean of `exp(−t_in_dwell/τ)` over the bin's samples, taken as evenly spaced over
    /// [`Bin::span`] (the rig's and the simulator's clock): a geometric series, exact for evenly
    /// spaced samples; where rows were skipped or the clock jitters, an approximation.
    pub fn settle(&self, tau: f64) -> f64 {
        let (a, b) = self.span;
        let first = (-a / tau).exp();
        if self.n < 2.0 || !(b > a) {
            return first;
        }
        // Σ_{i<n} q^i / n with q = exp(−h/τ), h the spacing; exp_m1 keeps it exact as h/τ → 0.
        let x = (b - a) / (self.n - 1.0) / tau;
        first * (-self.n * x).exp_m1() / (-x).exp_m1() / self.n
    }
}

/// A campaign reduced to bins (independent of gravity and of any model).
#[derive(Clone, Debug, PartialEq)]
pub struct Binned {
    /// Channel names, in column order.
    pub channels: Vec<String>,
    /// Commanded angles of each position (dwell), degrees.
    pub angles: Vec<(f64, f64)>,
    /// Mean time of each position, s.
    pub t_pos: Vec<f64>,
    /// The bins, in file order.
    pub bins: Vec<Bin>,
    /// Mean code of each bin, per channel: `mean[channel][bin]`.
    pub mean: Vec<Vec<f64>>,
    /// Sum of squared deviations from the bin means over all bins, per channel, codes².
    pub within: Vec<f64>,
    /// Mean temperature of each bin, °C, when the campaign has `temp_c`.
    pub temp: Option<Vec<f64>>,
    /// Warnings of the reader (excluded samples, single-sample dwells), one line each.
    pub warnings: Vec<String>,
}

impl Binned {
    /// Reduces an in-memory campaign to bins.
    pub fn from_campaign(c: &Campaign) -> Binned {
        let names = c.channels.iter().map(|ch| ch.name.clone()).collect();
        let mut b = Binner::new(names, &c.dwells(), c.temp_c.is_some());
        c.for_each_row(|k, row| b.push(k, row));
        let mut out = b.out;
        out.warnings = c.warnings.clone();
        out
    }

    /// Reads a campaign file into bins in two streaming passes (the first learns each dwell's
    /// length), in memory bounded by the number of dwells, with the checks and messages of
    /// [`Campaign::read`].
    pub fn read(path: &Path) -> Result<Binned, CampaignError> {
        Binned::read_with(path, None)
    }

    /// [`Binned::read`] with the code range the user declared, which the file's `# codes:` line
    /// must not contradict.
    pub fn read_with(path: &Path, declared: Option<CodeRange>) -> Result<Binned, CampaignError> {
        let first = Campaign::reduce_with(path, declared)?;
        Binned::fill(Reread::open(path, declared, &first)?)
    }

    /// The second pass of [`Binned::read`].
    fn fill<R: Read>(mut rows: Reread<'_, R>) -> Result<Binned, CampaignError> {
        let mut b = Binner::new(rows.channel_names(), rows.dwells(), rows.has_temp());
        while let Some((k, row)) = rows.next_row()? {
            b.push(k, row);
        }
        let warnings = rows.finish()?;
        Ok(Binned { warnings, ..b.out })
    }

    /// Number of positions.
    pub fn npos(&self) -> usize {
        self.angles.len()
    }
}

/// One bin being filled.
#[derive(Clone, Debug, Default)]
struct BinAcc {
    t: DwellAcc,
    temp: DwellAcc,
    codes: Vec<DwellAcc>,
    span: (f64, f64),
}

/// Cuts rows into bins as they come, given the length of every dwell: bin `b` of a dwell of `n`
/// rows holds its rows `b·n/k .. (b+1)·n/k`, `k = min(BINS, n)`.
pub(crate) struct Binner {
    lens: Vec<usize>,
    out: Binned,
    /// Current dwell, its first time, the rows of it seen, the current bin, and its time sums.
    pos: usize,
    t0: f64,
    seen: usize,
    bin: usize,
    t_dwell: DwellAcc,
    cur: BinAcc,
}

impl Binner {
    /// A binner for rows of the given dwells (angles and lengths).
    pub fn new(channels: Vec<String>, dwells: &[Dwell], has_temp: bool) -> Binner {
        let nch = channels.len();
        Binner {
            lens: dwells.iter().map(Dwell::len).collect(),
            out: Binned {
                angles: dwells.iter().map(|d| (d.alpha_deg, d.beta_deg)).collect(),
                mean: vec![Vec::new(); nch],
                within: vec![0.0; nch],
                temp: has_temp.then(Vec::new),
                channels,
                t_pos: Vec::new(),
                bins: Vec::new(),
                warnings: Vec::new(),
            },
            pos: 0,
            t0: 0.0,
            seen: 0,
            bin: 0,
            t_dwell: DwellAcc::default(),
            cur: BinAcc { codes: vec![DwellAcc::default(); nch], ..BinAcc::default() },
        }
    }

    /// Adds the next row, of dwell `k`. The rows must continue the dwells given, as the rows of
    /// a campaign's own dwells and a [`Reread`] of its file do.
    pub fn push(&mut self, k: usize, row: &Row) {
        if self.seen == 0 {
            self.t0 = row.t;
        }
        let offset = row.t - self.t0;
        let c = &mut self.cur;
        if c.t.is_empty() {
            c.span.0 = offset;
        }
        c.span.1 = offset;
        c.t.push(row.t);
        if let Some(t) = row.temp {
            c.temp.push(t);
        }
        c.codes.iter_mut().zip(&row.codes).for_each(|(a, &v)| a.push(v));
        self.t_dwell.push(row.t);
        self.seen += 1;
        let n = self.lens[k];
        let nb = BINS.min(n);
        if self.seen == (self.bin + 1) * n / nb {
            self.close_bin();
            self.bin += 1;
        }
        if self.seen == n {
            self.out.t_pos.push(self.t_dwell.mean());
            self.t_dwell = DwellAcc::default();
            (self.pos, self.seen, self.bin) = (self.pos + 1, 0, 0);
        }
    }

    fn close_bin(&mut self) {
        let c = &mut self.cur;
        let t = c.t.mean();
        self.out.bins.push(Bin {
            pos: self.pos,
            bin: self.bin,
            n: c.t.len() as f64,
            t,
            t_in_dwell: t - self.t0,
            span: c.span,
        });
        if let Some(temp) = self.out.temp.as_mut() {
            temp.push(c.temp.mean());
        }
        for (ch, a) in c.codes.iter_mut().enumerate() {
            self.out.mean[ch].push(a.mean());
            self.out.within[ch] += a.within_ss();
            *a = DwellAcc::default();
        }
        (c.t, c.temp) = (DwellAcc::default(), DwellAcc::default());
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::reduce::DwellRows;

    #[test]
    fn the_settling_mean_of_a_bin_is_the_mean_over_its_evenly_spaced_samples() {
        for (n, a, h, tau) in [(50usize, 0.0, 0.01, 0.03), (7, 0.35, 0.1, 2.0), (400, 1.0, 1e-4, 0.5)] {
            let bin = Bin {
                pos: 0,
                bin: 0,
                n: n as f64,
                t: 0.0,
                t_in_dwell: 0.0,
                span: (a, a + (n - 1) as f64 * h),
            };
            let want = (0..n).map(|i| (-(a + i as f64 * h) / tau).exp()).sum::<f64>() / n as f64;
            assert!((bin.settle(tau) - want).abs() <= 1e-13 * want, "{n} {a} {h} {tau}");
        }
        let one = Bin { pos: 0, bin: 0, n: 1.0, t: 0.0, t_in_dwell: 0.0, span: (0.2, 0.2) };
        assert_eq!(one.settle(0.1), (-2f64).exp());
    }

    #[test]
    fn rows_that_do_not_continue_the_first_pass_are_refused() {
        let text = "t_s,alpha_deg,beta_deg,x\n0,0,0,100\n0.1,0,0,101\n1,90,0,300\n";
        let p = Path::new("c.csv");
        let first = Campaign::reduce_reader(text.as_bytes(), p).unwrap();
        let fill = |t: &str| {
            let rows = DwellRows::new(t.as_bytes(), p, None).unwrap();
            Binned::fill(Reread::new(rows, &first, p).unwrap())
        };
        let ok = fill(text).unwrap();
        assert_eq!(ok.bins.len(), 3);
        let more = format!("{text}1.1,90,0,301\n2,0,0,5\n");
        let e = fill(&more).unwrap_err();
        assert!(e.to_string().starts_with("c.csv: changed while it was read"), "{e}");
        let fewer = "t_s,alpha_deg,beta_deg,x\n0,0,0,100\n0.1,0,0,101\n";
        let e = fill(fewer).unwrap_err();
        assert!(e.to_string().contains("1 dwells where 2 were read before"), "{e}");
    }
}
