//! A full pose evaluation spread over several calls, one stage per call, for a caller
//! with a fixed budget per control tick (the supervisor).

use crate::branch::Branch;
use crate::ik::inverse_into;
use crate::jacobian::{jacobian_into, tripod_jacobian};
use crate::mechanism::Mechanism;
use crate::pose::Pose;
use crate::scalar::Real;
use crate::singularity::ConditionEstimator;

use super::certificate::{FullEvaluation, GuardMinima};
use super::pose::Evaluation;
use super::readings::{unreachable, Guard, Reading, Severity};
use super::setup::Guards;
use crate::statics::Statics;

/// The stages of a staged full evaluation, in order.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stage {
    /// Workspace box and tilt cone, inverse kinematics, joint ranges, spherical-joint
    /// tilts, collision, serial singularity.
    Kinematic,
    /// The Jacobians (Eq. 7.14, 7.18), and the start of the parallel measure's SVD
    /// ([`ConditionEstimator::begin`]).
    Jacobian,
    /// One sweep of the parallel measure's SVD ([`ConditionEstimator::sweep`]); repeated
    /// until it converges (one or two sweeps warm-started, four or five cold, at most
    /// [`crate::singularity::MAX_SWEEPS`]).
    Parallel,
    /// The payload statics (Eq. 7.10): actuator forces and torques.
    Statics,
}

/// The most stages a staged evaluation takes: the kinematic stage, the Jacobian, every
/// sweep the SVD may take, the statics.
pub const MAX_STAGES: u32 = 3 + crate::singularity::MAX_SWEEPS as u32;

/// A full guard evaluation spread over several calls of [`Guards::advance`], one
/// [`Stage`] per call, so that a caller with a fixed budget per control tick (the
/// supervisor) never runs a whole evaluation in one tick. Run to the end it reaches the
/// verdict of [`Guards::evaluate_pose`]: the same first stop-level reading, and whether a
/// warn level was reached (when nothing stops).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Staged<T: Real> {
    pose: Pose<T>,
    eval: Evaluation<T>,
    jac_ok: bool,
    inv_cond: T,
    inv_cond_ok: bool,
    /// The SVD's largest singular value of the scaled Jtilde (with `inv_cond`).
    sigma_max: T,
    stop: Option<Reading<T>>,
    warn: bool,
    next: Option<Stage>,
    /// The smallest margin of each guard so far.
    minima: GuardMinima<T>,
    /// The payload statics, once computed.
    statics: Option<Statics<T>>,
    /// The first guard of the parallel measure or the payload efforts at a warn level.
    late_warn: Option<Guard>,
}

impl<T: Real> Staged<T> {
    /// Nothing to evaluate (finished).
    pub fn new(branch: Branch) -> Self {
        Staged {
            pose: Pose::central(T::zero()),
            eval: Evaluation::new(branch),
            jac_ok: false,
            inv_cond: T::zero(),
            inv_cond_ok: false,
            sigma_max: T::zero(),
            stop: None,
            warn: false,
            next: None,
            minima: GuardMinima::new(),
            statics: None,
            late_warn: None,
        }
    }
    /// Starts over at `pose`.
    pub fn start(&mut self, pose: &Pose<T>) {
        self.pose = *pose;
        self.jac_ok = false;
        self.inv_cond_ok = false;
        self.sigma_max = T::zero();
        self.stop = None;
        self.warn = false;
        self.next = Some(Stage::Kinematic);
        self.minima = GuardMinima::new();
        self.statics = None;
        self.late_warn = None;
    }
    /// The pose being evaluated.
    pub fn pose(&self) -> &Pose<T> {
        &self.pose
    }
    /// The stage the next call runs (None: finished).
    pub fn next_stage(&self) -> Option<Stage> {
        self.next
    }
    /// Whether the evaluation has finished.
    pub fn is_finished(&self) -> bool {
        self.next.is_none()
    }
    /// The first stop-level reading so far.
    pub fn stop(&self) -> Option<&Reading<T>> {
        self.stop.as_ref()
    }
    /// Whether a warn level was reached so far.
    pub fn warn(&self) -> bool {
        self.warn
    }
    /// The parallel measure (inverse condition number), once its SVD has converged.
    pub fn inv_cond(&self) -> Option<T> {
        self.inv_cond_ok.then_some(self.inv_cond)
    }
    /// The first guard among the parallel measure and the payload efforts found at a warn
    /// level (the kinematic guards' warn levels follow the setpoint's own solution).
    pub fn late_warn(&self) -> Option<Guard> {
        self.late_warn
    }
    /// What the finished evaluation computed, for [`Guards::certify`]: None unless it ran
    /// to the end (statics included) without a stop-level reading.
    pub fn full(&self) -> Option<FullEvaluation<'_, T>> {
        let statics = self.statics.as_ref()?;
        (self.next.is_none() && self.stop.is_none() && self.jac_ok && self.inv_cond_ok).then_some({
            FullEvaluation {
                sol: &self.eval.sol,
                jac: &self.eval.jac,
                inv_cond: self.inv_cond,
                sigma_max: self.sigma_max,
                statics,
                minima: &self.minima,
                warn: self.late_warn,
            }
        })
    }
}

impl<T: Real, M: Mechanism<T>> Guards<T, M> {
    /// Runs the next stage of a staged full evaluation (see [`Staged`]): one of the
    /// inverse kinematics with the kinematic guards, the Jacobians (and the start of the
    /// SVD), one sweep of the parallel measure's SVD (warm-started by `cond`, which holds
    /// the decomposition in progress between the calls), the payload statics. The
    /// evaluation ends early at the first stop-level reading.
    pub fn advance(&self, st: &mut Staged<T>, cond: &mut ConditionEstimator<T>) {
        let Some(stage) = st.next else { return };
        let Staged {
            pose,
            eval,
            jac_ok,
            inv_cond,
            inv_cond_ok,
            sigma_max,
            stop,
            warn,
            next,
            minima,
            statics,
            late_warn,
        } = st;
        let mut visit = |r: &Reading<T>| {
            minima.record(r.guard, r.margin);
            match r.severity {
                Some(Severity::Stop) if stop.is_none() => *stop = Some(*r),
                Some(Severity::Warn) => {
                    *warn = true;
                    let late = matches!(
                        r.guard,
                        Guard::ParallelSingularity | Guard::Force | Guard::Torque
                    );
                    if late && late_warn.is_none() {
                        *late_warn = Some(r.guard);
                    }
                }
                _ => {}
            }
        };
        *next = match stage {
            Stage::Kinematic => {
                self.workspace_readings(pose, &mut visit);
                match inverse_into(&self.robot, pose, self.branch, &mut eval.sol) {
                    Err(e) => {
                        visit(&unreachable(e.chain));
                        None
                    }
                    Ok(()) => {
                        self.kinematic_readings(&eval.sol, &mut visit);
                        Some(Stage::Jacobian)
                    }
                }
            }
            Stage::Jacobian => {
                *jac_ok = jacobian_into(&self.robot, &eval.sol, &mut eval.jac).is_ok();
                // The SVD of Jtilde (computed alone at a serial singularity, where J is
                // not).
                let computed;
                let jtilde = if *jac_ok {
                    &eval.jac.jtilde
                } else {
                    computed = tripod_jacobian(&eval.sol);
                    &computed
                };
                match cond.begin(jtilde, self.robot.rp()) {
                    Ok(()) => Some(Stage::Parallel),
                    Err(e) => {
                        self.parallel_verdict(Err(e), &mut visit);
                        None
                    }
                }
            }
            Stage::Parallel => match cond.sweep() {
                None => Some(Stage::Parallel),
                Some(result) => {
                    let value = self.parallel_verdict(result, &mut visit);
                    if let Some(x) = value {
                        *inv_cond = x;
                        *inv_cond_ok = true;
                        *sigma_max = cond.sigma_max();
                    }
                    match value {
                        Some(_) if *jac_ok => Some(Stage::Statics),
                        _ => None,
                    }
                }
            },
            Stage::Statics => {
                *statics = self.statics_readings(&eval.jac, pose, *inv_cond, &mut visit);
                None
            }
        };
        if stop.is_some() {
            *next = None;
        }
    }
}
