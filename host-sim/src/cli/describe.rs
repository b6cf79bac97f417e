//! `host-sim describe`: the robot description of the geometry in use (URDF), and the
//! joint-state vector of the description (every joint, the passive ones computed by the
//! kinematics) for actuated joints read as CSV.

use crate::error::CliError;
use clap::Args;
use kinematics_core::guards::Limits;
use kinematics_core::{Branch, Mechanism, Pose};
use robot_config::edge::{joint_columns, joints_from_edge, pose_to_edge};
use robot_config::selection::SelectedRobot;
use robot_config::units::{fixed9, m_to_mm, rad_to_deg};
use robot_description::{to_urdf, Description, JointType};
use std::io::{Read, Write};
use std::path::PathBuf;

/// `host-sim describe` options.
#[derive(Debug, Args)]
#[command(group(clap::ArgGroup::new("what").required(true).args(["urdf", "joint_states"])))]
pub struct DescribeArgs {
    /// Write the URDF: the base, the rotating (USR: lower) links, the spherical joints, the
    /// legs (cylinder and piston; USR: upper link), the platform pins and the platform, at
    /// the geometry's dimensions; the platform hangs off chain 1, the passive joints of
    /// every chain follow `/joint_states`.
    #[arg(long)]
    pub urdf: bool,
    /// Batch form of the joint states: CSV on stdin with the actuated joints (the columns
    /// `ik` writes: l1_mm..theta3_deg or alpha1_deg..beta3_deg; other columns ignored); CSV
    /// on stdout: the pose of the forward kinematics (x_mm..rz_deg), then every moving
    /// joint of the description (<joint>_mm for prismatic, <joint>_deg for revolute), then
    /// error.
    #[arg(long, conflicts_with = "urdf")]
    pub joint_states: bool,
    /// Where to write the URDF [default: stdout].
    #[arg(long, value_name = "PATH", requires = "urdf")]
    pub out: Option<PathBuf>,
    /// The inverse-kinematics branch 0..=7 of the description's joint states (the
    /// prototype runs branch 0).
    #[arg(long, value_name = "0..7", default_value_t = 0)]
    pub branch: u32,
}

/// Runs `describe`.
pub fn run(
    args: &DescribeArgs,
    selected: &SelectedRobot,
    limits: &Limits<f64>,
) -> Result<(), CliError> {
    let branch = Branch::new(args.branch).map_err(|e| CliError::Describe(e.to_string()))?;
    let d = Description::new(&selected.robot, limits, branch)
        .map_err(|e| CliError::Describe(e.to_string()))?;
    if args.urdf {
        let text = to_urdf(
            d.tree(),
            &format!(
                "{} on branch {}; written by host-sim describe",
                selected.source, branch
            ),
        );
        return match &args.out {
            Some(path) => std::fs::write(path, text).map_err(|e| CliError::Output {
                path: path.clone(),
                error: e.to_string(),
            }),
            None => std::io::stdout()
                .write_all(text.as_bytes())
                .map_err(|e| CliError::Describe(format!("stdout: {e}"))),
        };
    }
    joint_states(&d)
}

/// The `--joint-states` batch: stdin to stdout.
fn joint_states(d: &Description) -> Result<(), CliError> {
    let robot = d.robot();
    let mut input = String::new();
    std::io::stdin()
        .read_to_string(&mut input)
        .map_err(|e| CliError::Describe(format!("stdin: {e}")))?;
    let mut reader = csv::Reader::from_reader(input.as_bytes());
    let headers = reader
        .headers()
        .map_err(|e| CliError::Describe(format!("input header: {e}")))?
        .clone();
    let names = joint_columns(robot.kind());
    let mut index = [0usize; 6];
    for (k, n) in names.iter().enumerate() {
        index[k] = headers.iter().position(|h| h.trim() == *n).ok_or_else(|| {
            CliError::Describe(format!(
                "input: no column {n} (the joints are {})",
                names.join(",")
            ))
        })?;
    }
    let moving: Vec<(String, bool)> = d
        .tree()
        .joints
        .iter()
        .filter(|j| j.kind != JointType::Fixed)
        .map(|j| {
            (
                j.name.clone(),
                matches!(j.kind, JointType::Prismatic { .. }),
            )
        })
        .collect();
    let mut out = csv::Writer::from_writer(std::io::stdout());
    let mut header: Vec<String> = ["x_mm", "y_mm", "z_mm", "rx_deg", "ry_deg", "rz_deg"]
        .map(String::from)
        .to_vec();
    for (n, linear) in &moving {
        header.push(format!("{n}_{}", if *linear { "mm" } else { "deg" }));
    }
    header.push("error".into());
    let write_err = |e: csv::Error| CliError::Describe(format!("stdout: {e}"));
    out.write_record(&header).map_err(write_err)?;
    let guess = Pose::central(robot.hc());
    for (row, record) in reader.records().enumerate() {
        let line = row + 2;
        let mut cells = vec![String::new(); header.len()];
        let result = record
            .map_err(|e| format!("line {line}: {e}"))
            .and_then(|r| {
                let mut v = [0.0; 6];
                for (k, i) in index.iter().enumerate() {
                    let text = r.get(*i).unwrap_or("").trim();
                    v[k] = text.parse::<f64>().map_err(|_| {
                        format!("line {line}: {}: `{text}` is not a number", names[k])
                    })?;
                }
                let q = joints_from_edge(robot, v);
                d.joint_states_from_joints(&q, &guess)
                    .map_err(|e| format!("line {line}: {e}"))
            });
        match result {
            Ok((pose, states)) => {
                for (c, x) in cells.iter_mut().zip(pose_to_edge(&pose)) {
                    *c = fixed9(x);
                }
                for (k, ((_, linear), v)) in moving.iter().zip(&states.positions).enumerate() {
                    cells[6 + k] = fixed9(if *linear { m_to_mm(*v) } else { rad_to_deg(*v) });
                }
            }
            Err(e) => {
                if let Some(last) = cells.last_mut() {
                    *last = e;
                }
            }
        }
        out.write_record(&cells).map_err(write_err)?;
    }
    out.flush()
        .map_err(|e| CliError::Describe(format!("stdout: {e}")))
}
