//! Incremental quadrature encoder on the motor shaft, read through a 16-bit hardware
//! counter that wraps (like an STM32 timer in encoder mode).
//!
//! The ideal count is `floor((theta - theta_ref) * cpr / 2 pi)`: it increases with positive
//! motor rotation (which moves the joint towards `+q`). At reset the reference sits half a
//! count below the shaft angle, so the counter reads 0 and changes after half a count of
//! motion either way. Each update adds the change of the ideal count to the counter,
//! modulo 2^16; the controller must extend it to a wider count.
//!
//! Faults act on the counting, not on the shaft: a stuck encoder drops every change (the
//! counter freezes; when the fault is cleared, counting resumes from the frozen value,
//! the counts missed stay missed), and a lossy encoder drops one count in every `n`.

use std::f64::consts::TAU;

/// `x.floor() as i64` (saturating, NaN to 0) without a call to libm's `floor`, which the
/// baseline x86-64 target makes for `f64::floor` (this runs in every plant step): the
/// truncation, one less for a negative non-integer.
#[inline]
fn floor_to_i64(x: f64) -> i64 {
    let t = x as i64;
    // Saturating: below i64::MIN the truncation already saturated.
    t.saturating_sub(i64::from((t as f64) > x))
}

/// Encoder state of one joint.
#[derive(Debug, Clone, PartialEq)]
pub struct QuadratureEncoder {
    counts_per_rev: u32,
    /// `counts_per_rev / 2 pi`.
    counts_per_rad: f64,
    reference_angle: f64,
    last_ideal: i64,
    counter: u16,
    /// Counts dropped so far by a lossy encoder, towards the next dropped count.
    loss_tally: u64,
    /// Counter frozen.
    pub stuck: bool,
    /// Drop one count in every `n` (None: healthy).
    pub lose_one_in: Option<u32>,
    /// Keep only one count in every `n` (a failing sensor; None: healthy).
    pub keep_one_in: Option<u32>,
    /// Counts seen towards the next kept count.
    keep_tally: u64,
}

impl QuadratureEncoder {
    /// An encoder with `counts_per_rev` counts per shaft revolution (lines x quadrature),
    /// reset at shaft angle 0.
    pub fn new(counts_per_rev: u32) -> Self {
        let mut e = QuadratureEncoder {
            counts_per_rev,
            counts_per_rad: f64::from(counts_per_rev) / TAU,
            reference_angle: 0.0,
            last_ideal: 0,
            counter: 0,
            loss_tally: 0,
            stuck: false,
            lose_one_in: None,
            keep_one_in: None,
            keep_tally: 0,
        };
        e.reset(0.0);
        e
    }

    /// Counts per shaft revolution.
    pub fn counts_per_rev(&self) -> u32 {
        self.counts_per_rev
    }

    /// Shaft angle of one count, rad.
    pub fn count_angle(&self) -> f64 {
        TAU / f64::from(self.counts_per_rev)
    }

    /// Sets the counter to 0 at shaft angle `angle` (mid-count).
    pub fn reset(&mut self, angle: f64) {
        self.reference_angle = angle - 0.5 * self.count_angle();
        self.last_ideal = 0;
        self.counter = 0;
        self.loss_tally = 0;
    }

    /// The ideal (unwrapped, fault-free) count at shaft angle `angle`.
    pub fn ideal_count(&self, angle: f64) -> i64 {
        floor_to_i64((angle - self.reference_angle) * self.counts_per_rad)
    }

    /// Follows the shaft to `angle`.
    pub fn update(&mut self, angle: f64) {
        let ideal = self.ideal_count(angle);
        let mut delta = ideal - self.last_ideal;
        self.last_ideal = ideal;
        if self.stuck || delta == 0 {
            return;
        }
        if let Some(n) = self.lose_one_in {
            let n = u64::from(n.max(1));
            self.loss_tally += delta.unsigned_abs();
            let lost = self.loss_tally / n;
            self.loss_tally %= n;
            // The tally was below n before this update, so `lost <= |delta|`.
            let lost = lost.min(delta.unsigned_abs()) as i64;
            delta -= lost * delta.signum();
        }
        if let Some(n) = self.keep_one_in {
            let n = u64::from(n.max(1));
            let before = self.keep_tally / n;
            self.keep_tally += delta.unsigned_abs();
            let kept = (self.keep_tally / n - before) as i64;
            delta = kept * delta.signum();
        }
        // Adding modulo 2^16 is exactly what the hardware counter does.
        self.counter = self.counter.wrapping_add(delta.rem_euclid(1 << 16) as u16);
    }

    /// Moves the counter by `counts` without shaft motion (an electrical glitch: noise on
    /// the A/B lines counted as edges).
    pub fn glitch(&mut self, counts: i64) {
        self.counter = self.counter.wrapping_add(counts.rem_euclid(1 << 16) as u16);
    }

    /// The 16-bit hardware counter.
    pub fn counter(&self) -> u16 {
        self.counter
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_revolution_is_2000_counts_and_the_counter_wraps_both_ways() {
        let mut e = QuadratureEncoder::new(2000);
        e.update(TAU);
        assert_eq!(e.counter(), 2000);
        e.update(40.0 * TAU); // 80 000 counts: wrapped once
        assert_eq!(e.counter(), (80_000 % 65_536) as u16);
        e.update(-TAU); // -2000 counts
        assert_eq!(e.counter(), 63_536);
    }

    #[test]
    fn counts_are_floored_with_the_sign_of_the_rotation() {
        let mut e = QuadratureEncoder::new(2000);
        let c = e.count_angle();
        e.update(0.49 * c);
        assert_eq!(e.counter(), 0);
        e.update(0.51 * c);
        assert_eq!(e.counter(), 1);
        e.update(-0.51 * c);
        assert_eq!(e.counter(), u16::MAX);
    }

    #[test]
    fn the_fast_floor_is_floor() {
        for x in [
            0.0,
            -0.0,
            0.5,
            -0.5,
            1.0,
            -1.0,
            -1.0 - f64::EPSILON,
            1e15 + 0.5,
            -1e15 - 0.5,
            4.0e18,
            1e300,
            -1e300,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NAN,
        ] {
            assert_eq!(floor_to_i64(x), x.floor() as i64, "{x}");
        }
    }

    #[test]
    fn a_lossy_encoder_drops_one_count_in_n() {
        let mut e = QuadratureEncoder::new(2000);
        e.lose_one_in = Some(100);
        for k in 1..=1000 {
            e.update(f64::from(k) * 10.0 * e.count_angle());
        }
        assert_eq!(e.counter(), 10_000 - 100);
    }
}
