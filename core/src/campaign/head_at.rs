//! The head's word on each position: the comment line `acquire` writes before a position's rows,
//! with the angles commanded and the angles the head read back once the move was done.
//!
//! `# head_at: position=5 alpha_deg=90 beta_deg=-60 read_back_alpha_deg=90.00012 read_back_beta_deg=-60`
//!
//! The rows keep the commanded angles (the method's nominal ones); this line says where the head
//! reported itself. It is written in the same write as the position's rows, so a position cut by
//! a crash loses its line with its rows. Readers of the rows skip it as every comment.

use serde::{Deserialize, Serialize};
use std::io::BufRead;
use std::path::Path;

use super::CampaignError;

/// The key of the line.
pub const HEAD_AT_KEY: &str = "head_at";

/// One position's commanded and read-back angles, degrees.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct HeadAt {
    /// The position, 1-based.
    pub position: usize,
    /// α commanded, degrees.
    pub alpha_deg: f64,
    /// β commanded, degrees.
    pub beta_deg: f64,
    /// α the head read back, degrees.
    pub read_back_alpha_deg: f64,
    /// β the head read back, degrees.
    pub read_back_beta_deg: f64,
}

impl HeadAt {
    /// The comment line, with its line feed.
    pub fn line(&self) -> String {
        format!(
            "# {HEAD_AT_KEY}: position={} alpha_deg={} beta_deg={} read_back_alpha_deg={} read_back_beta_deg={}\n",
            self.position, self.alpha_deg, self.beta_deg, self.read_back_alpha_deg, self.read_back_beta_deg
        )
    }

    /// Parses one line (with or without its line feed); `None` when it is not a `head_at` line
    /// or a field is missing or not a finite number.
    pub fn parse(line: &str) -> Option<HeadAt> {
        let rest =
            line.trim().strip_prefix('#')?.trim_start().strip_prefix(HEAD_AT_KEY)?.strip_prefix(':')?;
        let mut fields = std::collections::BTreeMap::new();
        for word in rest.split_whitespace() {
            let (k, v) = word.split_once('=')?;
            fields.insert(k, v);
        }
        let num = |k: &str| fields.get(k)?.parse::<f64>().ok().filter(|v| v.is_finite());
        Some(HeadAt {
            position: fields.get("position")?.parse().ok()?,
            alpha_deg: num("alpha_deg")?,
            beta_deg: num("beta_deg")?,
            read_back_alpha_deg: num("read_back_alpha_deg")?,
            read_back_beta_deg: num("read_back_beta_deg")?,
        })
    }

    /// Every `head_at` line of a campaign (a gzip file is decompressed), in file order.
    pub fn read_all(path: &Path) -> Result<Vec<HeadAt>, CampaignError> {
        let reader = std::io::BufReader::new(super::open(path)?);
        let mut out = Vec::new();
        for line in reader.lines() {
            let line = line.map_err(|cause| CampaignError::Io { path: path.to_owned(), cause })?;
            if let Some(h) = HeadAt::parse(&line) {
                out.push(h);
            }
        }
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_line_round_trips_and_other_comments_are_not_it() {
        let h = HeadAt {
            position: 5,
            alpha_deg: 90.0,
            beta_deg: -60.0,
            read_back_alpha_deg: 90.00012,
            read_back_beta_deg: -60.0,
        };
        assert_eq!(
            h.line(),
            "# head_at: position=5 alpha_deg=90 beta_deg=-60 read_back_alpha_deg=90.00012 read_back_beta_deg=-60\n"
        );
        assert_eq!(HeadAt::parse(&h.line()), Some(h));
        for other in
            ["# note: head_at", "# head_at: position=5", "# head_at: position=x alpha_deg=1", "1,2,3"]
        {
            assert_eq!(HeadAt::parse(other), None, "{other}");
        }
        let nan = h.line().replace("=-60 read", "=NaN read");
        assert_eq!(HeadAt::parse(&nan), None);
    }

    #[test]
    fn a_campaign_with_the_lines_reads_as_without() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("c.csv");
        let h = |k, a: f64| HeadAt {
            position: k,
            alpha_deg: a,
            beta_deg: 0.0,
            read_back_alpha_deg: a + 1e-4,
            read_back_beta_deg: 0.0,
        };
        let text = format!(
            "# g_m_s2: 9.81\nt_s,alpha_deg,beta_deg,x\n{}0,0,0,100\n0.1,0,0,101\n{}1,90,0,300\n1.1,90,0,301\n",
            h(1, 0.0).line(),
            h(2, 90.0).line()
        );
        std::fs::write(&p, &text).unwrap();
        assert_eq!(HeadAt::read_all(&p).unwrap(), vec![h(1, 0.0), h(2, 90.0)]);
        let plain =
            text.lines().filter(|l| !l.starts_with("# head_at")).collect::<Vec<_>>().join("\n") + "\n";
        assert_eq!(
            super::super::tests::parse(&text).unwrap().len(),
            super::super::tests::parse(&plain).unwrap().len()
        );
    }
}
