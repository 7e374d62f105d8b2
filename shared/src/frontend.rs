//! The emulated analog front end's channel into the QEMU node (USART2 of QEMU's
//! `b-l475e-iot01a`, the second `-serial`): the contract between `accelcal emulate` (host) and the
//! QEMU board's sample source (firmware), defined once.
//!
//! On the real board ADC1, triggered by TIM6, converts a code set per sampling period whether or
//! not the firmware keeps up. The emulated bench does the same over USART2: the front end sends one
//! [`FeSet`] per sampling period of the rate the node asked for, paced by the host's clock, and
//! numbers them; the node's sample source counts a jump in the numbers as sets lost (an overrun),
//! exactly like a lapped DMA ring. The node tells the front end its sampling rate with
//! [`FeCtl::Rate`] at boot and after every change, as the real board programs TIM6.
//!
//! Both directions use the link's framing ([`crate::wire::encode`], [`crate::wire::FrameDecoder`]:
//! postcard, COBS, a zero terminator).

use serde::{Deserialize, Serialize};

use crate::wire::Codes;

/// One code set from the front end: what ADC1 would have converted in one sampling period.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct FeSet {
    /// The front end's set counter, modulo 2¹⁶ (the node detects up to 65535 sets lost at once).
    pub index: u16,
    /// Raw codes, channels x, y, z (unsigned 16-bit, as the node's ADC delivers them).
    pub codes: Codes,
    /// The front end's temperature channel at this set, in 0.01 °C (the sensor's own temperature,
    /// which a thermal record with the front-end input applies).
    pub temp_cc: i16,
}

impl FeSet {
    /// The temperature, °C.
    pub fn temp_c(&self) -> f32 {
        self.temp_cc as f32 / 100.0
    }

    /// The temperature field of `temp_c` (°C), rounded to 0.01 °C and clamped to the field.
    pub fn temp_field(temp_c: f64) -> i16 {
        let v = libm::round(temp_c * 100.0);
        if v.is_nan() {
            0
        } else {
            v.clamp(i16::MIN as f64, i16::MAX as f64) as i16
        }
    }
}

/// What the node tells the front end.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum FeCtl {
    /// Convert code sets at this rate per channel from now on, Hz (sent at boot and on every
    /// accepted [`crate::wire::HostMsg::SetRate`]).
    Rate {
        /// Sampling rate, Hz.
        hz: u32,
    },
}

/// Longest frame of a [`FeSet`] or [`FeCtl`], the terminator included: 3 + 3·3 + 3 varint bytes
/// (index, codes, temperature), one COBS byte and the zero (tested).
pub const FE_MAX_FRAME: usize = 17;

/// Sets lost between two consecutive [`FeSet::index`] values `prev` and `next` (0 when `next`
/// follows `prev`).
pub fn lost_between(prev: u16, next: u16) -> u32 {
    next.wrapping_sub(prev).wrapping_sub(1) as u32
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::wire::{encode, FrameDecoder};

    #[test]
    fn frames_fit_and_round_trip() {
        let mut buf = [0u8; FE_MAX_FRAME];
        let set = FeSet { index: u16::MAX, codes: [u16::MAX; 3], temp_cc: i16::MIN };
        let frame = encode(&set, &mut buf).unwrap().to_vec();
        assert!(frame.len() <= FE_MAX_FRAME, "{}", frame.len());
        let mut d = FrameDecoder::<FE_MAX_FRAME>::new();
        let mut got = Vec::new();
        d.push(&frame, |m: Result<FeSet, _>| got.push(m));
        assert_eq!(got, vec![Ok(set)]);
        let ctl = FeCtl::Rate { hz: u32::MAX };
        let frame = encode(&ctl, &mut buf).unwrap().to_vec();
        assert!(frame.len() <= FE_MAX_FRAME);
        // Literal bytes: variant 0, 1000 = varint [0xe8, 0x07]; COBS [0x01, 0x03, 0xe8, 0x07].
        assert_eq!(encode(&FeCtl::Rate { hz: 1000 }, &mut buf).unwrap(), &[0x01, 0x03, 0xe8, 0x07, 0x00]);
    }

    #[test]
    fn lost_sets_across_the_wrap() {
        assert_eq!(lost_between(5, 6), 0);
        assert_eq!(lost_between(65535, 0), 0);
        assert_eq!(lost_between(65534, 2), 3);
        assert_eq!(lost_between(7, 7), 65535);
    }
}
