//! Writing a calibration record into a real node through a debug probe (probe-rs as a library).
//!
//! The write never leaves the node without a valid record and never touches the firmware:
//! 1. attach, read both record slots and the MCU's unique id; a slot the probe cannot read (the
//!    read fails, or it raised a double ECC error in that slot, `FLASH_ECCR`) is unreadable;
//! 2. refuse a record no node accepts ([`accelcal_shared::boot::gate`], checked before the probe is
//!    opened) and a record made for another device;
//! 3. plan the write with [`WritePlan::from_readings`]: the slot *not* in force (an unreadable slot
//!    is never in force, so it is the target), sequence number one higher, a version-2 page;
//! 4. program exactly that slot's 2 KiB page (one flash sector; `keep_unwritten_bytes` keeps
//!    everything else, `verify` reads it back); the STM32L4 flash algorithm erases the page and
//!    programs it in ascending double words, so the commit double word at its end lands last;
//! 5. read both slots again and check that the new record is the one in force.
//!
//! Once attached, the core is reset on every path, success or error, so the firmware runs again
//! (and loads the new record) and is never left halted.
//!
//! A power cut or a disconnect during step 4 leaves the target slot without its commit, failing
//! its CRC, or unreadable, so the old record stays in force: the slot image only becomes valid
//! once complete. Not tested against hardware in this repository (no probe in CI); the slot logic
//! it relies on is tested with a power-cut simulation in the probe's programming order in
//! `accelcal_shared::slots`.

use accelcal_shared::contract::{N_SLOTS, SLOT_ADDRS, UID_ADDR};
use accelcal_shared::flash_ecc::{nmi_action, NmiAction, FLASH_ECCR_ADDR};
use accelcal_shared::record::Record;
use accelcal_shared::slots::{select_readings, WritePlan, SLOT_SIZE};
use probe_rs::flashing::DownloadOptions;
use probe_rs::probe::list::Lister;
use probe_rs::probe::DebugProbeSelector;
use probe_rs::{MemoryInterface, Permissions, Session};

/// Why a record could not be written.
#[derive(Debug, thiserror::Error)]
pub enum FlashError {
    /// The record file is not a valid record.
    #[error("invalid calibration record: {0}")]
    Record(accelcal_shared::record::RecordError),
    /// A node would refuse the record ([`accelcal_shared::boot::gate`]).
    #[error("{}", crate::calibrate::refusal(*.0))]
    Refused(accelcal_shared::boot::BootError),
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
    /// The write failed and the reset after it failed too: the core may be left halted.
    #[error("{error}; resetting the core afterwards failed too ({reset}): power-cycle the node")]
    NotReset {
        /// The write's error.
        error: Box<FlashError>,
        /// The reset's error.
        reset: String,
    },
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
/// `chip` (e.g. `STM32L475VGTx`). Once attached, the core is reset whatever happens.
pub fn flash_record(record: &[u8], chip: &str, selector: Option<&str>) -> Result<FlashReport, FlashError> {
    let rec = Record::parse(record).map_err(FlashError::Record)?;
    accelcal_shared::boot::gate(&rec).map_err(FlashError::Refused)?;
    let record = &record[..rec.len()];

    let lister = Lister::new();
    let probes = lister.list_all();
    let probe = match selector {
        Some(s) => {
            let sel: DebugProbeSelector = s.parse().map_err(probe_err)?;
            lister
                .open(sel)
                .map_err(|e| FlashError::NoProbe(format!(" matching {s}: {e}; {}", seen(&probes))))?
        }
        None => {
            let first = probes.first().ok_or_else(|| FlashError::NoProbe(format!(": {}", seen(&probes))))?;
            first.open().map_err(probe_err)?
        }
    };
    let mut session = probe.attach(chip, Permissions::default()).map_err(probe_err)?;
    let result = write_attached(&mut session, &rec, record);
    let reset = session.core(0).and_then(|mut core| core.reset()).map_err(|e| e.to_string());
    finish(result, reset)
}

/// What probe-rs sees, and what to check when it is not the probe wanted.
fn seen(probes: &[probe_rs::probe::DebugProbeInfo]) -> String {
    if probes.is_empty() {
        return "probe-rs sees none. Check that the board's ST-LINK USB port (CN7, \"USB STLINK\") is \
                connected, that this user may open the USB device (on Linux, probe-rs's udev rules), and \
                that no other program (OpenOCD, STM32CubeProgrammer, a debugger) holds it"
            .into();
    }
    let list: Vec<String> = probes
        .iter()
        .map(|p| {
            let serial = p.serial_number.as_deref().map(|s| format!(":{s}")).unwrap_or_default();
            format!("{} ({:04x}:{:04x}{serial})", p.identifier, p.vendor_id, p.product_id)
        })
        .collect();
    format!("probe-rs sees {} (select one with --probe VID:PID[:SERIAL])", list.join(", "))
}

/// The outcome of a write followed by the core reset: the write's error first, a failed reset
/// named with it.
fn finish(
    result: Result<FlashReport, FlashError>,
    reset: Result<(), String>,
) -> Result<FlashReport, FlashError> {
    match (result, reset) {
        (Ok(report), Ok(())) => Ok(report),
        (Ok(_), Err(reset)) => Err(FlashError::Probe(format!("resetting the core after the write: {reset}"))),
        (Err(error), Ok(())) => Err(error),
        (Err(error), Err(reset)) => Err(FlashError::NotReset { error: Box::new(error), reset }),
    }
}

/// Steps 1–5 of the module docs on an attached session (the caller resets the core).
fn write_attached(session: &mut Session, rec: &Record, record: &[u8]) -> Result<FlashReport, FlashError> {
    let mut slots = [[0u8; SLOT_SIZE]; N_SLOTS];
    let mut uid = [0u8; 12];
    let readable = read_slots(session, &mut slots)?;
    session.core(0).map_err(probe_err)?.read_8(UID_ADDR.into(), &mut uid).map_err(probe_err)?;
    if rec.device_id != uid {
        return Err(FlashError::WrongDevice { record: hex(&rec.device_id), mcu: hex(&uid) });
    }
    let plan = WritePlan::from_readings(readings(&slots, readable), record).map_err(FlashError::Plan)?;
    let address = SLOT_ADDRS[plan.slot as usize].into();

    let mut loader = session.target().flash_loader();
    // The whole page: exactly one 2 KiB sector, erased bytes included, programmed in ascending
    // double words, so the commit double word at the page's end is programmed last.
    loader.add_data(address, &plan.page).map_err(probe_err)?;
    let mut options = DownloadOptions::default();
    options.keep_unwritten_bytes = true;
    options.verify = true;
    loader.commit(session, options).map_err(probe_err)?;

    let readable = read_slots(session, &mut slots)?;
    match select_readings(readings(&slots, readable)) {
        Ok(a) if a.slot == plan.slot && a.image.sequence == plan.sequence => {}
        _ => return Err(FlashError::Verify(plan.slot)),
    }
    Ok(FlashReport { slot: plan.slot, sequence: plan.sequence, address })
}

/// The slot readings: a slot's bytes when it was readable.
fn readings(slots: &[[u8; SLOT_SIZE]; N_SLOTS], readable: [bool; N_SLOTS]) -> [Option<&[u8]>; N_SLOTS] {
    [0, 1].map(|i| readable[i].then_some(&slots[i][..]))
}

/// Reads both slots through the probe; returns which ones were readable. A slot is unreadable
/// when the probe's read fails or when reading it raised a double ECC error in it (FLASH_ECCR, the
/// same decision as the node's NMI handler, [`nmi_action`]); that error is then cleared. (If the
/// node's firmware is running, its NMI handler may clear ECCD first; the torn slot's bytes then
/// fail its commit or CRC check, so it is not in force and is planned as the target all the same.)
fn read_slots(
    session: &mut Session,
    slots: &mut [[u8; SLOT_SIZE]; N_SLOTS],
) -> Result<[bool; N_SLOTS], FlashError> {
    let mut core = session.core(0).map_err(probe_err)?;
    let mut readable = [true; N_SLOTS];
    for (i, buf) in slots.iter_mut().enumerate() {
        if core.read_8(SLOT_ADDRS[i].into(), buf).is_err() {
            readable[i] = false;
        }
        let eccr = core.read_word_32(FLASH_ECCR_ADDR.into()).map_err(probe_err)?;
        if let NmiAction::SlotUnreadable { slot, clear } = nmi_action(eccr) {
            readable[slot as usize] = false;
            core.write_word_32(FLASH_ECCR_ADDR.into(), clear).map_err(probe_err)?;
        }
    }
    Ok(readable)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn no_probe_says_what_to_check() {
        let e = FlashError::NoProbe(format!(": {}", seen(&[])));
        let msg = e.to_string();
        assert!(msg.starts_with("no debug probe found: probe-rs sees none."), "{msg}");
        assert!(msg.contains("USB STLINK") && msg.contains("udev"), "{msg}");
    }

    fn report() -> FlashReport {
        FlashReport { slot: 1, sequence: 2, address: 0x080F_F800 }
    }

    #[test]
    fn the_reset_follows_every_outcome_and_its_failure_is_named() {
        assert_eq!(finish(Ok(report()), Ok(())).unwrap(), report());
        let e = finish(Ok(report()), Err("link lost".into())).unwrap_err();
        assert_eq!(e.to_string(), "probe: resetting the core after the write: link lost");
        let e = finish(Err(FlashError::Verify(1)), Ok(())).unwrap_err();
        assert!(matches!(e, FlashError::Verify(1)), "{e}");
        let e = finish(Err(FlashError::Verify(1)), Err("link lost".into())).unwrap_err();
        assert_eq!(
            e.to_string(),
            "after writing slot 1, the record in force is not the new one; resetting the core \
             afterwards failed too (link lost): power-cycle the node"
        );
    }

    #[test]
    fn an_unreadable_slot_is_planned_as_the_target() {
        use accelcal_shared::linear::Model4;
        use accelcal_shared::slots::SlotImage;
        let m = Model4 { u0: [32000.0; 3], k: [[1600.0, 0.0, 0.0], [0.0, 1600.0, 0.0], [0.0, 0.0, 1600.0]] };
        let mut buf = [0u8; accelcal_shared::record::MAX_RECORD_LEN];
        let n = Record::from_model4(*b"QEMU-B-L475E", 1, &m).emit(&mut buf).unwrap();
        let page = SlotImage::build(&buf[..n], 5).unwrap();
        let slots = [page, [0u8; SLOT_SIZE]];
        let plan = WritePlan::from_readings(readings(&slots, [true, false]), &buf[..n]).unwrap();
        assert_eq!((plan.slot, plan.sequence), (1, 6));
        let plan = WritePlan::from_readings(readings(&slots, [false, true]), &buf[..n]).unwrap();
        assert_eq!((plan.slot, plan.sequence), (0, 1));
    }
}
