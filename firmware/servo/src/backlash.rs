//! Lead-screw backlash compensation: a direction-reversal offset added to the position
//! setpoint.
//!
//! The encoders sit on the motors, so the backlash between motor and load (0.08..0.2 mm
//! on the legs) is invisible to the position loop: after a reversal the motor travels
//! the gap before the load follows. With the encoder's zero referred to the middle of the
//! gap, a load at `r` needs the motor at `r + b/2` while pushing towards `+q` and at
//! `r - b/2` while pushing towards `-q` (`b` the total backlash). The compensator
//!
//! 1. tracks the direction of the commanded motion with a hysteresis: the direction
//!    flips only once the setpoint has come back by more than `hysteresis` from its
//!    furthest point in the current direction (noise smaller than that never toggles it);
//! 2. moves its offset towards `direction * b/2`, not as a step but ramped over a
//!    configurable setpoint distance (`|d offset| <= b / ramp_distance * |d r|`) or time
//!    (`|d offset| <= b / ramp_time * dt`), so the motor setpoint never jumps;
//! 3. reports the offset and its rate (to add to the velocity feed-forward).
//!
//! Homing must refer the encoder zero to the middle of the gap (e.g. home from one side,
//! then shift the reference by b/2) and can tell the compensator which flank is in
//! contact with [`BacklashCompensator::reset`].
//!
//! **Limitation**: the compensation assumes that the load-side friction, not a steady
//! external load, decides which flank carries the load, so that the flank changes with
//! the direction of motion. Under a steady load larger than the load-side friction
//! (e.g. gravity on a leg) the same flank carries the load in both directions; then the
//! compensation is right in one direction and doubles the error in the other (plant
//! model, 20 N on each leg: 60 um RMS load error without compensation, 78..90 um with).
//! For such joints disable it and refer the homing to the loaded flank instead.
//!
//! Disabled at run time by [`BacklashParams::enabled`] (the offset ramps to 0, and back in
//! when re-enabled), or at build time by the cargo feature `backlash-off` (offset always 0).

use num_traits::Float;

use crate::checks::{is_leg, Check, ConfigError};
use crate::num::{bound, lit, max_of, valid_dt};
use crate::NUM_JOINTS;

/// How the offset is brought in after a reversal.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum BacklashRamp<S> {
    /// The full change of `b` is spread over this much setpoint travel, u (> 0).
    Distance(S),
    /// The full change of `b` is spread over this much time, s (> 0).
    Time(S),
    /// Whichever of the two is faster at the moment: the distance at high speed, the
    /// time near a smooth reversal where the setpoint barely moves (both > 0).
    DistanceOrTime {
        /// Setpoint travel for the full change, u.
        distance: S,
        /// Time for the full change, s.
        time: S,
    },
}

/// Backlash compensation of one joint (`u` = m for the legs, rad for the links).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BacklashParams<S> {
    /// Compensation on. Default `true`. When off the offset ramps to zero.
    pub enabled: bool,
    /// Total backlash `b`, u, finite and >= 0; the offset is `+-b/2`. Default legs
    /// 0.12e-3 m (mid-range of the thesis' 0.08..0.2 mm), links 20 arcsec = 9.7e-5 rad
    /// (thesis; about one encoder count, 8.7e-5 rad, so the effect there is marginal).
    pub width: S,
    /// Setpoint travel back from the furthest point needed to accept a reversal, u,
    /// finite and >= 0. Default legs 5e-6 m (~3 counts), links 5e-5 rad (~0.6 count,
    /// half the link backlash): above the setpoint noise of a teleoperated master, well
    /// below the leg backlash.
    pub hysteresis: S,
    /// Ramp of the offset. Default `DistanceOrTime { distance: b, time: 0.02 s }` (legs
    /// 0.12e-3 m, links 1e-4 rad): the full change of b takes at most 20 ms, and less at
    /// speed (motor at <= 2x the commanded speed). On the plant model (`sim/plant`,
    /// 1 kHz, 1..40 mm sine moves) this left 5..9 % of the uncompensated 60 um RMS load
    /// error; distance-only ramps of b/3..b left 7..20 % (slow near smooth reversals),
    /// a 10 ms time ramp was as accurate with higher current peaks; on the friction-only
    /// test plant (tests/backlash.rs) the distance part helps at sharp reversals.
    pub ramp: BacklashRamp<S>,
}

impl<S: Float> BacklashParams<S> {
    /// Default of a prismatic leg (see the field docs).
    pub fn leg() -> Self {
        BacklashParams {
            enabled: true,
            width: lit(0.12e-3),
            hysteresis: lit(5e-6),
            ramp: BacklashRamp::DistanceOrTime {
                distance: lit(0.12e-3),
                time: lit(0.02),
            },
        }
    }

    /// Default of a rotating link (see the field docs).
    pub fn link() -> Self {
        BacklashParams {
            enabled: true,
            width: lit(20.0 / 3600.0 * core::f64::consts::PI / 180.0),
            hysteresis: lit(5e-5),
            ramp: BacklashRamp::DistanceOrTime {
                distance: lit(1e-4),
                time: lit(0.02),
            },
        }
    }

    /// Compensation off (zero width).
    pub fn off() -> Self {
        BacklashParams {
            enabled: false,
            width: S::zero(),
            hysteresis: S::zero(),
            ramp: BacklashRamp::Time(S::one()),
        }
    }

    /// Checks every field of joint `joint`; the error names the first bad one.
    pub fn validate(&self, joint: usize) -> Result<(), ConfigError> {
        let c = Check {
            section: "backlash",
            joint,
        };
        c.non_negative("width", self.width)?;
        c.non_negative("hysteresis", self.hysteresis)?;
        match self.ramp {
            BacklashRamp::Distance(d) => c.positive("ramp.distance", d),
            BacklashRamp::Time(t) => c.positive("ramp.time", t),
            BacklashRamp::DistanceOrTime { distance, time } => {
                c.positive("ramp.distance", distance)?;
                c.positive("ramp.time", time)
            }
        }
    }
}

/// Backlash compensation of the six joints.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BacklashConfig<S> {
    /// Per joint, joint order. Default [`BacklashParams::leg`] x3, [`BacklashParams::link`] x3.
    pub joints: [BacklashParams<S>; NUM_JOINTS],
}

impl<S: Float> Default for BacklashConfig<S> {
    fn default() -> Self {
        let mut joints = [BacklashParams::leg(); NUM_JOINTS];
        for (j, p) in joints.iter_mut().enumerate() {
            if !is_leg(j) {
                *p = BacklashParams::link();
            }
        }
        BacklashConfig { joints }
    }
}

impl<S: Float> BacklashConfig<S> {
    /// Every joint off.
    pub fn off() -> Self {
        BacklashConfig {
            joints: [BacklashParams::off(); NUM_JOINTS],
        }
    }

    /// Checks every joint; the error names the first bad field and its joint.
    pub fn validate(&self) -> Result<(), ConfigError> {
        for (j, p) in self.joints.iter().enumerate() {
            p.validate(j)?;
        }
        Ok(())
    }
}

/// Direction of the commanded motion (which flank the motor should push on).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Direction {
    /// Not known yet (no motion beyond the hysteresis since reset): offset 0.
    Unknown,
    /// Towards `+q`: offset `+b/2`.
    Positive,
    /// Towards `-q`: offset `-b/2`.
    Negative,
}

impl Direction {
    /// The direction a signed quantity points (`Unknown` for zero or NaN).
    pub fn of_sign<S: Float>(x: S) -> Self {
        if x > S::zero() {
            Direction::Positive
        } else if x < S::zero() {
            Direction::Negative
        } else {
            Direction::Unknown
        }
    }

    fn sign<S: Float>(self) -> S {
        match self {
            Direction::Unknown => S::zero(),
            Direction::Positive => S::one(),
            Direction::Negative => -S::one(),
        }
    }
}

/// The compensator's result for one sample.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BacklashOutput<S> {
    /// Offset to add to the position setpoint, u.
    pub offset: S,
    /// Rate of change of the offset over the sample, u/s (add to the desired velocity).
    pub offset_rate: S,
}

/// Backlash compensator state of one joint.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BacklashCompensator<S> {
    params: BacklashParams<S>,
    direction: Direction,
    /// Furthest setpoint in the current direction (the start point while Unknown).
    extreme: S,
    last_setpoint: S,
    offset: S,
    primed: bool,
    /// The flank imposed by a steady external load (Unknown: none, follow the motion).
    preload: Direction,
    /// `b/2` of the sanitized width (0 for a NaN, infinite or negative width), prepared
    /// with the parameters so that a sample only compares and multiplies.
    half: S,
    /// The sanitized hysteresis (0 for NaN, infinite or negative).
    hysteresis: S,
}

impl<S: Float> BacklashCompensator<S> {
    /// A compensator with direction unknown and offset 0; the first update takes its
    /// setpoint as the start point.
    pub fn new(params: BacklashParams<S>) -> Self {
        BacklashCompensator {
            params,
            direction: Direction::Unknown,
            extreme: S::zero(),
            last_setpoint: S::zero(),
            offset: S::zero(),
            primed: false,
            preload: Direction::Unknown,
            half: sane_half_width(params.width),
            hysteresis: sane_hysteresis(params.hysteresis),
        }
    }

    /// Imposes the flank in contact from a steady external load: when the load the motor
    /// must hold exceeds the friction, the motor pushes the same way whichever way it moves
    /// (a leg carrying the tool's weight rests on one flank both up and down), so the
    /// offset follows the load, not the motion. `Direction::Unknown` returns to the
    /// direction of motion. The offset ramps as usual.
    pub fn set_preload(&mut self, direction: Direction) {
        self.preload = direction;
    }

    /// The parameters.
    pub fn params(&self) -> &BacklashParams<S> {
        &self.params
    }

    /// Replaces the parameters; the offset ramps to the new target (no jump).
    pub fn set_params(&mut self, params: BacklashParams<S>) {
        self.params = params;
        self.half = sane_half_width(params.width);
        self.hysteresis = sane_hysteresis(params.hysteresis);
    }

    /// Restarts at `setpoint` with the gap known to be taken up in `direction` (e.g. after
    /// homing against a flank): the offset is set to its full value at once, since the
    /// motor is already at that flank. `Direction::Unknown` gives offset 0.
    pub fn reset(&mut self, setpoint: S, direction: Direction) {
        self.direction = direction;
        self.offset = if self.active() {
            direction.sign::<S>() * self.half_width()
        } else {
            S::zero()
        };
        if setpoint.is_finite() {
            self.extreme = setpoint;
            self.last_setpoint = setpoint;
            self.primed = true;
        } else {
            self.primed = false;
        }
    }

    /// Restarts at `setpoint` with the motor `offset` (u) beyond it, as a previous
    /// compensator of this joint left it (the motors were off since, held by the brakes:
    /// the gap has not changed): the direction is the offset's sign (unknown for 0), the
    /// offset is kept, so that the motor setpoint `setpoint + offset` is where the motor
    /// stands and nothing moves. A non-finite offset counts as 0; one beyond `b/2` (the
    /// width changed since) ramps back to `+-b/2` as usual.
    pub fn resume(&mut self, setpoint: S, offset: S) {
        let offset = if offset.is_finite() {
            offset
        } else {
            S::zero()
        };
        self.reset(setpoint, Direction::of_sign(offset));
        self.offset = offset;
    }

    /// The offset of a gap fully taken up in `direction`: `+-b/2`, 0 for `Unknown` or
    /// with the compensation off.
    pub fn flank_offset(&self, direction: Direction) -> S {
        if self.active() {
            direction.sign::<S>() * self.half_width()
        } else {
            S::zero()
        }
    }

    /// The current direction of the commanded motion.
    pub fn direction(&self) -> Direction {
        self.direction
    }

    /// The current offset, u.
    pub fn offset(&self) -> S {
        self.offset
    }

    fn active(&self) -> bool {
        self.params.enabled && !cfg!(feature = "backlash-off")
    }

    fn half_width(&self) -> S {
        self.half
    }

    /// One sample: follows the setpoint `setpoint` (u) over `dt` (s) and returns the
    /// offset to add to it. A non-finite setpoint or invalid `dt` leaves the state as it
    /// is and returns the current offset with rate 0.
    pub fn update(&mut self, setpoint: S, dt: S) -> BacklashOutput<S> {
        if !setpoint.is_finite() || !valid_dt(dt) {
            return BacklashOutput {
                offset: self.offset,
                offset_rate: S::zero(),
            };
        }
        self.update_checked(setpoint, dt)
    }

    /// [`update`](Self::update) of a finite `setpoint` and a valid `dt` (as
    /// [`JointServo`](crate::JointServo) makes sure).
    #[inline(always)]
    pub(crate) fn update_checked(&mut self, setpoint: S, dt: S) -> BacklashOutput<S> {
        if !self.primed {
            self.extreme = setpoint;
            self.last_setpoint = setpoint;
            self.primed = true;
        }
        let h = self.hysteresis;

        // Direction with hysteresis: `extreme` is the furthest setpoint in the current
        // direction; a return by more than h from it reverses the direction.
        match self.direction {
            Direction::Positive => {
                if setpoint > self.extreme {
                    self.extreme = setpoint;
                } else if setpoint < self.extreme - h {
                    self.direction = Direction::Negative;
                    self.extreme = setpoint;
                }
            }
            Direction::Negative => {
                if setpoint < self.extreme {
                    self.extreme = setpoint;
                } else if setpoint > self.extreme + h {
                    self.direction = Direction::Positive;
                    self.extreme = setpoint;
                }
            }
            Direction::Unknown => {
                if setpoint > self.extreme + h {
                    self.direction = Direction::Positive;
                    self.extreme = setpoint;
                } else if setpoint < self.extreme - h {
                    self.direction = Direction::Negative;
                    self.extreme = setpoint;
                }
            }
        }

        // Target offset: +-b/2 by the flank in contact (the load's when one is imposed,
        // else the motion's; 0 when off or unknown).
        let flank = if self.preload == Direction::Unknown {
            self.direction
        } else {
            self.preload
        };
        let target = if self.active() {
            flank.sign::<S>() * self.half_width()
        } else {
            S::zero()
        };
        let old = self.offset;
        let gap = target - old;
        // Towards the target by at most the ramp's step. At the target (where the offset
        // stays but for a ramp after a reversal) the step is 0 whatever its limit, which
        // is then not computed. (`bound`, not the NaN-safe `clamp_sym`: the differences
        // of finite values and their quotient by a finite `dt > 0` cannot be NaN.)
        let step = if gap == S::zero() {
            gap
        } else {
            bound(gap, self.max_step(setpoint, dt))
        };
        self.offset = old + step;
        self.last_setpoint = setpoint;
        BacklashOutput {
            offset: self.offset,
            offset_rate: bound((self.offset - old) / dt, S::max_value()),
        }
    }

    /// The largest change of the offset in a sample from `last_setpoint` to `setpoint`
    /// lasting `dt`: finite and `>= 0`.
    #[inline(always)]
    fn max_step(&self, setpoint: S, dt: S) -> S {
        // Largest change this sample: b per ramp distance of setpoint travel, or b per
        // ramp time (at least b/2 per ramp when b = 0 so a disabled joint still ramps out).
        // (Neither can be NaN: a plain comparison.)
        let full = self.half_width() * lit(2.0);
        let b = if self.offset.abs() > full {
            self.offset.abs()
        } else {
            full
        };
        let travel = (setpoint - self.last_setpoint).abs();
        let by_distance = |d: S| if d > S::zero() { b / d * travel } else { b };
        let by_time = |t: S| if t > S::zero() { b / t * dt } else { b };
        let max_step = match self.params.ramp {
            BacklashRamp::Distance(d) => by_distance(d),
            BacklashRamp::Time(t) => by_time(t),
            BacklashRamp::DistanceOrTime { distance, time } => {
                // The larger, or the time's when the distance's is NaN (`b / d` infinite
                // and no travel); the time's cannot be NaN (`dt > 0`), so one comparison
                // does what `max_of` does.
                let (d, t) = (by_distance(distance), by_time(time));
                if d >= t {
                    d
                } else {
                    t
                }
            }
        };
        if max_step.is_finite() {
            max_step
        } else {
            b
        }
    }
}

/// `b/2` for a finite width `b > 0`, else 0.
fn sane_half_width<S: Float>(b: S) -> S {
    if b.is_finite() && b > S::zero() {
        b * lit(0.5)
    } else {
        S::zero()
    }
}

/// The hysteresis when finite and `>= 0`, else 0.
fn sane_hysteresis<S: Float>(h: S) -> S {
    if h.is_finite() {
        max_of(h, S::zero())
    } else {
        S::zero()
    }
}
