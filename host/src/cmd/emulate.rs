//! `accelcal emulate`: the emulated bench (the node in QEMU, a simulated unit's front end, an
//! emulated dividing head) until Ctrl-C or SIGTERM.

use std::io::Write;
use std::sync::atomic::Ordering;

use accelcal_core::error::bad;
use accelcal_core::sim::Unit;
use accelcal_line::emulate::bench::{Bench, BenchOptions, NodeOptions};
use accelcal_line::emulate::head::SensorTemp;
use accelcal_line::emulate::{Motion, PaceOptions};

use crate::settings::line::Emulate;

/// Runs `accelcal emulate`.
pub fn run(a: &Emulate) -> anyhow::Result<()> {
    let units = a.units.iter().map(|u| Unit::read_for_node(&u.file)).collect::<Result<Vec<_>, _>>()?;
    if !a.elf.is_file() {
        return Err(bad(format!(
            "{}: no such firmware ELF (build it with `cargo xtask test` or see firmware/README.md)",
            a.elf.display()
        )));
    }
    let mut nodes = Vec::with_capacity(units.len());
    for (u, unit) in a.units.iter().zip(units) {
        let record = match &u.record {
            Some(p) => Some(
                std::fs::read(p).map_err(|e| bad(format!("{}: cannot read the record: {e}", p.display())))?,
            ),
            None => None,
        };
        nodes.push(NodeOptions { seed: u.seed.unwrap_or(unit.seed), unit, record });
    }
    let opts = BenchOptions {
        qemu: a.qemu_bin.clone(),
        elf: a.elf.clone(),
        nodes,
        motion: Motion { speed_deg_s: a.head_speed_deg_s, ..Motion::default() },
        sensor: SensorTemp::soaked(a.chamber_c, a.thermal_lag_s),
        pace: PaceOptions { rate_factor: a.rate_factor, ..PaceOptions::default() },
        gdb_port: a.gdb_port,
        head_port: a.head_port,
        head: a.head,
        head_fault: a.head_fault,
        first_node: a.first_node,
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
        errln!(
            "emulate: node running in QEMU, link {}, gdbstub {}, head {}; Ctrl-C stops",
            node.port,
            node.gdb,
            bench.endpoints.head
        );
    } else {
        for (i, node) in nodes.iter().enumerate() {
            errln!(
                "emulate: node {} of {} ({}) running in QEMU, device {}, link {}, gdbstub {}",
                i + 1,
                nodes.len(),
                a.units[i].file.display(),
                node.device_id,
                node.port,
                node.gdb
            );
        }
        errln!("emulate: head {} shared by the {} nodes; Ctrl-C stops", bench.endpoints.head, nodes.len());
    }
    let result = bench.run_until(&stop);
    let several = bench.nodes.len() > 1;
    for (i, n) in bench.nodes.iter().enumerate() {
        let which = if several { format!(" of node {}", i + 1) } else { String::new() };
        errln!(
            "emulate: stopped; the front end{which} sent {} sample sets at {} Hz ({} skipped because QEMU fell behind)",
            n.counters.sent.load(Ordering::Relaxed),
            n.rate_hz.load(Ordering::Relaxed),
            n.counters.skipped.load(Ordering::Relaxed)
        );
    }
    drop(bench);
    result.map_err(|e| e.context("the emulated node stopped"))
}
