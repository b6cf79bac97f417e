//! The guards' verdict on a pose at the edge: the guards of `kinematics-core` prepared on
//! every branch for a robot and its limits ([`Check`]), the violations at a pose, and their
//! texts in the guards' edge units (`host-sim check`'s `violations` column, the `guards`
//! column of `ik`, `fk`, `jacobian` and `forces`, and the Python module's `check`).

use crate::units::fixed;
use kinematics_core::guards::{Guard, GuardSetupError, Guards, Limits, Reading, Severity, Subject};
use kinematics_core::{Branch, Pose, Robot};
use thiserror::Error;

/// Why a branch has no guards to evaluate.
#[derive(Clone, Copy, Debug, PartialEq, Error)]
pub enum VerdictError {
    /// The guards of a branch cannot be set up for the robot and limits.
    #[error("guards on branch {branch}: {error}")]
    Guards { branch: u8, error: GuardSetupError },
    /// A branch without guards (there are eight, one per branch).
    #[error("branch {0}: no guards")]
    NoGuards(u8),
}

/// A guard's SI value in its edge unit (mm, deg, N, N m; dimensionless measures as is).
pub fn to_edge(guard: Guard, si: f64) -> f64 {
    si * guard.edge_unit().0
}

/// A guard's SI value as edge text: 3 decimals in mm, deg, N, N m; 4 when dimensionless.
pub fn edge_text(guard: Guard, si: f64) -> String {
    let decimals = if guard.edge_unit().1.is_empty() { 4 } else { 3 };
    fixed(to_edge(guard, si), decimals)
}

/// One violation as `guard:subject:value:limit`, in the guard's edge unit.
pub fn violation_text(r: &Reading<f64>) -> String {
    format!(
        "{}:{}:{}:{}",
        r.guard.name(),
        r.subject,
        edge_text(r.guard, r.value),
        edge_text(r.guard, r.limit)
    )
}

/// A reading in words: severity, guard, subject, value and the limit it broke, in the
/// guard's edge unit, e.g. `stop: stroke of chain 1 is 404.100 mm, limit 210.000 mm`.
pub fn reading_words(r: &Reading<f64>) -> String {
    let unit = r.guard.edge_unit().1;
    let unit = if unit.is_empty() {
        String::new()
    } else {
        format!(" {unit}")
    };
    let subject = match r.subject {
        Subject::Robot => String::new(),
        Subject::Chain(c) => format!(" of chain {}", c.number()),
        Subject::Joint(j) => format!(" of q{j}"),
        Subject::Axis(_) => format!(" along {}", r.subject),
    };
    let severity = r.severity.map(|s| s.to_string()).unwrap_or_default();
    format!(
        "{severity}: {}{subject} is {}{unit}, limit {}{unit}",
        guard_words(r.guard),
        edge_text(r.guard, r.value),
        edge_text(r.guard, r.limit),
    )
}

/// A guard in words (the board's words for the same guards, `board_words::guard_name`).
pub fn guard_words(g: Guard) -> &'static str {
    match g {
        Guard::LinkAngle => "link angle",
        Guard::TiltCone => "platform tilt",
        Guard::SerialSingularity => "serial singularity",
        Guard::ParallelSingularity => "parallel singularity",
        Guard::TipSpeed => "tip speed",
        Guard::AngularSpeed => "angular speed",
        Guard::TipAccel => "tip acceleration",
        Guard::AngularAccel => "angular acceleration",
        Guard::JointSpeed => "joint speed",
        Guard::JointAccel => "joint acceleration",
        other => other.name(),
    }
}

/// The guards prepared for a robot and limits on every branch.
pub struct Check {
    /// Index = branch bits; a branch whose guards cannot be set up keeps the reason.
    guards: Vec<Result<Guards<f64, Robot<f64>>, GuardSetupError>>,
}

impl Check {
    /// Prepares the guards of `robot` with `limits` on the 8 branches.
    pub fn new(robot: &Robot<f64>, limits: &Limits<f64>) -> Check {
        let guards = Branch::ALL
            .iter()
            .map(|&b| Guards::new(*robot, b, *limits))
            .collect();
        Check { guards }
    }

    /// The guards of a branch.
    fn guards(&self, branch: Branch) -> Result<&Guards<f64, Robot<f64>>, VerdictError> {
        match self.guards.get(usize::from(branch.bits())) {
            Some(Ok(g)) => Ok(g),
            Some(Err(e)) => Err(VerdictError::Guards {
                branch: branch.bits(),
                error: *e,
            }),
            None => Err(VerdictError::NoGuards(branch.bits())),
        }
    }

    /// Every violation at a pose on a branch, in evaluation order.
    pub fn violations(
        &self,
        pose: &Pose<f64>,
        branch: Branch,
    ) -> Result<Vec<Reading<f64>>, VerdictError> {
        let guards = self.guards(branch)?;
        let mut out = Vec::new();
        guards.evaluate_pose(pose, &mut |r| {
            if r.severity.is_some() {
                out.push(*r);
            }
        });
        Ok(out)
    }

    /// The guards' verdict at a pose on a branch, for the `guards` column: `ok` when no
    /// guard is violated, else the first violation of the worst severity in words
    /// ([`reading_words`]), followed by the count of the other violations.
    pub fn verdict(&self, pose: &Pose<f64>, branch: Branch) -> Result<String, VerdictError> {
        Ok(verdict_words(&self.violations(pose, branch)?))
    }
}

/// The worst severity among violations (None when there are none).
pub fn worst(violations: &[Reading<f64>]) -> Option<Severity> {
    violations.iter().filter_map(|r| r.severity).max()
}

/// The verdict of [`Check::verdict`] from the violations.
pub fn verdict_words(violations: &[Reading<f64>]) -> String {
    let worst = worst(violations);
    let Some(first) = violations.iter().find(|r| r.severity == worst) else {
        return "ok".to_string();
    };
    match violations.len() - 1 {
        0 => reading_words(first),
        n => format!("{} (and {n} more: see check)", reading_words(first)),
    }
}
