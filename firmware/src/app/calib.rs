//! The calibration the node applies: chosen once at boot from the record slots, then applied to
//! every sample set.
//!
//! The hot path is [`calibrate_block_f32`] (or [`calibrate_block_fixed`] in the `fixed-point`
//! build): `a = K⁻¹ (u − u0)` per sample set, 3 subtractions and 9 multiply-adds. With a thermal
//! record it is [`calibrate_block_thermal_f32`] (or [`calibrate_block_thermal_fixed`]): the same
//! per set, plus the shared [`ThermalTracker`]'s add and compare, and once per
//! [`SETS_PER_UPDATE`](accelcal_shared::thermal::SETS_PER_UPDATE) sets the re-evaluation of the
//! calibration at the filtered temperature. They are exported unmangled and never inlined so that
//! the benchmark can find them in the ELF and count the instructions QEMU executes inside them.
//!
//! The calibration in force ([`Calibration`]) is fixed at boot and shared by the tasks; the state
//! a thermal record needs (the tracker) belongs to whoever applies it: [`Calibration::applier`]
//! makes a fresh one, the live stream keeps one for its life and the replay path one per replay
//! run.

use accelcal_shared::boot::{self, Arithmetic, NodeCal, TempInputs};
#[cfg(not(feature = "fixed-point"))]
use accelcal_shared::linear::LinearCalF32;
#[cfg(feature = "fixed-point")]
use accelcal_shared::linear::LinearCalFixed;
use accelcal_shared::slots::{SlotRead, N_SLOTS, SLOT_SIZE};
#[cfg(feature = "fixed-point")]
use accelcal_shared::thermal::ThermalTrackerFixed;
use accelcal_shared::thermal::{ThermalCalF32, ThermalTracker};
use accelcal_shared::wire::{Block, BlockTemp, Codes, RecordFault, RecordStatus, MAX_BLOCK};
use heapless::Vec;

use super::ports::RecordStorage;

/// Model 4 in the build's arithmetic: f32 (the Cortex-M4F's FPU path) or, with the
/// `fixed-point` feature, fixed point (output m/s²·2¹⁶, for FPU-less parts). Each build compiles
/// the calibration of its own arithmetic only (flash).
#[cfg(not(feature = "fixed-point"))]
pub type LinearCal = LinearCalF32;
/// Model 4 in the build's arithmetic (see the f32 build's definition).
#[cfg(feature = "fixed-point")]
pub type LinearCal = LinearCalFixed;

/// The build's thermal tracker: f32, or re-quantised to fixed point at each evaluation.
#[cfg(not(feature = "fixed-point"))]
pub type Tracker = ThermalTracker;
/// The build's thermal tracker (see the f32 build's definition).
#[cfg(feature = "fixed-point")]
pub type Tracker = ThermalTrackerFixed;

/// The calibration in force, or none.
#[derive(Clone, Copy, Debug)]
pub enum Calibration {
    /// Model 4.
    Model4(LinearCal),
    /// Model 4 with thermal terms: the model (evaluated in f32), and the calibration at its
    /// reference temperature (applied where no temperature is known).
    Thermal(ThermalCalF32, LinearCal),
    /// No valid record: sample sets leave the node as raw codes flagged uncalibrated.
    Uncalibrated,
}

/// Calibrates `codes` into `out` (m/s²), pairwise, with a thermal record, in f32: each set with
/// the calibration the tracker gives for its temperature (`temp_c`, °C, one per set). Returns
/// whether a set was calibrated outside the record's range. The thermal hot path.
#[cfg(not(feature = "fixed-point"))]
#[unsafe(no_mangle)]
#[inline(never)]
pub fn calibrate_block_thermal_f32(
    tracker: &mut ThermalTracker,
    codes: &[Codes],
    temp_c: &[f32],
    out: &mut [[f32; 3]],
) -> bool {
    tracker.apply_block(codes, temp_c, out)
}

/// [`calibrate_block_thermal_f32`] in fixed point (m/s²·2¹⁶).
#[cfg(feature = "fixed-point")]
#[unsafe(no_mangle)]
#[inline(never)]
pub fn calibrate_block_thermal_fixed(
    tracker: &mut ThermalTrackerFixed,
    codes: &[Codes],
    temp_c: &[f32],
    out: &mut [[i32; 3]],
) -> bool {
    tracker.apply_block(codes, temp_c, out)
}

/// The calibration in force with the state its application needs: a thermal record's tracker.
#[derive(Clone, Copy, Debug)]
pub enum Applier {
    /// Model 4 (or no record): nothing to keep.
    Static(Calibration),
    /// A thermal record.
    Thermal(Tracker),
}

impl Applier {
    /// Calibrates a block of `codes` with their temperatures `temp_c` (one per set; the block is
    /// cut to the shorter of the two and to [`MAX_BLOCK`]), and reports the block's temperature:
    /// its mean, and for a thermal record the temperature the calibration was evaluated at and
    /// whether a set was calibrated outside the record's range.
    pub fn apply_block(&mut self, codes: &[Codes], temp_c: &[f32]) -> (Block, Option<BlockTemp>) {
        let n = codes.len().min(temp_c.len()).min(MAX_BLOCK);
        let (codes, temp_c) = (&codes[..n], &temp_c[..n]);
        match self {
            Applier::Static(cal) => (cal.apply_block(codes), ThermalTracker::block_temp(temp_c, None)),
            #[cfg(not(feature = "fixed-point"))]
            Applier::Thermal(tr) => {
                let mut v = Vec::new();
                let _ = v.resize(n, [0.0; 3]);
                let flagged = calibrate_block_thermal_f32(tr, codes, temp_c, &mut v);
                (Block::Calibrated(v), ThermalTracker::block_temp(temp_c, Some((tr, flagged))))
            }
            #[cfg(feature = "fixed-point")]
            Applier::Thermal(tr) => {
                let mut v = Vec::new();
                let _ = v.resize(n, [0; 3]);
                let flagged = calibrate_block_thermal_fixed(tr, codes, temp_c, &mut v);
                (Block::CalibratedFixed(v), ThermalTracker::block_temp(temp_c, Some((tr.tracker(), flagged))))
            }
        }
    }

    /// Feeds the temperatures of sets that are not calibrated (raw output) to a thermal record's
    /// tracker, so that its filter keeps following the temperature; returns the block's
    /// temperature report (mean only).
    pub fn track(&mut self, temp_c: &[f32]) -> Option<BlockTemp> {
        if let Applier::Thermal(tr) = self {
            temp_c.iter().for_each(|&t| {
                tr.on_set(t);
            });
        }
        ThermalTracker::block_temp(temp_c, None)
    }
}

/// Calibrates `codes` into `out` (m/s²), pairwise, in f32. The node's hot path.
#[cfg(not(feature = "fixed-point"))]
#[unsafe(no_mangle)]
#[inline(never)]
pub fn calibrate_block_f32(cal: &LinearCalF32, codes: &[Codes], out: &mut [[f32; 3]]) {
    for (u, a) in codes.iter().zip(out.iter_mut()) {
        *a = cal.apply(*u);
    }
}

/// Calibrates `codes` into `out` (m/s²·2¹⁶), pairwise, in fixed point.
#[cfg(feature = "fixed-point")]
#[unsafe(no_mangle)]
#[inline(never)]
pub fn calibrate_block_fixed(cal: &LinearCalFixed, codes: &[Codes], out: &mut [[i32; 3]]) {
    for (u, a) in codes.iter().zip(out.iter_mut()) {
        *a = cal.apply(*u);
    }
}

impl Calibration {
    /// A fresh applier of this calibration (a thermal record's tracker not yet fed).
    pub fn applier(&self) -> Applier {
        match *self {
            Calibration::Thermal(model, start) => Applier::Thermal(Tracker::new(model, start)),
            cal => Applier::Static(cal),
        }
    }

    /// The output block for raw `codes` (at most [`MAX_BLOCK`]) without temperatures: a thermal
    /// record is applied at its reference temperature.
    pub fn apply_block(&self, codes: &[Codes]) -> Block {
        let n = codes.len().min(MAX_BLOCK);
        let codes = &codes[..n];
        match self {
            Calibration::Model4(cal) | Calibration::Thermal(_, cal) => apply(cal, codes),
            Calibration::Uncalibrated => {
                let mut v = Vec::new();
                let _ = v.extend_from_slice(codes);
                Block::Uncalibrated(v)
            }
        }
    }
}

/// Model 4 in f32 on a block of `codes`.
#[cfg(not(feature = "fixed-point"))]
fn apply(cal: &LinearCal, codes: &[Codes]) -> Block {
    let mut v = Vec::new();
    let _ = v.resize(codes.len(), [0.0; 3]);
    calibrate_block_f32(cal, codes, &mut v);
    Block::Calibrated(v)
}

/// Model 4 in fixed point on a block of `codes`.
#[cfg(feature = "fixed-point")]
fn apply(cal: &LinearCal, codes: &[Codes]) -> Block {
    let mut v = Vec::new();
    let _ = v.resize(codes.len(), [0; 3]);
    calibrate_block_fixed(cal, codes, &mut v);
    Block::CalibratedFixed(v)
}

/// Reads the record slots and returns the calibration to apply and what to report about it: the
/// decision is [`boot::decide`] (shared, tested on the host), given the board's temperature
/// `inputs` (a thermal record naming an input the board lacks is refused). Every way a record can
/// be unusable ends in [`Calibration::Uncalibrated`] with the reason.
pub fn load(storage: &impl RecordStorage, inputs: TempInputs) -> (Calibration, RecordStatus) {
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
    match boot::decide(readings, &storage.device_id(), arith, inputs) {
        Ok(boot) => {
            if let Some(e) = boot.skipped {
                defmt::warn!("record slot {=u8} skipped: {}", boot.slot ^ 1, e);
            }
            defmt::info!(
                "record in use: slot {=u8} (format v{=u8}), sequence {=u32}, created {=u64}",
                boot.slot,
                boot.slot_version,
                boot.sequence,
                boot.record.created_unix_s
            );
            // The boot decision calibrates in the build's own arithmetic (`arith` above).
            let Some(c) = own(boot.cal) else {
                defmt::error!("boot decision in the other arithmetic: streaming raw codes");
                return (Calibration::Uncalibrated, RecordStatus::Missing(RecordFault::Singular));
            };
            let cal = match boot.thermal {
                None => Calibration::Model4(c),
                Some(m) => Calibration::Thermal(m, c),
            };
            if let Some(m) = boot.thermal {
                defmt::info!(
                    "thermal record: input {=str}, t_ref {=f32} °C, calibrated {=f32}..={=f32} °C",
                    m.thermal.source.name(),
                    m.thermal.t_ref_c,
                    m.thermal.t_min_c,
                    m.thermal.t_max_c
                );
            }
            (cal, boot.status())
        }
        Err(e) => {
            defmt::warn!("no valid calibration record ({}): streaming raw codes flagged UNCALIBRATED", e);
            (Calibration::Uncalibrated, RecordStatus::Missing(e.fault()))
        }
    }
}

/// The boot decision's calibration if it is in this build's arithmetic. (A function of its own:
/// with the conversion written inline in [`load`], the real image measured 160 B larger.)
#[cfg(not(feature = "fixed-point"))]
fn own(cal: NodeCal) -> Option<LinearCal> {
    cal.into_f32()
}

/// The boot decision's calibration if it is in this build's arithmetic.
#[cfg(feature = "fixed-point")]
fn own(cal: NodeCal) -> Option<LinearCal> {
    cal.into_fixed()
}
