//! The STM32L475's internal temperature sensor: the factory calibration values and the conversion
//! of a reading to °C, as the real board's firmware does it (tested here on the host).
//!
//! The sensor is ADC1 channel 17 (VSENSE, with ADC_CCR CH17SEL = 1; RM0351 §18.4.32,
//! "Temperature sensor"). ST measures it on every part at 30 °C and 130 °C with VDDA = VREF+ =
//! 3.0 V and stores the 12-bit readings in system memory, TS_CAL1 and TS_CAL2 (STM32L475xx
//! datasheet DS10969, "Temperature sensor calibration values"); VREFINT_CAL, the internal
//! reference read at 30 °C and VDDA = 3.0 V, lets the node correct a reading for its own VDDA
//! (DS10969, "Internal voltage reference calibration values"; RM0351 §18.4.34). The addresses
//! are the datasheet's; stm32-metapac 21 (`chips/stm32l475vg/pac.rs`) agrees on VREFINT_CAL's,
//! `VREFINTCAL` at 0x1FFF_75AA, and has no TS_CAL entries for this chip.
//!
//! `T = 30 + (130 − 30)·(TS_DATA·VREFINT_CAL/VREFINT_DATA − TS_CAL1)/(TS_CAL2 − TS_CAL1)`
//! (RM0351 §18.4.32, with VDDA/3.0 V = VREFINT_CAL/VREFINT_DATA).

/// Address of TS_CAL1, a u16: the sensor's 12-bit reading at 30 °C, VDDA = 3.0 V.
pub const TS_CAL1_ADDR: u32 = 0x1FFF_75A8;
/// Address of TS_CAL2, a u16: the sensor's 12-bit reading at 130 °C, VDDA = 3.0 V.
pub const TS_CAL2_ADDR: u32 = 0x1FFF_75CA;
/// Address of VREFINT_CAL, a u16: VREFINT's 12-bit reading at 30 °C, VDDA = 3.0 V.
pub const VREFINT_CAL_ADDR: u32 = 0x1FFF_75AA;
/// Temperature of TS_CAL1, °C.
pub const TS_CAL1_TEMP_C: f32 = 30.0;
/// Temperature of TS_CAL2, °C.
pub const TS_CAL2_TEMP_C: f32 = 130.0;

/// A part's factory calibration of its temperature sensor, and the node's VDDA correction.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct McuTempCal {
    /// TS_CAL1 (12-bit).
    pub ts_cal1: u16,
    /// TS_CAL2 (12-bit).
    pub ts_cal2: u16,
    /// `VREFINT_CAL / VREFINT_DATA`: VDDA / 3.0 V, from the node's reading of VREFINT (in
    /// 12-bit units).
    pub vdda_ratio: f32,
}

impl McuTempCal {
    /// The calibration from the stored values and the node's VREFINT reading (12-bit units; an
    /// oversampled sum divided by its ratio). `None` when the values cannot be a calibration:
    /// unprogrammed (0 or 0xFFFF), TS_CAL2 not above TS_CAL1, or a VREFINT reading of zero.
    pub fn new(ts_cal1: u16, ts_cal2: u16, vrefint_cal: u16, vrefint_data: f32) -> Option<McuTempCal> {
        let programmed = |v: u16| v != 0 && v != 0xFFFF && v < 4096;
        if !(programmed(ts_cal1) && programmed(ts_cal2) && programmed(vrefint_cal)) || ts_cal2 <= ts_cal1 {
            return None;
        }
        let vdda_ratio = vrefint_cal as f32 / vrefint_data;
        (vdda_ratio.is_finite() && vdda_ratio > 0.0).then_some(McuTempCal { ts_cal1, ts_cal2, vdda_ratio })
    }

    /// The temperature, °C, of a sensor reading `ts_data` (12-bit units).
    pub fn temp_c(&self, ts_data: f32) -> f32 {
        let slope = (TS_CAL2_TEMP_C - TS_CAL1_TEMP_C) / (self.ts_cal2 as f32 - self.ts_cal1 as f32);
        TS_CAL1_TEMP_C + slope * (ts_data * self.vdda_ratio - self.ts_cal1 as f32)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_calibration_points_map_to_their_temperatures_at_any_vdda() {
        // Typical values of an STM32L4 (TS_CAL1 ≈ 1035, TS_CAL2 ≈ 1370, VREFINT_CAL ≈ 1655).
        let at_3v0 = McuTempCal::new(1035, 1370, 1655, 1655.0).unwrap();
        assert_eq!(at_3v0.temp_c(1035.0), 30.0);
        assert_eq!(at_3v0.temp_c(1370.0), 130.0);
        assert!((at_3v0.temp_c(1035.0 + 335.0 * 0.25) - 55.0).abs() < 1e-4);
        // At VDDA = 3.3 V every reading is 3.0/3.3 of what it is at 3.0 V, VREFINT's included.
        let k = 3.0 / 3.3;
        let at_3v3 = McuTempCal::new(1035, 1370, 1655, 1655.0 * k).unwrap();
        assert!((at_3v3.temp_c(1035.0 * k) - 30.0).abs() < 1e-3);
        assert!((at_3v3.temp_c(1370.0 * k) - 130.0).abs() < 1e-3);
    }

    #[test]
    fn values_that_cannot_be_a_calibration_are_refused() {
        assert_eq!(McuTempCal::new(0xFFFF, 1370, 1655, 1655.0), None);
        assert_eq!(McuTempCal::new(1035, 0, 1655, 1655.0), None);
        assert_eq!(McuTempCal::new(1370, 1035, 1655, 1655.0), None);
        assert_eq!(McuTempCal::new(1035, 1370, 1655, 0.0), None);
        assert_eq!(McuTempCal::new(1035, 1370, 0xFFFF, 1655.0), None);
    }
}
