//! Commissioning on the emulated board: the release image of the board with the second
//! position channel (`rspr-board-position-channel`, its potentiometers read by an AD7689 on
//! SPI3), miswired
//! in the emulator's mechanics (`board_emulator::miswiring`), commissioned by the master
//! of `host-sim commission` (`teleop::commission::run`, the same call, nobody at the
//! robot) in the board's time. Each case boots the image once and tests every joint; the
//! miswirings of a case sit on different joints (a joint's test moves that joint alone,
//! the others braked, so each joint's findings are its own wiring's).
//!
//! Properties, measured on the emulator's mechanics (the plant's load side):
//! * wired as the pin map says, every joint is reported so;
//! * each miswiring is found on its joint, with exactly the finding that names it (and
//!   its fix in the joint's text), and no other joint reports anything;
//! * no joint moves further from where it stood than the test's stated travel (3 mm on a
//!   leg, 3 deg on a link: `teleop::commission::LIMITS`);
//! * each joint rests, after its test, where it stood before it, within a tenth of the
//!   push (the return: `control::commissioning`) plus one step of the channel's converter
//!   the return ends on;
//! * a second after the Disable that ends commissioning, the straight robot has latched no
//!   fault (the two channels agree at rest).
//!
//! The image is `$RSPR_BOARD_PC_ELF`, else `rspr-board-position-channel` in the Cortex-M
//! workspace's default target directory (`firmware/cortex-m/board/build-and-size.sh`
//! builds it; `run.sh` sets the variable).
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::needless_range_loop
)]

use std::path::{Path, PathBuf};
use std::time::Instant;

use board_emulator::bench::{Bench, BenchConfig};
use board_emulator::miswiring;
use board_emulator::pins::POSITION_CHANNEL;
use board_profile::position_channel::PositionChannel;
use board_scenarios::master::{Rig, SharedRig};
use master_link::{CommissionFindings as F, CommissionRecord};
use teleop::commission::{joint_text, Person, NAMES};

fn image() -> PathBuf {
    std::env::var_os("RSPR_BOARD_PC_ELF").map_or_else(
        || {
            Path::new(env!("CARGO_MANIFEST_DIR")).join(
                "../../firmware/cortex-m/target/thumbv7em-none-eabihf/release/rspr-board-position-channel",
            )
        },
        PathBuf::from,
    )
}

/// The test's stated travel (`CommissionConfig::reference`): 3 mm, 3 deg.
const LIMIT: [f64; 6] = [0.003, 0.003, 0.003, 0.05236, 0.05236, 0.05236];

/// Where a joint may rest after its test from where it stood: a tenth of the push (1.5 mm,
/// 1.5 deg) plus one step of the channel's converter (the AD7689: 1.5 µm on a leg,
/// 0.0052 deg on a link), the sensor the return ends on.
fn return_tolerance(joint: usize) -> f64 {
    let tenth = if joint < 3 { 0.15e-3 } else { 0.002618 };
    tenth + PositionChannel::REFERENCE.step_unit(joint)
}

/// Nobody at the robot; notes where the joints stand as each test is about to start.
struct Watcher {
    rig: SharedRig,
    before: Vec<[f64; 6]>,
}

impl Person for Watcher {
    fn ready(&mut self, _joint: u8) {
        self.before.push(self.rig.lock().bench.last.q);
    }
    fn moved_towards_plus(&mut self, _joint: u8) -> Option<bool> {
        None
    }
    fn say(&mut self, text: &str) {
        println!("{text}");
    }
}

/// A case's outcome: each joint's record, each joint's largest motion from where it stood
/// at the start over [`LIMIT`], and where each rested after its test from where it stood
/// before it over [`return_tolerance`].
struct Outcome {
    records: Vec<CommissionRecord>,
    /// The state and the latched fault a second after the Disable that ends commissioning.
    after: Option<(master_link::RobotState, master_link::FaultRecord)>,
    travel: [f64; 6],
    rested: [f64; 6],
}

/// Boots the image on the robot miswired as `texts` say and commissions every joint.
fn commission(texts: &[&str]) -> Outcome {
    let wall = Instant::now();
    let mut config = BenchConfig::reference(image()).unwrap();
    config.board = POSITION_CHANNEL;
    config.position_channel = true;
    config.mechanics.wiring = miswiring::parse(texts).unwrap();
    let rig = SharedRig::new(Rig::new(Bench::start(config).unwrap()));
    rig.lock().truth = Some(Vec::new());
    let mut s = rig.session();
    s.hello(10.0).unwrap();
    s.wait(0.1).unwrap();
    // A miswiring may latch a fault at boot (a normally open switch reads actuated where
    // no joint can be): the person at the robot confirms (`host-sim commission --confirm`).
    let confirm = s
        .last_status()
        .is_some_and(|st| st.status.state == master_link::RobotState::Fault);
    let q0 = rig.lock().bench.last.q;
    let mut watcher = Watcher {
        rig: rig.clone(),
        before: Vec::new(),
    };
    let joints: Vec<u8> = (0..6).collect();
    let records = teleop::commission::run(&mut s, &joints, confirm, &mut watcher)
        .unwrap_or_else(|e| panic!("{texts:?}: {e}"));
    s.wait(1.0).unwrap();
    let after = s.last_status().map(|st| (st.status.state, st.status.fault));
    println!("{texts:?}: 1 s after the Disable: {after:?}");
    let mut r = rig.lock();
    let end = r.bench.last.q;
    let mut travel = [0.0f64; 6];
    for (_, q) in r.truth.take().unwrap_or_default() {
        for k in 0..6 {
            travel[k] = travel[k].max((q[k] - q0[k]).abs() / LIMIT[k]);
        }
    }
    let mut rested = [0.0f64; 6];
    for j in 0..6 {
        let after = watcher.before.get(j + 1).copied().unwrap_or(end);
        rested[j] = (after[j] - watcher.before[j][j]).abs() / return_tolerance(j);
    }
    println!(
        "{texts:?}: confirmed {confirm}; scales {:.4?}",
        records.iter().map(|r| r.scale).collect::<Vec<_>>()
    );
    println!(
        "{texts:?}: {:.2} s of board time in {:.1} s of wall time; travel / limit {travel:.2?}; rested / tolerance {rested:.2?}",
        r.bench.now_s(),
        wall.elapsed().as_secs_f64()
    );
    Outcome {
        records,
        after,
        travel,
        rested,
    }
}

/// Every joint within the travel and back where it stood.
fn within(o: &Outcome, case: &str) {
    for k in 0..6 {
        assert!(
            o.travel[k] <= 1.0,
            "{case}: {} moved {:.2} of the stated travel",
            NAMES[k],
            o.travel[k]
        );
        assert!(
            o.rested[k] <= 1.0,
            "{case}: {} rested {:.2} of its tolerance from where it stood",
            NAMES[k],
            o.rested[k]
        );
    }
}

/// Each joint's findings are `expected[j]`; a joint with a finding names it, and its fix,
/// in its text.
fn found(o: &Outcome, case: &str, expected: [F; 6]) {
    for (j, r) in o.records.iter().enumerate() {
        let text = joint_text(r);
        assert_eq!(
            r.findings, expected[j],
            "{case}: {} found {:?}, expected {:?}\n{text}",
            NAMES[j], r.findings, expected[j]
        );
        if expected[j].is_empty() {
            assert!(text.contains(&format!("{}: OK", NAMES[j])), "{text}");
        } else {
            assert!(text.contains(&format!("{}: FOUND", NAMES[j])), "{text}");
            assert!(text.contains(&format!("{}:   fix:", NAMES[j])), "{text}");
        }
    }
}

/// Property: wired as the pin map says, commissioning reports nothing, within the travel,
/// every joint back where it stood.
#[test]
fn a_straight_robot_reports_nothing() {
    let o = commission(&[]);
    within(&o, "straight");
    found(&o, "straight", [F::NONE; 6]);
    let (state, fault) = o.after.expect("a status after the Disable");
    assert_ne!(
        state,
        master_link::RobotState::Fault,
        "straight: a fault latched after commissioning: {fault:?}"
    );
}

/// Property: a motor reversed (l1), two encoders swapped (l2 with theta2), a gear ratio
/// 10 % off (l3), an encoder reversed (theta1) and an inverted brake (theta3), all on one
/// robot, are each found on their joint, within the travel, every joint back where it
/// stood.
#[test]
fn five_miswirings_on_one_robot_are_each_found() {
    let case = [
        "motor-reversed=l1",
        "encoders-swapped=l2,theta2",
        "gear-scale=l3:1.1",
        "encoder-reversed=theta1",
        "brake-inverted=theta3",
    ];
    let o = commission(&case);
    within(&o, "five");
    found(
        &o,
        "five",
        [
            F::MOTOR_REVERSED,
            F::ENCODER_SWAPPED,
            F::SCALE,
            F::ENCODER_REVERSED,
            F::ENCODER_SWAPPED,
            F::BRAKE_INVERTED,
        ],
    );
    assert_eq!(
        o.records[1].moved_encoder, 4,
        "l2's motion on theta2's counter"
    );
    assert_eq!(
        o.records[4].moved_encoder, 1,
        "theta2's motion on l2's counter"
    );
    assert!(
        (o.records[2].scale - 1.1).abs() < 0.05,
        "l3's scale {}",
        o.records[2].scale
    );
}

/// Property: a normally open home switch (l1, which latches a fault at boot: confirmed),
/// and the kinds above on the other kind of joint (an inverted brake on l2, an encoder
/// reversed on l3, a motor reversed on theta1, a gear ratio 10 % off the other way on
/// theta2) are each found on their joint,
/// theta3 wired straight reports nothing, within the travel, every joint back where it
/// stood.
#[test]
fn the_miswirings_on_the_other_joints_are_each_found() {
    let case = [
        "switch-normally-open=l1",
        "brake-inverted=l2",
        "encoder-reversed=l3",
        "motor-reversed=theta1",
        "gear-scale=theta2:0.9",
    ];
    let o = commission(&case);
    within(&o, "other");
    found(
        &o,
        "other",
        [
            F::SWITCH_INVERTED,
            F::BRAKE_INVERTED,
            F::ENCODER_REVERSED,
            F::MOTOR_REVERSED,
            F::SCALE,
            F::NONE,
        ],
    );
    assert!(
        (o.records[4].scale - 0.9).abs() < 0.05,
        "theta2's scale {}",
        o.records[4].scale
    );
}
