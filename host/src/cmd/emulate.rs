//! `accelcal emulate`: the emulated bench (the node in QEMU, a simulated unit's front end, an
//! emulated dividing head) until Ctrl-C or SIGTERM.

use std::io::Write;
use std::sync::atomic::Ordering;

use accelcal_core::error::bad;
use accelcal_core::sim::Unit;
use accelcal_line::emulate::bench::{Bench, BenchOptions, NodeOptions};
use accelcal_line::emulate::head::SensorTemp;
use accelcal_line::emulate::{Motion, PaceOptions};

use crate::cli::EmulateArgs;

/// Runs `accelcal emulate`.
pub fn run(a: &EmulateArgs) -> anyhow::Result<()> {
    if !accelcal_line::node::head::CHAMBER_RANGE_C.contains(&a.chamber) {
        return Err(bad(format!("--chamber must be a temperature in -60..=150 °C, got {}", a.chamber)));
    }
    if !(a.thermal_lag_s.is_finite() && a.thermal_lag_s >= 0.0) {
        return Err(bad(format!(
            "--thermal-lag-s must be a number of seconds >= 0, got {}",
            a.thermal_lag_s
        )));
    }
    let units = a.unit.iter().map(|p| Unit::read_for_node(p)).collect::<Result<Vec<_>, _>>()?;
    if !a.elf.is_file() {
        return Err(bad(format!(
            "{}: no such firmware ELF (build it with `cargo xtask test` or see firmware/README.md)",
            a.elf.display()
        )));
    }
    let mut nodes = Vec::with_capacity(units.len());
    for (i, unit) in units.into_iter().enumerate() {
        let record = match a.record.get(i) {
            Some(p) => Some(
                std::fs::read(p).map_err(|e| bad(format!("{}: cannot read the record: {e}", p.display())))?,
            ),
            None => None,
        };
        nodes.push(NodeOptions { seed: a.seed.get(i).copied().unwrap_or(unit.seed), unit, record });
    }
    let opts = BenchOptions {
        qemu: a.qemu_bin.clone(),
        elf: a.elf.clone(),
        nodes,
        motion: Motion { speed_deg_s: a.head_speed, ..Motion::default() },
        sensor: SensorTemp::soaked(a.chamber, a.thermal_lag_s),
        pace: PaceOptions { rate_factor: a.rate_factor, ..PaceOptions::default() },
        gdb_port: a.gdb_port.unwrap_or(0),
        head_port: a.head_port.unwrap_or(0),
        first_node: usize::from(a.first_node) - 1,
    };
    let stop = super::live::stop_flag()?;
    let mut bench = Bench::start(opts)?;
    let line = serde_json::to_string(&bench.endpoints)?;
    let mut out = std::io::stdout().lock();
    writeln!(out, "{line}")?;
    out.flush()?;
    drop(out);
    let nodes = &bench.endpoints.nodes;
    if let [node] = nodes.as_slice() {
        eprintln!(
            "emulate: node running in QEMU, link {}, gdbstub {}, head {}; Ctrl-C stops",
            node.port, node.gdb, bench.endpoints.head
        );
    } else {
        for (i, node) in nodes.iter().enumerate() {
            eprintln!(
                "emulate: node {} of {} ({}) running in QEMU, device {}, link {}, gdbstub {}",
                i + 1,
                nodes.len(),
                a.unit[i].display(),
                node.device_id,
                node.port,
                node.gdb
            );
        }
        eprintln!("emulate: head {} shared by the {} nodes; Ctrl-C stops", bench.endpoints.head, nodes.len());
    }
    let result = bench.run_until(&stop);
    let several = bench.nodes.len() > 1;
    for (i, n) in bench.nodes.iter().enumerate() {
        let which = if several { format!(" of node {}", i + 1) } else { String::new() };
        eprintln!(
            "emulate: stopped; the front end{which} sent {} sample sets at {} Hz ({} skipped because QEMU fell behind)",
            n.counters.sent.load(Ordering::Relaxed),
            n.rate_hz.load(Ordering::Relaxed),
            n.counters.skipped.load(Ordering::Relaxed)
        );
    }
    drop(bench);
    result.map_err(|e| e.context("the emulated node stopped"))
}
