//! `cargo xtask bench station`: how a station run's time is spent, in emulation, with one node
//! and with four on one head (issue 32 item 3). Each run is `accelcal station` on an emulated
//! bench (`accelcal emulate`, a simulated unit per node, the head at 600°/s); the station's last
//! line states each step's time from the units' journals and the share of the run during which
//! the head was neither moving nor dwelling.

use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Command, Stdio};

use anyhow::Context;

/// The station's command line on an emulated bench, the one the line tests run.
#[path = "../../tests/support/station_line.rs"]
mod station_line;
use station_line::{station_line, Unit};

/// Node counts measured.
const NODES: [usize; 2] = [1, 4];

pub fn bench() -> anyhow::Result<()> {
    let (exe, elf) = crate::live::emulated_bench()?;
    let mut lines = Vec::new();
    for n in NODES {
        lines.push((n, station(&exe, &elf, n)?));
    }
    println!("station time (release build, emulated head at 600°/s, random:24 plan, 200 sets at 1 kHz per position):");
    for (n, line) in lines {
        println!("  {n} node{}: {line}", if n == 1 { "" } else { "s" });
    }
    Ok(())
}

/// One station run with `n` nodes; the station's time line.
fn station(exe: &Path, elf: &Path, n: usize) -> anyhow::Result<String> {
    let dir = std::env::temp_dir().join(format!("accelcal-station-bench-{}-{n}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir)?;
    let mut em = Command::new(exe);
    em.args(["emulate", "--qemu"]).arg(elf).args(["--head-speed", "600"]);
    for i in 0..n {
        let unit = dir.join(format!("unit-{i}.json"));
        let out = Command::new(exe)
            .args(["simulate", "--samples", "2", "--seed", &(i + 1).to_string(), "-o"])
            .arg(dir.join(format!("unit-{i}.csv")))
            .arg("--truth")
            .arg(&unit)
            .output()?;
        anyhow::ensure!(out.status.success(), "simulate failed: {}", String::from_utf8_lossy(&out.stderr));
        em.arg("--unit").arg(&unit);
    }
    let mut em =
        em.stdout(Stdio::piped()).stderr(Stdio::null()).spawn().context("starting accelcal emulate")?;
    let mut line = String::new();
    BufReader::new(em.stdout.take().expect("piped")).read_line(&mut line)?;
    let result = (|| {
        let v: serde_json::Value =
            serde_json::from_str(&line).with_context(|| format!("emulate printed `{line}`"))?;
        let head = v["head"].as_str().context("no head")?.to_string();
        let nodes = v["nodes"].as_array().context("no nodes")?;
        let mut units = Vec::new();
        for (i, node) in nodes.iter().enumerate() {
            let field = |key: &str| node[key].as_str().map(str::to_string).context("node field");
            units.push((
                field("port")?,
                field("gdb")?,
                format!("B-{i}"),
                dir.join(format!("b-{i}")).display().to_string(),
            ));
        }
        let units: Vec<Unit> =
            units.iter().map(|(port, gdb, serial, out)| Unit { port, gdb, serial, out }).collect();
        let db = dir.join("line.sqlite").display().to_string();
        let mut args = station_line(&head, &units);
        args.extend_from_slice(&["--db", &db]);
        eprintln!("$ accelcal {}", args.join(" "));
        let out = Command::new(exe)
            .args(&args)
            .stdin(Stdio::null())
            .output()
            .context("running accelcal station")?;
        let err = String::from_utf8_lossy(&out.stderr);
        anyhow::ensure!(out.status.success(), "station failed: {err}");
        err.lines()
            .find_map(|l| l.strip_prefix("station: time "))
            .map(|l| format!("time {l}"))
            .context("the station printed no time line")
    })();
    let _ = Command::new("kill").args(["-INT", &em.id().to_string()]).status();
    let _ = em.wait();
    let _ = std::fs::remove_dir_all(&dir);
    result
}
