//! The second position channel of the board built with it (`firmware/cortex-m/board`,
//! `--no-default-features --features position-channel`: the STM32F405ZG, LQFP144): a
//! potentiometer per joint on an AD7689's IN0..IN5 (joint order), the converter on SPI3
//! (PC10 SCK, PC11 MISO, PC12 MOSI) with its `CNV` on PD0; the legs' home switches on
//! PD3..PD5 ([`crate::pins::POSITION_CHANNEL`]; the table at the top of
//! `firmware/cortex-m/board/src/board.rs`).
//!
//! **The sensor is the plant's** (`plant::PositionSensor`: its travel, mid-scale, noise,
//! offset and faults, `sim/plant/plant.toml`'s `[position_sensor]`): its reading is the
//! 16-bit code of the wiper's fraction of the converter's reference (ratiometric), which
//! this module puts on the converter's inputs every plant step. **The converter** is
//! [`crate::ad7689::Ad7689`] on rigless's SPI3, selected by `CNV` low. This module owns
//! none of the sensor's or the converter's constants, only the wiring.

use rigless::device::Level;
use rigless::soc::stm32f427::peripherals::gpio::Pin;
use rigless::soc::stm32f427::peripherals::spi::Select;

use crate::ad7689::Ad7689;
use crate::mcu::BoardMcu;
use crate::pins::{PinId, Port};

/// SPI3's index in rigless's `Stm32f427::spi` (SPI1, SPI2, SPI3, ...).
pub const SPI3: usize = 2;

/// The converter's `CNV` (its select: low = its result on `MISO`).
pub const CNV: PinId = PinId::new(Port::D, 0);

/// SPI3's pins (DS8626 table 9, AF6): SCK, MISO, MOSI.
pub const SPI3_PINS: [PinId; 3] = [
    PinId::new(Port::C, 10),
    PinId::new(Port::C, 11),
    PinId::new(Port::C, 12),
];

/// The alternate function of [`SPI3_PINS`].
pub const SPI3_AF: u8 = 6;

/// The converter's inputs the joints use, joint order.
pub const INPUTS: [u8; 6] = [0, 1, 2, 3, 4, 5];

/// Hangs the converter on SPI3 behind `CNV`.
pub fn attach(mcu: &mut BoardMcu) {
    let Some(pin) = Pin::new(CNV.number) else {
        return;
    };
    if let Some(spi) = mcu.part.spi.get_mut(SPI3) {
        spi.attach_selected(
            Ad7689::new(),
            Select {
                port: "GPIOD",
                pin,
                active: Level::Low,
            },
        );
    }
}

/// The converter on SPI3, if attached.
pub fn converter(mcu: &mut BoardMcu) -> Option<&mut Ad7689> {
    mcu.part.spi.get_mut(SPI3)?.chip_mut::<Ad7689>(0)
}

/// Puts the plant's readings `counts` (joint order) on the converter's inputs.
pub fn sense(mcu: &mut BoardMcu, counts: &[u16; 6]) {
    if let Some(adc) = converter(mcu) {
        let mut codes = [0u16; 8];
        for (input, c) in INPUTS.iter().zip(counts) {
            if let Some(slot) = codes.get_mut(usize::from(*input)) {
                *slot = *c;
            }
        }
        adc.set_inputs(&codes);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// No two joints share an input, and every input is one of the AD7689's eight.
    #[test]
    fn one_input_per_joint() {
        let mut ch = INPUTS.to_vec();
        ch.sort_unstable();
        ch.dedup();
        assert_eq!(ch.len(), 6);
        assert!(ch.iter().all(|c| *c < 8));
    }
}
