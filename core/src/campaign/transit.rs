//! Sample sets lost in transit between the node and the host, counted from an acquired
//! campaign: `acquire` writes each set's `t_s` from the node's sample counter, so a set lost on
//! the link leaves a gap of more than one sample period between two rows of a dwell.

use super::{Campaign, CampaignError};

/// What a campaign's dwells kept and lost.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Transit {
    /// Sets lost between the rows of a dwell.
    pub lost: u64,
    /// Rows kept, every dwell.
    pub kept: u64,
    /// The fewest rows a dwell kept (0 without dwells).
    pub min_kept: u64,
}

impl Transit {
    /// Counts the sets each dwell of `c` lost, at `rate_hz` (the campaign's `# rate_hz:`): a step
    /// of `t_s` of `n` sample periods (rounded) between two rows loses `n − 1` sets; a step back
    /// (a counter that wrapped) loses none.
    pub fn of(c: &Campaign, rate_hz: f64) -> Transit {
        let mut t = Transit::default();
        let mut first = true;
        for d in c.dwells() {
            let kept = (d.end - d.start) as u64;
            t.kept += kept;
            t.min_kept = if first { kept } else { t.min_kept.min(kept) };
            first = false;
            for w in c.t_s[d.start..d.end].windows(2) {
                let periods = ((w[1] - w[0]) * rate_hz).round();
                if periods.is_finite() && periods > 1.0 {
                    t.lost += periods as u64 - 1;
                }
            }
        }
        t
    }

    /// The sets the campaign file `path` lost, at the rate its header states (`# rate_hz:`, as
    /// `acquire` writes it); `None` when it states no positive rate to count them by.
    pub fn of_file(path: &std::path::Path) -> Result<Option<Transit>, CampaignError> {
        let header = super::header(path)?;
        let rate = header
            .iter()
            .find(|(k, _)| k == crate::sim::plan::RATE_KEY)
            .and_then(|(_, v)| v.parse::<f64>().ok())
            .filter(|r| r.is_finite() && *r > 0.0);
        match rate {
            Some(rate) => Ok(Some(Transit::of(&Campaign::read(path)?, rate))),
            None => Ok(None),
        }
    }

    /// The sets sent: kept and lost.
    pub fn sent(&self) -> u64 {
        self.kept + self.lost
    }

    /// In words: `12,043 of 124,000 sample sets lost in transit; every position kept at least 400`.
    pub fn words(&self) -> String {
        format!(
            "{} of {} sample sets lost in transit; every position kept at least {}",
            thousands(self.lost),
            thousands(self.sent()),
            thousands(self.min_kept)
        )
    }
}

/// `n` with a comma between each group of three digits.
fn thousands(n: u64) -> String {
    let digits = n.to_string();
    let mut s = String::new();
    for (i, c) in digits.chars().enumerate() {
        if i > 0 && (digits.len() - i).is_multiple_of(3) {
            s.push(',');
        }
        s.push(c);
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_gap_between_two_rows_of_a_dwell_is_sets_lost() {
        // 500 Hz: dwell 1 has rows at 0, 2, 8 ms (2 sets lost), dwell 2 at 1.000, 1.002 s.
        let c = Campaign {
            t_s: vec![0.0, 0.002, 0.008, 1.0, 1.002],
            alpha_deg: vec![0.0, 0.0, 0.0, 90.0, 90.0],
            beta_deg: vec![0.0; 5],
            ..Campaign::default()
        };
        let t = Transit::of(&c, 500.0);
        assert_eq!(t, Transit { lost: 2, kept: 5, min_kept: 2 });
        assert_eq!(t.words(), "2 of 7 sample sets lost in transit; every position kept at least 2");
        let big = Transit { lost: 12_043, kept: 111_957, min_kept: 400 };
        assert_eq!(
            big.words(),
            "12,043 of 124,000 sample sets lost in transit; every position kept at least 400"
        );
    }

    #[test]
    fn a_file_is_counted_at_the_rate_its_header_states() {
        let d = tempfile::tempdir().unwrap();
        let rows = "t_s,alpha_deg,beta_deg,x\n0,0,0,1\n0.002,0,0,1\n0.008,0,0,1\n";
        let with = d.path().join("with.csv");
        std::fs::write(&with, format!("# rate_hz: 500\n{rows}")).unwrap();
        assert_eq!(Transit::of_file(&with).unwrap(), Some(Transit { lost: 2, kept: 3, min_kept: 3 }));
        let without = d.path().join("without.csv");
        std::fs::write(&without, rows).unwrap();
        assert_eq!(Transit::of_file(&without).unwrap(), None);
        std::fs::write(&without, format!("# rate_hz: 0\n{rows}")).unwrap();
        assert_eq!(Transit::of_file(&without).unwrap(), None);
    }
}
