//! The setpoint supervisor: turns a stream of master targets (pose, timestamp) into joint
//! setpoints at the control rate, so that no setpoint ever violates a stop-level guard.
//!
//! Each control period has two phases, with constant bounded work in each:
//! - **the step** ([`Supervisor::step`], real time): the profile's step and, while moving,
//!   the kinematic guards and the Jacobian of the candidate setpoint; its output feeds the
//!   joint servos at once;
//! - **the evaluation** ([`Supervisor::evaluate`], after the outputs are written):
//!   `stages_per_tick` stages of a full guard evaluation (see [`Staged`]: the inverse
//!   kinematics with the kinematic guards, the Jacobians with the start of the parallel
//!   measure's SVD, one sweep of that SVD, or the payload statics), whose verdicts the next
//!   step acts on. A step that finds the evaluation did not run since the step before
//!   brakes ([`Counters::evaluations_missed`]): the braking points' horizon assumes it
//!   runs every period. [`Supervisor::tick`] is the two in that order.
//!
//! A full evaluation of a pose thus takes a few periods (five when the SVD starts warm, at
//! most [`MAX_STAGES`]). The checker works on one pose at a time, taking turns between the
//! pending path and the braking point; each kind of pose keeps its own warm-started SVD
//! ([`ConditionEstimator`]).
//! 1. **Verify** the pending target: the straight segment to it from whichever of the goal
//!    the robot is heading for (a verified target) and the setpoint is nearer is sampled at
//!    `path_step` / `path_step_angle`, the end point first; a stop-level violation
//!    anywhere refuses the target (the robot keeps its goal).
//! 2. **Move** towards the verified goal with a speed- and acceleration-limited profile in
//!    Cartesian space: speeds capped by the tip and angular speed limits and scaled down so
//!    that J·twist stays within the joint speed limits; the braking profile (discrete: the
//!    largest v with v·dt + v²/2a' ≤ d, a' 5 % under the braking deceleration) makes it
//!    stop at the goal. The Cartesian accelerations are scaled down where the Jacobian
//!    would turn them into more than the joints' acceleration limits.
//! 3. **Check**, in turn with the path samples, the braking point: where braking would stop
//!    if it began only when the check after this one has finished, the robot accelerating
//!    until then, but no farther than the goal (the bound is in `goal.rs`,
//!    `Supervisor::braking_point`). A target verified while moving replaces the goal once
//!    such a check has looked past the goal towards it. A stop-level violation there turns
//!    the motion into a controlled stop (full deceleration along the current twist on
//!    every tick) within the stretch the earlier braking points covered. The candidate
//!    setpoint itself gets the kinematic guards (reach, workspace, joint ranges, tilt,
//!    collision, serial singularity) every tick; it lies on the stretch the braking points
//!    (about 0.2 mm apart at 25 mm/s) and the path samples (0.5 mm apart) checked in full.
//!    A stop-level violation of the candidate holds the last safe setpoint and latches the
//!    reason until [`Supervisor::clear`].
//! 4. **Certified regions** ([`crate::guards::certificate`]): every full evaluation
//!    without a stop-level violation certifies a region around its pose (a Lipschitz bound
//!    of every stop-level guard's margin along straight motions); the newest two are kept.
//!    A target whose whole segment (from the same start as its path check) lies in one is
//!    accepted at once, without a path check, and a braking point whose whole stretch from
//!    the setpoint lies in one passes without an evaluation of its own: the region's
//!    guarantee covers every pose of those straight motions, not only samples of them.
//!    When no path or braking point waits, the checker evaluates the goal to certify the
//!    region around it, so the region follows the stream. A verified target waiting to
//!    replace the goal takes over as soon as the braking stretch towards it lies in a
//!    region: tried when it is accepted and after every evaluation phase, on the state the
//!    next step starts from. A setpoint inside a region is solved without the kinematic
//!    guards ([`Guards::solve_certified`]): the region's guarantee already covers them.
//!    Near a boundary the regions shrink and the staged checks above take over.
//! 5. **The lead** ([`lead`], [`SupervisorConfig::lead`]): the profile stops at its goal,
//!    so a goal moving at u is trailed by the braking curve's distance u²/2a' + u·dt (54 ms
//!    at 25 mm/s). Each target's translation is led by that distance along the stream's
//!    path (predicted to second order); the led target is verified like any other, and a
//!    led target whose path check fails pauses the lead (the master's own target is
//!    verified instead, no refusal). A stream that stops abruptly is overshot by up to the
//!    lead (onto verified poses) and the robot goes back to the master's last pose.
//!
//! What the supervisor is doing (following its goal, braking, stopped) is one value,
//! `Activity`, whose transitions are one table (`mode.rs`); the reported [`Mode`] adds
//! whether a target is being verified and whether the setpoint moves.
//!
//! The files, each one concept, in the order they build on each other (a file uses only
//! names of files above it, and calls only methods of files above it):
//! - vocabulary, no supervisor state: `config.rs` ([`SupervisorConfig`],
//!   [`SupervisorError`]), `report.rs` ([`TickOutput`], [`Mode`], [`Margins`],
//!   [`Refusal`], [`Counters`]), `mode.rs` (the activity and its transitions), [`profile`]
//!   (the motion profile, pure functions), [`lead`] (the stream's velocity and the led
//!   target), [`path`] (the segment to a target and its samples), `checker.rs` (the staged
//!   evaluation in progress and what it is for);
//! - `state.rs`: the [`Supervisor`] itself, its start and its accessors;
//! - `regions.rs` (the certified regions), `setpoint.rs` (the setpoint, the profile's
//!   limits at it, the candidate's guards and joint rates, a step scaled down);
//! - `admission.rs` (the checks at submission and the refusals), `goal.rs` (the goal, the
//!   next goal and the braking point);
//! - `verification.rs` (the path checks of targets);
//! - `evaluation.rs` (the evaluation phase), `step.rs` (the step, by phase);
//! - `period.rs` (submit, tick, brake, clear).
//!
//! [`Staged`]: crate::guards::Staged
//! [`ConditionEstimator`]: crate::singularity::ConditionEstimator
//! [`Guards::solve_certified`]: crate::guards::Guards::solve_certified

mod admission;
mod checker;
mod config;
mod evaluation;
mod goal;
pub mod lead;
mod mode;
pub mod path;
mod period;
pub mod profile;
mod regions;
mod report;
mod setpoint;
mod state;
mod step;
mod verification;

pub use crate::guards::MAX_STAGES;
pub use config::{SupervisorConfig, SupervisorError};
pub use path::interpolate;
pub use report::{Counters, Margins, Mode, Refusal, TickOutput};
pub use state::Supervisor;
