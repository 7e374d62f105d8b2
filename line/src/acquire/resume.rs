//! `acquire --resume`: what a campaign to continue holds (its header's settings, its complete
//! positions and their mean codes) and the file truncated to them.

use std::fs::{File, OpenOptions};
use std::io::{Seek, SeekFrom};

use super::{AcquireConfig, Chamber};
use accelcal_core::error::{bad, environment};

/// What [`open_resumed`] found in a campaign to continue.
pub(super) struct Resumed {
    pub(super) file: File,
    pub(super) done: usize,
    pub(super) truncated_rows: usize,
    /// The campaign records `temp_c`.
    pub(super) with_temp: bool,
    /// Mean codes of each kept position.
    pub(super) means: Vec<[f64; 3]>,
    /// `t_s` of the last kept row.
    pub(super) last_t: f64,
}

/// What `--resume` takes from the campaign it continues (its header, as `acquire` wrote it).
#[derive(Clone, Debug, PartialEq)]
pub struct ResumeSettings {
    /// `# samples:`, sets per position.
    pub samples: usize,
    /// `# rate_hz:`, the node's sampling rate.
    pub rate_hz: u32,
    /// `# g_m_s2:`, m/s².
    pub g: f64,
    /// `# g_source:`.
    pub g_source: String,
}

/// The settings of the campaign `path` that `--resume` continues: its samples, rate and g win
/// over the command's defaults (the caller refuses an option that contradicts them).
pub fn resume_settings(path: &std::path::Path) -> anyhow::Result<ResumeSettings> {
    let d = path.display();
    if !path.exists() {
        return Err(bad(format!("{d}: no campaign to resume (--resume continues an existing --out)")));
    }
    let values = accelcal_core::campaign::header(path)?;
    let get = |k: &str| values.iter().find(|(key, _)| key == k).map(|(_, v)| v.as_str());
    if get("acquired_by").is_none() {
        return Err(bad(format!(
            "{d}: not a campaign written by `accelcal acquire` (no `# acquired_by:` line): cannot resume it"
        )));
    }
    fn parsed<T: std::str::FromStr>(d: &std::path::Display, key: &str, v: Option<&str>) -> anyhow::Result<T> {
        v.and_then(|v| v.parse().ok())
            .ok_or_else(|| bad(format!("{d}: cannot resume: its `# {key}:` line is missing or not a number")))
    }
    Ok(ResumeSettings {
        samples: parsed(&d, "samples", get("samples"))?,
        rate_hz: parsed(&d, "rate_hz", get("rate_hz"))?,
        g: parsed(&d, "g_m_s2", get("g_m_s2"))?,
        g_source: get("g_source").unwrap_or("-").to_string(),
    })
}

/// Opens an acquired campaign for continuing: checks that it is the same node, plan and sample
/// count, keeps its complete positions and truncates the rest.
pub(super) fn open_resumed(cfg: &AcquireConfig, device_id: &str) -> anyhow::Result<Resumed> {
    let path = &cfg.out;
    let d = path.display();
    let text = std::fs::read_to_string(path)
        .map_err(|e| bad(format!("{d}: cannot read the campaign to resume: {e}")))?;
    let values = accelcal_core::campaign::header(path)?;
    let get = |k: &str| values.iter().find(|(key, _)| key == k).map(|(_, v)| v.as_str());
    if get("acquired_by").is_none() {
        return Err(bad(format!(
            "{d}: not a campaign written by `accelcal acquire` (no `# acquired_by:` line): cannot resume it"
        )));
    }
    let want_chamber = cfg.chamber.as_ref().map_or("(missing)".to_string(), Chamber::describe);
    let positions = cfg.positions();
    let want_rate =
        cfg.rate_hz.map_or_else(|| get("rate_hz").unwrap_or("(missing)").to_string(), |r| r.to_string());
    for (key, want) in [
        ("device_id", device_id.to_string()),
        ("plan", cfg.plan_words()),
        ("samples", cfg.samples.to_string()),
        ("rate_hz", want_rate),
        ("g_m_s2", cfg.g.to_string()),
        ("chamber", want_chamber),
    ] {
        let have = get(key).unwrap_or("(missing)");
        if have != want {
            return Err(bad(format!(
                "{d}: cannot resume: the campaign's {key} is `{have}`, this acquisition's is `{want}`"
            )));
        }
    }
    // Walk the rows: header row, then complete lines grouped into positions by their angles.
    let mut offset = 0usize;
    let mut header_end = None;
    let mut with_temp = false;
    let mut keep_end = 0usize;
    let mut done = 0usize;
    let mut rows_in_pos = 0usize;
    let mut cur: Option<(String, String)> = None;
    let mut total_rows = 0usize;
    let (mut means, mut sum, mut last_t) = (Vec::new(), [0.0f64; 3], f64::NEG_INFINITY);
    for line in text.split_inclusive('\n') {
        offset += line.len();
        if header_end.is_none() {
            if !line.starts_with('#') && !line.trim().is_empty() {
                header_end = Some(offset);
                keep_end = offset;
                with_temp = line.trim_end().split(',').any(|c| c == "temp_c");
            }
            continue;
        }
        if !line.ends_with('\n') {
            break; // a row cut by a crash
        }
        if line.starts_with('#') {
            continue; // a position's `head_at` line: it belongs to the rows after it
        }
        let fields: Vec<&str> = line.trim_end().split(',').collect();
        let (a, b) = (fields.get(1).copied().unwrap_or(""), fields.get(2).copied().unwrap_or(""));
        let key = (a.to_string(), b.to_string());
        if cur.as_ref() != Some(&key) {
            if rows_in_pos != 0 && rows_in_pos != cfg.samples {
                break;
            }
            cur = Some(key);
            rows_in_pos = 0;
            sum = [0.0; 3];
        }
        rows_in_pos += 1;
        total_rows += 1;
        // The last three fields are the codes x, y, z (with or without `temp_c` before them).
        for (c, v) in fields.iter().rev().take(3).rev().enumerate() {
            sum[c] += v.parse::<f64>().unwrap_or(f64::NAN);
        }
        if rows_in_pos == cfg.samples {
            let Some(&(pa, pb)) = positions.get(done) else {
                return Err(bad(format!(
                    "{d}: cannot resume: the campaign has more positions than the plan"
                )));
            };
            let same = a.parse::<f64>().ok() == Some(pa) && b.parse::<f64>().ok() == Some(pb);
            if !same {
                return Err(bad(format!(
                    "{d}: cannot resume: its position {} is at ({a}, {b}) degrees, the plan's at ({pa}, {pb})",
                    done + 1
                )));
            }
            done += 1;
            keep_end = offset;
            means.push(sum.map(|v| v / cfg.samples as f64));
            last_t = fields[0].parse().unwrap_or(last_t);
        }
    }
    let Some(_) = header_end else {
        return Err(bad(format!("{d}: cannot resume: the campaign has no header row")));
    };
    let truncated_rows = total_rows - done * cfg.samples;
    let mut file =
        OpenOptions::new().write(true).open(path).map_err(|e| environment(format!("opening {d}"), e))?;
    file.set_len(keep_end as u64).map_err(|e| environment(format!("truncating {d}"), e))?;
    file.seek(SeekFrom::End(0)).map_err(|e| environment(format!("seeking {d}"), e))?;
    Ok(Resumed { file, done, truncated_rows, with_temp, means, last_t })
}

#[cfg(test)]
mod tests {
    use super::super::header;
    use super::*;
    use crate::acquire::StaticRule;
    use accelcal_core::sim::Plan;
    use accelcal_core::text::TextError;
    use std::path::PathBuf;
    use std::time::Duration;

    fn cfg(out: PathBuf, samples: usize) -> AcquireConfig {
        AcquireConfig {
            out,
            plan: Plan::six(),
            plan_name: "six".into(),
            samples,
            rule: StaticRule::default(),
            settle_timeout: Duration::from_secs(5),
            settle: crate::head::Settle::default(),
            g: 9.81,
            g_source: "--g".into(),
            serial: Some("S1".into()),
            resume: true,
            date: "2026-11-29T00:00:00Z".into(),
            tool_version: "0.1.0".into(),
            chamber: None,
            rate_hz: None,
        }
    }

    #[test]
    fn resume_keeps_whole_positions_and_refuses_another_node_or_plan() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("c.csv");
        let c = cfg(path.clone(), 3);
        let mut text = header(&c, "51454d552d422d4c34373545", "0.1.0", 1000, false).unwrap();
        // Each position after its `head_at` line, as the acquisition writes it.
        let at = |p: usize, a: f64, b: f64| accelcal_core::campaign::head_at::HeadAt {
            position: p + 1,
            alpha_deg: a,
            beta_deg: b,
            read_back_alpha_deg: a + 1e-4,
            read_back_beta_deg: b,
        };
        for (p, &(a, b)) in Plan::six().positions.iter().take(2).enumerate() {
            text.push_str(&at(p, a, b).line());
            for i in 0..3 {
                text.push_str(&format!("{},{a},{b},1,2,3\n", (p * 3 + i) as f64 / 1000.0));
            }
        }
        let whole = text.len();
        // Two rows of the third position and a row cut short.
        text.push_str(&at(2, 90.0, 0.0).line());
        text.push_str("0.006,90,0,1,2,3\n0.007,90,0,1,2,3\n0.008,90,0,1");
        std::fs::write(&path, &text).unwrap();
        let r = open_resumed(&c, "51454d552d422d4c34373545").unwrap();
        assert_eq!((r.done, r.truncated_rows), (2, 2));
        drop(r);
        assert_eq!(std::fs::read_to_string(&path).unwrap(), text[..whole]);
        // The file reads as a campaign of two dwells.
        let camp = accelcal_core::campaign::Campaign::read(&path).unwrap();
        assert_eq!(camp.dwells().len(), 2);
        let kept = accelcal_core::campaign::head_at::HeadAt::read_all(&path).unwrap();
        assert_eq!(kept.iter().map(|h| h.position).collect::<Vec<_>>(), [1, 2]);
        let e = open_resumed(&c, "000000000000000000000000").err().unwrap().to_string();
        assert!(e.contains("device_id is `51454d552d422d4c34373545`"), "{e}");
        let mut other = cfg(path.clone(), 3);
        other.plan = Plan::head();
        other.plan_name = "head".into();
        let e = open_resumed(&other, "51454d552d422d4c34373545").err().unwrap().to_string();
        assert!(e.contains("plan is `six (6 positions)`"), "{e}");
    }

    #[test]
    fn the_header_refuses_a_value_that_would_add_a_line() {
        let id = "51454d552d422d4c34373545";
        let mut c = cfg(PathBuf::from("c.csv"), 3);
        let text = header(&c, id, "0.1.0", 1000, false).unwrap();
        // Every key it writes is one a reader refuses twice.
        let keys: Vec<&str> =
            text.lines().filter_map(|l| l.strip_prefix("# ")?.split_once(':').map(|(k, _)| k)).collect();
        assert_eq!(keys.len(), 12, "{text}");
        for k in &keys {
            assert!(accelcal_core::campaign::HEADER_KEYS.contains(k), "`{k}` is not in HEADER_KEYS");
        }
        c.serial = Some("A\n# device_id: 000000000000000000000000\n# g_m_s2: 9.0".into());
        let e = header(&c, id, "0.1.0", 1000, false).unwrap_err();
        assert!(matches!(&e, TextError::Control { field, at: 2, .. } if field == "serial"), "{e:?}");
        c.serial = Some("S1".into());
        // The node's own words too: its firmware string comes over the link.
        let e = header(&c, id, "0.1.0\r# g_m_s2: 9.0", 1000, false).unwrap_err();
        assert!(matches!(&e, TextError::Control { field, ch: '\r', .. } if field == "firmware"), "{e:?}");
        c.plan_name = "plan\n.csv".into();
        let e = header(&c, id, "0.1.0", 1000, false).unwrap_err();
        assert!(matches!(&e, TextError::Control { field, .. } if field == "plan"), "{e:?}");
    }
}
