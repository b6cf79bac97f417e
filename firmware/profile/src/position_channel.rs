//! The second position channel of the boards that have it: the one owner of its converter
//! and its sensors' travel. The firmware's calibration (`control::absolute`), the board
//! image's driver (`firmware/cortex-m/board`, the `position-channel` image) and the emulated
//! board's converter (`firmware/board-emulator`) take these from here; the plant model
//! (`sim/plant/plant.toml`, `[position_sensor]`) is tested equal to them.
//!
//! **The converter** is an AD7689 (16 bits, 8 channels, 250 kSPS, SPI) beside the MCU, its
//! reference the potentiometers' supply (ratiometric). Its resolution is chosen by the
//! channel's cross-check: the firmware's `agree` bound (`control::absolute::ChannelConfig`)
//! is five filtered noise deviations of the reading, and a 12-bit converter's quantisation
//! (one step = 16 counts of 65536, `step^2 / 12` of variance) makes that bound 19.3 counts
//! instead of 4.2 (see `firmware/control/tests/position_channel_resolution.rs`, which maps
//! both to the platform).

/// The channel's converter and sensors.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PositionChannel {
    /// The converter's resolution, bits (its codes: `0 .. 2^bits`).
    pub bits: u32,
    /// A leg potentiometer's electrical travel, m (over the converter's full scale).
    pub leg_travel_m: f64,
    /// A link potentiometer's electrical angle, rad.
    pub link_travel_rad: f64,
}

/// Counts of the channel's readings over a potentiometer's travel, whatever the converter:
/// the hal's readings are 16-bit (`hal::AbsolutePositions`), a converter of fewer bits
/// is scaled up to them.
pub const READING_COUNTS: f64 = 65536.0;

impl PositionChannel {
    /// The reference board's: an AD7689 (16 bits); 100 mm linear potentiometers on the legs,
    /// 340 deg single-turn ones on the links (`sim/plant/plant.toml`).
    pub const REFERENCE: PositionChannel = PositionChannel {
        bits: 16,
        leg_travel_m: 0.1,
        link_travel_rad: 340.0 * core::f64::consts::PI / 180.0,
    };

    /// The same sensors read by the STM32F405's own 12-bit ADC (the alternative the
    /// converter was chosen against).
    pub const ON_CHIP_12_BIT: PositionChannel = PositionChannel {
        bits: 12,
        ..PositionChannel::REFERENCE
    };

    /// One converter step in counts of the 16-bit reading (1 for the AD7689, 16 for a
    /// 12-bit ADC).
    pub fn step_counts(&self) -> f64 {
        READING_COUNTS / libm_exp2(self.bits)
    }

    /// Reading counts per joint unit (counts/m on a leg, counts/rad on a link).
    pub fn counts_per_unit(&self, joint: usize) -> f64 {
        if joint < crate::NUM_JOINTS / 2 {
            READING_COUNTS / self.leg_travel_m
        } else {
            READING_COUNTS / self.link_travel_rad
        }
    }

    /// One converter step in joint units (m, rad).
    pub fn step_unit(&self, joint: usize) -> f64 {
        self.step_counts() / self.counts_per_unit(joint)
    }
}

/// `2^bits` for the converters' widths (no `std` here).
fn libm_exp2(bits: u32) -> f64 {
    f64::from(1u32 << bits.min(31))
}

/// The AD7689 (Analog Devices data sheet, rev. E): its configuration word and its timing.
///
/// The 14-bit configuration (`CFG`) goes in MSB first on the first 14 clocks of a data
/// read (`DIN`); a word with its overwrite bit clear leaves the configuration as it is.
/// The new configuration applies from the conversion after the next one (the data sheet's
/// two-deep pipeline: the next conversion was set up when its `CNV` rose). With the
/// sequencer on, that conversion converts IN0, the following ones IN1 .. `INx` in turn,
/// then IN0 again. A conversion starts on `CNV`'s rising edge and its 16-bit result is
/// read after it ends (`tCONV`) with `CNV` low, MSB first (read after conversion).
pub mod ad7689 {
    /// `CFG` bit 13: overwrite the configuration with this word.
    pub const CFG_OVERWRITE: u16 = 1 << 13;
    /// `INCC` (bits 12:10) = 0b111: unipolar, each input referred to GND.
    pub const INCC_UNIPOLAR_GND: u16 = 0b111 << 10;
    /// `INx` (bits 9:7): the sequencer's last channel.
    pub const fn last_channel(channel: u16) -> u16 {
        (channel & 0b111) << 7
    }
    /// `BW` (bit 6): the full bandwidth of the input filter.
    pub const BW_FULL: u16 = 1 << 6;
    /// `REF` (bits 5:3) = 0b110: an external reference on `REF` (the potentiometers'
    /// supply: ratiometric), the temperature sensor off.
    pub const REF_EXTERNAL: u16 = 0b110 << 3;
    /// `SEQ` (bits 2:1) = 0b11: scan IN0 .. `INx`, without the temperature.
    pub const SEQ_SCAN: u16 = 0b11 << 1;
    /// `RB` (bit 0) = 1: do not read the configuration back after the data.
    pub const RB_OFF: u16 = 1;

    /// The inputs the channel uses: IN0 .. IN5, joint order.
    pub const CHANNELS: u16 = 6;

    /// The configuration the board writes: unipolar to GND, the sequencer over IN0 .. IN5,
    /// full bandwidth, the external (ratiometric) reference, no read-back.
    pub const CFG: u16 = CFG_OVERWRITE
        | INCC_UNIPOLAR_GND
        | last_channel(CHANNELS - 1)
        | BW_FULL
        | REF_EXTERNAL
        | SEQ_SCAN
        | RB_OFF;

    /// The 16-bit frame that carries `cfg` (the 14 bits first, MSB first).
    pub const fn frame(cfg: u16) -> u16 {
        cfg << 2
    }

    /// The configuration a 16-bit frame on `DIN` carries.
    pub const fn cfg_of(frame: u16) -> u16 {
        frame >> 2
    }

    /// The conversion time, ns: `CNV` rising to the data available (the data sheet's
    /// maximum, with margin).
    pub const T_CONV_NS: u32 = 3_200;
    /// The shortest time between two conversions' `CNV` rising edges, ns (`tCYC`, 250 kSPS).
    pub const T_CYC_NS: u32 = 4_000;
    /// The shortest `CNV` high pulse, ns (`tCNVH`).
    pub const T_CNVH_NS: u32 = 10;
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The configuration word by its fields (the data sheet's table of `CFG`'s bits: CFG 1,
    /// INCC 111, INx 101, BW 1, REF 110, SEQ 11, RB 1), 14 bits, and its frame.
    #[test]
    #[allow(clippy::unusual_byte_groupings)]
    fn the_configuration_word_is_its_fields() {
        assert_eq!(ad7689::CFG, 0b1_111_101_1_110_11_1);
        assert_eq!(ad7689::CFG >> 14, 0);
        assert_eq!(ad7689::cfg_of(ad7689::frame(ad7689::CFG)), ad7689::CFG);
    }

    /// One step of each converter on each joint.
    #[test]
    fn the_steps() {
        let r = PositionChannel::REFERENCE;
        let c = PositionChannel::ON_CHIP_12_BIT;
        assert_eq!(r.step_counts(), 1.0);
        assert_eq!(c.step_counts(), 16.0);
        assert!((r.step_unit(0) - 0.1 / 65536.0).abs() < 1e-15);
        assert!((c.step_unit(3).to_degrees() - 340.0 / 4096.0).abs() < 1e-12);
    }
}
