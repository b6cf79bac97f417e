//! The row-wise commands. Each one is a [`Calculation`] (its columns and its computation);
//! the CSV loop, the single-pose form and the error handling live in [`crate::batch`].

pub mod check;
pub mod fk;
pub mod forces;
pub mod ik;
pub mod jacobian;
pub mod singularity;

use crate::batch::{self, BatchError, Calculation, ColumnDefault, FlagValue, FlagValueError};
use crate::columns::{self, check_field, FieldError, Row, BRANCH, POSE};
use clap::Args;
use kinematics_core::singularity::SvdDidNotConverge;
use kinematics_core::{inverse, FkError, ForceError, IkError, JacobianError, Robot, Solution};
use robot_config::verdict::VerdictError;
use std::io::Write;
use thiserror::Error;

/// Why a row of a row-wise command has no result: a field, or the step that failed with
/// the core's reason.
#[derive(Debug, Error)]
pub enum RowError {
    #[error(transparent)]
    Field(#[from] FieldError),
    #[error("ik: {0}")]
    Ik(IkError),
    #[error("fk: {0}")]
    Fk(FkError),
    #[error("jacobian: {0}")]
    Jacobian(JacobianError),
    /// The conditioning of the tripod Jacobian.
    #[error("jacobian: {0}")]
    Conditioning(SvdDidNotConverge),
    #[error("forces: {0}")]
    Forces(ForceError),
    #[error("singularity: {0}")]
    Singularity(SvdDidNotConverge),
    /// The guards of the row's branch.
    #[error(transparent)]
    Verdict(#[from] VerdictError),
}

/// Input of the commands that work on a pose and a branch.
#[derive(Debug, Args)]
pub struct PoseInput {
    /// Batch form: read CSV with a header from stdin (columns found by name, extra columns
    /// echoed), write CSV to stdout, one row per input row; bad rows are reported in the
    /// `error` column and do not stop the run. An input without a `branch` column takes
    /// --branch for every row (and the output echoes it).
    #[arg(long, conflicts_with = "pose")]
    pub csv: bool,
    /// Single pose x_mm,y_mm,z_mm,rx_deg,ry_deg,rz_deg; (rx, ry, rz) is the rotation
    /// vector (axis * angle) in degrees.
    #[arg(
        long,
        value_name = "X,Y,Z,RX,RY,RZ",
        allow_hyphen_values = true,
        required_unless_present = "csv"
    )]
    pub pose: Option<String>,
    /// Inverse-kinematics branch 0..=7, one bit per chain, chain 1 in bit 0 (0 = the
    /// prototype's all-outer branch); with --csv, the branch of rows without a `branch`
    /// column.
    #[arg(long, value_name = "0..7", default_value = "0")]
    pub branch: String,
}

impl PoseInput {
    /// The columns of the single-pose form, in batch order (pose, then branch).
    pub fn flags(&self) -> Vec<FlagValue> {
        pose_flags(self.pose.as_deref(), &self.branch)
    }

    /// The batch form's default for an input without a `branch` column.
    pub fn defaults(&self) -> Vec<ColumnDefault> {
        vec![ColumnDefault {
            flag: "--branch",
            column: BRANCH,
            value: self.branch.clone(),
        }]
    }
}

/// The single-pose form's flags `--pose` and `--branch` as columns, in batch order.
pub fn pose_flags(pose: Option<&str>, branch: &str) -> Vec<FlagValue> {
    vec![
        FlagValue::new("--pose", &POSE, pose.unwrap_or_default()),
        FlagValue::new("--branch", &[BRANCH], branch),
    ]
}

/// Input columns of the commands that read a pose and a branch.
pub fn pose_columns() -> Vec<&'static str> {
    let mut c = POSE.to_vec();
    c.push(BRANCH);
    c
}

/// Shared first step: the inverse kinematics of a row's pose on its branch.
pub fn solve_row(robot: &Robot<f64>, row: &Row<'_>) -> Result<Solution<f64>, RowError> {
    let pose = columns::read_pose(row)?;
    let branch = columns::read_branch(row)?;
    inverse(robot, &pose, branch).map_err(RowError::Ik)
}

/// Runs a calculation in the batch form (stdin to stdout, a count of bad rows on stderr;
/// `defaults` fill the columns an input lacks) or the single form (the flags' one row).
pub fn execute<C: Calculation<Error = RowError>>(
    calc: &C,
    csv: bool,
    flags: &[FlagValue],
    defaults: &[ColumnDefault],
) -> Result<(), BatchError<RowError>> {
    if csv {
        // The default's value is checked like the single form's flag.
        for d in defaults {
            check_field(d.column, &d.value).map_err(|error| {
                BatchError::Flag(FlagValueError::Field {
                    flag: d.flag,
                    error,
                })
            })?;
        }
    }
    let stdout = std::io::stdout();
    if csv {
        let summary = batch::run_csv(calc, defaults, std::io::stdin().lock(), stdout.lock())?;
        eprintln!(
            "{}: {} rows, {} with errors (see the error column)",
            calc.name(),
            summary.rows,
            summary.bad_rows
        );
        Ok(())
    } else {
        batch::run_single(calc, flags, stdout.lock())?;
        stdout.lock().flush().map_err(|source| BatchError::Flush {
            name: calc.name(),
            source,
        })
    }
}
