//! Conversions between the wire (f32, m, rotation vectors, reasons, fault bits) and the
//! control application's values.

use kinematics_core::guards::{Guard, Reading, Subject};
use kinematics_core::supervisor::{Refusal as SupervisorRefusal, SupervisorConfig};
use kinematics_core::{scalar, Pose};
use master_link::{Breach, Faults, GuardId, NackReason, RefusedTarget, NO_JOINT};
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
        // The first guard the target itself breaks, else: farther from the setpoint than
        // one target may jump.
        SupervisorRefusal::TooFar {
            breaks: Some(reading),
            ..
        } => guard_reason(reading.guard),
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

/// The wire's name of a guard.
pub fn guard_id(g: Guard) -> GuardId {
    match g {
        Guard::Reach => GuardId::Reach,
        Guard::Stroke => GuardId::Stroke,
        Guard::LinkAngle => GuardId::LinkAngle,
        Guard::Yaw => GuardId::Yaw,
        Guard::Pitch => GuardId::Pitch,
        Guard::Tilt => GuardId::Tilt,
        Guard::Collision => GuardId::Collision,
        Guard::Workspace => GuardId::Workspace,
        Guard::TiltCone => GuardId::TiltCone,
        Guard::SerialSingularity => GuardId::SerialSingularity,
        Guard::ParallelSingularity => GuardId::ParallelSingularity,
        Guard::Force => GuardId::Force,
        Guard::Torque => GuardId::Torque,
        Guard::TipSpeed => GuardId::TipSpeed,
        Guard::AngularSpeed => GuardId::AngularSpeed,
        Guard::TipAccel => GuardId::TipAccel,
        Guard::AngularAccel => GuardId::AngularAccel,
        Guard::JointSpeed => GuardId::JointSpeed,
        Guard::JointAccel => GuardId::JointAccel,
    }
}

/// A reading on the wire: its guard, subject (chain 0..=2, joint 0..=5, axis 0..=2),
/// value and limit.
pub fn reading_breach<S: Scalar>(r: &Reading<S>) -> Breach {
    let subject = match r.subject {
        Subject::Robot => NO_JOINT,
        Subject::Chain(c) => c.index() as u8,
        Subject::Joint(j) => j.saturating_sub(1),
        Subject::Axis(a) => a,
    };
    Breach {
        guard: guard_id(r.guard),
        subject,
        value: to_f32(r.value),
        limit: to_f32(r.limit),
    }
}

/// What a supervisor refusal measured, on the wire: the guard's reading, or the rule of
/// admission with its value and limit (`cfg`: the supervisor's).
pub fn refusal_breach<S: Scalar>(r: &SupervisorRefusal<S>, cfg: &SupervisorConfig<S>) -> Breach {
    let rule = |guard: GuardId, value: f32, limit: f32| Breach {
        guard,
        subject: NO_JOINT,
        value,
        limit,
    };
    match r {
        SupervisorRefusal::NonFinite
        | SupervisorRefusal::OutOfOrder
        | SupervisorRefusal::Latched => Breach::NONE,
        SupervisorRefusal::Stale { age_us } => rule(
            GuardId::Age,
            *age_us as f32 * 1e-6,
            cfg.stale_after_us as f32 * 1e-6,
        ),
        SupervisorRefusal::TooFar {
            breaks: Some(reading),
            ..
        }
        | SupervisorRefusal::Path { reading, .. } => reading_breach(reading),
        SupervisorRefusal::TooFar {
            distance, angle, ..
        } => {
            if *distance > cfg.max_segment {
                rule(GuardId::Step, to_f32(*distance), to_f32(cfg.max_segment))
            } else {
                rule(
                    GuardId::StepAngle,
                    to_f32(*angle),
                    to_f32(cfg.max_segment_angle),
                )
            }
        }
    }
}

/// A supervisor refusal of the target stamped `timestamp_us` (master clock) on the wire,
/// not yet the reply to a frame.
pub fn refused_target<S: Scalar>(
    r: &SupervisorRefusal<S>,
    cfg: &SupervisorConfig<S>,
    timestamp_us: u64,
) -> RefusedTarget {
    RefusedTarget {
        reply_to: None,
        timestamp_us,
        reason: refusal_reason(r),
        breach: refusal_breach(r, cfg),
    }
}
