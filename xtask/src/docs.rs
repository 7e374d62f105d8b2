//! `cargo xtask docs`: writes the guide's command reference (`docs/src/reference/commands.md`)
//! from the help of the `accelcal` binary it builds (`cargo build -p accelcal`, the debug
//! profile). The text is [`commands_md`]'s, which `tests/docs.rs` compares with the committed file.

use std::path::PathBuf;
use std::process::Command;

use anyhow::{bail, Context};

use crate::commands_md::{commands_md, PATH};
use crate::root;

/// The cargo target directory: `CARGO_TARGET_DIR` (relative to the repository root when
/// relative), else `target/`.
fn target_dir() -> PathBuf {
    match std::env::var_os("CARGO_TARGET_DIR") {
        Some(d) if !d.is_empty() => root().join(d),
        _ => root().join("target"),
    }
}

/// Builds the binary and writes the reference.
pub fn run() -> anyhow::Result<()> {
    crate::run(&root(), "cargo", &["build", "--locked", "-p", "accelcal"])?;
    let bin = target_dir().join("debug").join("accelcal");
    if !bin.is_file() {
        bail!("{} is missing after `cargo build -p accelcal`", bin.display());
    }
    let text = commands_md(&mut |args: &[&str]| -> anyhow::Result<String> {
        let out = Command::new(&bin)
            .args(args)
            .output()
            .with_context(|| format!("cannot run {}", bin.display()))?;
        if !out.status.success() {
            bail!("`accelcal {}` failed: {}", args.join(" "), String::from_utf8_lossy(&out.stderr));
        }
        String::from_utf8(out.stdout)
            .with_context(|| format!("`accelcal {}` printed non-UTF-8", args.join(" ")))
    })?;
    let path = root().join(PATH);
    let old = std::fs::read_to_string(&path).unwrap_or_default();
    std::fs::write(&path, &text).with_context(|| format!("writing {}", path.display()))?;
    let sections = text.lines().filter(|l| l.starts_with("## accelcal")).count();
    let changed = if old == text { "unchanged" } else { "updated" };
    eprintln!("[xtask] docs: {PATH} {changed} ({sections} sections)");
    Ok(())
}
