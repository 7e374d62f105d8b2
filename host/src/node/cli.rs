//! The node subcommands' arguments and entry points: `accelcal flash`, `accelcal monitor`,
//! `accelcal hil`.

use std::io::Write;
use std::path::PathBuf;

use anyhow::Context;
use clap::Args;

use crate::error::bad;

/// `accelcal flash`: write a calibration record into a node through a debug probe.
#[derive(Debug, Args)]
pub struct FlashArgs {
    /// The calibration record file (from `accelcal fit --record`).
    #[arg(value_name = "RECORD")]
    pub record: PathBuf,
    /// probe-rs target name of the node's MCU.
    #[arg(long, default_value = "STM32L475VGTx")]
    pub chip: String,
    /// Debug probe to use, as VID:PID or VID:PID:SERIAL [default: the first one found].
    #[arg(long, value_name = "SELECTOR")]
    pub probe: Option<String>,
}

/// `accelcal monitor`: show a node's live stream.
#[derive(Debug, Args)]
pub struct MonitorArgs {
    /// Serial port of the node (the board's ST-LINK virtual COM port, e.g. /dev/ttyACM0).
    #[arg(long, value_name = "DEV")]
    pub port: String,
    /// Baud rate of the node's USART1.
    #[arg(long, default_value_t = super::monitor::NODE_BAUD)]
    pub baud: u32,
    /// Stop after this many messages [default: run until interrupted].
    #[arg(long, value_name = "N")]
    pub count: Option<u64>,
    /// First set the node's sampling rate per channel, Hz (100..=4000).
    #[arg(long, value_name = "HZ")]
    pub rate: Option<u32>,
}

/// `accelcal hil`: replay a campaign through the node's QEMU build.
#[derive(Debug, Args)]
pub struct HilArgs {
    /// The node's QEMU build (firmware/target/thumbv7em-none-eabihf/release/node-qemu).
    #[arg(long = "qemu", value_name = "ELF")]
    pub elf: PathBuf,
    /// Calibration record loaded into the node's flash (its device id must be the QEMU node's,
    /// 51454d552d422d4c34373545 = "QEMU-B-L475E").
    #[arg(long, value_name = "RECORD")]
    pub record: PathBuf,
    /// Campaign CSV whose channels x, y, z are replayed, row by row.
    #[arg(value_name = "CAMPAIGN")]
    pub campaign: PathBuf,
    /// CSV to write: `t_s,ax,ay,az`, the node's calibrated acceleration in m/s².
    #[arg(long, value_name = "OUT.csv")]
    pub out: PathBuf,
    /// The QEMU executable (QEMU >= 9 with the b-l475e-iot01a machine).
    #[arg(long, default_value = "qemu-system-arm", value_name = "PATH")]
    pub qemu_bin: PathBuf,
    /// Seconds the node may stay silent before the run fails.
    #[arg(long, default_value_t = 20)]
    pub timeout_s: u64,
}

fn read_file(path: &PathBuf, what: &str) -> anyhow::Result<Vec<u8>> {
    std::fs::read(path).map_err(|e| bad(format!("{}: cannot read the {what}: {e}", path.display())))
}

/// Runs `accelcal flash`.
pub fn run_flash(a: &FlashArgs) -> anyhow::Result<()> {
    let record = read_file(&a.record, "record")?;
    if let Err(e) = accelcal_shared::record::Record::parse(&record) {
        return Err(bad(format!("{}: {e}", a.record.display())));
    }
    let r = super::flash::flash_record(&record, &a.chip, a.probe.as_deref())
        .with_context(|| format!("writing {} to the node", a.record.display()))?;
    println!(
        "flash: wrote {} to record slot {} at {:#010x}, sequence {}; the node now uses it",
        a.record.display(),
        r.slot,
        r.address,
        r.sequence
    );
    Ok(())
}

/// Runs `accelcal monitor`.
pub fn run_monitor(a: &MonitorArgs) -> anyhow::Result<()> {
    super::monitor::monitor(&a.port, a.baud, a.count, a.rate, &mut std::io::stdout().lock())
}

/// Runs `accelcal hil`.
pub fn run_hil(a: &HilArgs, warnings: &mut crate::cmd::Warnings) -> anyhow::Result<()> {
    let record = read_file(&a.record, "record")?;
    if let Err(e) = accelcal_shared::record::Record::parse(&record) {
        return Err(bad(format!("{}: {e}", a.record.display())));
    }
    if !a.elf.is_file() {
        return Err(bad(format!(
            "{}: no such firmware ELF (build it with `cargo xtask test` or see firmware/README.md)",
            a.elf.display()
        )));
    }
    // The header and the first block are checked before the node starts.
    let mut codes = super::hil::CampaignCodes::open(&a.campaign)?;
    let mut opts = super::hil::HilOptions::new(&a.elf);
    opts.qemu = a.qemu_bin.clone();
    opts.timeout = std::time::Duration::from_secs(a.timeout_s);
    let mut out = crate::output::AtomicFile::create(&a.out)?;
    let writing = || format!("writing {}", a.out.display());
    writeln!(out.writer(), "{}", super::hil::CSV_HEADER).with_context(writing)?;
    let mut sets = 0;
    let status = super::hil::replay_blocks(&opts, &record, codes.by_ref(), |t_s, accel| {
        sets += accel.len();
        super::hil::write_rows(out.writer(), &t_s, accel).with_context(writing)
    })
    .map_err(|e| if e.is::<super::hil::HilError>() { e.context("running the node in QEMU") } else { e })?;
    warnings.extend(codes.warnings());
    out.commit()?;
    println!(
        "hil: {} sample sets replayed through {}; {}; wrote {}",
        sets,
        a.elf.display(),
        super::monitor::format_status(&status),
        a.out.display()
    );
    Ok(())
}
