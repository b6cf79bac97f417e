//! The vocabulary of the guards: which guard, about what, how serious, with the value,
//! the limit and the signed margin.

use crate::chain::Chain;
use crate::scalar::Real;
use core::fmt;

use super::limits::Levels;

/// How serious a violation is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Severity {
    /// Continue, but raise the warning flag (e.g. approaching a singularity).
    Warn,
    /// Refuse the setpoint: hold the last safe one.
    Stop,
}

impl fmt::Display for Severity {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Severity::Warn => "warn",
            Severity::Stop => "stop",
        })
    }
}

/// The guards, by name.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Guard {
    /// The pose has no inverse-kinematics solution on the branch.
    Reach,
    /// Prismatic stroke (RSPR l_i), m.
    Stroke,
    /// Rotating-link angle θ_i (RSPR) away from its central value, rad.
    LinkAngle,
    /// Lower-link yaw α_i (USR) away from its central value, rad.
    Yaw,
    /// Lower-link pitch β_i (USR) away from its central value, rad.
    Pitch,
    /// Spherical-joint tilt, rad (CONVENTIONS.md).
    Tilt,
    /// Piercing radius of the leg axis in the plane of the central motors' tops, m (11.4).
    Collision,
    /// Distance of the platform centre outside the task box plus margin, m (per axis).
    Workspace,
    /// Platform tilt (angle between n and z0), rad.
    TiltCone,
    /// Serial singularity measure, dimensionless (Eq. 10.6 / 10.11).
    SerialSingularity,
    /// Parallel singularity measure: inverse condition number of scaled Jtilde.
    ParallelSingularity,
    /// Prismatic actuator force for the declared payload wrench, N.
    Force,
    /// Revolute actuator torque for the declared payload wrench, N m.
    Torque,
    /// Speed of o_p, m/s.
    TipSpeed,
    /// Angular speed of the platform, rad/s.
    AngularSpeed,
    /// Acceleration of o_p, m/s².
    TipAccel,
    /// Angular acceleration of the platform, rad/s².
    AngularAccel,
    /// Joint speed, m/s or rad/s.
    JointSpeed,
    /// Joint acceleration, m/s² or rad/s².
    JointAccel,
}

impl Guard {
    /// Every guard, in report order.
    pub const ALL: [Guard; 19] = [
        Guard::Reach,
        Guard::Stroke,
        Guard::LinkAngle,
        Guard::Yaw,
        Guard::Pitch,
        Guard::Tilt,
        Guard::Collision,
        Guard::Workspace,
        Guard::TiltCone,
        Guard::SerialSingularity,
        Guard::ParallelSingularity,
        Guard::Force,
        Guard::Torque,
        Guard::TipSpeed,
        Guard::AngularSpeed,
        Guard::TipAccel,
        Guard::AngularAccel,
        Guard::JointSpeed,
        Guard::JointAccel,
    ];

    /// The name used at the edges (`guard:chain:value:limit`).
    pub const fn name(self) -> &'static str {
        match self {
            Guard::Reach => "reach",
            Guard::Stroke => "stroke",
            Guard::LinkAngle => "link_angle",
            Guard::Yaw => "yaw",
            Guard::Pitch => "pitch",
            Guard::Tilt => "tilt",
            Guard::Collision => "collision",
            Guard::Workspace => "workspace",
            Guard::TiltCone => "tilt_cone",
            Guard::SerialSingularity => "serial",
            Guard::ParallelSingularity => "parallel",
            Guard::Force => "force",
            Guard::Torque => "torque",
            Guard::TipSpeed => "tip_speed",
            Guard::AngularSpeed => "angular_speed",
            Guard::TipAccel => "tip_accel",
            Guard::AngularAccel => "angular_accel",
            Guard::JointSpeed => "joint_speed",
            Guard::JointAccel => "joint_accel",
        }
    }

    /// Unit of the value in SI, and the factor and unit used at the edges (mm, deg).
    pub const fn edge_unit(self) -> (f64, &'static str) {
        const DEG: f64 = 180.0 / core::f64::consts::PI;
        match self {
            Guard::Reach | Guard::SerialSingularity | Guard::ParallelSingularity => (1.0, ""),
            Guard::Stroke | Guard::Collision | Guard::Workspace => (1e3, "mm"),
            Guard::LinkAngle | Guard::Yaw | Guard::Pitch | Guard::Tilt | Guard::TiltCone => {
                (DEG, "deg")
            }
            Guard::Force => (1.0, "N"),
            Guard::Torque => (1.0, "N m"),
            Guard::TipSpeed => (1e3, "mm/s"),
            Guard::AngularSpeed => (DEG, "deg/s"),
            Guard::TipAccel => (1e3, "mm/s^2"),
            Guard::AngularAccel => (DEG, "deg/s^2"),
            // Joint rates mix units; the edge uses mm/s for legs and deg/s for angles.
            Guard::JointSpeed | Guard::JointAccel => (1.0, "SI"),
        }
    }
}

impl fmt::Display for Guard {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// What a reading is about.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Subject {
    /// The whole robot or platform.
    Robot,
    /// One chain.
    Chain(Chain),
    /// One joint, 1..=6 in q order.
    Joint(u8),
    /// One world axis: 0 = x, 1 = y, 2 = z.
    Axis(u8),
}

impl fmt::Display for Subject {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Subject::Robot => f.write_str("-"),
            Subject::Chain(c) => write!(f, "{}", c.number()),
            Subject::Joint(j) => write!(f, "q{j}"),
            Subject::Axis(a) => f.write_str(match a {
                0 => "x",
                1 => "y",
                _ => "z",
            }),
        }
    }
}

/// One guard's measurement.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Reading<T: Real> {
    pub guard: Guard,
    pub subject: Subject,
    /// The measured value (SI).
    pub value: T,
    /// The limit it was compared with: the violated level, or the stop level when fine.
    pub limit: T,
    /// Signed distance to the stop level, positive inside (SI, the guard's unit).
    pub margin: T,
    /// `None` when fine.
    pub severity: Option<Severity>,
}

/// Most violations a single evaluation can produce (joint ranges, tilt, collision, forces
/// per chain or joint, plus the robot-wide guards, plus the motion guards).
pub const MAX_VIOLATIONS: usize = 48;

/// Every violation of one evaluation, not just the first.
#[derive(Clone, Debug, PartialEq)]
pub struct Verdict<T: Real> {
    /// The violations in evaluation order.
    pub violations: heapless::Vec<Reading<T>, MAX_VIOLATIONS>,
    /// Violations that did not fit (never expected; counted rather than lost silently).
    pub overflow: u16,
    /// The worst severity seen, including overflowed ones.
    pub worst: Option<Severity>,
}

impl<T: Real> Default for Verdict<T> {
    fn default() -> Self {
        Verdict {
            violations: heapless::Vec::new(),
            overflow: 0,
            worst: None,
        }
    }
}

impl<T: Real> Verdict<T> {
    /// Records a reading if it is a violation.
    pub fn record(&mut self, r: &Reading<T>) {
        if let Some(s) = r.severity {
            self.worst = self.worst.max(Some(s));
            if self.violations.push(*r).is_err() {
                self.overflow = self.overflow.saturating_add(1);
            }
        }
    }
    /// True when no guard is violated at all.
    pub fn is_ok(&self) -> bool {
        self.worst.is_none()
    }
    /// True when a stop-level guard is violated.
    pub fn is_stop(&self) -> bool {
        self.worst == Some(Severity::Stop)
    }
    /// The first stop-level violation, if any.
    pub fn first_stop(&self) -> Option<&Reading<T>> {
        self.violations
            .iter()
            .find(|r| r.severity == Some(Severity::Stop))
    }
}

/// A reading of `value` against warn and stop levels; a lower bound (the value must stay
/// ≥ the levels) or an upper bound (≤). A NaN value is always beyond the stop level.
pub(super) fn bounded<T: Real>(
    guard: Guard,
    subject: Subject,
    value: T,
    levels: Levels<T>,
    lower: bool,
) -> Reading<T> {
    let beyond = |level: T| {
        if lower {
            !(value >= level)
        } else {
            !(value <= level)
        }
    };
    let (severity, limit) = if beyond(levels.stop) {
        (Some(Severity::Stop), levels.stop)
    } else if beyond(levels.warn) {
        (Some(Severity::Warn), levels.warn)
    } else {
        (None, levels.stop)
    };
    Reading {
        guard,
        subject,
        value,
        limit,
        margin: if lower {
            value - levels.stop
        } else {
            levels.stop - value
        },
        severity,
    }
}

/// A lower-bound reading (value must stay ≥ the levels).
pub(super) fn lower<T: Real>(
    guard: Guard,
    subject: Subject,
    value: T,
    levels: Levels<T>,
) -> Reading<T> {
    bounded(guard, subject, value, levels, true)
}

/// An upper-bound reading (value must stay ≤ the levels).
pub(super) fn upper<T: Real>(
    guard: Guard,
    subject: Subject,
    value: T,
    levels: Levels<T>,
) -> Reading<T> {
    bounded(guard, subject, value, levels, false)
}

pub(super) fn stop_only<T: Real>(l: T) -> Levels<T> {
    Levels { warn: l, stop: l }
}

/// The stop-level reading of a chain that cannot reach the pose.
pub(super) fn unreachable<T: Real>(chain: Chain) -> Reading<T> {
    Reading {
        guard: Guard::Reach,
        subject: Subject::Chain(chain),
        value: T::zero(),
        limit: T::zero(),
        margin: -T::one(),
        severity: Some(Severity::Stop),
    }
}
