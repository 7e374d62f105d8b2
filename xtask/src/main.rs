//! `cargo xtask`: the one entry point for developer tasks. Each subcommand prints every command
//! it runs before running it.
//!
//! - `test`: host and shared tests, the no_std build of `shared` for the MCU target, the
//!   firmware builds and the QEMU tests.
//! - `lint`: rustfmt and clippy (warnings are errors).
//! - `bench`: the benchmarks the README quotes (GMDH against the PyPI `gmdh` package).

use std::path::{Path, PathBuf};
use std::process::Command;

use anyhow::{bail, Context};

mod firmware;
mod gmdh;

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).parent().expect("xtask sits in the workspace").to_path_buf()
}

/// Runs a command in `dir`, echoing it first; fails on a non-zero exit.
pub fn run(dir: &Path, program: &str, args: &[&str]) -> anyhow::Result<()> {
    let shown = dir.strip_prefix(root()).ok().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new("."));
    eprintln!("$ (cd {}) {program} {}", shown.display(), args.join(" "));
    let status = Command::new(program)
        .args(args)
        .current_dir(dir)
        .status()
        .with_context(|| format!("starting {program}"))?;
    if !status.success() {
        bail!("`{program} {}` failed with {status}", args.join(" "));
    }
    Ok(())
}

fn test() -> anyhow::Result<()> {
    let r = root();
    // First: QEMU, both firmware builds and the QEMU tests (the workspace tests below include
    // tests/hil.rs, which needs the QEMU build).
    firmware::test()?;
    run(&r, "cargo", &["test", "--workspace", "--locked"])?;
    run(
        &r,
        "cargo",
        &[
            "build",
            "-p",
            "accelcal-shared",
            "--target",
            "thumbv7em-none-eabihf",
            "--no-default-features",
            "--locked",
        ],
    )?;
    Ok(())
}

fn lint() -> anyhow::Result<()> {
    let r = root();
    run(&r, "cargo", &["fmt", "--all", "--check"])?;
    run(&r, "cargo", &["clippy", "--workspace", "--all-targets", "--locked", "--", "-D", "warnings"])?;
    Ok(())
}

fn bench() -> anyhow::Result<()> {
    gmdh::bench(&root())?;
    firmware::bench()
}

fn main() -> anyhow::Result<()> {
    let task = std::env::args().nth(1).unwrap_or_default();
    match task.as_str() {
        "test" => test(),
        "lint" => lint(),
        "bench" => bench(),
        _ => {
            eprintln!("usage: cargo xtask <test|lint|bench>\n  test   every test: host, shared (desktop and no_std target), firmware builds, QEMU\n  lint   rustfmt --check and clippy -D warnings\n  bench  the benchmarks quoted in the README");
            std::process::exit(2)
        }
    }
}
