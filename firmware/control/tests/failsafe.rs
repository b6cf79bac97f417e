#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::needless_range_loop
)]
//! The fail-safe rules: the heartbeat's hold (SS2) then its fault (SS1); the emergency
//! stop through both channels (the hard-wired relay, the interrupt) from every state; the
//! safety relay's feedback; a tracking fault's STO with brakes; outputs off once a stop is
//! complete; the deadline policy and the watchdog; the fault log across a reset.

use control::estop::{emergency_stop_isr, EStopLatch};
use control::faults::{FaultLog, Persisted};
use control::heartbeat::{HeartbeatConfig, HeartbeatLevel, HeartbeatMonitor};
use control::modes::{Event, ModeKind, State};
use control::monitors::Finding;
use control::runtime::Runtime;
use control::service::{ServiceConfig, TickService};
use control::watchdog::{FeedDecision, TickTiming, WatchdogConfig, WatchdogPolicy};
use hal::{QuadratureCounter, SafeOutputs};
use kinematics_core::{Pose, RsprGeometry};
use master_link::MasterToBoard;
use master_link::{FaultCause, Faults, NackReason, ResetCause, StopStatus, Warnings};

use crate::common;
use common::PlantHw;

/// The reference board (its period and clock).
const PROFILE: board_profile::BoardProfile = board_profile::BoardProfile::REFERENCE;

// ---------------------------------------------------------------------------------------
// Fixture: the runtime on the plant model
// ---------------------------------------------------------------------------------------

type Rt = Runtime<f64, RsprGeometry<f64>>;

/// Heartbeat times of these tests: hold after 30 ms, fault after 120 ms.
const HB: HeartbeatConfig = HeartbeatConfig {
    hold_after_us: 30_000,
    disable_after_us: 120_000,
};

/// The tick service's settings: the board profile's period and core clock.
fn service_config() -> ServiceConfig {
    ServiceConfig::for_period(
        PROFILE.control_period_us,
        PROFILE.cpu_hz,
        control::link::FIRMWARE_VERSION,
    )
}

fn tick(rt: &mut Rt, hw: &mut PlantHw, t: &mut u64, beat: bool) {
    *t += 1000;
    if beat {
        rt.command(&MasterToBoard::Heartbeat, *t).unwrap();
    }
    rt.tick(hw, *t);
    hw.step_ms();
}

/// A runtime and plant in each state: Boot, Disabled, Homing, Ready (its stop done),
/// Enabling, Enabled, Fault.
fn snapshots() -> Vec<(State, Rt, PlantHw, u64)> {
    let g = RsprGeometry::<f64>::reference();
    // The plant with home switches on the legs and hard stops on the links.
    let (mut hw, _, mut cfg) = common::homing_fixture([0.16, 0.161, 0.159], [0.2; 3]);
    cfg.heartbeat = HB;
    let mut rt = Rt::new(g, cfg, 0).unwrap();
    let mut out = vec![(State::Boot, rt.clone(), hw.clone(), 0)];
    let mut t = 0;
    rt.boot_done(hw.counts(), t, ResetCause::PowerOn, None)
        .unwrap();
    out.push((State::Disabled, rt.clone(), hw.clone(), t));
    rt.command(&MasterToBoard::Home { rehome: false }, t)
        .unwrap();
    for _ in 0..50 {
        tick(&mut rt, &mut hw, &mut t, true);
    }
    assert_eq!(rt.state(), State::Homing, "{:?}", rt.status().fault);
    out.push((State::Homing, rt.clone(), hw.clone(), t));
    while rt.state() == State::Homing {
        tick(&mut rt, &mut hw, &mut t, true);
        assert!(t < 60_000_000);
    }
    assert_eq!(rt.state(), State::Ready, "{:?}", rt.status().fault);
    for _ in 0..100 {
        tick(&mut rt, &mut hw, &mut t, true);
    }
    out.push((State::Ready, rt.clone(), hw.clone(), t));
    rt.command(&MasterToBoard::Enable, t).unwrap();
    tick(&mut rt, &mut hw, &mut t, true);
    assert_eq!(rt.state(), State::Enabling);
    out.push((State::Enabling, rt.clone(), hw.clone(), t));
    while rt.state() == State::Enabling {
        tick(&mut rt, &mut hw, &mut t, true);
        assert!(t < 70_000_000);
    }
    assert_eq!(rt.state(), State::Enabled, "{:?}", rt.status().fault);
    out.push((State::Enabled, rt.clone(), hw.clone(), t));
    rt.fault(Finding::joint(FaultCause::Overcurrent, 2, 9.0f64), t);
    out.push((State::Fault, rt, hw, t));
    out
}

fn enabled() -> (Rt, PlantHw, u64) {
    let (_, rt, hw, t) = snapshots().remove(5);
    assert_eq!(rt.state(), State::Enabled);
    (rt, hw, t)
}

// ---------------------------------------------------------------------------------------
// Heartbeat
// ---------------------------------------------------------------------------------------

#[test]
fn heartbeat_monitor_escalates_once_at_the_configured_times() {
    let mut m = HeartbeatMonitor::new(HB, 1_000);
    assert!(HB.validate().is_ok());
    assert!(HeartbeatConfig {
        hold_after_us: 10,
        disable_after_us: 10
    }
    .validate()
    .is_err());
    assert_eq!(m.poll(1_000 + 29_999), None);
    assert_eq!(m.poll(1_000 + 30_000), Some(Event::HeartbeatLate));
    assert_eq!(m.poll(1_000 + 31_000), None, "once");
    assert_eq!(m.level(), HeartbeatLevel::Late);
    assert_eq!(m.poll(1_000 + 119_999), None);
    let lost = Some(Event::Fault(FaultCause::HeartbeatTimeout));
    assert_eq!(m.poll(1_000 + 120_000), lost);
    assert_eq!(m.poll(1_000 + 500_000), None, "once");
    assert_eq!(m.beat(700_000), Some(Event::HeartbeatRestored));
    assert_eq!(m.beat(701_000), None);
    assert_eq!(m.level(), HeartbeatLevel::Alive);
    // A silence seen only after the fault time jumps straight to the fault.
    assert_eq!(m.poll(701_000 + 200_000), lost);
    assert_eq!((m.holds(), m.losses(), m.beats()), (1, 2, 2));
}

/// Property: a silent master makes a moving robot hold (SS2) at the hold time, refusing
/// targets, and at the fault time the fault `HeartbeatTimeout` stops it as SS1: the
/// brakes applied while the drives still hold, torque off once they have engaged; the
/// robot stays within 0.5 mm of where the hold stopped it, short of the target, and the
/// homing is kept. The fault's value is the silence in ms.
#[test]
fn heartbeat_loss_holds_then_stops_with_brakes() {
    let (mut rt, mut hw, mut t) = enabled();
    let last_beat = t;
    let target = Pose {
        t: nalgebra::Vector3::new(0.0, 0.0, 0.165),
        r: nalgebra::Rotation3::identity(),
    };
    let (p, r) = control::wire::pose_to_wire(&target);
    rt.command(
        &MasterToBoard::PoseTarget {
            timestamp_us: 1_000,
            position_m: p,
            rotation_vector_rad: r,
        },
        t,
    )
    .unwrap();
    let mut held_at = None;
    let mut faulted_at = None;
    let mut braked_at = None;
    let mut off_at = None;
    let mut z_at_hold = 0.0;
    while t - last_beat < 250_000 {
        tick(&mut rt, &mut hw, &mut t, false);
        let since = t - last_beat;
        if held_at.is_none() && (rt.mode().kind() == ModeKind::Holding) {
            held_at = Some(since);
            z_at_hold = common::true_pose(&hw).t.z;
            assert!(rt.status().warnings.contains(Warnings::HEARTBEAT_LATE));
            let cmd = MasterToBoard::PoseTarget {
                timestamp_us: 2_000,
                position_m: p,
                rotation_vector_rad: r,
            };
            assert_eq!(rt.command(&cmd, t), Err(NackReason::InvalidState));
        }
        if faulted_at.is_none() && rt.state() == State::Fault {
            faulted_at = Some(since);
            assert_eq!(rt.status().fault.cause, FaultCause::HeartbeatTimeout);
            // Its value is the silence that raised it, in ms (what the operator reads).
            assert_eq!(rt.status().fault.value, (since / 1000) as f32);
            assert!(hw.enabled, "SS1: the drives hold while the brakes engage");
        }
        if braked_at.is_none() && faulted_at.is_some() && !hw.brakes_released {
            braked_at = Some(since);
            assert!(hw.enabled);
        }
        if off_at.is_none() && braked_at.is_some() && !hw.enabled {
            off_at = Some(since);
            assert_eq!(rt.status().stop, StopStatus::SafeStop1Done);
        }
    }
    assert_eq!(held_at, Some(HB.hold_after_us));
    assert_eq!(faulted_at, Some(HB.disable_after_us));
    let (braked, off) = (braked_at.unwrap(), off_at.unwrap());
    assert!(braked <= HB.disable_after_us + 2_000, "brakes at {braked}");
    // The first tick strictly after the brakes' engage time.
    assert_eq!(off - braked, rt.config().stops.brake_engage_us + 1000);
    let z_end = common::true_pose(&hw).t.z;
    assert!((z_end - z_at_hold).abs() < 0.5e-3, "{z_at_hold} -> {z_end}");
    assert!(z_end < 0.165 - 1e-3, "did not carry on to the target");
    assert!(rt.homed());
    // Heartbeats again: clear, then the master enables again.
    rt.command(&MasterToBoard::Heartbeat, t).unwrap();
    rt.command(&MasterToBoard::ClearFault, t).unwrap();
    assert_eq!(rt.state(), State::Ready);
    rt.command(&MasterToBoard::Enable, t).unwrap();
    assert_eq!(rt.state(), State::Enabling);
}

#[test]
fn heartbeat_hold_ends_with_a_heartbeat() {
    let (mut rt, mut hw, mut t) = enabled();
    for _ in 0..40 {
        tick(&mut rt, &mut hw, &mut t, false);
    }
    assert!((rt.mode().kind() == ModeKind::Holding && rt.session().hold().heartbeat));
    assert_eq!(rt.status().stop, StopStatus::SafeOperatingStop);
    rt.command(&MasterToBoard::Heartbeat, t).unwrap();
    assert!((rt.mode().kind() == ModeKind::Following));
    tick(&mut rt, &mut hw, &mut t, true);
    assert_eq!(rt.state(), State::Enabled);
    assert_eq!(rt.status().stop, StopStatus::None);
    assert!(hw.enabled && hw.brakes_released);
}

// ---------------------------------------------------------------------------------------
// Emergency stop
// ---------------------------------------------------------------------------------------

/// Fake output registers.
#[derive(Default)]
struct Regs {
    pwm_on: bool,
    driver_enable: bool,
    brake_coils: bool,
    forced: u32,
}

impl SafeOutputs for Regs {
    fn force_safe(&mut self) {
        self.pwm_on = false;
        self.driver_enable = false;
        self.brake_coils = false;
        self.forced += 1;
    }
}

static LATCH: EStopLatch = EStopLatch::new();

/// Property: from every state, the e-stop interrupt puts the outputs in their safe state
/// at once (PWM off, driver enable low, brakes applied) and the next tick latches
/// `EmergencyStopButton` with STO: the drives off and the brakes applied in that tick.
#[test]
fn emergency_stop_from_every_state() {
    for (state, rt, mut hw, t) in snapshots() {
        let mut regs = Regs {
            pwm_on: true,
            driver_enable: true,
            brake_coils: true,
            forced: 0,
        };
        let latch = EStopLatch::new();
        emergency_stop_isr(&mut regs, &latch);
        assert!(!regs.pwm_on && !regs.driver_enable && !regs.brake_coils && regs.forced == 1);
        assert!(latch.is_tripped());
        let cfg = service_config();
        let mut svc = TickService::new(rt, cfg);
        svc.begin(t + 1000, 0, latch.take());
        assert_eq!(latch.take(), control::estop::EStopTrip::NONE, "taken once");
        svc.tick(&mut hw, t + 1000);
        let rt = svc.runtime();
        assert_eq!(rt.state(), State::Fault, "from {state:?}");
        assert!(!hw.enabled && !hw.brakes_released, "from {state:?}");
        assert!(rt.status().faults.contains(Faults::EMERGENCY_STOP));
        let st = rt.status();
        assert_eq!(st.stop, StopStatus::SafeTorqueOff, "from {state:?}");
        // The status reports the first fault since the last clear; the log has them all.
        if state != State::Fault {
            assert_eq!(st.fault.cause, FaultCause::EmergencyStopButton);
        }
        let newest = rt.fault_log().newest().unwrap();
        assert_eq!(newest.record.cause, FaultCause::EmergencyStopButton);
        assert_eq!(newest.stop, StopStatus::SafeTorqueOff);
        // The message path too.
        let mut rt2 = rt.clone();
        assert_eq!(
            rt2.command(&MasterToBoard::EmergencyStop, t),
            Ok(control::link::Answer::Ack)
        );
        assert_eq!(rt2.state(), State::Fault);
    }
    LATCH.trip();
    LATCH.trip();
    assert_eq!(LATCH.take(), control::estop::EStopTrip::BUTTON);
    assert_eq!(LATCH.count(), 2);
    // The message's trip is told apart from the button's.
    LATCH.trip_message();
    assert!(LATCH.is_tripped());
    assert_eq!(
        LATCH.take(),
        control::estop::EStopTrip {
            button: false,
            message: true
        }
    );
}

/// Property: after the e-stop path forced the outputs safe behind the runtime's back, a
/// `ClearFault` and an `Enable` answered in the tick that latched the stop are refused
/// (sent before the master could know of the stop, they do not end it); sent again after
/// that tick, the fault is cleared and the enable switches the bridges on again: the
/// runtime never drives disabled bridges nor releases the brakes without torque (fuzz
/// finding 3, `fuzz/regressions/commands-finding-3-*`).
#[test]
fn the_estop_path_forcing_outputs_safe_is_seen_by_the_next_enable() {
    use hal::{Brakes, MotorOutputs};
    let (rt, mut hw, t) = enabled();
    assert!(hw.enabled);
    let cfg = service_config();
    let mut svc = TickService::new(rt, cfg);
    // What `SafeOutputs::force_safe` does to the board: bridges off, brakes applied.
    let latch = EStopLatch::new();
    MotorOutputs::disable(&mut hw);
    Brakes::set_brakes_released(&mut hw, false);
    latch.trip_message();
    let now = t + 1000;
    svc.begin(now, 0, latch.take());
    let rt = svc.runtime_mut();
    assert_eq!(rt.state(), State::Fault);
    rt.command(&MasterToBoard::Heartbeat, now).unwrap();
    assert_eq!(
        rt.command(&MasterToBoard::ClearFault, now),
        Err(NackReason::Busy),
        "a ClearFault in the tick that latched the stop"
    );
    assert_eq!(
        rt.command(&MasterToBoard::Enable, now),
        Err(NackReason::Faulted)
    );
    let out = svc.tick(&mut hw, now);
    assert!(!out.drives_on && !hw.enabled && !hw.brakes_released);
    hw.step_ms();
    let now = now + 1000;
    svc.begin(now, 0, latch.take());
    let rt = svc.runtime_mut();
    rt.command(&MasterToBoard::Heartbeat, now).unwrap();
    rt.command(&MasterToBoard::ClearFault, now).unwrap();
    rt.command(&MasterToBoard::Enable, now).unwrap();
    let mut now = now;
    // The brakes' engage and settle wait, the check's two 40 ms pushes, the 60 ms release.
    for _ in 0..400 {
        let out = svc.tick(&mut hw, now);
        assert_eq!(
            out.drives_on, hw.enabled,
            "the runtime's torque flag and the bridges agree ({:?})",
            out.state
        );
        assert!(
            !hw.brakes_released || hw.enabled,
            "brakes released without torque"
        );
        hw.step_ms();
        now += 1000;
        svc.runtime_mut()
            .command(&MasterToBoard::Heartbeat, now)
            .unwrap();
        svc.begin(now, 0, latch.take());
    }
    let st = svc.runtime().status();
    assert_eq!(svc.runtime().state(), State::Enabled, "{:?}", st.fault);
    assert!(st.faults.is_empty(), "{:?}", st.faults);
}

/// Property (SR-3): the commands answered in the tick whose start latched an emergency
/// stop were sent before their master could know of the stop, and none ends it: from
/// every state, the button's latch (the button released again before the tick) with
/// `ClearFault`, `Home { rehome }`, `Enable` and `Commission { confirm }` queued, each is
/// refused and the tick ends in `Fault` with STO, the drives off and the brakes applied;
/// from `Enabled`, the `ClearFault` of the next tick is taken (the robot `Ready`).
#[test]
fn no_command_of_the_tick_that_latched_an_emergency_stop_ends_it() {
    use hal::{Brakes, MotorOutputs};
    for (state, rt, mut hw, t) in snapshots() {
        if state == State::Boot {
            continue;
        }
        let cfg = service_config();
        let mut svc = TickService::new(rt, cfg);
        // The ISR: bridges off, brakes applied, the latch tripped.
        let latch = EStopLatch::new();
        MotorOutputs::disable(&mut hw);
        Brakes::set_brakes_released(&mut hw, false);
        latch.trip();
        let now = t + 1000;
        svc.begin(now, 0, latch.take());
        for msg in [
            MasterToBoard::Heartbeat,
            MasterToBoard::ClearFault,
            MasterToBoard::Home { rehome: true },
            MasterToBoard::Enable,
            MasterToBoard::Commission {
                joint: 0,
                confirm: true,
            },
        ] {
            let r = svc.runtime_mut().command(&msg, now);
            let refused = msg == MasterToBoard::Heartbeat || r.is_err();
            assert!(refused, "{msg:?} from {state:?}: {r:?}");
        }
        svc.tick(&mut hw, now);
        let st = svc.runtime().status();
        assert_eq!(st.state, State::Fault, "from {state:?}");
        assert_eq!(st.stop, StopStatus::SafeTorqueOff, "from {state:?}");
        assert!(!hw.enabled && !hw.brakes_released, "from {state:?}");
        if state == State::Enabled {
            hw.step_ms();
            let now = now + 1000;
            svc.begin(now, 0, latch.take());
            let rt = svc.runtime_mut();
            rt.command(&MasterToBoard::Heartbeat, now).unwrap();
            assert_eq!(
                rt.command(&MasterToBoard::ClearFault, now),
                Ok(control::link::Answer::Ack),
                "the next tick's ClearFault"
            );
            assert_eq!(rt.state(), State::Ready);
        }
    }
}

/// Property: the button's hard-wired channel stops the robot without the MCU (the relay
/// removes the drivers' power and the brakes' coil power while no tick runs); the MCU
/// latches `EmergencyStopButton`, refuses to clear while the button is pressed, and once it
/// is released clears to Ready (the homing is kept) and enables again.
#[test]
fn the_hard_wired_estop_stops_without_the_mcu_and_blocks_clearing() {
    let (mut rt, mut hw, mut t) = enabled();
    hw.press_estop(true);
    // No tick: the relay alone.
    assert_eq!(hw.plant.bridges_on(), [false; 6]);
    hw.step_ms();
    for _ in 0..20 {
        hw.step_ms();
    }
    assert_eq!(hw.plant.brakes_holding(), [true; 6]);
    // The MCU sees the button.
    tick(&mut rt, &mut hw, &mut t, true);
    assert_eq!(rt.state(), State::Fault);
    assert_eq!(rt.status().fault.cause, FaultCause::EmergencyStopButton);
    assert!(!hw.enabled && !hw.brakes_released);
    assert_eq!(
        rt.command(&MasterToBoard::ClearFault, t),
        Err(NackReason::FaultStillActive)
    );
    assert_eq!(
        rt.command(&MasterToBoard::Enable, t),
        Err(NackReason::Faulted)
    );
    hw.press_estop(false);
    tick(&mut rt, &mut hw, &mut t, true);
    rt.command(&MasterToBoard::ClearFault, t).unwrap();
    assert_eq!(rt.state(), State::Ready);
    assert!(rt.status().faults.is_empty());
    rt.command(&MasterToBoard::Enable, t).unwrap();
    assert_eq!(rt.state(), State::Enabling);
}

/// Property: the button and the relay's feedback must agree within the debounce time: a
/// welded relay (button pressed, relay closed) and a relay open without the button both
/// latch `SafetyRelayMismatch` with the case in its value (1, 2), and an enable is refused
/// while they disagree.
#[test]
fn a_safety_relay_that_disagrees_with_the_button_is_a_fault() {
    // Welded: the button is pressed, the relay stays closed.
    let (mut rt, mut hw, mut t) = enabled();
    hw.relay_welded = true;
    hw.press_estop(true);
    let debounce = rt.config().relay_debounce_ticks;
    for _ in 0..=debounce {
        tick(&mut rt, &mut hw, &mut t, true);
    }
    let log = rt.fault_log();
    let causes: Vec<_> = (0..log.len()).map(|i| log.get(i).unwrap().record).collect();
    assert_eq!(causes[0].cause, FaultCause::EmergencyStopButton);
    let mismatch = causes
        .iter()
        .find(|r| r.cause == FaultCause::SafetyRelayMismatch)
        .expect("mismatch logged");
    assert_eq!(mismatch.value, 1.0);
    // Open without the button (a failed relay or a cut wire): enable refused, then fault.
    let (_, mut rt, mut hw, mut t) = snapshots().remove(3);
    assert_eq!(rt.state(), State::Ready);
    hw.relay_stuck_open = true;
    tick(&mut rt, &mut hw, &mut t, true);
    assert_eq!(
        rt.command(&MasterToBoard::Enable, t),
        Err(NackReason::SafetyRelayMismatch)
    );
    for _ in 0..=debounce {
        tick(&mut rt, &mut hw, &mut t, true);
    }
    assert_eq!(rt.state(), State::Fault);
    assert_eq!(rt.status().fault.cause, FaultCause::SafetyRelayMismatch);
    assert_eq!(rt.status().fault.value, 2.0);
    assert_eq!(
        rt.command(&MasterToBoard::ClearFault, t),
        Err(NackReason::FaultStillActive)
    );
}

// ---------------------------------------------------------------------------------------
// Any fault: its stop
// ---------------------------------------------------------------------------------------

/// Property: a stuck encoder is found (a dead encoder or the following error, with its
/// joint), its stop is STO: the drives off and the brakes applied in the tick it is
/// found; the homing is lost.
#[test]
fn a_stuck_encoder_stops_with_sto_and_brakes() {
    let (mut rt, mut hw, mut t) = enabled();
    hw.plant.inject(0, plant::Fault::EncoderStuck).unwrap();
    let (p, r) = control::wire::pose_to_wire(&Pose {
        t: nalgebra::Vector3::new(0.0, 0.0, 0.170),
        r: nalgebra::Rotation3::identity(),
    });
    rt.command(
        &MasterToBoard::PoseTarget {
            timestamp_us: 10,
            position_m: p,
            rotation_vector_rad: r,
        },
        t,
    )
    .unwrap();
    let mut faulted = None;
    for k in 0..2000 {
        tick(&mut rt, &mut hw, &mut t, true);
        if rt.state() == State::Fault {
            faulted.get_or_insert(k);
            assert!(!hw.enabled && !hw.brakes_released);
        }
    }
    let k = faulted.expect("found");
    let st = rt.status();
    println!("stuck encoder: {:?} after {k} ms", st.fault);
    assert!(
        matches!(
            st.fault.cause,
            FaultCause::EncoderDead | FaultCause::FollowingError
        ),
        "{:?}",
        st.fault
    );
    assert_eq!(st.fault.joint, 0);
    assert_eq!(st.stop, StopStatus::SafeTorqueOff);
    // The homing is lost: clearing goes to Disabled.
    rt.command(&MasterToBoard::ClearFault, t).unwrap();
    assert_eq!(rt.state(), State::Disabled);
    assert!(rt.status().warnings.contains(Warnings::NOT_HOMED));
}

/// Property: outside homing, enabling and enabled, once any stop is complete, the drives
/// are off and the brakes applied on every tick (SR-4).
#[test]
fn outputs_stay_off_outside_the_driving_states() {
    for (state, mut rt, mut hw, mut t) in snapshots() {
        for _ in 0..100 {
            tick(&mut rt, &mut hw, &mut t, true);
        }
        let drives = matches!(rt.state(), State::Homing | State::Enabling | State::Enabled);
        assert_eq!(hw.enabled, drives, "{state:?}");
        if !drives {
            assert!(!hw.brakes_released, "{state:?}");
        }
    }
}

// ---------------------------------------------------------------------------------------
// Deadlines, resets, the fault log
// ---------------------------------------------------------------------------------------

/// Property: a tick late by more than a quarter period, or the third overrun within 100
/// ticks, latches `DeadlineMissed` (its value: µs late or run) with STO, and the watchdog
/// is never fed again (it resets the board).
#[test]
fn a_missed_deadline_is_a_fault_and_starves_the_watchdog() {
    let cfg = service_config();
    let cycles = |us: u32| us * 168;
    // Late start.
    let (rt, mut hw, t0) = enabled();
    let mut svc = TickService::new(rt, cfg);
    let mut t = t0;
    for _ in 0..5 {
        t += 1000;
        svc.runtime_mut()
            .command(&MasterToBoard::Heartbeat, t)
            .unwrap();
        svc.begin(t, 0, control::estop::EStopTrip::NONE);
        svc.tick(&mut hw, t);
        assert!(svc.finish(t, cycles(300)).feed_watchdog);
        hw.step_ms();
    }
    t += 1000 + 300;
    svc.begin(t, 0, control::estop::EStopTrip::NONE);
    svc.tick(&mut hw, t);
    let out = svc.finish(t, cycles(300));
    assert!(!out.feed_watchdog && svc.starved());
    assert_eq!(out.status.fault.cause, FaultCause::DeadlineMissed);
    assert_eq!(out.status.fault.value, 300.0);
    assert_eq!(out.status.stop, StopStatus::SafeTorqueOff);
    assert!(!hw.enabled && !hw.brakes_released);
    for _ in 0..10 {
        t += 1000;
        svc.begin(t, 0, control::estop::EStopTrip::NONE);
        svc.tick(&mut hw, t);
        assert!(
            !svc.finish(t, cycles(300)).feed_watchdog,
            "starved for good"
        );
    }
    // Overruns: two are tolerated, the third within the window is not.
    let (rt, mut hw, t0) = enabled();
    let mut svc = TickService::new(rt, cfg);
    let mut t = t0;
    for k in 0..3 {
        t += 1000;
        svc.runtime_mut()
            .command(&MasterToBoard::Heartbeat, t)
            .unwrap();
        svc.begin(t, 0, control::estop::EStopTrip::NONE);
        svc.tick(&mut hw, t);
        let out = svc.finish(t, cycles(900));
        hw.step_ms();
        if k < 2 {
            assert_eq!(out.status.fault.cause, FaultCause::None);
        } else {
            assert_eq!(out.status.fault.cause, FaultCause::DeadlineMissed);
            assert_eq!(out.status.fault.value, 900.0);
            assert!(!out.feed_watchdog);
        }
    }
}

/// Property: the overruns are counted in a sliding window: three overruns within any 100
/// consecutive ticks latch `DeadlineMissed`, wherever the ticks start counting (three in a
/// row from the 99th tick on, found by the search: a window that restarts every 100 ticks
/// split them two and one and never latched), and three spread over more than 100 ticks
/// do not (SR-5: a missed deadline detected within its 3 ticks).
#[test]
fn overruns_are_counted_in_a_sliding_window() {
    let cfg = service_config();
    let cycles = |us: u32| us * (PROFILE.cpu_hz / 1_000_000);
    let run = |overrun_at: &[u32], ticks: u32| -> Option<u32> {
        let (rt, mut hw, t0) = enabled();
        let mut svc = TickService::new(rt, cfg);
        let mut t = t0;
        for k in 0..ticks {
            t += 1000;
            svc.runtime_mut()
                .command(&MasterToBoard::Heartbeat, t)
                .unwrap();
            svc.begin(t, 0, control::estop::EStopTrip::NONE);
            svc.tick(&mut hw, t);
            let exec = if overrun_at.contains(&k) { 900 } else { 300 };
            let out = svc.finish(t, cycles(exec));
            hw.step_ms();
            if out.status.fault.cause == FaultCause::DeadlineMissed {
                return Some(k);
            }
        }
        None
    };
    for start in [0, 97, 98, 99, 100, 150, 199] {
        assert_eq!(
            run(&[start, start + 1, start + 2], start + 10),
            Some(start + 2),
            "three overruns in a row from tick {start}"
        );
    }
    assert_eq!(
        run(&[10, 60, 109], 120),
        Some(109),
        "three within 100 ticks"
    );
    assert_eq!(run(&[10, 60, 110], 120), None, "spread over 101 ticks");
}

/// Property: the fault log survives a reset in RAM the start-up code does not clear: what
/// `persist` wrote, `restore` gives back entry for entry; garbage and a corrupted word are
/// refused; a runtime booted with the log reports it and the reset cause.
#[test]
fn the_fault_log_survives_a_watchdog_reset() {
    let (mut rt, mut hw, mut t) = enabled();
    rt.fault(Finding::joint(FaultCause::Overload, 4, 0.61f64), t);
    tick(&mut rt, &mut hw, &mut t, true);
    rt.fault(Finding::board(FaultCause::DeadlineMissed, 412.0f64), t);
    let mut words = Persisted::ZERO;
    rt.fault_log().persist(&mut words);
    let log = FaultLog::restore(&words).expect("valid");
    assert_eq!(&log, rt.fault_log());
    assert_eq!(FaultLog::restore(&Persisted::ZERO), None);
    let mut bad = words;
    bad.entries[0][1] ^= 1 << 7;
    assert_eq!(FaultLog::restore(&bad), None);
    // Boot after the watchdog reset.
    let (hw2, _, cfg) = common::homing_fixture([0.16, 0.161, 0.159], [0.2; 3]);
    let mut rt2 = Rt::new(RsprGeometry::reference(), cfg, 0).unwrap();
    let mut hw2 = hw2;
    rt2.boot_done(hw2.counts(), 0, ResetCause::Watchdog, Some(log))
        .unwrap();
    let st = rt2.status();
    assert_eq!(st.fault_log_len, 2);
    assert_eq!(st.reset.cause, ResetCause::Watchdog);
    assert!(!st.reset.acknowledged);
    let page = rt2.fault_log_page(0);
    assert_eq!(page.entries[0].record.cause, FaultCause::Overload);
    assert_eq!(page.entries[0].record.joint, 4);
    assert_eq!(page.entries[1].record.cause, FaultCause::DeadlineMissed);
}

// ---------------------------------------------------------------------------------------
// Watchdog
// ---------------------------------------------------------------------------------------

#[test]
fn watchdog_is_fed_only_for_ticks_on_time() {
    let cfg = WatchdogConfig {
        period_us: PROFILE.control_period_us,
        max_lateness_us: 200,
        max_execution_us: 700,
    };
    let mut w = WatchdogPolicy::new(cfg);
    assert!(!w.should_feed(0), "nothing before the first tick");
    let mut t = 10_000;
    for _ in 0..10 {
        assert_eq!(w.on_tick(t, 300), FeedDecision::Feed);
        assert!(w.should_feed(t + 500));
        t += 1000;
    }
    // Jitter within the tolerance is fed.
    assert!(w.on_tick(t + 150, 300).feed());
    t += 1000;
    // A late tick (interval 1000 + 150 + 250 over the period) is not.
    assert_eq!(w.on_tick(t + 400, 300), FeedDecision::Late(250));
    assert!(!w.should_feed(t + 450));
    t += 1000;
    // An overrun is not.
    assert_eq!(w.on_tick(t + 400, 900), FeedDecision::Overrun(900));
    t += 1000;
    // Back on schedule.
    assert!(w.on_tick(t + 400, 300).feed());
    // A missing tick: the deadline passes, nothing feeds.
    assert!(w.should_feed(t + 400 + 1200));
    assert!(!w.should_feed(t + 400 + 1201));
    assert!(!w.should_feed(t + 400 + 50_000));
    assert_eq!(w.worst_execution_us(), 900);
    assert_eq!(w.worst_lateness_us(), 250);
    assert_eq!((w.fed(), w.withheld()), (12, 2));
}

#[test]
fn tick_timing_keeps_the_worst_case() {
    let mut tt = TickTiming::default();
    tt.record(3, 1000);
    tt.record(12, 500);
    tt.record(1, 84_000);
    assert_eq!(tt.worst_jitter_us, 12);
    assert_eq!(tt.worst_cycles, 84_000);
    assert_eq!(tt.last_cycles, 84_000);
    assert_eq!(TickTiming::cycles_to_us(84_000, 84_000_000), 1000);
}
