//! The calibration the node applies: chosen once at boot from the record slots, then applied to
//! every sample set.
//!
//! The hot path is [`calibrate_block_f32`] (or [`calibrate_block_fixed`] in the `fixed-point`
//! build): `a = K⁻¹ (u − u0)` per sample set, 3 subtractions and 9 multiply-adds. They are
//! exported unmangled and never inlined so that the benchmark can find them in the ELF and count
//! the instructions QEMU executes inside them.

use accelcal_shared::boot::{self, Arithmetic, NodeCal};
use accelcal_shared::linear::{LinearCalF32, LinearCalFixed};
use accelcal_shared::slots::{SlotRead, N_SLOTS, SLOT_SIZE};
use accelcal_shared::wire::{Block, Codes, RecordStatus};
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

/// Reads the record slots and returns the calibration to apply and what to report about it: the
/// decision is [`boot::decide`] (shared, tested on the host). Every way a record can be unusable
/// ends in [`Calibration::Uncalibrated`] with the reason.
pub fn load(storage: &impl RecordStorage) -> (Calibration, RecordStatus) {
    let mut bufs = [[0u8; SLOT_SIZE]; N_SLOTS];
    let [a, b] = &mut bufs;
    let reads = [storage.read_slot(0, a), storage.read_slot(1, b)];
    for (slot, r) in reads.iter().enumerate() {
        if *r == SlotRead::Unreadable {
            defmt::warn!("record slot {=usize} is unreadable (flash ECC error): treated as invalid", slot);
        }
    }
    let readings = [
        (reads[0] == SlotRead::Complete).then_some(&a[..]),
        (reads[1] == SlotRead::Complete).then_some(&b[..]),
    ];
    let arith = if cfg!(feature = "fixed-point") { Arithmetic::Fixed } else { Arithmetic::F32 };
    match boot::decide(readings, &storage.device_id(), arith) {
        Ok(boot) => {
            if let Some(e) = boot.skipped {
                defmt::warn!("record slot {=u8} skipped: {}", boot.slot ^ 1, defmt::Display2Format(&e));
            }
            defmt::info!(
                "record in use: slot {=u8} (format v{=u8}), sequence {=u32}, created {=u64}",
                boot.slot,
                boot.slot_version,
                boot.sequence,
                boot.record.created_unix_s
            );
            let cal = match boot.cal {
                NodeCal::F32(c) => Calibration::F32(c),
                NodeCal::Fixed(c) => Calibration::Fixed(c),
            };
            (cal, boot.status())
        }
        Err(e) => {
            defmt::warn!(
                "no valid calibration record ({}): streaming raw codes flagged UNCALIBRATED",
                defmt::Display2Format(&e)
            );
            (Calibration::Uncalibrated, RecordStatus::Missing(e.fault()))
        }
    }
}
