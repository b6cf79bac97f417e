//! Poses between the master side (`masters::CartesianPose`, f64, SI) and the wire (f32
//! position and rotation vector, SI), and the status's poses.

use master_link::StatusReport;
use masters::CartesianPose;

/// A pose as the wire carries it: position, m, and rotation vector, rad.
pub fn wire_pose(p: &CartesianPose) -> ([f32; 3], [f32; 3]) {
    let r = p.rotation_vector_rad();
    let t = p.position_m;
    (
        [t.x as f32, t.y as f32, t.z as f32],
        [r.x as f32, r.y as f32, r.z as f32],
    )
}

/// A pose from the wire's position (m) and rotation vector (rad); `None` when not finite.
pub fn pose_from_wire(
    position_m: [f32; 3],
    rotation_vector_rad: [f32; 3],
) -> Option<CartesianPose> {
    CartesianPose::from_position_rotation_vector(
        position_m.map(f64::from),
        rotation_vector_rad.map(f64::from),
    )
    .ok()
}

/// The measured pose of a status (CRTK `measured_cp`).
pub fn measured_cp(s: &StatusReport) -> Option<CartesianPose> {
    pose_from_wire(s.position_m, s.rotation_vector_rad)
}

/// The supervisor's setpoint of a status (CRTK `setpoint_cp`).
pub fn setpoint_cp(s: &StatusReport) -> Option<CartesianPose> {
    pose_from_wire(s.setpoint_position_m, s.setpoint_rotation_vector_rad)
}

/// The guard margins of a status by name (finite ones only).
pub fn margins(s: &StatusReport) -> Vec<(&'static str, f64)> {
    let m = &s.margins;
    [
        ("nearest", m.nearest),
        ("serial", m.serial),
        ("parallel", m.parallel),
        ("stroke", m.stroke),
        ("tilt", m.tilt),
        ("collision", m.collision),
        ("workspace", m.workspace),
    ]
    .into_iter()
    .map(|(k, v)| (k, f64::from(v)))
    .filter(|(_, v)| v.is_finite())
    .collect()
}
