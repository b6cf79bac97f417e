//! The supervisor's state, how it starts, and what it tells its callers between ticks.
//! The operations on it are in the files of their concepts (see the module
//! documentation of [`super`]).

use crate::branch::Branch;
use crate::double_buffer::DoubleBuffer;
use crate::guards::{Certificate, Evaluation, Guard, GuardMargins, Guards, Limits, Reading};
use crate::jacobian::{jacobian_into, Jacobians};
use crate::mechanism::Mechanism;
use crate::pose::Pose;
use crate::scalar::{lit, Real};
use crate::singularity::ConditionEstimator;
use crate::vectors::{Joints, Twist};

use super::checker::Checker;
use super::config::{SupervisorConfig, SupervisorError};
use super::lead::Stream;
use super::mode::Activity;
use super::path::{Pending, Target};
use super::profile::ProfileLimits;
use super::report::{Counters, Margins, Refusal};

/// The setpoint supervisor.
#[derive(Clone, Debug)]
pub struct Supervisor<T: Real, M: Mechanism<T>> {
    pub(super) guards: Guards<T, M>,
    pub(super) cfg: SupervisorConfig<T>,
    /// The control period, µs.
    pub(super) dt_us: u64,
    /// The setpoint: its pose, joints, joint rates and twist.
    pub(super) pose: Pose<T>,
    pub(super) q: Joints<T>,
    pub(super) qdot: Joints<T>,
    pub(super) twist: Twist<T>,
    /// The setpoint's solution and Jacobians (the current one; J for the joint-speed caps,
    /// valid when `jac_ok`, not at a serial singularity) and the candidate's (the spare): a
    /// kept candidate swaps the roles, so nothing is copied.
    pub(super) evals: DoubleBuffer<Evaluation<T>>,
    pub(super) jac_ok: bool,
    /// The warn-level guard reached at the setpoint.
    pub(super) warning: Option<Guard>,
    /// What the supervisor is doing, with the goal ([`super::mode`]).
    pub(super) activity: Activity<T>,
    /// What the last evaluation phase left for the next step; None when it has not run
    /// since the last step.
    pub(super) handoff: Option<Handoff<T>>,
    /// The path in verification.
    pub(super) pending: Option<Pending<T>>,
    /// The newest target that arrived while another was being verified; it is verified
    /// next (older queued ones are superseded), so a fast stream never starves the check.
    pub(super) queued: Option<Target<T>>,
    pub(super) last_stamp_us: Option<u64>,
    /// The master's stream, for the lead.
    pub(super) stream: Stream<T>,
    /// The full evaluations of path samples, braking points and the goal, one at a time.
    pub(super) checker: Checker<T>,
    /// The warm start of the setpoint's own check (the kinematic depth has no SVD to
    /// warm-start, but the guards take one).
    pub(super) cond_setpoint: ConditionEstimator<T>,
    /// The parallel measure or a payload effort at a warn level at the last braking point
    /// checked.
    pub(super) ahead_warn: Option<Guard>,
    /// The parallel measure of the last full evaluation.
    pub(super) parallel: T,
    /// The regions certified by the newest two full evaluations without a stop-level
    /// violation ([`crate::guards::certificate`]): a target whose segment lies in one is
    /// accepted at once, and a braking point whose stretch from the setpoint does needs
    /// no evaluation of its own.
    pub(super) certs: [Option<Certificate<T>>; 2],
    pub(super) counters: Counters,
    pub(super) last_refusal: Option<Refusal<T>>,
}

/// What an evaluation phase leaves for the step after it (the setpoint does not change in
/// between).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Handoff<T: Real> {
    /// The profile limits at the setpoint, as the phase computed them (None when it ran
    /// while stopped).
    pub limits: Option<ProfileLimits<T>>,
    /// A braking point was found unsafe: the step brakes.
    pub brake: bool,
}

impl<T: Real> Handoff<T> {
    /// No limits computed, nothing found.
    pub const NOTHING: Self = Handoff {
        limits: None,
        brake: false,
    };
}

/// How the start pose checked: its evaluation (solution and Jacobians), whether it has a
/// Jacobian, its warning and its parallel measure.
struct Start<T: Real> {
    eval: Evaluation<T>,
    jac_ok: bool,
    warning: Option<Guard>,
    parallel: T,
}

/// The start pose's checks: no stop-level violation, an inverse-kinematics solution, and
/// the parallel measure of one full evaluation (NaN if it failed).
fn check_start<T: Real, M: Mechanism<T>>(
    guards: &Guards<T, M>,
    start: &Pose<T>,
) -> Result<Start<T>, SupervisorError<T>> {
    let (verdict, sol) = guards.check_pose(start);
    let mut parallel = lit::<T>(f64::NAN);
    guards.evaluate_pose(start, &mut |r| {
        if r.guard == Guard::ParallelSingularity {
            parallel = r.value;
        }
    });
    let sol = match (verdict.is_stop(), sol) {
        (false, Some(s)) => s,
        _ => return Err(SupervisorError::UnsafeStart(verdict.first_stop().copied())),
    };
    let mut eval = Evaluation::new(guards.branch());
    eval.sol = sol;
    let jac_ok = jacobian_into(guards.robot(), &sol, &mut eval.jac).is_ok();
    Ok(Start {
        eval,
        jac_ok,
        warning: verdict.violations.first().map(|r| r.guard),
        parallel,
    })
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
        cfg.validate()?;
        let guards = Guards::new(robot, branch, limits).map_err(SupervisorError::Setup)?;
        let s = check_start(&guards, start)?;
        Ok(Supervisor {
            guards,
            cfg,
            dt_us: cfg.dt_us(),
            pose: *start,
            q: s.eval.sol.q(),
            qdot: Joints::zeros(),
            twist: Twist::zeros(),
            evals: DoubleBuffer::new(s.eval, Evaluation::new(branch)),
            jac_ok: s.jac_ok,
            warning: s.warning,
            activity: Activity::holding(start),
            handoff: Some(Handoff::NOTHING),
            pending: None,
            queued: None,
            last_stamp_us: None,
            stream: Stream::default(),
            checker: Checker::new(branch),
            cond_setpoint: ConditionEstimator::new(),
            ahead_warn: None,
            parallel: s.parallel,
            certs: [None; 2],
            counters: Counters::default(),
            last_refusal: None,
        })
    }

    /// The guards in use.
    pub fn guards(&self) -> &Guards<T, M> {
        &self.guards
    }

    /// The counters.
    pub fn config(&self) -> &SupervisorConfig<T> {
        &self.cfg
    }

    /// Counts of what it refused or did.
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
        self.activity.latched()
    }

    /// The kinematic guard margins of the setpoint (from its solution, no new evaluation;
    /// see [`crate::guards::Guards::margins_at`]).
    pub fn setpoint_margins(&self) -> GuardMargins<T> {
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
}
