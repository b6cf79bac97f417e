//! `host-sim ranges`: the columns of thesis Tables 8.2/8.3 for one geometry over the task
//! (the 40 x 40 x 20 mm box at [0, 0, hc], platform parallel and rotated +20 deg about
//! [1,1,0], the thesis wrench): each joint's min, max and span, the spherical-joint tilt,
//! for the USR the angles gamma_i and delta_i (CONVENTIONS.md, "Joints"), and the actuator
//! force and torque ranges; then the same over the three chains ([`Ranges::table_columns`]),
//! the columns as the thesis prints them.
//!
//! Thesis Table 8.3 (USR) is reproduced to its printed precision by the `rotated` column on
//! the thesis's 10 mm grid (`--grid 5,5,3`); the `task` column (both orientations, as
//! CONVENTIONS.md defines the task) has the same angle ranges but wider torque ranges where
//! the parallel orientation needs more torque (host-sim/design/tests/tables.rs states the
//! details).

use crate::forces_path::tau_columns;
use kinematics_core::singularity::SvdDidNotConverge;
use kinematics_core::{
    actuator_forces, inverse, jacobian, measures, tilt_angles, Branch, ForceError, IkError,
    JacobianError, JointKind, Mechanism, Robot, RobotKind, SocketAxes, Solution, Wrench,
};
use robot_config::edge::{joint_columns, pose_from_edge, EdgeError, POSE};
use robot_config::task_box::TaskBox;
use robot_config::units::{fixed, m_to_mm, rad_to_deg, wrap_deg};
use thiserror::Error;

/// Why the ranges cannot be evaluated at all.
#[derive(Clone, Copy, Debug, PartialEq, Error)]
pub enum RangesError {
    /// The spherical joints' axes (the central configuration on branch 0).
    #[error("socket axes: {0}")]
    SocketAxes(IkError),
    /// The central pose on the branch evaluated.
    #[error("central pose: {0}")]
    CentralPose(IkError),
    #[error(transparent)]
    Pose(#[from] EdgeError),
}

/// The step that failed at one task pose.
#[derive(Clone, Copy, Debug, PartialEq, Error)]
pub enum PoseFailure {
    #[error("ik: {0}")]
    Ik(IkError),
    #[error("singularity measures: {0}")]
    Measures(SvdDidNotConverge),
    #[error("jacobian: {0}")]
    Jacobian(JacobianError),
    #[error("forces: {0}")]
    Forces(ForceError),
}

/// A task pose (edge units) where a step failed.
#[derive(Clone, Copy, Debug, PartialEq, Error)]
#[error("{pose:?}: {failure}")]
pub struct TaskPoseFailure {
    /// x_mm, y_mm, z_mm, rx_deg, ry_deg, rz_deg.
    pub pose: [f64; 6],
    pub failure: PoseFailure,
}

/// The range of one quantity over a set of poses.
#[derive(Clone, Debug, PartialEq)]
pub struct QuantityRange {
    /// Unit-suffixed name, e.g. `l1_mm`, `gamma2_deg`, `f3_n`.
    pub quantity: String,
    /// `parallel`, `rotated` or `task` (both orientations).
    pub orientation: &'static str,
    pub min: f64,
    pub max: f64,
    /// Poses that contributed.
    pub poses: usize,
}

impl QuantityRange {
    /// max - min.
    pub fn span(&self) -> f64 {
        self.max - self.min
    }
}

/// The result of `ranges`.
#[derive(Clone, Debug, PartialEq)]
pub struct Ranges {
    pub rows: Vec<QuantityRange>,
    /// Task poses evaluated.
    pub poses: usize,
    /// Poses without inverse-kinematics solution, measures or forces, with the reason.
    pub failures: Vec<TaskPoseFailure>,
    /// The smallest parallel-singularity measure (inverse condition number of the scaled
    /// Jtilde) over the solved task poses; infinite when none was solved.
    pub parallel_inv_cond_min: f64,
    /// The smallest dimensionless serial-singularity measure over the solved task poses and
    /// chains (RSPR |Cn2_i| / rb, USR |Cn1 Cr2 - Cr1 Cn2| / l1^2); infinite when none.
    pub serial_relative_min: f64,
}

impl Ranges {
    /// The row of a quantity at an orientation key.
    pub fn get(&self, quantity: &str, orientation: &str) -> Option<&QuantityRange> {
        self.rows
            .iter()
            .find(|r| r.quantity == quantity && r.orientation == orientation)
    }

    /// The columns of thesis Tables 8.2/8.3 at an orientation key: each quantity's range
    /// over all three chains (min over the chains' minima, max over their maxima), in
    /// [`quantity_names`] order, e.g. `alpha_deg` from alpha1..3, `t_beta_nm` (the
    /// thesis's T_r) from t_beta1..3, `f_n` from f1..3. Quantities without any contributing
    /// pose are left out.
    pub fn table_columns(&self, orientation: &str) -> Vec<QuantityRange> {
        let mut out: Vec<QuantityRange> = Vec::new();
        for q in self
            .rows
            .iter()
            .filter(|q| q.orientation == orientation && q.poses > 0)
        {
            let name = chain_group(&q.quantity);
            match out.iter_mut().find(|c| c.quantity == name) {
                Some(c) => {
                    c.min = c.min.min(q.min);
                    c.max = c.max.max(q.max);
                    c.poses = c.poses.max(q.poses);
                }
                None => out.push(QuantityRange {
                    quantity: name,
                    ..q.clone()
                }),
            }
        }
        out
    }
}

/// The name of a per-chain quantity without its chain number: `t_alpha2_nm` ->
/// `t_alpha_nm`, `l1_mm` -> `l_mm`.
pub fn chain_group(quantity: &str) -> String {
    match quantity.rfind('_') {
        Some(k) => {
            let (stem, unit) = quantity.split_at(k);
            format!(
                "{}{unit}",
                stem.trim_end_matches(|c: char| c.is_ascii_digit())
            )
        }
        None => quantity.to_string(),
    }
}

/// The names of the quantities of a robot, in table order.
pub fn quantity_names(kind: RobotKind) -> Vec<String> {
    let mut q: Vec<String> = joint_columns(kind).iter().map(|s| s.to_string()).collect();
    if kind == RobotKind::Usr {
        q.extend((1..=3).map(|i| format!("gamma{i}_deg")));
        q.extend((1..=3).map(|i| format!("delta{i}_deg")));
    }
    q.extend((1..=3).map(|i| format!("tilt{i}_deg")));
    q.extend(tau_columns(kind).iter().map(|s| s.to_string()));
    q
}

/// An angle (deg) continued around a reference (deg), so ranges do not break at +-180.
fn near(angle_deg: f64, reference_deg: f64) -> f64 {
    reference_deg + wrap_deg(angle_deg - reference_deg)
}

/// The geometric quantities of a solution, in [`quantity_names`] order (without forces).
fn geometric(
    robot: &Robot<f64>,
    sol: &Solution<f64>,
    axes: &SocketAxes<f64>,
    reference: Option<&[f64]>,
) -> Vec<f64> {
    let kinds = robot.joint_kinds();
    let mut v: Vec<f64> = sol
        .q()
        .iter()
        .zip(kinds.iter())
        .map(|(x, k)| match k {
            JointKind::Linear => m_to_mm(*x),
            JointKind::Angular => wrap_deg(rad_to_deg(*x)),
        })
        .collect();
    if robot.kind() == RobotKind::Usr {
        v.extend(sol.chains.0.iter().map(|c| wrap_deg(rad_to_deg(c.gamma))));
        v.extend(sol.chains.0.iter().map(|c| {
            let a = c.e - c.b;
            let b = c.p - c.b;
            rad_to_deg(a.cross(&b).norm().atan2(a.dot(&b)))
        }));
    }
    v.extend(tilt_angles(sol, axes).0.iter().map(|t| rad_to_deg(*t)));
    if let Some(r) = reference {
        // Angles continue around their central values; lengths and tilts are unchanged.
        let angular: Vec<bool> = kinds
            .iter()
            .map(|k| *k == JointKind::Angular)
            .chain(std::iter::repeat_n(
                true,
                if robot.kind() == RobotKind::Usr { 3 } else { 0 },
            ))
            .collect();
        for ((x, r), a) in v.iter_mut().zip(r).zip(angular) {
            if a {
                *x = near(*x, *r);
            }
        }
    }
    v
}

/// Evaluates the ranges over the task on one branch.
pub fn evaluate(
    robot: &Robot<f64>,
    task: &TaskBox,
    wrench: [f64; 6],
    branch: Branch,
    min_inv_cond: f64,
) -> Result<Ranges, RangesError> {
    let hc_mm = m_to_mm(robot.hc());
    let axes = SocketAxes::new(robot).map_err(RangesError::SocketAxes)?;
    let central = inverse(
        robot,
        &pose_from_edge(&POSE, [0.0, 0.0, hc_mm, 0.0, 0.0, 0.0])?,
        branch,
    )
    .map_err(RangesError::CentralPose)?;
    let reference = geometric(robot, &central, &axes, None);
    let names = quantity_names(robot.kind());
    let keys = ["parallel", "rotated", "task"];
    // acc[orientation][quantity] = (min, max, count)
    let mut acc = vec![vec![(f64::INFINITY, f64::NEG_INFINITY, 0usize); names.len()]; 3];
    let mut failures = Vec::new();
    let (mut parallel_inv_cond_min, mut serial_relative_min) = (f64::INFINITY, f64::INFINITY);
    let poses = task.poses(hc_mm);
    for tp in &poses {
        let pose = pose_from_edge(&POSE, tp.pose)?;
        let failed = |failure| TaskPoseFailure {
            pose: tp.pose,
            failure,
        };
        let sol = match inverse(robot, &pose, branch) {
            Ok(s) => s,
            Err(e) => {
                failures.push(failed(PoseFailure::Ik(e)));
                continue;
            }
        };
        let mut values = geometric(robot, &sol, &axes, Some(&reference));
        match measures(robot, &sol) {
            Ok(m) => {
                parallel_inv_cond_min = parallel_inv_cond_min.min(m.parallel_inv_cond);
                for (_, &r) in m.serial_relative.iter() {
                    serial_relative_min = serial_relative_min.min(r);
                }
            }
            Err(e) => failures.push(failed(PoseFailure::Measures(e))),
        }
        let tau = jacobian(robot, &sol)
            .map_err(PoseFailure::Jacobian)
            .and_then(|j| {
                actuator_forces(&j, robot.rp(), &Wrench::from(wrench), min_inv_cond)
                    .map_err(PoseFailure::Forces)
            });
        match tau {
            Ok(st) => values.extend(st.tau.iter()),
            Err(e) => {
                failures.push(failed(e));
                values.extend([f64::NAN; 6]);
            }
        }
        for o in [tp.orientation.min(1), 2] {
            if let Some(slot) = acc.get_mut(o) {
                for (a, v) in slot.iter_mut().zip(&values) {
                    if v.is_finite() {
                        *a = (a.0.min(*v), a.1.max(*v), a.2 + 1);
                    }
                }
            }
        }
    }
    let mut rows = Vec::new();
    for (name_index, name) in names.iter().enumerate() {
        for (o, key) in keys.iter().enumerate() {
            let (min, max, count) = acc[o][name_index];
            rows.push(QuantityRange {
                quantity: name.clone(),
                orientation: key,
                min,
                max,
                poses: count,
            });
        }
    }
    Ok(Ranges {
        rows,
        poses: poses.len(),
        failures,
        parallel_inv_cond_min,
        serial_relative_min,
    })
}

/// The CSV text: quantity,orientation,min,max,span,poses.
pub fn to_csv(r: &Ranges) -> String {
    let mut s = String::from("quantity,orientation,min,max,span,poses\n");
    for q in &r.rows {
        s.push_str(&format!(
            "{},{},{},{},{},{}\n",
            q.quantity,
            q.orientation,
            fixed(q.min, 6),
            fixed(q.max, 6),
            fixed(q.span(), 6),
            q.poses
        ));
    }
    s
}

/// The human-readable table.
pub fn to_table(r: &Ranges, title: &str) -> String {
    let mut s = format!("{title}\n");
    s.push_str(&format!(
        "{:<14} | {:>27} | {:>27} | {:>27}\n",
        "quantity",
        "parallel min / max / span",
        "rotated min / max / span",
        "task min / max / span"
    ));
    let names: Vec<&String> = r
        .rows
        .iter()
        .filter(|q| q.orientation == "task")
        .map(|q| &q.quantity)
        .collect();
    for name in names {
        s.push_str(&format!("{name:<14}"));
        for key in ["parallel", "rotated", "task"] {
            match r.get(name, key) {
                Some(q) if q.poses > 0 => s.push_str(&format!(
                    " | {:>8.2} {:>8.2} {:>8.2}",
                    q.min,
                    q.max,
                    q.span()
                )),
                _ => s.push_str(&format!(" | {:>26}", "-")),
            }
        }
        s.push('\n');
    }
    s.push_str("\nthe columns of thesis Tables 8.2/8.3 (each quantity over the three chains):\n");
    let columns = r.table_columns("task");
    for c in &columns {
        s.push_str(&format!("{:<14}", c.quantity));
        for key in ["parallel", "rotated", "task"] {
            match r
                .table_columns(key)
                .iter()
                .find(|x| x.quantity == c.quantity)
            {
                Some(q) => s.push_str(&format!(
                    " | {:>8.2} {:>8.2} {:>8.2}",
                    q.min,
                    q.max,
                    q.span()
                )),
                None => s.push_str(&format!(" | {:>26}", "-")),
            }
        }
        s.push('\n');
    }
    s.push_str(&format!(
        "smallest singularity measures over the task: parallel inv_cond {:.4}, serial {:.4}\n",
        r.parallel_inv_cond_min, r.serial_relative_min
    ));
    s.push_str(&format!(
        "{} task poses, {} failed\n",
        r.poses,
        r.failures.len()
    ));
    for f in r.failures.iter().take(10) {
        s.push_str(&format!("  failed: {f}\n"));
    }
    s
}
