//! The node's boot decision as a pure function: from the two slot readings and the MCU's device
//! id, which record is in force and the calibration to apply, or why there is none.
//!
//! The firmware reads the slots (turning a flash ECC error into an unreadable slot), calls
//! [`decide`] and applies the result; everything it decides is tested here on the host.
//!
//! The record part of the decision is [`accept`]: the node calls it (through [`decide`]) on the
//! record in force, and the host calls it (through [`gate`]) on a record before writing it, so
//! the host refuses exactly the records a node would refuse, for the node's reason.

use crate::linear::{LinearCalF32, LinearCalFixed};
use crate::record::{Record, RecordError, TempSource};
use crate::slots::{self, SlotError, SlotReading, N_SLOTS};
use crate::thermal::{self, ThermalCalF32, ThermalModel};
use crate::wire::{record_error_code, RecordFault, RecordStatus};

/// The arithmetic the node calibrates in.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Arithmetic {
    /// f32 (FPU parts).
    F32,
    /// Fixed point, output m/s²·2¹⁶ (FPU-less parts).
    Fixed,
}

/// The calibration to apply, in the node's arithmetic.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum NodeCal {
    /// Model 4 in f32.
    F32(LinearCalF32),
    /// Model 4 in fixed point.
    Fixed(LinearCalFixed),
}

impl NodeCal {
    /// The calibration if it is in f32.
    pub fn into_f32(self) -> Option<LinearCalF32> {
        match self {
            NodeCal::F32(c) => Some(c),
            NodeCal::Fixed(_) => None,
        }
    }

    /// The calibration if it is in fixed point.
    pub fn into_fixed(self) -> Option<LinearCalFixed> {
        match self {
            NodeCal::Fixed(c) => Some(c),
            NodeCal::F32(_) => None,
        }
    }
}

/// A record in force.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Boot {
    /// Slot it was read from (0 or 1).
    pub slot: u8,
    /// Format version of that slot (1 or 2).
    pub slot_version: u8,
    /// The slot's write sequence number.
    pub sequence: u32,
    /// The record.
    pub record: Record,
    /// The record's CRC-32, as stored in its last four bytes.
    pub crc: u32,
    /// The calibration to apply (for a thermal record: at its reference temperature, until the
    /// node has read a temperature).
    pub cal: NodeCal,
    /// For a record with thermal terms: the model the node re-evaluates per block of sample sets.
    pub thermal: Option<ThermalCalF32>,
    /// The other slot, when it holds something that is not valid and not simply empty (worth a
    /// log line: e.g. a newer record of another format version, or an unreadable page).
    pub skipped: Option<SlotError>,
}

impl Boot {
    /// What the node reports about its record.
    pub fn status(&self) -> RecordStatus {
        RecordStatus::InUse {
            slot: self.slot,
            sequence: self.sequence,
            created_unix_s: self.record.created_unix_s,
            crc: self.crc,
        }
    }
}

/// Why no record is in force.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum BootError {
    /// Neither slot holds a valid slot image; the more informative of the two slots' errors
    /// (see [`slots::select_readings`]) that is not about the record itself.
    NoSlot(SlotError),
    /// The slot in force (or, with none valid, a committed slot) holds a record that does not
    /// parse.
    BadRecord(RecordError),
    /// The record was made for another device.
    WrongDevice,
    /// The record's device id is all zeros: it was made for no device, and no MCU has that id
    /// (the node reports it as [`RecordFault::WrongDevice`]).
    NoDeviceId,
    /// The record is not model 4 (with, or without, the thermal terms `t`, `t^2`, `ax*t`,
    /// `ay*t`, `az*t`) for three channels.
    NotModel4,
    /// The record's sensitivity matrix cannot be inverted (or does not fit fixed point).
    Singular,
    /// The record's thermal terms read a temperature input this node does not have (see
    /// [`TempInputs`]).
    NoTempInput(TempSource),
}

/// The temperature inputs a node has, which a thermal record's [`TempSource`] must name.
///
/// The boards: the real B-L475E-IOT01A reads the MCU's internal sensor only (its analog front end
/// has three channels, x, y, z); the QEMU board reads the emulated front end's temperature only
/// (QEMU's ADC is a stub, so it has no MCU sensor). A node does not substitute one input for the
/// other: a record fitted against the front end's sensor describes the unit's own temperature,
/// the MCU's sensor sits on another die with its own offset and lag, so applying the record with
/// it would compensate with the wrong temperature, silently.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TempInputs {
    /// The MCU's internal sensor ([`TempSource::Mcu`]).
    pub mcu: bool,
    /// The front end's temperature channel ([`TempSource::FrontEnd`]).
    pub front_end: bool,
}

impl TempInputs {
    /// The real board: the MCU's sensor.
    pub const MCU: TempInputs = TempInputs { mcu: true, front_end: false };
    /// The QEMU board: the emulated front end's channel.
    pub const FRONT_END: TempInputs = TempInputs { mcu: false, front_end: true };
    /// Every input: what [`gate`] assumes, since it cannot know the board the record goes to.
    pub const ALL: TempInputs = TempInputs { mcu: true, front_end: true };

    /// Whether the node has `source`.
    pub const fn has(self, source: TempSource) -> bool {
        match source {
            TempSource::Mcu => self.mcu,
            TempSource::FrontEnd => self.front_end,
        }
    }
}

impl BootError {
    /// The reason as the node reports it over the link.
    pub fn fault(&self) -> RecordFault {
        match *self {
            BootError::NoSlot(_) => RecordFault::NoSlot,
            BootError::BadRecord(e) => RecordFault::BadRecord(record_error_code(e)),
            BootError::WrongDevice | BootError::NoDeviceId => RecordFault::WrongDevice,
            BootError::NotModel4 => RecordFault::NotModel4,
            BootError::Singular => RecordFault::Singular,
            BootError::NoTempInput(_) => RecordFault::NoTempInput,
        }
    }
}

impl core::fmt::Display for BootError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            BootError::NoSlot(e) => write!(f, "no valid record slot ({e})"),
            BootError::BadRecord(e) => write!(f, "record slot holds an invalid record: {e}"),
            BootError::WrongDevice => f.write_str("the record was made for another device"),
            BootError::NoDeviceId => f.write_str(
                "the record's device id is all zeros: it was made for no device, no node accepts it",
            ),
            BootError::NotModel4 => f.write_str(
                "the record is not model 4 (optionally with the thermal terms t, t^2, ax*t, ay*t, az*t) \
                 for three channels",
            ),
            BootError::Singular => f.write_str(
                "the record's sensitivity matrix cannot be inverted (or does not fit fixed point)",
            ),
            BootError::NoTempInput(s) => write!(
                f,
                "the record's thermal terms read the temperature input `{}`, which this node does not have",
                s.name()
            ),
        }
    }
}

/// Decides which record is in force. `readings` are the two slots as read (`None`: unreadable),
/// `device_id` the MCU's unique id, `arith` the node's arithmetic, `inputs` the temperature
/// inputs the board has. Accepts any bytes.
pub fn decide(
    readings: [SlotReading<'_>; N_SLOTS],
    device_id: &[u8; 12],
    arith: Arithmetic,
    inputs: TempInputs,
) -> Result<Boot, BootError> {
    let active = slots::select_readings(readings).map_err(|e| match e {
        SlotError::Record(r) => BootError::BadRecord(r),
        e => BootError::NoSlot(e),
    })?;
    let other = (active.slot ^ 1) as usize;
    let skipped = match slots::parse_reading(readings[other]) {
        Err(e) if e != SlotError::NotCommitted => Some(e),
        _ => None,
    };
    let record = Record::parse(active.image.record).map_err(BootError::BadRecord)?;
    let cal = accept(&record, device_id, arith, inputs)?;
    // The parse checked that the record's bytes hold its length, CRC included.
    let n = record.len();
    let crc = match active.image.record.get(n.saturating_sub(4)..n) {
        Some(&[a, b, c, d]) => u32::from_le_bytes([a, b, c, d]),
        _ => return Err(BootError::BadRecord(RecordError::Truncated)),
    };
    Ok(Boot {
        slot: active.slot,
        slot_version: active.image.version,
        sequence: active.image.sequence,
        thermal: ThermalModel::of(&record).map(|m| m.to_f32()),
        record,
        crc,
        cal,
        skipped,
    })
}

/// Whether the node with unique id `device_id`, calibrating in `arith`, with the temperature
/// inputs `inputs`, accepts `record` (a parsed record), and the calibration it then applies (a
/// thermal record's at its reference temperature); or why not, in this order: a device id of all
/// zeros, another device's id, not model 4 (with or without thermal terms) on three channels, a
/// thermal record whose temperature input the node lacks, a sensitivity matrix that cannot be
/// inverted (for a thermal record: anywhere on [`ThermalModel::invertible`]'s grid over the
/// calibrated range) or, in fixed point, does not fit the format.
pub fn accept(
    record: &Record,
    device_id: &[u8; 12],
    arith: Arithmetic,
    inputs: TempInputs,
) -> Result<NodeCal, BootError> {
    if record.device_id == [0; 12] {
        return Err(BootError::NoDeviceId);
    }
    if record.device_id != *device_id {
        return Err(BootError::WrongDevice);
    }
    if record.n_channels != 3 || !thermal::node_applies(record.structure) {
        return Err(BootError::NotModel4);
    }
    let singular = |_| BootError::Singular;
    if let Some(m) = ThermalModel::of(record) {
        if !inputs.has(m.thermal.source) {
            return Err(BootError::NoTempInput(m.thermal.source));
        }
        m.invertible().map_err(singular)?;
        let f = m.to_f32();
        let t_ref = m.thermal.t_ref_c;
        return Ok(match arith {
            Arithmetic::F32 => NodeCal::F32(f.at(t_ref).map_err(singular)?),
            Arithmetic::Fixed => {
                let (lo, hi) = (m.thermal.t_min_c, m.thermal.t_max_c);
                for temp in [lo, hi] {
                    f.at_wide(temp).and_then(|c| c.to_fixed()).map_err(singular)?;
                }
                NodeCal::Fixed(f.at_wide(t_ref).and_then(|c| c.to_fixed()).map_err(singular)?)
            }
        });
    }
    let inverse = record.model4().ok_or(BootError::NotModel4)?.invert().map_err(singular)?;
    Ok(match arith {
        Arithmetic::F32 => NodeCal::F32(inverse.to_f32()),
        Arithmetic::Fixed => NodeCal::Fixed(inverse.to_fixed().map_err(singular)?),
    })
}

/// The check of a record about to be written: whether every node build (f32 and fixed point)
/// whose unique id is the record's own device id, and which has the record's temperature input,
/// accepts it ([`accept`] with [`TempInputs::ALL`]). The gate checks the record alone: it cannot
/// know the board the record will reach, so a record that passes is refused by a node for one of
/// two reasons only: that it is another device, or that its board lacks the record's temperature
/// input ([`BootError::NoTempInput`]: a front-end record on the real board, an MCU-sensor record
/// on the QEMU board).
pub fn gate(record: &Record) -> Result<(), BootError> {
    for arith in [Arithmetic::F32, Arithmetic::Fixed] {
        accept(record, &record.device_id, arith, TempInputs::ALL)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::linear::Model4;
    use crate::record::MAX_RECORD_LEN;
    use crate::slots::{SlotImage, SLOT_SIZE};
    use crate::terms::Structure;

    const ID: [u8; 12] = *b"QEMU-B-L475E";

    fn model() -> Model4 {
        Model4 {
            u0: [32100.5, 33012.25, 31877.75],
            k: [[1671.2, 8.5, -3.25], [-4.0, 1650.75, 6.5], [2.5, -7.75, 1689.0]],
        }
    }

    fn bytes(r: &Record) -> std::vec::Vec<u8> {
        let mut buf = [0u8; MAX_RECORD_LEN];
        let n = r.emit(&mut buf).unwrap();
        buf[..n].to_vec()
    }

    fn record(id: [u8; 12], created: u64) -> std::vec::Vec<u8> {
        bytes(&Record::from_model4(id, created, &model()))
    }

    #[test]
    fn the_newer_valid_slot_is_in_force_with_its_calibration() {
        let a = SlotImage::build(&record(ID, 1), 4).unwrap();
        let b = SlotImage::build_v1(&record(ID, 2), 5).unwrap();
        let boot = decide([Some(&a), Some(&b)], &ID, Arithmetic::F32, TempInputs::ALL).unwrap();
        let rec = record(ID, 2);
        assert_eq!(boot.crc, crate::record::crc32(&rec[..rec.len() - 4]));
        assert_eq!((boot.slot, boot.slot_version, boot.sequence), (1, 1, 5));
        assert_eq!(
            boot.status(),
            RecordStatus::InUse { slot: 1, sequence: 5, created_unix_s: 2, crc: boot.crc }
        );
        let inv = model().invert().unwrap();
        assert_eq!(boot.cal, NodeCal::F32(inv.to_f32()));
        assert_eq!(boot.skipped, None);
        let boot = decide([Some(&a), None], &ID, Arithmetic::Fixed, TempInputs::ALL).unwrap();
        assert_eq!((boot.slot, boot.slot_version, boot.sequence), (0, 2, 4));
        assert_eq!(boot.cal, NodeCal::Fixed(inv.to_fixed().unwrap()));
        assert_eq!(boot.skipped, Some(SlotError::Unreadable));
    }

    #[test]
    fn each_reason_for_no_record() {
        let erased = [0xffu8; SLOT_SIZE];
        let no = |r: [SlotReading<'_>; 2]| decide(r, &ID, Arithmetic::F32, TempInputs::ALL).unwrap_err();
        assert_eq!(no([Some(&erased), Some(&erased)]), BootError::NoSlot(SlotError::NotCommitted));
        assert_eq!(no([None, Some(&erased)]), BootError::NoSlot(SlotError::Unreadable));
        assert_eq!(no([None, None]).fault(), RecordFault::NoSlot);
        let other = SlotImage::build(&record(*b"another-chip", 1), 1).unwrap();
        assert_eq!(no([Some(&other), None]), BootError::WrongDevice);
        let mut quad = Record::from_model4(ID, 1, &model());
        quad.structure = Structure::from_indices(&[0, 1, 2, 3, 4]);
        let quad = SlotImage::build(&bytes(&quad), 1).unwrap();
        assert_eq!(no([Some(&erased), Some(&quad)]), BootError::NotModel4);
        let mut sing = model();
        sing.k[2] = sing.k[1];
        let sing = SlotImage::build(&bytes(&Record::from_model4(ID, 1, &sing)), 1).unwrap();
        assert_eq!(no([Some(&sing), Some(&erased)]), BootError::Singular);
        assert_eq!(no([Some(&sing), Some(&erased)]).fault(), RecordFault::Singular);
        // A committed slot whose record does not parse (a bit flipped, both CRCs of the slot made
        // to match) is reported by the record's error.
        let good = record(ID, 1);
        let mut bad = good.clone();
        bad[4] = 9; // format version 9
        let n = bad.len();
        let crc = crate::record::crc32(&bad[..n - 4]);
        bad[n - 4..].copy_from_slice(&crc.to_le_bytes());
        let mut page = SlotImage::build_v1(&good, 1).unwrap();
        page[16..16 + n].copy_from_slice(&bad);
        let mut covered = page[4..12].to_vec();
        covered.extend_from_slice(&bad);
        page[12..16].copy_from_slice(&crate::record::crc32(&covered).to_le_bytes());
        let e = no([Some(&page), Some(&erased)]);
        assert_eq!(e, BootError::BadRecord(RecordError::UnsupportedVersion(9)));
        assert_eq!(e.fault(), RecordFault::BadRecord(3));
        let zero = SlotImage::build(&record([0; 12], 1), 1).unwrap();
        assert_eq!(no([Some(&zero), None]), BootError::NoDeviceId);
        assert_eq!(no([Some(&zero), None]).fault(), RecordFault::WrongDevice);
        // Next to a valid slot it is skipped, and named.
        let ok = SlotImage::build(&good, 0).unwrap();
        let boot = decide([Some(&page), Some(&ok)], &ID, Arithmetic::F32, TempInputs::ALL).unwrap();
        assert_eq!(boot.slot, 1);
        assert_eq!(boot.skipped, Some(SlotError::Record(RecordError::UnsupportedVersion(9))));
    }

    #[test]
    fn the_gate_refuses_what_a_node_refuses_and_passes_what_it_accepts() {
        let ok = Record::from_model4(ID, 1, &model());
        assert_eq!(gate(&ok), Ok(()));
        assert!(accept(&ok, &ID, Arithmetic::F32, TempInputs::MCU).is_ok());
        assert_eq!(
            accept(&ok, b"another-chip", Arithmetic::F32, TempInputs::ALL),
            Err(BootError::WrongDevice)
        );
        assert_eq!(gate(&Record::from_model4([0; 12], 1, &model())), Err(BootError::NoDeviceId));
        let mut five = ok;
        five.n_channels = 5;
        assert_eq!(gate(&five), Err(BootError::NotModel4));
        let mut quad = ok;
        quad.structure = Structure::from_indices(&[0, 1, 2, 3, 4]);
        assert_eq!(gate(&quad), Err(BootError::NotModel4));
        let mut sing = model();
        sing.k[2] = sing.k[1];
        assert_eq!(gate(&Record::from_model4(ID, 1, &sing)), Err(BootError::Singular));
        // Invertible, but K⁻¹ far too large for fixed point: the f32 build would accept it, the
        // fixed-point build would not, so the gate refuses it.
        let mut tiny = model();
        tiny.k = [[1e-9, 0.0, 0.0], [0.0, 1e-9, 0.0], [0.0, 0.0, 1e-9]];
        let tiny = Record::from_model4(ID, 1, &tiny);
        assert!(accept(&tiny, &ID, Arithmetic::F32, TempInputs::ALL).is_ok());
        assert_eq!(accept(&tiny, &ID, Arithmetic::Fixed, TempInputs::ALL), Err(BootError::Singular));
        assert_eq!(gate(&tiny), Err(BootError::Singular));
    }

    #[test]
    fn a_thermal_record_is_accepted_with_its_model_and_checked_over_its_range() {
        use crate::record::{TempSource, Thermal};
        let mut r = Record::from_model4(ID, 7, &model());
        r.g_m_s2 = Some(9.81);
        r.structure = Structure::from_indices(&[1, 2, 3, 20, 22]);
        for c in 0..3 {
            r.coefficients[c][4] = 3.0; // t, codes/°C
            r.coefficients[c][5] = if c == 0 { 0.167 } else { 0.0 }; // ax*t
        }
        r.thermal =
            Some(Thermal { t_ref_c: 25.0, t_min_c: -10.0, t_max_c: 50.0, source: TempSource::FrontEnd });
        assert_eq!(gate(&r), Ok(()));
        let page = SlotImage::build(&bytes(&r), 3).unwrap();
        let boot = decide([Some(&page), None], &ID, Arithmetic::F32, TempInputs::FRONT_END).unwrap();
        let th = boot.thermal.expect("a thermal record carries its model");
        assert_eq!(boot.cal, NodeCal::F32(th.at(25.0).unwrap()));
        assert_eq!(th.thermal.source, TempSource::FrontEnd);
        assert!(decide([Some(&page), None], &ID, Arithmetic::Fixed, TempInputs::ALL).is_ok());
        // A board without the record's input refuses it, in both arithmetics; the gate, which
        // cannot know the board, passes it (above).
        for arith in [Arithmetic::F32, Arithmetic::Fixed] {
            let e = decide([Some(&page), None], &ID, arith, TempInputs::MCU).unwrap_err();
            assert_eq!(e, BootError::NoTempInput(TempSource::FrontEnd));
            assert_eq!(e.fault(), RecordFault::NoTempInput);
            assert!(e.to_string().contains("`front-end`"), "{e}");
        }
        let mut mcu = r;
        mcu.thermal.as_mut().unwrap().source = TempSource::Mcu;
        assert_eq!(gate(&mcu), Ok(()));
        assert!(accept(&mcu, &ID, Arithmetic::F32, TempInputs::MCU).is_ok());
        assert_eq!(
            accept(&mcu, &ID, Arithmetic::F32, TempInputs::FRONT_END),
            Err(BootError::NoTempInput(TempSource::Mcu))
        );
        // Model 4 needs no temperature input at all.
        let none = TempInputs { mcu: false, front_end: false };
        assert!(accept(&Record::from_model4(ID, 1, &model()), &ID, Arithmetic::F32, none).is_ok());
        // A record for another device is refused as such before its input is looked at.
        assert_eq!(accept(&r, b"another-chip", Arithmetic::F32, none), Err(BootError::WrongDevice));
        // Model 4 boots without a thermal model.
        assert_eq!(
            decide(
                [Some(&SlotImage::build(&record(ID, 1), 1).unwrap()), None],
                &ID,
                Arithmetic::F32,
                TempInputs::ALL
            )
            .unwrap()
            .thermal,
            None
        );
        // Thermal terms on a quadratic model are not what a node applies.
        let mut quad = r;
        quad.structure = Structure::from_indices(&[1, 2, 3, 4, 20]);
        assert_eq!(gate(&quad), Err(BootError::NotModel4));
        // A sensitivity that vanishes inside the calibrated range is refused.
        let mut vanishing = r;
        vanishing.coefficients[0][5] = -1671.2 / 30.0; // K_xx(t) = 0 at 55 °C
        vanishing.thermal.as_mut().unwrap().t_max_c = 60.0;
        assert_eq!(gate(&vanishing), Err(BootError::Singular));
    }
}
