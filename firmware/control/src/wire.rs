//! Conversions between the wire (f32, m, rotation vectors, reasons, fault bits) and the
//! control application's values.

use kinematics_core::guards::Guard;
use kinematics_core::supervisor::Refusal as SupervisorRefusal;
use kinematics_core::{scalar, Pose};
use master_link::{Faults, NackReason};
use nalgebra::Vector3;

use crate::scalar::Scalar;

/// `f32` of a scalar (NaN if it does not convert).
pub fn to_f32<S: Scalar>(x: S) -> f32 {
    num_traits::ToPrimitive::to_f32(&x).unwrap_or(f32::NAN)
}

/// A pose from wire units; `InvalidValue` if a component is not finite.
pub fn pose_from_wire<S: Scalar>(
    position_m: [f32; 3],
    rotation_vector_rad: [f32; 3],
) -> Result<Pose<S>, NackReason> {
    let v = |a: [f32; 3]| {
        let [x, y, z] = a.map(|c| scalar::lit::<S>(f64::from(c)));
        Vector3::new(x, y, z)
    };
    Pose::from_position_rotation_vector(v(position_m), v(rotation_vector_rad))
        .map_err(|_| NackReason::InvalidValue)
}

/// A pose in wire units (position m, rotation vector rad).
pub fn pose_to_wire<S: Scalar>(pose: &Pose<S>) -> ([f32; 3], [f32; 3]) {
    let r = pose.rotation_vector();
    (
        [to_f32(pose.t.x), to_f32(pose.t.y), to_f32(pose.t.z)],
        [to_f32(r.x), to_f32(r.y), to_f32(r.z)],
    )
}

/// The Nack reason for a supervisor refusal.
pub fn refusal_reason<S: Scalar>(r: &SupervisorRefusal<S>) -> NackReason {
    match r {
        SupervisorRefusal::NonFinite => NackReason::InvalidValue,
        SupervisorRefusal::Stale { .. } | SupervisorRefusal::OutOfOrder => NackReason::StaleTarget,
        // Farther from the setpoint than one target may jump.
        SupervisorRefusal::TooFar { .. } => NackReason::VelocityLimit,
        SupervisorRefusal::Path { reading, .. } => guard_reason(reading.guard),
        SupervisorRefusal::Latched => NackReason::Faulted,
    }
}

/// The Nack reason for a violated guard.
pub fn guard_reason(g: Guard) -> NackReason {
    match g {
        Guard::Stroke | Guard::LinkAngle | Guard::Yaw | Guard::Pitch | Guard::Tilt => {
            NackReason::JointLimit
        }
        Guard::SerialSingularity | Guard::ParallelSingularity => NackReason::NearSingularity,
        Guard::TipSpeed
        | Guard::AngularSpeed
        | Guard::TipAccel
        | Guard::AngularAccel
        | Guard::JointSpeed
        | Guard::JointAccel => NackReason::VelocityLimit,
        Guard::Reach
        | Guard::Collision
        | Guard::Workspace
        | Guard::TiltCone
        | Guard::Force
        | Guard::Torque => NackReason::OutOfWorkspace,
    }
}

/// The fault bit latched when the supervisor stops on a guard.
pub fn guard_fault(g: Guard) -> Faults {
    match guard_reason(g) {
        NackReason::JointLimit => Faults::JOINT_LIMIT,
        NackReason::NearSingularity => Faults::SINGULARITY,
        _ => Faults::KINEMATICS,
    }
}
