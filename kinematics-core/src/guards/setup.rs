//! The guards prepared for one robot and branch: the limits validated, the central joint
//! values (the reference of the angle ranges) and the spherical joints' socket axes
//! computed once. The evaluations are in [`super::pose`], [`super::staged`],
//! [`super::motion`] and [`super::certificate`].

use crate::branch::Branch;
use crate::chain::PerChain;
use crate::ik::{inverse, IkError};
use crate::mechanism::Mechanism;
use crate::pose::Pose;
use crate::scalar::Real;
use crate::tilt::SocketAxes;
use core::fmt;

use super::limits::{Limits, LimitsError};

/// Why the guards cannot be set up.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum GuardSetupError {
    Limits(LimitsError),
    /// The central configuration (the reference of link angles and socket axes) has no
    /// solution.
    Central(IkError),
}

impl fmt::Display for GuardSetupError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            GuardSetupError::Limits(e) => write!(f, "limits: {e}"),
            GuardSetupError::Central(e) => write!(f, "central configuration: {e}"),
        }
    }
}

/// The guards prepared for one robot and branch.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Guards<T: Real, M: Mechanism<T>> {
    pub(super) robot: M,
    pub(super) branch: Branch,
    pub(super) limits: Limits<T>,
    pub(super) axes: SocketAxes<T>,
    /// (qa, qb) of each chain at the central configuration: the reference of the angle ranges.
    pub(super) central: PerChain<(T, T)>,
}

impl<T: Real, M: Mechanism<T>> Guards<T, M> {
    /// Prepares the guards: validates the limits and computes the central joint values and
    /// socket axes.
    pub fn new(robot: M, branch: Branch, limits: Limits<T>) -> Result<Self, GuardSetupError> {
        limits.validate().map_err(GuardSetupError::Limits)?;
        let central = inverse(&robot, &Pose::central(robot.hc()), branch)
            .map_err(GuardSetupError::Central)?;
        let axes = SocketAxes::new(&robot).map_err(GuardSetupError::Central)?;
        Ok(Guards {
            robot,
            branch,
            limits,
            axes,
            central: central.chains.map(|_, c| (c.qa, c.qb)),
        })
    }

    /// The robot.
    pub fn robot(&self) -> &M {
        &self.robot
    }
    /// The branch.
    pub fn branch(&self) -> Branch {
        self.branch
    }
    /// The limits.
    pub fn limits(&self) -> &Limits<T> {
        &self.limits
    }
}
