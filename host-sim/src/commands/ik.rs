//! `ik`: the joints of a pose on a branch.

use super::{execute, pose_columns, solve_row, PoseInput, RowError};
use crate::batch::{BatchError, Calculation};
use crate::columns::Row;
use crate::columns::{joint_columns, joints_to_edge};
use clap::Args;
use kinematics_core::Robot;
use robot_config::units::fixed9;

/// `host-sim ik`: in x_mm..rz_deg,branch; out the same, then the joints and `error`.
#[derive(Debug, Args)]
pub struct IkArgs {
    #[command(flatten)]
    pub input: PoseInput,
}

/// Inverse kinematics of each row.
pub struct Ik<'a> {
    pub robot: &'a Robot<f64>,
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
        joint_columns(self.robot.kind()).to_vec()
    }
    fn compute(&self, row: &Row<'_>) -> Result<Vec<String>, RowError> {
        let sol = solve_row(self.robot, row)?;
        Ok(joints_to_edge(self.robot, &sol.q()).map(fixed9).to_vec())
    }
}

/// Runs `ik`.
pub fn run(args: &IkArgs, robot: &Robot<f64>) -> Result<(), BatchError<RowError>> {
    execute(&Ik { robot }, args.input.csv, &args.input.flags())
}
