#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
//! Every warning flag of the status (`master_link::Warnings`) raised where its condition
//! occurs, on the runtime and the plant (a test per flag); every fault bit the bit of a
//! fault cause the board raises, and every cause's bit a named one.

use control::modes::State;
use control::runtime::{Runtime, RuntimeConfig};
use control::service::{ServiceConfig, TickService};
use hal::QuadratureCounter;
use kinematics_core::guards::{Guards, Severity};
use kinematics_core::{Branch, Pose, RsprGeometry};
use master_link::{
    FaultCause, Faults, FirmwareVersion, LinkCounters, MasterToBoard, ResetCause, Warnings,
};
use nalgebra::Vector3;

use crate::common;
use common::PlantHw;

type Rt = Runtime<f64, RsprGeometry<f64>>;

fn tick(rt: &mut Rt, hw: &mut PlantHw, t: &mut u64) {
    *t += 1000;
    if (*t).is_multiple_of(20_000) {
        rt.command(&MasterToBoard::Heartbeat, *t).unwrap();
    }
    rt.tick(hw, *t);
    hw.step_ms();
}

/// The runtime on the homing fixture, booted, with `configure` applied to its settings.
fn booted(configure: impl Fn(&mut RuntimeConfig<f64>)) -> (Rt, PlantHw, u64) {
    let (mut hw, _, mut cfg) = common::homing_fixture([0.16, 0.161, 0.159], [0.2; 3]);
    configure(&mut cfg);
    let mut rt = Rt::new(RsprGeometry::reference(), cfg, 0).unwrap();
    rt.boot_done(hw.counts(), 0, ResetCause::PowerOn, None)
        .unwrap();
    (rt, hw, 0)
}

/// Homed (with the park move) and enabled (the brake check passed).
fn enabled(configure: impl Fn(&mut RuntimeConfig<f64>)) -> (Rt, PlantHw, u64) {
    let (mut rt, mut hw, mut t) = booted(configure);
    rt.command(&MasterToBoard::Home { rehome: false }, t)
        .unwrap();
    while rt.state() != State::Ready {
        tick(&mut rt, &mut hw, &mut t);
        assert!(t < 60_000_000, "{:?}", rt.status().fault);
    }
    for _ in 0..100 {
        tick(&mut rt, &mut hw, &mut t);
    }
    rt.command(&MasterToBoard::Enable, t).unwrap();
    while rt.state() != State::Enabled {
        tick(&mut rt, &mut hw, &mut t);
        assert!(t < 70_000_000, "{:?}", rt.status().fault);
    }
    (rt, hw, t)
}

fn warns(rt: &Rt, w: Warnings) -> bool {
    rt.status().warnings.contains(w)
}

/// Streams targets on the straight line to `goal` at 100 Hz for `ms` ms (a master's
/// stream), each stamped with the board's time.
fn stream_to(rt: &mut Rt, hw: &mut PlantHw, t: &mut u64, goal: &Pose<f64>, ms: u64) {
    for k in 0..ms {
        if k % 10 == 0 {
            let (p, r) = control::wire::pose_to_wire(goal);
            let _ = rt.command(
                &MasterToBoard::PoseTarget {
                    timestamp_us: *t,
                    position_m: p,
                    rotation_vector_rad: r,
                },
                *t,
            );
        }
        tick(rt, hw, t);
    }
}

/// `NOT_HOMED`: from boot until the homing is done.
#[test]
fn not_homed_until_the_homing_is_done() {
    let (rt, _, _) = booted(|_| {});
    assert!(warns(&rt, Warnings::NOT_HOMED));
    let (rt, _, _) = enabled(|_| {});
    assert!(!warns(&rt, Warnings::NOT_HOMED));
}

/// `HEARTBEAT_LATE`: enabled, and no heartbeat for longer than the hold time.
#[test]
fn heartbeat_late_when_the_heartbeat_is_late() {
    let (mut rt, mut hw, mut t) = enabled(|_| {});
    assert!(!warns(&rt, Warnings::HEARTBEAT_LATE));
    let hold = rt.config().heartbeat.hold_after_us;
    let end = t + hold + 5_000;
    while t < end {
        t += 1000;
        rt.tick(&mut hw, t);
        hw.step_ms();
    }
    assert!(warns(&rt, Warnings::HEARTBEAT_LATE));
}

/// `TARGET_STALE`: following, and no target accepted for longer than the supervisor's
/// staleness age (100 ms): set after enabling without targets, cleared by a target, set
/// again once the stream stops; not while holding (the clutch).
#[test]
fn target_stale_when_no_target_arrives_while_following() {
    let (mut rt, mut hw, mut t) = enabled(|_| {});
    let age = rt.config().controller.supervisor.stale_after_us;
    assert_eq!(age, 100_000);
    for _ in 0..(age / 1000 + 5) {
        tick(&mut rt, &mut hw, &mut t);
    }
    assert!(
        warns(&rt, Warnings::TARGET_STALE),
        "no target since enabling"
    );
    let here = *rt.controller().unwrap().supervisor().setpoint();
    stream_to(&mut rt, &mut hw, &mut t, &here, 50);
    assert!(!warns(&rt, Warnings::TARGET_STALE), "a stream at 100 Hz");
    for _ in 0..(age / 1000 - 20) {
        tick(&mut rt, &mut hw, &mut t);
    }
    assert!(!warns(&rt, Warnings::TARGET_STALE), "not yet stale");
    for _ in 0..30 {
        tick(&mut rt, &mut hw, &mut t);
    }
    assert!(warns(&rt, Warnings::TARGET_STALE), "the stream stopped");
    rt.command(&MasterToBoard::Clutch { engaged: true }, t)
        .unwrap();
    tick(&mut rt, &mut hw, &mut t);
    assert_eq!(rt.state(), State::Enabled);
    assert!(
        !warns(&rt, Warnings::TARGET_STALE),
        "holding on the clutch is not a stale stream"
    );
}

/// `LINK_ERRORS`: the receiving side has rejected frames (the link counters added to the
/// status as it goes out).
#[test]
fn link_errors_when_frames_were_rejected() {
    let (rt, _, _) = booted(|_| {});
    let mut st = rt.status();
    control::telemetry::with_link(&mut st, Some(LinkCounters::default()));
    assert!(!st.warnings.contains(Warnings::LINK_ERRORS));
    let bad = LinkCounters {
        bad_checksum: 1,
        ..LinkCounters::default()
    };
    control::telemetry::with_link(&mut st, Some(bad));
    assert!(st.warnings.contains(Warnings::LINK_ERRORS));
}

/// `CYCLE_OVERRUN`: a tick that ran longer than 80 % of the period.
#[test]
fn cycle_overrun_when_a_tick_runs_too_long() {
    let (rt, mut hw, _) = booted(|_| {});
    let profile = board_profile::BoardProfile::REFERENCE;
    let cycles_per_us = profile.cpu_hz / 1_000_000;
    let cfg = ServiceConfig::for_period(
        profile.control_period_us,
        profile.cpu_hz,
        FirmwareVersion {
            major: 0,
            minor: 1,
            patch: 0,
        },
    );
    let mut s = TickService::new(rt, cfg);
    let mut t = 1000;
    s.begin(t, 0, Default::default());
    s.tick(&mut hw, t);
    let out = s.finish(t, cycles_per_us * 100);
    assert!(!out.status.warnings.contains(Warnings::CYCLE_OVERRUN));
    t += 1000;
    s.begin(t, 0, Default::default());
    s.tick(&mut hw, t);
    let out = s.finish(t, cycles_per_us * 900);
    assert!(out.status.warnings.contains(Warnings::CYCLE_OVERRUN));
}

/// `VELOCITY_LIMITED`: the current limit capped a duty (a joint held against its brake:
/// the servo asks more than the motor may draw).
#[test]
fn velocity_limited_when_the_current_limit_caps_a_duty() {
    let (mut rt, mut hw, mut t) = enabled(|_| {});
    assert!(!warns(&rt, Warnings::VELOCITY_LIMITED));
    // A leg seized at its load: the servo's effort grows until the limit caps it.
    let q = hw.plant.joint_positions();
    hw.stop_below[0] = Some(q[0] - 1e-6);
    hw.stop_above[0] = Some(q[0] + 1e-6);
    let mut goal = *rt.controller().unwrap().supervisor().setpoint();
    goal.t.z += 0.002;
    let mut seen = false;
    for _ in 0..40 {
        stream_to(&mut rt, &mut hw, &mut t, &goal, 10);
        seen |= warns(&rt, Warnings::VELOCITY_LIMITED);
        if seen || rt.state() == State::Fault {
            break;
        }
    }
    assert!(
        seen,
        "state {:?}, fault {:?}",
        rt.state(),
        rt.status().fault
    );
}

/// A pose in the task box (and its margin) whose legs come within 10 % of half the stroke
/// of an end, with every guard below its stop level: the task box's corner, tilted about
/// [1, 1, 0] as far as the guards allow.
fn near_stroke_end(g: &RsprGeometry<f64>) -> Pose<f64> {
    let limits = kinematics_core::guards::Limits::reference();
    let guards = Guards::new(*g, Branch::OUTER, limits).unwrap();
    let axis = Vector3::new(1.0, 1.0, 0.0).normalize();
    for k in 0..500 {
        let tilt = (25.0 - 0.05 * f64::from(k)).to_radians();
        let pose =
            Pose::from_position_rotation_vector(Vector3::new(0.02, 0.02, 0.150), axis * tilt)
                .unwrap();
        let mut stops = 0;
        let Some(sol) = guards.evaluate_pose(&pose, &mut |r| {
            if r.severity == Some(Severity::Stop) {
                stops += 1;
            }
        }) else {
            continue;
        };
        if stops == 0 && guards.margins_at(&sol).stroke < 0.08 {
            return pose;
        }
    }
    panic!("no pose near a stroke end");
}

/// `NEAR_JOINT_LIMIT`: the setpoint's legs within 10 % of half the stroke of an end (a
/// target at the task box's tilted corner).
#[test]
fn near_joint_limit_at_the_tilted_corner() {
    let (mut rt, mut hw, mut t) = enabled(|_| {});
    assert!(!warns(&rt, Warnings::NEAR_JOINT_LIMIT));
    let goal = near_stroke_end(rt.robot());
    let mut seen = false;
    for _ in 0..600 {
        stream_to(&mut rt, &mut hw, &mut t, &goal, 10);
        seen |= warns(&rt, Warnings::NEAR_JOINT_LIMIT);
        if seen {
            break;
        }
    }
    assert!(
        seen,
        "state {:?}, fault {:?}, margins {:?}",
        rt.state(),
        rt.status().fault,
        rt.status().margins
    );
}

/// `NEAR_SERIAL_SINGULARITY`, `NEAR_PARALLEL_SINGULARITY`: the setpoint's measures below
/// their warning levels. With the reference levels the task box stays above them (its
/// worst: serial 0.265, parallel 0.059 against 0.15 and 0.03); here the levels are raised
/// (serial 0.9, parallel 0.3) and the robot goes from the central pose (serial 1.0,
/// parallel 0.17: only the parallel one near) to the task box's tilted corner (serial
/// 0.76).
#[test]
fn near_singularities_below_their_warning_levels() {
    let (rt, _, _) = enabled(|_| {});
    assert!(!warns(&rt, Warnings::NEAR_SERIAL_SINGULARITY));
    assert!(!warns(&rt, Warnings::NEAR_PARALLEL_SINGULARITY));
    let (mut rt, mut hw, mut t) = enabled(|cfg| {
        cfg.controller.limits.serial.warn = 0.9;
        cfg.controller.limits.parallel.warn = 0.3;
    });
    let m = rt.controller().unwrap().supervisor().margins();
    assert!(m.serial > 0.9 && m.parallel < 0.3, "{m:?}");
    assert!(!warns(&rt, Warnings::NEAR_SERIAL_SINGULARITY));
    assert!(warns(&rt, Warnings::NEAR_PARALLEL_SINGULARITY));
    let goal = near_stroke_end(rt.robot());
    let mut seen = false;
    for _ in 0..600 {
        stream_to(&mut rt, &mut hw, &mut t, &goal, 10);
        seen |= warns(&rt, Warnings::NEAR_SERIAL_SINGULARITY);
        if seen {
            break;
        }
    }
    assert!(
        seen,
        "state {:?}, fault {:?}, margins {:?}",
        rt.state(),
        rt.status().fault,
        rt.controller().map(|c| c.supervisor().margins())
    );
}

/// Every warning named in the protocol has its test above; bit 3 (a target clamped to
/// the workspace, which the board never does) is reserved.
#[test]
fn every_warning_is_one_of_the_tested() {
    let tested = Warnings::NOT_HOMED
        | Warnings::HEARTBEAT_LATE
        | Warnings::TARGET_STALE
        | Warnings::LINK_ERRORS
        | Warnings::CYCLE_OVERRUN
        | Warnings::VELOCITY_LIMITED
        | Warnings::NEAR_JOINT_LIMIT
        | Warnings::NEAR_SERIAL_SINGULARITY
        | Warnings::NEAR_PARALLEL_SINGULARITY;
    assert_eq!(tested, Warnings::ALL);
    assert!(!Warnings::ALL.contains(Warnings::from_bits_retain(1 << 3)));
}

/// Every fault bit is the bit of a cause, and every cause's bit is a named bit: a bit no
/// cause raises cannot be defined.
#[test]
fn every_fault_bit_has_a_cause() {
    let mut raised = Faults::NONE;
    for c in FaultCause::ALL {
        let b = c.bit();
        assert!(!b.is_empty() && b.unknown().is_empty(), "{c:?}");
        raised.insert(b);
    }
    assert_eq!(raised, Faults::ALL);
}
