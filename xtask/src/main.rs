//! `cargo xtask`: the one entry point for developer tasks. Each subcommand prints every command
//! it runs before running it.
//!
//! - `test`: host and shared tests, the no_std build of `shared` for the MCU target, the
//!   firmware builds and the QEMU tests.
//! - `lint`: rustfmt and clippy (warnings are errors).
//! - `bench`: the benchmarks the guide quotes (GMDH against the PyPI `gmdh` package, the Monte
//!   Carlo check of the uncertainty budget, the firmware, the live path); `bench fleet`, only
//!   when named, the fleet's commands and pages on a line-sized PostgreSQL database.
//! - `fuzz`: the mutation fuzzer of the record parser, the record slots and the frame decoder, for
//!   a bounded time.
//! - `docs`: the guide's command reference (`docs/src/reference/commands.md`) from the built
//!   binary's help.

use std::path::{Path, PathBuf};
use std::process::Command;

use anyhow::{bail, Context};

mod commands_md;
mod docs;
mod firmware;
mod gmdh;
mod live;
mod station;

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).parent().expect("xtask sits in the workspace").to_path_buf()
}

/// Runs a command in `dir`, echoing it first; fails on a non-zero exit.
pub fn run(dir: &Path, program: &str, args: &[&str]) -> anyhow::Result<()> {
    let mut cmd = Command::new(program);
    cmd.args(args).current_dir(dir);
    run_cmd(&mut cmd)
}

/// Every command `run_cmd` ran, with its wall time, for `test`'s summary.
static TIMES: std::sync::Mutex<Vec<(String, f64)>> = std::sync::Mutex::new(Vec::new());

/// Prints `cmd` as a line that can be pasted into a shell (its directory and environment
/// included), runs it, prints its wall time, and fails unless it succeeds.
pub fn run_cmd(cmd: &mut Command) -> anyhow::Result<()> {
    let dir = cmd
        .get_current_dir()
        .map(|d| d.strip_prefix(root()).unwrap_or(d).to_path_buf())
        .filter(|d| !d.as_os_str().is_empty())
        .map(|d| format!("(cd {} && ", d.display()))
        .unwrap_or_default();
    let args: Vec<String> = cmd.get_args().map(|a| shell_quote(&a.to_string_lossy())).collect();
    let envs: Vec<String> = cmd
        .get_envs()
        .filter_map(|(k, v)| Some(format!("{}={} ", k.to_string_lossy(), shell_quote(&v?.to_string_lossy()))))
        .collect();
    let close = if dir.is_empty() { "" } else { ")" };
    let shown =
        format!("{dir}{}{} {}{close}", envs.concat(), cmd.get_program().to_string_lossy(), args.join(" "));
    eprintln!("$ {shown}");
    let start = std::time::Instant::now();
    let status = cmd.status().with_context(|| format!("cannot run {:?}", cmd.get_program()))?;
    let secs = start.elapsed().as_secs_f64();
    eprintln!("[xtask] {secs:.1} s: {shown}");
    TIMES.lock().unwrap_or_else(|e| e.into_inner()).push((shown.clone(), secs));
    if !status.success() {
        bail!("`{shown}` failed with {status}");
    }
    Ok(())
}

/// `v` as one shell word: quoted when it holds a space or a shell metacharacter (so that a printed
/// command can be pasted as it is).
pub fn shell_quote(v: &str) -> String {
    if !v.is_empty() && v.chars().all(|c| c.is_ascii_alphanumeric() || "-_=./,:@%+".contains(c)) {
        v.to_string()
    } else {
        format!("'{}'", v.replace('\'', r"'\''"))
    }
}

/// The wall time of each step run so far, and their sum.
fn print_times(task: &str) {
    let times = TIMES.lock().unwrap_or_else(|e| e.into_inner());
    eprintln!("[xtask] {task}: the time of each step");
    for (cmd, secs) in times.iter() {
        eprintln!("[xtask] {secs:>7.1} s  {cmd}");
    }
    eprintln!("[xtask] {:>7.1} s  in all", times.iter().map(|t| t.1).sum::<f64>());
}

fn test() -> anyhow::Result<()> {
    let r = root();
    // First: QEMU and the firmware builds (the workspace's tests include the QEMU tests of
    // tests/hil.rs, tests/live.rs and tests/line.rs, which run the QEMU builds).
    firmware::test()?;
    // The certificate test (tests/line.rs) prints a page with headless Chromium.
    run(&r, "bash", &["scripts/setup-chromium.sh"])?;
    // The DCC tests (tests/cli/dcc.rs) validate every DCC with xmllint against tests/data/dcc.
    run(&r, "bash", &["scripts/setup-xmllint.sh"])?;
    // The PostgreSQL tests (tests/db_pg.rs) start throwaway clusters of Debian's server.
    run(&r, "bash", &["scripts/setup-postgres.sh"])?;
    if nextest_present() {
        // Every test binary's tests in one pool, two at a time, the emulated benches one at a
        // time (`.config/nextest.toml`); nextest runs no doctests, so `cargo test --doc` does.
        run(&r, "cargo", &["nextest", "run", "--workspace", "--locked", "--no-tests", "fail"])?;
        run(&r, "cargo", &["test", "--workspace", "--locked", "--doc"])?;
    } else {
        eprintln!(
            "[xtask] cargo-nextest is not installed: `cargo test` runs the test binaries one after the other"
        );
        run(&r, "cargo", &["test", "--workspace", "--locked"])?;
    }
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

/// Whether `cargo nextest` runs here (it is not a dependency: `cargo install cargo-nextest`).
fn nextest_present() -> bool {
    Command::new("cargo")
        .args(["nextest", "--version"])
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .status()
        .is_ok_and(|s| s.success())
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
            uncertainty_bench()?;
            design_bench()?;
            firmware::bench()?;
            live::bench()?;
            station::bench()
        }
        Some("uncertainty") => uncertainty_bench(),
        Some("design") => design_bench(),
        Some("firmware") => firmware::bench(),
        Some("live") => live::bench(),
        Some("station") => station::bench(),
        Some("fleet") => fleet_bench(),
        Some(other) => {
            anyhow::bail!(
                "bench: unknown part `{other}` (the parts: uncertainty, design, firmware, live, station, fleet)"
            )
        }
    }
}

/// Issue 31 item 5: `fleet` and `serve` on a PostgreSQL database of 100,000 units and 300,000
/// runs, in a cluster of its own under `target/bench-fleet-pg` (PostgreSQL from
/// `scripts/setup-postgres.sh`). The first run writes the line through the store path (about
/// 105 minutes on 2 cores); the cluster is halted after, its data kept, and later runs time
/// the same database. Not part of `bench` without a part.
fn fleet_bench() -> anyhow::Result<()> {
    let r = root();
    run(&r, "cargo", &["build", "--release", "-p", "accelcal", "--locked"])?;
    let bin = r.join("target/release/accelcal");
    let dir = r.join("target/bench-fleet-pg");
    let script = r.join("scripts/postgres-cluster.sh");
    let cluster = |cmd: &str| -> anyhow::Result<String> {
        let out = std::process::Command::new("bash").arg(&script).arg(cmd).arg(&dir).output()?;
        anyhow::ensure!(
            out.status.success(),
            "postgres-cluster.sh {cmd}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        Ok(String::from_utf8(out.stdout)?.trim().to_string())
    };
    let url = cluster("resume")?;
    let done = run(&r, bin.to_str().expect("utf-8 path"), &["bench-fleet", "--db", &url]);
    cluster("halt")?;
    done
}

/// The Monte Carlo check of the uncertainty budget (JCGM 101) at three seeds, 1,000 units per
/// scenario each, on the release build.
fn uncertainty_bench() -> anyhow::Result<()> {
    let r = root();
    run(&r, "cargo", &["build", "--release", "-p", "accelcal", "--locked"])?;
    let bin = r.join("target/release/accelcal");
    for seed in ["1", "2", "3"] {
        run(
            &r,
            bin.to_str().expect("utf-8 path"),
            &["uncertainty-check", "--units", "1000", "--seed", seed],
        )?;
    }
    Ok(())
}

/// Issue 32's plans side by side: with 10 s per move, 80 codes of noise and 20″ of head angle
/// error, the plan `plan --design auto` designs for the paper's plan's U at its 4 s dwell, then
/// for 10 % above it, then designed plans of 14 to 22 positions at exactly half the paper plan's
/// head time, each checked by 1,000 simulated units per plan.
fn design_bench() -> anyhow::Result<()> {
    let r = root();
    run(&r, "cargo", &["build", "--release", "-p", "accelcal", "--locked"])?;
    let bin = r.join("target/release/accelcal");
    let bin = bin.to_str().expect("utf-8 path");
    let dir = r.join("target/bench-design");
    std::fs::create_dir_all(&dir)?;
    let path = |n: &str| dir.join(n).to_str().expect("utf-8 path").to_string();
    // 10 s per move at 100 Hz; the paper plan's 4 s dwell.
    let (move_s, rate_hz) = (10.0, 100.0);
    let unit_and_head = ["--noise", "80", "--head-angle-u", "20", "--move-s", "10", "--g", "9.80665"];
    let common = [&unit_and_head[..], &["--samples", "400"]].concat();
    let (same, same_json) = (path("same-u.csv"), path("same-u.json"));
    let mut args = vec!["plan", "--design", "auto"];
    args.extend_from_slice(&common);
    args.extend_from_slice(&["--montecarlo", "1000", "--out", &same, "--json", &same_json]);
    run(&r, bin, &args)?;
    let doc: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&same_json)?)?;
    let paper = doc["compared"][0]["U_m_s2"].as_f64().context("the paper plan's U in the JSON")?;
    let target = format!("{:.4e}", 1.1 * paper);
    let (within, within_json) = (path("within-10.csv"), path("within-10.json"));
    let mut args = vec!["plan", "--design", "auto"];
    args.extend_from_slice(&common);
    args.extend_from_slice(&[
        "--target-U",
        &target,
        "--montecarlo",
        "1000",
        "--out",
        &within,
        "--json",
        &within_json,
    ]);
    run(&r, bin, &args)?;
    // The aim as the issue states it: a designed plan at half the paper plan's head time, its
    // dwell filling that time, for each number of positions around the best.
    let half = doc["compared"][0]["head_time_s"].as_f64().context("the paper plan's head time")? / 2.0;
    let paper_mc =
        doc["compared"][0]["montecarlo"]["rms_stated_U_m_s2"].as_f64().context("the paper plan's MC U")?;
    let mut rows = Vec::new();
    for n in [14usize, 15, 16, 18, 20, 22] {
        let samples = ((half / n as f64 - move_s) * rate_hz).floor() as usize;
        let (csv, json) = (path(&format!("half-{n}.csv")), path(&format!("half-{n}.json")));
        let (n_s, samples_s) = (n.to_string(), samples.to_string());
        let mut args = vec!["plan", "--design", &n_s];
        args.extend_from_slice(&unit_and_head);
        args.extend_from_slice(&["--samples", &samples_s]);
        args.extend_from_slice(&["--montecarlo", "1000", "--out", &csv, "--json", &json]);
        run(&r, bin, &args)?;
        let d: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json)?)?;
        let designed = d["compared"].as_array().and_then(|c| c.last()).context("the designed plan's row")?;
        let mc = &designed["montecarlo"];
        let field = |v: &serde_json::Value, k: &str| v[k].as_f64().with_context(|| format!("{k} in {json}"));
        rows.push(format!(
            "| {n} × {:.2} s | {:.0} s ({:.1} %) | {:.3e} | {:.3e} | {:+.1} % | {:.1} % |",
            samples as f64 / rate_hz,
            field(designed, "head_time_s")?,
            100.0 * field(designed, "head_time_s")? / (2.0 * half),
            field(designed, "U_m_s2")?,
            field(mc, "rms_stated_U_m_s2")?,
            100.0 * (field(mc, "rms_stated_U_m_s2")? / paper_mc - 1.0),
            100.0 * field(mc, "coverage")?,
        ));
    }
    println!(
        "\ndesigned plans at half the paper plan's head time ({half:.0} s); the paper plan's MC RMS of U {paper_mc:.3e} m/s²"
    );
    println!(
        "| positions × dwell | head time | predicted U | MC RMS of U | above the paper's (MC) | coverage |"
    );
    println!("|---|---|---|---|---|---|");
    rows.iter().for_each(|row| println!("{row}"));
    Ok(())
}

fn main() -> anyhow::Result<()> {
    let task = std::env::args().nth(1).unwrap_or_default();
    match task.as_str() {
        "test" => test().inspect(|()| print_times("test")),
        "lint" => lint().inspect(|()| print_times("lint")),
        "bench" => bench(std::env::args().nth(2).as_deref()),
        "fuzz" => fuzz(&std::env::args().skip(2).collect::<Vec<_>>()),
        "firmware" => firmware::build(),
        "docs" => docs::run(),
        _ => {
            eprintln!("usage: cargo xtask <test|lint|bench|fuzz|firmware|docs>\n  test   every test: host, shared (desktop and no_std target), firmware builds, QEMU\n  lint   rustfmt --check and clippy -D warnings\n  bench  [uncertainty|design|firmware|live|station]: the benchmarks quoted in the guide (a part: only that one)\n  fuzz   [--seconds N] [--target record|slots|frame|all] [--seed S]: the parsers' mutation fuzzer\n  firmware  the node images (real board, QEMU f32, QEMU fixed point), as the tests build them\n  docs   the guide's command reference (docs/src/reference/commands.md) from the built binary's help");
            std::process::exit(2)
        }
    }
}
