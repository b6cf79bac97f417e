//! `singularity`: the serial measure of each chain, the parallel measure and the nearest
//! singularity (CONVENTIONS.md, "Measures").

use super::{execute, pose_columns, solve_row, PoseInput, RowError};
use crate::batch::{BatchError, Calculation};
use crate::columns::Row;
use clap::Args;
use kinematics_core::{measures, Robot, RobotKind};
use robot_config::units::significant;

/// `host-sim singularity`: in x_mm..rz_deg,branch; out the input, then the serial measures
/// (RSPR serial1_mm.. = |Cn2_i| and serial1_frac.. = over rb; USR serial1_mm2.. =
/// |Cn1 Cr2 - Cr1 Cn2| and serial1_frac.. = over l1²), parallel_inv_cond, det_sign,
/// nearest (`parallel` or `serial:N`) and `error`.
#[derive(Debug, Args)]
pub struct SingularityArgs {
    #[command(flatten)]
    pub input: PoseInput,
}

/// The singularity measures of each row.
pub struct Singularity<'a> {
    pub robot: &'a Robot<f64>,
}

impl Singularity<'_> {
    /// The serial measure's columns and the factor from SI to their unit.
    fn serial_columns(&self) -> ([&'static str; 3], f64) {
        match self.robot.kind() {
            RobotKind::Rspr => (["serial1_mm", "serial2_mm", "serial3_mm"], 1e3),
            RobotKind::Usr => (["serial1_mm2", "serial2_mm2", "serial3_mm2"], 1e6),
        }
    }
}

impl Calculation for Singularity<'_> {
    type Error = RowError;
    fn name(&self) -> &'static str {
        "singularity"
    }
    fn required_columns(&self) -> Vec<&'static str> {
        pose_columns()
    }
    fn result_columns(&self) -> Vec<&'static str> {
        let mut c = self.serial_columns().0.to_vec();
        c.extend(["serial1_frac", "serial2_frac", "serial3_frac"]);
        c.extend(["parallel_inv_cond", "det_sign", "nearest"]);
        c
    }
    fn compute(&self, row: &Row<'_>) -> Result<Vec<String>, RowError> {
        let sol = solve_row(self.robot, row)?;
        let m = measures(self.robot, &sol).map_err(RowError::Singularity)?;
        let scale = self.serial_columns().1;
        let mut out: Vec<String> = m.serial.0.iter().map(|&x| significant(x * scale)).collect();
        out.extend(m.serial_relative.0.iter().map(|&x| significant(x)));
        out.push(significant(m.parallel_inv_cond));
        out.push(m.parallel_det_sign.to_string());
        out.push(m.nearest.to_string());
        Ok(out)
    }
}

/// Runs `singularity`.
pub fn run(args: &SingularityArgs, robot: &Robot<f64>) -> Result<(), BatchError<RowError>> {
    execute(&Singularity { robot }, args.input.csv, &args.input.flags())
}
