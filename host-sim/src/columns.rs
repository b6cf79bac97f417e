//! Column names of the CSV edge and the readers that turn a row's fields into the core's
//! SI types. Every name carries its unit (CONVENTIONS.md, "Units").

use crate::batch::Row;
use crate::units::{deg_to_rad, m_to_mm, mm_to_m, rad_to_deg, wrap_deg};
use kinematics_core::{Branch, JointKind, Joints, Mechanism, Pose, Robot, RobotKind, Wrench};
use nalgebra::Vector3;

/// A pose: position of o_p in mm, rotation vector (axis * angle) in degrees.
pub const POSE: [&str; 6] = ["x_mm", "y_mm", "z_mm", "rx_deg", "ry_deg", "rz_deg"];
/// The initial pose of the forward kinematics (same units as [`POSE`]).
pub const INITIAL_POSE: [&str; 6] = ["x0_mm", "y0_mm", "z0_mm", "rx0_deg", "ry0_deg", "rz0_deg"];
/// The inverse-kinematics branch, 0..=7 (CONVENTIONS.md, "Branches").
pub const BRANCH: &str = "branch";
/// The wrench the platform exerts on its environment, moment about o_p, in {0}.
pub const WRENCH: [&str; 6] = ["fx_n", "fy_n", "fz_n", "tx_nm", "ty_nm", "tz_nm"];
/// RSPR joints in q order: prismatic lengths, then rotating-link angles.
pub const RSPR_JOINTS: [&str; 6] = [
    "l1_mm",
    "l2_mm",
    "l3_mm",
    "theta1_deg",
    "theta2_deg",
    "theta3_deg",
];
/// USR joints in q order: yaws, then elevations of the lower links.
pub const USR_JOINTS: [&str; 6] = [
    "alpha1_deg",
    "alpha2_deg",
    "alpha3_deg",
    "beta1_deg",
    "beta2_deg",
    "beta3_deg",
];

/// The joint columns of a robot, in q order.
pub fn joint_columns(kind: RobotKind) -> [&'static str; 6] {
    match kind {
        RobotKind::Rspr => RSPR_JOINTS,
        RobotKind::Usr => USR_JOINTS,
    }
}

/// Parses one numeric field; the message names the column.
pub fn parse_number(column: &str, text: &str) -> Result<f64, String> {
    let text = text.trim();
    if text.is_empty() {
        return Err(format!("{column}: empty"));
    }
    match text.parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(v),
        Ok(_) => Err(format!("{column}: \"{text}\" is not a finite number")),
        Err(_) => Err(format!("{column}: \"{text}\" is not a number")),
    }
}

/// Parses a branch number 0..=7.
pub fn parse_branch(text: &str) -> Result<Branch, String> {
    let text = text.trim();
    if text.is_empty() {
        return Err(format!("{BRANCH}: empty"));
    }
    let bits: u32 = text
        .parse()
        .map_err(|_| format!("{BRANCH}: \"{text}\" is not an integer 0..=7"))?;
    Branch::new(bits).map_err(|_| format!("{BRANCH}: {bits} is out of range 0..=7"))
}

/// Checks one field of a column this module knows (the branch or a number).
pub fn check_field(column: &str, text: &str) -> Result<(), String> {
    if column == BRANCH {
        parse_branch(text).map(|_| ())
    } else {
        parse_number(column, text).map(|_| ())
    }
}

/// A pose from its edge values (mm, deg); `columns` name the values in messages.
pub fn pose_from_edge(columns: &[&str; 6], v: [f64; 6]) -> Result<Pose<f64>, String> {
    let [x, y, z, rx, ry, rz] = v;
    Pose::from_position_rotation_vector(
        Vector3::new(mm_to_m(x), mm_to_m(y), mm_to_m(z)),
        Vector3::new(deg_to_rad(rx), deg_to_rad(ry), deg_to_rad(rz)),
    )
    .map_err(|e| {
        let column = columns
            .get(usize::from(e.component))
            .copied()
            .unwrap_or("pose");
        format!("{column}: not finite")
    })
}

/// A pose's edge values (mm, deg); the rotation vector has an angle in [0, 180] deg.
pub fn pose_to_edge(pose: &Pose<f64>) -> [f64; 6] {
    let r = pose.rotation_vector();
    [
        m_to_mm(pose.t.x),
        m_to_mm(pose.t.y),
        m_to_mm(pose.t.z),
        rad_to_deg(r.x),
        rad_to_deg(r.y),
        rad_to_deg(r.z),
    ]
}

/// Joints from their edge values: lengths in mm, angles in degrees.
pub fn joints_from_edge(robot: &Robot<f64>, v: [f64; 6]) -> Joints<f64> {
    let kinds = robot.joint_kinds();
    Joints::from_fn(|i, _| match (kinds.get(i), v.get(i)) {
        (Some(JointKind::Linear), Some(&x)) => mm_to_m(x),
        (Some(JointKind::Angular), Some(&x)) => deg_to_rad(x),
        _ => f64::NAN,
    })
}

/// A joint vector's edge values: lengths in mm, angles in degrees wrapped to (-180, 180].
pub fn joints_to_edge(robot: &Robot<f64>, q: &Joints<f64>) -> [f64; 6] {
    let kinds = robot.joint_kinds();
    let mut out = [0.0; 6];
    for ((o, kind), x) in out.iter_mut().zip(kinds.iter()).zip(q.iter()) {
        *o = match kind {
            JointKind::Linear => m_to_mm(*x),
            JointKind::Angular => wrap_deg(rad_to_deg(*x)),
        };
    }
    out
}

/// The pose columns of a row, in SI.
pub fn read_pose(row: &Row<'_>) -> Result<Pose<f64>, String> {
    pose_from_edge(&POSE, row.numbers(&POSE)?)
}

/// The branch column of a row.
pub fn read_branch(row: &Row<'_>) -> Result<Branch, String> {
    match row.get(BRANCH) {
        Some(text) => parse_branch(text),
        None => Err(format!("{BRANCH}: missing")),
    }
}

/// The joint columns of a row, in SI.
pub fn read_joints(row: &Row<'_>, robot: &Robot<f64>) -> Result<Joints<f64>, String> {
    Ok(joints_from_edge(
        robot,
        row.numbers(&joint_columns(robot.kind()))?,
    ))
}

/// The wrench columns of a row (N, N m).
pub fn read_wrench(row: &Row<'_>) -> Result<Wrench<f64>, String> {
    Ok(Wrench::from(row.numbers(&WRENCH)?))
}

/// The optional initial pose of a row: `None` when all six columns are absent or empty.
pub fn read_initial_pose(row: &Row<'_>) -> Result<Option<Pose<f64>>, String> {
    let given = INITIAL_POSE
        .iter()
        .any(|c| row.get(c).is_some_and(|t| !t.trim().is_empty()));
    if !given {
        return Ok(None);
    }
    let values = row
        .numbers(&INITIAL_POSE)
        .map_err(|e| format!("{e} (give all six initial-pose columns or none)"))?;
    pose_from_edge(&INITIAL_POSE, values).map(Some)
}
