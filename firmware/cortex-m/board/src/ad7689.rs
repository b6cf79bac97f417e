//! The second position channel's converter: an AD7689 (16 bits, 8 channels, 250 kSPS) on
//! SPI3, its `CNV` on a GPIO (the board's pin map, `board.rs`), the six potentiometers on
//! IN0..IN5 in joint order, supplied from its reference (ratiometric).
//!
//! Its configuration word, its pipeline and its timing are `board_profile::position_channel::ad7689`
//! (the one owner; the emulated board's converter is written against the same). The
//! driver runs the converter's sequencer over IN0..IN5, one conversion per joint per
//! control tick, read after each conversion (`CNV` high for `tCONV`, then low while the
//! 16-bit result is clocked out MSB first): the six readings of a tick are taken within
//! 6 `tCYC` = 24 µs, so they stand for one instant as the encoders do.
//!
//! The fifth read of every tick writes the configuration again, so the sequence restarts at
//! IN0 on the next tick's first conversion (the configuration applies from the conversion
//! after the next) whatever happened to the converter before: a lost or extra conversion
//! mislabels at most one tick's readings, which the channel's cross-check sees.
//!
//! SPI3 (APB1, 42 MHz) is a master at 21 MHz (`BR` = /2, the AD7689 takes up to 40 MHz at
//! 3.3 V), mode 0 (`CPOL` = 0, `CPHA` = 0: the converter shifts `SDO` out on the falling
//! edge and latches `DIN` on the rising one), 16-bit frames, MSB first, its `NSS` managed by
//! software (`CNV` is the converter's select). Registers are written directly (RM0090
//! chapter 28): the driver touches `CR1`, `SR` and `DR` and nothing else, which keeps the
//! image within its text budget.

use board_profile::position_channel::ad7689;
use cortex_m::peripheral::DWT;
use embassy_stm32::gpio::Output;
use embassy_stm32::pac;
use embassy_stm32::pac::spi::vals;

use crate::board::CPU_HZ;

/// Cycles of the core for `ns` nanoseconds, rounded up.
const fn cycles(ns: u32) -> u32 {
    ((ns as u64 * CPU_HZ as u64).div_ceil(1_000_000_000)) as u32
}

/// `tCONV` in core cycles.
const CONV_CYCLES: u32 = cycles(ad7689::T_CONV_NS);
/// `tCYC` in core cycles.
const CYC_CYCLES: u32 = cycles(ad7689::T_CYC_NS);

/// The converter on SPI3 with its `CNV` pin.
#[allow(dead_code)]
pub struct Ad7689 {
    cnv: Output<'static>,
    /// The cycle count at the last `CNV` rising edge.
    last_start: u32,
}

/// SPI3's alternate function on PC10 (SCK), PC11 (MISO), PC12 (MOSI): AF6 (DS8626 table 9).
const SPI3_AF: u8 = 6;

// Built by the boards with the channel only (the others name the type, never make one).
#[allow(dead_code)]
impl Ad7689 {
    /// Puts PC10..PC12 on SPI3, sets SPI3 up, and configures the converter (its first two
    /// conversions, whose results are discarded, carry the configuration in).
    pub fn new(cnv: Output<'static>) -> Self {
        pac::RCC.apb1enr().modify(|w| w.set_spi3en(true));
        let port = pac::GPIOC;
        for pin in 10..=12usize {
            port.afr(1).modify(|w| w.set_afr(pin - 8, SPI3_AF));
            port.ospeedr()
                .modify(|w| w.set_ospeedr(pin, pac::gpio::vals::Ospeedr::HIGH_SPEED));
            port.moder()
                .modify(|w| w.set_moder(pin, pac::gpio::vals::Moder::ALTERNATE));
        }
        pac::SPI3.cr1().write(|w| {
            w.set_mstr(vals::Mstr::MASTER);
            w.set_br(vals::Br::DIV2);
            w.set_cpol(vals::Cpol::IDLE_LOW);
            w.set_cpha(vals::Cpha::FIRST_EDGE);
            w.set_dff(vals::Dff::BITS16);
            w.set_ssm(true);
            w.set_ssi(true);
            w.set_spe(true);
        });
        let mut adc = Ad7689 {
            cnv,
            last_start: DWT::cycle_count().wrapping_sub(CYC_CYCLES),
        };
        adc.convert(ad7689::frame(ad7689::CFG));
        adc.convert(0);
        adc
    }

    /// One conversion and its result: `CNV` high no sooner than `tCYC` after the last
    /// start, held for `tCONV`, then low while the result is read and `din` is written.
    fn convert(&mut self, din: u16) -> u16 {
        while DWT::cycle_count().wrapping_sub(self.last_start) < CYC_CYCLES {}
        self.cnv.set_high();
        let start = DWT::cycle_count();
        self.last_start = start;
        while DWT::cycle_count().wrapping_sub(start) < CONV_CYCLES {}
        self.cnv.set_low();
        let spi = pac::SPI3;
        // A word left over (none in normal running) is dropped first.
        if spi.sr().read().rxne() {
            let _ = spi.dr().read();
        }
        spi.dr().write(|w| w.set_dr(din));
        while !spi.sr().read().rxne() {}
        spi.dr().read().dr()
    }

    /// The six readings, IN0..IN5 (joint order), one conversion each; the fifth read
    /// carries the configuration again (the module's documentation).
    pub fn read(&mut self) -> [u16; 6] {
        let mut out = [0u16; 6];
        for (k, o) in out.iter_mut().enumerate() {
            let din = if k == 4 {
                ad7689::frame(ad7689::CFG)
            } else {
                0
            };
            *o = self.convert(din);
        }
        out
    }
}
