//! `cargo xtask bench live`: sample sets per second through the node's live path in QEMU. The
//! emulated bench (`accelcal emulate`, a simulated unit on the front end) runs the node's QEMU
//! build; `accelcal monitor --rate-hz R` reads its stream for a fixed time at each rate, counting the
//! sets that arrive and the sets the node reports lost (jumps of its sample counter).

use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::Instant;

use anyhow::Context;

use crate::{root, run};

/// Seconds measured at each rate.
const SECONDS: u64 = 30;
/// Rates measured, Hz.
const RATES: [u32; 6] = [100, 250, 500, 750, 1000, 2000];

/// What an emulated bench needs: QEMU, the node's QEMU build and the release `accelcal`; the
/// paths of the binary and of the node's image.
pub fn emulated_bench() -> anyhow::Result<(std::path::PathBuf, std::path::PathBuf)> {
    let r = root();
    crate::firmware::prepare()?;
    crate::firmware::setup_qemu()?;
    crate::firmware::build_qemu()?;
    run(&r, "cargo", &["build", "--release", "--locked", "-p", "accelcal"])?;
    Ok((r.join("target/release/accelcal"), crate::firmware::elf("node-qemu")))
}

pub fn bench() -> anyhow::Result<()> {
    let (exe, elf) = emulated_bench()?;
    let dir = std::env::temp_dir().join(format!("accelcal-live-bench-{}", std::process::id()));
    std::fs::create_dir_all(&dir)?;
    let unit = dir.join("unit.json");
    let out = Command::new(&exe)
        .args(["simulate", "--samples", "2", "-o"])
        .arg(dir.join("unit.csv"))
        .arg("--truth")
        .arg(&unit)
        .output()?;
    anyhow::ensure!(out.status.success(), "simulate failed: {}", String::from_utf8_lossy(&out.stderr));
    let mut em = Command::new(&exe)
        .args(["emulate", "--qemu"])
        .arg(&elf)
        .arg("--unit")
        .arg(&unit)
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .context("starting accelcal emulate")?;
    let mut line = String::new();
    BufReader::new(em.stdout.take().expect("piped")).read_line(&mut line)?;
    let port = string_field(&line, "port").with_context(|| format!("no port in emulate's line `{line}`"))?;
    let result = sweep(&exe, &port);
    let _ = Command::new("kill").args(["-INT", &em.id().to_string()]).status();
    let _ = em.wait();
    let _ = std::fs::remove_dir_all(&dir);
    result
}

/// The string value of `key` in a flat JSON object of strings (what `emulate` prints).
fn string_field(line: &str, key: &str) -> Option<String> {
    let start = line.find(&format!("\"{key}\":\""))? + key.len() + 4;
    let len = line[start..].find('"')?;
    Some(line[start..start + len].to_string())
}

/// Measures every rate of [`RATES`].
fn sweep(exe: &Path, port: &str) -> anyhow::Result<()> {
    let mut rows = Vec::new();
    for rate in RATES {
        // Blocks of 16 sets plus one status a second.
        let count = (rate as u64 * SECONDS / 16 + SECONDS).to_string();
        let t0 = Instant::now();
        let out = Command::new(exe)
            .args(["monitor", "--port", port, "--rate-hz", &rate.to_string(), "--count", &count])
            .output()
            .context("running accelcal monitor")?;
        let secs = t0.elapsed().as_secs_f64();
        anyhow::ensure!(out.status.success(), "monitor failed: {}", String::from_utf8_lossy(&out.stderr));
        let text = String::from_utf8_lossy(&out.stdout);
        let (mut sets, mut lost) = (0u64, 0u64);
        for l in text.lines() {
            if let Some(rest) = l.strip_prefix("# gap: ") {
                lost += rest.split_whitespace().next().and_then(|n| n.parse::<u64>().ok()).unwrap_or(0);
            } else if !(l.starts_with('#') || l.starts_with("status:") || l.contains(" set: ")) {
                sets += 1;
            }
        }
        rows.push((rate, secs, sets, lost));
    }
    println!();
    println!("live path in QEMU (accelcal emulate -> node-qemu -> accelcal monitor), {SECONDS} s of stream per rate:");
    println!(
        "  {:>8} {:>8} {:>10} {:>10} {:>12} {:>8}",
        "rate Hz", "time s", "received", "lost", "received/s", "lost %"
    );
    for (rate, secs, sets, lost) in rows {
        let pct = 100.0 * lost as f64 / (sets + lost).max(1) as f64;
        println!("  {rate:>8} {secs:>8.1} {sets:>10} {lost:>10} {:>12.0} {pct:>8.2}", sets as f64 / secs);
    }
    Ok(())
}
