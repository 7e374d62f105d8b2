//! Writing a calibration record into a real node through a debug probe (probe-rs as a library).
//!
//! The write never leaves the node without a valid record and never touches the firmware:
//! 1. attach, read both record slots and the MCU's unique id;
//! 2. refuse a record made for another device;
//! 3. plan the write with [`WritePlan`]: the slot *not* in force, sequence number one higher;
//! 4. program exactly that slot's 2 KiB page (one flash sector; `keep_unwritten_bytes` keeps
//!    everything else, `verify` reads it back);
//! 5. read both slots again and check that the new record is the one in force; reset the core so
//!    the firmware loads it.
//!
//! A power cut or a disconnect during step 4 leaves the target slot failing its CRC (or erased),
//! so the old record stays in force: the slot image only becomes valid once complete.
//! Not tested against hardware in this repository (no probe in CI); the slot logic it relies on is
//! tested with a power-cut simulation in `accelcal_shared::slots`.

use accelcal_shared::record::Record;
use accelcal_shared::slots::{select, WritePlan, SLOT_SIZE};
use probe_rs::flashing::DownloadOptions;
use probe_rs::probe::list::Lister;
use probe_rs::probe::DebugProbeSelector;
use probe_rs::{MemoryInterface, Permissions};

use super::{RECORD_SLOTS, UID_ADDR};

/// Why a record could not be written.
#[derive(Debug, thiserror::Error)]
pub enum FlashError {
    /// The record file is not a valid record.
    #[error("invalid calibration record: {0}")]
    Record(accelcal_shared::record::RecordError),
    /// No probe is connected (or none matches the selector).
    #[error("no debug probe found{0}")]
    NoProbe(String),
    /// The record was made for another MCU.
    #[error("the record is for device {record}, the connected MCU is {mcu}")]
    WrongDevice {
        /// Device id in the record (hex).
        record: String,
        /// The MCU's unique id (hex).
        mcu: String,
    },
    /// Planning the slot write failed.
    #[error("cannot plan the slot write: {0}")]
    Plan(accelcal_shared::slots::SlotError),
    /// Read-back does not show the new record in force.
    #[error("after writing slot {0}, the record in force is not the new one")]
    Verify(u8),
    /// probe-rs failed.
    #[error("probe: {0}")]
    Probe(String),
}

fn probe_err(e: impl std::fmt::Display) -> FlashError {
    FlashError::Probe(e.to_string())
}

fn hex(b: &[u8]) -> String {
    b.iter().map(|x| format!("{x:02x}")).collect()
}

/// What was written.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FlashReport {
    /// Slot written (0 or 1).
    pub slot: u8,
    /// Its sequence number.
    pub sequence: u32,
    /// Flash address of the slot.
    pub address: u64,
}

/// Writes `record` (the bytes of a record file) into the inactive slot of the node attached
/// through the probe `selector` (VID:PID[:serial]; the first probe found when `None`), for target
/// `chip` (e.g. `STM32L475VGTx`).
pub fn flash_record(record: &[u8], chip: &str, selector: Option<&str>) -> Result<FlashReport, FlashError> {
    let rec = Record::parse(record).map_err(FlashError::Record)?;
    let record = &record[..rec.len()];

    let lister = Lister::new();
    let probe = match selector {
        Some(s) => {
            let sel: DebugProbeSelector = s.parse().map_err(probe_err)?;
            lister.open(sel).map_err(|e| FlashError::NoProbe(format!(" matching {s}: {e}")))?
        }
        None => {
            let probes = lister.list_all();
            let first = probes.first().ok_or_else(|| FlashError::NoProbe(String::new()))?;
            first.open().map_err(probe_err)?
        }
    };
    let mut session = probe.attach(chip, Permissions::default()).map_err(probe_err)?;

    let mut slots = [[0u8; SLOT_SIZE]; 2];
    let mut uid = [0u8; 12];
    {
        let mut core = session.core(0).map_err(probe_err)?;
        for (buf, addr) in slots.iter_mut().zip(RECORD_SLOTS) {
            core.read_8(addr, buf).map_err(probe_err)?;
        }
        core.read_8(UID_ADDR, &mut uid).map_err(probe_err)?;
    }
    if rec.device_id != uid {
        return Err(FlashError::WrongDevice { record: hex(&rec.device_id), mcu: hex(&uid) });
    }
    let plan = WritePlan::new([&slots[0], &slots[1]], record).map_err(FlashError::Plan)?;
    let address = RECORD_SLOTS[plan.slot as usize];

    let mut loader = session.target().flash_loader();
    // The whole page: exactly one 2 KiB sector, erased bytes included.
    loader.add_data(address, &plan.page).map_err(probe_err)?;
    let mut options = DownloadOptions::default();
    options.keep_unwritten_bytes = true;
    options.verify = true;
    loader.commit(&mut session, options).map_err(probe_err)?;

    let mut core = session.core(0).map_err(probe_err)?;
    for (buf, addr) in slots.iter_mut().zip(RECORD_SLOTS) {
        core.read_8(addr, buf).map_err(probe_err)?;
    }
    match select([&slots[0], &slots[1]]) {
        Ok(a) if a.slot == plan.slot && a.image.sequence == plan.sequence => {}
        _ => return Err(FlashError::Verify(plan.slot)),
    }
    core.reset().map_err(probe_err)?;
    Ok(FlashReport { slot: plan.slot, sequence: plan.sequence, address })
}
