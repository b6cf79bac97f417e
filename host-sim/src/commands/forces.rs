//! `forces`: the actuator forces and torques that hold a wrench, tau = J^-T s_e.

use super::{execute, pose_columns, solve_row, PoseInput, RowError};
use crate::batch::{Calculation, FlagValue};
use crate::columns::Row;
use crate::columns::{read_wrench, WRENCH};
use crate::error::CliError;
use crate::flags::min_inv_cond;
use clap::Args;
use kinematics_core::{actuator_forces, jacobian, Mechanism, Robot};
use robot_config::units::significant;

/// `host-sim forces`: in x_mm..rz_deg, branch, fx_n..tz_nm; out the input, then tau1..tau6
/// (RSPR: N on the prismatic joints, N m on the rotating links; USR: all N m) and `error`.
#[derive(Debug, Args)]
pub struct ForcesArgs {
    #[command(flatten)]
    pub input: PoseInput,
    /// The wrench fx_n,fy_n,fz_n,tx_nm,ty_nm,tz_nm the platform exerts on its environment
    /// (moment about the platform centre, world frame), e.g. the thesis's 7,7,7,0.7,0.7,0.7.
    #[arg(
        long,
        value_name = "FX,FY,FZ,TX,TY,TZ",
        allow_hyphen_values = true,
        required_unless_present = "csv",
        conflicts_with = "csv"
    )]
    pub wrench: Option<String>,
    /// Smallest accepted inverse condition number of the tripod Jacobian (moment columns
    /// divided by rp); below it the pose counts as a parallel singularity and the row fails
    /// instead of printing unbounded forces.
    #[arg(long, value_name = "X", default_value_t = 1e-6)]
    pub min_inv_cond: f64,
}

/// The actuator forces of each row.
pub struct Forces<'a> {
    pub robot: &'a Robot<f64>,
    pub min_inv_cond: f64,
}

impl Calculation for Forces<'_> {
    type Error = RowError;
    fn name(&self) -> &'static str {
        "forces"
    }
    fn required_columns(&self) -> Vec<&'static str> {
        let mut c = pose_columns();
        c.extend(WRENCH);
        c
    }
    fn result_columns(&self) -> Vec<&'static str> {
        vec!["tau1", "tau2", "tau3", "tau4", "tau5", "tau6"]
    }
    fn compute(&self, row: &Row<'_>) -> Result<Vec<String>, RowError> {
        let wrench = read_wrench(row)?;
        let sol = solve_row(self.robot, row)?;
        let jac = jacobian(self.robot, &sol).map_err(RowError::Jacobian)?;
        let statics = actuator_forces(&jac, self.robot.rp(), &wrench, self.min_inv_cond)
            .map_err(RowError::Forces)?;
        Ok(statics.tau.iter().map(|&x| significant(x)).collect())
    }
}

/// Runs `forces`.
pub fn run(args: &ForcesArgs, robot: &Robot<f64>) -> Result<(), CliError> {
    min_inv_cond(args.min_inv_cond)?;
    let mut flags = args.input.flags();
    flags.push(FlagValue::new(
        "--wrench",
        &WRENCH,
        args.wrench.as_deref().unwrap_or_default(),
    ));
    let calc = Forces {
        robot,
        min_inv_cond: args.min_inv_cond,
    };
    Ok(execute(&calc, args.input.csv, &flags)?)
}
