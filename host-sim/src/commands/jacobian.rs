//! `jacobian`: J = dq/dx at a pose, and the conditioning of the tripod Jacobian.

use super::{execute, pose_columns, solve_row, PoseInput, RowError};
use crate::batch::{BatchError, Calculation};
use crate::columns::Row;
use clap::Args;
use kinematics_core::singularity::parallel_inv_cond;
use kinematics_core::{jacobian, Mechanism, Robot};
use robot_config::units::significant;

/// `host-sim jacobian`: in x_mm..rz_deg,branch; out the input, then j11..j66 (SI, row-major,
/// rows in q order, columns [v; w]), inv_cond and `error`.
#[derive(Debug, Args)]
pub struct JacobianArgs {
    #[command(flatten)]
    pub input: PoseInput,
}

/// The entries j11..j66, row-major.
const ENTRIES: [&str; 36] = [
    "j11", "j12", "j13", "j14", "j15", "j16", "j21", "j22", "j23", "j24", "j25", "j26", "j31",
    "j32", "j33", "j34", "j35", "j36", "j41", "j42", "j43", "j44", "j45", "j46", "j51", "j52",
    "j53", "j54", "j55", "j56", "j61", "j62", "j63", "j64", "j65", "j66",
];

/// The Jacobian of each row.
pub struct JacobianCalc<'a> {
    pub robot: &'a Robot<f64>,
}

impl Calculation for JacobianCalc<'_> {
    type Error = RowError;
    fn name(&self) -> &'static str {
        "jacobian"
    }
    fn required_columns(&self) -> Vec<&'static str> {
        pose_columns()
    }
    fn result_columns(&self) -> Vec<&'static str> {
        let mut c = ENTRIES.to_vec();
        c.push("inv_cond");
        c
    }
    fn compute(&self, row: &Row<'_>) -> Result<Vec<String>, RowError> {
        let sol = solve_row(self.robot, row)?;
        let jac = jacobian(self.robot, &sol).map_err(RowError::Jacobian)?;
        let inv_cond =
            parallel_inv_cond(&jac.jtilde, self.robot.rp()).map_err(RowError::Conditioning)?;
        // nalgebra stores column-major; the output is row-major.
        let mut out: Vec<String> = jac.j.transpose().iter().map(|&x| significant(x)).collect();
        out.push(significant(inv_cond));
        Ok(out)
    }
}

/// Runs `jacobian`.
pub fn run(args: &JacobianArgs, robot: &Robot<f64>) -> Result<(), BatchError<RowError>> {
    execute(&JacobianCalc { robot }, args.input.csv, &args.input.flags())
}
