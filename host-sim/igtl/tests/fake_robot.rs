//! The simulated robot keeps its speed limits and its box.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use common::proptest_config;
use igtl::fake_robot::{FakeRobot, FakeRobotConfig};
use igtl::{RefusalReason, Robot, TargetPose, Timestamp};
use kinematics_core::pose::rotation_angle;
use nalgebra::{Rotation3, Vector3};
use proptest::prelude::*;
use std::time::Duration;

fn target(t_mm: [f64; 3], w: [f64; 3]) -> TargetPose {
    TargetPose {
        t: Vector3::from(t_mm) / 1000.0,
        r: Some(Rotation3::from_scaled_axis(Vector3::from(w))),
        timestamp: Timestamp::UNUSED,
        peer: "127.0.0.1:1".parse().unwrap(),
    }
}

proptest! {
    #![proptest_config(proptest_config(256))]

    /// Each step moves o_p by at most speed * dt and turns by at most angular_speed * dt,
    /// and after enough steps the robot is exactly at the target.
    #[test]
    fn steps_respect_the_speed_limits_and_arrive(
        t in prop::array::uniform3(-20.0f64..20.0),
        w in prop::array::uniform3(-0.2f64..0.2),
        dt_ms in 1u64..50,
    ) {
        let config = FakeRobotConfig::default();
        let mut robot = FakeRobot::new(config);
        let goal = target([t[0], t[1], 160.0 + t[2] / 2.0], w);
        robot.submit_target(&goal).unwrap();
        let dt = Duration::from_millis(dt_ms);
        for _ in 0..10_000 {
            let before = robot.measured_pose().unwrap();
            robot.step(dt);
            let after = robot.measured_pose().unwrap();
            let s = dt.as_secs_f64();
            prop_assert!((after.t - before.t).norm() <= config.speed * s * (1.0 + 1e-9));
            prop_assert!(rotation_angle(&(before.r.inverse() * after.r)) <= config.angular_speed * s * (1.0 + 1e-6) + 1e-12);
            if after.t == goal.t && Some(after.r) == goal.r {
                return Ok(());
            }
        }
        prop_assert!(false, "not at the target after 10000 steps");
    }

    /// Targets outside the box (task box + 5 mm margin) are refused as unreachable.
    #[test]
    fn targets_outside_the_box_are_refused(
        axis in 0usize..3, sign in prop_oneof![Just(-1.0), Just(1.0)], beyond in 0.001f64..100.0,
    ) {
        let half = [25.0, 25.0, 15.0];
        let mut t = [0.0, 0.0, 160.0];
        t[axis] += sign * (half[axis] + beyond);
        let mut robot = FakeRobot::new(FakeRobotConfig::default());
        let refusal = robot.submit_target(&target(t, [0.0; 3])).unwrap_err();
        prop_assert_eq!(refusal.reason, RefusalReason::Unreachable);
        prop_assert!(robot.target().is_none());
    }
}

#[test]
fn a_target_tilted_beyond_the_cone_is_refused() {
    let mut robot = FakeRobot::new(FakeRobotConfig::default());
    let tilted = target([0.0, 0.0, 160.0], [26f64.to_radians(), 0.0, 0.0]);
    let refusal = robot.submit_target(&tilted).unwrap_err();
    assert!(
        refusal.detail.contains("tilt_deg=26.00"),
        "{}",
        refusal.detail
    );
    let ok = target([0.0, 0.0, 160.0], [24f64.to_radians(), 0.0, 0.0]);
    assert!(robot.submit_target(&ok).is_ok());
}
