//! Poses and joints in their edge form (CONVENTIONS.md, "Units" and "Pose"): the
//! unit-suffixed names of their components and the conversions between mm/deg values and
//! the core's SI types.

use crate::units::{deg_to_rad, m_to_mm, mm_to_m, rad_to_deg, wrap_deg};
use kinematics_core::{JointKind, Joints, Mechanism, Pose, Robot, RobotKind};
use nalgebra::Vector3;
use thiserror::Error;

/// A pose: position of o_p in mm, rotation vector (axis * angle) in degrees.
pub const POSE: [&str; 6] = ["x_mm", "y_mm", "z_mm", "rx_deg", "ry_deg", "rz_deg"];
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

/// The joint names of a robot, in q order.
pub fn joint_columns(kind: RobotKind) -> [&'static str; 6] {
    match kind {
        RobotKind::Rspr => RSPR_JOINTS,
        RobotKind::Usr => USR_JOINTS,
    }
}

/// A pose whose edge values do not make a pose.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Error)]
pub enum EdgeError {
    /// A component is NaN or infinite.
    #[error("{name}: not finite")]
    NotFinite {
        /// The component's name (e.g. `z_mm`).
        name: &'static str,
    },
}

/// A pose from its edge values (mm, deg); `names` name the values in messages.
pub fn pose_from_edge(names: &[&'static str; 6], v: [f64; 6]) -> Result<Pose<f64>, EdgeError> {
    let [x, y, z, rx, ry, rz] = v;
    Pose::from_position_rotation_vector(
        Vector3::new(mm_to_m(x), mm_to_m(y), mm_to_m(z)),
        Vector3::new(deg_to_rad(rx), deg_to_rad(ry), deg_to_rad(rz)),
    )
    .map_err(|e| EdgeError::NotFinite {
        name: names
            .get(usize::from(e.component))
            .copied()
            .unwrap_or("pose"),
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

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used)]
    use super::*;

    #[test]
    fn a_non_finite_component_is_named() {
        let e = pose_from_edge(&POSE, [0.0, 0.0, f64::NAN, 0.0, 0.0, 0.0]).unwrap_err();
        assert_eq!(e.to_string(), "z_mm: not finite");
        let e = pose_from_edge(&POSE, [0.0, 0.0, 160.0, 0.0, f64::INFINITY, 0.0]).unwrap_err();
        assert_eq!(e.to_string(), "ry_deg: not finite");
    }

    #[test]
    fn edge_values_round_trip() {
        let p = [10.0, -5.0, 165.0, 5.0, 0.0, -3.0];
        let back = pose_to_edge(&pose_from_edge(&POSE, p).unwrap());
        for (a, b) in p.iter().zip(back) {
            assert!((a - b).abs() < 1e-12, "{a} vs {b}");
        }
    }
}
