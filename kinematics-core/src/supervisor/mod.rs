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
//!    until then, but no farther than the goal (the bound is in `run_checker`). A
//!    target verified while moving replaces the goal once such a check has looked past the
//!    goal towards it. A stop-level violation there
//!    turns the motion into a controlled stop (full deceleration along the current twist on
//!    every tick) within the stretch the earlier braking points covered. The candidate
//!    setpoint itself gets the kinematic guards (reach, workspace, joint ranges, tilt,
//!    collision, serial singularity) every tick; it lies on the stretch the braking points
//!    (about 0.2 mm apart at 25 mm/s) and the path samples (0.5 mm apart) checked in full.
//!    A stop-level violation of the candidate holds the last safe setpoint and latches the
//!    reason until [`Supervisor::clear`].
//!
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
//!    led target whose path
//!    check fails pauses the lead (the master's own target is verified instead, no
//!    refusal). A stream that stops abruptly is overshot by up to the lead (onto verified
//!    poses) and the robot goes back to the master's last pose.
//!
//! Near serial singularities J̇·twist moves the joints at a constant twist: braking and
//! slowing down use the Cartesian deceleration the joints follow for that change
//! ([`profile::braking_accels`], [`profile::slowing_step`]), and a step the motion guards
//! still refuse is scaled down ([`profile::step_scales`]) before the supervisor holds.
//!
//! Modules: [`admission`] (the checks at submission, refusals, counters), [`path`] (the
//! path check, the certified regions and the checker's jobs), [`profile`] (the motion
//! profile, pure functions), [`lead`] (the stream's velocity and the led target).

use crate::branch::Branch;
use crate::double_buffer::DoubleBuffer;
use crate::guards::{
    Certificate, Depth, Evaluation, Guard, GuardSetupError, Guards, Limits, MotionSample, Reading,
    Severity, Solved, Staged,
};
use crate::jacobian::{jacobian_into, Jacobians};
use crate::mechanism::{JointKind, Mechanism};
use crate::pose::{rotation_vector, Pose};
use crate::scalar::{lit, norm3, wrap_angle, Real};
use crate::singularity::ConditionEstimator;
use crate::vectors::{Joints, Twist};
use core::fmt;
use nalgebra::Vector3;

pub mod admission;
pub mod lead;
pub mod path;
pub mod profile;

pub use admission::{Counters, Refusal};
pub use path::interpolate;
use path::Pending;
use profile::ProfileLimits;

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
    /// Lead the master's stream (default on, see [`lead`]): a target is led along the
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
    queued: Option<path::Target<T>>,
    last_stamp_us: Option<u64>,
    latched: Option<Reading<T>>,
    braking: bool,
    warning: Option<Guard>,
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
    /// The parallel measure or a payload effort at a warn level at the last braking point
    /// checked.
    ahead_warn: Option<Guard>,
    /// A verified target accepted while moving: it replaces the goal once a braking-point
    /// check that looked past the goal (up to this target) has passed, since the checks
    /// before looked no farther than the goal.
    next_goal: Option<Pose<T>>,
    /// The braking-point job in progress was computed towards `next_goal`.
    job_for_next: bool,
    /// The parallel measure of the last full evaluation.
    parallel: T,
    /// The regions certified by the newest two full evaluations without a stop-level
    /// violation ([`crate::guards::certificate`]): a target whose segment lies in one is
    /// accepted at once, and a braking point whose stretch from the setpoint does needs
    /// no evaluation of its own.
    certs: [Option<Certificate<T>>; 2],
    /// The master's stream, for the lead.
    stream: lead::Stream<T>,
    /// The control period, µs.
    dt_us: u64,
    /// A braking point the evaluation phase found unsafe: the next step brakes.
    ahead_stop: bool,
    /// The evaluation phase ran since the last step.
    evaluated: bool,
    /// The profile limits at the setpoint, as the evaluation phase computed them for the
    /// next step (the setpoint does not change in between).
    next_limits: Option<ProfileLimits<T>>,
}

pub use crate::guards::MAX_STAGES;

/// What the checker is evaluating.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Job {
    /// A sample of the pending path.
    Path,
    /// The end of the pending path (checked first).
    PathEnd,
    /// The braking point.
    Ahead,
    /// The goal, to certify the region around it (when nothing else waits).
    Refresh,
}

/// One tick's step: the candidate setpoint, its twist and joint rates, what its kinematic
/// check solved and the warn-level guard it reached.
struct Step<T: Real> {
    pose: Pose<T>,
    twist: Twist<T>,
    qdot: Joints<T>,
    solved: Solved,
    warn: Option<Guard>,
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
            warning: verdict.violations.first().map(|r| r.guard),
            counters: Counters::default(),
            last_refusal: None,
            checker: Staged::new(branch),
            job: None,
            path_turn: true,
            cond_setpoint: ConditionEstimator::new(),
            cond_path: ConditionEstimator::new(),
            cond_path_end: ConditionEstimator::new(),
            cond_ahead: ConditionEstimator::new(),
            ahead_warn: None,
            next_goal: None,
            job_for_next: false,
            parallel: start_parallel,
            certs: [None; 2],
            stream: lead::Stream::default(),
            dt_us: (crate::scalar::to_f64(cfg.dt * lit(1e6)) + 0.5) as u64,
            ahead_stop: false,
            evaluated: true,
            next_limits: None,
        })
    }

    /// Stops as soon as the limits allow, e.g. when the master falls silent: forgets the
    /// pending and queued targets and brakes along the current twist at full deceleration
    /// (within the stretch the braking points have checked); the goal becomes where the
    /// robot comes to rest. Not a latched stop: new targets are taken.
    pub fn brake(&mut self) {
        self.drop_pending();
        self.stream.reset();
        if self.moving() {
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

    /// The newest certified region, if any (see [`crate::guards::certificate`]).
    pub fn certificate(&self) -> Option<&Certificate<T>> {
        self.certs[0].as_ref()
    }

    /// The latched stop reason.
    pub fn latched(&self) -> Option<&Reading<T>> {
        self.latched.as_ref()
    }

    /// The kinematic guard margins of the setpoint (from its solution, no new evaluation;
    /// see [`crate::guards::Guards::margins_at`]).
    pub fn setpoint_margins(&self) -> crate::guards::GuardMargins<T> {
        self.guards.margins_at(&self.evals.current().sol)
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
        self.stream.reset();
        self.braking = false;
        self.ahead_stop = false;
        Ok(())
    }

    /// Evaluates the kinematic guards at `pose` into the spare of `self.evals`
    /// (the solution and its Jacobians; [`Self::keep_candidate`] makes it the setpoint's):
    /// the first stop-level reading, whether a warn level is reached, and what was solved.
    ///
    /// A pose inside a certified region violates no stop-level guard (the region's
    /// guarantee, [`crate::guards::certificate`]): there only what the setpoint needs is
    /// solved ([`Guards::solve_certified`]: the inverse kinematics, the serial measures'
    /// warn level, the Jacobians), which is the same outcome at less cost.
    fn kinematic_check(&mut self, pose: &Pose<T>) -> (Option<Reading<T>>, Option<Guard>, Solved) {
        let mut stop = None;
        let mut warn = None;
        let mut visit = |r: &Reading<T>| match r.severity {
            Some(Severity::Stop) if stop.is_none() => stop = Some(*r),
            Some(Severity::Warn) if warn.is_none() => warn = Some(r.guard),
            _ => {}
        };
        let certified = self.certs.iter().flatten().any(|c| c.contains(pose));
        if certified {
            self.counters.setpoints_certified += 1;
        }
        // (The kinematic depth has no SVD to warm-start.)
        let cond = &mut self.cond_setpoint;
        let scratch = self.evals.spare_mut();
        let solved = if certified {
            self.guards.solve_certified(pose, &mut visit, scratch)
        } else {
            self.guards
                .evaluate_pose_into(pose, &mut visit, cond, scratch, Depth::Kinematic)
        };
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

    /// The joint kinds and the setpoint's Jacobian, when there is one (not at a serial
    /// singularity).
    fn setpoint_jacobian(&self) -> Option<&nalgebra::Matrix6<T>> {
        self.jacobians().map(|j| &j.j)
    }

    /// This tick's profile limits: the motion limits a hair inside (so that rounding
    /// never trips the motion guards that check the output), the accelerations within
    /// what the joints can follow at the setpoint ([`profile::joint_safe_accels`]).
    pub(super) fn profile_limits(&self) -> ProfileLimits<T> {
        let l = shaved(self.guards.limits());
        let (mut tip_accel, mut angular_accel) = (l.tip_accel, l.angular_accel);
        if let Some(j) = self.setpoint_jacobian() {
            (tip_accel, angular_accel) = profile::joint_safe_accels(
                j,
                &self.guards.robot().joint_kinds(),
                l.tip_accel,
                l.angular_accel,
                &l.joint_accel,
                self.cfg.joint_accel_headroom,
            );
        }
        ProfileLimits {
            tip_speed: l.tip_speed,
            angular_speed: l.angular_speed,
            tip_accel,
            angular_accel,
        }
    }

    /// One tick of the profile from the twist (`v0`, `w0`) towards the desired (`vd`,
    /// `wd`): each change limited to `l`'s accelerations (what the joints follow whatever
    /// the direction); while it slows down (neither speed grows), the full Cartesian
    /// accelerations scaled to what the joints follow for this change
    /// ([`profile::slowing_step`], never less), so that the profile keeps up with speed caps
    /// that fall as J grows towards a serial singularity. The speeds never grow faster than
    /// `l` allows, which the braking points assume, and slow at least as fast as `l` allows,
    /// which the braking curve assumes.
    fn profile_step(
        &self,
        l: &ProfileLimits<T>,
        (v0, w0): (&Vector3<T>, &Vector3<T>),
        (vd, wd): (&Vector3<T>, &Vector3<T>),
    ) -> (Vector3<T>, Vector3<T>) {
        let dt = self.cfg.dt;
        let slowing = norm3(vd) <= norm3(v0) && norm3(wd) <= norm3(w0);
        match self.setpoint_jacobian() {
            Some(j) if slowing => {
                let full = shaved(self.guards.limits());
                profile::slowing_step(
                    j,
                    &self.guards.robot().joint_kinds(),
                    (v0, w0),
                    (vd, wd),
                    (l.tip_accel, l.angular_accel),
                    (full.tip_accel, full.angular_accel),
                    &full.joint_accel,
                    self.cfg.joint_accel_headroom,
                    dt,
                )
            }
            _ => (
                v0 + profile::limit_step(vd - v0, l.tip_accel, dt),
                w0 + profile::limit_step(wd - w0, l.angular_accel, dt),
            ),
        }
    }

    /// The profile limits of a controlled stop along the twist (`v0`, `w0`): the full
    /// (shaved) decelerations scaled to what the joints can follow in this direction
    /// ([`profile::braking_accels`]), never less than `l`'s.
    fn braking_limits(
        &self,
        l: &ProfileLimits<T>,
        v0: &Vector3<T>,
        w0: &Vector3<T>,
    ) -> ProfileLimits<T> {
        let full = shaved(self.guards.limits());
        let Some(j) = self.setpoint_jacobian() else {
            return *l;
        };
        let (tip_accel, angular_accel) = profile::braking_accels(
            j,
            &self.guards.robot().joint_kinds(),
            v0,
            w0,
            full.tip_accel,
            full.angular_accel,
            &full.joint_accel,
            self.cfg.joint_accel_headroom,
        );
        ProfileLimits {
            tip_accel: tip_accel.max(l.tip_accel),
            angular_accel: angular_accel.max(l.angular_accel),
            ..*l
        }
    }

    /// Speed caps along the unit directions at the setpoint ([`profile::speed_caps`]).
    fn speed_caps(&self, l: &ProfileLimits<T>, dir_v: &Vector3<T>, dir_w: &Vector3<T>) -> (T, T) {
        match self.setpoint_jacobian() {
            Some(j) => profile::speed_caps(
                j,
                &self.guards.robot().joint_kinds(),
                l,
                &self.guards.limits().joint_speed,
                self.cfg.joint_speed_headroom,
                dir_v,
                dir_w,
            ),
            None => (l.tip_speed, l.angular_speed),
        }
    }

    fn hold(&mut self, reason: Reading<T>) -> TickOutput<T> {
        self.latched = Some(reason);
        self.ahead_stop = false;
        self.stream.reset();
        self.counters.stops += 1;
        self.twist = Twist::zeros();
        self.qdot = Joints::zeros();
        self.drop_pending();
        self.output(None)
    }

    fn output(&self, warning: Option<Guard>) -> TickOutput<T> {
        let moving = self.moving();
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
            warning: warning.is_some(),
            warn_guard: warning,
            stop: self.latched,
        }
    }

    /// The setpoint moves (its twist is not zero).
    fn moving(&self) -> bool {
        self.twist.iter().any(|x| *x != T::zero())
    }

    /// The setpoint's twist as its translational and angular velocities (v, ω).
    fn twist_parts(&self) -> (Vector3<T>, Vector3<T>) {
        let t = &self.twist;
        (Vector3::new(t.x, t.y, t.z), Vector3::new(t.w, t.a, t.b))
    }

    /// The braking points' horizon n in ticks (see [`Self::run_checker`]).
    fn horizon_ticks(&self) -> T {
        let per_job = MAX_STAGES.div_ceil(u32::from(self.cfg.stages_per_tick));
        lit::<T>(f64::from(3 * per_job))
    }

    /// A verified target waiting to replace the goal takes over as soon as the braking
    /// stretch towards it lies in a certified region. Tried when the target is accepted
    /// and at the end of every evaluation phase, on the state the next step starts from
    /// (its pose, twist and profile limits): the same check as at the start of that step,
    /// off the real-time step, so that a led stream moves the goal on every tick.
    pub(super) fn try_take_over(&mut self) {
        let Some(next) = self.next_goal else { return };
        let moving = self.moving();
        if !moving || self.braking || self.ahead_stop {
            return;
        }
        let l = match self.next_limits {
            Some(l) => l,
            None => self.profile_limits(),
        };
        let (v0, w0) = self.twist_parts();
        let n = self.horizon_ticks();
        let a = profile::braking_point(&self.pose, &v0, &w0, &next, &l, n, self.cfg.dt);
        if let Some(warn) = self.certified(&self.pose, &a) {
            self.counters.ahead_certified += 1;
            self.ahead_warn = warn;
            self.goal = next;
            self.next_goal = None;
        }
    }

    /// Runs `stages_per_tick` stages of the checker: a path sample or the braking point in
    /// turn (the braking point only while moving and not braking). Returns whether a
    /// braking point was found unsafe.
    ///
    /// It runs in the evaluation phase after step k, on the state step k left, which is
    /// the state step k + 1 starts from: a verdict found here is acted on by step k + 1,
    /// as if the stage had run at its start. The timing below counts in those periods.
    ///
    /// The braking point checked by a job that starts on this tick must cover what can
    /// happen until the next braking-point job has finished: a job takes at most L ticks
    /// (L = [`MAX_STAGES`] / `stages_per_tick`, rounded up) and the next one may wait for
    /// one path sample, so it finishes at most 3·L - 1 ticks after this one; until then the
    /// profile may accelerate, to v' = |v| + a·(3L - 1)·dt, and a violation found then
    /// starts braking from there. The point checked is where the robot, moving on for 3L
    /// ticks at v' along its current twist, would stop from v' ([`profile::braking_point`]:
    /// 3.7 mm ahead at 25 mm/s, 250 mm/s², L = 13), but no farther than the goal (or the
    /// verified target waiting to replace it): the profile stops there with deceleration
    /// in hand, so a target next to a boundary is reached; the goal changes only after a
    /// check that looked past it.
    fn run_checker(
        &mut self,
        l: &ProfileLimits<T>,
        moving: bool,
        v0: &Vector3<T>,
        w0: &Vector3<T>,
    ) -> bool {
        let stages = self.cfg.stages_per_tick;
        let n = self.horizon_ticks();
        let mut ahead_stop = false;
        for _ in 0..stages {
            if self.job.is_none() {
                let horizon = self.next_goal.unwrap_or(self.goal);
                let for_next = self.next_goal.is_some();
                let mut ahead = (moving && !self.braking).then(|| {
                    profile::braking_point(&self.pose, v0, w0, &horizon, l, n, self.cfg.dt)
                });
                // A braking point whose whole stretch from the setpoint lies in a
                // certified region passes at once (as a passed check would).
                if let Some(a) = ahead {
                    if let Some(warn) = self.certified(&self.pose, &a) {
                        self.counters.ahead_certified += 1;
                        self.ahead_warn = warn;
                        if for_next {
                            if let Some(next) = self.next_goal.take() {
                                self.goal = next;
                            }
                        }
                        ahead = None;
                    }
                }
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
        ahead_stop
    }

    /// The joint rates of the candidate's twist: J·twist with the Jacobian its kinematic
    /// check computed, or finite differences from the setpoint's joints when J is singular
    /// (the serial guard stops long before).
    fn candidate_rates(&self, twist: &Twist<T>, with_jacobian: bool) -> Joints<T> {
        let dt = self.cfg.dt;
        if with_jacobian {
            return Joints::from(profile::jac_times(
                &self.candidate().jac.j,
                &(*twist).into(),
            ));
        }
        let mut qd = (self.candidate().sol.q() - self.q) / dt;
        for (x, k) in qd.iter_mut().zip(self.guards.robot().joint_kinds().iter()) {
            if *k == JointKind::Angular {
                *x = wrap_angle(*x * dt) / dt;
            }
        }
        qd
    }

    /// The motion guards on the output itself (from the last output to this one): the
    /// first stop-level reading, if any.
    fn motion_stop(&self, twist: &Twist<T>, qdot: &Joints<T>) -> Option<Reading<T>> {
        let dt = self.cfg.dt;
        let prev = MotionSample {
            twist: self.twist,
            qdot: self.qdot,
        };
        let cur = MotionSample {
            twist: *twist,
            qdot: *qdot,
        };
        if self.guards.motion_within_limits(&prev, &cur, dt) {
            return None;
        }
        // The readings, for the stop's reason.
        let mut motion_stop = None;
        self.guards.evaluate_motion(&prev, &cur, dt, &mut |r| {
            if r.severity == Some(Severity::Stop) && motion_stop.is_none() {
                motion_stop = Some(*r);
            }
        });
        motion_stop
    }

    /// A step the motion guards refused, scaled down by β ([`profile::step_scales`]) to
    /// keep every joint within its speed and acceleration limits: the candidate displaced
    /// by β·twist·dt, with its own kinematic check and joint rates. While braking the least
    /// β (the shortest stop), else the largest (the least slow-down); a slower step stays
    /// on the stretch the braking points checked. `Err(Some(reading))` when the rescaled
    /// candidate violates a stop level, `Err(None)` when no β keeps the limits (or the
    /// rescaled step still does not): the caller holds.
    fn rescaled_step(&mut self, step: &Step<T>) -> Result<Step<T>, Option<Reading<T>>> {
        if step.solved != Solved::WithJacobian {
            return Err(None);
        }
        let l = shaved(self.guards.limits());
        let limits = profile::StepLimits {
            tip_accel: l.tip_accel,
            angular_accel: l.angular_accel,
            joint_speed: l.joint_speed,
            joint_accel: l.joint_accel,
        };
        let kinds = self.guards.robot().joint_kinds();
        let dt = self.cfg.dt;
        let (lo, hi) = profile::step_scales(
            &self.twist,
            &step.twist,
            &self.qdot,
            &step.qdot,
            &kinds,
            &limits,
            dt,
        )
        .ok_or(None)?;
        let beta = if self.braking { lo } else { hi };
        let twist = step.twist * beta;
        let (v, w) = (twist.fixed_rows::<3>(0), twist.fixed_rows::<3>(3));
        let pose = self.pose.displaced(&(v * dt), &(w * dt));
        let (stop, warn, solved) = self.kinematic_check(&pose);
        if let Some(r) = stop {
            return Err(Some(r));
        }
        if solved != Solved::WithJacobian {
            return Err(None);
        }
        let qdot = self.candidate_rates(&twist, true);
        if self.motion_stop(&twist, &qdot).is_some() {
            return Err(None);
        }
        self.counters.slowed += 1;
        Ok(Step {
            pose,
            twist,
            qdot,
            solved,
            warn: warn.or(self.ahead_warn),
        })
    }

    /// Snaps onto the (verified) goal and stops: its kinematic check first (the goal was
    /// checked in full: the end of its path, first of all).
    fn arrive(&mut self, at_goal: bool) -> TickOutput<T> {
        if !at_goal {
            let goal = self.goal;
            let (stop, warn, solved) = self.kinematic_check(&goal);
            if stop.is_none() && solved != Solved::No {
                self.keep_candidate(&goal, solved);
                self.warning = warn;
            }
        }
        self.twist = Twist::zeros();
        self.qdot = Joints::zeros();
        self.output(self.warning)
    }

    /// One control period: the step ([`Self::step`]), then the evaluation phase
    /// ([`Self::evaluate`]). Callers that write the step's output to the drives before
    /// the evaluation call the two themselves.
    pub fn tick(&mut self) -> TickOutput<T> {
        let out = self.step();
        self.evaluate();
        out
    }

    /// The evaluation phase of a period, after its step: `stages_per_tick` stages of the
    /// checker (`run_checker`). A braking point found unsafe is acted on by the next step.
    pub fn evaluate(&mut self) {
        self.evaluated = true;
        if self.latched.is_some() {
            return;
        }
        let moving = self.moving();
        let l = self.profile_limits();
        self.next_limits = Some(l);
        let (v0, w0) = self.twist_parts();
        if self.run_checker(&l, moving, &v0, &w0) {
            self.ahead_stop = true;
        }
        self.try_take_over();
    }

    /// The real-time step of a period: the profile's step towards the goal or a
    /// controlled stop ([`profile`]), the candidate setpoint's kinematic guards and the
    /// motion guards on the output. It acts on the verdicts of the evaluation phase
    /// before it; when that phase did not run (a scheduling fault), a moving robot brakes
    /// on the stretch checked before.
    pub fn step(&mut self) -> TickOutput<T> {
        let limits = self.next_limits.take();
        if self.latched.is_some() {
            return self.output(None);
        }
        let moving = self.moving();
        let l = limits.unwrap_or_else(|| self.profile_limits());
        let dt = self.cfg.dt;
        let (v0, w0) = self.twist_parts();
        let mut ahead_stop = core::mem::take(&mut self.ahead_stop);
        if !core::mem::replace(&mut self.evaluated, false) {
            self.counters.evaluations_missed += 1;
            ahead_stop |= moving;
        }
        // A stream fallen silent after a led target: back to the master's newest target.
        if let Some(plain) = self.stream.tick(self.dt_us) {
            self.take_target(&path::Target::plain(&plain));
        }
        // Standing still, a verified target waiting for a braking-point check takes over
        // at once (there is no motion to look past the goal).
        if !moving {
            if let Some(next) = self.next_goal.take() {
                self.goal = next;
            }
        }
        // Towards the goal (world frame), with the braking profile.
        let e_t = self.goal.t - self.pose.t;
        let e_r = rotation_vector(&(self.goal.r * self.pose.r.inverse()));
        let (d, a) = (norm3(&e_t), norm3(&e_r));
        if !self.braking && self.pending.is_none() && profile::arrived(d, a, &v0, &w0, &l, dt) {
            return self.arrive(d + a == T::zero());
        }
        // At rest on the goal (e.g. while a new target is being verified): the setpoint
        // stays, and it was checked when it became the setpoint.
        if !self.braking && d + a == T::zero() && !moving {
            self.twist = Twist::zeros();
            self.qdot = Joints::zeros();
            return self.output(self.warning);
        }
        let candidate;
        let (v1, w1);
        if ahead_stop || self.braking {
            // Brake on the stretch checked before: decelerate along the current twist, at
            // the full deceleration on every tick until the robot stands.
            if !self.braking {
                self.counters.brakes += 1;
            }
            self.braking = true;
            self.drop_pending();
            let b = self.braking_limits(&l, &v0, &w0);
            v1 = profile::step_braking(&v0, b.tip_accel, dt);
            w1 = profile::step_braking(&w0, b.angular_accel, dt);
            candidate = self.pose.displaced(&(v1 * dt), &(w1 * dt));
            self.goal = profile::stop_point(&v1, &w1, &candidate, &b);
        } else {
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
            let vd = profile::desired_velocity(&dir_v, d, vcap, l.tip_accel, dt);
            let wd = profile::desired_velocity(&dir_w, a, wcap, l.angular_accel, dt);
            (v1, w1) = self.profile_step(&l, (&v0, &w0), (&vd, &wd));
            candidate = self.pose.displaced(&(v1 * dt), &(w1 * dt));
        }
        let (stop, warn, solved) = self.kinematic_check(&candidate);
        // A warn level of the parallel measure or a payload effort reached at the braking
        // point is reported as well (those are only evaluated there while moving).
        let warn = warn.or(self.ahead_warn);
        match (stop, solved) {
            (Some(r), _) => return self.hold(r),
            (None, Solved::No) => return self.output(warn), // unreachable: no solution is a stop
            _ => {}
        }
        // The guards computed the candidate's Jacobians already (in the scratch): reuse them.
        let mut step = Step {
            pose: candidate,
            twist: Twist::new(v1.x, v1.y, v1.z, w1.x, w1.y, w1.z),
            qdot: Joints::zeros(),
            solved,
            warn,
        };
        step.qdot = self.candidate_rates(&step.twist, solved == Solved::WithJacobian);
        if let Some(r) = self.motion_stop(&step.twist, &step.qdot) {
            step = match self.rescaled_step(&step) {
                Ok(s) => s,
                Err(reason) => return self.hold(reason.unwrap_or(r)),
            };
            if self.braking {
                let (v, w) = (step.twist.fixed_rows::<3>(0), step.twist.fixed_rows::<3>(3));
                let b = self.braking_limits(&l, &v0, &w0);
                self.goal = profile::stop_point(&v.into(), &w.into(), &step.pose, &b);
            }
        }
        let Step {
            pose: candidate,
            twist,
            qdot,
            solved,
            warn,
        } = step;
        self.keep_candidate(&candidate, solved);
        self.qdot = qdot;
        self.twist = twist;
        self.warning = warn;
        if warn.is_some() {
            self.counters.warn_ticks += 1;
        }
        if self.braking && twist.iter().all(|x| *x == T::zero()) {
            self.braking = false;
            self.goal = self.pose;
        }
        self.output(warn)
    }
}
