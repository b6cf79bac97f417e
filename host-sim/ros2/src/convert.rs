//! A board status as the ROS 2 messages, and a `servo_cp` message as a board target.
//!
//! Frames (`CONVENTIONS.md`, Frames): poses are of the platform frame {p} in the world
//! (base) frame {0}, whose frame ids are [`BASE_FRAME`] and [`PLATFORM_FRAME`]. Units SI:
//! metres, radians, the orientation as a unit quaternion (ROS's x, y, z, w).
//! Joints (`CONVENTIONS.md`, Joints) in the board's order, named [`JOINT_NAMES`]: the
//! prismatic lengths l_i in metres, the rotating links' angles θ_i in radians.

use crate::messages::{
    DiagnosticArray, DiagnosticStatus, Header, JointState, KeyValue, Point, Pose, PoseStamped,
    Quaternion, TfMessage, Time, Transform, TransformStamped,
};
use kinematics_core::{inverse, Branch, Mechanism};
use master_link::{FaultCause, RobotState, StatusReport, Warnings};
use masters::CartesianPose;
use nalgebra::{Quaternion as NaQuaternion, UnitQuaternion, Vector3};
use operator::conversions::{measured_cp, setpoint_cp};
use thiserror::Error;

/// The frame id of the world (base) frame {0}.
pub const BASE_FRAME: &str = "base";
/// The frame id of the platform frame {p}.
pub const PLATFORM_FRAME: &str = "platform";
/// The actuated joints' names, in the board's joint order.
pub const JOINT_NAMES: [&str; 6] = ["l1", "l2", "l3", "theta1", "theta2", "theta3"];
/// The `hardware_id` of the diagnostics.
pub const HARDWARE_ID: &str = "rspr";

/// A `servo_cp` that cannot be a target.
#[derive(Clone, Debug, PartialEq, Error)]
pub enum PoseError {
    #[error("servo_cp pose.{field} is not finite ({value})")]
    NotFinite { field: &'static str, value: f64 },
    #[error(
        "servo_cp pose.orientation is not a rotation: its norm is {norm:.6} (a unit quaternion x, y, z, w is expected)"
    )]
    NotUnit { norm: f64 },
    #[error(
        "servo_cp header.frame_id is {0:?}: targets are poses of the platform in {BASE_FRAME:?} (or an empty frame id)"
    )]
    Frame(String),
}

/// How far from 1 a quaternion's norm may be and still be taken as a rotation (and
/// normalised): a quaternion typed with 6 decimals is within about 1e-6 of unit norm.
pub const UNIT_NORM_TOLERANCE: f64 = 1e-3;

/// A `servo_cp` message as the board's target: the pose of {p} in {0}.
pub fn target_of(msg: &PoseStamped) -> Result<CartesianPose, PoseError> {
    if !(msg.header.frame_id.is_empty() || msg.header.frame_id == BASE_FRAME) {
        return Err(PoseError::Frame(msg.header.frame_id.clone()));
    }
    let p = msg.pose.position;
    let q = msg.pose.orientation;
    for (field, value) in [
        ("position.x", p.x),
        ("position.y", p.y),
        ("position.z", p.z),
        ("orientation.x", q.x),
        ("orientation.y", q.y),
        ("orientation.z", q.z),
        ("orientation.w", q.w),
    ] {
        if !value.is_finite() {
            return Err(PoseError::NotFinite { field, value });
        }
    }
    let quaternion = NaQuaternion::new(q.w, q.x, q.y, q.z);
    let norm = quaternion.norm();
    // Written so that a NaN norm is refused too.
    if (norm - 1.0).abs().partial_cmp(&UNIT_NORM_TOLERANCE) != Some(std::cmp::Ordering::Less) {
        return Err(PoseError::NotUnit { norm });
    }
    Ok(CartesianPose {
        position_m: Vector3::new(p.x, p.y, p.z),
        orientation: UnitQuaternion::from_quaternion(quaternion),
    })
}

/// A pose as `geometry_msgs/Pose`.
pub fn pose_msg(p: &CartesianPose) -> Pose {
    let q = p.orientation.quaternion();
    Pose {
        position: Point {
            x: p.position_m.x,
            y: p.position_m.y,
            z: p.position_m.z,
        },
        orientation: Quaternion {
            x: q.i,
            y: q.j,
            z: q.k,
            w: q.w,
        },
    }
}

fn header(stamp: Time, frame: &str) -> Header {
    Header {
        stamp,
        frame_id: frame.to_string(),
    }
}

/// A pose of {p} in {0}, stamped.
pub fn pose_stamped(p: &CartesianPose, stamp: Time) -> PoseStamped {
    PoseStamped {
        header: header(stamp, BASE_FRAME),
        pose: pose_msg(p),
    }
}

/// `measured_cp`: the measured pose of the status (`None` when it is not finite).
pub fn measured_cp_msg(s: &StatusReport, stamp: Time) -> Option<PoseStamped> {
    measured_cp(s).map(|p| pose_stamped(&p, stamp))
}

/// `setpoint_cp`: the supervisor's setpoint (`None` while there is none: not finite).
pub fn setpoint_cp_msg(s: &StatusReport, stamp: Time) -> Option<PoseStamped> {
    setpoint_cp(s).map(|p| pose_stamped(&p, stamp))
}

/// Joint positions (joint order, SI) as `sensor_msgs/JointState` (no velocities or efforts:
/// the status carries none).
pub fn joint_state(q: [f64; 6], stamp: Time) -> JointState {
    JointState {
        header: header(stamp, ""),
        name: JOINT_NAMES.iter().map(|n| n.to_string()).collect(),
        position: q.to_vec(),
        velocity: Vec::new(),
        effort: Vec::new(),
    }
}

/// `measured_js`: the measured joints of the status (the encoders).
pub fn measured_js_msg(s: &StatusReport, stamp: Time) -> JointState {
    joint_state(s.joints.map(f64::from), stamp)
}

/// `setpoint_js`: the joints of the setpoint pose by the inverse kinematics of `robot` on
/// the outer branch (the prototype's: `CONVENTIONS.md`, Branches); `None` while there is no
/// setpoint or when it has no solution.
pub fn setpoint_js_msg<M: Mechanism<f64> + ?Sized>(
    robot: &M,
    s: &StatusReport,
    stamp: Time,
) -> Option<JointState> {
    let p = setpoint_cp(s)?;
    let pose = kinematics_core::Pose {
        t: p.position_m,
        r: p.orientation.to_rotation_matrix(),
    };
    let q = inverse(robot, &pose, Branch::OUTER).ok()?.q();
    Some(joint_state([q[0], q[1], q[2], q[3], q[4], q[5]], stamp))
}

/// `/tf`: {p} in {0} at the measured pose.
pub fn tf_msg(s: &StatusReport, stamp: Time) -> Option<TfMessage> {
    let p = measured_cp(s)?;
    let pose = pose_msg(&p);
    Some(TfMessage {
        transforms: vec![TransformStamped {
            header: header(stamp, BASE_FRAME),
            child_frame_id: PLATFORM_FRAME.to_string(),
            transform: Transform {
                translation: pose.position,
                rotation: pose.orientation,
            },
        }],
    })
}

/// The diagnostics of a status: the latched fault (`ERROR` in `Fault`, with the cause in
/// words and the stop in force) and the guard margins (`WARN` while the board warns of a
/// joint limit or a singularity; each margin's share left and its words).
pub fn diagnostics_msg(s: &StatusReport, stamp: Time) -> DiagnosticArray {
    let kv = |k: &str, v: String| KeyValue {
        key: k.to_string(),
        value: v,
    };
    let fault_words = board_words::fault(&s.fault);
    let faulted = s.state == RobotState::Fault;
    let fault = DiagnosticStatus {
        level: if faulted {
            DiagnosticStatus::ERROR
        } else {
            DiagnosticStatus::OK
        },
        name: "rspr: latched fault".into(),
        message: match (&fault_words, faulted) {
            (Some(f), true) => format!("fault: {f}"),
            (None, true) => "fault: not reported".into(),
            (_, false) => "no fault latched".into(),
        },
        hardware_id: HARDWARE_ID.into(),
        values: vec![
            kv("state", board_words::state(s.state).to_string()),
            kv(
                "cause",
                if s.fault.cause == FaultCause::None {
                    "none".into()
                } else {
                    fault_words.unwrap_or_default()
                },
            ),
            kv(
                "stop",
                board_words::stop(s.state, s.stop)
                    .unwrap_or("none")
                    .to_string(),
            ),
        ],
    };
    let warn = s.warnings.intersects(
        Warnings::NEAR_JOINT_LIMIT
            | Warnings::NEAR_SERIAL_SINGULARITY
            | Warnings::NEAR_PARALLEL_SINGULARITY,
    );
    let mut values = vec![kv("nearest", board_words::nearest_margin(&s.margins))];
    for m in board_words::margins(&s.margins) {
        values.push(kv(
            &format!("{} share left", m.guard),
            format!("{:.4}", m.left),
        ));
    }
    let margins = DiagnosticStatus {
        level: if warn {
            DiagnosticStatus::WARN
        } else {
            DiagnosticStatus::OK
        },
        name: "rspr: guard margins".into(),
        message: board_words::nearest_margin_short(&s.margins),
        hardware_id: HARDWARE_ID.into(),
        values,
    };
    DiagnosticArray {
        header: header(stamp, ""),
        status: vec![fault, margins],
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::expect_used)]
    use super::*;
    use kinematics_core::{forward, FkConfig, RsprGeometry};
    use proptest::prelude::*;

    fn msg(p: [f64; 3], q: [f64; 4], frame: &str) -> PoseStamped {
        PoseStamped {
            header: Header {
                stamp: Time::default(),
                frame_id: frame.into(),
            },
            pose: Pose {
                position: Point {
                    x: p[0],
                    y: p[1],
                    z: p[2],
                },
                orientation: Quaternion {
                    x: q[0],
                    y: q[1],
                    z: q[2],
                    w: q[3],
                },
            },
        }
    }

    proptest! {
        #![proptest_config(proptest_config::cases(64))]

        /// A pose written as a message and read back as a target is the same pose (to
        /// rounding, 1e-12), in either frame spelling the target takes.
        #[test]
        fn pose_round_trips(x in -0.05..0.05f64, y in -0.05..0.05f64, z in 0.13..0.2f64,
                            rx in -0.5..0.5f64, ry in -0.5..0.5f64, rz in -0.5..0.5f64) {
            let p = CartesianPose {
                position_m: Vector3::new(x, y, z),
                orientation: UnitQuaternion::from_scaled_axis(Vector3::new(rx, ry, rz)),
            };
            let mut m = pose_stamped(&p, Time::default());
            prop_assert_eq!(m.header.frame_id.as_str(), BASE_FRAME);
            for frame in [BASE_FRAME, ""] {
                m.header.frame_id = frame.into();
                let back = target_of(&m).expect("a valid pose");
                prop_assert!((back.position_m - p.position_m).norm() < 1e-12);
                prop_assert!(back.orientation.angle_to(&p.orientation) < 1e-9);
            }
        }

        /// setpoint_js is the inverse kinematics of setpoint_cp: the forward kinematics of
        /// the published joints gives the setpoint pose back (1e-9 m: FK's tolerance is far
        /// below; the pose is f32 on the wire, the check is on the f64 the IK saw).
        #[test]
        fn setpoint_js_inverts_setpoint_cp(x in -0.02..0.02f64, y in -0.02..0.02f64,
                                           z in 0.15..0.17f64, rx in -0.2..0.2f64) {
            let robot = RsprGeometry::<f64>::reference();
            let s = StatusReport {
                setpoint_position_m: [x as f32, y as f32, z as f32],
                setpoint_rotation_vector_rad: [rx as f32, 0.0, 0.0],
                ..StatusReport::default()
            };
            let js = setpoint_js_msg(&robot, &s, Time::default()).expect("inside the task");
            prop_assert_eq!(&js.name, &JOINT_NAMES.map(String::from).to_vec());
            let q = kinematics_core::Joints::from_column_slice(&js.position);
            let sp = setpoint_cp(&s).expect("finite");
            let seed = kinematics_core::Pose { t: sp.position_m, r: sp.orientation.to_rotation_matrix() };
            let fk = forward(&robot, &q, Branch::OUTER, &seed, &FkConfig::default()).expect("FK converges");
            prop_assert!((fk.pose.t - sp.position_m).norm() < 1e-9, "{}", (fk.pose.t - sp.position_m).norm());
        }
    }

    /// A target in another frame, with a NaN or with a quaternion that is not a rotation
    /// is refused, and the message names what is wrong.
    #[test]
    fn bad_targets_are_refused_with_the_field() {
        let e = target_of(&msg([0.0, 0.0, 0.16], [0.0, 0.0, 0.0, 1.0], "world"))
            .expect_err("a foreign frame");
        assert!(e.to_string().contains("\"world\""), "{e}");
        let e =
            target_of(&msg([0.0, f64::NAN, 0.16], [0.0, 0.0, 0.0, 1.0], "base")).expect_err("NaN");
        assert!(e.to_string().contains("position.y"), "{e}");
        let e = target_of(&msg([0.0, 0.0, 0.16], [0.0, 0.0, 0.0, 0.0], "base"))
            .expect_err("zero quaternion");
        assert!(e.to_string().contains("norm is 0.000000"), "{e}");
        let e = target_of(&msg([0.0, 0.0, 0.16], [0.0, 0.0, 0.0, 1.01], "base"))
            .expect_err("a quaternion 1 % long");
        assert!(matches!(e, PoseError::NotUnit { .. }), "{e}");
    }

    /// The fault diagnostic is ERROR with the cause in words in Fault, OK otherwise; the
    /// margins diagnostic warns exactly when the board warns of a limit or singularity.
    #[test]
    fn diagnostics_follow_the_status() {
        let mut s = StatusReport::default();
        let d = diagnostics_msg(&s, Time::default());
        assert_eq!(d.status[0].level, DiagnosticStatus::OK);
        assert_eq!(d.status[1].level, DiagnosticStatus::OK);
        s.state = RobotState::Fault;
        s.fault.cause = FaultCause::EmergencyStopButton;
        s.warnings.insert(Warnings::NEAR_JOINT_LIMIT);
        let d = diagnostics_msg(&s, Time::default());
        assert_eq!(d.status[0].level, DiagnosticStatus::ERROR);
        let words = board_words::fault(&s.fault).expect("a cause");
        assert_eq!(d.status[0].message, format!("fault: {words}"));
        assert_eq!(d.status[1].level, DiagnosticStatus::WARN);
    }
}
