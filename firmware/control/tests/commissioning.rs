#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::needless_range_loop
)]
//! Commissioning on the plant with the board around it (`sim/board-on-plant`, the second
//! position channel fitted, the switches and stops of the reference mechanics): every
//! miswiring of `board_on_plant::Wiring` injected on any joint is found and named with
//! the joint (and the fix it implies: the finding's bit), no joint of the plant moves
//! beyond the test's stated travel limit (3 mm, 3 deg) from where it stood, measured on the
//! plant's load side; the straight wiring reports nothing.

use board_on_plant::Wiring;
use control::modes::State;
use control::runtime::Runtime;
use hal::QuadratureCounter;
use kinematics_core::RsprGeometry;
use master_link::{
    BoardToMaster, CommissionFindings as F, CommissionRecord, MasterToBoard, NackReason, ResetCause,
};
use proptest::prelude::*;

use crate::common;
use common::PlantHw;

type Rt = Runtime<f64, RsprGeometry<f64>>;

/// The test's travel limit (`CommissionConfig::reference`): 3 mm, 3 deg.
const LIMIT: [f64; 6] = [0.003, 0.003, 0.003, 0.0524, 0.0524, 0.0524];

/// A plant at rest near the central configuration (the legs at 160 mm, the links 0.2 rad
/// above their hard stops' homing positions is not needed: near central), channel fitted,
/// miswired as `wiring` says, and the runtime booted on it.
fn booted(wiring: Wiring) -> (Rt, PlantHw, u64) {
    let c = common::central_q();
    let (mut hw, _, cfg) = common::homing_fixture([c[0], c[1] + 0.001, c[2] - 0.001], [0.0; 3]);
    hw.plant.set_joint_positions(c).unwrap();
    hw.position_channel = true;
    hw.wiring = wiring;
    let mut rt = Rt::new(RsprGeometry::reference(), cfg, 0).unwrap();
    let t = 0;
    rt.boot_done(hw.counts(), t, ResetCause::PowerOn, None)
        .unwrap();
    (rt, hw, t)
}

/// One tick with a heartbeat, then the plant over it.
fn step(rt: &mut Rt, hw: &mut PlantHw, t: &mut u64) {
    *t += 1000;
    rt.command(&MasterToBoard::Heartbeat, *t).unwrap();
    rt.tick(hw, *t);
    hw.step_ms();
}

/// The board's answer to `Commission` as the master sees it.
fn record(rt: &mut Rt, joint: u8, confirm: bool, t: u64) -> Result<CommissionRecord, NackReason> {
    let a = rt.command(&MasterToBoard::Commission { joint, confirm }, t)?;
    let req = control::link::Request {
        seq: 1,
        message: MasterToBoard::Commission { joint, confirm },
        session: 0,
    };
    match req.reply(Ok(a), &rt.status(), Default::default()) {
        BoardToMaster::Commissioning(r) => Ok(r),
        other => panic!("unexpected reply {other:?}"),
    }
}

/// What a run found: each joint's record, the largest motion of each joint on the plant
/// from where it stood, over the test's limit, and where each joint tested came to rest
/// after its test from where it stood before it, over its [`RETURN`].
struct Run {
    records: Vec<CommissionRecord>,
    travel: [f64; 6],
    returned: [f64; 6],
    /// The status a second after the Disable that ends commissioning.
    after: master_link::StatusReport,
}

/// How far from where it stood a joint may rest after its test: a tenth of the push's
/// 1.5 mm or 1.5 deg (the return ends where the channel reads the start less the push's
/// coast; what is left is the two coasts' difference and the channel's resolution, 1.5 um
/// or 0.005 deg). A homing from the encoders' counts since boot then starts within a tenth
/// of a push of the truth, where a test left in place put it a whole push away.
const RETURN: [f64; 6] = [0.15e-3, 0.15e-3, 0.15e-3, 0.0026, 0.0026, 0.0026];

/// Commissions `joints` one after the other, as `host-sim commission` does.
fn commission(wiring: Wiring, joints: &[u8]) -> Run {
    let (mut rt, mut hw, mut t) = booted(wiring);
    step(&mut rt, &mut hw, &mut t);
    let q0 = hw.plant.joint_positions();
    let mut travel = [0.0f64; 6];
    let mut returned = [0.0f64; 6];
    let mut records = Vec::new();
    for &j in joints {
        let before = hw.plant.joint_positions()[usize::from(j)];
        let confirm = rt.status().state == State::Fault;
        record(&mut rt, j, confirm, t).unwrap_or_else(|e| panic!("joint {j}: refused {e:?}"));
        let mut r = None;
        for _ in 0..3000 {
            step(&mut rt, &mut hw, &mut t);
            let q = hw.plant.joint_positions();
            for k in 0..6 {
                travel[k] = travel[k].max((q[k] - q0[k]).abs() / LIMIT[k]);
            }
            assert_ne!(
                rt.status().state,
                State::Fault,
                "joint {j}: {:?}",
                rt.status().fault
            );
            let rec = record(&mut rt, j, false, t).unwrap();
            if rec.done {
                r = Some(rec);
                break;
            }
        }
        records.push(r.unwrap_or_else(|| panic!("joint {j}: the test never ended")));
        let after = hw.plant.joint_positions()[usize::from(j)];
        returned[usize::from(j)] = (after - before).abs() / RETURN[usize::from(j)];
    }
    // Out of the mode as `host-sim commission` leaves it: Disable, then a second.
    rt.command(&MasterToBoard::Disable, t).unwrap();
    for _ in 0..1000 {
        step(&mut rt, &mut hw, &mut t);
    }
    Run {
        records,
        travel,
        returned,
        after: rt.status(),
    }
}

const NAMES: [&str; 6] = ["l1", "l2", "l3", "theta1", "theta2", "theta3"];

#[test]
fn the_straight_wiring_reports_nothing_and_stays_within_the_travel() {
    let run = commission(Wiring::straight(), &[0, 1, 2, 3, 4, 5]);
    for (j, r) in run.records.iter().enumerate() {
        assert!(r.findings.is_empty(), "{}: {r:?}", NAMES[j]);
        assert_eq!(usize::from(r.moved_encoder), j, "{}: {r:?}", NAMES[j]);
        assert!(r.reference, "{}: no reference", NAMES[j]);
        assert!((r.scale - 1.0).abs() < 0.05, "{}: scale {r:?}", NAMES[j]);
    }
    for k in 0..6 {
        assert!(
            run.travel[k] <= 1.0,
            "{} moved {:.2} of its limit",
            NAMES[k],
            run.travel[k]
        );
        assert!(
            run.returned[k] <= 1.0,
            "{} rested {:.2} of its return tolerance from where it stood",
            NAMES[k],
            run.returned[k]
        );
    }
    // Every joint back where it stood: the monitors that resume after the mode (the
    // channel against the encoders, the motor models) find nothing.
    assert_ne!(run.after.state, State::Fault, "{:?}", run.after.fault);
    println!("travel / limit {:.2?}", run.travel);
    println!("rest after / return tolerance {:.2?}", run.returned);
}

/// The miswirings of the issue, on joint `j` (a swap pairs it with `other`).
#[derive(Clone, Copy, Debug)]
enum Miswiring {
    MotorReversed,
    EncoderReversed,
    EncodersSwapped { other: usize },
    GearOff,
    SwitchNormallyOpen,
    BrakeInverted,
}

fn wiring_of(m: Miswiring, j: usize) -> Wiring {
    let mut w = Wiring::straight();
    match m {
        Miswiring::MotorReversed => w.motor_reversed[j] = true,
        Miswiring::EncoderReversed => w.encoder_reversed[j] = true,
        Miswiring::EncodersSwapped { other } => w.encoders_swapped = Some((j, other)),
        Miswiring::GearOff => w.count_scale[j] = 1.1,
        Miswiring::SwitchNormallyOpen => w.switch_normally_open[j] = true,
        Miswiring::BrakeInverted => w.brake_inverted[j] = true,
    }
    w
}

/// The finding that names the miswiring (on the joint tested).
fn expected(m: Miswiring) -> F {
    match m {
        Miswiring::MotorReversed => F::MOTOR_REVERSED,
        Miswiring::EncoderReversed => F::ENCODER_REVERSED,
        Miswiring::EncodersSwapped { .. } => F::ENCODER_SWAPPED,
        Miswiring::GearOff => F::SCALE,
        Miswiring::SwitchNormallyOpen => F::SWITCH_INVERTED,
        Miswiring::BrakeInverted => F::BRAKE_INVERTED,
    }
}

fn check(m: Miswiring, j: usize) -> Result<(), TestCaseError> {
    let run = commission(wiring_of(m, j), &[0, 1, 2, 3, 4, 5]);
    for k in 0..6 {
        prop_assert!(
            run.travel[k] <= 1.0,
            "{m:?} on {}: {} moved {:.2} of its limit",
            NAMES[j],
            NAMES[k],
            run.travel[k]
        );
        prop_assert!(
            run.returned[k] <= 1.0,
            "{m:?} on {}: {} rested {:.2} of its return tolerance from where it stood",
            NAMES[j],
            NAMES[k],
            run.returned[k]
        );
    }
    let r = &run.records[j];
    prop_assert_eq!(r.findings, expected(m), "{:?} on {}: {:?}", m, NAMES[j], r);
    if let Miswiring::EncodersSwapped { other } = m {
        prop_assert_eq!(usize::from(r.moved_encoder), other);
        let o = &run.records[other];
        prop_assert_eq!(
            o.findings,
            F::ENCODER_SWAPPED,
            "partner {}: {:?}",
            NAMES[other],
            o
        );
        prop_assert_eq!(usize::from(o.moved_encoder), j);
    }
    if let Miswiring::GearOff = m {
        prop_assert!((r.scale - 1.1).abs() < 0.02, "scale {}", r.scale);
    }
    for (k, o) in run.records.iter().enumerate() {
        let partner = matches!(m, Miswiring::EncodersSwapped { other } if other == k);
        if k != j && !partner {
            prop_assert!(
                o.findings.is_empty(),
                "{:?} on {}: {} found {:?}",
                m,
                NAMES[j],
                NAMES[k],
                o
            );
        }
    }
    Ok(())
}

/// Every (miswiring, joint) there is: each kind on each joint, and each pair of joints with
/// their encoders swapped.
fn every_miswiring() -> Vec<(Miswiring, usize)> {
    let mut all = Vec::new();
    for j in 0..6 {
        all.extend([
            (Miswiring::MotorReversed, j),
            (Miswiring::EncoderReversed, j),
            (Miswiring::GearOff, j),
            (Miswiring::SwitchNormallyOpen, j),
            (Miswiring::BrakeInverted, j),
        ]);
        all.extend(((j + 1)..6).map(|other| (Miswiring::EncodersSwapped { other }, j)));
    }
    all
}

/// Property: every miswiring kind on every joint (and every pair of joints swapped, 45
/// cases) is found on its joint (a swap on both), nothing on the others, every joint within
/// the travel and back where it stood.
#[test]
fn every_miswiring_on_every_joint_is_found_within_the_travel() {
    let cases = every_miswiring();
    assert_eq!(cases.len(), 5 * 6 + 15);
    let failed: Vec<String> = cases
        .iter()
        .filter_map(|&(m, j)| {
            check(m, j)
                .err()
                .map(|e| format!("{m:?} on {}: {e}", NAMES[j]))
        })
        .collect();
    assert!(failed.is_empty(), "{}", failed.join("\n"));
}

/// Property: a commissioned robot homes from where the tests left it. Each test pushes its
/// joint 1.5 mm or 1.5 deg and drives it back; on a board without the second channel the
/// return ends on the encoder (the joint rests within the backlash of where it stood:
/// within [`RETURN`]) and the homing starts from the rest positions moved by what the
/// encoders counted since boot, so a leg and a link commissioned first still reach their
/// references (a test that left its joint 1.5 mm or 1.5 deg away, with a homing estimated
/// from the rest alone, took the link's estimate out of its homing range: NotFound).
#[test]
fn a_commissioned_robot_homes_from_where_the_tests_left_it() {
    let c = common::central_q();
    let (mut hw, _, cfg) = common::homing_fixture([c[0], c[1] + 0.001, c[2] - 0.001], [0.2; 3]);
    let mut rt = Rt::new(RsprGeometry::reference(), cfg, 0).unwrap();
    let mut t = 0;
    rt.boot_done(hw.counts(), t, ResetCause::PowerOn, None)
        .unwrap();
    step(&mut rt, &mut hw, &mut t);
    let q0 = hw.plant.joint_positions();
    for j in [0u8, 3] {
        record(&mut rt, j, false, t).unwrap_or_else(|e| panic!("joint {j}: refused {e:?}"));
        let mut done = false;
        for _ in 0..3000 {
            step(&mut rt, &mut hw, &mut t);
            if record(&mut rt, j, false, t).unwrap().done {
                done = true;
                break;
            }
        }
        assert!(done, "joint {j}: the test never ended");
    }
    let q1 = hw.plant.joint_positions();
    for j in [0, 3] {
        let rested = (q1[j] - q0[j]).abs();
        println!("{} rests {rested:.6} from where it stood", NAMES[j]);
        assert!(
            rested <= RETURN[j],
            "{} not back where it stood: {q0:?} -> {q1:?}",
            NAMES[j]
        );
    }
    // Commissioning ends by Disable (a stop to torque off); Busy while that stop runs.
    rt.command(&MasterToBoard::Disable, t).unwrap();
    let mut asked = 0;
    while rt.command(&MasterToBoard::Home { rehome: false }, t) == Err(NackReason::Busy) {
        asked += 1;
        assert!(asked < 2000, "Home refused Busy for 2 s: {:?}", rt.status());
        step(&mut rt, &mut hw, &mut t);
    }
    assert!(
        rt.state() == State::Homing,
        "Home refused: {:?}",
        rt.status()
    );
    let mut ms = 0;
    while !rt.homed() && ms < 120_000 {
        step(&mut rt, &mut hw, &mut t);
        ms += 1;
        assert_ne!(rt.status().state, State::Fault, "{:?}", rt.status().fault);
    }
    assert!(rt.homed(), "not homed after 120 s: {:?}", rt.status());
    // A sweep of every joint to its switch or stop, not a reference taken at once.
    assert!(ms > 5_000, "homed after {ms} ms");
}

/// Property (a restart interlock): a stop a person asked for (the `EmergencyStop` message)
/// is ended only by `ClearFault`. `Commission { confirm }`, which starts a test that moves
/// a joint, is refused with `Faulted` after it, and no joint of the plant moves in the
/// second after the refusal; after `ClearFault` the same command is taken.
#[test]
fn an_emergency_stop_is_not_ended_by_a_commissioning_test() {
    let (mut rt, mut hw, mut t) = booted(Wiring::default());
    step(&mut rt, &mut hw, &mut t);
    record(&mut rt, 0, false, t).unwrap();
    for _ in 0..50 {
        step(&mut rt, &mut hw, &mut t);
    }
    rt.command(&MasterToBoard::EmergencyStop, t).unwrap();
    step(&mut rt, &mut hw, &mut t);
    assert_eq!(rt.state(), State::Fault);
    // The stop ends at torque off (the joint under test was pushed: at most its brake's
    // engage time).
    for _ in 0..1000 {
        step(&mut rt, &mut hw, &mut t);
    }
    let q0 = hw.plant.joint_positions();
    for j in 0..6u8 {
        assert_eq!(
            record(&mut rt, j, true, t).map(|_| ()),
            Err(NackReason::Faulted),
            "joint {j}: Commission {{ confirm }} after an emergency stop"
        );
    }
    for _ in 0..1000 {
        step(&mut rt, &mut hw, &mut t);
    }
    assert_eq!(rt.state(), State::Fault);
    let q1 = hw.plant.joint_positions();
    for k in 0..6 {
        assert!(
            (q1[k] - q0[k]).abs() < 1e-9,
            "joint {k} moved {} after the refusal",
            q1[k] - q0[k]
        );
    }
    rt.command(&MasterToBoard::ClearFault, t).unwrap();
    step(&mut rt, &mut hw, &mut t);
    record(&mut rt, 1, false, t).unwrap();
    step(&mut rt, &mut hw, &mut t);
    assert_eq!(rt.state(), State::Commissioning);
}
