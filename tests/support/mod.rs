//! Helpers shared by the QEMU test binaries (`hil.rs`, `hil_load.rs`): where the node's QEMU build
//! is, and record bytes.

use std::path::{Path, PathBuf};
use std::process::Command;

use accelcal_shared::record::{Record, MAX_RECORD_LEN};

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
        "{} is missing: build it with `cargo xtask test` (or `cd firmware && {build}`)",
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
