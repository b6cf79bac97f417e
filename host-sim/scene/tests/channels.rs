//! The scene's channels as an MCAP reader sees them: every topic of `scene::TOPICS` with
//! its documented schema (protobuf), the transforms of `/tf` composed from `base` to
//! `platform` on the measured pose (to 1e-12 m: about a dozen f64 rigid transforms of
//! sizes below 0.3 m err by about 1e-15 m), `/joint_states` naming every moving joint of
//! the description, and a measured pose out of reach logged without transforms.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use foxglove::messages::{FrameTransforms, JointStates, PoseInFrame};
use foxglove::Decode;
use kinematics_core::guards::{Guards, Limits};
use kinematics_core::pose::Pose;
use kinematics_core::{Branch, Robot, RsprGeometry};
use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion, Vector3};
use robot_description::{to_urdf, Description, Drive};
use scene::{GuardMargins, RobotState, Scene, Snapshot, TOPICS};
use std::collections::HashMap;

fn iso(
    t: &Option<foxglove::messages::Vector3>,
    q: &Option<foxglove::messages::Quaternion>,
) -> Isometry3<f64> {
    let t = (*t).unwrap();
    let q = (*q).unwrap();
    Isometry3::from_parts(
        Translation3::new(t.x, t.y, t.z),
        UnitQuaternion::from_quaternion(Quaternion::new(q.w, q.x, q.y, q.z)),
    )
}

#[test]
fn an_mcap_reader_finds_every_channel_and_the_transforms_of_the_measured_pose() {
    let robot = Robot::Rspr(RsprGeometry::reference());
    let d = Description::new(&robot, &Limits::reference(), Branch::OUTER).unwrap();
    let moving: Vec<String> = d
        .tree()
        .joints
        .iter()
        .filter(|j| j.drive != Drive::Fixed)
        .map(|j| j.name.clone())
        .collect();
    let guards = Guards::new(robot, Branch::OUTER, Limits::reference()).unwrap();
    let urdf = to_urdf(d.tree(), "test");
    let ctx = foxglove::Context::new();
    let writer = ctx
        .mcap_writer()
        .create(std::io::Cursor::new(Vec::new()))
        .unwrap();
    let mut scene = Scene::new(&ctx, d, urdf.clone());
    scene.log_description(0);
    let poses: Vec<Pose<f64>> = (0..3)
        .map(|k| {
            let k = f64::from(k);
            Pose::from_position_rotation_vector(
                Vector3::new(0.004 * k, -0.003 * k, 0.16 + 0.002 * k),
                Vector3::new(0.05 * k, 0.02, -0.03 * k),
            )
            .unwrap()
        })
        .collect();
    for (k, p) in poses.iter().enumerate() {
        scene.log(&Snapshot {
            time_ns: 1_000_000 * (k as u64 + 1),
            measured: Some(*p),
            setpoint: Some(*p),
            target: Some(*p),
            measured_joints: Some([0.17, 0.17, 0.17, 0.0, 0.0, 0.0]),
            margins: scene::margins_at(&guards, p),
            state: Some(RobotState {
                state: "Enabled".into(),
                stop: String::new(),
                fault: String::new(),
                fault_latched: false,
            }),
        });
    }
    // Out of reach: the pose is logged, its transforms are not.
    let far = Pose::from_position_rotation_vector(Vector3::new(0.5, 0.0, 0.16), Vector3::zeros())
        .unwrap();
    scene.log(&Snapshot {
        time_ns: 9_000_000,
        measured: Some(far),
        setpoint: None,
        target: None,
        measured_joints: None,
        margins: Some(GuardMargins {
            nearest: 0.0,
            serial: 0.0,
            parallel: 0.0,
            stroke: 0.0,
            tilt: 0.0,
            collision: 0.0,
            workspace: 0.0,
        }),
        state: None,
    });
    assert_eq!(scene.unposed, 1);
    let bytes = writer.close().unwrap().into_inner();

    let expected: HashMap<&str, &str> = TOPICS
        .iter()
        .copied()
        .zip([
            "robotdescription.RobotDescription",
            "foxglove.FrameTransforms",
            "foxglove.JointStates",
            "foxglove.PoseInFrame",
            "foxglove.PoseInFrame",
            "foxglove.PoseInFrame",
            "foxglove.JointStates",
            "foxglove.JointStates",
            "guardmargins.GuardMargins",
            "robotstate.RobotState",
        ])
        .collect();
    let mut by_topic: HashMap<String, Vec<(u64, Vec<u8>)>> = HashMap::new();
    for m in mcap::MessageStream::new(&bytes).unwrap() {
        let m = m.unwrap();
        let schema = m.channel.schema.as_ref().unwrap();
        assert_eq!(schema.encoding, "protobuf");
        assert_eq!(m.channel.message_encoding, "protobuf");
        assert_eq!(
            expected.get(m.channel.topic.as_str()).copied(),
            Some(schema.name.as_str()),
            "{}",
            m.channel.topic
        );
        by_topic
            .entry(m.channel.topic.clone())
            .or_default()
            .push((m.log_time, m.data.into_owned()));
    }
    for t in TOPICS {
        assert!(by_topic.contains_key(t), "no message on {t}");
    }
    assert_eq!(
        by_topic["/tf"].len(),
        3,
        "transforms only for poses in reach"
    );
    assert_eq!(by_topic["/measured_cp"].len(), 4);
    for ((time, tf), p) in by_topic["/tf"].iter().zip(&poses) {
        let tf = FrameTransforms::decode(tf.as_slice()).unwrap();
        let child: HashMap<&str, _> = tf
            .transforms
            .iter()
            .map(|x| (x.child_frame_id.as_str(), x))
            .collect();
        let (mut frame, mut pose) = ("platform", Isometry3::identity());
        while frame != "base" {
            let x = child[frame];
            pose = iso(&x.translation, &x.rotation) * pose;
            frame = x.parent_frame_id.as_str();
        }
        let dt = (pose.translation.vector - p.t).norm();
        let dr = (pose.rotation.to_rotation_matrix().matrix() - p.r.matrix()).norm();
        assert!(
            dt < 1e-12 && dr < 1e-12,
            "at {time}: /tf is {dt:e} m, {dr:e} off"
        );
        let measured = by_topic["/measured_cp"]
            .iter()
            .find(|(t, _)| t == time)
            .map(|(_, b)| PoseInFrame::decode(b.as_slice()).unwrap())
            .unwrap();
        assert_eq!(measured.frame_id, "base");
        let mp = measured.pose.unwrap();
        let m_iso = iso(&mp.position, &mp.orientation);
        assert!((m_iso.translation.vector - p.t).norm() < 1e-15);
    }
    let js = JointStates::decode(by_topic["/joint_states"][0].1.as_slice()).unwrap();
    let names: Vec<String> = js.joints.iter().map(|j| j.name.clone()).collect();
    assert_eq!(names, moving);
    let mjs = JointStates::decode(by_topic["/measured_js"][0].1.as_slice()).unwrap();
    let names: Vec<&str> = mjs.joints.iter().map(|j| j.name.as_str()).collect();
    assert_eq!(names, ["l1", "l2", "l3", "theta1", "theta2", "theta3"]);
}
