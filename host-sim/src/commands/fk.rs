//! `fk`: the pose of joints on a branch, by the core's Newton iteration.

use super::{execute, RowError};
use crate::batch::{BatchError, Calculation, FlagValue};
use crate::columns::Row;
use crate::columns::{
    joint_columns, pose_to_edge, read_branch, read_initial_pose, read_joints, BRANCH, INITIAL_POSE,
    POSE,
};
use clap::Args;
use kinematics_core::{forward, FkConfig, Mechanism, Pose, Robot};
use robot_config::units::fixed9;

/// `host-sim fk`: in branch, the joints (the column names `ik` writes) and optionally an
/// initial pose x0_mm..rz0_deg; out the input, then x_mm..rz_deg, iterations and `error`.
#[derive(Debug, Args)]
pub struct FkArgs {
    /// Batch form: CSV on stdin (columns branch, the joints, optional x0_mm..rz0_deg; an
    /// empty initial pose means the central configuration), CSV on stdout.
    #[arg(long, conflicts_with_all = ["joints", "initial", "branch"])]
    pub csv: bool,
    /// Joints q1..q6 in q order: RSPR l1_mm,l2_mm,l3_mm,theta1_deg,theta2_deg,theta3_deg;
    /// USR alpha1_deg,alpha2_deg,alpha3_deg,beta1_deg,beta2_deg,beta3_deg.
    #[arg(
        long,
        value_name = "Q1,..,Q6",
        allow_hyphen_values = true,
        required_unless_present = "csv"
    )]
    pub joints: Option<String>,
    /// Initial pose of the iteration x0_mm,y0_mm,z0_mm,rx0_deg,ry0_deg,rz0_deg
    /// [default: the central configuration [0, 0, hc], R = I].
    #[arg(long, value_name = "X,Y,Z,RX,RY,RZ", allow_hyphen_values = true)]
    pub initial: Option<String>,
    /// Inverse-kinematics branch 0..=7 the joints belong to.
    #[arg(long, value_name = "0..7", default_value = "0")]
    pub branch: String,
}

/// Forward kinematics of each row.
pub struct Fk<'a> {
    pub robot: &'a Robot<f64>,
}

impl Calculation for Fk<'_> {
    type Error = RowError;
    fn name(&self) -> &'static str {
        "fk"
    }
    fn required_columns(&self) -> Vec<&'static str> {
        let mut c = vec![BRANCH];
        c.extend(joint_columns(self.robot.kind()));
        c
    }
    fn optional_columns(&self) -> Vec<&'static str> {
        INITIAL_POSE.to_vec()
    }
    fn result_columns(&self) -> Vec<&'static str> {
        let mut c = POSE.to_vec();
        c.push("iterations");
        c
    }
    fn compute(&self, row: &Row<'_>) -> Result<Vec<String>, RowError> {
        let branch = read_branch(row)?;
        let q = read_joints(row, self.robot)?;
        let guess = read_initial_pose(row)?.unwrap_or_else(|| Pose::central(self.robot.hc()));
        let fk =
            forward(self.robot, &q, branch, &guess, &FkConfig::default()).map_err(RowError::Fk)?;
        let mut out: Vec<String> = pose_to_edge(&fk.pose).map(fixed9).to_vec();
        out.push(fk.iterations.to_string());
        Ok(out)
    }
}

/// Runs `fk`.
pub fn run(args: &FkArgs, robot: &Robot<f64>) -> Result<(), BatchError<RowError>> {
    let mut flags = vec![
        FlagValue::new("--branch", &[BRANCH], &args.branch),
        FlagValue::new(
            "--joints",
            &joint_columns(robot.kind()),
            args.joints.as_deref().unwrap_or_default(),
        ),
    ];
    if let Some(initial) = &args.initial {
        flags.push(FlagValue::new("--initial", &INITIAL_POSE, initial));
    }
    execute(&Fk { robot }, args.csv, &flags)
}
