#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::needless_range_loop
)]
//! The second position channel on the whole board application against the plant
//! (`BoardSim` behind the in-process master, virtual time): after a reset with the robot
//! left in the workspace, `Home` on a board with the channel restores the position from it
//! and only verifies it, while a board without it sweeps to its switches as the prototype
//! does; the status says which board it is.

use kinematics_core::{inverse, Branch, Pose, RsprGeometry};
use master_link::{MasterToBoard, ResetCause, RobotState};
use nalgebra::{Rotation3, Vector3};
use simulation::bench::Bench;
use simulation::board::{BoardSim, BoardSimConfig};

/// Where a tool inside a patient may have left the robot: the platform 7 mm off the axis
/// (6 mm in x, -4 mm in y) at a height of 165 mm, tilted 5 deg.
fn in_the_workspace() -> [f64; 6] {
    let g = RsprGeometry::<f64>::reference();
    let pose = Pose {
        t: Vector3::new(0.006, -0.004, 0.165),
        r: Rotation3::from_scaled_axis(Vector3::new(0.0, 5f64.to_radians(), 0.0)),
    };
    let q = inverse(&g, &pose, Branch::OUTER).unwrap().q();
    std::array::from_fn(|j| q[j])
}

/// What a `Home` after a watchdog reset did: the platform's largest distance from where it
/// rested (m), each joint's largest travel (m, rad), the largest error of the measured
/// joints against the true ones once homed (m on a leg, rad on a link), and whether the
/// status said the channel is fitted.
struct Homed {
    platform_travel: f64,
    joint_travel: [f64; 6],
    error: [f64; 6],
    channel: bool,
}

fn home_after_a_reset(position_channel: bool) -> Homed {
    let mut cfg = BoardSimConfig::reference(Some(in_the_workspace())).unwrap();
    cfg.position_channel = position_channel;
    let mut b = Bench::new(
        BoardSim::new(cfg, ResetCause::Watchdog, None).unwrap(),
        0xc4a7,
    );
    let hello = b.hello_msg();
    assert_eq!(b.request(&hello, 100).unwrap(), None);
    b.command(&MasterToBoard::AcknowledgeReset).unwrap();
    b.run_ms(20).unwrap();
    let start = *b.board.truth();
    b.command(&MasterToBoard::Home { rehome: false }).unwrap();
    let (mut platform_travel, mut joint_travel) = (0.0f64, [0.0f64; 6]);
    for _ in 0..120_000 {
        if b.board.runtime().state() != RobotState::Homing {
            break;
        }
        b.tick().unwrap();
        let now = b.board.truth();
        platform_travel = platform_travel.max((now.pose.t - start.pose.t).norm());
        for ((t, q), q0) in joint_travel.iter_mut().zip(now.q).zip(start.q) {
            *t = t.max((q - q0).abs());
        }
    }
    let st = b.board.runtime().status();
    assert_eq!(st.state, RobotState::Ready, "{:?}", st.fault);
    b.run_ms(100).unwrap();
    let q = b.board.runtime().sensing().measured().q;
    let truth = b.board.truth().q;
    Homed {
        platform_travel,
        joint_travel,
        error: std::array::from_fn(|j| (q[j] - truth[j]).abs()),
        channel: b.board.runtime().status().position_channel,
    }
}

/// Property: with the channel fitted, `Home` after a reset (the robot left in the
/// workspace) restores the position from the channel and only verifies it: no joint moves
/// more than 1.1 mm or 1.1 deg (the verification's 1 mm, 1 deg out and back), the platform
/// no more than 2 mm, the board is Ready where it rested (no sweep, no park move), the
/// measured joints read the true ones within 0.1 mm and 0.05 deg, and the status says the
/// channel is fitted. Without the channel the same `Home` sweeps: the platform travels
/// more than 10 mm (to the switches and back to the park pose), and the status says so.
#[test]
fn home_after_a_reset_restores_with_the_channel_and_sweeps_without() {
    let with = home_after_a_reset(true);
    println!(
        "with the channel: platform travel {:.3} mm, joints {:?}, error {:?}",
        with.platform_travel * 1e3,
        with.joint_travel,
        with.error
    );
    assert!(with.channel, "the status says the channel is fitted");
    assert!(with.platform_travel < 2e-3, "{}", with.platform_travel);
    for j in 0..6 {
        let (travel, error) = if j < 3 {
            (1.1e-3, 0.1e-3)
        } else {
            (1.1f64.to_radians(), 0.05f64.to_radians())
        };
        assert!(
            with.joint_travel[j] < travel,
            "joint {j}: {:?}",
            with.joint_travel
        );
        assert!(with.error[j] < error, "joint {j}: {:?}", with.error);
    }

    let without = home_after_a_reset(false);
    println!(
        "without the channel: platform travel {:.3} mm, joints {:?}",
        without.platform_travel * 1e3,
        without.joint_travel
    );
    assert!(
        !without.channel,
        "the status says the channel is not fitted"
    );
    assert!(
        without.platform_travel > 10e-3,
        "{}",
        without.platform_travel
    );
}
