//! `cargo xtask`: the one entry point for developer tasks. Each subcommand prints every command
//! it runs before running it.
//!
//! - `test`: host and shared tests, the no_std build of `shared` for the MCU target, the
//!   firmware builds and the QEMU tests.
//! - `lint`: rustfmt and clippy (warnings are errors).
//! - `bench`: the benchmarks the README quotes (GMDH against the PyPI `gmdh` package).
//! - `fuzz`: the mutation fuzzer of the record parser, the record slots and the frame decoder, for
//!   a bounded time.

use std::path::{Path, PathBuf};
use std::process::Command;

use anyhow::{bail, Context};

mod firmware;
mod gmdh;
mod live;

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
    // The certificate test (tests/line.rs) prints a page with headless Chromium.
    run(&r, "bash", &["scripts/setup-chromium.sh"])?;
    // The PostgreSQL tests (tests/db_pg.rs) start throwaway clusters of Debian's server.
    run(&r, "bash", &["scripts/setup-postgres.sh"])?;
    run(&r, "cargo", &["test", "--workspace", "--locked"])?;
    // A short fuzzing run (test profile: overflow checks on, artifacts shared with the tests).
    run(&r, "cargo", &fuzz_args("test", TEST_FUZZ_SECONDS, "all"))?;
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

/// Seconds of fuzzing in `cargo xtask test` (shared between the three targets).
const TEST_FUZZ_SECONDS: &str = "10";

/// `cargo run` of the fuzzer (`fuzz/`) under `profile`, for `seconds` on `target`.
fn fuzz_args<'a>(profile: &'a str, seconds: &'a str, target: &'a str) -> Vec<&'a str> {
    vec![
        "run",
        "--locked",
        "--profile",
        profile,
        "-p",
        "accelcal-fuzz",
        "--",
        "--seconds",
        seconds,
        "--target",
        target,
    ]
}

/// `cargo xtask fuzz [--seconds N] [--target record|slots|frame|all] [--seed S]`: the fuzzer in the
/// `fuzz` profile (optimised, overflow checks and debug assertions on).
fn fuzz(args: &[String]) -> anyhow::Result<()> {
    let mut seconds = "60".to_string();
    let mut target = "all".to_string();
    let mut seed = None;
    let mut it = args.iter();
    while let Some(a) = it.next() {
        let v = it.next().with_context(|| format!("{a} needs a value"))?;
        match a.as_str() {
            "--seconds" => seconds = v.clone(),
            "--target" => target = v.clone(),
            "--seed" => seed = Some(v.clone()),
            _ => bail!("unknown argument `{a}` (cargo xtask fuzz [--seconds N] [--target record|slots|frame|all] [--seed S])"),
        }
    }
    let mut cmd = fuzz_args("fuzz", &seconds, &target);
    if let Some(s) = &seed {
        cmd.extend(["--seed", s]);
    }
    run(&root(), "cargo", &cmd)
}

fn lint() -> anyhow::Result<()> {
    let r = root();
    run(&r, "cargo", &["fmt", "--all", "--check"])?;
    run(&r, "cargo", &["clippy", "--workspace", "--all-targets", "--locked", "--", "-D", "warnings"])?;
    firmware::lint()
}

/// `bench` runs both benchmarks; `bench firmware` only the firmware's (no Python, no PyPI).
fn bench(only: Option<&str>) -> anyhow::Result<()> {
    match only {
        None => {
            gmdh::bench(&root())?;
            firmware::bench()?;
            live::bench()
        }
        Some("firmware") => firmware::bench(),
        Some("live") => live::bench(),
        Some(other) => anyhow::bail!("bench: unknown part `{other}` (the parts: firmware, live)"),
    }
}

fn main() -> anyhow::Result<()> {
    let task = std::env::args().nth(1).unwrap_or_default();
    match task.as_str() {
        "test" => test(),
        "lint" => lint(),
        "bench" => bench(std::env::args().nth(2).as_deref()),
        "fuzz" => fuzz(&std::env::args().skip(2).collect::<Vec<_>>()),
        "firmware" => firmware::build(),
        _ => {
            eprintln!("usage: cargo xtask <test|lint|bench|fuzz|firmware>\n  test   every test: host, shared (desktop and no_std target), firmware builds, QEMU\n  lint   rustfmt --check and clippy -D warnings\n  bench  [firmware|live]: the benchmarks quoted in the README (a part: only that one)\n  fuzz   [--seconds N] [--target record|slots|frame|all] [--seed S]: the parsers' mutation fuzzer\n  firmware  the node images (real board, QEMU f32, QEMU fixed point), as the tests build them");
            std::process::exit(2)
        }
    }
}
