//! Tracking-error (following-error) monitor per joint, as industrial drives have, with a
//! stuck-encoder / no-motion check. Faults latch until [`TrackingMonitor::reset`].
//!
//! * **Following error**: `|setpoint - measured| > window` continuously for longer than
//!   `time_to_fault` (the durations are sums of the sample times; the comparisons allow
//!   half a sample for rounding, so with 1 ms samples and 50 ms the 51st sample trips).
//! * **No motion**: the servo drives hard in the direction of a commanded motion
//!   (`|r_dot| >= stuck_min_speed`, `|duty| >= stuck_duty`, duty and `r_dot` of the same
//!   sign, same direction throughout) while the measured position makes no more than
//!   `stuck_motion` of progress in the commanded direction for longer than `stuck_time`.
//!   A frozen encoder, a disconnected motor (also one that sinks backwards under a load)
//!   or a jammed joint trips it, usually well before the following-error window is
//!   exceeded. Progress beyond `stuck_motion` restarts the timer.

use core::fmt;

use num_traits::Float;

use crate::checks::{is_leg, Check, ConfigError};
use crate::num::{lit, sign, valid_dt};
use crate::{joint_name, NUM_JOINTS};

/// What tripped.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FaultKind {
    /// `|setpoint - measured|` stayed above the window for longer than the time to fault.
    FollowingError,
    /// High duty towards a commanded motion without measured motion (stuck encoder,
    /// disconnected motor, jammed joint).
    NoMotion,
    /// A setpoint, desired velocity/acceleration or measurement was NaN or infinite.
    NonFiniteInput,
    /// The sample time was not finite and > 0 (not tied to a joint).
    InvalidTimeStep,
}

impl FaultKind {
    /// A short name for logs.
    pub fn name(self) -> &'static str {
        match self {
            FaultKind::FollowingError => "following error",
            FaultKind::NoMotion => "no motion (stuck encoder or motor)",
            FaultKind::NonFiniteInput => "non-finite input",
            FaultKind::InvalidTimeStep => "invalid time step",
        }
    }
}

/// A latched servo fault.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrackingFault<S> {
    /// What tripped.
    pub kind: FaultKind,
    /// The joint (0..6, joint order); `None` only for [`FaultKind::InvalidTimeStep`].
    pub joint: Option<usize>,
    /// `setpoint - measured` when it tripped, u (m or rad); 0 if not finite.
    pub error: S,
    /// How long the condition had lasted when it tripped, s (0 for input faults).
    pub duration: S,
    /// Servo time when it tripped, us since the servo was created (sum of the `dt`s).
    pub time_us: u64,
}

impl<S: Float + fmt::Display> fmt::Display for TrackingFault<S> {
    /// E.g. `following error on joint 1 (l2): error -0.001200 m for 0.0510 s at t = 1050000 us`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let unit = match self.joint {
            Some(j) => {
                write!(f, "{} on joint {} ({})", self.kind.name(), j, joint_name(j))?;
                if is_leg(j) {
                    "m"
                } else {
                    "rad"
                }
            }
            None => {
                write!(f, "{}", self.kind.name())?;
                ""
            }
        };
        write!(
            f,
            ": error {:.6} {} for {:.4} s at t = {} us",
            self.error, unit, self.duration, self.time_us
        )
    }
}

/// Tracking limits of one joint (`u` = m for the legs, rad for the links).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrackingLimits<S> {
    /// Following-error window, u, finite and > 0. Default legs 1e-3 m, links 0.02 rad
    /// (~1.1 deg). With velocity feed-forward the error at full speed stays well below
    /// (~0.1 mm on the legs), so only a real failure leaves the window.
    pub window: S,
    /// How long the error must stay outside the window to fault, s, finite and >= 0.
    /// Default 0.05 s (50 samples at 1 kHz): rides through a short disturbance.
    pub time_to_fault: S,
    /// |duty| at or above which the no-motion check runs, in (0, 1]. Default 0.05: below
    /// the largest duty the current limit allows at stall (0.076 on the legs, 0.06 on the
    /// links: the rated efforts), at 66 % and 83 % of the rated efforts at stall, above the
    /// tool's holding duty (< 0.04); a healthy joint at 0.05 duty from rest runs at 19 mm/s
    /// or 1.4 rad/s free, and makes `stuck_motion` of progress within a few ms.
    pub stuck_duty: S,
    /// |desired velocity| at or above which the no-motion check runs, u/s, finite and
    /// > 0. Default legs 2e-3 m/s, links 0.02 rad/s.
    pub stuck_min_speed: S,
    /// Measured progress in the commanded direction that counts as "moving", u, finite
    /// and > 0. Default legs 15e-6 m
    /// (10 counts), links 1e-3 rad (~11 counts).
    pub stuck_motion: S,
    /// How long the joint may be driven hard without moving before it faults, s, finite
    /// and >= 0. Default 0.02 s: a healthy joint driven at 0.15 duty from rest makes
    /// `stuck_motion` of progress in ~2 ms (legs) / ~3 ms (links) (mechanical time
    /// constants 6 and 15 ms), and 0.15 duty at stall is ~440 N on a leg and ~1.3 N m on
    /// a link, far beyond any task force; meanwhile a frozen encoder lets the motor run
    /// away (on the plant model a leg ran ~3 mm in 30 ms), so this is kept short.
    pub stuck_time: S,
}

impl<S: Float> TrackingLimits<S> {
    /// Default of a prismatic leg (see the field docs).
    pub fn leg() -> Self {
        TrackingLimits {
            window: lit(1e-3),
            time_to_fault: lit(0.05),
            stuck_duty: lit(0.05),
            stuck_min_speed: lit(2e-3),
            stuck_motion: lit(15e-6),
            stuck_time: lit(0.02),
        }
    }

    /// Default of a rotating link (see the field docs).
    pub fn link() -> Self {
        TrackingLimits {
            window: lit(0.02),
            time_to_fault: lit(0.05),
            stuck_duty: lit(0.05),
            stuck_min_speed: lit(0.02),
            stuck_motion: lit(1e-3),
            stuck_time: lit(0.02),
        }
    }

    /// Checks every field of joint `joint`; the error names the first bad one.
    pub fn validate(&self, joint: usize) -> Result<(), ConfigError> {
        let c = Check {
            section: "tracking",
            joint,
        };
        c.positive("window", self.window)?;
        c.non_negative("time_to_fault", self.time_to_fault)?;
        c.unit_fraction("stuck_duty", self.stuck_duty)?;
        c.positive("stuck_min_speed", self.stuck_min_speed)?;
        c.positive("stuck_motion", self.stuck_motion)?;
        c.non_negative("stuck_time", self.stuck_time)
    }
}

/// Tracking limits of the six joints.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrackingConfig<S> {
    /// Per joint, joint order. Default [`TrackingLimits::leg`] x3, [`TrackingLimits::link`] x3.
    pub joints: [TrackingLimits<S>; NUM_JOINTS],
}

impl<S: Float> Default for TrackingConfig<S> {
    fn default() -> Self {
        let mut joints = [TrackingLimits::leg(); NUM_JOINTS];
        for (j, l) in joints.iter_mut().enumerate() {
            if !is_leg(j) {
                *l = TrackingLimits::link();
            }
        }
        TrackingConfig { joints }
    }
}

impl<S: Float> TrackingConfig<S> {
    /// Checks every joint; the error names the first bad field and its joint.
    pub fn validate(&self) -> Result<(), ConfigError> {
        for (j, l) in self.joints.iter().enumerate() {
            l.validate(j)?;
        }
        Ok(())
    }
}

/// One sample's input to the monitor.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrackingSample<S> {
    /// Position setpoint the loop tracks (after backlash compensation), u.
    pub setpoint: S,
    /// Desired velocity, u/s.
    pub setpoint_velocity: S,
    /// Measured position, u.
    pub measured: S,
    /// Duty commanded in this sample.
    pub duty: S,
}

/// Tracking monitor state of one joint.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrackingMonitor<S> {
    limits: TrackingLimits<S>,
    joint: usize,
    /// Time the error has been outside the window, s.
    over_window_for: S,
    /// Time of hard drive without motion, s.
    stuck_for: S,
    /// Measured position when the no-motion timer (re)started, u.
    stuck_ref: S,
    /// Direction of the commanded motion being timed (+1/-1), 0 when not timing.
    stuck_dir: S,
    latched: Option<TrackingFault<S>>,
}

impl<S: Float> TrackingMonitor<S> {
    /// A monitor of joint `joint` (the index reported in its faults).
    pub fn new(joint: usize, limits: TrackingLimits<S>) -> Self {
        TrackingMonitor {
            limits,
            joint,
            over_window_for: S::zero(),
            stuck_for: S::zero(),
            stuck_ref: S::zero(),
            stuck_dir: S::zero(),
            latched: None,
        }
    }

    /// The limits.
    pub fn limits(&self) -> &TrackingLimits<S> {
        &self.limits
    }

    /// Replaces the limits (timers kept).
    pub fn set_limits(&mut self, limits: TrackingLimits<S>) {
        self.limits = limits;
    }

    /// The latched fault, if any.
    pub fn fault(&self) -> Option<TrackingFault<S>> {
        self.latched
    }

    /// Clears the latched fault and the timers.
    pub fn reset(&mut self) {
        self.latched = None;
        self.over_window_for = S::zero();
        self.stuck_for = S::zero();
        self.stuck_dir = S::zero();
    }

    /// Latches `fault` (if nothing is latched yet) and returns the latched fault.
    pub fn latch(&mut self, fault: TrackingFault<S>) -> TrackingFault<S> {
        *self.latched.get_or_insert(fault)
    }

    /// One sample of duration `dt` (s) ending at servo time `time_us`. Returns the
    /// latched fault, if any (a new one or an earlier one). Non-finite values or an
    /// invalid `dt` latch [`FaultKind::NonFiniteInput`] / [`FaultKind::InvalidTimeStep`].
    pub fn update(
        &mut self,
        s: &TrackingSample<S>,
        dt: S,
        time_us: u64,
    ) -> Option<TrackingFault<S>> {
        if self.latched.is_some() {
            return self.latched;
        }
        let zero = S::zero();
        if !valid_dt(dt) {
            return Some(self.latch(TrackingFault {
                kind: FaultKind::InvalidTimeStep,
                joint: None,
                error: zero,
                duration: zero,
                time_us,
            }));
        }
        if !(s.setpoint_velocity.is_finite() && s.duty.is_finite()) {
            return Some(self.latch(self.non_finite(time_us)));
        }
        if self.update_checked(s, dt, time_us) {
            self.latched
        } else {
            None
        }
    }

    /// The fault of a non-finite sample at servo time `time_us`.
    fn non_finite(&self, time_us: u64) -> TrackingFault<S> {
        TrackingFault {
            kind: FaultKind::NonFiniteInput,
            joint: Some(self.joint),
            error: S::zero(),
            duration: S::zero(),
            time_us,
        }
    }

    /// [`update`](Self::update) of a sample whose `dt` is valid and whose desired
    /// velocity and duty are finite (as [`JointServo`](crate::JointServo) makes sure);
    /// returns whether a fault is latched (then [`fault`](Self::fault) is it), so that
    /// no fault is copied out when nothing trips.
    #[inline(always)]
    pub(crate) fn update_checked(&mut self, s: &TrackingSample<S>, dt: S, time_us: u64) -> bool {
        if self.latched.is_some() {
            return true;
        }
        let zero = S::zero();
        let error = s.setpoint - s.measured;
        if !error.is_finite() {
            self.latch(self.non_finite(time_us));
            return true;
        }
        let l = &self.limits;
        // "Longer than" with half a sample of margin against rounding in the sums of dt.
        let half_dt = dt * lit(0.5);

        // Following error: outside the window continuously for longer than time_to_fault.
        if error.abs() > l.window {
            self.over_window_for = self.over_window_for + dt;
            if self.over_window_for > l.time_to_fault + half_dt {
                self.latch(TrackingFault {
                    kind: FaultKind::FollowingError,
                    joint: Some(self.joint),
                    error,
                    duration: self.over_window_for,
                    time_us,
                });
                return true;
            }
        } else {
            self.over_window_for = zero;
        }

        // No motion: driving hard towards a commanded motion (same direction throughout)
        // while the measurement stays within stuck_motion of where the timer started.
        let suspect = s.setpoint_velocity.abs() >= l.stuck_min_speed
            && s.duty.abs() >= l.stuck_duty
            && sign(s.duty) == sign(s.setpoint_velocity);
        let dir = sign(s.setpoint_velocity);
        if !suspect {
            self.stuck_dir = zero;
            self.stuck_for = zero;
        } else if self.stuck_dir != dir || (s.measured - self.stuck_ref) * dir > l.stuck_motion {
            // Start timing (or restart: the direction changed, or the joint made progress
            // in the commanded direction; motion the other way is no progress).
            self.stuck_dir = dir;
            self.stuck_ref = s.measured;
            self.stuck_for = zero;
        } else {
            self.stuck_for = self.stuck_for + dt;
            if self.stuck_for > l.stuck_time + half_dt {
                self.latch(TrackingFault {
                    kind: FaultKind::NoMotion,
                    joint: Some(self.joint),
                    error,
                    duration: self.stuck_for,
                    time_us,
                });
                return true;
            }
        }
        false
    }
}
