//! `ik`: the joints of a pose on a branch, and the guards' verdict on that pose.

use super::check::{Check, GUARDS_COLUMN};
use super::{execute, pose_columns, solve_row, PoseInput, RowError};
use crate::batch::{BatchError, Calculation};
use crate::columns::{joint_columns, joints_to_edge, read_branch, read_pose, Row};
use clap::Args;
use kinematics_core::guards::Limits;
use kinematics_core::Robot;
use robot_config::units::fixed9;

/// `host-sim ik`: in x_mm..rz_deg,branch; out the same, then the joints, the guards' verdict
/// and `error`.
#[derive(Debug, Args)]
pub struct IkArgs {
    #[command(flatten)]
    pub input: PoseInput,
}

/// Inverse kinematics of each row.
pub struct Ik<'a> {
    pub robot: &'a Robot<f64>,
    /// The guards whose verdict on the pose goes to the `guards` column.
    pub guards: Check,
}

impl Calculation for Ik<'_> {
    type Error = RowError;
    fn name(&self) -> &'static str {
        "ik"
    }
    fn required_columns(&self) -> Vec<&'static str> {
        pose_columns()
    }
    fn result_columns(&self) -> Vec<&'static str> {
        let mut c = joint_columns(self.robot.kind()).to_vec();
        c.push(GUARDS_COLUMN);
        c
    }
    fn compute(&self, row: &Row<'_>) -> Result<Vec<String>, RowError> {
        let sol = solve_row(self.robot, row)?;
        let mut out = joints_to_edge(self.robot, &sol.q()).map(fixed9).to_vec();
        out.push(self.guards.verdict(&read_pose(row)?, read_branch(row)?)?);
        Ok(out)
    }
}

/// Runs `ik`.
pub fn run(
    args: &IkArgs,
    robot: &Robot<f64>,
    limits: &Limits<f64>,
) -> Result<(), BatchError<RowError>> {
    let calc = Ik {
        robot,
        guards: Check::new(robot, limits),
    };
    execute(
        &calc,
        args.input.csv,
        &args.input.flags(),
        &args.input.defaults(),
    )
}
