//! Helpers shared by the QEMU tests (`hil`, `hil_load`, `live`, `line`): where the node's QEMU
//! build is, record bytes, and the one emulated bench at a time.

pub mod station_line;

use std::path::{Path, PathBuf};
use std::process::Command;

use accelcal_shared::record::{Record, TempSource, Thermal, MAX_RECORD_LEN};
use accelcal_shared::thermal::ThermalModel;

/// The node's QEMU build: `ACCELCAL_NODE_QEMU_ELF`, else the firmware's release target directory.
/// Fails, naming the command that provides it, when the ELF or `qemu-system-arm` with the
/// b-l475e-iot01a machine is missing.
pub fn node_elf() -> PathBuf {
    let elf = firmware_elf(
        "ACCELCAL_NODE_QEMU_ELF",
        "target/thumbv7em-none-eabihf/release/node-qemu",
        "cargo build --release --features board-qemu --bin node-qemu",
    );
    let qemu_ok = Command::new("qemu-system-arm")
        .args(["-M", "help"])
        .output()
        .is_ok_and(|o| String::from_utf8_lossy(&o.stdout).contains("b-l475e-iot01a"));
    assert!(
        qemu_ok,
        "qemu-system-arm with the b-l475e-iot01a machine is missing: run `bash scripts/setup-qemu.sh`"
    );
    elf
}

/// A firmware build: the path in the environment variable `var`, else `default` under
/// `firmware/`; fails naming `build` (run in `firmware/`) when the file is missing.
pub fn firmware_elf(var: &str, default: &str, build: &str) -> PathBuf {
    let elf = std::env::var_os(var)
        .map(PathBuf::from)
        .unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("../firmware").join(default));
    assert!(
        elf.is_file(),
        "{} is missing: build it with `cargo xtask firmware` (or `cd firmware && {build}`)",
        elf.display()
    );
    elf
}

/// The bytes of a record.
pub fn record_bytes(r: &Record) -> Vec<u8> {
    let mut buf = [0u8; MAX_RECORD_LEN];
    let n = r.emit(&mut buf).unwrap();
    buf[..n].to_vec()
}

/// The thermal model the QEMU tests load (`hil.rs`, `live.rs`): model 4 of a plausible triad with
/// `t` (3 codes/°C of bias on each channel) and `ax*t`, `ay*t`, `az*t` (100 ppm/°C of each
/// sensitivity, the unit), read from the front end, calibrated over −10..50 °C.
/// One emulated bench at a time (the tests of `line`, `live` and `hil_load`): each runs QEMU,
/// which spins a host core, and a paced front end; two at once on a 2-core machine starve each
/// other (the tests would pass, slower and with more lost sets). Under nextest the test group
/// `bench` (`.config/nextest.toml`) does the same across processes.
static ONE_BENCH: std::sync::Mutex<()> = std::sync::Mutex::new(());

/// Waits for the emulated bench to be free; it is this test's until the guard is dropped.
pub fn one_bench() -> std::sync::MutexGuard<'static, ()> {
    ONE_BENCH.lock().unwrap_or_else(|e| e.into_inner())
}

pub fn thermal_model() -> ThermalModel {
    let k = [[1671.2, 8.5, -3.25], [-4.0, 1650.75, 6.5], [2.5, -7.75, 1689.0]];
    ThermalModel {
        thermal: Thermal { t_ref_c: 25.0, t_min_c: -10.0, t_max_c: 50.0, source: TempSource::FrontEnd },
        bias: [[32100.5, 3.0, 0.0], [33012.25, 3.0, 0.0], [31877.75, 3.0, 0.0]],
        k,
        kt: k.map(|r| r.map(|v| v * 1e-4)),
    }
}
