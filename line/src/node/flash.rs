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

use accelcal_core::error::{Classify, Kind};
use accelcal_shared::contract::{N_SLOTS, SLOT_ADDRS, UID_ADDR};
use accelcal_shared::flash_ecc::{nmi_action, rearm, NmiAction, ECCC, ECCD, FLASH_ECCR_ADDR};
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
    #[error("{}", accelcal_core::calibrate::refusal(*.0, &accelcal_core::error::Plain))]
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
    /// The GDB server failed.
    #[error(transparent)]
    Gdb(#[from] super::gdb::GdbError),
    /// The GDB server cannot read the MCU's unique id and the node's link did not give it.
    #[error(
        "the gdb server cannot read the MCU's unique id at {UID_ADDR:#010x} ({0}); give --port so that the node \
         tells its id over its link (QEMU does not map the unique-id area)"
    )]
    NoDeviceId(String),
    /// The write failed and the reset after it failed too: the core may be left halted.
    #[error("{error}; resetting the core afterwards failed too ({reset}): power-cycle the node")]
    NotReset {
        /// The write's error.
        error: Box<FlashError>,
        /// The reset's error.
        reset: String,
    },
    /// The write failed or was refused, and the MCU was then reset: it runs the record that was
    /// in force before.
    #[error("{0}; the MCU was reset and runs the record in force before")]
    Released(Box<FlashError>),
}

impl accelcal_core::error::Worded for FlashError {
    fn worded(&self, w: &dyn accelcal_core::error::Wording) -> Option<String> {
        match self {
            FlashError::Refused(e) => Some(accelcal_core::calibrate::refusal(*e, w)),
            _ => None,
        }
    }
}

impl Classify for FlashError {
    fn kind(&self) -> Kind {
        match self {
            // The record given: unreadable, one no node accepts, one too large for a slot, or
            // another unit's.
            FlashError::Record(_)
            | FlashError::Refused(_)
            | FlashError::Plan(_)
            | FlashError::WrongDevice { .. } => Kind::BadInput,
            FlashError::Gdb(e) => e.kind(),
            FlashError::Released(e) => e.kind(),
            FlashError::NoProbe(_)
            | FlashError::Verify(_)
            | FlashError::Probe(_)
            | FlashError::NoDeviceId(_)
            | FlashError::NotReset { .. } => Kind::Environment,
        }
    }
}

fn probe_err(e: impl std::fmt::Display) -> FlashError {
    FlashError::Probe(e.to_string())
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
fn finish<T>(result: Result<T, FlashError>, reset: Result<(), String>) -> Result<T, FlashError> {
    match (result, reset) {
        (Ok(report), Ok(())) => Ok(report),
        (Ok(_), Err(reset)) => Err(FlashError::Probe(format!("resetting the core after the write: {reset}"))),
        (Err(error), Ok(())) => Err(FlashError::Released(Box::new(error))),
        (Err(error), Err(reset)) => Err(FlashError::NotReset { error: Box::new(error), reset }),
    }
}

/// What writing a record slot needs of the node's memory: a probe-rs session, or a GDB server.
pub trait NodeMemory {
    /// Reads `buf.len()` bytes at `addr`.
    fn read(&mut self, addr: u32, buf: &mut [u8]) -> Result<(), FlashError>;
    /// Writes one 32-bit word at `addr` (a peripheral register).
    fn write_u32(&mut self, addr: u32, v: u32) -> Result<(), FlashError>;
    /// Erases the flash page at `addr` and programs `page` into it, in ascending order.
    fn program_page(&mut self, addr: u32, page: &[u8]) -> Result<(), FlashError>;
}

/// A probe-rs session as [`NodeMemory`].
struct Probe<'a>(&'a mut Session);

impl NodeMemory for Probe<'_> {
    fn read(&mut self, addr: u32, buf: &mut [u8]) -> Result<(), FlashError> {
        self.0.core(0).map_err(probe_err)?.read_8(addr.into(), buf).map_err(probe_err)
    }
    fn write_u32(&mut self, addr: u32, v: u32) -> Result<(), FlashError> {
        self.0.core(0).map_err(probe_err)?.write_word_32(addr.into(), v).map_err(probe_err)
    }
    fn program_page(&mut self, addr: u32, page: &[u8]) -> Result<(), FlashError> {
        let mut loader = self.0.target().flash_loader();
        // The whole page: exactly one 2 KiB sector, erased bytes included, programmed in ascending
        // double words, so the commit double word at the page's end is programmed last.
        loader.add_data(addr.into(), page).map_err(probe_err)?;
        let mut options = DownloadOptions::default();
        options.keep_unwritten_bytes = true;
        options.verify = true;
        loader.commit(self.0, options).map_err(probe_err)
    }
}

/// A GDB server as [`NodeMemory`]. Flash is programmed by the server's flash driver when it has
/// one (`vFlashErase`/`vFlashWrite`/`vFlashDone`: Black Magic Probe, OpenOCD); otherwise (QEMU's
/// gdbstub, whose flash is plain memory) the page is first filled with 0xFF, as an erase leaves
/// it, then written in ascending chunks, so that the commit double word at its end lands last.
pub struct Gdb {
    client: super::gdb::GdbClient,
    /// Program only this many bytes of the page after erasing it, then stop (a write cut
    /// part-way, for tests of the torn-write safety).
    pub cut_after: Option<usize>,
}

impl NodeMemory for Gdb {
    fn read(&mut self, addr: u32, buf: &mut [u8]) -> Result<(), FlashError> {
        Ok(self.client.read(addr, buf)?)
    }
    fn write_u32(&mut self, addr: u32, v: u32) -> Result<(), FlashError> {
        Ok(self.client.write(addr, &v.to_le_bytes())?)
    }
    fn program_page(&mut self, addr: u32, page: &[u8]) -> Result<(), FlashError> {
        let n = self.cut_after.unwrap_or(page.len()).min(page.len());
        if self.cut_after.is_none() && self.client.program_flash(addr, page)? {
            return Ok(());
        }
        self.client.write(addr, &vec![0xFF; page.len()])?;
        Ok(self.client.write(addr, &page[..n])?)
    }
}

/// SCB AIRCR (ARMv7-M ARM §B3.2.6): VECTKEY 0x05FA with SYSRESETREQ requests a system reset.
const AIRCR: u32 = 0xE000_ED0C;
const AIRCR_SYSRESETREQ: u32 = 0x05FA_0004;

/// What a write through a GDB server did.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GdbFlash {
    /// The record was written and read back in force; the MCU was reset.
    Written(FlashReport),
    /// The write was cut after `bytes` bytes of slot `slot` (`cut_after`), and the MCU reset.
    Cut {
        /// Slot written in part.
        slot: u8,
        /// Bytes written after the erase.
        bytes: usize,
    },
}

/// Writes `record` into the inactive slot through the GDB server at `addr` (steps 1–5 of the
/// module docs), then resets the MCU (SYSRESETREQ) and detaches, so the node boots with the new
/// record. `device_id` is the node's id as its link reports it, used when the server cannot read
/// the unique-id area (QEMU). `cut_after` stops the page write part-way (tests).
///
/// A GDB server halts the core when a client connects, and a server such as QEMU's leaves it
/// halted when the client goes away without detaching: so once connected, every path, a refusal
/// and a failure of the server's connection included, resets the MCU and detaches ([`release`]),
/// reconnecting for it when the connection itself failed. The node then runs again with the
/// record in force before (a failed or refused write never puts a record in force), and the
/// error says so.
pub fn flash_record_gdb(
    record: &[u8],
    addr: &str,
    device_id: Option<[u8; 12]>,
    cut_after: Option<usize>,
) -> Result<GdbFlash, FlashError> {
    let rec = Record::parse(record).map_err(FlashError::Record)?;
    accelcal_shared::boot::gate(&rec).map_err(FlashError::Refused)?;
    let record = &record[..rec.len()];
    let client = super::gdb::GdbClient::connect(addr, GDB_TIMEOUT)?;
    let mut mem = Gdb { client, cut_after };
    let result = write_gdb(&mut mem, &rec, record, device_id, cut_after);
    finish(result, release(mem.client, addr))
}

/// How long a GDB server may take to answer one request.
const GDB_TIMEOUT: std::time::Duration = std::time::Duration::from_secs(10);

/// Steps 1–5 through a GDB server, or the cut write of `cut_after` (the caller releases the core).
fn write_gdb(
    mem: &mut Gdb,
    rec: &Record,
    record: &[u8],
    device_id: Option<[u8; 12]>,
    cut_after: Option<usize>,
) -> Result<GdbFlash, FlashError> {
    let mut uid = [0u8; 12];
    let uid = match mem.read(UID_ADDR, &mut uid) {
        Ok(()) => uid,
        Err(e) => device_id.ok_or_else(|| FlashError::NoDeviceId(e.to_string()))?,
    };
    match cut_after {
        None => write_slot(mem, rec, record, uid).map(GdbFlash::Written),
        Some(n) => {
            let plan = plan_write(mem, rec, record, uid)?;
            mem.program_page(SLOT_ADDRS[plan.slot as usize], &plan.page)?;
            Ok(GdbFlash::Cut { slot: plan.slot, bytes: n.min(plan.page.len()) })
        }
    }
}

/// Resets the MCU (SYSRESETREQ) and detaches, so that the target runs; when the connection
/// `client` failed (the server went away, a timeout), once more over a new connection. A reset
/// the server refuses still detaches (the core then runs on from where it was halted).
pub fn release(client: super::gdb::GdbClient, addr: &str) -> Result<(), String> {
    use super::gdb::{GdbClient, GdbError};
    // `Err(true, ..)`: the connection failed, worth another.
    let once = |mut c: GdbClient| match c.write(AIRCR, &AIRCR_SYSRESETREQ.to_le_bytes()) {
        Ok(()) => c.detach().map_err(|e| (true, e.to_string())),
        Err(e @ GdbError::Protocol { .. }) => match c.detach() {
            Ok(()) => Err((false, format!("the reset was refused ({e}); the core was resumed without it"))),
            Err(d) => Err((true, format!("the reset was refused ({e}), the detach failed ({d})"))),
        },
        Err(e) => Err((true, e.to_string())),
    };
    match once(client) {
        Ok(()) => Ok(()),
        Err((false, e)) => Err(e),
        Err((true, first)) => GdbClient::connect(addr, GDB_TIMEOUT)
            .map_err(|e| e.to_string())
            .and_then(|c| once(c).map_err(|(_, e)| e))
            .map_err(|again| format!("{first}; over a new connection: {again}")),
    }
}

/// Steps 1–5 of the module docs on an attached session (the caller resets the core).
fn write_attached(session: &mut Session, rec: &Record, record: &[u8]) -> Result<FlashReport, FlashError> {
    let mut mem = Probe(session);
    let mut uid = [0u8; 12];
    mem.read(UID_ADDR, &mut uid)?;
    write_slot(&mut mem, rec, record, uid)
}

/// Reads both slots, checks the device, plans the write, programs the slot not in force and
/// reads both slots back to check that the new record is in force (steps 1–5; `uid` is the MCU's
/// unique id as read by the caller).
pub fn write_slot(
    mem: &mut impl NodeMemory,
    rec: &Record,
    record: &[u8],
    uid: [u8; 12],
) -> Result<FlashReport, FlashError> {
    let plan = plan_write(mem, rec, record, uid)?;
    let address = SLOT_ADDRS[plan.slot as usize];
    mem.program_page(address, &plan.page)?;
    check_in_force(mem, &plan)?;
    Ok(FlashReport { slot: plan.slot, sequence: plan.sequence, address: address.into() })
}

/// Steps 1–3: the slots as they are, the device check, and the plan.
pub fn plan_write(
    mem: &mut impl NodeMemory,
    rec: &Record,
    record: &[u8],
    uid: [u8; 12],
) -> Result<WritePlan, FlashError> {
    let mut slots = [[0u8; SLOT_SIZE]; N_SLOTS];
    let readable = read_slots(mem, &mut slots)?;
    if rec.device_id != uid {
        return Err(FlashError::WrongDevice {
            record: super::session::device_id_hex(&rec.device_id),
            mcu: super::session::device_id_hex(&uid),
        });
    }
    WritePlan::from_readings(readings(&slots, readable), record).map_err(FlashError::Plan)
}

/// Step 5: reads both slots and checks that the planned write is in force.
pub fn check_in_force(mem: &mut impl NodeMemory, plan: &WritePlan) -> Result<(), FlashError> {
    let mut slots = [[0u8; SLOT_SIZE]; N_SLOTS];
    let readable = read_slots(mem, &mut slots)?;
    match select_readings(readings(&slots, readable)) {
        Ok(a) if a.slot == plan.slot && a.image.sequence == plan.sequence => Ok(()),
        _ => Err(FlashError::Verify(plan.slot)),
    }
}

/// The slot readings: a slot's bytes when it was readable.
fn readings(slots: &[[u8; SLOT_SIZE]; N_SLOTS], readable: [bool; N_SLOTS]) -> [Option<&[u8]>; N_SLOTS] {
    [0, 1].map(|i| readable[i].then_some(&slots[i][..]))
}

/// Reads both slots; returns which ones were readable. A slot is unreadable when the read fails
/// or when reading it raised a double ECC error in it (FLASH_ECCR, the same decision as the node's
/// NMI handler, [`nmi_action`]); that error is then cleared. (If the node's firmware is running,
/// its NMI handler may clear ECCD first; the torn slot's bytes then fail its commit or CRC check,
/// so it is not in force and is planned as the target all the same.)
fn read_slots(
    mem: &mut impl NodeMemory,
    slots: &mut [[u8; SLOT_SIZE]; N_SLOTS],
) -> Result<[bool; N_SLOTS], FlashError> {
    let mut readable = [true; N_SLOTS];
    for (i, buf) in slots.iter_mut().enumerate() {
        // Re-arm the ECC address capture first, as the node does (`flash_ecc::rearm`): while ECCC
        // or ECCD is set, FLASH_ECCR keeps an earlier error's address, and the slot's own double
        // error would go unseen. Written only when a flag is set (the usual case writes nothing).
        let eccr = read_eccr(mem)?;
        if eccr & (ECCC | ECCD) != 0 {
            mem.write_u32(FLASH_ECCR_ADDR, rearm(eccr))?;
        }
        if mem.read(SLOT_ADDRS[i], buf).is_err() {
            readable[i] = false;
        }
        if let NmiAction::SlotUnreadable { slot, clear } = nmi_action(read_eccr(mem)?) {
            readable[slot as usize] = false;
            mem.write_u32(FLASH_ECCR_ADDR, clear)?;
        }
    }
    Ok(readable)
}

/// FLASH_ECCR, read from the node.
fn read_eccr(mem: &mut impl NodeMemory) -> Result<u32, FlashError> {
    let mut eccr = [0u8; 4];
    mem.read(FLASH_ECCR_ADDR, &mut eccr)?;
    Ok(u32::from_le_bytes(eccr))
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
        let e = finish::<FlashReport>(Err(FlashError::Verify(1)), Ok(())).unwrap_err();
        assert!(matches!(&e, FlashError::Released(b) if matches!(**b, FlashError::Verify(1))), "{e}");
        assert_eq!(
            e.to_string(),
            "after writing slot 1, the record in force is not the new one; the MCU was reset and runs the \
             record in force before"
        );
        let e = finish::<FlashReport>(Err(FlashError::Verify(1)), Err("link lost".into())).unwrap_err();
        assert_eq!(
            e.to_string(),
            "after writing slot 1, the record in force is not the new one; resetting the core \
             afterwards failed too (link lost): power-cycle the node"
        );
    }

    #[test]
    fn an_unreadable_slot_is_planned_as_the_target() {
        use accelcal_shared::slots::SlotImage;
        let rec = record();
        let page = SlotImage::build(&rec, 5).unwrap();
        let slots = [page, [0u8; SLOT_SIZE]];
        let plan = WritePlan::from_readings(readings(&slots, [true, false]), &rec).unwrap();
        assert_eq!((plan.slot, plan.sequence), (1, 6));
        let plan = WritePlan::from_readings(readings(&slots, [false, true]), &rec).unwrap();
        assert_eq!((plan.slot, plan.sequence), (0, 1));
    }

    /// A GDB server that halts the target on connection (as QEMU's does), cannot read the
    /// unique-id area, accepts memory writes and logs every packet; it serves `sessions`
    /// connections. The first one is closed at its `drop_at`-th packet, when given.
    fn halting_server(
        sessions: usize,
        drop_at: Option<usize>,
    ) -> (String, std::thread::JoinHandle<Vec<String>>) {
        use std::io::{Read, Write};
        let l = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
        let addr = l.local_addr().unwrap().to_string();
        let server = std::thread::spawn(move || {
            let mut log = Vec::new();
            for session in 0..sessions {
                let (mut s, _) = l.accept().unwrap();
                let (mut buf, mut byte, mut n) = (Vec::new(), [0u8], 0);
                while s.read(&mut byte).unwrap_or(0) == 1 {
                    match byte[0] {
                        b'$' => buf.clear(),
                        b'#' => {
                            s.read_exact(&mut [0u8; 2]).unwrap();
                            let p = String::from_utf8(buf.clone()).unwrap();
                            log.push(p.clone());
                            n += 1;
                            if session == 0 && drop_at == Some(n) {
                                break;
                            }
                            let answer = match p.as_bytes()[0] {
                                b'?' => "S05",
                                b'm' => "E14",
                                b'M' | b'D' => "OK",
                                _ => "",
                            };
                            let sum = answer.bytes().fold(0u8, |a, b| a.wrapping_add(b));
                            s.write_all(format!("+${answer}#{sum:02x}").as_bytes()).unwrap();
                            s.read_exact(&mut [0u8]).unwrap();
                            if p == "D" {
                                break;
                            }
                        }
                        b => buf.push(b),
                    }
                }
            }
            log
        });
        (addr, server)
    }

    /// A model-4 record of QEMU's device id.
    fn record() -> Vec<u8> {
        use accelcal_shared::linear::Model4;
        let m = Model4 { u0: [32000.0; 3], k: [[1600.0, 0.0, 0.0], [0.0, 1600.0, 0.0], [0.0, 0.0, 1600.0]] };
        let mut buf = [0u8; accelcal_shared::record::MAX_RECORD_LEN];
        let n = Record::from_model4(*b"QEMU-B-L475E", 1, &m).emit(&mut buf).unwrap();
        buf[..n].to_vec()
    }

    const RESET: &str = "Me000ed0c,4:0400fa05";

    #[test]
    fn a_refusal_once_connected_resets_and_detaches_and_says_so() {
        let (addr, server) = halting_server(1, None);
        let e = flash_record_gdb(&record(), &addr, None, None).unwrap_err();
        assert!(matches!(&e, FlashError::Released(b) if matches!(**b, FlashError::NoDeviceId(_))), "{e}");
        assert!(e.to_string().ends_with("the MCU was reset and runs the record in force before"), "{e}");
        let log = server.join().unwrap();
        assert_eq!(log[log.len() - 2..], [RESET.to_string(), "D".to_string()], "{log:?}");
    }

    #[test]
    fn a_connection_lost_once_connected_is_released_over_a_new_one() {
        // The first session is closed at its second packet (the unique-id read).
        let (addr, server) = halting_server(2, Some(2));
        let e = flash_record_gdb(&record(), &addr, None, None).unwrap_err();
        assert!(matches!(&e, FlashError::Released(_)), "{e}");
        let log = server.join().unwrap();
        assert_eq!(log, ["?", "m1fff7590,c", "?", RESET, "D"], "{e}");
    }

    /// A node's flash as far as `read_slots` sees it: FLASH_ECCR latches an error's address only
    /// while ECCC and ECCD are clear (RM0351, FLASH_ECCR), and reading slot 1 raises a double
    /// error there.
    struct LatchingFlash {
        eccr: u32,
        writes: Vec<u32>,
    }

    impl NodeMemory for LatchingFlash {
        fn read(&mut self, addr: u32, buf: &mut [u8]) -> Result<(), FlashError> {
            if addr == FLASH_ECCR_ADDR {
                buf.copy_from_slice(&self.eccr.to_le_bytes());
            } else if addr == SLOT_ADDRS[1] && self.eccr & (ECCC | ECCD) == 0 {
                // Bank 2, offset of slot 1 (0x080F_F800 − 0x0808_0000).
                self.eccr |= ECCD | accelcal_shared::flash_ecc::BK_ECC | 0x7_F800;
            } else if addr == SLOT_ADDRS[1] {
                self.eccr |= ECCD; // flagged, the address not updated
            }
            Ok(())
        }
        fn write_u32(&mut self, addr: u32, v: u32) -> Result<(), FlashError> {
            assert_eq!(addr, FLASH_ECCR_ADDR);
            self.writes.push(v);
            // Write 1 to clear ECCC/ECCD: the address fields go with them.
            self.eccr &= !(v & (ECCC | ECCD));
            if self.eccr & (ECCC | ECCD) == 0 {
                self.eccr &= accelcal_shared::flash_ecc::ECCIE;
            }
            Ok(())
        }
        fn program_page(&mut self, _: u32, _: &[u8]) -> Result<(), FlashError> {
            unreachable!("read_slots does not program")
        }
    }

    #[test]
    fn a_corrected_error_latched_earlier_does_not_hide_a_torn_slot() {
        let mut slots = [[0u8; SLOT_SIZE]; N_SLOTS];
        // A single error corrected in application flash (bank 1) before the session.
        let mut mem = LatchingFlash { eccr: ECCC | 0x0_4100, writes: vec![] };
        assert_eq!(read_slots(&mut mem, &mut slots).unwrap(), [true, false]);
        assert_eq!(mem.writes[0], ECCC | ECCD, "re-armed before slot 0");
        // A clean node: nothing to re-arm, nothing written but the torn slot's clear.
        let mut mem = LatchingFlash { eccr: 0, writes: vec![] };
        assert_eq!(read_slots(&mut mem, &mut slots).unwrap(), [true, false]);
        assert_eq!(mem.writes, [ECCD]);
    }
}
