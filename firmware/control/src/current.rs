//! Motor currents: the peak limit that caps every duty command, the I²t model of each
//! motor's continuous rating (derating, then a fault), the overcurrent trip and the
//! sustained-overload trip.
//!
//! Two layers keep the current under the peak:
//! * **in the drivers, cycle by cycle:** each H-bridge regulates its current to a trip level
//!   set on the board to the joint's peak (current chopping, as the DRV887x drivers do),
//!   so that no transient exceeds it, even the impact on an obstacle within a tick;
//! * **here, every tick:** the duty command is capped on the motor model
//!   `i = (V·d − Ke·ω)/R` (the inductance neglected: L/R is 0.1 to 0.24 ms, well under the
//!   1 ms tick), with the measured supply V and the measured motor speed ω:
//!   `(−i_lim·R + Ke·ω)/V ≤ d ≤ (i_lim·R + Ke·ω)/V`, so that the drivers do not chop in
//!   steady state and the I²t derating lowers the current below the drivers' trip level. A
//!   correction on the measured current covers the model's error (a warm winding, a worn
//!   brush): while the measured current exceeds the limit, the limit used shrinks in
//!   proportion, and recovers slowly after.
//!
//! A current held at the limit (measured at 90 % of the peak or more) for longer than the
//! overload time is a fault (the joint pushes against something with its rated force);
//! a current above the trip level of the monitor (1.5 × the peak: a short, a failed driver)
//! is an overcurrent fault.

use crate::scalar::lit;
use num_traits::Float;
use servo::NUM_JOINTS;

/// The normalised temperature rise (1 = the continuous rating's) from which the I²t model
/// derates the peak current.
const DERATING_FROM: f64 = 0.9;

/// One motor and its transmission, SI (the defaults are the reference robot's:
/// `host-sim/plant/plant.toml`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MotorModel<S> {
    /// Winding plus bridge resistance, Ω.
    pub resistance_ohm: S,
    /// Back-EMF constant, V s/rad (= the torque constant, N m/A).
    pub back_emf_v_s_per_rad: S,
    /// Motor radians per joint unit (rad/m on a leg, rad/rad on a link).
    pub motor_rad_per_unit: S,
    /// Joint effort per ampere (N/A on a leg, N m/A on a link), efficiencies included.
    pub effort_per_amp: S,
    /// Continuous current of the motor (its thermal rating), A.
    pub continuous_a: S,
    /// Thermal time constant of the winding, s.
    pub thermal_time_s: S,
}

impl<S: Float> MotorModel<S> {
    /// A leg: 40 mm ironless motor (maxon RE 40 class), 2:1 spur pair, 6 mm lead screw.
    pub fn leg() -> Self {
        let ratio = 2.0 * core::f64::consts::TAU / 0.006; // motor rad per m of leg
        MotorModel {
            resistance_ohm: lit(0.317 + 0.03),
            back_emf_v_s_per_rad: lit(0.0302),
            motor_rad_per_unit: lit(ratio),
            effort_per_amp: lit(0.0302 * ratio * 0.95 * 0.70),
            continuous_a: lit(5.77),
            thermal_time_s: lit(41.6),
        }
    }
    /// A rotating link: 25 mm ironless motor (maxon RE 25 class), 36:1 spur train.
    pub fn link() -> Self {
        MotorModel {
            resistance_ohm: lit(2.14 + 0.03),
            back_emf_v_s_per_rad: lit(0.0234),
            motor_rad_per_unit: lit(36.0),
            effort_per_amp: lit(0.0234 * 36.0 * 0.90),
            continuous_a: lit(1.2),
            thermal_time_s: lit(12.4),
        }
    }
}

/// Current limits of one joint.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CurrentLimits<S> {
    /// The joint's effort limit (N or N m): the peak current is this over
    /// `effort_per_amp`. Default: the continuous ratings, 220 N and 0.5 N m.
    pub effort_limit: S,
    /// Measured current above which the overcurrent trip counts, A (default 1.5 × the peak
    /// current: the limit cannot cause it, a short or a driver failure can).
    pub trip_a: S,
    /// Consecutive ticks above `trip_a` that trip (default 1: the limit and its
    /// correction cannot produce such a current, so one sample is a short or a failed
    /// driver; a second sample would come after the correction has already cut the duty).
    pub trip_ticks: u16,
    /// How long the current may stay at the limit (90 % of the peak or more) before it is
    /// an overload fault, µs (default 8 ms).
    pub overload_us: u64,
}

/// Current monitoring settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CurrentConfig<S> {
    /// The motors, joint order.
    pub motors: [MotorModel<S>; NUM_JOINTS],
    /// The limits, joint order.
    pub limits: [CurrentLimits<S>; NUM_JOINTS],
}

impl<S: Float> Default for CurrentConfig<S> {
    fn default() -> Self {
        let (leg, link) = (MotorModel::<S>::leg(), MotorModel::<S>::link());
        let limits = |m: &MotorModel<S>, effort: f64| {
            let peak = lit::<S>(effort) / m.effort_per_amp;
            CurrentLimits {
                effort_limit: lit(effort),
                trip_a: peak * lit(1.5),
                trip_ticks: 1,
                overload_us: 8_000,
            }
        };
        CurrentConfig {
            motors: [leg, leg, leg, link, link, link],
            limits: [
                limits(&leg, 220.0),
                limits(&leg, 220.0),
                limits(&leg, 220.0),
                limits(&link, 0.5),
                limits(&link, 0.5),
                limits(&link, 0.5),
            ],
        }
    }
}

/// What the current monitor found on one tick.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum CurrentFault<S> {
    /// Above the trip level (joint, A).
    Overcurrent {
        /// Joint.
        joint: usize,
        /// Measured current, A.
        current_a: S,
    },
    /// The peak limit held the command too long (joint, A).
    Overload {
        /// Joint.
        joint: usize,
        /// Measured current, A.
        current_a: S,
    },
    /// The I²t model's temperature rise exceeded the continuous rating (joint, the rise
    /// as a fraction of the rating's).
    OverTemperature {
        /// Joint.
        joint: usize,
        /// Normalised temperature rise (1 = the continuous rating's).
        heat: S,
    },
}

/// The per-joint current limiter and monitors.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CurrentMonitor<S> {
    cfg: CurrentConfig<S>,
    /// Correction of the model from the measured currents, (0, 1].
    correction: [S; NUM_JOINTS],
    /// Normalised temperature rise of each winding (1 = steady state at the continuous
    /// current).
    heat: [S; NUM_JOINTS],
    above_trip: [u16; NUM_JOINTS],
    /// Since when the current has been at the limit, per joint.
    at_limit_since: [Option<u64>; NUM_JOINTS],
    /// Peak |current| seen per joint, A.
    peak_a: [S; NUM_JOINTS],
    /// The last tick's duties were limited, per joint.
    limited: [bool; NUM_JOINTS],
}

impl<S: Float> CurrentMonitor<S> {
    /// Cold motors, no correction.
    pub fn new(cfg: CurrentConfig<S>) -> Self {
        CurrentMonitor {
            cfg,
            correction: [S::one(); NUM_JOINTS],
            heat: [S::zero(); NUM_JOINTS],
            above_trip: [0; NUM_JOINTS],
            at_limit_since: [None; NUM_JOINTS],
            peak_a: [S::zero(); NUM_JOINTS],
            limited: [false; NUM_JOINTS],
        }
    }

    /// The settings.
    pub fn config(&self) -> &CurrentConfig<S> {
        &self.cfg
    }
    /// Normalised temperature rise of each winding.
    pub fn heat(&self) -> [S; NUM_JOINTS] {
        self.heat
    }
    /// Peak |current| seen per joint, A.
    pub fn peak_a(&self) -> [S; NUM_JOINTS] {
        self.peak_a
    }
    /// Which joints the last tick limited.
    pub fn limited(&self) -> [bool; NUM_JOINTS] {
        self.limited
    }

    /// The temperature rise (normalised) from which the peak current is derated.
    pub fn derating_from(&self) -> S {
        lit(DERATING_FROM)
    }

    /// The peak current of joint `j` now: the effort limit, derated by the I²t model from
    /// 90 % of the continuous rating's temperature rise down to the continuous current at
    /// 100 %.
    pub fn peak_current(&self, j: usize) -> S {
        let (Some(m), Some(l), Some(h)) = (
            self.cfg.motors.get(j),
            self.cfg.limits.get(j),
            self.heat.get(j),
        ) else {
            return S::zero();
        };
        let peak = l.effort_limit / m.effort_per_amp;
        let start = lit::<S>(DERATING_FROM);
        if *h <= start || peak <= m.continuous_a {
            return peak;
        }
        let k = ((*h - start) / (S::one() - start)).min(S::one());
        peak - (peak - m.continuous_a) * k
    }

    /// Monitors the currents measured at the start of the tick (`currents`, A) at `now_us`,
    /// over the last `dt` s, with the drives producing torque (`torque`): the overcurrent
    /// trip, the sustained overload, the I²t model, the model correction. Returns the first
    /// fault found.
    pub fn monitor(
        &mut self,
        currents: &[S; NUM_JOINTS],
        dt: S,
        torque: bool,
        now_us: u64,
    ) -> Option<CurrentFault<S>> {
        let mut fault = None;
        for j in 0..NUM_JOINTS {
            let (Some(i), Some(m), Some(l)) = (
                currents.get(j).copied(),
                self.cfg.motors.get(j),
                self.cfg.limits.get(j),
            ) else {
                continue;
            };
            let i = if i.is_finite() {
                i.abs()
            } else {
                S::infinity()
            };
            if let Some(p) = self.peak_a.get_mut(j) {
                *p = p.max(i);
            }
            // Overcurrent: consecutive samples above the trip level.
            if let Some(n) = self.above_trip.get_mut(j) {
                *n = if i > l.trip_a { n.saturating_add(1) } else { 0 };
                if *n >= l.trip_ticks && fault.is_none() {
                    fault = Some(CurrentFault::Overcurrent {
                        joint: j,
                        current_a: i,
                    });
                }
            }
            // I²t: first-order winding temperature, normalised to the rise at the
            // continuous current.
            if let Some(h) = self.heat.get_mut(j) {
                let target = (i / m.continuous_a).powi(2);
                let a = (dt / m.thermal_time_s).min(S::one());
                *h = *h + (target - *h) * a;
                if *h > S::one() && fault.is_none() {
                    fault = Some(CurrentFault::OverTemperature { joint: j, heat: *h });
                }
            }
            // The model correction: shrink while the measurement exceeds the limit.
            let peak = self.peak_current(j);
            // Overload: at the limit for longer than the overload time.
            if let Some(since) = self.at_limit_since.get_mut(j) {
                if torque && i >= peak * lit(0.9) {
                    let t0 = *since.get_or_insert(now_us);
                    if now_us.saturating_sub(t0) >= l.overload_us && fault.is_none() {
                        fault = Some(CurrentFault::Overload {
                            joint: j,
                            current_a: i,
                        });
                    }
                } else {
                    *since = None;
                }
            }
            if let Some(c) = self.correction.get_mut(j) {
                if torque && i > peak && i.is_finite() {
                    *c = (*c * peak / i).max(lit(0.2));
                } else {
                    *c = (*c * lit(1.01)).min(S::one());
                }
            }
        }
        fault
    }

    /// Caps the duties `duty` so that the model's current stays within the peak (see the
    /// module docs), given the supply voltage `supply_v` and the joint speeds `qdot` (m/s,
    /// rad/s) at the start of the tick; every duty ends within [-1, 1] (a NaN becomes 0).
    pub fn limit(&mut self, duty: &mut [S; NUM_JOINTS], qdot: &[S; NUM_JOINTS], supply_v: S) {
        let v = if supply_v.is_finite() && supply_v > lit(1.0) {
            supply_v
        } else {
            lit(1.0)
        };
        for j in 0..NUM_JOINTS {
            let peak = self.peak_current(j);
            let (Some(d), Some(m), Some(c), Some(w)) = (
                duty.get_mut(j),
                self.cfg.motors.get(j),
                self.correction.get(j),
                qdot.get(j),
            ) else {
                continue;
            };
            let omega = if w.is_finite() {
                *w * m.motor_rad_per_unit
            } else {
                S::zero()
            };
            let i_lim = peak * *c;
            let ke = m.back_emf_v_s_per_rad;
            // The range the current allows, within what a bridge can apply: a joint driven
            // faster than its no-load speed (back-driven) puts one bound beyond ±1.
            // (Comparisons, not `Float::min/max`: those are libm calls on the Cortex-M4.)
            let hi = (i_lim * m.resistance_ohm + ke * omega) / v;
            let lo = (-i_lim * m.resistance_ohm + ke * omega) / v;
            let unit = |x: S| {
                if x > S::one() {
                    S::one()
                } else if x < -S::one() {
                    -S::one()
                } else {
                    x
                }
            };
            let (hi, lo) = (unit(hi), unit(lo));
            // (If the two cross, the current cannot be kept within the limit at any duty
            // the bridge applies: the duty nearest the allowed range, towards braking.)
            let (lo, hi) = if lo > hi { (hi, hi) } else { (lo, hi) };
            let limited = *d > hi || *d < lo;
            if d.is_nan() {
                *d = S::zero();
            } else if *d > hi {
                *d = hi;
            } else if *d < lo {
                *d = lo;
            }
            if let Some(x) = self.limited.get_mut(j) {
                *x = limited;
            }
        }
    }

    /// Forgets the overload timers (the drives went off).
    pub fn reset_overload(&mut self) {
        self.at_limit_since = [None; NUM_JOINTS];
        self.limited = [false; NUM_JOINTS];
    }
}
