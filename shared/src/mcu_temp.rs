//! The STM32L475's internal temperature sensor: the factory calibration values and the conversion
//! of a reading to °C, as the real board's firmware does it (tested here on the host).
//!
//! The sensor is ADC1 channel 17 (VSENSE, with ADC_CCR CH17SEL = 1; RM0351 §18.4.32,
//! "Temperature sensor"). ST measures it on every part at 30 °C and at 110 °C with VDDA = VREF+ =
//! 3.0 V and stores the 12-bit readings in system memory, TS_CAL1 and TS_CAL2 (STM32L475xx
//! datasheet DS10969, "Temperature sensor calibration values"). The second point is 110 °C on the
//! STM32L471/475/476/485/486 and 130 °C on the other L4 lines: ST's LL ADC header
//! (`stm32l4xx_ll_adc.h`, `TEMPSENSOR_CAL2_TEMP`, defined per part) has 110 for exactly those five
//! parts. The node runs on an STM32L475VG, so 110 °C. VREFINT_CAL, the internal
//! reference read at 30 °C and VDDA = 3.0 V, lets the node correct a reading for its own VDDA
//! (DS10969, "Internal voltage reference calibration values"; RM0351 §18.4.34). The addresses
//! are the datasheet's; stm32-metapac 21 (`chips/stm32l475vg/pac.rs`) agrees on VREFINT_CAL's,
//! `VREFINTCAL` at 0x1FFF_75AA, and has no TS_CAL entries for this chip.
//!
//! `T = 30 + (110 − 30)·(TS_DATA·VREFINT_CAL/VREFINT_DATA − TS_CAL1)/(TS_CAL2 − TS_CAL1)`
//! (RM0351 §18.4.32, with VDDA/3.0 V = VREFINT_CAL/VREFINT_DATA).

/// Address of TS_CAL1, a u16: the sensor's 12-bit reading at 30 °C, VDDA = 3.0 V.
pub const TS_CAL1_ADDR: u32 = 0x1FFF_75A8;
/// Address of TS_CAL2, a u16: the sensor's 12-bit reading at [`TS_CAL2_TEMP_C`], VDDA = 3.0 V.
pub const TS_CAL2_ADDR: u32 = 0x1FFF_75CA;
/// Address of VREFINT_CAL, a u16: VREFINT's 12-bit reading at 30 °C, VDDA = 3.0 V.
pub const VREFINT_CAL_ADDR: u32 = 0x1FFF_75AA;
/// Temperature of TS_CAL1, °C.
pub const TS_CAL1_TEMP_C: f32 = 30.0;
/// Temperature of TS_CAL2 on the STM32L475, °C (130 °C on other L4 lines: see the module's
/// documentation).
pub const TS_CAL2_TEMP_C: f32 = 110.0;

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
        // Typical values of an STM32L4 (TS_CAL1 ≈ 1035, TS_CAL2 ≈ 1310, VREFINT_CAL ≈ 1655).
        let at_3v0 = McuTempCal::new(1035, 1310, 1655, 1655.0).unwrap();
        assert_eq!(at_3v0.temp_c(1035.0), 30.0);
        // TS_CAL2 is the reading at 110 °C on the STM32L475 (130 °C read it as 1.25·(T − 30) + 30).
        assert_eq!(at_3v0.temp_c(1310.0), 110.0);
        assert!((at_3v0.temp_c(1035.0 + 275.0 * 0.25) - 50.0).abs() < 1e-4);
        // At VDDA = 3.3 V every reading is 3.0/3.3 of what it is at 3.0 V, VREFINT's included.
        let k = 3.0 / 3.3;
        let at_3v3 = McuTempCal::new(1035, 1310, 1655, 1655.0 * k).unwrap();
        assert!((at_3v3.temp_c(1035.0 * k) - 30.0).abs() < 1e-3);
        assert!((at_3v3.temp_c(1310.0 * k) - 110.0).abs() < 1e-3);
    }

    /// ST's reference conversion, `__LL_ADC_CALC_TEMPERATURE` of `stm32l4xx_ll_adc.h` for an
    /// STM32L475 (TEMPSENSOR_CAL2_TEMP = 110, TEMPSENSOR_CAL_VREFANALOG = 3000 mV), in its
    /// integer arithmetic: `((data·vdda_mv/3000 − cal1)·(110 − 30))/(cal2 − cal1) + 30`.
    fn st_ll_calc_temperature(vdda_mv: i32, data: i32, cal1: i32, cal2: i32) -> i32 {
        ((data * vdda_mv / 3000 - cal1) * (110 - 30)) / (cal2 - cal1) + 30
    }

    #[test]
    fn the_conversion_agrees_with_st_reference_macro() {
        let (cal1, cal2, vrefint_cal) = (1035u16, 1310u16, 1655u16);
        for vdda_mv in [3000, 3300] {
            // The node's VREFINT reading at this VDDA, and VDDA as ST's macro wants it.
            let vrefint_data = vrefint_cal as f32 * 3000.0 / vdda_mv as f32;
            let cal = McuTempCal::new(cal1, cal2, vrefint_cal, vrefint_data).unwrap();
            for true_c in [-40, 0, 25, 30, 60, 85, 110, 125] {
                // The sensor's reading at `true_c` and this VDDA (linear between the points).
                let at_3v0 = cal1 as f32 + (true_c - 30) as f32 * (cal2 - cal1) as f32 / 80.0;
                let data = (at_3v0 * 3000.0 / vdda_mv as f32).round();
                let st = st_ll_calc_temperature(vdda_mv, data as i32, cal1 as i32, cal2 as i32);
                let ours = cal.temp_c(data);
                // The macro's formula without its integer truncations, and the macro itself (its
                // two truncating divisions lose up to 80/275 °C and 1 °C).
                let exact = (data as f64 * vdda_mv as f64 / 3000.0 - cal1 as f64) * 80.0
                    / (cal2 - cal1) as f64
                    + 30.0;
                assert!(
                    (ours as f64 - exact).abs() < 1e-3,
                    "{vdda_mv} mV, {true_c} °C: ours {ours}, ST exact {exact}"
                );
                assert!((ours - st as f32).abs() < 1.3, "{vdda_mv} mV, {true_c} °C: ours {ours}, ST {st}");
                assert!((ours - true_c as f32).abs() < 0.4, "{vdda_mv} mV, {true_c} °C: ours {ours}");
            }
        }
    }

    #[test]
    fn values_that_cannot_be_a_calibration_are_refused() {
        assert_eq!(McuTempCal::new(0xFFFF, 1370, 1655, 1655.0), None);
        assert_eq!(McuTempCal::new(1035, 0, 1655, 1655.0), None);
        assert_eq!(McuTempCal::new(1310, 1035, 1655, 1655.0), None);
        assert_eq!(McuTempCal::new(1035, 1310, 1655, 0.0), None);
        assert_eq!(McuTempCal::new(1035, 1310, 0xFFFF, 1655.0), None);
    }
}
