//! Firmware tasks: building both node builds, running the QEMU tests, and the benchmark (exact
//! instruction count of the calibration hot path on the emulated Cortex-M4F, and the real build's
//! flash and static RAM footprint). Every command is printed before it runs.

use std::io::{Read, Write};
use std::os::unix::net::UnixStream;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use accelcal_shared::contract;
use accelcal_shared::linear::Model4;
use accelcal_shared::record::{Record, TempSource, Thermal, MAX_RECORD_LEN};
use accelcal_shared::slots::SlotImage;
use accelcal_shared::thermal::ThermalModel;
use accelcal_shared::wire::{
    self, Block, FrameDecoder, HostMsg, NodeMsg, RecordStatus, ReplayTemp, MAX_FRAME,
};
use anyhow::{bail, ensure, Context};
use object::{Object, ObjectSection, ObjectSymbol, SectionKind};

use crate::run_cmd as run;

/// Flash of the STM32L475VG (the node contract, checked against memory.x): where text, rodata and
/// the initial values of data live.
const FLASH: std::ops::Range<u64> =
    contract::FLASH_BASE as u64..(contract::FLASH_BASE + contract::FLASH_SIZE) as u64;
/// SRAM1 (the node contract).
const RAM: std::ops::Range<u64> = contract::RAM_BASE as u64..(contract::RAM_BASE + contract::RAM_SIZE) as u64;
/// Address of record slot 0 (the node contract).
const SLOT0: u64 = contract::SLOT_ADDRS[0] as u64;
/// Footprint budgets of the issue.
const FLASH_BUDGET: u64 = 48 * 1024;
const RAM_BUDGET: u64 = 16 * 1024;
/// The hot-path symbol (firmware/src/app/calib.rs).
const HOT_PATH: &str = "calibrate_block_f32";
/// The fixed-point build's hot path.
const HOT_PATH_FIXED: &str = "calibrate_block_fixed";
/// The hot path with a thermal record (firmware/src/app/calib.rs).
const HOT_PATH_THERMAL: &str = "calibrate_block_thermal_f32";

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn fw_dir() -> PathBuf {
    root().join("firmware")
}

pub fn elf(bin: &str) -> PathBuf {
    fw_dir().join("target/thumbv7em-none-eabihf/release").join(bin)
}

/// A cargo command for the firmware workspace (its own .cargo/config.toml picks the target).
fn fw_cargo(args: &[&str]) -> Command {
    let mut c = Command::new(std::env::var_os("CARGO").unwrap_or_else(|| "cargo".into()));
    c.current_dir(fw_dir()).args(args);
    // Settings of the outer (host) cargo invocation must not leak into the thumb build.
    for k in ["RUSTFLAGS", "CARGO_ENCODED_RUSTFLAGS", "CARGO_TARGET_DIR", "CARGO_BUILD_TARGET"] {
        c.env_remove(k);
    }
    let flags = remap_flags();
    if flags.iter().any(|f| f.contains(char::is_whitespace)) {
        c.env("CARGO_ENCODED_RUSTFLAGS", flags.join("\x1f"));
    } else {
        c.env("RUSTFLAGS", flags.join(" "));
    }
    c
}

/// The `--remap-path-prefix` flags of every firmware build, what cargo's `trim-paths` (not stable
/// in the pinned toolchain) does: the registry's source directories and the repository root are
/// cut from the paths compiled into the image (the panic locations), so that
/// `/root/.cargo/registry/src/index.crates.io-…/embassy-stm32-0.6.0/src/dma/mod.rs` is stored as
/// `embassy-stm32-0.6.0/src/dma/mod.rs` and `<repository>/shared/src/wire.rs` as
/// `shared/src/wire.rs`. The image then holds no path of the build machine, and its size (the
/// flash budget) does not depend on where the repository and CARGO_HOME are.
pub fn remap_flags() -> Vec<String> {
    remap_prefixes().iter().map(|p| format!("--remap-path-prefix={}/=", p.display())).collect()
}

/// The directories [`remap_flags`] cuts from the image's paths.
fn remap_prefixes() -> Vec<PathBuf> {
    let mut prefixes = Vec::new();
    let cargo_home = std::env::var_os("CARGO_HOME")
        .map(PathBuf::from)
        .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".cargo")));
    if let Some(Ok(dirs)) = cargo_home.map(|h| std::fs::read_dir(h.join("registry/src"))) {
        let mut dirs: Vec<PathBuf> =
            dirs.filter_map(|d| Some(d.ok()?.path())).filter(|d| d.is_dir()).collect();
        dirs.sort();
        prefixes.extend(dirs);
    }
    // Lexically, as cargo names the path dependency `../shared` (no symlink resolution).
    prefixes.push(Path::new(env!("CARGO_MANIFEST_DIR")).parent().unwrap_or(Path::new("/")).to_path_buf());
    prefixes
}

/// Checks [`remap_flags`]' invariant on a built image: no section that goes into the MCU's flash
/// holds a path of the build machine (a registry directory or the repository root).
fn check_no_machine_paths(path: &Path) -> anyhow::Result<()> {
    let data = std::fs::read(path).with_context(|| format!("reading {}", path.display()))?;
    let file = object::File::parse(&*data).with_context(|| format!("parsing {}", path.display()))?;
    let prefixes: Vec<String> = remap_prefixes().iter().map(|p| format!("{}/", p.display())).collect();
    for s in file.sections().filter(|s| FLASH.contains(&s.address()) && s.size() > 0) {
        let bytes = s.data().with_context(|| format!("{}: section {:?}", path.display(), s.name()))?;
        for p in &prefixes {
            ensure!(
                !bytes.windows(p.len()).any(|w| w == p.as_bytes()),
                "{}: section {} holds the build machine's path {p} (is the path remapping gone?)",
                path.display(),
                s.name().unwrap_or("?")
            );
        }
    }
    Ok(())
}

/// The MCU target of the firmware and of `shared`'s no_std build.
pub const THUMB: &str = "thumbv7em-none-eabihf";

/// What every firmware build needs first: the thumb target, and the dependencies' sources in
/// cargo's registry (fetched before [`remap_flags`] lists the registry's directories, so that a
/// fresh CARGO_HOME gets the same image as a used one).
pub fn prepare() -> anyhow::Result<()> {
    ensure_thumb_target()?;
    run(&mut fw_cargo(&["fetch", "--locked"]))
}

/// Installs the thumb target into the pinned toolchain when it is missing (idempotent).
/// rustup applies `rust-toolchain.toml`'s `targets` only to a toolchain it installs itself, so a
/// machine that already had the pinned toolchain lacks the target until this runs.
pub fn ensure_thumb_target() -> anyhow::Result<()> {
    let listed = Command::new("rustup").args(["target", "list", "--installed"]).current_dir(root()).output();
    match listed {
        Ok(out) if out.status.success() => {
            if String::from_utf8_lossy(&out.stdout).lines().any(|l| l.trim() == THUMB) {
                println!("setup: target {THUMB} is installed");
                return Ok(());
            }
            run(Command::new("rustup").args(["target", "add", THUMB]).current_dir(root()))
        }
        _ => bail!(
            "the {THUMB} target is needed and rustup is not available to install it; \
             install it with your toolchain manager (rustup: `rustup target add {THUMB}`)"
        ),
    }
}

pub fn setup_qemu() -> anyhow::Result<()> {
    run(Command::new("bash").arg(root().join("scripts/setup-qemu.sh")))
}

fn build_real() -> anyhow::Result<()> {
    run(&mut fw_cargo(&["build", "--release", "--locked", "--features", "board-real", "--bin", "node-real"]))
}

pub fn build_qemu() -> anyhow::Result<()> {
    run(&mut fw_cargo(&["build", "--release", "--locked", "--features", "board-qemu", "--bin", "node-qemu"]))
}

/// The fixed-point QEMU build: its own binary in the same target directory.
fn fixed_elf() -> PathBuf {
    elf("node-qemu-fixed")
}

fn build_qemu_fixed() -> anyhow::Result<()> {
    run(&mut fw_cargo(&[
        "build",
        "--release",
        "--locked",
        "--features",
        "board-qemu,fixed-point",
        "--bin",
        "node-qemu-fixed",
    ]))
}

/// `cargo xtask firmware`: the three node images (the real board's, QEMU's in f32 and in fixed
/// point), built as the tests and the benchmark build them; prints where they are.
pub fn build() -> anyhow::Result<()> {
    prepare()?;
    build_real()?;
    build_qemu()?;
    build_qemu_fixed()?;
    for p in [elf("node-real"), elf("node-qemu"), fixed_elf()] {
        check_no_machine_paths(&p)?;
        println!("built {}", p.display());
    }
    Ok(())
}

/// `cargo xtask test` (firmware part): installs QEMU when missing and builds the real firmware
/// and the QEMU builds (f32 and fixed point) where the QEMU tests (`tests/hil.rs`, run with the
/// workspace's tests) look for them.
pub fn test() -> anyhow::Result<()> {
    prepare()?;
    setup_qemu()?;
    build_real()?;
    build_qemu()?;
    build_qemu_fixed()?;
    for p in [elf("node-real"), elf("node-qemu"), fixed_elf()] {
        check_no_machine_paths(&p)?;
    }
    println!("firmware images: no path of the build machine in flash");
    Ok(())
}

/// `cargo xtask lint` (firmware part): rustfmt and clippy (warnings are errors) on the firmware
/// workspace, for each board and for the fixed-point variant.
pub fn lint() -> anyhow::Result<()> {
    prepare()?;
    run(&mut fw_cargo(&["fmt", "--all", "--check"]))?;
    for features in ["board-real", "board-qemu", "board-qemu,fixed-point"] {
        run(&mut fw_cargo(&[
            "clippy",
            "--release",
            "--locked",
            "--features",
            features,
            "--bins",
            "--",
            "-D",
            "warnings",
        ]))?;
    }
    Ok(())
}

/// Flash (text + data) and static RAM (data + bss + uninit) of an ELF, from its sections.
pub fn footprint(path: &Path) -> anyhow::Result<(u64, u64)> {
    let data = std::fs::read(path).with_context(|| format!("reading {}", path.display()))?;
    let file = object::File::parse(&*data).with_context(|| format!("parsing {}", path.display()))?;
    let (mut flash, mut ram) = (0u64, 0u64);
    for s in file.sections() {
        let (addr, size) = (s.address(), s.size());
        if size == 0 {
            continue;
        }
        match s.kind() {
            SectionKind::UninitializedData | SectionKind::UninitializedTls if RAM.contains(&addr) => {
                ram += size
            }
            SectionKind::Data | SectionKind::Tls if RAM.contains(&addr) => {
                ram += size;
                flash += size; // initial values are copied from flash at boot
            }
            SectionKind::Text
            | SectionKind::ReadOnlyData
            | SectionKind::ReadOnlyString
            | SectionKind::Data
                if FLASH.contains(&addr) =>
            {
                flash += size
            }
            _ => {}
        }
    }
    Ok((flash, ram))
}

/// Address range of a function symbol (Thumb bit cleared).
fn symbol_range(path: &Path, name: &str) -> anyhow::Result<std::ops::Range<u64>> {
    let data = std::fs::read(path)?;
    let file = object::File::parse(&*data)?;
    let sym = file
        .symbols()
        .find(|s| s.name() == Ok(name))
        .with_context(|| format!("{}: no symbol {name}", path.display()))?;
    let start = sym.address() & !1;
    ensure!(sym.size() > 0, "{name} has no size");
    Ok(start..start + sym.size())
}

/// The address ranges of function `name` and of every function it calls, directly or not: the
/// targets of the Thumb-2 `BL` instructions in their code that are the start of a function symbol
/// (a literal-pool word that happens to decode as `BL` is passed over unless it lands on one).
/// The first range is `name`'s.
fn call_tree(path: &Path, name: &str) -> anyhow::Result<Vec<(String, std::ops::Range<u64>)>> {
    let data = std::fs::read(path)?;
    let file = object::File::parse(&*data)?;
    let functions: std::collections::BTreeMap<u64, (String, u64)> = file
        .symbols()
        .filter(|s| s.kind() == object::SymbolKind::Text && s.size() > 0)
        .filter_map(|s| Some((s.address() & !1, (s.name().ok()?.to_string(), s.size()))))
        .collect();
    let root = symbol_range(path, name)?;
    let mut todo = vec![(name.to_string(), root)];
    let mut done: Vec<(String, std::ops::Range<u64>)> = Vec::new();
    while let Some((n, range)) = todo.pop() {
        if done.iter().any(|(_, r)| r.start == range.start) {
            continue;
        }
        let section = file
            .sections()
            .find(|s| s.address() <= range.start && range.end <= s.address() + s.size())
            .with_context(|| format!("{n}: not in a section"))?;
        let bytes = section.data()?;
        let code =
            &bytes[(range.start - section.address()) as usize..(range.end - section.address()) as usize];
        let hw = |i: usize| code.get(i..i + 2).map(|b| u16::from_le_bytes([b[0], b[1]]) as u32);
        let mut i = 0;
        while let Some(h1) = hw(i) {
            if h1 >> 11 < 0b11101 {
                i += 2;
                continue;
            }
            let h2 = hw(i + 2).unwrap_or(0);
            if h1 >> 11 == 0b11110 && h2 >> 14 == 0b11 && (h2 >> 12) & 1 == 1 {
                let s = (h1 >> 10) & 1;
                let i1 = !(((h2 >> 13) & 1) ^ s) & 1;
                let i2 = !(((h2 >> 11) & 1) ^ s) & 1;
                let imm = (s << 24) | (i1 << 23) | (i2 << 22) | ((h1 & 0x3ff) << 12) | ((h2 & 0x7ff) << 1);
                let offset = ((imm << 7) as i32 >> 7) as i64;
                let target = (range.start as i64 + i as i64 + 4 + offset) as u64;
                if let Some((callee, size)) = functions.get(&target) {
                    todo.push((callee.clone(), target..target + size));
                }
            }
            i += 4;
        }
        done.push((n, range));
    }
    Ok(done)
}

/// The benchmark's triad: plausible (codes per m/s² ≈ 1670, mid-scale offsets).
fn bench_model() -> Model4 {
    Model4 {
        u0: [32100.5, 33012.25, 31877.75],
        k: [[1671.2, 8.5, -3.25], [-4.0, 1650.75, 6.5], [2.5, -7.75, 1689.0]],
    }
}

/// The record the benchmark loads: the triad as model 4, or with thermal terms (`t` and each
/// axis's `·t`: 3 codes/°C of bias and 100 ppm/°C of sensitivity, the unit), read from
/// the QEMU board's front end over −10..50 °C.
fn bench_record(thermal: bool) -> anyhow::Result<Vec<u8>> {
    let m = bench_model();
    let r = if thermal {
        let th = ThermalModel {
            thermal: Thermal { t_ref_c: 25.0, t_min_c: -10.0, t_max_c: 50.0, source: TempSource::FrontEnd },
            bias: m.u0.map(|b| [b, 3.0, 0.0]),
            k: m.k,
            kt: m.k.map(|r| r.map(|v| v * 1e-4)),
        };
        th.to_record(contract::QEMU_DEVICE_ID, 1_800_000_000, 9.81)
    } else {
        Record::from_model4(contract::QEMU_DEVICE_ID, 1_800_000_000, &m)
    };
    let mut buf = [0u8; MAX_RECORD_LEN];
    let n = r.emit(&mut buf).map_err(|e| anyhow::anyhow!("{e}"))?;
    Ok(buf[..n].to_vec())
}

struct Qemu(Child);

impl Drop for Qemu {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

fn frame(msg: &HostMsg) -> anyhow::Result<Vec<u8>> {
    let mut buf = [0u8; MAX_FRAME];
    let mut out = vec![0u8];
    out.extend_from_slice(wire::encode(msg, &mut buf).map_err(|e| anyhow::anyhow!("{e}"))?);
    Ok(out)
}

/// Boots the QEMU node with instruction tracing restricted to `ranges` (the first is the hot
/// path's, the others those of the functions it calls), replays `n_calls` blocks of `per_call`
/// code sets (with temperatures and the thermal record when `thermal`), and returns (instructions
/// executed in `ranges` from the first entry into the hot path on, calls entering the hot path,
/// the part of those instructions in the hot path's own range).
fn count_instructions(
    elf: &Path,
    dir: &Path,
    ranges: &[std::ops::Range<u64>],
    n_calls: usize,
    per_call: usize,
    thermal: bool,
) -> anyhow::Result<(u64, u64, u64)> {
    let range = &ranges[0];
    let slot = dir.join("slot0.bin");
    std::fs::write(&slot, SlotImage::build(&bench_record(thermal)?, 1).map_err(|e| anyhow::anyhow!("{e}"))?)?;
    let sock = dir.join(format!("link{per_call}.sock"));
    let log = dir.join(format!("exec{per_call}.log"));
    let _ = std::fs::remove_file(&sock);
    let mut cmd = Command::new("qemu-system-arm");
    cmd.args(["-M", "b-l475e-iot01a", "-m", "1M", "-display", "none", "-monitor", "none"])
        .args(["-semihosting-config", "enable=on,target=native"])
        .args(["-accel", "tcg,one-insn-per-tb=on", "-d", "exec,nochain"])
        .arg("-dfilter")
        .arg(ranges.iter().map(|r| format!("{:#x}..{:#x}", r.start, r.end - 1)).collect::<Vec<_>>().join(","))
        .arg("-D")
        .arg(&log)
        .arg("-chardev")
        .arg(format!("socket,id=link,path={},server=on,wait=on", sock.display()))
        .args(["-serial", "chardev:link", "-device"])
        .arg(format!("loader,file={},addr={SLOT0:#x}", slot.display()))
        .arg("-kernel")
        .arg(elf)
        .stdout(Stdio::null());
    let args: Vec<String> = cmd.get_args().map(|a| a.to_string_lossy().into_owned()).collect();
    println!("$ qemu-system-arm {}", args.join(" "));
    let mut qemu = Qemu(cmd.spawn().context("starting qemu-system-arm")?);
    let t0 = Instant::now();
    let mut s = loop {
        if let Ok(s) = UnixStream::connect(&sock) {
            break s;
        }
        if let Some(st) = qemu.0.try_wait()? {
            bail!("qemu exited: {st}");
        }
        ensure!(t0.elapsed() < Duration::from_secs(10), "qemu did not open {}", sock.display());
        std::thread::sleep(Duration::from_millis(20));
    };
    s.set_read_timeout(Some(Duration::from_millis(200)))?;
    let mut dec = FrameDecoder::<MAX_FRAME>::new();
    let mut recv = |s: &mut UnixStream, out: &mut Vec<NodeMsg>| -> anyhow::Result<()> {
        let mut buf = [0u8; 1024];
        match s.read(&mut buf) {
            Ok(0) => bail!("the node closed the link"),
            Ok(n) => dec.push(&buf[..n], |m: Result<NodeMsg, _>| out.extend(m.ok())),
            Err(e) if matches!(e.kind(), std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut) => {}
            Err(e) => return Err(e.into()),
        }
        Ok(())
    };
    // Wait for the status the node sends at boot, and check it accepted the record.
    let mut msgs = Vec::new();
    loop {
        recv(&mut s, &mut msgs)?;
        if let Some(NodeMsg::Status(st)) = msgs.iter().find(|m| matches!(m, NodeMsg::Status(_))) {
            ensure!(
                matches!(st.record, RecordStatus::InUse { .. }),
                "node refused the record: {:?}",
                st.record
            );
            break;
        }
        ensure!(t0.elapsed() < Duration::from_secs(20), "the node did not report its status");
    }
    let mut all = Vec::new();
    for k in 0..n_calls {
        let codes = (0..per_call)
            .map(|i| {
                let v = (k * 977 + i * 131) as u16;
                [v.wrapping_mul(7), v.wrapping_mul(11), v.wrapping_mul(13)]
            })
            .collect::<Vec<_>>();
        let codes = heapless::Vec::from_slice(&codes).map_err(|_| anyhow::anyhow!("block too large"))?;
        // A slow ramp inside the calibrated range.
        let temp = thermal.then(|| ReplayTemp {
            restart: k == 0,
            temp_c: (0..per_call).map(|i| 20.0 + 0.01 * (k * per_call + i) as f32).collect(),
        });
        all.extend_from_slice(&frame(&HostMsg::Replay { seq: k as u32, codes, temp })?);
    }
    s.write_all(&all)?;
    let mut answered = 0;
    let t1 = Instant::now();
    while answered < n_calls {
        msgs.clear();
        recv(&mut s, &mut msgs)?;
        for m in &msgs {
            if let NodeMsg::Replayed { data, .. } = m {
                let ok = matches!(data, Block::Calibrated(v) if v.len() == per_call)
                    || matches!(data, Block::CalibratedFixed(v) if v.len() == per_call);
                ensure!(ok, "unexpected answer {m:?}");
                answered += 1;
            }
        }
        ensure!(t1.elapsed() < Duration::from_secs(60), "the node answered {answered} of {n_calls} requests");
    }
    drop(qemu); // the log is complete once QEMU has exited
    let text = std::fs::read_to_string(&log).with_context(|| format!("reading {}", log.display()))?;
    let (mut insns, mut calls, mut retried, mut own) = (0u64, 0u64, 0u64, 0u64);
    let mut prev = None;
    // The callees also run at boot (the record check evaluates a thermal model): count from the
    // first entry into the hot path on.
    let mut entered = false;
    for line in text.lines().filter(|l| l.starts_with("Trace ")) {
        // "Trace 0: 0x7f.. [00000000/08001554/00000000/ff200000] calibrate_block_f32"
        let pc = line
            .split('[')
            .nth(1)
            .and_then(|f| f.split('/').nth(1))
            .and_then(|h| u64::from_str_radix(h, 16).ok())
            .with_context(|| format!("unexpected trace line: {line}"))?;
        // QEMU logs a translation block when it enters it; when an interrupt is pending it leaves
        // the block before its (single) instruction runs and logs it again after the handler. The
        // hot path has no branch-to-self, so a repeated PC is such a retry, not an execution.
        if prev == Some(pc) {
            retried += 1;
            continue;
        }
        prev = Some(pc);
        entered |= pc == range.start;
        if entered && ranges.iter().any(|r| r.contains(&pc)) {
            insns += 1;
            own += range.contains(&pc) as u64;
            calls += (pc == range.start) as u64;
        }
    }
    println!("  ({retried} trace entries were interrupt retries, not counted)");
    ensure!(calls == n_calls as u64, "traced {calls} calls of the hot path, expected {n_calls}");
    Ok((insns, calls, own))
}

/// `cargo xtask bench`: exact instructions per calibrated triad sample set on QEMU's Cortex-M4F,
/// and the real release build's flash and static RAM.
pub fn bench() -> anyhow::Result<()> {
    prepare()?;
    setup_qemu()?;
    build_real()?;
    build_qemu()?;
    let (flash, ram) = footprint(&elf("node-real"))?;
    let qemu_elf = elf("node-qemu");
    let range = symbol_range(&qemu_elf, HOT_PATH)?;
    let dir = std::env::temp_dir().join(format!("accelcal-bench-{}", std::process::id()));
    std::fs::create_dir_all(&dir)?;
    const CALLS: usize = 64;
    let block = wire::MAX_BLOCK;
    let (i16, _, _) = count_instructions(&qemu_elf, &dir, std::slice::from_ref(&range), CALLS, block, false)?;
    let (i1, _, _) = count_instructions(&qemu_elf, &dir, std::slice::from_ref(&range), CALLS, 1, false)?;
    let thermal_tree = call_tree(&qemu_elf, HOT_PATH_THERMAL)?;
    let thermal_ranges: Vec<_> = thermal_tree.iter().map(|(_, r)| r.clone()).collect();
    let (t16, _, t16_own) = count_instructions(&qemu_elf, &dir, &thermal_ranges, CALLS, block, true)?;
    build_qemu_fixed()?;
    let fixed_range = symbol_range(&fixed_elf(), HOT_PATH_FIXED)?;
    let (q16, _, _) =
        count_instructions(&fixed_elf(), &dir, std::slice::from_ref(&fixed_range), CALLS, block, false)?;
    let _ = std::fs::remove_dir_all(&dir);
    let per_set_block = i16 as f64 / (CALLS * block) as f64;
    let per_set_marginal = (i16 - i1) as f64 / (CALLS * (block - 1)) as f64;
    let per_call_single = i1 as f64 / CALLS as f64;
    println!();
    println!(
        "hot path `{HOT_PATH}` ({:#x}..{:#x}), f32, executed instructions on QEMU's Cortex-M4F:",
        range.start, range.end
    );
    println!(
        "  {CALLS} calls x {block} sets: {i16} instructions = {per_set_block:.2} per sample set (budget 40)"
    );
    println!("  {CALLS} calls x 1 set:   {i1} instructions = {per_call_single:.2} per single-set call");
    println!("  marginal cost of one more set in a block: {per_set_marginal:.2} instructions");
    let per_set_thermal = t16 as f64 / (CALLS * block) as f64;
    println!(
        "thermal record (`{HOT_PATH_THERMAL}` and what it calls: {}): {CALLS} calls x {block} sets: {t16} instructions = {per_set_thermal:.2} per sample set (aim 60; model 4: {per_set_block:.2}), the calibration re-evaluated once per {block} sets included",
        thermal_tree.iter().skip(1).map(|(n, _)| n.as_str()).collect::<Vec<_>>().join(", ")
    );
    println!(
        "  of which in `{HOT_PATH_THERMAL}` itself {:.2} per set, in what it calls (the re-evaluation) {:.2} per set",
        t16_own as f64 / (CALLS * block) as f64,
        (t16 - t16_own) as f64 / (CALLS * block) as f64
    );
    println!(
        "fixed-point build (`{HOT_PATH_FIXED}`): {CALLS} calls x {block} sets: {q16} instructions = {:.2} per sample set",
        q16 as f64 / (CALLS * block) as f64
    );
    println!("real release build (node-real): flash text+data {flash} B ({:.1} KiB, budget 48 KiB), static RAM {ram} B ({:.1} KiB, budget 16 KiB)", flash as f64 / 1024.0, ram as f64 / 1024.0);
    ensure!(flash <= FLASH_BUDGET, "flash {flash} B exceeds the 48 KiB budget");
    ensure!(ram <= RAM_BUDGET, "static RAM {ram} B exceeds the 16 KiB budget");
    if per_set_block > 40.0 {
        println!("warning: {per_set_block:.2} instructions per sample set exceeds the 40 aim");
    }
    if per_set_thermal > 60.0 {
        println!("warning: {per_set_thermal:.2} instructions per sample set with a thermal record exceeds the 60 aim");
    }
    Ok(())
}
