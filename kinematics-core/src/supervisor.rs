//! The setpoint supervisor: turns a stream of master targets (pose, timestamp) into joint
//! setpoints at the control rate, so that no setpoint ever violates a stop-level guard.
//!
//! Per tick, with constant bounded work: one stage of a full guard evaluation (see
//! [`Staged`]: the inverse kinematics with the kinematic guards, the Jacobians with the
//! start of the parallel measure's SVD, one sweep of that SVD, or the payload statics) and,
//! while moving, the kinematic guards and the Jacobian of the candidate setpoint. A full
//! evaluation of a pose thus takes a few ticks (five when the SVD starts warm, at most
//! [`MAX_STAGES`]). The
//! checker works on one pose at a time, taking turns between the pending path and the
//! braking point; each kind of pose keeps its own warm-started SVD
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
//!    until then, but no farther than the goal (see [`Supervisor::tick`] for the bound). A
//!    target verified while moving replaces the goal once such a check has looked past the
//!    goal towards it. A stop-level violation there
//!    turns the motion into a controlled stop (full deceleration along the current twist on
//!    every tick) within the stretch the earlier braking points covered. The candidate
//!    setpoint itself gets the kinematic guards (reach, workspace, joint ranges, tilt,
//!    collision, serial singularity) every tick; it lies on the stretch the braking points
//!    (about 0.2 mm apart at 25 mm/s) and the path samples (0.5 mm apart) checked in full.
//!    A stop-level violation of the candidate holds the last safe setpoint and latches the
//!    reason until [`Supervisor::clear`].

use crate::branch::Branch;
use crate::double_buffer::DoubleBuffer;
use crate::guards::{
    Depth, Evaluation, Guard, GuardSetupError, Guards, Limits, MotionSample, Reading, Severity,
    Solved, Staged,
};
use crate::jacobian::{jacobian_into, Jacobians};
use crate::mechanism::{JointKind, Mechanism};
use crate::pose::{rotation_angle, rotation_vector, Pose};
use crate::scalar::{lit, norm3, scale3, sqrt, sub3, wrap_angle, Real};
use crate::singularity::ConditionEstimator;
use crate::{Joints, Twist};
use core::fmt;
use nalgebra::Vector3;

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
        }
    }
}

/// The supervisor's state, by name.
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

/// Why a target was refused.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Refusal<T: Real> {
    /// A component is NaN or infinite.
    NonFinite,
    /// The timestamp is older than `stale_after_us` (or from the future by as much).
    Stale { age_us: i64 },
    /// The timestamp is not newer than the last accepted one.
    OutOfOrder,
    /// Too far from the current setpoint (m, rad).
    TooFar { distance: T, angle: T },
    /// The straight path to it crosses a stop-level region at this fraction of the way.
    Path { fraction: T, reading: Reading<T> },
    /// The supervisor is stopped; clear it first.
    Latched,
}

impl<T: Real> fmt::Display for Refusal<T> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Refusal::NonFinite => f.write_str("target is not finite"),
            Refusal::Stale { age_us } => write!(f, "target is stale ({age_us} µs old)"),
            Refusal::OutOfOrder => f.write_str("target timestamp is not newer than the last"),
            Refusal::TooFar { distance, angle } => write!(
                f,
                "target too far from the setpoint ({:.1} mm, {:.1} deg)",
                crate::geometry::to_f64(*distance) * 1e3,
                crate::geometry::to_f64(*angle).to_degrees()
            ),
            Refusal::Path { fraction, reading } => write!(
                f,
                "path crosses {} at {:.0}% of the way",
                reading.guard,
                crate::geometry::to_f64(*fraction) * 100.0
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
    pub brakes: u32,
    pub stops: u32,
    pub warn_ticks: u32,
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
    /// The latched stop reason, if stopped.
    pub stop: Option<Reading<T>>,
}

#[derive(Clone, Copy, Debug, PartialEq)]
struct Pending<T: Real> {
    from: Pose<T>,
    to: Pose<T>,
    /// The whole segment ([`segment`]), computed once, not for every sample.
    dv: Vector3<T>,
    dw: Vector3<T>,
    samples: u16,
    /// Next sample to check; sample `samples` (the end) is checked first.
    next: u16,
    end_checked: bool,
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

/// The setpoint supervisor.
#[derive(Clone, Debug)]
pub struct Supervisor<T: Real, M: Mechanism<T>> {
    guards: Guards<T, M>,
    cfg: SupervisorConfig<T>,
    pose: Pose<T>,
    q: Joints<T>,
    qdot: Joints<T>,
    twist: Twist<T>,
    /// The setpoint's solution and Jacobians (the current one; J for the joint-speed caps,
    /// valid when `jac_ok`, not at a serial singularity) and the candidate's (the spare): a
    /// kept candidate swaps the roles, so nothing is copied.
    evals: DoubleBuffer<Evaluation<T>>,
    jac_ok: bool,
    goal: Pose<T>,
    pending: Option<Pending<T>>,
    /// The newest target that arrived while another was being verified; it is verified
    /// next (older queued ones are superseded), so a fast stream never starves the check.
    queued: Option<Pose<T>>,
    last_stamp_us: Option<u64>,
    latched: Option<Reading<T>>,
    braking: bool,
    warning: bool,
    counters: Counters,
    last_refusal: Option<Refusal<T>>,
    /// The full evaluation in progress, one stage per tick, and what it is for.
    checker: Staged<T>,
    job: Option<Job>,
    /// The next job goes to the path check (else to the braking point) when both wait.
    path_turn: bool,
    /// Warm starts of the parallel measure's SVD, one per stream of nearby poses.
    cond_setpoint: ConditionEstimator<T>,
    cond_path: ConditionEstimator<T>,
    cond_path_end: ConditionEstimator<T>,
    cond_ahead: ConditionEstimator<T>,
    /// A warn level was reached at the last braking point checked.
    ahead_warn: bool,
    /// A verified target accepted while moving: it replaces the goal once a braking-point
    /// check that looked past the goal (up to this target) has passed, since the checks
    /// before looked no farther than the goal.
    next_goal: Option<Pose<T>>,
    /// The braking-point job in progress was computed towards `next_goal`.
    job_for_next: bool,
    /// The parallel measure of the last full evaluation.
    parallel: T,
}

pub use crate::guards::MAX_STAGES;

/// What the checker is evaluating.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Job {
    /// A sample of the pending path.
    Path,
    /// The end of the pending path (checked first).
    PathEnd,
    /// The braking point.
    Ahead,
}

/// Pose at fraction `s` of the straight segment a → b (translation linear, rotation about
/// the fixed world axis of b·aᵀ).
pub fn interpolate<T: Real>(a: &Pose<T>, b: &Pose<T>, s: T) -> Pose<T> {
    let (dv, dw) = segment(a, b);
    along(a, &dv, &dw, s)
}

/// The straight segment a → b: its translation and the rotation vector of b·aᵀ.
fn segment<T: Real>(a: &Pose<T>, b: &Pose<T>) -> (Vector3<T>, Vector3<T>) {
    (sub3(&b.t, &a.t), rotation_vector(&(b.r * a.r.inverse())))
}

/// The pose at fraction `s` of the segment (`dv`, `dw`) from `from` ([`segment`]).
fn along<T: Real>(from: &Pose<T>, dv: &Vector3<T>, dw: &Vector3<T>, s: T) -> Pose<T> {
    from.displaced(&scale3(dv, s), &scale3(dw, s))
}

/// J·x, written out over J's column arrays (nalgebra's generic product, and loops, cost
/// several times the arithmetic on the Cortex-M4).
fn jac_times<T: Real>(j: &nalgebra::Matrix6<T>, x: &[T; 6]) -> [T; 6] {
    let [c0, c1, c2, c3, c4, c5] = &j.data.0;
    let [x0, x1, x2, x3, x4, x5] = *x;
    macro_rules! row {
        ($i:literal) => {
            c0[$i] * x0 + c1[$i] * x1 + c2[$i] * x2 + c3[$i] * x3 + c4[$i] * x4 + c5[$i] * x5
        };
    }
    [row!(0), row!(1), row!(2), row!(3), row!(4), row!(5)]
}

/// The limit of a joint of `kind` from a [prismatic, revolute] pair.
fn of_kind<T: Real>(pair: &[T; 2], kind: JointKind) -> T {
    match kind {
        JointKind::Linear => pair[0],
        JointKind::Angular => pair[1],
    }
}

/// The motion limits scaled by (1 - 1000 ε).
fn shaved<T: Real>(l: &Limits<T>) -> Limits<T> {
    let k = T::one() - T::default_epsilon() * lit(1000.0);
    Limits {
        tip_speed: l.tip_speed * k,
        angular_speed: l.angular_speed * k,
        tip_accel: l.tip_accel * k,
        angular_accel: l.angular_accel * k,
        ..*l
    }
}

/// The parallel measure at the start pose (one full evaluation; NaN if it failed).
fn start_parallel<T: Real, M: Mechanism<T>>(guards: &Guards<T, M>, start: &Pose<T>) -> T {
    let mut parallel = lit::<T>(f64::NAN);
    guards.evaluate_pose(start, &mut |r| {
        if r.guard == Guard::ParallelSingularity {
            parallel = r.value;
        }
    });
    parallel
}

impl<T: Real, M: Mechanism<T> + Clone> Supervisor<T, M> {
    /// A supervisor holding at `start`, which must be safe.
    pub fn new(
        robot: M,
        branch: Branch,
        limits: Limits<T>,
        cfg: SupervisorConfig<T>,
        start: &Pose<T>,
    ) -> Result<Self, SupervisorError<T>> {
        let pos = |x: T| x > T::zero() && x.is_finite();
        if !(pos(cfg.dt) && cfg.dt >= lit(1e-4) && cfg.dt <= lit(0.1)) {
            return Err(SupervisorError::Config("dt must be within 0.1 .. 100 ms"));
        }
        if !(pos(cfg.path_step) && pos(cfg.path_step_angle)) {
            return Err(SupervisorError::Config("path steps must be positive"));
        }
        if !(pos(cfg.max_segment) && pos(cfg.max_segment_angle)) {
            return Err(SupervisorError::Config("max segment must be positive"));
        }
        if !(1..=MAX_STAGES).contains(&u32::from(cfg.stages_per_tick)) {
            return Err(SupervisorError::Config(
                "stages_per_tick must be within 1 ..= 13 (MAX_STAGES)",
            ));
        }
        let n = (cfg.max_segment / cfg.path_step).max(cfg.max_segment_angle / cfg.path_step_angle);
        if !(n <= lit(4096.0)) {
            return Err(SupervisorError::Config(
                "max segment / path step exceeds 4096 samples",
            ));
        }
        if !(pos(cfg.joint_speed_headroom) && cfg.joint_speed_headroom <= T::one()) {
            return Err(SupervisorError::Config(
                "joint_speed_headroom must be in (0, 1]",
            ));
        }
        if !(pos(cfg.joint_accel_headroom) && cfg.joint_accel_headroom <= T::one()) {
            return Err(SupervisorError::Config(
                "joint_accel_headroom must be in (0, 1]",
            ));
        }
        let guards = Guards::new(robot, branch, limits).map_err(SupervisorError::Setup)?;
        let (verdict, sol) = guards.check_pose(start);
        let start_parallel = start_parallel(&guards, start);
        let sol = match (verdict.is_stop(), sol) {
            (false, Some(s)) => s,
            _ => return Err(SupervisorError::UnsafeStart(verdict.first_stop().copied())),
        };
        let mut start_eval = Evaluation::new(branch);
        start_eval.sol = sol;
        let jac_ok = jacobian_into(guards.robot(), &sol, &mut start_eval.jac).is_ok();
        Ok(Supervisor {
            guards,
            cfg,
            pose: *start,
            q: sol.q(),
            qdot: Joints::zeros(),
            twist: Twist::zeros(),
            evals: DoubleBuffer::new(start_eval, Evaluation::new(branch)),
            jac_ok,
            goal: *start,
            pending: None,
            queued: None,
            last_stamp_us: None,
            latched: None,
            braking: false,
            warning: !verdict.is_ok(),
            counters: Counters::default(),
            last_refusal: None,
            checker: Staged::new(branch),
            job: None,
            path_turn: true,
            cond_setpoint: ConditionEstimator::new(),
            cond_path: ConditionEstimator::new(),
            cond_path_end: ConditionEstimator::new(),
            cond_ahead: ConditionEstimator::new(),
            ahead_warn: false,
            next_goal: None,
            job_for_next: false,
            parallel: start_parallel,
        })
    }

    /// Stops as soon as the limits allow, e.g. when the master falls silent: forgets the
    /// pending and queued targets and brakes along the current twist at full deceleration
    /// (within the stretch the braking points have checked); the goal becomes where the
    /// robot comes to rest. Not a latched stop: new targets are taken.
    pub fn brake(&mut self) {
        self.drop_pending();
        if self.twist.iter().any(|x| *x != T::zero()) {
            self.braking = true;
        } else {
            self.goal = self.pose;
        }
    }

    /// The guards in use.
    pub fn guards(&self) -> &Guards<T, M> {
        &self.guards
    }
    /// The counters.
    pub fn counters(&self) -> &Counters {
        &self.counters
    }
    /// The last refusal, if any.
    pub fn last_refusal(&self) -> Option<&Refusal<T>> {
        self.last_refusal.as_ref()
    }
    /// The current setpoint pose.
    pub fn setpoint(&self) -> &Pose<T> {
        &self.pose
    }
    /// The joints of the current setpoint.
    pub fn setpoint_joints(&self) -> &Joints<T> {
        &self.q
    }
    /// The setpoint's twist [v; ω].
    pub fn twist(&self) -> &Twist<T> {
        &self.twist
    }
    /// The Jacobians at the current setpoint (None at a serial singularity), e.g. to map
    /// a known tool load to the joints.
    pub fn jacobians(&self) -> Option<&Jacobians<T>> {
        self.jac_ok.then_some(&self.evals.current().jac)
    }
    /// The latched stop reason.
    pub fn latched(&self) -> Option<&Reading<T>> {
        self.latched.as_ref()
    }
    /// The singularity margins near the setpoint (see [`Margins`]).
    pub fn margins(&self) -> Margins<T> {
        let robot = self.guards.robot();
        let sol = &self.evals.current().sol;
        let serial = sol
            .chains
            .iter()
            .map(|(_, c)| robot.serial_measure(c).1)
            .fold(T::max_value().unwrap_or(T::one()), |m, x| m.min(x));
        Margins {
            serial,
            parallel: self.parallel,
        }
    }

    fn refuse(&mut self, r: Refusal<T>) -> Result<(), Refusal<T>> {
        let c = &mut self.counters;
        match r {
            Refusal::NonFinite => c.non_finite += 1,
            Refusal::Stale { .. } => c.stale += 1,
            Refusal::OutOfOrder => c.out_of_order += 1,
            Refusal::TooFar { .. } => c.too_far += 1,
            Refusal::Path { .. } => c.path_refused += 1,
            Refusal::Latched => c.refused_latched += 1,
        }
        self.last_refusal = Some(r);
        Err(r)
    }

    /// Submits a master target stamped `stamp_us`, at clock time `now_us`. Accepted targets
    /// are verified over the next ticks; a refusal is returned (and counted) at once for
    /// non-finite, stale, out-of-order or too-distant targets.
    pub fn submit(
        &mut self,
        target: &Pose<T>,
        stamp_us: u64,
        now_us: u64,
    ) -> Result<(), Refusal<T>> {
        if self.latched.is_some() {
            return self.refuse(Refusal::Latched);
        }
        if !target.is_finite() {
            return self.refuse(Refusal::NonFinite);
        }
        let age = now_us as i128 - stamp_us as i128;
        if age.unsigned_abs() > u128::from(self.cfg.stale_after_us) {
            let age_us = age.clamp(i128::from(i64::MIN), i128::from(i64::MAX)) as i64;
            return self.refuse(Refusal::Stale { age_us });
        }
        if self.last_stamp_us.is_some_and(|last| stamp_us <= last) {
            return self.refuse(Refusal::OutOfOrder);
        }
        self.check_distance(target)?;
        self.last_stamp_us = Some(stamp_us);
        if self.pending.is_some() {
            if self.queued.is_some() {
                self.counters.superseded += 1;
            }
            self.queued = Some(*target);
            return Ok(());
        }
        self.start_pending(target);
        Ok(())
    }

    /// Refuses a target too far from the current setpoint.
    fn check_distance(&mut self, target: &Pose<T>) -> Result<(), Refusal<T>> {
        let distance = norm3(&(target.t - self.pose.t));
        let angle = rotation_angle(&(target.r * self.pose.r.inverse()));
        if !(distance <= self.cfg.max_segment && angle <= self.cfg.max_segment_angle) {
            self.refuse(Refusal::TooFar { distance, angle })?;
        }
        Ok(())
    }

    /// Starts verifying the straight segment to `target` from whichever of the goal the
    /// robot is heading for (itself verified) and the setpoint is nearer to it, in path
    /// samples: a fast stream of targets is then verified in short steps from the goal
    /// however far the setpoint lags behind it, and a target back towards the setpoint
    /// from the setpoint. The motion from the setpoint to the new goal stays within the
    /// braking-point checks. While braking, from the setpoint.
    fn start_pending(&mut self, target: &Pose<T>) {
        let samples_from = |from: &Pose<T>| {
            let distance = norm3(&(target.t - from.t));
            let angle = rotation_angle(&(target.r * from.r.inverse()));
            (distance / self.cfg.path_step).max(angle / self.cfg.path_step_angle)
        };
        let goal = self.next_goal.unwrap_or(self.goal);
        let (at_goal, at_setpoint) = (samples_from(&goal), samples_from(&self.pose));
        // (The setpoint is within `max_segment` of the target: checked on submission.)
        let (from, n) = if !self.braking && at_goal < at_setpoint {
            (goal, at_goal)
        } else {
            (self.pose, at_setpoint)
        };
        let n = n.ceil().max(T::one());
        let samples = crate::geometry::to_f64(n) as u16;
        let (dv, dw) = segment(&from, target);
        self.pending = Some(Pending {
            from,
            to: *target,
            dv,
            dw,
            samples: samples.max(1),
            next: 1,
            end_checked: false,
        });
    }

    /// Starts the queued target, if any, once the previous check is over.
    fn start_queued(&mut self) {
        if let Some(q) = self.queued.take() {
            if self.check_distance(&q).is_ok() {
                self.start_pending(&q);
            }
        }
    }

    /// Clears a latched stop when the current setpoint is safe again (e.g. after the
    /// limits were reviewed); the goal becomes the current setpoint.
    pub fn clear(&mut self) -> Result<(), Option<Reading<T>>> {
        let (verdict, _) = self.guards.check_pose(&self.pose);
        if verdict.is_stop() {
            return Err(verdict.first_stop().copied());
        }
        self.latched = None;
        self.goal = self.pose;
        self.drop_pending();
        self.braking = false;
        Ok(())
    }

    /// Evaluates the kinematic guards at `pose` into the spare of `self.evals`
    /// (the solution and its Jacobians; [`Self::keep_candidate`] makes it the setpoint's):
    /// the first stop-level reading, whether a warn level is reached, and what was solved.
    fn kinematic_check(&mut self, pose: &Pose<T>) -> (Option<Reading<T>>, bool, Solved) {
        let mut stop = None;
        let mut warn = false;
        // (The kinematic depth has no SVD to warm-start.)
        let cond = &mut self.cond_setpoint;
        let scratch = self.evals.spare_mut();
        let solved = self.guards.evaluate_pose_into(
            pose,
            &mut |r| match r.severity {
                Some(Severity::Stop) if stop.is_none() => stop = Some(*r),
                Some(Severity::Warn) => warn = true,
                _ => {}
            },
            cond,
            scratch,
            Depth::Kinematic,
        );
        (stop, warn, solved)
    }

    /// The candidate's evaluation (see [`Self::kinematic_check`]).
    fn candidate(&self) -> &Evaluation<T> {
        self.evals.spare()
    }

    /// The candidate checked last becomes the setpoint: its pose, joints and Jacobians.
    fn keep_candidate(&mut self, pose: &Pose<T>, solved: Solved) {
        self.q = self.candidate().sol.q();
        self.pose = *pose;
        self.jac_ok = solved == Solved::WithJacobian;
        self.evals.swap();
    }

    /// Forgets the pending and the queued target (and a path check in progress).
    fn drop_pending(&mut self) {
        self.pending = None;
        self.queued = None;
        self.next_goal = None;
        if matches!(self.job, Some(Job::Path | Job::PathEnd)) {
            self.job = None;
        }
    }

    /// Starts the checker's next job, if there is one: a sample of the pending path or
    /// the braking point `ahead` (while moving and not braking), in turn when both wait.
    fn start_job(&mut self, ahead: Option<&Pose<T>>) {
        match (self.pending, ahead) {
            (Some(p), None) => self.begin_path(&p),
            (Some(p), Some(_)) if self.path_turn => self.begin_path(&p),
            (_, Some(a)) => self.begin(a, Job::Ahead),
            (None, None) => {}
        }
    }

    /// Starts on the pending path's next sample (its end first).
    fn begin_path(&mut self, p: &Pending<T>) {
        let (k, job) = if p.end_checked {
            (p.next, Job::Path)
        } else {
            (p.samples, Job::PathEnd)
        };
        let s = lit::<T>(f64::from(k)) / lit(f64::from(p.samples));
        self.begin(&along(&p.from, &p.dv, &p.dw, s), job);
    }

    fn begin(&mut self, pose: &Pose<T>, job: Job) {
        self.checker.start(pose);
        self.job = Some(job);
        self.path_turn = job == Job::Ahead;
    }

    /// Runs one stage of the checker's job; when it finishes, acts on its verdict. Returns
    /// whether a braking point was found unsafe.
    fn run_stage(&mut self) -> bool {
        let Some(job) = self.job else { return false };
        let cond = match job {
            Job::Path => &mut self.cond_path,
            Job::PathEnd => &mut self.cond_path_end,
            Job::Ahead => &mut self.cond_ahead,
        };
        self.guards.advance(&mut self.checker, cond);
        if !self.checker.is_finished() {
            return false;
        }
        self.job = None;
        let stop = self.checker.stop().copied();
        if let Some(x) = self.checker.inv_cond() {
            self.parallel = x;
        }
        match job {
            Job::Ahead => {
                self.ahead_warn = self.checker.warn();
                if stop.is_none() && self.job_for_next {
                    if let Some(next) = self.next_goal.take() {
                        self.goal = next;
                    }
                }
                stop.is_some()
            }
            Job::Path | Job::PathEnd => {
                self.path_sample_checked(stop);
                false
            }
        }
    }

    /// The verdict on the pending path's current sample.
    fn path_sample_checked(&mut self, stop: Option<Reading<T>>) {
        let Some(mut p) = self.pending else { return };
        if let Some(reading) = stop {
            let k = if p.end_checked { p.next } else { p.samples };
            self.pending = None;
            let _ = self.refuse(Refusal::Path {
                fraction: lit::<T>(f64::from(k)) / lit(f64::from(p.samples)),
                reading,
            });
            self.start_queued();
            return;
        }
        if p.end_checked {
            p.next += 1;
        } else {
            p.end_checked = true;
        }
        if p.next >= p.samples {
            self.pending = None;
            if self.twist.iter().any(|x| *x != T::zero()) {
                self.next_goal = Some(p.to);
            } else {
                self.goal = p.to;
            }
            self.braking = false;
            self.counters.accepted += 1;
            self.start_queued();
            return;
        }
        self.pending = Some(p);
    }

    /// Speed caps (m/s, rad/s) for motion along the unit directions, within the joint
    /// speed limits (with headroom) at the current setpoint's Jacobian.
    fn speed_caps(&self, l: &Limits<T>, dir_v: &Vector3<T>, dir_w: &Vector3<T>) -> (T, T) {
        let (vmax, wmax) = (l.tip_speed, l.angular_speed);
        let Some(j) = self.jacobians().map(|j| &j.j) else {
            return (vmax, wmax);
        };
        let probe = [
            dir_v.x * vmax,
            dir_v.y * vmax,
            dir_v.z * vmax,
            dir_w.x * wmax,
            dir_w.y * wmax,
            dir_w.z * wmax,
        ];
        // q̇ = J·probe over J's column-major storage (nalgebra's generic product costs
        // several times the arithmetic on the Cortex-M4).
        let qd = jac_times(j, &probe);
        let mut scale = T::one();
        for (v, kind) in qd.iter().zip(self.guards.robot().joint_kinds().iter()) {
            let lim = of_kind(&l.joint_speed, *kind) * self.cfg.joint_speed_headroom;
            if v.abs() * scale > lim {
                scale = lim / v.abs();
            }
        }
        (vmax * scale, wmax * scale)
    }

    /// The Cartesian acceleration limits scaled so that no joint exceeds its acceleration
    /// limit (with headroom) whatever the direction of the change of twist, at the current
    /// setpoint's Jacobian: |J_j·Δ| ≤ |J_j,v|·|Δv| + |J_j,ω|·|Δω| (Cauchy-Schwarz, per row).
    fn joint_safe_accels(&self, l: &Limits<T>) -> (T, T) {
        let (at, aw) = (l.tip_accel, l.angular_accel);
        let Some(j) = self.jacobians().map(|j| &j.j) else {
            return (at, aw);
        };
        // Squared norms of each row's [v] and [ω] halves, over the column arrays.
        let [c0, c1, c2, c3, c4, c5] = &j.data.0;
        macro_rules! halves {
            ($i:literal) => {
                (
                    c0[$i] * c0[$i] + c1[$i] * c1[$i] + c2[$i] * c2[$i],
                    c3[$i] * c3[$i] + c4[$i] * c4[$i] + c5[$i] * c5[$i],
                )
            };
        }
        let rows = [
            halves!(0),
            halves!(1),
            halves!(2),
            halves!(3),
            halves!(4),
            halves!(5),
        ];
        let mut scale = T::one();
        let kinds = self.guards.robot().joint_kinds();
        for (kind, (v2, w2)) in kinds.iter().zip(rows.iter()) {
            let lim = of_kind(&l.joint_accel, *kind) * self.cfg.joint_accel_headroom;
            let worst = sqrt(*v2) * at + sqrt(*w2) * aw;
            if worst * scale > lim {
                scale = lim / worst;
            }
        }
        (at * scale, aw * scale)
    }

    fn hold(&mut self, reason: Reading<T>) -> TickOutput<T> {
        self.latched = Some(reason);
        self.counters.stops += 1;
        self.twist = Twist::zeros();
        self.qdot = Joints::zeros();
        self.drop_pending();
        self.output(false)
    }

    fn output(&self, warning: bool) -> TickOutput<T> {
        let moving = self.twist.iter().any(|x| *x != T::zero());
        let mode = if self.latched.is_some() {
            Mode::Stopped
        } else if self.braking {
            Mode::Braking
        } else if self.pending.is_some() {
            Mode::Verifying
        } else if moving {
            Mode::Moving
        } else {
            Mode::Holding
        };
        TickOutput {
            pose: self.pose,
            q: self.q,
            qdot: self.qdot,
            twist: self.twist,
            mode,
            warning,
            stop: self.latched,
        }
    }

    /// One control tick.
    ///
    /// The braking point checked by a job that starts on this tick must cover what can
    /// happen until the next braking-point job has finished: a job takes at most L ticks
    /// (L = [`MAX_STAGES`] / `stages_per_tick`, rounded up) and the next one may wait for
    /// one path sample, so it finishes at most 3·L - 1 ticks after this one; until then the
    /// profile may accelerate, to v' = |v| + a·(3L - 1)·dt, and a violation found then
    /// starts braking from there. The point checked is where the robot, moving on for 3L
    /// ticks at v' along its current twist, would stop from v': v'²/2a + 3L·v'·dt ahead
    /// (3.7 mm at 25 mm/s, 250 mm/s², L = 13), but no farther than the goal (or the verified
    /// target waiting to replace it): the profile stops there with deceleration in hand, so
    /// a target next to a boundary is reached; the goal changes only after a check that
    /// looked past it.
    pub fn tick(&mut self) -> TickOutput<T> {
        if self.latched.is_some() {
            return self.output(false);
        }
        let moving = self.twist.iter().any(|x| *x != T::zero());
        // The limiter runs a hair inside the limits so that rounding never trips the
        // motion guards that check its output.
        let mut l = shaved(self.guards.limits());
        // Every acceleration of this tick (profile, braking, look-ahead) within what the
        // joints can follow here.
        (l.tip_accel, l.angular_accel) = self.joint_safe_accels(&l);
        let dt = self.cfg.dt;
        let two = lit::<T>(2.0);
        let v0 = Vector3::new(self.twist.x, self.twist.y, self.twist.z);
        let w0 = Vector3::new(self.twist.w, self.twist.a, self.twist.b);
        // The checker: `stages_per_tick` stages.
        let stages = self.cfg.stages_per_tick;
        let mut ahead_stop = false;
        for _ in 0..stages {
            if self.job.is_none() {
                // The goal the profile stops at (or the verified target waiting to replace
                // it): the braking point need not look past it.
                let horizon = self.next_goal.unwrap_or(self.goal);
                let for_next = self.next_goal.is_some();
                let ahead = (moving && !self.braking).then(|| {
                    let per_job = MAX_STAGES.div_ceil(u32::from(stages));
                    let n = lit::<T>(f64::from(3 * per_job));
                    let to_t = norm3(&(horizon.t - self.pose.t));
                    let to_r = norm3(&rotation_vector(&(horizon.r * self.pose.r.inverse())));
                    let reach = |v: &Vector3<T>, amax: T, to_horizon: T| {
                        let speed = norm3(v);
                        if speed > T::zero() {
                            let vp = speed + amax * (n - T::one()) * dt;
                            let far = (vp * vp / (two * amax) + n * vp * dt).min(to_horizon);
                            v * (far / speed)
                        } else {
                            Vector3::zeros()
                        }
                    };
                    self.pose.displaced(
                        &reach(&v0, l.tip_accel, to_t),
                        &reach(&w0, l.angular_accel, to_r),
                    )
                });
                self.start_job(ahead.as_ref());
                if self.job == Some(Job::Ahead) {
                    self.job_for_next = for_next;
                }
            }
            if self.job.is_none() {
                break;
            }
            ahead_stop |= self.run_stage();
        }
        // Standing still, a verified target waiting for a braking-point check takes over
        // at once (there is no motion to look past the goal).
        if !moving {
            if let Some(next) = self.next_goal.take() {
                self.goal = next;
            }
        }
        // Desired twist towards the goal (world frame), with the braking profile.
        let e_t = self.goal.t - self.pose.t;
        let e_r = rotation_vector(&(self.goal.r * self.pose.r.inverse()));
        let (d, a) = (norm3(&e_t), norm3(&e_r));
        let dir_v = if d > T::zero() {
            e_t / d
        } else {
            Vector3::zeros()
        };
        let dir_w = if a > T::zero() {
            e_r / a
        } else {
            Vector3::zeros()
        };
        let (vcap, wcap) = self.speed_caps(&l, &dir_v, &dir_w);
        // The braking profile, discrete: the largest speed v with v·dt + v²/2a' ≤ d, so that
        // after this tick's move the robot can still stop at the goal, with a' 5 % under
        // the deceleration braking uses (the acceleration scale changes along the way).
        let curve = |dist: T, amax: T| {
            let a_ = amax * lit(0.95);
            sqrt(a_ * a_ * dt * dt + two * a_ * dist) - a_ * dt
        };
        let v_des = dir_v * vcap.min(curve(d, l.tip_accel)).min(d / dt);
        let w_des = dir_w * wcap.min(curve(a, l.angular_accel)).min(a / dt);
        // Acceleration limit on the change of twist.
        let limit_step = |dv: Vector3<T>, amax: T| {
            let n = norm3(&dv);
            let m = amax * dt;
            if n > m {
                dv * (m / n)
            } else {
                dv
            }
        };
        let mut v1 = v0 + limit_step(v_des - v0, l.tip_accel);
        let mut w1 = w0 + limit_step(w_des - w0, l.angular_accel);
        // Arrival: within one tick's worth of braking of the (verified) goal, at a speed that
        // one tick of deceleration cancels, snap onto it and stop.
        let dt2 = dt * dt;
        if !self.braking
            && self.pending.is_none()
            && d <= l.tip_accel * dt2
            && a <= l.angular_accel * dt2
            && norm3(&v0) <= l.tip_accel * dt
            && norm3(&w0) <= l.angular_accel * dt
        {
            if d + a > T::zero() {
                // The goal was checked in full (the end of its path, first of all).
                let goal = self.goal;
                let (stop, warn, solved) = self.kinematic_check(&goal);
                if stop.is_none() && solved != Solved::No {
                    self.keep_candidate(&goal, solved);
                    self.warning = warn;
                }
            }
            self.twist = Twist::zeros();
            self.qdot = Joints::zeros();
            return self.output(self.warning);
        }
        // At rest on the goal (e.g. while a new target is being verified): the setpoint
        // stays, and it was checked when it became the setpoint.
        if !self.braking && d + a == T::zero() && !moving {
            self.twist = Twist::zeros();
            self.qdot = Joints::zeros();
            return self.output(self.warning);
        }
        let mut candidate = self.pose.displaced(&(v1 * dt), &(w1 * dt));
        // Where braking from the candidate would stop.
        let stop_point = |v: &Vector3<T>, w: &Vector3<T>, from: &Pose<T>| {
            let sv = norm3(v) / (two * l.tip_accel);
            let sw = norm3(w) / (two * l.angular_accel);
            from.displaced(&(v * sv), &(w * sw))
        };
        if ahead_stop || self.braking {
            // Brake on the stretch checked before: decelerate along the current twist, at
            // the full deceleration on every tick until the robot stands.
            if !self.braking {
                self.counters.brakes += 1;
            }
            self.braking = true;
            self.drop_pending();
            v1 = v0 - limit_step(v0, l.tip_accel);
            w1 = w0 - limit_step(w0, l.angular_accel);
            candidate = self.pose.displaced(&(v1 * dt), &(w1 * dt));
            self.goal = stop_point(&v1, &w1, &candidate);
        }
        let (stop, warn, solved) = self.kinematic_check(&candidate);
        // A warn level reached at the braking point is reported as well (the payload's
        // torque, e.g., is only evaluated there while moving).
        let warn = warn || self.ahead_warn;
        match (stop, solved) {
            (Some(r), _) => return self.hold(r),
            (None, Solved::No) => return self.output(warn), // unreachable: no solution is a stop
            _ => {}
        }
        // The guards computed the candidate's Jacobians already (in the scratch): reuse them.
        let with_jac = solved == Solved::WithJacobian;
        let q_new = self.candidate().sol.q();
        let twist = Twist::new(v1.x, v1.y, v1.z, w1.x, w1.y, w1.z);
        let qdot = if with_jac {
            Joints::from(jac_times(&self.candidate().jac.j, &twist.into()))
        } else {
            {
                // Finite differences when J is singular (the serial guard stops long before).
                let mut qd = (q_new - self.q) / dt;
                for (x, k) in qd.iter_mut().zip(self.guards.robot().joint_kinds().iter()) {
                    if *k == JointKind::Angular {
                        *x = wrap_angle(*x * dt) / dt;
                    }
                }
                qd
            }
        };
        // Motion guards on the output itself.
        let prev = MotionSample {
            twist: self.twist,
            qdot: self.qdot,
        };
        let cur = MotionSample { twist, qdot };
        if !self.guards.motion_within_limits(&prev, &cur, dt) {
            // The readings, for the stop's reason.
            let mut motion_stop = None;
            self.guards.evaluate_motion(&prev, &cur, dt, &mut |r| {
                if r.severity == Some(Severity::Stop) && motion_stop.is_none() {
                    motion_stop = Some(*r);
                }
            });
            if let Some(r) = motion_stop {
                return self.hold(r);
            }
        }
        self.keep_candidate(&candidate, solved);
        self.qdot = qdot;
        self.twist = twist;
        self.warning = warn;
        if warn {
            self.counters.warn_ticks += 1;
        }
        if self.braking && norm3(&v1) + norm3(&w1) == T::zero() {
            self.braking = false;
            self.goal = self.pose;
        }
        self.output(warn)
    }
}
