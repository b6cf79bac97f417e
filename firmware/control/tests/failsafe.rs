#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::needless_range_loop
)]
//! The fail-safe rules: heartbeat hold then disable at the configured times, the
//! emergency stop from every state (interrupt path and input level), any fault forcing the
//! outputs off, and the watchdog feeding policy.

use control::estop::{emergency_stop_isr, outputs_allowed, EStopLatch};
use control::heartbeat::{HeartbeatConfig, HeartbeatLevel, HeartbeatMonitor};
use control::link::Command;
use control::runtime::Runtime;
use control::state_machine::{Event, State};
use control::watchdog::{FeedDecision, TickTiming, WatchdogConfig, WatchdogPolicy};
use hal::{QuadratureCounter, SafeOutputs};
use kinematics_core::{Pose, RsprGeometry};
use master_link::{Faults, NackReason, Warnings};

mod common;
use common::PlantHw;

// ---------------------------------------------------------------------------------------
// Fixture: the runtime on the plant model
// ---------------------------------------------------------------------------------------

type Rt = Runtime<f64, RsprGeometry<f64>>;

/// Heartbeat times of these tests: hold after 30 ms, disable after 120 ms.
const HB: HeartbeatConfig = HeartbeatConfig {
    hold_after_us: 30_000,
    disable_after_us: 120_000,
};

/// A runtime and plant in each state: Boot, Disabled, Homing, Ready, Enabled, Fault.
fn snapshots() -> Vec<(State, Rt, PlantHw, u64)> {
    let g = RsprGeometry::<f64>::reference();
    // The plant with home switches on the legs and hard stops on the links.
    let (mut hw, _, mut cfg) = common::homing_fixture([0.16, 0.161, 0.159], [0.2; 3]);
    cfg.heartbeat = HB;
    let mut rt = Rt::new(g, cfg, 0).unwrap();
    let mut out = vec![(State::Boot, rt.clone(), hw.clone(), 0)];
    let mut t = 0;
    rt.boot_done(hw.counts(), t).unwrap();
    out.push((State::Disabled, rt.clone(), hw.clone(), t));
    rt.command(&Command::Home, t).unwrap();
    for _ in 0..50 {
        t += 1000;
        rt.command(&Command::Heartbeat, t).unwrap();
        rt.tick(&mut hw, t);
        hw.step_ms();
    }
    assert_eq!(rt.state(), State::Homing);
    out.push((State::Homing, rt.clone(), hw.clone(), t));
    while rt.state() == State::Homing {
        t += 1000;
        rt.command(&Command::Heartbeat, t).unwrap();
        rt.tick(&mut hw, t);
        hw.step_ms();
        assert!(t < 60_000_000);
    }
    assert_eq!(rt.state(), State::Ready);
    out.push((State::Ready, rt.clone(), hw.clone(), t));
    rt.command(&Command::Enable, t).unwrap();
    t += 1000;
    rt.command(&Command::Heartbeat, t).unwrap();
    rt.tick(&mut hw, t);
    hw.step_ms();
    assert_eq!(rt.state(), State::Enabled);
    out.push((State::Enabled, rt.clone(), hw.clone(), t));
    rt.event(Event::Fault(Faults::OVERCURRENT), t).unwrap();
    out.push((State::Fault, rt, hw, t));
    out
}

fn enabled() -> (Rt, PlantHw, u64) {
    let (_, rt, hw, t) = snapshots().remove(4);
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
    assert_eq!(m.poll(1_000 + 30_000), Some(Event::HeartbeatLost));
    assert_eq!(m.poll(1_000 + 31_000), None, "once");
    assert_eq!(m.level(), HeartbeatLevel::Late);
    assert_eq!(m.poll(1_000 + 119_999), None);
    assert_eq!(m.poll(1_000 + 120_000), Some(Event::HeartbeatLostLong));
    assert_eq!(m.poll(1_000 + 500_000), None, "once");
    assert_eq!(m.beat(700_000), Some(Event::HeartbeatRestored));
    assert_eq!(m.beat(701_000), None);
    assert_eq!(m.level(), HeartbeatLevel::Alive);
    // A silence seen only after the disable time jumps straight to the disable.
    assert_eq!(m.poll(701_000 + 200_000), Some(Event::HeartbeatLostLong));
    assert_eq!((m.holds(), m.losses(), m.beats()), (1, 2, 2));
}

#[test]
fn heartbeat_loss_holds_then_disables_the_robot() {
    let (mut rt, mut hw, mut t) = enabled();
    let last_beat = t;
    let target = Pose {
        t: nalgebra::Vector3::new(0.0, 0.0, 0.165),
        r: nalgebra::Rotation3::identity(),
    };
    let (p, r) = control::wire::pose_to_wire(&target);
    rt.command(
        &Command::Target {
            stamp_us: 1_000,
            position_m: p,
            rotation_vector_rad: r,
        },
        t,
    )
    .unwrap();
    let mut held_at = None;
    let mut disabled_at = None;
    let mut z_at_hold = 0.0;
    while t - last_beat < 200_000 {
        t += 1000;
        rt.tick(&mut hw, t);
        hw.step_ms();
        let m = rt.machine();
        if held_at.is_none() && m.hold().is_some() {
            held_at = Some(t - last_beat);
            z_at_hold = rt.measured().pose.unwrap().t.z;
            assert!(rt.status().warnings.contains(Warnings::HEARTBEAT_LATE));
            // Targets are refused while holding.
            let cmd = Command::Target {
                stamp_us: 2_000,
                position_m: p,
                rotation_vector_rad: r,
            };
            assert_eq!(rt.command(&cmd, t), Err(NackReason::InvalidState));
        }
        if disabled_at.is_none() && rt.state() == State::Ready {
            disabled_at = Some(t - last_beat);
            assert!(!hw.enabled, "drives off at the disable");
        }
    }
    assert_eq!(held_at, Some(HB.hold_after_us));
    assert_eq!(disabled_at, Some(HB.disable_after_us));
    // It was moving up when the hold began, and stopped within a few tenths of a mm.
    let z_end = rt.measured().pose.unwrap().t.z;
    assert!((z_end - z_at_hold).abs() < 0.5e-3, "{z_at_hold} -> {z_end}");
    assert!(z_end < 0.165 - 1e-3, "did not carry on to the target");
    assert!(rt.machine().homed());
    // Heartbeats again: the master must enable again.
    rt.command(&Command::Heartbeat, t).unwrap();
    assert_eq!(rt.state(), State::Ready);
    rt.command(&Command::Enable, t).unwrap();
    assert_eq!(rt.state(), State::Enabled);
}

#[test]
fn heartbeat_hold_ends_with_a_heartbeat() {
    let (mut rt, mut hw, mut t) = enabled();
    for _ in 0..40 {
        t += 1000;
        rt.tick(&mut hw, t);
        hw.step_ms();
    }
    assert!(rt.machine().hold().is_some_and(|h| h.heartbeat));
    rt.command(&Command::Heartbeat, t).unwrap();
    assert!(rt.machine().following());
    t += 1000;
    rt.tick(&mut hw, t);
    assert_eq!(rt.state(), State::Enabled);
    assert!(hw.enabled);
}

// ---------------------------------------------------------------------------------------
// Emergency stop
// ---------------------------------------------------------------------------------------

/// Fake output registers.
#[derive(Default)]
struct Regs {
    pwm_on: bool,
    driver_enable: bool,
    forced: u32,
}

impl SafeOutputs for Regs {
    fn force_safe(&mut self) {
        self.pwm_on = false;
        self.driver_enable = false;
        self.forced += 1;
    }
}

static LATCH: EStopLatch = EStopLatch::new();

#[test]
fn emergency_stop_from_every_state() {
    for (state, mut rt, mut hw, t) in snapshots() {
        // The interrupt: outputs off at once, latch tripped.
        let mut regs = Regs {
            pwm_on: true,
            driver_enable: true,
            forced: 0,
        };
        let latch = EStopLatch::new();
        emergency_stop_isr(&mut regs, &latch);
        assert!(!regs.pwm_on && !regs.driver_enable && regs.forced == 1);
        assert!(latch.is_tripped());
        // The next control tick takes the latch.
        assert!(latch.take());
        assert!(!latch.take(), "taken once");
        let tr = rt.event(Event::EmergencyStop, t).unwrap();
        assert_eq!(tr.to, State::Fault, "from {state:?}");
        rt.tick(&mut hw, t + 1000);
        assert!(!hw.enabled && hw.plant.duty() == [0.0; 6], "from {state:?}");
        assert!(rt.machine().faults().contains(Faults::EMERGENCY_STOP));
        assert_eq!(rt.status().state, master_link::RobotState::Fault);
        assert!(!outputs_allowed(rt.machine()));
        // The message path too.
        let mut rt2 = rt.clone();
        assert_eq!(rt2.command(&Command::EmergencyStop, t), Ok(()));
        assert_eq!(rt2.state(), State::Fault);
    }
    // The static latch of the board.
    LATCH.trip();
    LATCH.trip();
    assert!(LATCH.take());
    assert_eq!(LATCH.count(), 2);
}

#[test]
fn emergency_stop_input_blocks_clearing_until_released() {
    let (mut rt, mut hw, mut t) = enabled();
    rt.set_estop_input(true, t);
    assert_eq!(rt.state(), State::Fault);
    t += 1000;
    rt.tick(&mut hw, t);
    assert!(!hw.enabled);
    assert_eq!(
        rt.command(&Command::ClearFault, t),
        Err(NackReason::FaultStillActive)
    );
    assert_eq!(rt.command(&Command::Enable, t), Err(NackReason::Faulted));
    rt.set_estop_input(false, t);
    rt.command(&Command::ClearFault, t).unwrap();
    // The e-stop keeps the homing.
    assert_eq!(rt.state(), State::Ready);
    assert!(rt.status().faults.is_empty());
    rt.command(&Command::Enable, t).unwrap();
    assert_eq!(rt.state(), State::Enabled);
}

// ---------------------------------------------------------------------------------------
// Any fault: outputs safe
// ---------------------------------------------------------------------------------------

#[test]
fn a_tracking_fault_turns_every_output_off() {
    let (mut rt, mut hw, mut t) = enabled();
    hw.plant.inject(0, plant::Fault::EncoderStuck).unwrap();
    let (p, r) = control::wire::pose_to_wire(&Pose {
        t: nalgebra::Vector3::new(0.0, 0.0, 0.170),
        r: nalgebra::Rotation3::identity(),
    });
    rt.command(
        &Command::Target {
            stamp_us: 10,
            position_m: p,
            rotation_vector_rad: r,
        },
        t,
    )
    .unwrap();
    let mut faulted = None;
    for k in 0..2000 {
        t += 1000;
        rt.command(&Command::Heartbeat, t).unwrap();
        rt.tick(&mut hw, t);
        if rt.state() == State::Fault {
            faulted.get_or_insert(k);
            assert!(!hw.enabled && hw.plant.duty() == [0.0; 6]);
        }
        hw.step_ms();
    }
    assert!(faulted.is_some());
    let st = rt.status();
    assert!(
        st.faults.contains(Faults::FOLLOWING_ERROR),
        "{:?}",
        st.faults
    );
    // The homing is lost: clearing goes to Disabled.
    rt.command(&Command::ClearFault, t).unwrap();
    assert_eq!(rt.state(), State::Disabled);
    assert!(rt.status().warnings.contains(Warnings::NOT_HOMED));
}

#[test]
fn outputs_stay_off_outside_homing_and_enabled() {
    for (state, mut rt, mut hw, t) in snapshots() {
        hw.enabled = true;
        let before = hw.disables;
        rt.tick(&mut hw, t + 1000);
        let drives = matches!(rt.state(), State::Homing | State::Enabled);
        assert_eq!(hw.enabled, drives, "{state:?}");
        assert_eq!(outputs_allowed(rt.machine()), drives, "{state:?}");
        if !drives {
            assert!(hw.disables > before);
        }
    }
}

// ---------------------------------------------------------------------------------------
// Watchdog
// ---------------------------------------------------------------------------------------

#[test]
fn watchdog_is_fed_only_for_ticks_on_time() {
    let cfg = WatchdogConfig {
        period_us: 1000,
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
    assert_eq!(TickTiming::cycles_to_us(84_000, 168_000_000), 500);
}
