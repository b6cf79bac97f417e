//! A board status as the ROS 2 messages, and a `servo_cp` or `servo_jp` message as a
//! board target.
//!
//! Frames (`CONVENTIONS.md`, Frames): poses are of the platform frame {p} in the world
//! (base) frame {0}, whose frame ids are [`BASE_FRAME`] and [`PLATFORM_FRAME`]. Units SI:
//! metres, radians, the orientation as a unit quaternion (ROS's x, y, z, w).
//! Joints (`CONVENTIONS.md`, Joints) in the board's order, named [`JOINT_NAMES`]: the
//! prismatic lengths l_i in metres, the rotating links' angles θ_i in radians.
//! `/joint_states` and the full `/tf` carry every joint and link of the robot description
//! (`robot_description`), whose names are the URDF's.

use crate::messages::{
    DiagnosticArray, DiagnosticStatus, Header, JointState, KeyValue, Point, Pose, PoseStamped,
    Quaternion, TfMessage, Time, Transform, TransformStamped,
};
use kinematics_core::{forward, inverse, Branch, FkConfig, FkError, Joints, Mechanism};
use master_link::{FaultCause, RobotState, StatusReport, Warnings};
use masters::CartesianPose;
use nalgebra::{Isometry3, Quaternion as NaQuaternion, UnitQuaternion, Vector3};
use operator::conversions::{measured_cp, setpoint_cp};
use robot_description::{Description, JointStates};
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
    let pose = kinematic_pose(&setpoint_cp(s)?);
    let q = inverse(robot, &pose, Branch::OUTER).ok()?.q();
    Some(joint_state([q[0], q[1], q[2], q[3], q[4], q[5]], stamp))
}

/// A pose as a kinematics pose (t, R).
pub fn kinematic_pose(p: &CartesianPose) -> kinematics_core::Pose<f64> {
    kinematics_core::Pose {
        t: p.position_m,
        r: p.orientation.to_rotation_matrix(),
    }
}

/// A kinematics pose (t, R) as a target pose.
pub fn cartesian_pose(p: &kinematics_core::Pose<f64>) -> CartesianPose {
    CartesianPose {
        position_m: p.t,
        orientation: UnitQuaternion::from_rotation_matrix(&p.r),
    }
}

/// Why the measured joints of a status could not be posed as the description.
#[derive(Clone, Debug, PartialEq, Error)]
pub enum PosingError {
    #[error("the measured joints have no forward kinematics on branch {branch}: {error}")]
    Fk { branch: Branch, error: FkError },
    #[error("the description at the measured joints: {0}")]
    Description(String),
}

/// Every joint of the description at the measured joints `q` of a status: the pose by the
/// forward kinematics of `q` (from `guess`, the board's measured pose or the last one
/// found), then [`Description::joint_states`] at it, so that the actuated joints equal
/// `q` to the forward kinematics' tolerance (`FkConfig::default`: about 1e-15 m and
/// 1e-14 rad in f64) and the passive ones are those of that pose. With the pose.
pub fn measured_joint_states(
    d: &Description,
    q: [f64; 6],
    guess: &kinematics_core::Pose<f64>,
) -> Result<(kinematics_core::Pose<f64>, JointStates), PosingError> {
    let fk = forward(
        d.robot(),
        &Joints::from(q),
        d.branch(),
        guess,
        &FkConfig::default(),
    )
    .map_err(|error| PosingError::Fk {
        branch: d.branch(),
        error,
    })?;
    let states = d
        .joint_states(&fk.pose)
        .map_err(|e| PosingError::Description(e.to_string()))?;
    Ok((fk.pose, states))
}

/// `/joint_states`: every moving joint of the description, named as in the URDF, SI.
pub fn joint_states_msg(states: &JointStates, stamp: Time) -> JointState {
    JointState {
        header: header(stamp, ""),
        name: states.names.clone(),
        position: states.positions.clone(),
        velocity: Vec::new(),
        effort: Vec::new(),
    }
}

fn transform_msg(iso: &Isometry3<f64>) -> Transform {
    let t = iso.translation.vector;
    let q = iso.rotation.quaternion();
    Transform {
        translation: Point {
            x: t.x,
            y: t.y,
            z: t.z,
        },
        rotation: Quaternion {
            x: q.i,
            y: q.j,
            z: q.k,
            w: q.w,
        },
    }
}

/// `/tf`: every joint of the description (fixed ones too) as the transform from its
/// parent link to its child link at the joint states, URDF's semantics: the frames of
/// every link from [`BASE_FRAME`] to [`PLATFORM_FRAME`] (which hangs off chain 1's pin),
/// what `robot_state_publisher` would publish from `/joint_states`. A joint missing from
/// `states` is an error of the caller (`None`).
pub fn tf_msg(d: &Description, states: &JointStates, stamp: Time) -> Option<TfMessage> {
    let values = states.as_map();
    d.tree()
        .joints
        .iter()
        .map(|j| {
            let v = match j.drive {
                robot_description::Drive::Fixed => 0.0,
                _ => *values.get(&j.name)?,
            };
            Some(TransformStamped {
                header: header(stamp, &j.parent),
                child_frame_id: j.child.clone(),
                transform: transform_msg(&j.transform(v)),
            })
        })
        .collect::<Option<Vec<_>>>()
        .map(|transforms| TfMessage { transforms })
}

/// A `servo_jp` that cannot be a target.
#[derive(Clone, Debug, PartialEq, Error)]
pub enum JointTargetError {
    #[error(
        "servo_jp names {count} joints: the six actuated joints l1, l2, l3, theta1, theta2, theta3 are expected"
    )]
    Count { count: usize },
    #[error(
        "servo_jp has {names} names and {positions} positions: one position per name is expected"
    )]
    Positions { names: usize, positions: usize },
    #[error(
        "servo_jp name[{index}] is {name:?}: not an actuated joint (l1, l2, l3, theta1, theta2, theta3)"
    )]
    UnknownName { index: usize, name: String },
    #[error("servo_jp names joint {name:?} twice (name[{first}] and name[{second}])")]
    Duplicate {
        name: String,
        first: usize,
        second: usize,
    },
    #[error("servo_jp position[{index}] ({name}) is not finite ({value})")]
    NotFinite {
        index: usize,
        name: &'static str,
        value: f64,
    },
    #[error(
        "servo_jp joints have no forward kinematics on branch {branch} (SI: l in m, theta in rad): {error}"
    )]
    NoForwardKinematics { branch: Branch, error: FkError },
}

/// The six actuated joints of a `servo_jp` in the board's order (`CONVENTIONS.md`,
/// Joints), whatever order the message names them in: exactly the six names of
/// [`JOINT_NAMES`], each once, one finite position each (m, rad).
pub fn joints_of(msg: &JointState) -> Result<[f64; 6], JointTargetError> {
    if msg.name.len() != JOINT_NAMES.len() {
        return Err(JointTargetError::Count {
            count: msg.name.len(),
        });
    }
    if msg.position.len() != msg.name.len() {
        return Err(JointTargetError::Positions {
            names: msg.name.len(),
            positions: msg.position.len(),
        });
    }
    let mut q = [0.0; 6];
    let mut seen: [Option<usize>; 6] = [None; 6];
    for (index, (name, value)) in msg.name.iter().zip(&msg.position).enumerate() {
        let Some(k) = JOINT_NAMES.iter().position(|n| n == name) else {
            return Err(JointTargetError::UnknownName {
                index,
                name: name.clone(),
            });
        };
        if let Some(first) = seen[k] {
            return Err(JointTargetError::Duplicate {
                name: name.clone(),
                first,
                second: index,
            });
        }
        if !value.is_finite() {
            return Err(JointTargetError::NotFinite {
                index,
                name: JOINT_NAMES[k],
                value: *value,
            });
        }
        seen[k] = Some(index);
        q[k] = *value;
    }
    Ok(q)
}

/// A `servo_jp` message as the board's target: the pose of the forward kinematics of its
/// joints on `robot`'s `branch`, found from `guess` (the measured pose: the robot moves
/// continuously, so the assembly mode it is in is the one the iteration reaches).
pub fn target_of_joints<M: Mechanism<f64> + ?Sized>(
    robot: &M,
    branch: Branch,
    msg: &JointState,
    guess: &kinematics_core::Pose<f64>,
) -> Result<CartesianPose, JointTargetError> {
    let q = joints_of(msg)?;
    forward(robot, &Joints::from(q), branch, guess, &FkConfig::default())
        .map(|fk| cartesian_pose(&fk.pose))
        .map_err(|error| JointTargetError::NoForwardKinematics { branch, error })
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
    use kinematics_core::guards::Limits;
    use kinematics_core::{Robot, RsprGeometry};
    use proptest::prelude::*;
    use std::collections::HashMap;

    fn description() -> Description {
        let robot = Robot::Rspr(RsprGeometry::<f64>::reference());
        Description::new(&robot, &Limits::reference(), Branch::OUTER).expect("the reference")
    }

    /// A pose of the task box (CONVENTIONS.md, The reference robot): offsets from the
    /// centre [0, 0, hc] up to 20, 20, 10 mm, tilted up to 20 deg about any axis.
    fn task_pose(d: [f64; 3], r: [f64; 3]) -> kinematics_core::Pose<f64> {
        let hc = RsprGeometry::<f64>::reference().hc;
        kinematics_core::Pose {
            t: Vector3::new(d[0], d[1], hc + d[2]),
            r: nalgebra::Rotation3::from_scaled_axis(Vector3::from(r)),
        }
    }

    fn ik_q(pose: &kinematics_core::Pose<f64>) -> [f64; 6] {
        let robot = RsprGeometry::<f64>::reference();
        inverse(&robot, pose, Branch::OUTER)
            .expect("inside the task")
            .q()
            .into()
    }

    fn jp(names: &[&str], values: &[f64]) -> JointState {
        JointState {
            name: names.iter().map(|n| n.to_string()).collect(),
            position: values.to_vec(),
            ..JointState::default()
        }
    }

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
            let q = Joints::from_column_slice(&js.position);
            let sp = setpoint_cp(&s).expect("finite");
            let seed = kinematics_core::Pose { t: sp.position_m, r: sp.orientation.to_rotation_matrix() };
            let fk = forward(&robot, &q, Branch::OUTER, &seed, &FkConfig::default()).expect("FK converges");
            prop_assert!((fk.pose.t - sp.position_m).norm() < 1e-9, "{}", (fk.pose.t - sp.position_m).norm());
        }

        /// servo_jp with the joints of a pose of the task box, named in any order, is the
        /// target of that pose: the forward kinematics from the central pose gives it back
        /// (1e-9 m and rad: the iteration stops at a joint residual of 1e-15 m / 1e-14 rad,
        /// which the inverse Jacobian, of gain far below 1e3 inside the task box, keeps
        /// below 1e-11; a joint off by 1e-6 would move the pose by about 1e-6).
        #[test]
        fn servo_jp_is_the_pose_of_its_joints(dx in -0.02..0.02f64, dy in -0.02..0.02f64,
                                              dz in -0.01..0.01f64,
                                              rx in -0.2..0.2f64, ry in -0.2..0.2f64, rz in -0.2..0.2f64,
                                              order in Just((0..6).collect::<Vec<usize>>()).prop_shuffle()) {
            let d = description();
            let pose = task_pose([dx, dy, dz], [rx, ry, rz]);
            let q = ik_q(&pose);
            let names: Vec<&str> = order.iter().map(|&k| JOINT_NAMES[k]).collect();
            let values: Vec<f64> = order.iter().map(|&k| q[k]).collect();
            let central = kinematics_core::Pose::central(d.robot().hc());
            let target = target_of_joints(d.robot(), d.branch(), &jp(&names, &values), &central)
                .expect("a pose of the task box");
            prop_assert!((target.position_m - pose.t).norm() < 1e-9,
                "{}", (target.position_m - pose.t).norm());
            let r = UnitQuaternion::from_rotation_matrix(&pose.r);
            prop_assert!(target.orientation.angle_to(&r) < 1e-9);
        }

        /// /joint_states at the measured joints of a pose: every moving joint of the
        /// description in its order, the actuated ones equal to the joints (1e-12 m or rad:
        /// the forward kinematics' residual is 1e-15 m / 1e-14 rad, the angles compared
        /// modulo 2π); /tf of them, composed from `base` along the parent links, puts
        /// `platform` at the pose (1e-9 m and rad, as the description's closure test: a
        /// dozen f64 transforms err by about 1e-14 m) and has one transform per joint.
        #[test]
        fn joint_states_and_tf_at_the_measured_joints(dx in -0.02..0.02f64, dy in -0.02..0.02f64,
                                                      dz in -0.01..0.01f64,
                                                      rx in -0.2..0.2f64, ry in -0.2..0.2f64) {
            let d = description();
            let pose = task_pose([dx, dy, dz], [rx, ry, 0.0]);
            let q = ik_q(&pose);
            let guess = kinematics_core::Pose::central(d.robot().hc());
            let (fk, states) = measured_joint_states(&d, q, &guess).expect("posed");
            prop_assert!((fk.t - pose.t).norm() < 1e-9);
            let msg = joint_states_msg(&states, Time::default());
            let moving: Vec<String> = d.tree().joints.iter()
                .filter(|j| j.drive != robot_description::Drive::Fixed)
                .map(|j| j.name.clone()).collect();
            prop_assert_eq!(&msg.name, &moving);
            let by_name: HashMap<&str, f64> =
                msg.name.iter().map(String::as_str).zip(msg.position.iter().copied()).collect();
            for (k, n) in JOINT_NAMES.iter().enumerate() {
                let v = by_name[n];
                let e = if k < 3 { (v - q[k]).abs() } else {
                    kinematics_core::scalar::wrap_angle(v - q[k]).abs()
                };
                prop_assert!(e < 1e-12, "{n}: {v} against {}", q[k]);
            }
            let tf = tf_msg(&d, &states, Time::default()).expect("every joint valued");
            prop_assert_eq!(tf.transforms.len(), d.tree().joints.len());
            let parent: HashMap<&str, (&str, Isometry3<f64>)> = tf.transforms.iter().map(|t| {
                let tr = t.transform.translation;
                let r = t.transform.rotation;
                let iso = Isometry3::from_parts(
                    nalgebra::Translation3::new(tr.x, tr.y, tr.z),
                    UnitQuaternion::from_quaternion(NaQuaternion::new(r.w, r.x, r.y, r.z)),
                );
                (t.child_frame_id.as_str(), (t.header.frame_id.as_str(), iso))
            }).collect();
            let mut frame = PLATFORM_FRAME;
            let mut platform = Isometry3::identity();
            while frame != BASE_FRAME {
                let (p, iso) = parent[frame];
                platform = iso * platform;
                frame = p;
            }
            prop_assert!((platform.translation.vector - pose.t).norm() < 1e-9,
                "{}", (platform.translation.vector - pose.t).norm());
            let r = UnitQuaternion::from_rotation_matrix(&pose.r);
            prop_assert!(platform.rotation.angle_to(&r) < 1e-9);
        }
    }

    /// servo_jp messages that cannot be a target are refused, each saying what is wrong:
    /// the count of names, names and positions of different counts, an unknown or a
    /// repeated name, a value that is not finite, joints with no forward kinematics: at
    /// θ = 0 the spherical-joint centres b_i are (e + rb)·√3 = 190.5 mm apart, the
    /// platform joints rp·√3 = 86.6 mm, and legs of 10 mm span at most 20 mm of the
    /// difference, so no pose has them.
    #[test]
    fn bad_servo_jp_is_refused_with_the_reason() {
        let d = description();
        let central = kinematics_core::Pose::central(d.robot().hc());
        let q = ik_q(&central);
        let target = |m: &JointState| target_of_joints(d.robot(), d.branch(), m, &central);
        let e = target(&jp(&JOINT_NAMES[..5], &q[..5])).expect_err("five joints");
        assert_eq!(e, JointTargetError::Count { count: 5 });
        assert!(e.to_string().contains("names 5 joints"), "{e}");
        let e = target(&jp(&JOINT_NAMES, &q[..5])).expect_err("five positions");
        assert_eq!(
            e,
            JointTargetError::Positions {
                names: 6,
                positions: 5
            }
        );
        let mut names = JOINT_NAMES;
        names[2] = "l4";
        let e = target(&jp(&names, &q)).expect_err("l4");
        assert!(e.to_string().contains("name[2] is \"l4\""), "{e}");
        names[2] = "l1";
        let e = target(&jp(&names, &q)).expect_err("l1 twice");
        assert!(
            e.to_string().contains("\"l1\" twice (name[0] and name[2])"),
            "{e}"
        );
        let mut bad = q;
        bad[4] = f64::NAN;
        let e = target(&jp(&JOINT_NAMES, &bad)).expect_err("NaN");
        assert!(
            e.to_string().contains("position[4] (theta2) is not finite"),
            "{e}"
        );
        let e =
            target(&jp(&JOINT_NAMES, &[0.01, 0.01, 0.01, 0.0, 0.0, 0.0])).expect_err("10 mm legs");
        assert!(
            matches!(e, JointTargetError::NoForwardKinematics { .. }),
            "{e}"
        );
        assert!(e.to_string().contains("no forward kinematics"), "{e}");
        // The central joints themselves are a target: the refusals above are the defects.
        assert!(target(&jp(&JOINT_NAMES, &q)).is_ok());
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
