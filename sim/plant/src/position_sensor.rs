//! The second position channel: an absolute position sensor per joint on the load side,
//! beside the incremental encoder on the motor shaft. On the reference robot it is a
//! conductive-plastic potentiometer (the legs: linear, between the leg's fixed tube and its
//! moving rod; the links: single-turn, on the link's axis) read ratiometrically by a 16-bit
//! SAR ADC on the board: the reading is a fraction of the potentiometer's supply, 0 .. 65535
//! counts over its electrical travel.
//!
//! The reading of joint `q` at time `t`:
//!
//! ```text
//! counts = clamp(round(32768 + (q - mid) * counts_per_unit + offset + noise(t) + drift(t)), 0, 65535)
//! ```
//!
//! * `counts_per_unit`: 65536 counts over the electrical travel (the resolution: one count,
//!   1.53 um on a 100 mm leg potentiometer, 0.0052 deg on a 340 deg link potentiometer);
//! * `mid`: the joint position at mid-scale (where the potentiometer is mounted);
//! * `offset`: what the channel's calibration leaves of the mounting (counts; the firmware
//!   does not know it: it is the channel's error against the true position);
//! * `noise(t)`: zero-mean, `noise_lsb` counts rms, a fresh value every microsecond of plant
//!   time, a function of the joint and the time only (so a run is a function of its
//!   inputs, whoever reads the sensor and how often);
//! * `drift(t)`: an injected drift, growing linearly from its injection.
//!
//! Faults ([`SensorFaults`]): stuck (the reading freezes where it was: a worn track, a
//! wiper lifted off it, a frozen converter), open wire (the wiper or the supply open: the
//! board's pull-down takes the input to 0 counts), drift (the reading walks away at a
//! constant rate: a failing reference, a creeping connector).
//!
//! Not modelled: the track's nonlinearity (the firmware's calibration removes it; the
//! residual is the offset), the converter's own nonlinearity, the potentiometer's
//! mechanical play.

/// Counts at mid-scale.
pub const MID_SCALE: f64 = 32768.0;
/// Counts at full scale.
pub const FULL_SCALE: u16 = u16::MAX;

/// The faults injected into one joint's sensor (none by default).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct SensorFaults {
    /// The reading is frozen at this count.
    pub stuck: Option<u16>,
    /// A wire is open: the input reads 0 counts.
    pub open_wire: bool,
    /// The reading drifts at `.0` joint units per second (m/s, rad/s) since the plant time
    /// `.1` (s).
    pub drift: Option<(f64, f64)>,
}

/// One joint's absolute position sensor and its converter channel.
#[derive(Debug, Clone, PartialEq)]
pub struct PositionSensor {
    /// Converter counts per joint unit (counts/m, counts/rad).
    pub counts_per_unit: f64,
    /// The joint position at mid-scale (m, rad).
    pub mid: f64,
    /// Noise, counts rms.
    pub noise_lsb: f64,
    /// The calibration's residual offset, counts.
    pub offset_lsb: f64,
    /// Seeds the joint's noise.
    seed: u64,
    faults: SensorFaults,
}

/// SplitMix64: one step of a well-mixed 64-bit hash.
fn mix(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

impl PositionSensor {
    /// A sensor of `counts_per_unit` counts per joint unit with mid-scale at `mid`, noise
    /// `noise_lsb` counts rms, offset `offset_lsb` counts; `seed` makes its noise its own.
    pub fn new(counts_per_unit: f64, mid: f64, noise_lsb: f64, offset_lsb: f64, seed: u64) -> Self {
        PositionSensor {
            counts_per_unit,
            mid,
            noise_lsb,
            offset_lsb,
            seed,
            faults: SensorFaults::default(),
        }
    }

    /// Zero-mean noise of unit variance at `time_s`: the sum of four uniform variates
    /// (Irwin-Hall) scaled to unit variance, bounded by +-3.46.
    fn unit_noise(&self, time_s: f64) -> f64 {
        let us = (time_s * 1e6).round().max(0.0) as u64;
        let mut h = mix(self.seed ^ mix(us));
        let mut sum = 0.0;
        for _ in 0..4 {
            sum += (h & 0xFFFF) as f64 / 65536.0;
            h >>= 16;
        }
        // Four uniforms on [0, 1): mean 2, variance 4/12.
        (sum - 2.0) * 3f64.sqrt()
    }

    /// The ideal count of the joint position `q` (no noise, no fault), unclamped.
    pub fn ideal_counts(&self, q: f64) -> f64 {
        MID_SCALE + (q - self.mid) * self.counts_per_unit + self.offset_lsb
    }

    /// The converter's reading of the joint position `q` at plant time `time_s`.
    pub fn reading(&self, q: f64, time_s: f64) -> u16 {
        if self.faults.open_wire {
            return 0;
        }
        if let Some(c) = self.faults.stuck {
            return c;
        }
        let drift = self
            .faults
            .drift
            .map_or(0.0, |(rate, since)| rate * (time_s - since).max(0.0));
        let x = self.ideal_counts(q + drift) + self.noise_lsb * self.unit_noise(time_s);
        if x.is_nan() {
            return 0;
        }
        x.round().clamp(0.0, f64::from(FULL_SCALE)) as u16
    }

    /// The joint position a reading stands for, by the sensor's own calibration (without
    /// the offset the calibration does not know): what the firmware computes.
    pub fn position_of(&self, counts: u16) -> f64 {
        self.mid + (f64::from(counts) - MID_SCALE) / self.counts_per_unit
    }

    /// The faults injected.
    pub fn faults(&self) -> SensorFaults {
        self.faults
    }

    /// Replaces the faults injected.
    pub fn set_faults(&mut self, faults: SensorFaults) {
        self.faults = faults;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn leg() -> PositionSensor {
        PositionSensor::new(65536.0 / 0.1, 0.177, 1.0, 0.0, 7)
    }

    /// The noise has zero mean and the stated rms, and stays within its bound.
    #[test]
    fn the_noise_has_the_stated_rms() {
        let s = leg();
        let n = 20_000;
        let xs: Vec<f64> = (0..n).map(|k| s.unit_noise(k as f64 * 1e-3)).collect();
        let mean = xs.iter().sum::<f64>() / n as f64;
        let rms = (xs.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / n as f64).sqrt();
        assert!(mean.abs() < 0.03, "mean {mean}");
        assert!((rms - 1.0).abs() < 0.03, "rms {rms}");
        assert!(xs.iter().all(|x| x.abs() <= 3.47));
    }

    /// A reading is a function of the position and the time only.
    #[test]
    fn the_reading_is_a_function_of_position_and_time() {
        let s = leg();
        assert_eq!(s.reading(0.17, 1.234), s.reading(0.17, 1.234));
        let t: Vec<u16> = (0..50).map(|k| s.reading(0.17, k as f64 * 1e-3)).collect();
        assert!(t.iter().any(|c| *c != t[0]), "the noise changes with time");
    }
}
