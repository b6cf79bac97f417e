//! The supervisor's settings, their checks, and why a supervisor cannot start.

use crate::guards::{GuardSetupError, Reading, MAX_STAGES};
use crate::scalar::{lit, to_f64, Real};
use core::fmt;

/// Supervisor settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SupervisorConfig<T: Real> {
    /// Control period, s (default 1 ms; 0.1 ms .. 100 ms).
    pub dt: T,
    /// Targets older than this relative to the clock are stale, µs (default 100 ms).
    pub stale_after_us: u64,
    /// Spacing of the path-check samples in translation, m (default 0.5 mm).
    pub path_step: T,
    /// Spacing of the path-check samples in rotation, rad (default 0.5 deg).
    pub path_step_angle: T,
    /// Stages of the full guard evaluations run per tick (default 1: the least work per
    /// tick; 1 ..= [`MAX_STAGES`]). A full evaluation is five stages when the SVD starts
    /// warm, at most [`MAX_STAGES`]; the largest (the inverse kinematics with the kinematic
    /// guards, or one sweep of the SVD) costs 2,000 to 4,000 instructions on the
    /// Cortex-M4. At control rates well below 1 kHz more stages per tick keep the path
    /// check up with the master's stream (e.g. 5, about one full evaluation per tick, at
    /// 250 Hz).
    pub stages_per_tick: u16,
    /// Targets farther than this from the setpoint are refused outright, m (default 60 mm).
    pub max_segment: T,
    /// ... or rotated farther than this, rad (default 45 deg).
    pub max_segment_angle: T,
    /// Fraction of each joint speed limit the motion may use (default 0.8).
    pub joint_speed_headroom: T,
    /// Fraction of each joint acceleration limit the motion may use (default 0.8): the
    /// Cartesian accelerations are scaled down where J would turn them into more.
    pub joint_accel_headroom: T,
    /// Lead the master's stream (default on, see [`super::lead`]): a target is led along the
    /// stream's path by the braking curve's distance when the led segment lies in a
    /// certified region, so the robot is on the master's pose rather than 54 ms behind it
    /// at 25 mm/s; a stream that stops abruptly is overshot by up to that distance (inside
    /// the certified region) before the robot goes back to its last pose.
    pub lead: bool,
}

impl<T: Real> Default for SupervisorConfig<T> {
    fn default() -> Self {
        SupervisorConfig {
            dt: lit(1e-3),
            stale_after_us: 100_000,
            path_step: lit(0.5e-3),
            path_step_angle: lit(0.5f64.to_radians()),
            stages_per_tick: 1,
            max_segment: lit(0.060),
            max_segment_angle: lit(45f64.to_radians()),
            joint_speed_headroom: lit(0.8),
            joint_accel_headroom: lit(0.8),
            lead: true,
        }
    }
}

impl<T: Real> SupervisorConfig<T> {
    /// Checks every setting against its range (see the fields).
    pub(super) fn validate(&self) -> Result<(), SupervisorError<T>> {
        let pos = |x: T| x > T::zero() && x.is_finite();
        let fail = |s| Err(SupervisorError::Config(s));
        if !(pos(self.dt) && self.dt >= lit(1e-4) && self.dt <= lit(0.1)) {
            return fail("dt must be within 0.1 .. 100 ms");
        }
        if !(pos(self.path_step) && pos(self.path_step_angle)) {
            return fail("path steps must be positive");
        }
        if !(pos(self.max_segment) && pos(self.max_segment_angle)) {
            return fail("max segment must be positive");
        }
        if !(1..=MAX_STAGES).contains(&u32::from(self.stages_per_tick)) {
            return fail("stages_per_tick must be within 1 ..= 13 (MAX_STAGES)");
        }
        let n =
            (self.max_segment / self.path_step).max(self.max_segment_angle / self.path_step_angle);
        if !(n <= lit(4096.0)) {
            return fail("max segment / path step exceeds 4096 samples");
        }
        if !(pos(self.joint_speed_headroom) && self.joint_speed_headroom <= T::one()) {
            return fail("joint_speed_headroom must be in (0, 1]");
        }
        if !(pos(self.joint_accel_headroom) && self.joint_accel_headroom <= T::one()) {
            return fail("joint_accel_headroom must be in (0, 1]");
        }
        Ok(())
    }

    /// The control period, µs (rounded).
    pub(super) fn dt_us(&self) -> u64 {
        (to_f64(self.dt * lit(1e6)) + 0.5) as u64
    }
}

/// Why the supervisor cannot start.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SupervisorError<T: Real> {
    Setup(GuardSetupError),
    Config(&'static str),
    /// The start pose violates a stop-level guard.
    UnsafeStart(Option<Reading<T>>),
}

impl<T: Real> fmt::Display for SupervisorError<T> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SupervisorError::Setup(e) => write!(f, "{e}"),
            SupervisorError::Config(s) => write!(f, "supervisor config: {s}"),
            SupervisorError::UnsafeStart(Some(r)) => {
                write!(f, "start pose violates {} ({})", r.guard, r.subject)
            }
            SupervisorError::UnsafeStart(None) => f.write_str("start pose is unsafe"),
        }
    }
}
