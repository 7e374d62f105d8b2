//! Position plans for the dividing head: built-in ones and plan files.

use std::path::Path;

use rand::{Rng, SeedableRng};

/// The header key of a plan file's sample sets per position (`# samples: 800`), as a campaign's.
pub const SAMPLES_KEY: &str = "samples";
/// The header key of a plan file's sample rate, Hz (`# rate_hz: 500`), as a campaign's.
pub const RATE_KEY: &str = "rate_hz";

/// What a plan file's header states about its dwell (`plan --design` writes both; an older plan
/// file, or one written by hand, may state neither).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PlanHeader {
    /// `# samples:`: sample sets per position.
    pub samples: Option<usize>,
    /// `# rate_hz:`: the sample rate the dwell was designed at, Hz.
    pub rate_hz: Option<f64>,
}

impl PlanHeader {
    /// The header lines of a plan file with these values (each `# key: value` and a line feed).
    pub fn lines(&self) -> String {
        let mut s = String::new();
        if let Some(n) = self.samples {
            s.push_str(&format!("# {SAMPLES_KEY}: {n}\n"));
        }
        if let Some(r) = self.rate_hz {
            s.push_str(&format!("# {RATE_KEY}: {r}\n"));
        }
        s
    }

    /// Reads the `# key: value` comment lines before a plan file's header row: `# samples:` and
    /// `# rate_hz:`, each at most once; other comments are free text.
    pub fn read(path: &Path) -> Result<PlanHeader, String> {
        let d = path.display();
        let text = std::fs::read(path)
            .map_err(|e| format!("{d}: {e} (a plan is head, six, random:N or a plan file)"))?;
        Self::parse(&String::from_utf8_lossy(&text), &d.to_string())
    }

    /// [`PlanHeader::read`] on a plan file's text; `name` names the file in errors.
    pub fn parse(text: &str, name: &str) -> Result<PlanHeader, String> {
        let mut h = PlanHeader::default();
        let mut seen: [Option<usize>; 2] = [None, None];
        for (i, line) in text.lines().enumerate() {
            let line_no = i + 1;
            let t = line.trim();
            if t.is_empty() {
                continue;
            }
            let Some(comment) = t.strip_prefix('#') else { break };
            let Some((key, value)) = comment.split_once(':') else { continue };
            let (key, value) = (key.trim(), value.trim());
            let slot = match key {
                SAMPLES_KEY => 0,
                RATE_KEY => 1,
                _ => continue,
            };
            if let Some(first) = seen[slot] {
                return Err(format!(
                    "{name}:{line_no}: a second `# {key}:` line (the first is line {first})"
                ));
            }
            seen[slot] = Some(line_no);
            if slot == 0 {
                match value.parse::<usize>() {
                    Ok(n) if n > 0 => h.samples = Some(n),
                    _ => {
                        return Err(format!(
                            "{name}:{line_no}: `# {key}: {value}` is not a positive number of sample sets"
                        ))
                    }
                }
            } else {
                match value.parse::<f64>() {
                    Ok(r) if r.is_finite() && r > 0.0 => h.rate_hz = Some(r),
                    _ => {
                        return Err(format!(
                            "{name}:{line_no}: `# {key}: {value}` is not a positive rate in Hz"
                        ))
                    }
                }
            }
        }
        Ok(h)
    }
}

/// An ordered list of head positions `(alpha_deg, beta_deg)`.
#[derive(Clone, Debug, PartialEq)]
pub struct Plan {
    /// The positions, in the order the head visits them.
    pub positions: Vec<(f64, f64)>,
}

impl Plan {
    /// The default dividing-head plan: β ∈ {−60, −30, 0, 30, 60} × α every 30°, then β = ±90°
    /// (62 positions). It contains the six test-turn positions (each axis along ±g).
    pub fn head() -> Plan {
        let mut positions = Vec::new();
        for b in [-60.0, -30.0, 0.0, 30.0, 60.0] {
            for a in (0..12).map(|i| i as f64 * 30.0) {
                positions.push((a, b));
            }
        }
        positions.push((0.0, 90.0));
        positions.push((0.0, -90.0));
        Plan { positions }
    }

    /// The six test-turn positions: −z, +z, −x, +x, −y, +y along g.
    pub fn six() -> Plan {
        Plan {
            positions: vec![(0.0, 0.0), (180.0, 0.0), (90.0, 0.0), (270.0, 0.0), (0.0, 90.0), (0.0, -90.0)],
        }
    }

    /// A 24-position multipoint tumble (IEEE Std 1293-2018, the multipoint tumble test) for a
    /// triad: the block turned through a full circle in 45° steps in each of the three planes
    /// through two of its axes, 8 positions per circle; each ±axis orientation lies on two
    /// circles, so it is visited twice.
    pub fn tumble24() -> Plan {
        let mut positions = Vec::new();
        // The x–z plane: β = 0, α all round.
        positions.extend((0..8).map(|i| (i as f64 * 45.0, 0.0)));
        // The y–z plane: α = 0 and 180, β across.
        positions.extend([-90.0, -45.0, 0.0, 45.0, 90.0].map(|b| (0.0, b)));
        positions.extend([45.0, 0.0, -45.0].map(|b| (180.0, b)));
        // The x–y plane: α = 90 and 270, β across.
        positions.extend([-90.0, -45.0, 0.0, 45.0, 90.0].map(|b| (90.0, b)));
        positions.extend([45.0, 0.0, -45.0].map(|b| (270.0, b)));
        Plan { positions }
    }

    /// `n` orientations drawn uniformly on the sphere (angles rounded to 0.01°), seeded.
    pub fn random(n: usize, seed: u64) -> Plan {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed ^ 0x706c_616e);
        let positions = (0..n)
            .map(|_| {
                let a: f64 = rng.random_range(0.0..360.0);
                let b = (2.0 * rng.random::<f64>() - 1.0).asin().to_degrees();
                ((a * 100.0).round() / 100.0, (b * 100.0).round() / 100.0)
            })
            .collect();
        Plan { positions }
    }

    /// Parses a plan spec: `head`, `six`, `tumble24`, `random:N`, or the path of a plan file (CSV with the
    /// columns `alpha_deg,beta_deg`, `#` comments allowed).
    pub fn from_spec(spec: &str, seed: u64) -> Result<Plan, String> {
        match spec {
            "head" => Ok(Plan::head()),
            "six" => Ok(Plan::six()),
            "tumble24" => Ok(Plan::tumble24()),
            _ => {
                if let Some(n) = spec.strip_prefix("random:") {
                    return match n.parse::<usize>() {
                        Ok(n) if n > 0 => Ok(Plan::random(n, seed)),
                        _ => Err(format!("`{spec}`: expected random:N with N a positive integer")),
                    };
                }
                Plan::read(Path::new(spec))
            }
        }
    }

    /// Reads a plan file.
    pub fn read(path: &Path) -> Result<Plan, String> {
        let d = path.display();
        let mut rdr = csv::ReaderBuilder::new()
            .comment(Some(b'#'))
            .trim(csv::Trim::All)
            .from_path(path)
            .map_err(|e| format!("{d}: {e} (a plan is head, six, random:N or a plan file)"))?;
        let header = rdr.headers().map_err(|e| format!("{d}: {e}"))?.clone();
        let col =
            |n: &str| header.iter().position(|h| h == n).ok_or_else(|| format!("{d}: missing column `{n}`"));
        let (ai, bi) = (col("alpha_deg")?, col("beta_deg")?);
        let mut positions = Vec::new();
        for rec in rdr.records() {
            let rec = rec.map_err(|e| format!("{d}: {e}"))?;
            let line = rec.position().map(|p| p.line()).unwrap_or(0);
            let num = |i: usize| -> Result<f64, String> {
                rec.get(i)
                    .and_then(|s| s.parse::<f64>().ok())
                    .filter(|v| v.is_finite())
                    .ok_or_else(|| format!("{d}:{line}:{}: expected a finite angle in degrees", i + 1))
            };
            positions.push((num(ai)?, num(bi)?));
        }
        if positions.is_empty() {
            return Err(format!("{d}: the plan has no positions"));
        }
        Ok(Plan { positions })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_plan_header_states_its_dwell_once() {
        let text = "# designed by accelcal plan --design 12: 12 positions\n# samples: 800\n# rate_hz: 500\nalpha_deg,beta_deg\n# samples: 3\n0,0\n";
        let h = PlanHeader::parse(text, "p.csv").unwrap();
        assert_eq!(h, PlanHeader { samples: Some(800), rate_hz: Some(500.0) });
        assert_eq!(PlanHeader::parse(&h.lines(), "q").unwrap(), h);
        assert_eq!(
            PlanHeader::parse("# plan by hand\nalpha_deg,beta_deg\n0,0\n", "p").unwrap(),
            PlanHeader::default()
        );
        for (bad, why) in [
            ("# samples: 800\n# samples: 400\n", "p.csv:2: a second `# samples:` line (the first is line 1)"),
            ("# samples: 0\n", "p.csv:1: `# samples: 0` is not a positive number of sample sets"),
            ("# rate_hz: fast\n", "p.csv:1: `# rate_hz: fast` is not a positive rate in Hz"),
            ("# rate_hz: inf\n", "p.csv:1: `# rate_hz: inf` is not a positive rate in Hz"),
        ] {
            assert_eq!(PlanHeader::parse(bad, "p.csv").unwrap_err(), why);
        }
    }
}
