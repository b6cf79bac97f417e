//! The description's tree closes the robot's chains: for poses across the task box (both
//! orientations' ranges of tilt), on the reference RSPR, a per-chain (calibrated-like) RSPR
//! and the USR, the joint-state vector put through the tree's own forward kinematics
//! (what a URDF consumer computes) puts
//! - the platform frame at the pose (position to 1e-9 m, rotation to 1e-9 rad);
//! - every chain's pin at the platform's joint p_i = t + R pp_i (1e-9 m), its axis along
//!   R r_i (1e-9 rad): the passive joints of chains 2 and 3 close their loops;
//!
//! and the actuated joints equal the inverse kinematics' q (angles modulo 2π).
//!
//! The bound: each frame is a product of about a dozen rigid transforms of sizes below
//! 0.3 m, each exact to a few f64 rounding units (1e-16 relative), so the error is about
//! 1e-14 m; 1e-9 m leaves room without hiding a wrong joint (a joint off by 1e-6 rad moves
//! the platform by about 1e-7 m).
#![allow(clippy::unwrap_used, clippy::expect_used)]

use kinematics_core::guards::Limits;
use kinematics_core::pose::Pose;
use kinematics_core::{
    inverse, Branch, Chain, ChainDimensions, PerChain, PerChainGeometry, Robot, RsprGeometry,
    UsrGeometry,
};
use nalgebra::Vector3;
use proptest::prelude::*;
use robot_description::{Description, Drive, PLATFORM_FRAME};

fn per_chain() -> Robot<f64> {
    let g = RsprGeometry::<f64>::reference();
    // A built robot off its drawing by up to half a millimetre and half a degree.
    let chains = PerChain::from_fn(|c| {
        let k = c.index() as f64 + 1.0;
        let mut d = ChainDimensions::symmetric(&g, c);
        d.base_pivot += Vector3::new(0.0003 * k, -0.0002, 0.0004 / k);
        d.base_axis = Vector3::new(0.006 / k, -0.004, 1.0).normalize();
        d.link_length += 0.0004 * (k - 2.0);
        d.platform_joint += Vector3::new(-0.0002, 0.0003 * k, 0.0001);
        d.platform_axis = (d.platform_axis + Vector3::new(0.0, 0.0, 0.005 * (k - 2.0))).normalize();
        d.leg_offset = 0.0005 * (k - 1.5);
        d.leg_zero = -0.0002 * k;
        d.link_zero = 0.004 * (2.0 - k);
        d
    });
    Robot::RsprPerChain(PerChainGeometry::new(g, chains).unwrap())
}

fn robots() -> Vec<(Robot<f64>, f64)> {
    // The robot and the scale of its task box (the USR's is half the RSPR's).
    vec![
        (Robot::Rspr(RsprGeometry::reference()), 1.0),
        (per_chain(), 1.0),
        (Robot::Usr(UsrGeometry::reference()), 0.5),
    ]
}

fn check(robot: &Robot<f64>, pose: &Pose<f64>) -> Result<(), TestCaseError> {
    let d = Description::new(robot, &Limits::reference(), Branch::OUTER).unwrap();
    let states = d.joint_states(pose).unwrap();
    let frames = d.link_poses(&states).unwrap();
    let platform = frames[PLATFORM_FRAME];
    let dt = (platform.translation.vector - pose.t).norm();
    prop_assert!(dt < 1e-9, "platform position off by {dt:e} m");
    // The Frobenius norm of the difference of the rotation matrices (about the angle for
    // small angles; acos of the trace would round 1e-16 up to 1e-8 rad).
    let dr = (platform.rotation.to_rotation_matrix().matrix() - pose.r.matrix()).norm();
    prop_assert!(dr < 1e-9, "platform orientation off by {dr:e}");
    let sol = inverse(robot, pose, Branch::OUTER).unwrap();
    for chain in Chain::ALL {
        let i = chain.number();
        let pin = frames[&format!("pin{i}_link")];
        let p = pose.t + pose.r * d.platform_joint(chain);
        let dp = (pin.translation.vector - p).norm();
        prop_assert!(dp < 1e-9, "chain {i}: the pin is {dp:e} m from p_i");
        let cs = &sol.chains[chain];
        let dp_ik = (cs.p - p).norm();
        prop_assert!(dp_ik < 1e-9, "chain {i}: IK p_i differs by {dp_ik:e} m");
    }
    // Pin axes: every chain's pin x axis along R r_i (from the tree's pose of the platform
    // and the pins: the platform frame hangs off pin 1, so pins 2 and 3 are the check).
    for chain in [Chain::Two, Chain::Three] {
        let i = chain.number();
        let pin = frames[&format!("pin{i}_link")];
        let x = pin.rotation * Vector3::x();
        let r_i = match robot {
            Robot::RsprPerChain(g) => g.chains()[chain].platform_axis,
            _ => {
                let rad = kinematics_core::mechanism::radial::<f64>(chain);
                Vector3::new(-rad.y, rad.x, 0.0)
            }
        };
        let want = pose.r * r_i;
        // |x × want| is the sine of the angle: exact near zero, where acos is not.
        let angle = x.cross(&want).norm();
        prop_assert!(
            angle < 1e-9 && x.dot(&want) > 0.0,
            "chain {i}: pin axis off by {angle:e} rad"
        );
    }
    // Actuated joints equal the controller's q.
    let q = sol.q();
    let map = states.as_map();
    let usr = matches!(robot, Robot::Usr(_));
    let names: [&str; 6] = if usr {
        ["alpha1", "alpha2", "alpha3", "beta1", "beta2", "beta3"]
    } else {
        ["l1", "l2", "l3", "theta1", "theta2", "theta3"]
    };
    for (k, n) in names.iter().enumerate() {
        let v = map[*n];
        let diff = if k < 3 && !usr {
            v - q[k]
        } else {
            kinematics_core::scalar::wrap_angle(v - q[k])
        };
        prop_assert!(diff.abs() < 1e-12, "{n}: {v} against q {}", q[k]);
    }
    // Every moving joint has a value; the actuated ones are exactly six.
    let moving = d
        .tree()
        .joints
        .iter()
        .filter(|j| j.drive != Drive::Fixed)
        .count();
    prop_assert_eq!(states.names.len(), moving);
    let actuated = d
        .tree()
        .joints
        .iter()
        .filter(|j| j.drive == Drive::Actuated)
        .count();
    prop_assert_eq!(actuated, 6);
    Ok(())
}

proptest! {
    #![proptest_config(proptest_config::cases(200))]
    #[test]
    fn the_tree_closes_every_chain_across_the_task_box(
        which in 0usize..3,
        x in -0.02f64..0.02, y in -0.02f64..0.02, z in -0.01f64..0.01,
        rx in -0.25f64..0.25, ry in -0.25f64..0.25, rz in -0.2f64..0.2,
    ) {
        let (robot, s) = robots().swap_remove(which);
        use kinematics_core::mechanism::Mechanism;
        let pose = Pose::from_position_rotation_vector(
            Vector3::new(x * s, y * s, robot.hc() + z * s),
            Vector3::new(rx, ry, rz),
        ).unwrap();
        // Poses out of reach of a robot are not this test's subject.
        prop_assume!(inverse(&robot, &pose, Branch::OUTER).is_ok());
        check(&robot, &pose)?;
    }
}

#[test]
fn the_passive_joints_are_zero_at_the_central_configuration() {
    for (robot, _) in robots() {
        use kinematics_core::mechanism::Mechanism;
        let d = Description::new(&robot, &Limits::reference(), Branch::OUTER).unwrap();
        let states = d.joint_states(&Pose::central(robot.hc())).unwrap();
        for (n, v) in states.names.iter().zip(&states.positions) {
            let j = d.tree().joints.iter().find(|j| &j.name == n).unwrap();
            if j.drive == Drive::Passive {
                assert!(v.abs() < 1e-12, "{n} = {v} at the central configuration");
            }
        }
    }
}

#[test]
fn the_joint_states_from_joints_go_through_the_forward_kinematics() {
    let robot = per_chain();
    let d = Description::new(&robot, &Limits::reference(), Branch::OUTER).unwrap();
    let pose = Pose::from_position_rotation_vector(
        Vector3::new(0.012, -0.007, 0.165),
        Vector3::new(0.1, -0.2, 0.05),
    )
    .unwrap();
    let q = inverse(&robot, &pose, Branch::OUTER).unwrap().q();
    let (fk_pose, states) = d
        .joint_states_from_joints(&q, &Pose::central(0.16))
        .unwrap();
    assert!((fk_pose.t - pose.t).norm() < 1e-12);
    assert_eq!(states, d.joint_states(&fk_pose).unwrap());
}

#[test]
fn a_pose_out_of_reach_is_refused_with_the_chain() {
    let d = Description::new(
        &Robot::Rspr(RsprGeometry::reference()),
        &Limits::reference(),
        Branch::OUTER,
    )
    .unwrap();
    let far = Pose::central(0.16);
    let far = Pose {
        t: Vector3::new(0.5, 0.0, 0.16),
        ..far
    };
    let e = d.joint_states(&far).unwrap_err().to_string();
    assert!(
        e.contains("no inverse kinematics") && e.contains("chain"),
        "{e}"
    );
}
