#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::needless_range_loop
)]
//! The stop table, row by row, on the plant with the thesis tool attached: every fault
//! cause and every stopping command, triggered while the robot holds still, gets the stop
//! its row names, carried out on the outputs as IEC 60204-1 / 61800-5-2 define it, and the
//! platform moves no further than the bounds of the stops issue afterwards (0.1 mm for
//! SS1 and SS2, 0.5 mm for STO with brakes).

use control::modes::State;
use control::monitors::Finding;
use control::runtime::Runtime;
use control::stops::{reaction, StopCategory, StopEvent, TABLE};
use hal::QuadratureCounter;
use kinematics_core::RsprGeometry;
use master_link::MasterToBoard;
use master_link::{FaultCause, ResetCause, StopStatus};

use crate::common;
use common::PlantHw;

type Rt = Runtime<f64, RsprGeometry<f64>>;

fn tick(rt: &mut Rt, hw: &mut PlantHw, t: &mut u64, beat: bool) {
    step(rt, hw, t, beat, true)
}

fn step(rt: &mut Rt, hw: &mut PlantHw, t: &mut u64, beat: bool, tool: bool) {
    *t += 1000;
    if beat {
        rt.command(&MasterToBoard::Heartbeat, *t).unwrap();
    }
    rt.tick(hw, *t);
    // The tool's weight on the joints, at the true pose.
    if tool {
        let loads = common::tool_loads(&hw.plant.joint_positions());
        hw.plant.set_external_load(loads).unwrap();
    }
    hw.step_ms();
}

/// The robot homed (without the tool, as an instrument is mounted after homing), enabled,
/// the tool attached, holding still (settled for 300 ms).
fn holding_with_tool() -> (Rt, PlantHw, u64) {
    let (mut hw, _, cfg) = common::homing_fixture([0.16, 0.161, 0.159], [0.2; 3]);
    let mut rt = Rt::new(RsprGeometry::reference(), cfg, 0).unwrap();
    let mut t = 0;
    rt.boot_done(hw.counts(), t, ResetCause::PowerOn, None)
        .unwrap();
    rt.command(&MasterToBoard::Home { rehome: false }, t)
        .unwrap();
    while rt.state() == State::Homing {
        step(&mut rt, &mut hw, &mut t, true, false);
        assert!(t < 60_000_000);
    }
    for _ in 0..100 {
        step(&mut rt, &mut hw, &mut t, true, false);
    }
    assert_eq!(rt.state(), State::Ready, "{:?}", rt.fault_log().page(0));
    rt.command(&MasterToBoard::Enable, t).unwrap();
    while rt.state() != State::Enabled {
        step(&mut rt, &mut hw, &mut t, true, false);
        assert!(t < 70_000_000, "{:?}", rt.status().fault);
    }
    for _ in 0..300 {
        tick(&mut rt, &mut hw, &mut t, true);
    }
    (rt, hw, t)
}

/// Triggers `event` at `t`; returns whether the heartbeat goes on.
fn trigger(rt: &mut Rt, hw: &mut PlantHw, event: StopEvent, t: u64) -> bool {
    match event {
        StopEvent::Fault(FaultCause::EmergencyStopButton) => hw.press_estop(true),
        StopEvent::Fault(FaultCause::EmergencyStopMessage) => {
            rt.command(&MasterToBoard::EmergencyStop, t).unwrap();
        }
        StopEvent::Fault(cause) => rt.fault(Finding::joint(cause, 1, 1.0f64), t),
        StopEvent::Disable => {
            rt.command(&MasterToBoard::Disable, t).unwrap();
        }
        StopEvent::HeartbeatLate => return false,
        StopEvent::ClutchEngaged => {
            rt.command(&MasterToBoard::Clutch { engaged: true }, t)
                .unwrap();
        }
        StopEvent::OperatorAbsent => {
            rt.command(&MasterToBoard::OperatorPresent { present: false }, t)
                .unwrap();
        }
    }
    true
}

/// Property: every row's stop is carried out as its category defines it (STO: torque off
/// and brakes applied in the first tick; SS1: the brakes applied while the drives hold,
/// torque off once they have engaged; SS2: decelerate, then hold under power, brakes
/// released, standstill monitored), and the platform moves at most 0.1 mm after an SS1 or
/// SS2 and 0.5 mm after an STO with brakes (SR-2, SR-7: within the requirements' bounds).
#[test]
fn every_row_of_the_stop_table_stops_as_its_category_says() {
    let (rt0, hw0, t0) = holding_with_tool();
    let engage = rt0.config().stops.brake_engage_us;
    let hold_after = rt0.config().heartbeat.hold_after_us;
    println!(
        "{:<34} {:<5} {:>10} {:>12}",
        "event", "stop", "moved/µm", "status"
    );
    let mut worst = [0.0f64; 3];
    for event in TABLE {
        let (mut rt, mut hw, mut t) = (rt0.clone(), hw0.clone(), t0);
        let category = reaction(event).category;
        let p0 = common::true_pose(&hw).t;
        let beat = trigger(&mut rt, &mut hw, event, t);
        // When the stop starts: at once, or after the hold time for a late heartbeat.
        let start = if event == StopEvent::HeartbeatLate {
            t + hold_after
        } else {
            t
        };
        let mut first = None;
        let mut braked_at = None;
        let mut off_at = None;
        let mut moved = 0.0f64;
        // A late heartbeat is watched until the heartbeat is lost (its own row, SS1).
        let ticks = if event == StopEvent::HeartbeatLate {
            rt.config().heartbeat.disable_after_us / 1000 - 2
        } else {
            600
        };
        for _ in 0..ticks {
            tick(&mut rt, &mut hw, &mut t, beat);
            if t <= start {
                continue;
            }
            first.get_or_insert((hw.enabled, hw.brakes_released));
            if braked_at.is_none() && !hw.brakes_released {
                braked_at = Some(t);
            }
            if off_at.is_none() && !hw.enabled {
                off_at = Some(t);
            }
            moved = moved.max((common::true_pose(&hw).t - p0).norm());
        }
        let name = format!("{event:?}");
        let status = rt.status().stop;
        println!(
            "{name:<34} {:<5} {:>10.2} {:>12?}",
            match category {
                StopCategory::Sto => "STO",
                StopCategory::Ss1 => "SS1",
                StopCategory::Ss2 => "SS2",
            },
            moved * 1e6,
            status
        );
        match category {
            StopCategory::Sto => {
                assert_eq!(
                    first,
                    Some((false, false)),
                    "{name}: off and braked at once"
                );
                assert_eq!(status, StopStatus::SafeTorqueOff, "{name}");
                assert!(moved <= 0.5e-3, "{name}: moved {moved}");
                worst[0] = worst[0].max(moved);
            }
            StopCategory::Ss1 => {
                let (b, o) = (braked_at.expect("braked"), off_at.expect("off"));
                assert_eq!(first.map(|f| f.0), Some(true), "{name}: drives hold first");
                assert!(
                    o >= b + engage,
                    "{name}: torque off {o} before the brakes held ({b})"
                );
                // A fault's stop stays in force until the fault is cleared; the robot a
                // `Disable` stopped is `Ready`, where no stop is in force.
                let done = if event == StopEvent::Disable {
                    StopStatus::None
                } else {
                    StopStatus::SafeStop1Done
                };
                assert_eq!(status, done, "{name}");
                assert!(moved <= 0.1e-3, "{name}: moved {moved}");
                worst[1] = worst[1].max(moved);
            }
            StopCategory::Ss2 => {
                assert_eq!(
                    (braked_at, off_at),
                    (None, None),
                    "{name}: holds under power"
                );
                assert_eq!(status, StopStatus::SafeOperatingStop, "{name}");
                assert!(moved <= 0.1e-3, "{name}: moved {moved}");
                worst[2] = worst[2].max(moved);
            }
        }
    }
    println!(
        "worst motion after the stop: STO {:.2} µm, SS1 {:.2} µm, SS2 {:.2} µm",
        worst[0] * 1e6,
        worst[1] * 1e6,
        worst[2] * 1e6
    );
}

/// Property: a stop never weakens one in force (STO over SS1 over SS2), and a standstill
/// lost during a safe operating stop falls back to STO with brakes (SR-3).
#[test]
fn stops_only_escalate_and_a_lost_standstill_is_sto() {
    let (mut rt, mut hw, mut t) = holding_with_tool();
    rt.command(&MasterToBoard::Clutch { engaged: true }, t)
        .unwrap();
    for _ in 0..50 {
        tick(&mut rt, &mut hw, &mut t, true);
    }
    assert_eq!(rt.status().stop, StopStatus::SafeOperatingStop);
    // Push a joint out of the standstill window: 5 N m on a link against its hold.
    let mut moved = false;
    for _ in 0..500 {
        t += 1000;
        rt.command(&MasterToBoard::Heartbeat, t).unwrap();
        rt.tick(&mut hw, t);
        let mut loads = common::tool_loads(&hw.plant.joint_positions());
        loads[4] += 3.0;
        hw.plant.set_external_load(loads).unwrap();
        hw.step_ms();
        if rt.state() == State::Fault {
            moved = true;
            break;
        }
    }
    assert!(moved);
    let st = rt.status();
    assert_eq!(st.fault.cause, FaultCause::StandstillLost);
    assert_eq!(st.fault.joint, 4);
    assert_eq!(st.stop, StopStatus::SafeTorqueOff);
    assert!(!hw.enabled && !hw.brakes_released);
    // An SS2 request now changes nothing.
    rt.command(&MasterToBoard::OperatorPresent { present: false }, t)
        .unwrap();
    tick(&mut rt, &mut hw, &mut t, true);
    assert_eq!(rt.status().stop, StopStatus::SafeTorqueOff);
}

/// Property (found by the fuzzer): a fault whose stop is stronger than the one in force is
/// acted on and logged even while a weaker one is latched: an SS1 over-temperature, then
/// a limit switch closing, is STO at once, with both in the log.
#[test]
fn a_weaker_latched_fault_does_not_mask_a_stronger_one() {
    let (mut rt, mut hw, mut t) = holding_with_tool();
    rt.fault(Finding::joint(FaultCause::OverTemperature, 0, 1.1f64), t);
    tick(&mut rt, &mut hw, &mut t, true);
    assert!(
        matches!(
            rt.status().stop,
            StopStatus::SafeStop1Decelerating | StopStatus::SafeStop1Braking
        ),
        "{:?}",
        rt.status().stop
    );
    // Leg 3's switch closes (a switch that fails closed).
    hw.switch_below[2] = Some(1.0);
    tick(&mut rt, &mut hw, &mut t, true);
    let st = rt.status();
    assert_eq!(st.stop, StopStatus::SafeTorqueOff);
    assert!(!hw.enabled && !hw.brakes_released);
    assert_eq!(
        st.fault.cause,
        FaultCause::OverTemperature,
        "the first fault is reported"
    );
    let log = rt.fault_log();
    let causes: Vec<_> = (0..log.len())
        .map(|i| log.get(i).unwrap().record.cause)
        .collect();
    assert_eq!(
        causes,
        [FaultCause::OverTemperature, FaultCause::LimitSwitch]
    );
    // A lasting condition is logged once, not every tick.
    for _ in 0..50 {
        tick(&mut rt, &mut hw, &mut t, true);
    }
    assert_eq!(rt.fault_log().len(), 2);
}
