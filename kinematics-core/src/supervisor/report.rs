//! What the supervisor reports: the output of each tick with its mode, the singularity
//! margins near the setpoint, why a target was refused, and the counters of what it
//! refused or did.

use crate::guards::{Guard, Reading};
use crate::pose::Pose;
use crate::scalar::{to_f64, Real};
use crate::vectors::{Joints, Twist};
use core::fmt;

/// What the supervisor is doing, as reported with each tick.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mode {
    /// At the goal, nothing to do.
    Holding,
    /// A target is being verified (the robot keeps moving to its previous goal).
    Verifying,
    /// Moving towards the goal.
    Moving,
    /// Braking to a stop because the path ahead is unsafe.
    Braking,
    /// Stopped by a stop-level violation; latched until cleared.
    Stopped,
}

/// What one tick produces.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TickOutput<T: Real> {
    /// The setpoint pose.
    pub pose: Pose<T>,
    /// The joint setpoints.
    pub q: Joints<T>,
    /// Joint velocity feed-forward J · twist.
    pub qdot: Joints<T>,
    /// The setpoint's twist [v; ω].
    pub twist: Twist<T>,
    /// The state.
    pub mode: Mode,
    /// A warn-level guard is violated at the setpoint.
    pub warning: bool,
    /// Which: the first kinematic guard of the setpoint's own solution between its warn
    /// and stop levels, else the parallel measure or a payload effort at its warn level at
    /// the last braking point checked (those need a full evaluation, which the setpoint
    /// does not get).
    pub warn_guard: Option<Guard>,
    /// The latched stop reason, if stopped.
    pub stop: Option<Reading<T>>,
}

/// The singularity margins near the setpoint, for telemetry, from what the ticks computed
/// (no inverse kinematics or SVD of their own).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Margins<T: Real> {
    /// The smallest dimensionless serial measure of the setpoint's chains (Eq. 10.6 /
    /// 10.11, from the setpoint's inverse-kinematics solution).
    pub serial: T,
    /// The parallel inverse condition number of the last full evaluation (a path sample
    /// or braking point checked for the motion around the setpoint, or the start pose).
    pub parallel: T,
}

/// Why a target was refused. A reading in a refusal is as people read it
/// ([`crate::guards::Guards::in_world`]: a workspace reading gives the platform centre's
/// coordinate and the face of the box it crossed).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Refusal<T: Real> {
    /// A component is NaN or infinite.
    NonFinite,
    /// The timestamp is older than `stale_after_us` (or from the future by as much).
    Stale { age_us: i64 },
    /// The timestamp is not newer than the last accepted one.
    OutOfOrder,
    /// Too far from the current setpoint (m, rad). `breaks` is the first stop-level
    /// kinematic guard the target itself breaks (workspace, reach, joint ranges, tilt,
    /// collision, serial singularity), if any: the rule to name before the distance.
    TooFar {
        distance: T,
        angle: T,
        breaks: Option<Reading<T>>,
    },
    /// The straight path to the target stamped `stamp_us` crosses a stop-level region at
    /// this fraction of the way (1: the target itself, checked first).
    Path {
        fraction: T,
        reading: Reading<T>,
        stamp_us: u64,
    },
    /// The supervisor is stopped; clear it first.
    Latched,
}

impl<T: Real> fmt::Display for Refusal<T> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Refusal::NonFinite => f.write_str("target is not finite"),
            Refusal::Stale { age_us } => write!(f, "target is stale ({age_us} µs old)"),
            Refusal::OutOfOrder => f.write_str("target timestamp is not newer than the last"),
            Refusal::TooFar {
                breaks: Some(reading),
                ..
            } => write!(f, "target breaks {}", reading.guard),
            Refusal::TooFar {
                distance, angle, ..
            } => write!(
                f,
                "target too far from the setpoint ({:.1} mm, {:.1} deg)",
                to_f64(*distance) * 1e3,
                to_f64(*angle).to_degrees()
            ),
            Refusal::Path {
                fraction, reading, ..
            } => write!(
                f,
                "path crosses {} at {:.0}% of the way",
                reading.guard,
                to_f64(*fraction) * 100.0
            ),
            Refusal::Latched => f.write_str("supervisor is stopped; clear the fault first"),
        }
    }
}

/// Counts of what the supervisor refused or did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Counters {
    pub accepted: u32,
    pub non_finite: u32,
    pub stale: u32,
    pub out_of_order: u32,
    pub too_far: u32,
    pub path_refused: u32,
    pub refused_latched: u32,
    pub superseded: u32,
    /// Targets accepted at once because their whole segment lies in a certified region
    /// (also counted in `accepted`).
    pub certified: u32,
    /// Braking-point checks answered by a certified region instead of a full evaluation.
    pub ahead_certified: u32,
    /// Targets accepted led along the master's stream (of `accepted`; see [`super::lead`]).
    pub led: u32,
    /// Led targets whose path check failed: the lead paused and the master's own target
    /// was verified instead (not a refusal).
    pub lead_dropped: u32,
    pub brakes: u32,
    pub stops: u32,
    pub warn_ticks: u32,
    /// Ticks whose step was scaled down to keep the joints within their speed and
    /// acceleration limits ([`super::profile::step_scales`]: J̇·twist near a serial
    /// singularity, which the Cartesian profile does not see).
    pub slowed: u32,
    /// Steps that found the evaluation phase had not run since the step before (a
    /// scheduling fault): a moving robot brakes on the stretch checked before.
    pub evaluations_missed: u32,
    /// Kinematic checks of a setpoint (the candidate, a rescaled step, the goal on
    /// arrival) answered inside a certified region ([`crate::guards::Guards::solve_certified`]).
    pub setpoints_certified: u32,
}

impl Counters {
    /// Every target refused, whatever the reason (saturating).
    pub fn refused(&self) -> u32 {
        [
            self.non_finite,
            self.stale,
            self.out_of_order,
            self.too_far,
            self.path_refused,
            self.refused_latched,
        ]
        .iter()
        .fold(0u32, |acc, x| acc.saturating_add(*x))
    }
}
