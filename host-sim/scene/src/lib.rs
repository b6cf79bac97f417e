//! `scene`: the robot's 3-D scene on the Foxglove SDK's channels, the same for the live
//! view of a board (`host-sim view`, a WebSocket server) and for the simulation's MCAP
//! file, so that Foxglove shows both with one layout.
//!
//! The channels (topic, schema; SI units, poses of the platform frame `platform` in the
//! base frame `base` of CONVENTIONS.md):
//!
//! | topic | schema | what |
//! | --- | --- | --- |
//! | `/robot_description` | `robotdescription.RobotDescription` (`data`: the URDF) | the robot description, for Foxglove's URDF layer (source: topic) |
//! | `/tf` | `foxglove.FrameTransforms` | every joint's transform, parent link to child link, at the measured pose |
//! | `/joint_states` | `foxglove.JointStates` | every joint of the description (passive ones computed) at the measured pose |
//! | `/measured_cp`, `/setpoint_cp`, `/servo_cp` | `foxglove.PoseInFrame` | the measured pose, the supervisor's setpoint, the master's target (when known) |
//! | `/measured_js`, `/setpoint_js` | `foxglove.JointStates` | the six actuated joints, measured and at the setpoint |
//! | `/guard_margins` | `guardmargins.GuardMargins` | each guard's margin, a fraction of its range (1 far, 0 at the stop level) |
//! | `/robot_state` | `robotstate.RobotState` | the board's state, the stop in force and the latched fault in words |
//!
//! Nothing here depends on the link protocol: [`Snapshot`] is what a front end or the
//! simulation knows at an instant.

use foxglove::messages::{
    FrameTransform, FrameTransforms, JointState, JointStates, Pose as FoxPose, PoseInFrame,
    Quaternion, Timestamp, Vector3 as FoxVector3,
};
use foxglove::{Channel, Context};
use kinematics_core::pose::Pose;
use nalgebra::{Isometry3, UnitQuaternion};
use robot_description::{Description, Drive, BASE_FRAME};
use std::sync::Arc;

/// The topics, in the order of the table above.
pub const TOPICS: [&str; 10] = [
    "/robot_description",
    "/tf",
    "/joint_states",
    "/measured_cp",
    "/setpoint_cp",
    "/servo_cp",
    "/measured_js",
    "/setpoint_js",
    "/guard_margins",
    "/robot_state",
];

/// The robot description as a message: the URDF text (the field name of ROS's
/// `std_msgs/String`, which Foxglove's URDF layer reads from a topic).
#[derive(Debug, Clone, foxglove::Encode)]
pub struct RobotDescription {
    pub data: String,
}

/// The guard margins, each a fraction of its range (1 far, 0 at the stop level; NaN while
/// the supervisor does not run).
#[derive(Debug, Clone, Copy, PartialEq, foxglove::Encode)]
pub struct GuardMargins {
    pub nearest: f64,
    pub serial: f64,
    pub parallel: f64,
    pub stroke: f64,
    pub tilt: f64,
    pub collision: f64,
    pub workspace: f64,
}

/// The board's state and its latched fault, in words.
#[derive(Debug, Clone, PartialEq, foxglove::Encode)]
pub struct RobotState {
    /// The state machine's state (`Ready`, `Enabled`, `Fault`, ...).
    pub state: String,
    /// The stop in force, empty without one.
    pub stop: String,
    /// The latched fault with its cause, joint and value; empty without one.
    pub fault: String,
    /// A fault is latched.
    pub fault_latched: bool,
}

/// What is known of the robot at an instant (SI; poses in {0}).
#[derive(Debug, Clone, PartialEq)]
pub struct Snapshot {
    /// Log time, ns (Unix time live; the run's virtual time in the simulation).
    pub time_ns: u64,
    pub measured: Option<Pose<f64>>,
    pub setpoint: Option<Pose<f64>>,
    /// The master's target, when this process knows it.
    pub target: Option<Pose<f64>>,
    /// The six actuated joints in q order (m, rad), measured.
    pub measured_joints: Option<[f64; 6]>,
    pub margins: Option<GuardMargins>,
    pub state: Option<RobotState>,
}

/// The scene's channels on one Foxglove context.
pub struct Scene {
    description: Description,
    urdf: String,
    robot_description: Channel<RobotDescription>,
    tf: Channel<FrameTransforms>,
    joint_states: Channel<JointStates>,
    measured_cp: Channel<PoseInFrame>,
    setpoint_cp: Channel<PoseInFrame>,
    servo_cp: Channel<PoseInFrame>,
    measured_js: Channel<JointStates>,
    setpoint_js: Channel<JointStates>,
    margins: Channel<GuardMargins>,
    state: Channel<RobotState>,
    /// Snapshots whose measured pose had no inverse kinematics on the description's
    /// branch (no transforms logged for them).
    pub unposed: u64,
}

fn timestamp(ns: u64) -> Timestamp {
    Timestamp::new(
        u32::try_from(ns / 1_000_000_000).unwrap_or(u32::MAX),
        (ns % 1_000_000_000) as u32,
    )
}

fn fox_pose(iso: &Isometry3<f64>) -> FoxPose {
    let t = iso.translation.vector;
    let q = iso.rotation;
    FoxPose {
        position: Some(FoxVector3 {
            x: t.x,
            y: t.y,
            z: t.z,
        }),
        orientation: Some(Quaternion {
            x: q.i,
            y: q.j,
            z: q.k,
            w: q.w,
        }),
    }
}

fn iso_of(p: &Pose<f64>) -> Isometry3<f64> {
    Isometry3::from_parts(p.t.into(), UnitQuaternion::from_rotation_matrix(&p.r))
}

impl Scene {
    /// The channels on `ctx` for the robot `description`, whose URDF text is `urdf`.
    pub fn new(ctx: &Arc<Context>, description: Description, urdf: String) -> Self {
        let b = |topic: &str| ctx.channel_builder(topic);
        Scene {
            description,
            urdf,
            robot_description: b(TOPICS[0]).build(),
            tf: b(TOPICS[1]).build(),
            joint_states: b(TOPICS[2]).build(),
            measured_cp: b(TOPICS[3]).build(),
            setpoint_cp: b(TOPICS[4]).build(),
            servo_cp: b(TOPICS[5]).build(),
            measured_js: b(TOPICS[6]).build(),
            setpoint_js: b(TOPICS[7]).build(),
            margins: b(TOPICS[8]).build(),
            state: b(TOPICS[9]).build(),
            unposed: 0,
        }
    }

    /// The description the scene shows.
    pub fn description(&self) -> &Description {
        &self.description
    }

    /// Logs the robot description (once into a file; live, again now and then for clients
    /// that subscribe later).
    pub fn log_description(&self, time_ns: u64) {
        self.robot_description.log_with_time(
            &RobotDescription {
                data: self.urdf.clone(),
            },
            time_ns,
        );
    }

    /// The six actuated joints as a JointStates message, named as in the description.
    fn actuated(&self, time_ns: u64, q: &[f64; 6]) -> JointStates {
        let names = actuated_names(&self.description);
        JointStates {
            timestamp: Some(timestamp(time_ns)),
            joints: names
                .into_iter()
                .zip(q.iter())
                .map(|(name, v)| JointState {
                    name,
                    position: Some(*v),
                    ..Default::default()
                })
                .collect(),
        }
    }

    /// Logs everything the snapshot knows.
    pub fn log(&mut self, s: &Snapshot) {
        let ts = Some(timestamp(s.time_ns));
        let in_base = |p: &Pose<f64>| PoseInFrame {
            timestamp: ts,
            frame_id: BASE_FRAME.into(),
            pose: Some(fox_pose(&iso_of(p))),
        };
        if let Some(p) = &s.measured {
            self.measured_cp.log_with_time(&in_base(p), s.time_ns);
            match self.description.joint_states(p) {
                Ok(states) => {
                    let values = states.as_map();
                    let transforms = self
                        .description
                        .tree()
                        .joints
                        .iter()
                        .map(|j| {
                            let v = values.get(&j.name).copied().unwrap_or(0.0);
                            FrameTransform {
                                timestamp: ts,
                                parent_frame_id: j.parent.clone(),
                                child_frame_id: j.child.clone(),
                                translation: fox_pose(&j.transform(v)).position,
                                rotation: fox_pose(&j.transform(v)).orientation,
                            }
                        })
                        .collect();
                    self.tf
                        .log_with_time(&FrameTransforms { transforms }, s.time_ns);
                    let msg = JointStates {
                        timestamp: ts,
                        joints: states
                            .names
                            .iter()
                            .zip(&states.positions)
                            .map(|(n, v)| JointState {
                                name: n.clone(),
                                position: Some(*v),
                                ..Default::default()
                            })
                            .collect(),
                    };
                    self.joint_states.log_with_time(&msg, s.time_ns);
                }
                Err(_) => self.unposed += 1,
            }
        }
        if let Some(p) = &s.setpoint {
            self.setpoint_cp.log_with_time(&in_base(p), s.time_ns);
            if let Ok(sol) =
                kinematics_core::inverse(self.description.robot(), p, self.description.branch())
            {
                let q: [f64; 6] = sol.q().into();
                self.setpoint_js
                    .log_with_time(&self.actuated(s.time_ns, &q), s.time_ns);
            }
        }
        if let Some(p) = &s.target {
            self.servo_cp.log_with_time(&in_base(p), s.time_ns);
        }
        if let Some(q) = &s.measured_joints {
            self.measured_js
                .log_with_time(&self.actuated(s.time_ns, q), s.time_ns);
        }
        if let Some(m) = &s.margins {
            self.margins.log_with_time(m, s.time_ns);
        }
        if let Some(st) = &s.state {
            self.state.log_with_time(st, s.time_ns);
        }
    }
}

/// The names of the six actuated joints in q order (CONVENTIONS.md).
pub fn actuated_names(d: &Description) -> Vec<String> {
    let usr = matches!(d.robot(), kinematics_core::Robot::Usr(_));
    let names: [&str; 6] = if usr {
        ["alpha1", "alpha2", "alpha3", "beta1", "beta2", "beta3"]
    } else {
        ["l1", "l2", "l3", "theta1", "theta2", "theta3"]
    };
    // Every one of them is an actuated joint of the description (checked by its tests).
    debug_assert!(names.iter().all(|n| d
        .tree()
        .joints
        .iter()
        .any(|j| j.name == *n && j.drive == Drive::Actuated)));
    names.map(String::from).to_vec()
}

/// The guard margins at a pose as the board reports them (firmware `runtime::status`): the
/// kinematic margins of the pose's solution, the stroke as the smaller of stroke and link
/// angle, the parallel measure rescaled so that its stop level is 0 and isotropy 1, and
/// the nearest of all; `None` when the pose has no inverse kinematics.
pub fn margins_at(
    guards: &kinematics_core::guards::Guards<f64, kinematics_core::Robot<f64>>,
    pose: &Pose<f64>,
) -> Option<GuardMargins> {
    use kinematics_core::Mechanism;
    let robot = guards.robot();
    let sol = kinematics_core::inverse(robot, pose, guards.branch()).ok()?;
    let k = guards.margins_at(&sol);
    let limits = guards.limits();
    let jt = kinematics_core::jacobian::tripod_jacobian(&sol);
    let inv_cond = kinematics_core::singularity::parallel_inv_cond(&jt, robot.rp()).ok()?;
    let parallel = (inv_cond - limits.parallel.stop) / (1.0 - limits.parallel.stop);
    let mut m = GuardMargins {
        nearest: f64::NAN,
        serial: k.serial,
        parallel,
        stroke: k.stroke.min(k.link_angle),
        tilt: k.tilt,
        collision: k.collision,
        workspace: k.workspace,
    };
    m.nearest = [
        m.serial,
        m.parallel,
        m.stroke,
        m.tilt,
        m.collision,
        m.workspace,
    ]
    .into_iter()
    .fold(f64::INFINITY, f64::min);
    Some(m)
}
