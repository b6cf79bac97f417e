//! A software stand-in for the board's hardware behind the `hal` traits: six DC
//! motors (first-order: no-load speed and mechanical time constant of the prototype's
//! legs and links, as in firmware/servo/tests/common) driven by the duties, read by
//! 16-bit quadrature counters that wrap. The motor sits directly on the joint (no
//! backlash, no load). `counts()` and `set_duties()` only copy arrays, so they add almost
//! nothing to a measured control tick; the motors are advanced between ticks by [`step`].
//!
//! [`step`]: PlantStub::step

use hal::{AbsolutePositions, MotorOutputs, QuadratureCounter};
use nalgebra::ComplexField;

/// No-load speed at full duty: legs 0.378 m/s, links 28.5 rad/s.
const NO_LOAD: [f64; 6] = [0.378, 0.378, 0.378, 28.5, 28.5, 28.5];
/// Mechanical time constant: legs 5.6 ms, links 15 ms.
const TAU: [f64; 6] = [0.0056, 0.0056, 0.0056, 0.015, 0.015, 0.015];

/// The six motors and their counters.
pub struct PlantStub {
    /// True joint positions, m or rad.
    pub q: [f64; 6],
    /// Joint velocities.
    pub v: [f64; 6],
    q0: [f64; 6],
    raw0: [u16; 6],
    raw: [u16; 6],
    /// The second channel's readings (updated by `step`, copied by the reads).
    absolute: [u16; 6],
    duty: [f32; 6],
    enabled: bool,
    /// Calls of `set_duties` and `disable`.
    pub writes: u32,
    pub disables: u32,
}

fn counts_per_unit(j: usize) -> f64 {
    board_profile::BoardProfile::REFERENCE
        .joints
        .get(j)
        .map_or(1.0, |p| p.counts_per_unit())
}

impl PlantStub {
    /// Motors at rest at `q0`, the counters reading `raw0` there.
    pub fn new(q0: [f64; 6], raw0: [u16; 6]) -> Self {
        PlantStub {
            q: q0,
            v: [0.0; 6],
            q0,
            raw0,
            raw: raw0,
            absolute: [32768; 6],
            duty: [0.0; 6],
            enabled: true,
            writes: 0,
            disables: 0,
        }
    }

    /// The raw counters now.
    pub fn raw(&self) -> [u16; 6] {
        self.raw
    }

    /// The last duties applied (0 while disabled).
    pub fn duty(&self) -> [f32; 6] {
        self.duty
    }

    /// Advances the motors by `dt` with the duties held (exact solution of
    /// `tau v' = u v_max - v`), then updates the counters.
    pub fn step(&mut self, dt: f64) {
        for j in 0..6 {
            let u = if self.enabled {
                f64::from(self.duty[j])
            } else {
                0.0
            };
            let v_inf = u * NO_LOAD[j];
            let e = ComplexField::exp(-dt / TAU[j]);
            self.q[j] += v_inf * dt + (self.v[j] - v_inf) * TAU[j] * (1.0 - e);
            self.v[j] = v_inf + (self.v[j] - v_inf) * e;
            let counts = ComplexField::round((self.q[j] - self.q0[j]) * counts_per_unit(j)) as i64;
            self.raw[j] = self.raw0[j].wrapping_add(counts as u16);
            let c = 32768.0 + (self.q[j] - self.q0[j]) * absolute_counts_per_unit(j);
            self.absolute[j] = ComplexField::round(c).clamp(0.0, 65535.0) as u16;
        }
    }
}

/// Counts of the second channel's readings per joint unit: the board profile's
/// (`board_profile::position_channel::PositionChannel::REFERENCE`: 100 mm over 65536 counts
/// on a leg, 340 deg on a link).
pub fn absolute_counts_per_unit(j: usize) -> f64 {
    board_profile::position_channel::PositionChannel::REFERENCE.counts_per_unit(j)
}

/// The second position channel: a potentiometer per joint on the load side, at mid-scale
/// where the motors started (`q0`), read without noise.
impl AbsolutePositions for PlantStub {
    fn absolute_fitted(&self) -> bool {
        true
    }
    fn absolute_counts(&mut self) -> Option<[u16; 6]> {
        Some(self.absolute)
    }
}

impl QuadratureCounter for PlantStub {
    fn counts(&mut self) -> [u16; 6] {
        self.raw
    }
}

impl MotorOutputs<f32> for PlantStub {
    fn set_duties(&mut self, duty: &[f32; 6]) {
        self.writes += 1;
        for (d, x) in self.duty.iter_mut().zip(duty) {
            *d = if x.is_nan() { 0.0 } else { x.clamp(-1.0, 1.0) };
        }
    }
    fn disable(&mut self) {
        self.disables += 1;
        self.enabled = false;
        self.duty = [0.0; 6];
    }
    fn enable(&mut self) {
        self.enabled = true;
    }
}
