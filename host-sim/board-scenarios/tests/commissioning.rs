//! Commissioning on the emulated board: the release image of the board with the second
//! position channel (`rspr-board-position-channel`, its potentiometers read by an AD7689 on
//! SPI3), miswired in the emulator's mechanics (`board_emulator::miswiring`), commissioned
//! by the master of `host-sim commission` (`teleop::commission::run`, the same call, nobody
//! at the robot) in the board's time. Each robot boots the image once and tests every
//! joint.
//!
//! Properties, measured on the emulator's mechanics (the plant's load side):
//! * wired as the pin map says, every joint is reported so;
//! * every miswiring of the issue (a motor reversed, an encoder reversed, two encoders
//!   swapped, a gear ratio 10 % off, a normally open home switch, an inverted brake), on
//!   every joint, is found on its joint with exactly the finding that names it and its fix
//!   in the joint's text (a swap on both joints, each on the other's counter; a gear
//!   ratio's measured scale nearer the injected one than the drawing's);
//! * no joint moves further from where it stood than the test's stated travel (3 mm on a
//!   leg, 3 deg on a link: `teleop::commission::LIMITS`);
//! * each joint rests, after its test, where it stood before it, within a tenth of the
//!   push (the return: `control::commissioning`) plus one step of the channel's converter
//!   the return ends on;
//! * a second after the Disable that ends commissioning, the straight robot has latched no
//!   fault (the two channels agree at rest).
//!
//! # The layout ([`ROBOTS`])
//!
//! Six kinds on six joints are 36 (kind, joint) cells; a robot carries one miswiring per
//! joint, so six robots are the fewest (the emulator swaps one pair of encoders per robot,
//! so the six joints need three robots with a swap, each of which has four joints left for
//! the other five kinds' 30 cells: 3 x 4 + 3 x 6 = 30). The layout is a Latin rectangle:
//! each joint's column holds every kind once; robots 1 to 3 each swap one leg with one
//! link (l1 / theta1, l2 / theta2, l3 / theta3: every joint in a swap, each counter reading
//! a joint of the other unit). Each robot's set is chosen so that no finding can mask
//! another ([`the_layout_covers_every_kind_on_every_joint_and_no_finding_can_mask_another`]
//! checks it):
//! * one miswiring per joint: two on one joint test their combination, not each kind, and
//!   may hide each other (a joint's scale is measured on its own counter only, so a
//!   swapped encoder's gear ratio is not measured; without the second channel a motor and
//!   its encoder both reversed look straight);
//! * a joint's test moves that joint alone, the others braked and unpowered, so the motor,
//!   encoder and gear miswirings act only in their own joint's test: these are the kinds
//!   a robot without a swap carries twice (six joints, five kinds);
//! * the two kinds that reach beyond their joint's test, at most once per robot: an
//!   inverted brake leaves its joint free while the others are tested (the platform can
//!   drag it, and the encoder that moved most names the joint a push moved), and a
//!   normally open switch latches a fault at boot for the whole robot (the run is
//!   confirmed);
//! * the swapped pair carries nothing else, so the motion each push shows on the other's
//!   counter is the swap's alone.
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
use board_emulator::mechanics::Wiring;
use board_emulator::miswiring;
use board_emulator::pins::POSITION_CHANNEL;
use board_profile::position_channel::PositionChannel;
use board_scenarios::master::{Rig, SharedRig};
use master_link::{CommissionFindings as F, CommissionRecord};
use teleop::commission::{joint_text, Person, NAMES};

/// The miswired robots: every kind of the issue on every joint, one miswiring per joint
/// (the module's documentation, "The layout"). Robot by robot, l1 l2 l3 theta1 theta2
/// theta3 (S swap, B brake, N switch, E encoder, G gear, M motor):
/// S B N S E G; N S B M S E; B N S E G S; M E G B N M; E G M G B N; G M E N M B.
const ROBOTS: [&[&str]; 6] = [
    &[
        "encoders-swapped=l1,theta1",
        "brake-inverted=l2",
        "switch-normally-open=l3",
        "encoder-reversed=theta2",
        "gear-scale=theta3:1.1",
    ],
    &[
        "switch-normally-open=l1",
        "encoders-swapped=l2,theta2",
        "brake-inverted=l3",
        "motor-reversed=theta1",
        "encoder-reversed=theta3",
    ],
    &[
        "brake-inverted=l1",
        "switch-normally-open=l2",
        "encoders-swapped=l3,theta3",
        "encoder-reversed=theta1",
        "gear-scale=theta2:0.9",
    ],
    &[
        "motor-reversed=l1",
        "encoder-reversed=l2",
        "gear-scale=l3:1.1",
        "brake-inverted=theta1",
        "switch-normally-open=theta2",
        "motor-reversed=theta3",
    ],
    &[
        "encoder-reversed=l1",
        "gear-scale=l2:0.9",
        "motor-reversed=l3",
        "gear-scale=theta1:1.1",
        "brake-inverted=theta2",
        "switch-normally-open=theta3",
    ],
    &[
        "gear-scale=l1:0.9",
        "motor-reversed=l2",
        "encoder-reversed=l3",
        "switch-normally-open=theta1",
        "motor-reversed=theta2",
        "brake-inverted=theta3",
    ],
];

/// The miswirings of the issue.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Kind {
    MotorReversed,
    EncoderReversed,
    EncodersSwapped,
    GearOff,
    SwitchNormallyOpen,
    BrakeInverted,
}

impl Kind {
    const ALL: [Kind; 6] = [
        Kind::MotorReversed,
        Kind::EncoderReversed,
        Kind::EncodersSwapped,
        Kind::GearOff,
        Kind::SwitchNormallyOpen,
        Kind::BrakeInverted,
    ];

    /// The finding that names it, on its joint.
    fn finding(self) -> F {
        match self {
            Kind::MotorReversed => F::MOTOR_REVERSED,
            Kind::EncoderReversed => F::ENCODER_REVERSED,
            Kind::EncodersSwapped => F::ENCODER_SWAPPED,
            Kind::GearOff => F::SCALE,
            Kind::SwitchNormallyOpen => F::SWITCH_INVERTED,
            Kind::BrakeInverted => F::BRAKE_INVERTED,
        }
    }
}

/// The miswirings `w` puts on joint `j`.
fn kinds(w: &Wiring, j: usize) -> Vec<Kind> {
    let swapped = w.encoders_swapped.is_some_and(|(a, b)| a == j || b == j);
    [
        (w.motor_reversed[j], Kind::MotorReversed),
        (w.encoder_reversed[j], Kind::EncoderReversed),
        (swapped, Kind::EncodersSwapped),
        (w.count_scale[j] != 1.0, Kind::GearOff),
        (w.switch_normally_open[j], Kind::SwitchNormallyOpen),
        (w.brake_inverted[j], Kind::BrakeInverted),
    ]
    .into_iter()
    .filter_map(|(on, k)| on.then_some(k))
    .collect()
}

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

/// A robot's outcome: each joint's record, each joint's largest motion from where it
/// stood at the start over [`LIMIT`], and where each rested after its test from where it
/// stood before it over [`return_tolerance`].
struct Outcome {
    wiring: Wiring,
    records: Vec<CommissionRecord>,
    /// The state and the latched fault a second after the Disable that ends commissioning
    /// (when asked for).
    after: Option<(master_link::RobotState, master_link::FaultRecord)>,
    travel: [f64; 6],
    rested: [f64; 6],
}

/// Boots the image on the robot miswired as `texts` say and commissions every joint;
/// with `settle`, waits a second of the board's time after the Disable that ends it.
fn commission(texts: &[&str], settle: bool) -> Outcome {
    let wall = Instant::now();
    let mut config = BenchConfig::reference(image()).unwrap();
    config.board = POSITION_CHANNEL;
    config.position_channel = true;
    config.mechanics.wiring = miswiring::parse(texts).unwrap();
    let wiring = config.mechanics.wiring;
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
    let after = if settle {
        s.wait(1.0).unwrap();
        let after = s.last_status().map(|st| (st.status.state, st.status.fault));
        println!("{texts:?}: 1 s after the Disable: {after:?}");
        after
    } else {
        None
    };
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
        wiring,
        records,
        after,
        travel,
        rested,
    }
}

/// What `o` did wrong: a joint beyond the travel or not back where it stood; a joint whose
/// findings are not exactly those of its miswiring (none for a joint wired straight), or
/// whose text does not name them and their fix; a swap not seen on the other's counter; a
/// gear ratio's scale nearer the drawing's than the injected one.
fn failures(o: &Outcome) -> Vec<String> {
    let mut out = Vec::new();
    let w = &o.wiring;
    for k in 0..6 {
        if o.travel[k] > 1.0 {
            out.push(format!(
                "{} moved {:.2} of the stated travel",
                NAMES[k], o.travel[k]
            ));
        }
        if o.rested[k] > 1.0 {
            out.push(format!(
                "{} rested {:.2} of its tolerance from where it stood",
                NAMES[k], o.rested[k]
            ));
        }
    }
    if o.records.len() != 6 {
        out.push(format!("{} records of 6 joints", o.records.len()));
    }
    for (j, r) in o.records.iter().enumerate() {
        let text = joint_text(r);
        let expected = kinds(w, j)
            .into_iter()
            .fold(F::NONE, |f, k| F(f.0 | k.finding().0));
        if r.findings != expected {
            out.push(format!(
                "{} found {:?}, expected {expected:?}\n{text}",
                NAMES[j], r.findings
            ));
        }
        let named = if expected.is_empty() {
            text.contains(&format!("{}: OK", NAMES[j]))
        } else {
            text.contains(&format!("{}: FOUND", NAMES[j]))
                && text.contains(&format!("{}:   fix:", NAMES[j]))
        };
        if !named {
            out.push(format!(
                "{}: the text does not name the finding and its fix\n{text}",
                NAMES[j]
            ));
        }
        if let Some((a, b)) = w.encoders_swapped {
            let other = if j == a {
                Some(b)
            } else if j == b {
                Some(a)
            } else {
                None
            };
            if let Some(other) = other {
                if usize::from(r.moved_encoder) != other {
                    out.push(format!(
                        "{}'s motion on {}'s counter, expected on {}'s",
                        NAMES[j],
                        NAMES.get(usize::from(r.moved_encoder)).unwrap_or(&"none"),
                        NAMES[other]
                    ));
                }
            }
        }
        let injected = w.count_scale[j];
        if injected != 1.0 {
            let scale = f64::from(r.scale);
            // Nearer the injected scale than the drawing's (1): the reported scale says
            // which way the ratio is off and by about how much.
            if scale.is_nan() || (scale - injected).abs() >= 0.5 * (injected - 1.0).abs() {
                out.push(format!(
                    "{}'s scale {scale:.4}, injected {injected}",
                    NAMES[j]
                ));
            }
        }
    }
    out
}

/// Property (the layout, no board): every kind of the issue is on every joint in some
/// robot and every joint is in some robot's swap; on each robot every joint carries at most
/// one miswiring, at most one brake is inverted and at most one switch is normally open
/// (the module's documentation, "The layout": no finding can mask another).
#[test]
fn the_layout_covers_every_kind_on_every_joint_and_no_finding_can_mask_another() {
    let mut covered = [[false; 6]; 6];
    for (i, texts) in ROBOTS.iter().enumerate() {
        let w = miswiring::parse(texts).unwrap();
        assert_eq!(
            miswiring::describe(&w).len(),
            texts.len(),
            "robot {}: a miswiring given twice: {texts:?}",
            i + 1
        );
        for j in 0..6 {
            let here = kinds(&w, j);
            assert!(
                here.len() <= 1,
                "robot {}: {} carries {here:?}: one miswiring per joint",
                i + 1,
                NAMES[j]
            );
            for k in here {
                covered[Kind::ALL.iter().position(|x| *x == k).unwrap()][j] = true;
            }
        }
        for (what, n) in [
            (
                "inverted brakes",
                w.brake_inverted.iter().filter(|b| **b).count(),
            ),
            (
                "normally open switches",
                w.switch_normally_open.iter().filter(|b| **b).count(),
            ),
        ] {
            assert!(n <= 1, "robot {}: {n} {what}: one at most", i + 1);
        }
    }
    for (k, joints) in Kind::ALL.iter().zip(covered) {
        for j in 0..6 {
            assert!(joints[j], "{k:?} is on {} in no robot", NAMES[j]);
        }
    }
}

/// Property: wired as the pin map says, commissioning reports nothing, within the travel,
/// every joint back where it stood, and a second after the Disable no fault is latched.
#[test]
fn a_straight_robot_reports_nothing() {
    let o = commission(&[], true);
    let wrong = failures(&o);
    assert!(wrong.is_empty(), "straight:\n{}", wrong.join("\n"));
    let (state, fault) = o.after.expect("a status after the Disable");
    assert_ne!(
        state,
        master_link::RobotState::Fault,
        "straight: a fault latched after commissioning: {fault:?}"
    );
}

/// Property: on the robots of [`ROBOTS`] (every kind of miswiring on every joint), each
/// miswiring is found on its joint alone, named with its fix, within the travel, every
/// joint back where it stood. The robots are commissioned side by side, as many at once
/// as the machine has cores; every robot's failures are reported.
#[test]
fn every_miswiring_on_every_joint_is_found_on_its_joint_within_the_travel() {
    use std::sync::atomic::{AtomicUsize, Ordering};
    use std::sync::Mutex;
    let next = AtomicUsize::new(0);
    let wrong: Mutex<Vec<String>> = Mutex::new(Vec::new());
    let workers = std::thread::available_parallelism()
        .map_or(1, |n| n.get())
        .min(ROBOTS.len());
    std::thread::scope(|scope| {
        for _ in 0..workers {
            scope.spawn(|| loop {
                let i = next.fetch_add(1, Ordering::Relaxed);
                let Some(texts) = ROBOTS.get(i) else { break };
                let found = std::panic::catch_unwind(|| failures(&commission(texts, false)))
                    .unwrap_or_else(|e| {
                        vec![e
                            .downcast_ref::<String>()
                            .cloned()
                            .or_else(|| e.downcast_ref::<&str>().map(|s| s.to_string()))
                            .unwrap_or_else(|| "panicked".into())]
                    });
                wrong.lock().unwrap().extend(
                    found
                        .into_iter()
                        .map(|f| format!("robot {} {texts:?}: {f}", i + 1)),
                );
            });
        }
    });
    let wrong = wrong.into_inner().unwrap();
    assert!(wrong.is_empty(), "{}", wrong.join("\n"));
}
