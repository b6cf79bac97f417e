//! The loads a known tool puts on the joints along the homing's path, checked before the
//! homing moves anything.
//!
//! Homing drives the joint being homed open loop, at a small duty, towards its switch or
//! hard stop ([`crate::homing`]), while the others hold under servo. A tool's weight that
//! pulls the joint against its approach with more than a share of the push's effort would
//! stop it short (taken for a stall) or drive it; one that asks more of a held joint than
//! its rating would trip the overload monitor in the middle of the homing. With the tool
//! declared ([`crate::ToolLoad`]), the path is known before it starts: the configurations
//! where each joint begins and ends its approach (the joints homed before it backed off
//! their references, the others where they rest). At each, the forward kinematics give the
//! pose, the statics the efforts that hold the tool (τ = J⁻ᵀ s_e, Eq. 7.10), and the
//! homing is refused before it starts when one does not fit.

use kinematics_core::statics::forces_with_inv_cond;
use kinematics_core::{forward, jacobian, Branch, FkConfig, Joints, Mechanism, Pose};
use servo::NUM_JOINTS;

use crate::current::{CurrentLimits, MotorModel};
use crate::homing::HomingConfig;
use crate::planner::ToolLoad;
use crate::scalar::{lit, Scalar};

/// Why a homing with the declared tool is refused.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LoadRefusal<S> {
    /// The tool pulls `joint` against its approach with `effort` (N or N m); the push
    /// allows at most `allowed`.
    AgainstApproach {
        /// The joint.
        joint: usize,
        /// The effort, N or N m.
        effort: S,
        /// The most the push allows, N or N m.
        allowed: S,
    },
    /// Holding the tool asks `effort` of `joint`, above `allowed` (its rating's share).
    AboveRating {
        /// The joint.
        joint: usize,
        /// The effort, N or N m.
        effort: S,
        /// The most it may hold while homing, N or N m.
        allowed: S,
    },
    /// A configuration of the path has no pose or no statics (the check cannot vouch for
    /// it).
    Unknown {
        /// The joint being homed there.
        joint: usize,
    },
}

impl<S> LoadRefusal<S> {
    /// The joint concerned.
    pub fn joint(&self) -> usize {
        match self {
            LoadRefusal::AgainstApproach { joint, .. }
            | LoadRefusal::AboveRating { joint, .. }
            | LoadRefusal::Unknown { joint } => *joint,
        }
    }
}

/// The share of each joint's peak effort a held joint may give to the tool while homing.
const HOLD_SHARE: f64 = 0.8;

/// Checks the homing of `homing` from `rest` with the tool `tool` (see the module
/// documentation); `supply_v` sets the push's effort.
#[allow(clippy::too_many_arguments)]
pub fn check<S: Scalar, M: Mechanism<S>>(
    robot: &M,
    branch: Branch,
    fk: &FkConfig<S>,
    homing: &HomingConfig<S>,
    rest: &[S; NUM_JOINTS],
    tool: &ToolLoad<S>,
    motors: &[MotorModel<S>; NUM_JOINTS],
    limits: &[CurrentLimits<S>; NUM_JOINTS],
    supply_v: S,
) -> Result<(), LoadRefusal<S>> {
    let mut q = *rest;
    let mut guess = Pose::central(robot.hc());
    for j in homing.order.map(usize::from) {
        let (Some(h), Some(m)) = (homing.joints.get(j), motors.get(j)) else {
            return Err(LoadRefusal::Unknown { joint: j });
        };
        let sign = if h.towards_positive {
            S::one()
        } else {
            -S::one()
        };
        // The push at stall: the approach's duty across the winding.
        let push = h.approach_duty * supply_v / m.resistance_ohm * m.effort_per_amp;
        let start = q;
        let mut end = q;
        if let Some(x) = end.get_mut(j) {
            *x = h.home_position;
        }
        for config in [start, end] {
            let tau = efforts(robot, branch, fk, &config, &mut guess, tool)
                .ok_or(LoadRefusal::Unknown { joint: j })?;
            let against = sign * tau.get(j).copied().unwrap_or_else(S::zero);
            let allowed = push * h.load_share;
            if against > allowed {
                return Err(LoadRefusal::AgainstApproach {
                    joint: j,
                    effort: against,
                    allowed,
                });
            }
            for (k, (t, l)) in tau.iter().zip(limits.iter()).enumerate() {
                let allowed = l.effort_limit * lit(HOLD_SHARE);
                if !(t.abs() <= allowed) {
                    return Err(LoadRefusal::AboveRating {
                        joint: k,
                        effort: t.abs(),
                        allowed,
                    });
                }
            }
        }
        // It ends backed off its reference.
        if let Some(x) = q.get_mut(j) {
            *x = h.home_position - sign * h.backoff_distance;
        }
    }
    Ok(())
}

/// The efforts that hold the tool at the joints `q` (τ = J⁻ᵀ s_e, Eq. 7.10), the pose
/// solved from `guess` (which it becomes).
fn efforts<S: Scalar, M: Mechanism<S>>(
    robot: &M,
    branch: Branch,
    fk: &FkConfig<S>,
    q: &[S; NUM_JOINTS],
    guess: &mut Pose<S>,
    tool: &ToolLoad<S>,
) -> Option<[S; NUM_JOINTS]> {
    let joints = Joints::from_row_slice(q);
    let sol = forward(robot, &joints, branch, guess, fk).ok()?;
    *guess = sol.pose;
    let jac = jacobian(robot, &sol.solution).ok()?;
    let st = forces_with_inv_cond(&jac, &tool.wrench(&sol.pose), S::one(), S::zero()).ok()?;
    Some(core::array::from_fn(|k| {
        st.tau.get(k).copied().unwrap_or_else(S::zero)
    }))
}
