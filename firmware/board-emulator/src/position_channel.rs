//! The second position channel of the board built with it (`firmware/cortex-m/board`,
//! `--no-default-features --features position-channel`: the STM32F405ZG, LQFP144): a
//! potentiometer per joint on ADC3, PF3..PF8 (ADC3 IN9, IN14, IN15, IN4, IN5, IN6, joint
//! order; the table at the top of `firmware/cortex-m/board/src/board.rs`).
//!
//! **The sensor is the plant's** (`plant::PositionSensor`: its travel, mid-scale, noise and
//! offset, `sim/plant/plant.toml`'s `[position_sensor]`, and its faults): its reading, a
//! fraction of the potentiometer's travel in 65536 counts, is the wiper's fraction of its
//! supply. The potentiometers are supplied from the ADC's reference (ratiometric), so the
//! wiper's voltage is that fraction of `VREF+` and the reference cancels: this module owns
//! none of the sensor's constants, only the wiring.
//!
//! **The converter is rigless's ADC3** (RM0090 chapter 13: `ADON`, `SWSTART`, the sample
//! time of `SMPR1/2`, `SQR3`, `EOC`, `DR` at the 12-bit resolution; the registers the
//! firmware's `embassy_stm32::adc::Adc::blocking_read` touches). Its input is given in
//! microvolts against a reference of 3,300,000 µV (3.3 V: the rail), so the wiper's
//! voltage reaches the converter within 1 µV (0.02 of a 16-bit count) and the only
//! quantisation is the converter's own 12 bits (16 of the plant's counts), as on the part.
//! The firmware scales the 12-bit word to 16 bits (`<< 4`).

use rigless::soc::stm32f427::peripherals::adc::Channel;

use crate::mcu::BoardMcu;
use crate::pins::{AnalogInput, PinId, Port};

/// ADC3's index in rigless's `Stm32f427::adc` (ADC1, ADC2, ADC3).
pub const ADC3: usize = 2;

/// The potentiometers' inputs, joint order: the pin and its ADC3 channel (DS8626 table 7:
/// PF3 ADC3_IN9, PF4 IN14, PF5 IN15, PF6 IN4, PF7 IN5, PF8 IN6).
pub const POTENTIOMETERS: [AnalogInput; 6] = [
    AnalogInput {
        pin: PinId::new(Port::F, 3),
        channel: 9,
    },
    AnalogInput {
        pin: PinId::new(Port::F, 4),
        channel: 14,
    },
    AnalogInput {
        pin: PinId::new(Port::F, 5),
        channel: 15,
    },
    AnalogInput {
        pin: PinId::new(Port::F, 6),
        channel: 4,
    },
    AnalogInput {
        pin: PinId::new(Port::F, 7),
        channel: 5,
    },
    AnalogInput {
        pin: PinId::new(Port::F, 8),
        channel: 6,
    },
];

/// `VREF+` (the 3.3 V rail) in the unit ADC3's inputs are given in, µV.
pub const REFERENCE_UV: u32 = 3_300_000;

/// Counts of the plant's reading over the potentiometer's whole travel (`plant`'s
/// `FULL_SCALE` + 1: the reading is `fraction x 65536`).
const TRAVEL_COUNTS: f64 = 65536.0;

/// The wiper's voltage, µV, for the plant's reading `counts`: that fraction of `VREF+`.
pub fn wiper_uv(counts: u16) -> u32 {
    (f64::from(counts) / TRAVEL_COUNTS * f64::from(REFERENCE_UV)).round() as u32
}

/// The 12-bit word an ideal converter answers for `counts` (rigless's: the input's share of
/// the reference, rounded down), scaled to 16 bits as the firmware does: what the firmware
/// reads for the plant's reading.
pub fn firmware_counts(counts: u16) -> u16 {
    let word = u64::from(wiper_uv(counts)) * 4095 / u64::from(REFERENCE_UV);
    (word.min(4095) as u16) << 4
}

/// Puts the potentiometers' wipers for the plant's readings `counts` (joint order) on ADC3's
/// inputs, and its reference, from now on.
pub fn sense(mcu: &mut BoardMcu, counts: &[u16; 6]) {
    let Some(adc) = mcu.part.adc.get_mut(ADC3) else {
        return;
    };
    adc.set_reference(REFERENCE_UV);
    for (input, c) in POTENTIOMETERS.iter().zip(counts) {
        if let Some(ch) = Channel::new(input.channel) {
            adc.set_input(ch, wiper_uv(*c));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The firmware's reading is the plant's within the converter's 12 bits: never above
    /// it, and below it by at most one 12-bit step (16 counts) and the converter's
    /// full-scale gain (4095 at `VREF+`: `c / 4096` counts, 16 at the top), over the whole
    /// travel.
    #[test]
    fn the_firmware_reads_the_plant_within_the_converters_resolution() {
        for c in (0..=u16::MAX).step_by(7) {
            let f = firmware_counts(c);
            assert!(f <= c, "{c} read {f}");
            assert!(
                u32::from(c - f) <= 16 + u32::from(c).div_ceil(4096),
                "{c} read {f}"
            );
        }
        assert_eq!(firmware_counts(0), 0);
        assert_eq!(firmware_counts(32768), 32752);
    }

    /// No two joints share an input, and every channel is one of ADC3's pins (0..15).
    #[test]
    fn one_input_per_joint() {
        let mut ch: Vec<u8> = POTENTIOMETERS.iter().map(|p| p.channel).collect();
        ch.sort_unstable();
        ch.dedup();
        assert_eq!(ch.len(), 6);
        assert!(ch.iter().all(|c| *c < 16));
    }
}
