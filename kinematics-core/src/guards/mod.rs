//! The guards that keep every setpoint safe (thesis 3.2 and 11.4).
//!
//! One [`Limits`] value holds every limit; [`Guards`] prepares it for one robot and branch
//! (socket axes, central joint values) and evaluates a pose. Every guard produces a
//! [`Reading`] with the measured value, the limit and the signed margin, so the same code
//! gives a [`Verdict`] (the violations, each with its severity) for the supervisor and the
//! worst margins for the design tools. Nothing here allocates or panics.
//!
//! - [`readings`]: the vocabulary (guards, subjects, severities, readings, verdicts);
//! - [`limits`]: the limits and their reference values;
//! - [`pose`]: the pose guards (workspace, reach, joint ranges, tilt, collision,
//!   singularities, payload statics), in place ([`Guards::evaluate_pose_into`]) or as a
//!   convenience ([`Guards::evaluate_pose`], [`Guards::check_pose`]);
//! - [`staged`]: a full pose evaluation spread over several calls, one stage each;
//! - [`motion`]: the motion guards (speeds and accelerations of the platform and joints).

use crate::branch::Branch;
use crate::chain::PerChain;
use crate::ik::{inverse, IkError};
use crate::mechanism::Mechanism;
use crate::pose::Pose;
use crate::scalar::Real;
use crate::tilt::SocketAxes;
use core::fmt;

pub mod certificate;
pub mod limits;
pub mod motion;
pub mod pose;
pub mod readings;
pub mod staged;

pub use certificate::{Certificate, Constraint, FullEvaluation, GuardMinima, Rate};
pub use limits::{Levels, Limits, LimitsError};
pub use motion::MotionSample;
pub use pose::{orientation_distance, Depth, Evaluation, GuardMargins, Solved};
pub use readings::{Guard, Reading, Severity, Subject, Verdict, MAX_VIOLATIONS};
pub use staged::{Stage, Staged, MAX_STAGES};

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
    robot: M,
    branch: Branch,
    limits: Limits<T>,
    axes: SocketAxes<T>,
    /// (qa, qb) of each chain at the central configuration: the reference of the angle ranges.
    central: PerChain<(T, T)>,
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
