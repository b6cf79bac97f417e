//! Encoder position: extension of the wrapping 16-bit hardware counters to 64-bit counts,
//! conversion to joint units and the homing offset.
//!
//! ## Extension
//! Each read takes the difference to the previous raw value modulo 2^16, interpreted as
//! an `i16` (`raw.wrapping_sub(last) as i16`), and adds it to a 64-bit count. This is exact
//! as long as the counter moves by **fewer than 32768 counts between two reads** (in
//! either direction). That is the maximum speed: 32767 counts per read period, i.e. at a
//! 1 kHz read rate 49 m/s on a leg (666 667 counts/m) and 2 860 rad/s on a link
//! (11 459 counts/rad); the plant's no-load speeds (0.378 m/s, 28 rad/s) are about
//! 1/100 of that even at 10 kHz. [`JointEncoder::max_speed`] gives the figure for any
//! read period. Faster motion aliases silently (a count difference of 32768 + n reads as
//! -32768 + n), so reads must not be skipped for long while the joint moves.
//!
//! ## Joint units
//! `q = q_ref + (count - count_ref) / counts_per_unit`. Homing sets the reference
//! ([`JointEncoder::set_position`]: the current count reads `q`). Differences are taken in
//! `i64` before the conversion, so `f32` keeps one-count resolution within 2^24 counts of
//! the homing point (25 m on a leg, 1 464 rad on a link).

use num_traits::Float;

use crate::checks::{Check, ConfigError};
use crate::num::{from_i64, lit};
use crate::NUM_JOINTS;
use hal::QuadratureCounter;

/// Extends a wrapping 16-bit counter to a 64-bit count.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct CountExtender {
    last_raw: u16,
    count: i64,
}

impl CountExtender {
    /// Starts at count 0 with the counter at raw 0 (the hardware counter's reset value):
    /// the first [`update`](Self::update) then reads the raw value as a signed count.
    pub const fn new() -> Self {
        CountExtender {
            last_raw: 0,
            count: 0,
        }
    }

    /// Starts at `count` with the counter currently at `raw`.
    pub const fn starting_at(raw: u16, count: i64) -> Self {
        CountExtender {
            last_raw: raw,
            count,
        }
    }

    /// Takes a new raw counter value and returns the extended count.
    ///
    /// Exact if the counter moved by fewer than 32768 counts since the last call.
    pub fn update(&mut self, raw: u16) -> i64 {
        // Difference modulo 2^16, taken as the shortest signed step (-32768..=32767).
        let delta = raw.wrapping_sub(self.last_raw) as i16;
        self.last_raw = raw;
        // Wrapping: 2^63 counts are never reached (292 000 years at 10^9 counts/s).
        self.count = self.count.wrapping_add(i64::from(delta));
        self.count
    }

    /// The extended count after the last update.
    pub const fn count(&self) -> i64 {
        self.count
    }

    /// The last raw counter value.
    pub const fn last_raw(&self) -> u16 {
        self.last_raw
    }
}

/// One joint's encoder in joint units (m or rad).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct JointEncoder<S> {
    extender: CountExtender,
    counts_per_unit: S,
    ref_count: i64,
    ref_position: S,
}

impl<S: Float> JointEncoder<S> {
    /// An encoder with `counts_per_unit` counts per metre (legs) or per radian (links),
    /// reading 0 at count 0 (counter at raw 0). `counts_per_unit` must be finite and > 0
    /// (see [`EncoderConfig::validate`]); otherwise positions read 0.
    pub fn new(counts_per_unit: S) -> Self {
        JointEncoder {
            extender: CountExtender::new(),
            counts_per_unit,
            ref_count: 0,
            ref_position: S::zero(),
        }
    }

    /// Takes a new raw counter value and returns the joint position.
    pub fn update(&mut self, raw: u16) -> S {
        self.extender.update(raw);
        self.position()
    }

    /// The joint position at the last update: `q_ref + (count - count_ref) / counts_per_unit`.
    pub fn position(&self) -> S {
        let counts = self.extender.count().wrapping_sub(self.ref_count);
        let q = self.ref_position + from_i64::<S>(counts) / self.counts_per_unit;
        if q.is_finite() {
            q
        } else {
            S::zero()
        }
    }

    /// Homing: from now on the current count reads `q` (ignored if `q` is not finite).
    pub fn set_position(&mut self, q: S) {
        if q.is_finite() {
            self.ref_count = self.extender.count();
            self.ref_position = q;
        }
    }

    /// The extended count at the last update (counts since construction).
    pub fn count(&self) -> i64 {
        self.extender.count()
    }

    /// Counts per joint unit (counts/m or counts/rad).
    pub fn counts_per_unit(&self) -> S {
        self.counts_per_unit
    }

    /// One count in joint units (m or rad): the resolution.
    pub fn resolution(&self) -> S {
        S::one() / self.counts_per_unit
    }

    /// The largest joint speed (units/s) that the extension follows when read every
    /// `read_period` seconds: 32767 counts per read.
    pub fn max_speed(&self, read_period: S) -> S {
        lit::<S>(32767.0) / (self.counts_per_unit * read_period)
    }
}

/// Encoder resolution of the six joints.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EncoderConfig<S> {
    /// Counts per joint unit, counts/m for the legs and counts/rad for the links; finite
    /// and > 0. Default: legs 2000 counts per 3 mm = 666 666.67 counts/m
    /// (0.0015 mm/count: 500-line encoder x4 on the motor, 3 mm of leg per motor
    /// revolution); links 2000 counts per 10 deg = 11 459.16 counts/rad (0.005 deg/count,
    /// 36:1 gearing).
    pub counts_per_unit: [S; NUM_JOINTS],
}

impl<S: Float> Default for EncoderConfig<S> {
    /// The reference board's encoders ([`board_profile::BoardProfile::REFERENCE`]).
    fn default() -> Self {
        let cpu = board_profile::BoardProfile::REFERENCE.counts_per_unit();
        EncoderConfig {
            counts_per_unit: cpu.map(lit),
        }
    }
}

impl<S: Float> EncoderConfig<S> {
    /// Checks that every `counts_per_unit` is finite and > 0.
    pub fn validate(&self) -> Result<(), ConfigError> {
        for (joint, c) in self.counts_per_unit.iter().enumerate() {
            Check {
                section: "encoder",
                joint,
            }
            .positive("counts_per_unit", *c)?;
        }
        Ok(())
    }
}

/// The six joint encoders.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Encoders<S> {
    joints: [JointEncoder<S>; NUM_JOINTS],
}

impl<S: Float> Encoders<S> {
    /// Six encoders reading 0 with their counters at raw 0; validates the configuration.
    pub fn new(config: &EncoderConfig<S>) -> Result<Self, ConfigError> {
        config.validate()?;
        Ok(Encoders {
            joints: config.counts_per_unit.map(JointEncoder::new),
        })
    }

    /// Six encoders whose current raw counters `raw` read count 0 (position 0).
    pub fn starting_at(
        config: &EncoderConfig<S>,
        raw: &[u16; NUM_JOINTS],
    ) -> Result<Self, ConfigError> {
        let mut e = Self::new(config)?;
        for (enc, r) in e.joints.iter_mut().zip(raw) {
            enc.extender = CountExtender::starting_at(*r, 0);
        }
        Ok(e)
    }

    /// Takes six raw counter values and returns the joint positions.
    pub fn update(&mut self, raw: &[u16; NUM_JOINTS]) -> [S; NUM_JOINTS] {
        let mut q = [S::zero(); NUM_JOINTS];
        for ((qj, enc), r) in q.iter_mut().zip(self.joints.iter_mut()).zip(raw) {
            *qj = enc.update(*r);
        }
        q
    }

    /// Reads the hardware counters and returns the joint positions.
    pub fn read<C: QuadratureCounter + ?Sized>(&mut self, counter: &mut C) -> [S; NUM_JOINTS] {
        let raw = counter.counts();
        self.update(&raw)
    }

    /// The joint positions at the last update.
    pub fn positions(&self) -> [S; NUM_JOINTS] {
        self.joints.map(|e| e.position())
    }

    /// The extended counts at the last update.
    pub fn counts(&self) -> [i64; NUM_JOINTS] {
        self.joints.map(|e| e.count())
    }

    /// Homing of every joint: the current counts read `q` (non-finite entries ignored).
    pub fn set_positions(&mut self, q: &[S; NUM_JOINTS]) {
        for (enc, qj) in self.joints.iter_mut().zip(q) {
            enc.set_position(*qj);
        }
    }

    /// Homing of one joint; `false` if `joint` is out of range.
    pub fn set_position(&mut self, joint: usize, q: S) -> bool {
        match self.joints.get_mut(joint) {
            Some(enc) => {
                enc.set_position(q);
                true
            }
            None => false,
        }
    }

    /// One joint's encoder.
    pub fn joint(&self, joint: usize) -> Option<&JointEncoder<S>> {
        self.joints.get(joint)
    }
}
