//! The node subcommands: `accelcal flash`, `accelcal monitor`, `accelcal hil`.

use std::io::Write;
use std::path::PathBuf;

use accelcal_core::error::bad;
use accelcal_line::node::session::Session;
use accelcal_line::node::{flash, hil, monitor};
use accelcal_shared::wire::RecordStatus;
use anyhow::Context;

use crate::settings::line::{Flash, Hil};
use crate::settings::values::FlashRoute;

fn read_file(path: &PathBuf, what: &str) -> anyhow::Result<Vec<u8>> {
    std::fs::read(path).map_err(|e| bad(format!("{}: cannot read the {what}: {e}", path.display())))
}

/// Runs `accelcal flash`.
pub fn run_flash(a: &Flash) -> anyhow::Result<()> {
    let record = read_file(&a.record, "record")?;
    let rec = accelcal_shared::record::Record::parse(&record)
        .map_err(|e| bad(format!("{}: {e}", a.record.display())))?;
    accelcal_core::calibrate::gate(&a.record, &rec)?;
    // With --db, what is written is the run's stored record (the file must be it).
    let mut db = super::store::open(a.store.as_ref())?;
    let stored = match &mut db {
        Some(rdb) => Some(super::store::record_to_flash(rdb, &a.record, &record)?),
        None => None,
    };
    let record = stored.as_ref().map_or(record.clone(), |s| s.bytes().to_vec());
    let answer = std::time::Duration::from_secs(10);
    let node_id = match (&a.route, &a.port) {
        (FlashRoute::Gdb(_), Some(port)) => Some(Session::open(port, a.baud, answer)?.info()?.device_id),
        _ => None,
    };
    let writing = || format!("writing {} to the node", a.record.display());
    let (slot, sequence, address) = match &a.route {
        FlashRoute::Probe { chip, probe } => {
            let r = flash::flash_record(&record, chip, probe.as_deref()).with_context(writing)?;
            (r.slot, r.sequence, r.address)
        }
        FlashRoute::Gdb(addr) => {
            match flash::flash_record_gdb(&record, addr, node_id, a.cut_after).with_context(writing)? {
                flash::GdbFlash::Written(r) => (r.slot, r.sequence, r.address),
                flash::GdbFlash::Cut { slot, bytes } => {
                    outln!(
                    "flash: write CUT after {bytes} bytes of record slot {slot} (--cut-after), MCU reset: the previous \
                     record stays in force"
                )?;
                    return Ok(());
                }
            }
        }
    };
    outln!(
        "flash: wrote {} to record slot {slot} at {address:#010x}, sequence {sequence}; MCU reset",
        a.record.display()
    )?;
    if let Some(port) = &a.port {
        let crc = u32::from_le_bytes(record[rec.len() - 4..rec.len()].try_into().expect("4 bytes"));
        confirm(port, a.baud, slot, sequence, crc)?;
    }
    if let (Some(rdb), Some(rec)) = (&mut db, &stored) {
        rdb.db.record_flashed(rec).with_context(|| {
            format!(
                "the node runs the new record CRC {:08x}{}, but the database did not note the flash: run the same flash again to note it",
                rec.crc32(),
                if a.port.is_some() { " (it said so after its reset)" } else { "" }
            )
        })?;
        super::store::crash_point("db:flash");
        outln!(
            "db: run {}: flash of record CRC {:08x} stored in {}",
            rec.run_id(),
            rec.crc32(),
            rdb.db.target()
        )?;
    }
    Ok(())
}

/// Asks the rebooted node which record it runs; it must be the one just written. The node is
/// asked until it says so or 20 s have passed: the reset that the flash requested takes effect a
/// moment later (QEMU's main loop, a real board's debug probe), and an answer the node gave
/// before it (the record in force before) is not the verdict. The last answer is.
fn confirm(port: &str, baud: u32, slot: u8, sequence: u32, crc: u32) -> anyhow::Result<()> {
    let mut s = Session::open(port, baud, std::time::Duration::from_secs(10))?;
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(20);
    let last = loop {
        let late = std::time::Instant::now() > deadline;
        match s.info() {
            Ok(i) => match i.record {
                RecordStatus::InUse { slot: s2, sequence: q, crc: c, .. }
                    if (s2, q, c) == (slot, sequence, crc) =>
                {
                    outln!("flash: confirmed over {port}: the node runs the new record (slot {slot}, sequence {sequence}, CRC {crc:08x})")?;
                    return Ok(());
                }
                other if late => break other,
                _ => std::thread::sleep(std::time::Duration::from_millis(200)),
            },
            // The node reboots: no answer for a while.
            Err(e) if late => return Err(e.into()),
            Err(_) => {}
        }
    };
    Err(anyhow::Error::new(flash::FlashError::Verify(slot)).context(format!(
        "{port}: 20 s after the reset the node reports {last:?}, not the new record (slot {slot}, sequence {sequence}, CRC {crc:08x})"
    )))
}

/// Runs `accelcal monitor`.
pub fn run_monitor(a: &crate::settings::line::Monitor) -> anyhow::Result<()> {
    monitor::monitor(&a.port, a.baud, a.count, a.rate_hz, a.silence, &mut std::io::stdout().lock())
}

/// Runs `accelcal hil`.
pub fn run_hil(a: &Hil, warnings: &mut super::Warnings) -> anyhow::Result<()> {
    let record = read_file(&a.record, "record")?;
    let thermal = match accelcal_shared::record::Record::parse(&record) {
        Ok(r) => r.thermal.is_some(),
        Err(e) => return Err(bad(format!("{}: {e}", a.record.display()))),
    };
    if !a.elf.is_file() {
        return Err(bad(format!(
            "{}: no such firmware ELF (build it with `cargo xtask test` or see firmware/README.md)",
            a.elf.display()
        )));
    }
    // The header and the first block are checked before the node starts.
    let mut codes = hil::CampaignCodes::open_with(&a.campaign, a.codes)?;
    if thermal && !codes.has_temp() {
        return Err(bad(format!(
            "{}: no column `temp_c`: the record {} has thermal terms, and the node replays each set with its temperature",
            a.campaign.display(),
            a.record.display()
        )));
    }
    let mut opts = hil::HilOptions::new(&a.elf);
    opts.qemu = a.qemu_bin.clone();
    opts.timeout = a.timeout;
    let mut out = accelcal_core::output::AtomicFile::create(&a.out)?;
    let writing = || format!("writing {}", a.out.display());
    let header = if thermal { hil::CSV_HEADER_THERMAL } else { hil::CSV_HEADER };
    writeln!(out.writer(), "{header}").with_context(writing)?;
    let (mut sets, mut flagged) = (0, 0);
    // A thermal record's blocks go with their temperatures; a model-4 record's without.
    let blocks = codes.by_ref().map(|b| b.map(|(c, rows)| (c, rows.temp_c.filter(|_| thermal), rows.t_s)));
    let status = hil::replay_blocks(&opts, &record, blocks, |t_s, accel, temp| {
        sets += accel.len();
        flagged += usize::from(temp.is_some_and(|t| t.out_of_range)) * accel.len();
        hil::write_rows(out.writer(), &t_s, accel, thermal.then_some(temp)).with_context(writing)
    })
    .map_err(|e| if e.is::<hil::HilError>() { e.context("running the node in QEMU") } else { e })?;
    warnings.extend(codes.warnings());
    out.commit()?;
    let thermal_note = if thermal {
        format!("; {flagged} sets in blocks calibrated outside the record's temperature range")
    } else {
        String::new()
    };
    outln!(
        "hil: {} sample sets replayed through {}{thermal_note}; {}; wrote {}",
        sets,
        a.elf.display(),
        monitor::format_status(&status),
        a.out.display()
    )?;
    Ok(())
}
