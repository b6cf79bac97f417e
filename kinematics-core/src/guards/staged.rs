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
    next: Option<Stage>,
    /// The payload statics, once computed.
    statics: Option<Statics<T>>,
    /// What the readings so far found.
    found: Findings<T>,
}

/// What the readings of a staged evaluation found so far.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Findings<T: Real> {
    /// The first stop-level reading.
    stop: Option<Reading<T>>,
    /// A warn level was reached.
    warn: bool,
    /// The smallest margin of each guard.
    minima: GuardMinima<T>,
    /// The first guard of the parallel measure or the payload efforts at a warn level.
    late_warn: Option<Guard>,
}

impl<T: Real> Findings<T> {
    /// Nothing found yet.
    fn new() -> Self {
        Findings {
            stop: None,
            warn: false,
            minima: GuardMinima::new(),
            late_warn: None,
        }
    }

    /// Records one reading.
    #[inline]
    fn visit(&mut self, r: &Reading<T>) {
        self.minima.record(r.guard, r.margin);
        match r.severity {
            Some(Severity::Stop) if self.stop.is_none() => self.stop = Some(*r),
            Some(Severity::Warn) => {
                self.warn = true;
                let late = matches!(
                    r.guard,
                    Guard::ParallelSingularity | Guard::Force | Guard::Torque
                );
                if late && self.late_warn.is_none() {
                    self.late_warn = Some(r.guard);
                }
            }
            _ => {}
        }
    }
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
            next: None,
            statics: None,
            found: Findings::new(),
        }
    }
    /// Starts over at `pose`.
    pub fn start(&mut self, pose: &Pose<T>) {
        self.pose = *pose;
        self.jac_ok = false;
        self.inv_cond_ok = false;
        self.sigma_max = T::zero();
        self.next = Some(Stage::Kinematic);
        self.statics = None;
        self.found = Findings::new();
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
        self.found.stop.as_ref()
    }
    /// Whether a warn level was reached so far.
    pub fn warn(&self) -> bool {
        self.found.warn
    }
    /// The parallel measure (inverse condition number), once its SVD has converged.
    pub fn inv_cond(&self) -> Option<T> {
        self.inv_cond_ok.then_some(self.inv_cond)
    }
    /// The first guard among the parallel measure and the payload efforts found at a warn
    /// level (the kinematic guards' warn levels follow the setpoint's own solution).
    pub fn late_warn(&self) -> Option<Guard> {
        self.found.late_warn
    }
    /// What the finished evaluation computed, for [`Guards::certify`]: None unless it ran
    /// to the end (statics included) without a stop-level reading.
    pub fn full(&self) -> Option<FullEvaluation<'_, T>> {
        let statics = self.statics.as_ref()?;
        (self.next.is_none() && self.found.stop.is_none() && self.jac_ok && self.inv_cond_ok)
            .then_some({
                FullEvaluation {
                    sol: &self.eval.sol,
                    jac: &self.eval.jac,
                    inv_cond: self.inv_cond,
                    sigma_max: self.sigma_max,
                    statics,
                    minima: &self.found.minima,
                    warn: self.found.late_warn,
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
        let next = match stage {
            Stage::Kinematic => self.kinematic_stage(st),
            Stage::Jacobian => self.jacobian_stage(st, cond),
            Stage::Parallel => self.parallel_stage(st, cond),
            Stage::Statics => {
                let found = &mut st.found;
                st.statics = self
                    .statics_readings(&st.eval.jac, &st.pose, st.inv_cond, &mut |r| found.visit(r));
                None
            }
        };
        st.next = if st.found.stop.is_some() { None } else { next };
    }

    /// The workspace guards, the inverse kinematics and the kinematic guards.
    fn kinematic_stage(&self, st: &mut Staged<T>) -> Option<Stage> {
        let found = &mut st.found;
        let mut visit = |r: &Reading<T>| found.visit(r);
        self.workspace_readings(&st.pose, &mut visit);
        match inverse_into(&self.robot, &st.pose, self.branch, &mut st.eval.sol) {
            Err(e) => {
                visit(&unreachable(e.chain));
                None
            }
            Ok(()) => {
                self.kinematic_readings(&st.eval.sol, &mut visit);
                Some(Stage::Jacobian)
            }
        }
    }

    /// The Jacobians, and the start of the parallel measure's SVD (of Jtilde, computed
    /// alone at a serial singularity, where J is not).
    fn jacobian_stage(
        &self,
        st: &mut Staged<T>,
        cond: &mut ConditionEstimator<T>,
    ) -> Option<Stage> {
        let eval = &mut st.eval;
        st.jac_ok = jacobian_into(&self.robot, &eval.sol, &mut eval.jac).is_ok();
        let computed;
        let jtilde = if st.jac_ok {
            &eval.jac.jtilde
        } else {
            computed = tripod_jacobian(&eval.sol);
            &computed
        };
        match cond.begin(jtilde, self.robot.rp()) {
            Ok(()) => Some(Stage::Parallel),
            Err(e) => {
                self.parallel_verdict(Err(e), &mut |r| st.found.visit(r));
                None
            }
        }
    }

    /// One sweep of the parallel measure's SVD; once it has converged, its verdict (and
    /// the statics next, when the Jacobians exist).
    fn parallel_stage(
        &self,
        st: &mut Staged<T>,
        cond: &mut ConditionEstimator<T>,
    ) -> Option<Stage> {
        let Some(result) = cond.sweep() else {
            return Some(Stage::Parallel);
        };
        let value = self.parallel_verdict(result, &mut |r| st.found.visit(r));
        if let Some(x) = value {
            st.inv_cond = x;
            st.inv_cond_ok = true;
            st.sigma_max = cond.sigma_max();
        }
        match value {
            Some(_) if st.jac_ok => Some(Stage::Statics),
            _ => None,
        }
    }
}
