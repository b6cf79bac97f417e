#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::needless_range_loop
)]
//! The second position channel (an absolute position sensor per joint on the load side)
//! against the encoders, on the plant with the board around it (`sim/board-on-plant`, the
//! channel fitted) and the thesis tool on the platform: encoder faults named as the
//! encoder, in a held stop within 20 ms and 0.1 mm (0.1 deg on a link) of the push that
//! shows them, and while moving; a failed channel named as the sensor and stopped as the
//! stop table says; healthy joints pushed, or moving, raise nothing; `Home` restores the
//! references from the channel with a move of a millimetre or a degree per joint.

use control::modes::State;
use control::runtime::{reference_config_for, Runtime};
use control::stops::{reaction, StopCategory, StopEvent};
use hal::QuadratureCounter;
use kinematics_core::{Branch, RsprGeometry};
use master_link::{FaultCause, MasterToBoard, ResetCause, StopStatus};
use plant::Fault;

use crate::common;
use common::PlantHw;

type Rt = Runtime<f64, RsprGeometry<f64>>;

/// One tick of the runtime (a heartbeat first), then the plant over it with the tool's
/// weight (when `tool`) and `push` (N, N m, in +q) on the joints.
fn step(rt: &mut Rt, hw: &mut PlantHw, t: &mut u64, tool: bool, push: [f64; 6]) {
    *t += 1000;
    rt.command(&MasterToBoard::Heartbeat, *t).unwrap();
    rt.tick(hw, *t);
    let mut loads = if tool {
        common::tool_loads(&hw.plant.joint_positions())
    } else {
        [0.0; 6]
    };
    for j in 0..6 {
        loads[j] += push[j];
    }
    hw.plant.set_external_load(loads).unwrap();
    hw.step_ms();
}

/// The plant resting at `q` with the switches and stops of the reference mechanics, the
/// channel fitted, and the runtime booted on it.
fn booted(q: [f64; 6]) -> (Rt, PlantHw, u64) {
    let (mut hw, _, _) = common::homing_fixture([0.16, 0.161, 0.159], [0.2; 3]);
    hw.plant.set_joint_positions(q).unwrap();
    hw.position_channel = true;
    let cfg =
        reference_config_for(&RsprGeometry::reference(), Branch::OUTER, None, Some(q)).unwrap();
    let mut rt = Rt::new(RsprGeometry::reference(), cfg, 0).unwrap();
    let mut t = 0;
    rt.boot_done(hw.counts(), t, ResetCause::PowerOn, None)
        .unwrap();
    step(&mut rt, &mut hw, &mut t, false, [0.0; 6]);
    (rt, hw, t)
}

/// Homed by the channel at the central configuration, enabled, the tool attached (after
/// homing, as an instrument is mounted), following for 300 ms.
fn following_with_tool() -> (Rt, PlantHw, u64) {
    let (mut rt, mut hw, mut t) = booted(common::central_q());
    rt.command(&MasterToBoard::Home { rehome: false }, t)
        .unwrap();
    while rt.state() == State::Homing {
        step(&mut rt, &mut hw, &mut t, false, [0.0; 6]);
        assert!(t < 30_000_000);
    }
    assert_eq!(rt.state(), State::Ready, "{:?}", rt.status().fault);
    for _ in 0..100 {
        step(&mut rt, &mut hw, &mut t, false, [0.0; 6]);
    }
    rt.command(&MasterToBoard::Enable, t).unwrap();
    while rt.state() != State::Enabled {
        step(&mut rt, &mut hw, &mut t, false, [0.0; 6]);
        assert!(t < 40_000_000, "{:?}", rt.status().fault);
    }
    for _ in 0..300 {
        step(&mut rt, &mut hw, &mut t, true, [0.0; 6]);
    }
    assert_eq!(rt.status().fault.cause, FaultCause::None);
    (rt, hw, t)
}

/// The clutch engaged: the robot in a safe operating stop (SS2 done), holding the tool.
fn holding() -> (Rt, PlantHw, u64) {
    let (mut rt, mut hw, mut t) = following_with_tool();
    rt.command(&MasterToBoard::Clutch { engaged: true }, t)
        .unwrap();
    for _ in 0..200 {
        step(&mut rt, &mut hw, &mut t, true, [0.0; 6]);
    }
    assert_eq!(rt.status().stop, StopStatus::SafeOperatingStop);
    (rt, hw, t)
}

/// mm or deg per joint unit.
fn shown(j: usize) -> f64 {
    if j < 3 {
        1e3
    } else {
        1f64.to_degrees()
    }
}

/// The encoder faults: stuck, dead (one count in ten kept), miscounting (one in three lost).
const ENCODER_FAULTS: [(&str, Fault); 3] = [
    ("stuck", Fault::EncoderStuck),
    ("dead", Fault::EncoderCountsOneIn { one_in: 10 }),
    (
        "miscounting",
        Fault::EncoderLosesCounts {
            one_in: control::safety::MISCOUNT_ONE_IN,
        },
    ),
];

/// The push on a leg (100 N) and its equivalent on a link (the same share of the rated
/// effort: 100 N of 220 N, 0.23 N m of 0.5 N m), towards the motor from the side of the
/// backlash gap the load rests on (the tool's small loads and the friction leave it
/// anywhere in the gap): the push presses the load onto the motor. (A push the other way
/// first carries the load across the gap, healthy encoder or not:
/// `a_stuck_encoder_under_a_push_off_the_flank_is_found_past_the_gap`.)
fn push_on(joint: usize, hw: &PlantHw) -> f64 {
    let size = if joint < 3 { 100.0 } else { 0.23 };
    let gap = hw.plant.motor_side_joint_positions()[joint] - hw.plant.joint_positions()[joint];
    // The gap is the motor less the load: a load above its motor (gap < 0) is pressed
    // onto it by a push towards +q.
    -size * gap.signum()
}

/// Property: in a safe operating stop with the channel fitted, an encoder that sticks, dies
/// or miscounts, its joint then pushed (100 N on a leg, 0.23 N m on a link), is named within
/// 20 ms of the push and before the joint moved 0.1 mm (0.1 deg): the first fault logged
/// names the encoder of that joint (`EncoderDisagree`), the stop is the table's (STO).
/// An encoder that loses one count in `n` is held by the servo all the same (it still sees
/// `(n - 1) / n` of the motion): the disagreement it leaves is an `n`-th of the motor's
/// motion, which the channel resolves beyond its bound `agree` (`ChannelConfig::agree`,
/// from its noise and both resolutions). Where the hold keeps the motor within `n *
/// agree` (24 um on a leg for `n` = 3: what the channel cannot resolve; the safety
/// requirements' SR-5) the fault may stay unnamed: then, for as long as it is not named,
/// the motor moves at most `n * agree` and the load at most 0.1 mm (0.1 deg) from where
/// the push found them.
#[test]
fn encoder_faults_in_a_held_stop_are_named_within_20_ms_and_0_1_mm() {
    let (rt0, hw0, t0) = holding();
    println!(
        "{:<12} {:>5} {:>8} {:>14} {:>14} {:>16}",
        "fault", "joint", "after/ms", "moved then", "moved in all", "motor unnamed"
    );
    for joint in [0, 1, 2, 3, 4, 5] {
        let unit = if joint < 3 { "mm" } else { "deg" };
        let within = (control::safety::HELD_ENCODER_FAULT_S * 1e3).round() as u64;
        let bound = control::safety::HELD_ENCODER_FAULT_M[usize::from(joint >= 3)];
        for (name, fault) in ENCODER_FAULTS {
            let (mut rt, mut hw, mut t) = (rt0.clone(), hw0.clone(), t0);
            hw.plant.inject(joint, fault).unwrap();
            let q0 = hw.plant.joint_positions()[joint];
            let motor0 = hw.plant.motor_side_joint_positions()[joint];
            let mut push = [0.0; 6];
            push[joint] = push_on(joint, &hw);
            let mut detected = None;
            let (mut moved, mut motor_unnamed) = (0.0f64, 0.0f64);
            for k in 1..=300 {
                step(&mut rt, &mut hw, &mut t, true, push);
                moved = moved.max((hw.plant.joint_positions()[joint] - q0).abs());
                if detected.is_none() && rt.status().fault.cause != FaultCause::None {
                    detected = Some((k, moved));
                }
                if detected.is_none() {
                    let motor = hw.plant.motor_side_joint_positions()[joint] - motor0;
                    motor_unnamed = motor_unnamed.max(motor.abs());
                }
            }
            let (after, then) = detected
                .map_or(("-".to_string(), "held".to_string()), |(ms, m)| {
                    (ms.to_string(), format!("{:.4} {unit}", m * shown(joint)))
                });
            println!(
                "{name:<12} {joint:>5} {after:>8} {then:>14} {:>11.4} {unit} {:>12.4} {unit}",
                moved * shown(joint),
                motor_unnamed * shown(joint),
            );
            match detected {
                Some((ms, then)) if ms <= within => {
                    let first = rt.fault_log().page(0).entries[0].record;
                    assert_eq!(
                        (first.cause, usize::from(first.joint)),
                        (FaultCause::EncoderDisagree, joint),
                        "{name} on joint {joint}"
                    );
                    assert!(then <= bound, "{name} on joint {joint}: moved {then}");
                    assert_eq!(rt.status().stop, StopStatus::SafeTorqueOff);
                    assert_eq!(
                        reaction(StopEvent::Fault(FaultCause::EncoderDisagree)).category,
                        StopCategory::Sto
                    );
                }
                _ => {
                    // Not named in time: only a miscount the channel cannot resolve.
                    let Fault::EncoderLosesCounts { one_in } = fault else {
                        panic!("{name} on joint {joint}: not named in {within} ms: {detected:?}");
                    };
                    let agree = rt.monitors().channel.config().agree[joint];
                    let x = f64::from(one_in) * agree;
                    assert!(
                        motor_unnamed <= x,
                        "{name} on joint {joint}: unnamed while the motor moved {motor_unnamed} > {x}"
                    );
                    let load = detected.map_or(moved, |(_, then)| then);
                    if detected.is_some() {
                        let first = rt.fault_log().page(0).entries[0].record;
                        assert_eq!(
                            (first.cause, usize::from(first.joint)),
                            (FaultCause::EncoderDisagree, joint),
                            "{name} on joint {joint}, named late"
                        );
                    }
                    assert!(
                        load <= bound,
                        "{name} on joint {joint}: unnamed, moved {load}"
                    );
                }
            }
        }
    }
}

/// Property: a push that lifts a leg's load off the motor it rests on lets the load cross
/// the lead screw's backlash (0.12 mm) without the motor, healthy encoder or not: a stuck
/// encoder is then found within 20 ms, once the load has gone less than 0.1 mm beyond the
/// gap, named as the encoder.
#[test]
fn a_stuck_encoder_under_a_push_off_the_flank_is_found_past_the_gap() {
    let (mut rt, mut hw, mut t) = holding();
    hw.plant.inject(0, Fault::EncoderStuck).unwrap();
    let q0 = hw.plant.joint_positions()[0];
    let mut push = [0.0; 6];
    push[0] = -push_on(0, &hw);
    let mut detected = None;
    for k in 1..=100 {
        step(&mut rt, &mut hw, &mut t, true, push);
        if detected.is_none() && rt.status().fault.cause != FaultCause::None {
            detected = Some((k, hw.plant.joint_positions()[0] - q0));
        }
    }
    let (ms, moved) = detected.expect("detected");
    println!("lifted: found after {ms} ms, {:.4} mm", moved * 1e3);
    assert_eq!(rt.status().fault.cause, FaultCause::EncoderDisagree);
    assert!(ms <= 20 && moved <= 0.12e-3 + 0.1e-3, "{ms} ms, {moved} m");
}

/// Property: healthy joints pushed in a safe operating stop (either way: 100 N on a leg,
/// 0.23 N m on a link, for 2 s) raise nothing from the channel (no `EncoderDisagree`,
/// `PositionSensor` or `StandstillLost`): the load crossing the backlash, the servo holding
/// against the push. (A link pushed the way the tool's weight already loads it reaches the
/// overload monitor's limit: its own finding, not the channel's.)
#[test]
fn healthy_joints_pushed_in_a_held_stop_raise_nothing() {
    let (rt0, hw0, t0) = holding();
    for joint in [0, 1, 2, 3, 4, 5] {
        for sign in [-1.0, 1.0] {
            let (mut rt, mut hw, mut t) = (rt0.clone(), hw0.clone(), t0);
            let mut push = [0.0; 6];
            push[joint] = sign * push_on(joint, &hw);
            for _ in 0..2000 {
                step(&mut rt, &mut hw, &mut t, true, push);
            }
            let cause = rt.status().fault.cause;
            println!("joint {joint} pushed {sign}: {cause:?}");
            assert!(
                !matches!(
                    cause,
                    FaultCause::EncoderDisagree
                        | FaultCause::PositionSensor
                        | FaultCause::StandstillLost
                ),
                "joint {joint} pushed {sign}: {:?}",
                rt.status().fault
            );
        }
    }
}

/// Streams targets along a line at 20 mm/s (and a tilt) for `ms` ticks, with `at(k)` run
/// before tick `k`; returns the tick of the first fault, if any.
fn follow(
    rt: &mut Rt,
    hw: &mut PlantHw,
    t: &mut u64,
    ms: u64,
    mut at: impl FnMut(u64, &mut PlantHw),
) -> Option<u64> {
    let start = *t;
    let mut first = None;
    for k in 0..ms {
        if k % 10 == 0 {
            let s = ((*t - start) as f64 * 1e-6 * 0.02).min(0.015);
            let _ = rt.command(
                &MasterToBoard::PoseTarget {
                    timestamp_us: *t,
                    position_m: [s as f32, (0.5 * s) as f32, (0.16 + 0.3 * s) as f32],
                    rotation_vector_rad: [0.0, (3.0 * s) as f32, 0.0],
                },
                *t,
            );
        }
        at(k, hw);
        step(rt, hw, t, true, [0.0; 6]);
        if first.is_none() && rt.status().fault.cause != FaultCause::None {
            first = Some(k);
        }
    }
    first
}

/// Property: while the robot follows a path at 20 mm/s with the tool, an encoder that
/// sticks, dies or miscounts is found within 100 ms, and the first fault logged names that
/// joint's encoder: the channel's `EncoderDisagree`, or the back-EMF's `EncoderDead` where
/// it sees a stuck encoder first (while moving the channel allows the backlash); never the
/// motor, the current or the servo's tracking. The same path without a fault raises
/// nothing.
#[test]
fn encoder_faults_while_moving_are_named_as_the_encoder() {
    let (rt0, hw0, t0) = following_with_tool();
    {
        let (mut rt, mut hw, mut t) = (rt0.clone(), hw0.clone(), t0);
        let first = follow(&mut rt, &mut hw, &mut t, 1500, |_, _| {});
        assert_eq!(first, None, "{:?}", rt.status().fault);
    }
    for joint in [0, 2, 3, 4] {
        for (name, fault) in ENCODER_FAULTS {
            let (mut rt, mut hw, mut t) = (rt0.clone(), hw0.clone(), t0);
            let first = follow(&mut rt, &mut hw, &mut t, 800, |k, hw| {
                if k == 200 {
                    hw.plant.inject(joint, fault).unwrap();
                }
            });
            let found = first.expect("found") - 200;
            let record = rt.fault_log().page(0).entries[0].record;
            println!(
                "moving, {name} on joint {joint}: {:?} after {found} ms",
                record.cause
            );
            assert!(
                matches!(
                    record.cause,
                    FaultCause::EncoderDisagree | FaultCause::EncoderDead
                ),
                "{name} on joint {joint}: {:?}",
                record.cause
            );
            assert_eq!(usize::from(record.joint), joint, "{name}");
            assert!(found <= 100, "{name} on joint {joint}: {found} ms");
        }
    }
}

/// Property: a failed channel is named as the sensor (`PositionSensor`, its joint), and the
/// robot stops as the stop table says (SS1: decelerate, brakes, torque off) keeping its
/// homing: a sensor stuck while the robot moves, a wire open at rest or while moving, a
/// reading that drifts away while the robot holds still, a read that fails. An open wire
/// cannot be cleared while it stays open; a stuck one can (it shows only in motion).
#[test]
fn a_failed_channel_is_named_as_the_sensor_and_stops_as_the_table_says() {
    assert_eq!(
        reaction(StopEvent::Fault(FaultCause::PositionSensor)).category,
        StopCategory::Ss1
    );
    let (rt0, hw0, t0) = following_with_tool();
    let cases: [(&str, usize, Option<Fault>, bool); 6] = [
        ("stuck, moving", 0, Some(Fault::PositionSensorStuck), true),
        (
            "stuck link, moving",
            3,
            Some(Fault::PositionSensorStuck),
            true,
        ),
        (
            "open wire, at rest",
            1,
            Some(Fault::PositionSensorOpen),
            false,
        ),
        (
            "open wire, moving",
            4,
            Some(Fault::PositionSensorOpen),
            true,
        ),
        (
            "drifting link, at rest",
            5,
            Some(Fault::PositionSensorDrift {
                per_s: 0.05f64.to_radians(),
            }),
            false,
        ),
        ("read fails", 6, None, false),
    ];
    for (name, joint, fault, moving) in cases {
        let (mut rt, mut hw, mut t) = (rt0.clone(), hw0.clone(), t0);
        match fault {
            Some(f) => hw.plant.inject(joint, f).unwrap(),
            None => hw.position_channel_failed = true,
        }
        let ms = 3000;
        let first = if moving {
            follow(&mut rt, &mut hw, &mut t, ms, |_, _| {})
        } else {
            let mut first = None;
            for k in 0..ms {
                step(&mut rt, &mut hw, &mut t, true, [0.0; 6]);
                if first.is_none() && rt.status().fault.cause != FaultCause::None {
                    first = Some(k);
                }
            }
            first
        };
        let record = rt.fault_log().page(0).entries[0].record;
        println!(
            "{name}: {:?} on {} after {first:?} ms",
            record.cause, record.joint
        );
        assert_eq!(record.cause, FaultCause::PositionSensor, "{name}");
        if joint < 6 {
            assert_eq!(usize::from(record.joint), joint, "{name}");
        }
        assert_eq!(rt.status().stop, StopStatus::SafeStop1Done, "{name}");
        assert!(rt.homed(), "{name}: the encoders' references stand");
        let cleared = rt.command(&MasterToBoard::ClearFault, t);
        if matches!(fault, Some(Fault::PositionSensorOpen)) || fault.is_none() {
            assert_eq!(
                cleared,
                Err(master_link::NackReason::FaultStillActive),
                "{name}"
            );
        } else {
            assert!(cleared.is_ok(), "{name}: {cleared:?}");
        }
    }
}

/// A rest pose in the workspace, away from every switch and stop: the platform 6 mm off
/// the centre and tilted 5 deg (where a tool inside a patient may have left it).
fn in_the_workspace() -> [f64; 6] {
    use kinematics_core::{inverse, Pose};
    use nalgebra::{Rotation3, Vector3};
    let g = RsprGeometry::<f64>::reference();
    let pose = Pose {
        t: Vector3::new(0.006, -0.004, 0.165),
        r: Rotation3::from_scaled_axis(Vector3::new(0.0, 5f64.to_radians(), 0.0)),
    };
    let q = inverse(&g, &pose, Branch::OUTER).unwrap().q();
    std::array::from_fn(|j| q[j])
}

/// Property: with the channel fitted, `Home` from a pose in the workspace restores every
/// reference from the channel and verifies it: no joint moves more than 1.1 mm or 1.1 deg
/// (the verification's 1 mm, 1 deg out and back), no switch or stop is approached, there is
/// no park move (the robot stays where it is), the measured joints then read the true
/// load-side joints within half the legs' backlash (60 um, as after a sweep: the load rests
/// anywhere in the gap) and 0.03 deg on a link (the channel's calibration residual of 2
/// counts, 0.01 deg, the links' 20 arcsec of backlash and the noise), and the status says
/// the board has the channel.
#[test]
fn home_restores_the_references_from_the_channel_without_a_sweep() {
    let q_rest = in_the_workspace();
    let (mut rt, mut hw, mut t) = booted(q_rest);
    assert!(rt.status().position_channel);
    rt.command(&MasterToBoard::Home { rehome: false }, t)
        .unwrap();
    let mut moved = [0.0f64; 6];
    while rt.state() == State::Homing {
        step(&mut rt, &mut hw, &mut t, false, [0.0; 6]);
        let q = hw.plant.joint_positions();
        for j in 0..6 {
            moved[j] = moved[j].max((q[j] - q_rest[j]).abs());
        }
        assert!(t < 30_000_000);
        assert!(hw.switch_levels().iter().all(|s| !s), "a switch actuated");
    }
    assert_eq!(rt.state(), State::Ready, "{:?}", rt.status().fault);
    let took_s = t as f64 * 1e-6;
    let measured = rt.measured().q;
    let truth = hw.plant.joint_positions();
    println!(
        "restored in {took_s:.2} s; moved at most {:.3} mm, {:.3} deg",
        moved[..3].iter().fold(0.0f64, |a, x| a.max(*x)) * 1e3,
        moved[3..]
            .iter()
            .fold(0.0f64, |a, x| a.max(*x))
            .to_degrees()
    );
    for j in 0..6 {
        let bound = if j < 3 { 1.1e-3 } else { 1.1f64.to_radians() };
        assert!(moved[j] <= bound, "joint {j} moved {}", moved[j]);
        assert!(moved[j] >= 0.5 * bound, "joint {j} was verified by a move");
        let err = measured[j] - truth[j];
        let tol = if j < 3 { 60e-6 } else { 0.03f64.to_radians() };
        println!(
            "joint {j}: measured - true {:.2} um/mdeg",
            err * shown(j) * 1e3
        );
        assert!(
            err.abs() <= tol,
            "joint {j}: measured {} true {}",
            measured[j],
            truth[j]
        );
        assert!(
            (truth[j] - q_rest[j]).abs() <= 0.01 * bound,
            "joint {j} back where it was"
        );
    }
    assert!(rt.status().position_channel);
}

/// Property: a board without the channel homes as the prototype does (the sweep: every leg
/// reaches its home switch), and its status says it has no channel.
#[test]
fn a_board_without_the_channel_sweeps() {
    let (mut hw, _, cfg) = common::homing_fixture([0.16, 0.161, 0.159], [0.2; 3]);
    let mut rt = Rt::new(RsprGeometry::reference(), cfg, 0).unwrap();
    let mut t = 0;
    rt.boot_done(hw.counts(), t, ResetCause::PowerOn, None)
        .unwrap();
    rt.command(&MasterToBoard::Home { rehome: false }, t)
        .unwrap();
    let mut switched = [false; 6];
    while rt.state() == State::Homing {
        step(&mut rt, &mut hw, &mut t, false, [0.0; 6]);
        for (s, l) in switched.iter_mut().zip(hw.switch_levels()) {
            *s |= l;
        }
        assert!(t < 60_000_000);
    }
    assert_eq!(rt.state(), State::Ready);
    assert!(switched[..3].iter().all(|s| *s), "{switched:?}");
    assert!(!rt.status().position_channel);
    let (measured, truth) = (rt.measured().q, hw.plant.joint_positions());
    for j in 0..6 {
        println!(
            "swept, joint {j}: measured - true {:.2} um/mdeg",
            (measured[j] - truth[j]) * shown(j) * 1e3
        );
    }
}

/// Property: a stuck encoder found during the verification's move fails the restoring
/// homing, named as that joint's encoder (the channel's disagreement, or the back-EMF's
/// dead encoder, whichever sees it first); the references are not trusted.
#[test]
fn a_stuck_encoder_fails_the_verification() {
    let (mut rt, mut hw, mut t) = booted(in_the_workspace());
    hw.plant.inject(2, Fault::EncoderStuck).unwrap();
    rt.command(&MasterToBoard::Home { rehome: false }, t)
        .unwrap();
    for _ in 0..10_000 {
        step(&mut rt, &mut hw, &mut t, false, [0.0; 6]);
        if rt.state() != State::Homing {
            break;
        }
    }
    let first = rt.fault_log().page(0).entries[0].record;
    println!("{:?} on joint {}", first.cause, first.joint);
    assert_eq!(rt.state(), State::Fault);
    assert!(matches!(
        first.cause,
        FaultCause::EncoderDisagree | FaultCause::EncoderDead
    ));
    assert_eq!(first.joint, 2);
    assert!(!rt.homed());
}
