//! Poses from the edge form of the settings files: x_mm, y_mm, z_mm, rx_deg, ry_deg,
//! rz_deg with (rx, ry, rz) the rotation vector (CONVENTIONS.md, "Pose").

use kinematics_core::Pose;
use nalgebra::{Rotation3, Vector3};

/// A pose from the edge form x_mm, y_mm, z_mm, rx_deg, ry_deg, rz_deg.
pub fn pose_mm_deg(p: &[f64; 6]) -> Pose<f64> {
    Pose {
        t: Vector3::new(p[0], p[1], p[2]) * 1e-3,
        r: Rotation3::from_scaled_axis(Vector3::new(p[3], p[4], p[5]).map(f64::to_radians)),
    }
}

/// A pose displaced from `base` by an edge-form offset (translation added, rotation
/// vector composed in the world frame).
pub fn offset_pose(base: &Pose<f64>, d: &[f64; 6]) -> Pose<f64> {
    let off = pose_mm_deg(d);
    Pose {
        t: base.t + off.t,
        r: off.r * base.r,
    }
}
