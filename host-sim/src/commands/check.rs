//! `check`: the guards of `kinematics-core` at the edge.
//!
//! - Row-wise (single pose or `--csv`): the verdict at a pose on a branch: `ok` (true
//!   unless a stop-level guard is violated, i.e. the supervisor would accept the
//!   setpoint), `severity` (the worst: empty, `warn` or `stop`) and `violations`, a
//!   `;`-separated list of `guard:subject:value:limit` in the guard's edge unit.
//! - `--task-box`: every static guard's worst margin over the thesis's task box, where it
//!   occurs, the number of grid points with stop and warn violations, and a conclusion.
//!
//! A computed verdict or report exits 0 whatever it says; only bad input fails. The guards
//! prepared on every branch and the texts of their readings are `robot-config`'s
//! ([`robot_config::verdict`]), shared with the Python module.

use super::{execute, pose_columns, pose_flags, RowError};
use crate::batch::{BatchError, Calculation, ColumnDefault};
use crate::columns::{
    parse_branch, pose_from_edge, read_branch, read_pose, EdgeError, Row, BRANCH, POSE,
};
use crate::flags::{self, FlagError};
use clap::Args;
use kinematics_core::guards::{Guard, GuardSetupError, Guards, Limits, Reading, Severity, Subject};
use kinematics_core::{Branch, Mechanism, Robot, RobotKind, RsprGeometry, UsrGeometry};
use robot_config::selection::{kind_name, SelectedLimits, SelectedRobot};
use robot_config::task_box::{TaskBox, TaskPose};
use robot_config::units::{fixed, m_to_mm};
pub use robot_config::verdict::{edge_text, violation_text, worst, Check};
use std::fmt::Write as _;
use std::io::Write as _;
use thiserror::Error;

/// Why `check` cannot run or print.
#[derive(Debug, Error)]
pub enum CheckError {
    /// A flag's value, or flags that do not go together.
    #[error(transparent)]
    Flag(#[from] FlagError),
    /// The row-wise form: the input as a whole, or the single form's row.
    #[error(transparent)]
    Batch(#[from] BatchError<RowError>),
    /// The guards cannot be set up for the robot, branch and limits.
    #[error("{0}")]
    Guards(GuardSetupError),
    #[error(transparent)]
    Pose(#[from] EdgeError),
    #[error("check: cannot write the output: {0}")]
    Write(csv::Error),
    #[error("check: cannot write the output: {0}")]
    Flush(std::io::Error),
}

/// The default grid of `--task-box`, per orientation.
pub const DEFAULT_GRID: [usize; 3] = [9, 9, 5];

/// The columns of `check --task-box --csv`.
pub const TASK_COLUMNS: [&str; 11] = [
    "guard",
    "subject",
    "worst_value",
    "limit",
    "margin",
    "x_mm",
    "y_mm",
    "z_mm",
    "orientation",
    "stop_points",
    "warn_points",
];

/// `host-sim check`: in x_mm..rz_deg,branch; out the input, then ok, severity,
/// violations and `error`. Or `--task-box`: the worst margins over the task.
#[derive(Debug, Args)]
pub struct CheckArgs {
    /// Batch form: CSV on stdin (columns x_mm,y_mm,z_mm,rx_deg,ry_deg,rz_deg and optionally
    /// branch, found by name, extra columns echoed), CSV on stdout, one row per input row; bad rows are
    /// reported in the `error` column and do not stop the run. With --task-box: the task
    /// table as CSV (the conclusion goes to stderr).
    #[arg(long, conflicts_with = "pose")]
    pub csv: bool,
    /// Single pose x_mm,y_mm,z_mm,rx_deg,ry_deg,rz_deg; (rx, ry, rz) is the rotation
    /// vector (axis * angle) in degrees.
    #[arg(
        long,
        value_name = "X,Y,Z,RX,RY,RZ",
        allow_hyphen_values = true,
        required_unless_present_any = ["csv", "task_box"],
        conflicts_with = "task_box"
    )]
    pub pose: Option<String>,
    /// Inverse-kinematics branch 0..=7, one bit per chain, chain 1 in bit 0 (0 = the
    /// prototype's all-outer branch) [default: 0]; with the row-wise --csv, the branch of
    /// rows without a `branch` column.
    #[arg(long, value_name = "0..7")]
    pub branch: Option<String>,
    /// Check the thesis's task: the 40 x 40 x 20 mm box centred at [0, 0, hc], platform
    /// parallel and rotated +20 deg about [1,1,0]/sqrt(2), on a grid.
    #[arg(long)]
    pub task_box: bool,
    /// Grid points along x, y and z of the task box, per orientation [default: 9,9,5]
    /// (--task-box only).
    #[arg(long, value_name = "NX,NY,NZ")]
    pub grid: Option<String>,
}

/// The column of `ik`, `fk`, `jacobian` and `forces` that carries the guards' verdict.
pub const GUARDS_COLUMN: &str = "guards";

impl Calculation for Check {
    type Error = RowError;
    fn name(&self) -> &'static str {
        "check"
    }
    fn required_columns(&self) -> Vec<&'static str> {
        pose_columns()
    }
    fn result_columns(&self) -> Vec<&'static str> {
        vec!["ok", "severity", "violations"]
    }
    fn compute(&self, row: &Row<'_>) -> Result<Vec<String>, RowError> {
        let pose = read_pose(row)?;
        let branch = read_branch(row)?;
        let violations = self.violations(&pose, branch)?;
        let worst = worst(&violations);
        let list: Vec<String> = violations.iter().map(violation_text).collect();
        Ok(vec![
            (worst != Some(Severity::Stop)).to_string(),
            worst.map(|s| s.to_string()).unwrap_or_default(),
            list.join(";"),
        ])
    }
}

/// Runs `check`.
pub fn run(
    args: &CheckArgs,
    selected: &SelectedRobot,
    limits: &SelectedLimits,
) -> Result<(), CheckError> {
    if args.task_box {
        return run_task_box(args, selected, limits);
    }
    if args.grid.is_some() {
        return Err(FlagError::Invalid {
            flag: "--grid",
            reason: "only with --task-box".into(),
        }
        .into());
    }
    let branch = args.branch.as_deref().unwrap_or("0");
    let flags = pose_flags(args.pose.as_deref(), branch);
    // Rows without a `branch` column take --branch (0 when not given), as in `ik --csv`.
    let defaults = [ColumnDefault {
        flag: "--branch",
        column: BRANCH,
        value: branch.to_string(),
    }];
    Ok(execute(
        &Check::new(&selected.robot, &limits.limits),
        args.csv,
        &flags,
        &defaults,
    )?)
}

/// A reading and the task point where it occurred.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Found {
    pub reading: Reading<f64>,
    pub at: TaskPose,
}

/// What the task sweep found for one guard.
#[derive(Clone, Debug, PartialEq)]
pub struct GuardSummary {
    pub guard: Guard,
    /// The reading with the smallest margin (the signed distance to the stop level,
    /// positive inside); `None` when the guard never produced a reading (a disabled
    /// guard, or `reach` when every point is reached).
    pub worst: Option<Found>,
    /// The warn-level violation furthest beyond its level, if any.
    pub worst_warn: Option<Found>,
    /// Grid points where the guard is violated at the stop level.
    pub stop_points: usize,
    /// Grid points where the guard's worst violation is at the warn level.
    pub warn_points: usize,
}

/// The result of `check --task-box`.
#[derive(Clone, Debug, PartialEq)]
pub struct TaskCheck {
    pub task: TaskBox,
    pub branch: Branch,
    /// Grid points evaluated (both orientations).
    pub poses: usize,
    /// One summary per static guard of the robot, in [`Guard::ALL`] order.
    pub guards: Vec<GuardSummary>,
}

/// The guards that apply to a static pose of this robot: not the motion guards (speeds,
/// accelerations), and only the joint-range and actuator guards of its joints.
pub fn static_guards(robot: &Robot<f64>) -> Vec<Guard> {
    let kinds = robot.joint_kinds();
    let has = |k| kinds.contains(&k);
    let rspr = robot.kind() == RobotKind::Rspr;
    Guard::ALL
        .into_iter()
        .filter(|g| match g {
            Guard::Reach
            | Guard::Tilt
            | Guard::Collision
            | Guard::Workspace
            | Guard::TiltCone
            | Guard::SerialSingularity
            | Guard::ParallelSingularity => true,
            Guard::Stroke | Guard::LinkAngle => rspr,
            Guard::Yaw | Guard::Pitch => !rspr,
            Guard::Force => has(kinematics_core::JointKind::Linear),
            Guard::Torque => has(kinematics_core::JointKind::Angular),
            Guard::TipSpeed
            | Guard::AngularSpeed
            | Guard::TipAccel
            | Guard::AngularAccel
            | Guard::JointSpeed
            | Guard::JointAccel => false,
        })
        .collect()
}

/// Evaluates every static guard at every point of the task on a branch.
pub fn check_task(
    robot: &Robot<f64>,
    limits: &Limits<f64>,
    branch: Branch,
    task: &TaskBox,
) -> Result<TaskCheck, CheckError> {
    let guards = Guards::new(*robot, branch, *limits).map_err(CheckError::Guards)?;
    let mut summaries: Vec<GuardSummary> = static_guards(robot)
        .into_iter()
        .map(|guard| GuardSummary {
            guard,
            worst: None,
            worst_warn: None,
            stop_points: 0,
            warn_points: 0,
        })
        .collect();
    let points = task.poses(m_to_mm(robot.hc()));
    for at in &points {
        let pose = pose_from_edge(&POSE, at.pose)?;
        // The worst severity of each guard at this point.
        let mut here: Vec<Option<Severity>> = vec![None; summaries.len()];
        guards.evaluate_pose(&pose, &mut |r| {
            let Some(i) = summaries.iter().position(|s| s.guard == r.guard) else {
                return;
            };
            let (Some(s), Some(h)) = (summaries.get_mut(i), here.get_mut(i)) else {
                return;
            };
            let found = Found {
                reading: *r,
                at: *at,
            };
            // A NaN margin (never expected) counts as the worst, so it is not hidden.
            if s.worst
                .is_none_or(|w| r.margin.is_nan() || r.margin < w.reading.margin)
            {
                s.worst = Some(found);
            }
            if r.severity == Some(Severity::Warn)
                && s.worst_warn.is_none_or(|w| {
                    (r.value - r.limit).abs() > (w.reading.value - w.reading.limit).abs()
                })
            {
                s.worst_warn = Some(found);
            }
            *h = (*h).max(r.severity);
        });
        for (s, h) in summaries.iter_mut().zip(here) {
            match h {
                Some(Severity::Stop) => s.stop_points += 1,
                Some(Severity::Warn) => s.warn_points += 1,
                None => {}
            }
        }
    }
    Ok(TaskCheck {
        task: task.clone(),
        branch,
        poses: points.len(),
        guards: summaries,
    })
}

/// Where a reading is, for people: `chain 1`, `q4`, `axis x`, or nothing for the robot.
fn subject_words(subject: Subject) -> String {
    match subject {
        Subject::Robot => String::new(),
        Subject::Chain(c) => format!(" on chain {}", c.number()),
        Subject::Joint(_) => format!(" on {subject}"),
        Subject::Axis(_) => format!(" on axis {subject}"),
    }
}

/// A task point for people: `(-20.000, -20.000, 150.000) mm rotated`.
fn at_words(task: &TaskBox, at: &TaskPose) -> String {
    let [x, y, z, ..] = at.pose;
    let orientation = task
        .orientations()
        .get(at.orientation)
        .map_or("?", |o| o.key);
    format!(
        "({}, {}, {}) mm {orientation}",
        fixed(x, 3),
        fixed(y, 3),
        fixed(z, 3)
    )
}

/// The edge unit with a leading space, or nothing for dimensionless measures.
fn unit_suffix(guard: Guard) -> String {
    match guard.edge_unit().1 {
        "" => String::new(),
        u => format!(" {u}"),
    }
}

/// "<guard> fails at <pose> by <amount>" for the stop level, "exceeds its warn level"
/// for a warn-only guard; `None` when the guard is fine everywhere.
fn failure_words(task: &TaskBox, s: &GuardSummary) -> Option<String> {
    let g = s.guard;
    let u = unit_suffix(g);
    let points = |n: usize| if n == 1 { "point" } else { "points" };
    if s.stop_points > 0 {
        let w = s.worst?;
        let r = &w.reading;
        if g == Guard::Reach {
            return Some(format!(
                "reach fails at {}{} (no inverse-kinematics solution; {} {})",
                at_words(task, &w.at),
                subject_words(r.subject),
                s.stop_points,
                points(s.stop_points)
            ));
        }
        return Some(format!(
            "{g} fails at {}{} by {}{u} ({}{u} vs limit {}{u}; {} {})",
            at_words(task, &w.at),
            subject_words(r.subject),
            edge_text(g, -r.margin),
            edge_text(g, r.value),
            edge_text(g, r.limit),
            s.stop_points,
            points(s.stop_points)
        ));
    }
    if s.warn_points > 0 {
        let w = s.worst_warn?;
        let r = &w.reading;
        return Some(format!(
            "{g} exceeds its warn level at {}{} by {}{u} ({}{u} vs warn level {}{u}; {} {})",
            at_words(task, &w.at),
            subject_words(r.subject),
            edge_text(g, (r.value - r.limit).abs()),
            edge_text(g, r.value),
            edge_text(g, r.limit),
            s.warn_points,
            points(s.warn_points)
        ));
    }
    None
}

/// The one-line conclusion.
pub fn conclusion(check: &TaskCheck, robot: &Robot<f64>) -> String {
    let reference = *robot == Robot::Rspr(RsprGeometry::reference())
        || *robot == Robot::Usr(UsrGeometry::reference());
    let who = if reference {
        "the reference robot"
    } else {
        "the robot"
    };
    let failures: Vec<String> = check
        .guards
        .iter()
        .filter_map(|s| failure_words(&check.task, s))
        .collect();
    if failures.is_empty() {
        format!("Conclusion: {who} reaches the whole task box within the limits.")
    } else {
        format!(
            "Conclusion: {who} does NOT reach the whole task box within the limits: {}.",
            failures.join("; ")
        )
    }
}

/// The fields of one guard's row: value, limit and margin in edge units, where, counts.
fn row_fields(check: &TaskCheck, s: &GuardSummary) -> Vec<String> {
    let g = s.guard;
    let mut out = vec![g.name().to_string()];
    match &s.worst {
        Some(w) => {
            let r = &w.reading;
            let [x, y, z, ..] = w.at.pose;
            let orientation = check
                .task
                .orientations()
                .get(w.at.orientation)
                .map_or("", |o| o.key);
            out.extend([
                r.subject.to_string(),
                edge_text(g, r.value),
                edge_text(g, r.limit),
                edge_text(g, r.margin),
                fixed(x, 3),
                fixed(y, 3),
                fixed(z, 3),
                orientation.to_string(),
            ]);
        }
        None => out.extend(std::iter::repeat_n(String::new(), 8)),
    }
    out.push(s.stop_points.to_string());
    out.push(s.warn_points.to_string());
    out
}

/// The task table as CSV ([`TASK_COLUMNS`]).
pub fn task_csv(check: &TaskCheck, output: impl std::io::Write) -> Result<(), CheckError> {
    let mut writer = csv::Writer::from_writer(output);
    writer
        .write_record(TASK_COLUMNS)
        .map_err(CheckError::Write)?;
    for s in &check.guards {
        writer
            .write_record(row_fields(check, s))
            .map_err(CheckError::Write)?;
    }
    writer.flush().map_err(CheckError::Flush)
}

/// The readable task report.
pub fn task_text(check: &TaskCheck, selected: &SelectedRobot, limits: &SelectedLimits) -> String {
    let robot = &selected.robot;
    let hc_mm = m_to_mm(robot.hc());
    let mut out = format!(
        "host-sim check --task-box: {} robot, {}\nLimits: {}\n",
        kind_name(robot.kind()),
        selected.source,
        limits.source
    );
    let _ = writeln!(
        out,
        "Task box: {}, branch {}: {} poses",
        check.task.describe(hc_mm),
        check.branch.bits(),
        check.poses
    );
    for o in check.task.orientations() {
        let r = o.rotation_deg;
        let _ = writeln!(
            out,
            "  {:<9} {}, r ({:.3}, {:.3}, {:.3}) deg",
            o.key, o.label, r[0], r[1], r[2]
        );
    }
    out.push_str(
        "\nWorst margin of each static guard over the task\n\
         (margin: signed distance to the stop level, positive inside; limit: the level the\n\
         worst value violates, else the stop level; stop/warn: grid points where the guard\n\
         is violated at that level, warn counting points without a stop. The motion guards\n\
         (speeds, accelerations) do not apply to a static check and are not listed.)\n\n",
    );
    let _ = writeln!(
        out,
        "  {:<10} {:<7} {:>11} {:>11} {:>11} {:<4}  {:<36} {:>5} {:>5}",
        "guard", "subject", "worst", "limit", "margin", "unit", "at (x, y, z) mm", "stop", "warn"
    );
    for s in &check.guards {
        let f = row_fields(check, s);
        let cell = |i: usize| f.get(i).map_or("", String::as_str);
        let (subject, value, limit, margin, at) = if s.worst.is_some() {
            (
                cell(1).to_string(),
                cell(2).to_string(),
                cell(3).to_string(),
                cell(4).to_string(),
                format!("({}, {}, {}) {}", cell(5), cell(6), cell(7), cell(8)),
            )
        } else {
            let none = if s.guard == Guard::Reach {
                "every point reached"
            } else {
                "not evaluated (disabled)"
            };
            let dash = || "-".to_string();
            (dash(), dash(), dash(), dash(), none.to_string())
        };
        let _ = writeln!(
            out,
            "  {:<10} {:<7} {:>11} {:>11} {:>11} {:<4}  {:<36} {:>5} {:>5}",
            cell(0),
            subject,
            value,
            limit,
            margin,
            s.guard.edge_unit().1,
            at,
            s.stop_points,
            s.warn_points
        );
    }
    let _ = writeln!(out, "\n{}", conclusion(check, robot));
    out
}

/// Runs `check --task-box`.
fn run_task_box(
    args: &CheckArgs,
    selected: &SelectedRobot,
    limits: &SelectedLimits,
) -> Result<(), CheckError> {
    let grid = match &args.grid {
        Some(g) => flags::grid("--grid", g)?,
        None => DEFAULT_GRID,
    };
    let branch = match &args.branch {
        Some(b) => parse_branch(b).map_err(|error| FlagError::Field {
            flag: "--branch",
            error,
        })?,
        None => Branch::OUTER,
    };
    let check = check_task(
        &selected.robot,
        &limits.limits,
        branch,
        &TaskBox::thesis(grid),
    )?;
    let stdout = std::io::stdout();
    if args.csv {
        task_csv(&check, stdout.lock())?;
        eprintln!("{}", conclusion(&check, &selected.robot));
        Ok(())
    } else {
        let mut lock = stdout.lock();
        lock.write_all(task_text(&check, selected, limits).as_bytes())
            .and_then(|()| lock.flush())
            .map_err(CheckError::Flush)
    }
}
