//! The calibration the node applies: chosen once at boot from the record slots, then applied to
//! every sample set.
//!
//! The hot path is [`calibrate_block_f32`] (or [`calibrate_block_fixed`] in the `fixed-point`
//! build): `a = K⁻¹ (u − u0)` per sample set, 3 subtractions and 9 multiply-adds. They are
//! exported unmangled and never inlined so that the benchmark can find them in the ELF and count
//! the instructions QEMU executes inside them.

use accelcal_shared::linear::{LinearCalF32, LinearCalFixed};
use accelcal_shared::record::{Record, RecordError};
use accelcal_shared::slots::{self, SlotError, SlotImage};
use accelcal_shared::wire::{record_error_code, Block, Codes, RecordFault, RecordStatus};
use heapless::Vec;

use super::ports::RecordStorage;

/// The calibration in force, or none.
#[derive(Clone, Copy, Debug)]
pub enum Calibration {
    /// Model 4 in f32 (the Cortex-M4F's FPU path).
    F32(LinearCalF32),
    /// Model 4 in fixed point (output m/s²·2¹⁶), for FPU-less parts.
    Fixed(LinearCalFixed),
    /// No valid record: sample sets leave the node as raw codes flagged uncalibrated.
    Uncalibrated,
}

/// Calibrates `codes` into `out` (m/s²), pairwise, in f32. The node's hot path.
#[cfg_attr(not(feature = "fixed-point"), unsafe(no_mangle))]
#[inline(never)]
pub fn calibrate_block_f32(cal: &LinearCalF32, codes: &[Codes], out: &mut [[f32; 3]]) {
    for (u, a) in codes.iter().zip(out.iter_mut()) {
        *a = cal.apply(*u);
    }
}

/// Calibrates `codes` into `out` (m/s²·2¹⁶), pairwise, in fixed point.
#[cfg_attr(feature = "fixed-point", unsafe(no_mangle))]
#[inline(never)]
pub fn calibrate_block_fixed(cal: &LinearCalFixed, codes: &[Codes], out: &mut [[i32; 3]]) {
    for (u, a) in codes.iter().zip(out.iter_mut()) {
        *a = cal.apply(*u);
    }
}

impl Calibration {
    /// The output block for raw `codes` (at most [`MAX_BLOCK`](accelcal_shared::wire::MAX_BLOCK)).
    pub fn apply_block(&self, codes: &[Codes]) -> Block {
        let n = codes.len().min(accelcal_shared::wire::MAX_BLOCK);
        let codes = &codes[..n];
        match self {
            Calibration::F32(cal) => {
                let mut v = Vec::new();
                let _ = v.resize(n, [0.0; 3]);
                calibrate_block_f32(cal, codes, &mut v);
                Block::Calibrated(v)
            }
            Calibration::Fixed(cal) => {
                let mut v = Vec::new();
                let _ = v.resize(n, [0; 3]);
                calibrate_block_fixed(cal, codes, &mut v);
                Block::CalibratedFixed(v)
            }
            Calibration::Uncalibrated => {
                let mut v = Vec::new();
                let _ = v.extend_from_slice(codes);
                Block::Uncalibrated(v)
            }
        }
    }
}

/// Reads the record slots and returns the calibration to apply and what to report about it.
/// Every way a record can be unusable ends in [`Calibration::Uncalibrated`] with the reason.
pub fn load(storage: &impl RecordStorage) -> (Calibration, RecordStatus) {
    match try_load(storage) {
        Ok((cal, status)) => {
            if let RecordStatus::InUse { slot, sequence, created_unix_s } = status {
                defmt::info!(
                    "record in use: slot {=u8}, sequence {=u32}, created {=u64}",
                    slot,
                    sequence,
                    created_unix_s
                );
            }
            (cal, status)
        }
        Err(fault) => {
            defmt::warn!(
                "no valid calibration record ({}): streaming raw codes flagged UNCALIBRATED",
                defmt::Display2Format(&fault)
            );
            (Calibration::Uncalibrated, RecordStatus::Missing(fault))
        }
    }
}

/// The fault for a record that does not parse; logs the error with its value (the status carries
/// only its code: e.g. the unsupported version's number is in the log only).
fn bad_record(e: RecordError) -> RecordFault {
    defmt::warn!("record slot holds an invalid record: {}", defmt::Display2Format(&e));
    RecordFault::BadRecord(record_error_code(e))
}

fn try_load(storage: &impl RecordStorage) -> Result<(Calibration, RecordStatus), RecordFault> {
    let [a, b] = storage.slots();
    let slots = [&a[..], &b[..]];
    let active = slots::select(slots).map_err(|e| match e {
        SlotError::Record(r) => bad_record(r),
        _ => RecordFault::NoSlot,
    })?;
    // A committed slot passed over (e.g. a newer record of another format version) is logged.
    let other = (active.slot ^ 1) as usize;
    if let Err(e) = SlotImage::parse(slots[other]) {
        if e != SlotError::NotCommitted {
            defmt::warn!("record slot {=usize} skipped: {}", other, defmt::Display2Format(&e));
        }
    }
    let record = Record::parse(active.image.record).map_err(bad_record)?;
    if record.device_id != storage.device_id() {
        return Err(RecordFault::WrongDevice);
    }
    let model = record.model4().ok_or(RecordFault::NotModel4)?;
    let inverse = model.invert().map_err(|_| RecordFault::Singular)?;
    let cal = if cfg!(feature = "fixed-point") {
        Calibration::Fixed(inverse.to_fixed().map_err(|_| RecordFault::Singular)?)
    } else {
        Calibration::F32(inverse.to_f32())
    };
    let status = RecordStatus::InUse {
        slot: active.slot,
        sequence: active.image.sequence,
        created_unix_s: record.created_unix_s,
    };
    Ok((cal, status))
}
