#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::needless_range_loop
)]
//! The state machine (every state x every event), the homing procedure (fake joints and
//! the plant model) and the runtime from boot to following a target.

use control::homing::{
    HomeMethod, Homing, HomingConfig, HomingError, HomingPhase, HomingStatus, JointHoming,
    JointReferences,
};
use control::link::Command;
use control::runtime::Runtime;
use control::state_machine::{next_state, Event, Refusal, State, StateMachine, ALL_STATES};
use control::Sensing;
use hal::{CurrentSense, LimitSwitches, MotorOutputs, QuadratureCounter};
use kinematics_core::{Branch, Pose, RsprGeometry};
use master_link::{Faults, NackReason};
use nalgebra::{Rotation3, Vector3};
use servo::encoder::{EncoderConfig, LEG_COUNTS_PER_M, LINK_COUNTS_PER_RAD};
use servo::ServoConfig;

mod common;
use common::PlantHw;

// ---------------------------------------------------------------------------------------
// The transition table
// ---------------------------------------------------------------------------------------

/// A machine in `state`; `Fault` reached from `Ready` (homed) or `Disabled` (not homed).
fn machine_in(state: State, homed: bool) -> StateMachine {
    let mut m = StateMachine::new();
    let path: &[Event] = match (state, homed) {
        (State::Boot, _) => &[],
        (State::Disabled, _) => &[Event::BootDone],
        (State::Homing, _) => &[Event::BootDone, Event::Home],
        (State::Ready, _) => &[Event::BootDone, Event::Home, Event::HomingDone],
        (State::Enabled, _) => &[
            Event::BootDone,
            Event::Home,
            Event::HomingDone,
            Event::Enable,
        ],
        (State::Fault, true) => &[
            Event::BootDone,
            Event::Home,
            Event::HomingDone,
            Event::EmergencyStop,
        ],
        (State::Fault, false) => &[Event::BootDone, Event::EmergencyStop],
    };
    for ev in path {
        m.handle(*ev).unwrap();
    }
    assert_eq!(m.state(), state);
    m
}

/// The expected table, written out independently of `next_state`. Columns: Boot,
/// Disabled, Homing, Ready, Enabled, Fault (homed), Fault (not homed). `=` keeps the
/// state, `!X` refuses with X.
const TABLE: [(&str, [&str; 7]); 16] = [
    (
        "BootDone",
        ["Dis", "!NA", "!NA", "!NA", "!NA", "!NA", "!NA"],
    ),
    (
        "Enable",
        [
            "!Boot",
            "!NotHomed",
            "!Busy",
            "Ena",
            "=",
            "!Faulted",
            "!Faulted",
        ],
    ),
    (
        "Disable",
        ["!Boot", "=", "Dis", "=", "Rdy", "!Faulted", "!Faulted"],
    ),
    (
        "Home",
        [
            "!Boot", "Hom", "!Busy", "Hom", "!NA", "!Faulted", "!Faulted",
        ],
    ),
    (
        "HomingDone",
        ["!Boot", "!NA", "Rdy", "!NA", "!NA", "!NA", "!NA"],
    ),
    (
        "HomingFailed",
        ["!Boot", "!NA", "Flt", "!NA", "!NA", "!NA", "!NA"],
    ),
    ("Clutch on", ["=", "=", "=", "=", "=", "=", "="]),
    ("Clutch off", ["=", "=", "=", "=", "=", "=", "="]),
    ("HeartbeatLost", ["=", "=", "=", "=", "=", "=", "="]),
    ("HeartbeatLostLong", ["=", "=", "Dis", "=", "Rdy", "=", "="]),
    ("HeartbeatRestored", ["=", "=", "=", "=", "=", "=", "="]),
    (
        "EmergencyStop",
        ["Flt", "Flt", "Flt", "Flt", "Flt", "Flt", "Flt"],
    ),
    (
        "TrackingFault",
        ["Flt", "Flt", "Flt", "Flt", "Flt", "Flt", "Flt"],
    ),
    ("Fault", ["Flt", "Flt", "Flt", "Flt", "Flt", "Flt", "Flt"]),
    ("ClearFault", ["!Boot", "=", "=", "=", "=", "Rdy", "Dis"]),
    (
        "ClearFault active",
        ["!Boot", "=", "=", "=", "=", "!StillActive", "!StillActive"],
    ),
];

fn parse(code: &str, state: State) -> Result<State, Refusal> {
    Ok(match code {
        "=" => state,
        "Dis" => State::Disabled,
        "Hom" => State::Homing,
        "Rdy" => State::Ready,
        "Ena" => State::Enabled,
        "Flt" => State::Fault,
        "!NA" => return Err(Refusal::NotAllowed),
        "!Boot" => return Err(Refusal::Booting),
        "!NotHomed" => return Err(Refusal::NotHomed),
        "!Busy" => return Err(Refusal::Busy),
        "!Faulted" => return Err(Refusal::Faulted),
        "!StillActive" => return Err(Refusal::FaultStillActive),
        other => panic!("bad table code {other}"),
    })
}

#[test]
fn every_state_times_every_event() {
    let columns = [
        (State::Boot, false),
        (State::Disabled, false),
        (State::Homing, false),
        (State::Ready, true),
        (State::Enabled, true),
        (State::Fault, true),
        (State::Fault, false),
    ];
    let mut checked = 0;
    for ((name, row), event) in TABLE.iter().zip(Event::ALL) {
        for ((state, homed), code) in columns.iter().zip(row.iter()) {
            let expected = parse(code, *state);
            let mut m = machine_in(*state, *homed);
            let before = m;
            let got = m.handle(event);
            let ctx = format!("{name} in {state:?} (homed {homed})");
            match (expected, got) {
                (Ok(to), Ok(t)) => {
                    assert_eq!(t.to, to, "{ctx}");
                    assert_eq!(t.from, *state, "{ctx}");
                    assert_eq!(m.state(), to, "{ctx}");
                }
                (Err(r), Err(g)) => {
                    assert_eq!(g, r, "{ctx}");
                    // A refusal changes nothing but the refusal count.
                    assert_eq!(m.state(), before.state(), "{ctx}");
                    assert_eq!(m.faults(), before.faults(), "{ctx}");
                    assert_eq!(m.refusals(), before.refusals() + 1, "{ctx}");
                }
                (e, g) => panic!("{ctx}: expected {e:?}, got {g:?}"),
            }
            // The pure table agrees with the machine.
            assert_eq!(
                next_state(*state, event, *homed),
                got.map(|t| t.to),
                "{ctx}"
            );
            // Outputs: only homing and enabled may drive, never with a fault latched.
            assert_eq!(
                m.drives_on(),
                matches!(m.state(), State::Homing | State::Enabled),
                "{ctx}"
            );
            if m.state() == State::Fault {
                assert!(!m.faults().is_empty(), "{ctx}");
            } else {
                assert!(m.faults().is_empty(), "{ctx}");
            }
            checked += 1;
        }
    }
    assert_eq!(checked, 16 * 7);
    assert_eq!(ALL_STATES.len(), 6);
}

#[test]
fn refusals_map_to_nack_reasons() {
    let pairs = [
        (Refusal::Booting, NackReason::Busy),
        (Refusal::Busy, NackReason::Busy),
        (Refusal::NotHomed, NackReason::NotHomed),
        (Refusal::Faulted, NackReason::Faulted),
        (Refusal::FaultStillActive, NackReason::FaultStillActive),
        (Refusal::NotAllowed, NackReason::InvalidState),
        (Refusal::Holding, NackReason::InvalidState),
        (Refusal::UnsafeStart, NackReason::OutOfWorkspace),
    ];
    for (r, n) in pairs {
        assert_eq!(NackReason::from(r), n);
    }
}

#[test]
fn fault_bits_and_homing_validity() {
    // E-stop keeps the homing: clearing returns to Ready.
    let mut m = machine_in(State::Enabled, true);
    m.handle(Event::EmergencyStop).unwrap();
    assert_eq!(m.faults(), Faults::EMERGENCY_STOP);
    assert!(m.homed());
    m.handle(Event::Fault(Faults::OVERCURRENT)).unwrap();
    assert_eq!(m.faults(), Faults::EMERGENCY_STOP | Faults::OVERCURRENT);
    assert_eq!(
        m.handle(Event::ClearFault { cause_active: true }),
        Err(Refusal::FaultStillActive)
    );
    assert_eq!(m.state(), State::Fault);
    m.handle(Event::ClearFault {
        cause_active: false,
    })
    .unwrap();
    assert_eq!((m.state(), m.faults()), (State::Ready, Faults::NONE));
    // A tracking fault loses it: clearing returns to Disabled, enable needs homing.
    let mut m = machine_in(State::Enabled, true);
    m.handle(Event::TrackingFault).unwrap();
    assert_eq!(m.faults(), Faults::FOLLOWING_ERROR);
    assert!(!m.homed());
    m.handle(Event::ClearFault {
        cause_active: false,
    })
    .unwrap();
    assert_eq!(m.state(), State::Disabled);
    assert_eq!(m.handle(Event::Enable), Err(Refusal::NotHomed));
    // An empty fault set latches INTERNAL.
    let mut m = machine_in(State::Ready, true);
    m.handle(Event::Fault(Faults::NONE)).unwrap();
    assert_eq!(m.faults(), Faults::INTERNAL);
    // Homing failure.
    let mut m = machine_in(State::Homing, false);
    m.handle(Event::HomingFailed).unwrap();
    assert_eq!(m.faults(), Faults::HOMING_FAILED);
}

#[test]
fn clutch_and_heartbeat_hold_while_enabled() {
    let mut m = machine_in(State::Ready, true);
    // The pedal is remembered in any state; it only holds while enabled.
    m.handle(Event::Clutch { engaged: true }).unwrap();
    assert!(m.clutch_engaged());
    assert_eq!(m.hold(), None);
    m.handle(Event::Enable).unwrap();
    let h = m.hold().unwrap();
    assert!(h.clutch && !h.heartbeat);
    assert_eq!(m.target_gate(), Err(Refusal::Holding));
    m.handle(Event::Clutch { engaged: false }).unwrap();
    assert!(m.following());
    assert_eq!(m.target_gate(), Ok(()));
    // Heartbeat hold, ended by a heartbeat.
    m.handle(Event::HeartbeatLost).unwrap();
    assert!(m.hold().unwrap().heartbeat);
    assert_eq!(m.state(), State::Enabled);
    m.handle(Event::HeartbeatRestored).unwrap();
    assert!(m.following());
    // Hold then loss: drives off, homing kept.
    m.handle(Event::HeartbeatLost).unwrap();
    m.handle(Event::HeartbeatLostLong).unwrap();
    assert_eq!(m.state(), State::Ready);
    assert!(m.homed());
    assert_eq!(m.hold(), None);
    // Target gate per state.
    let gates = [
        (State::Boot, Err(Refusal::Booting)),
        (State::Disabled, Err(Refusal::NotHomed)),
        (State::Homing, Err(Refusal::Busy)),
        (State::Ready, Err(Refusal::NotAllowed)),
        (State::Enabled, Ok(())),
        (State::Fault, Err(Refusal::Faulted)),
    ];
    for (s, g) in gates {
        assert_eq!(machine_in(s, true).target_gate(), g, "{s:?}");
    }
}

// ---------------------------------------------------------------------------------------
// Homing against fake joints
// ---------------------------------------------------------------------------------------

/// Six ideal joints: velocity = duty x vmax, switches and hard stops below given positions.
#[derive(Clone)]
struct Fake {
    q: [f64; 6],
    vmax: [f64; 6],
    cpu: [f64; 6],
    switch_below: [Option<f64>; 6],
    stop_below: [Option<f64>; 6],
    duty: [f64; 6],
    enabled: bool,
    blocked: [bool; 6],
    stuck_switch: bool,
    /// A compliant stop: the joint still creeps into it at this fraction of its speed.
    creep: f64,
}

impl Fake {
    fn new(q: [f64; 6]) -> Self {
        Fake {
            q,
            vmax: [0.4, 0.4, 0.4, 28.0, 28.0, 28.0],
            cpu: [
                LEG_COUNTS_PER_M,
                LEG_COUNTS_PER_M,
                LEG_COUNTS_PER_M,
                LINK_COUNTS_PER_RAD,
                LINK_COUNTS_PER_RAD,
                LINK_COUNTS_PER_RAD,
            ],
            switch_below: [None; 6],
            stop_below: [None; 6],
            duty: [0.0; 6],
            enabled: false,
            blocked: [false; 6],
            stuck_switch: false,
            creep: 0.0,
        }
    }
    fn advance(&mut self, dt: f64) {
        for j in 0..6 {
            let d = if self.enabled { self.duty[j] } else { 0.0 };
            let mut nq = self.q[j] + d * self.vmax[j] * dt;
            self.blocked[j] = false;
            if let Some(s) = self.stop_below[j] {
                if nq < s {
                    let crept = self.q[j] + d * self.vmax[j] * dt * self.creep;
                    nq = crept.max(s - 0.01).min(s);
                    self.blocked[j] = d < 0.0;
                }
            }
            self.q[j] = nq;
        }
    }
}

impl QuadratureCounter for Fake {
    fn counts(&mut self) -> [u16; 6] {
        std::array::from_fn(|j| (self.q[j] * self.cpu[j]).round() as i64 as u16)
    }
}
impl MotorOutputs<f64> for Fake {
    fn set_duties(&mut self, duty: &[f64; 6]) {
        self.duty = duty.map(|d| d.clamp(-1.0, 1.0));
    }
    fn disable(&mut self) {
        self.enabled = false;
        self.duty = [0.0; 6];
    }
    fn enable(&mut self) {
        self.enabled = true;
    }
}
impl LimitSwitches for Fake {
    fn switches(&mut self) -> [bool; 6] {
        std::array::from_fn(|j| {
            self.stuck_switch || self.switch_below[j].is_some_and(|s| self.q[j] <= s)
        })
    }
}
impl CurrentSense<f64> for Fake {
    fn currents(&mut self) -> [f64; 6] {
        std::array::from_fn(|j| {
            let d = if self.enabled { self.duty[j] } else { 0.0 };
            if self.blocked[j] {
                d * 12.0
            } else {
                d * 0.5
            }
        })
    }
}

fn test_homing_config() -> HomingConfig<f64> {
    let mut c = HomingConfig::reference([0.0; 3], None);
    for j in 3..6 {
        c.joints[j].home_position = -1.0;
    }
    c.stall_time_us = 50_000;
    c.phase_timeout_us = 20_000_000;
    c
}

type Sense = Sensing<f64, RsprGeometry<f64>>;

/// The runtime's sensing on `hw`: its counters as they are now read count 0.
fn sensing(hw: &mut impl QuadratureCounter) -> Sense {
    let mut s = Sensing::new(
        RsprGeometry::reference(),
        Branch::OUTER,
        &EncoderConfig::default(),
        Default::default(),
    )
    .unwrap();
    s.boot(hw.counts());
    s
}

/// One homing step as the runtime runs it: the sensing reads the encoders first.
fn step(h: &mut Homing<f64>, hw: &mut Fake, s: &mut Sense, t: u64) -> HomingStatus {
    s.update(hw);
    h.step(hw, s, t)
}

fn run_homing(
    h: &mut Homing<f64>,
    hw: &mut Fake,
    s: &mut Sense,
    max_ms: u64,
) -> (HomingStatus, u64) {
    hw.enable();
    let mut t = 1_000u64;
    for _ in 0..max_ms {
        let st = step(h, hw, s, t);
        if !matches!(st, HomingStatus::Running(_)) {
            return (st, t);
        }
        hw.advance(1e-3);
        t += 1000;
    }
    panic!("homing did not finish: {:?}", h.phase());
}

fn new_homing(cfg: &HomingConfig<f64>) -> Homing<f64> {
    Homing::new(cfg, &ServoConfig::default()).unwrap()
}

/// Starts homing from what the sensing reads now.
fn start(h: &mut Homing<f64>, s: &Sense, t: u64) {
    h.start(&s.joints(), &JointReferences::counts(s), t);
}

#[test]
fn homes_on_switches_and_hard_stops() {
    let cfg = test_homing_config();
    let mut h = new_homing(&cfg);
    // True positions; the encoders start at an arbitrary count (incremental).
    let mut hw = Fake::new([0.17, 0.165, 0.18, 0.2, -0.3, 0.1]);
    for j in 0..3 {
        hw.switch_below[j] = Some(0.150);
    }
    for j in 3..6 {
        hw.stop_below[j] = Some(-1.0);
    }
    let mut s = sensing(&mut hw);
    start(&mut h, &s, 1_000);
    let (st, _) = run_homing(&mut h, &mut hw, &mut s, 60_000);
    let HomingStatus::Done = st else {
        panic!("{st:?}")
    };
    let q = s.joints();
    for j in 0..6 {
        // The encoders now read the true positions (to a few counts: the switch is seen
        // one tick after it closes).
        let tol = if j < 3 { 0.02e-3 } else { 0.002 };
        assert!(
            (q[j] - hw.q[j]).abs() < tol,
            "joint {j}: {} vs {}",
            q[j],
            hw.q[j]
        );
    }
    // Backed off from every switch and stop.
    assert!(hw.q[..3].iter().all(|&x| x >= 0.150 + 0.0019), "{:?}", hw.q);
    assert!(hw.q[3..].iter().all(|&x| x >= -1.0 + 0.049), "{:?}", hw.q);
    assert_eq!(h.phase(), HomingPhase::Done);
    // Homing never exceeded the duty limit.
    assert!(hw.duty.iter().all(|d| *d == 0.0));
}

#[test]
fn starting_on_the_switch_leaves_it_first() {
    let mut cfg = test_homing_config();
    cfg.order = [1, 0, 2, 3, 4, 5];
    let mut h = new_homing(&cfg);
    let mut hw = Fake::new([0.17, 0.149, 0.17, 0.0, 0.0, 0.0]);
    for j in 0..3 {
        hw.switch_below[j] = Some(0.150);
    }
    for j in 3..6 {
        hw.stop_below[j] = Some(-1.0);
    }
    let mut s = sensing(&mut hw);
    start(&mut h, &s, 1_000);
    hw.enable();
    let st = step(&mut h, &mut hw, &mut s, 1_000);
    assert_eq!(
        st,
        HomingStatus::Running(HomingPhase::LeaveSwitch { joint: 1 })
    );
    step(&mut h, &mut hw, &mut s, 2_000);
    assert!(hw.duty[1] > 0.0, "drives off the switch (away from -q)");
    let (st, _) = run_homing(&mut h, &mut hw, &mut s, 60_000);
    let HomingStatus::Done = st else {
        panic!("{st:?}")
    };
    let q = s.joints();
    assert!((q[1] - hw.q[1]).abs() < 0.02e-3);
}

#[test]
fn homing_failures_turn_the_outputs_off() {
    let cfg = test_homing_config();
    // Stall before the switch (an obstacle at 155 mm on l1).
    let mut hw = Fake::new([0.17; 6]);
    hw.stop_below[0] = Some(0.155);
    hw.switch_below[0] = Some(0.150);
    let mut h = new_homing(&cfg);
    let mut s = sensing(&mut hw);
    start(&mut h, &s, 1_000);
    let (st, _) = run_homing(&mut h, &mut hw, &mut s, 60_000);
    assert_eq!(
        st,
        HomingStatus::Failed(HomingError::StalledBeforeSwitch { joint: 0 })
    );
    assert!(!hw.enabled && hw.duty == [0.0; 6]);
    // No switch at all: gives up after max_travel.
    let mut hw = Fake::new([0.17; 6]);
    let mut h = new_homing(&cfg);
    let mut s = sensing(&mut hw);
    start(&mut h, &s, 1_000);
    let (st, _) = run_homing(&mut h, &mut hw, &mut s, 60_000);
    assert_eq!(st, HomingStatus::Failed(HomingError::NotFound { joint: 0 }));
    assert!(!hw.enabled);
    // A switch that never releases.
    let mut hw = Fake::new([0.17; 6]);
    hw.stuck_switch = true;
    let mut h = new_homing(&cfg);
    let mut s = sensing(&mut hw);
    start(&mut h, &s, 1_000);
    let (st, _) = run_homing(&mut h, &mut hw, &mut s, 60_000);
    assert_eq!(
        st,
        HomingStatus::Failed(HomingError::SwitchStuck { joint: 0 })
    );
    // A phase timeout.
    let mut cfg2 = cfg;
    cfg2.phase_timeout_us = 100_000;
    let mut hw = Fake::new([0.17; 6]);
    hw.switch_below[0] = Some(0.150);
    let mut h = new_homing(&cfg2);
    let mut s = sensing(&mut hw);
    start(&mut h, &s, 1_000);
    let (st, _) = run_homing(&mut h, &mut hw, &mut s, 60_000);
    assert_eq!(st, HomingStatus::Failed(HomingError::Timeout { joint: 0 }));
}

#[test]
fn homing_current_limit_detects_the_stop() {
    // A compliant stop (the joint creeps on, so the no-motion detection does not see
    // it): the current limit (blocked: 12 A per unit duty x 0.02 = 0.24 A > 0.2 A)
    // holds the current at the limit and finds the stop.
    let mut cfg = test_homing_config();
    cfg.order = [3, 0, 1, 2, 4, 5];
    cfg.stall_time_us = 30_000;
    cfg.joints[3].current_limit = 0.2;
    let mut hw = Fake::new([0.17, 0.17, 0.17, 0.0, 0.0, 0.0]);
    hw.creep = 0.05;
    hw.stop_below[3] = Some(-1.0);
    let mut h = new_homing(&cfg);
    let mut s = sensing(&mut hw);
    start(&mut h, &s, 1_000);
    hw.enable();
    let mut t = 1_000;
    let mut found = false;
    for _ in 0..5_000 {
        let st = step(&mut h, &mut hw, &mut s, t);
        if st == HomingStatus::Running(HomingPhase::BackOff { joint: 3 }) {
            found = true;
            break;
        }
        hw.advance(1e-3);
        t += 1000;
    }
    assert!(found, "{:?}", h.phase());
    // Found at the stop (it crept less than 2 mrad in), and the duty was limited.
    assert!(hw.q[3] < -1.0 && hw.q[3] > -1.002, "{}", hw.q[3]);
    assert!((s.joints()[3] - hw.q[3]).abs() < 1e-3);
}

#[test]
fn homing_config_is_validated() {
    let good = test_homing_config();
    assert!(good.validate().is_ok());
    let mut c = good;
    c.order = [0, 0, 1, 2, 3, 4];
    assert!(c.validate().is_err());
    let mut c = good;
    c.joints[2].approach_duty = f64::NAN;
    assert_eq!(c.validate(), Err(HomingError::Config { joint: 2 }));
    let mut c = good;
    c.duty_limit = 1.5;
    assert!(c.validate().is_err());
    let _ = JointHoming {
        method: HomeMethod::Switch,
        ..good.joints[0]
    };
}

// ---------------------------------------------------------------------------------------
// The plant model
// ---------------------------------------------------------------------------------------

/// The plant placed near its switches and stops (legs 10 mm above the switch, links
/// 0.15 .. 0.25 rad above the stop), switches at 150 mm and stops 60 deg below the central
/// angles.
fn plant_near_home() -> (PlantHw, [f64; 6]) {
    let (hw, c, _) = common::homing_fixture([0.160, 0.161, 0.159], [0.2, 0.25, 0.15]);
    (hw, c)
}

#[test]
fn homes_the_plant_and_parks_at_the_central_configuration() {
    let (mut hw, c) = plant_near_home();
    let mut cfg = HomingConfig::reference([c[3], c[4], c[5]], Some(c));
    cfg.park_speed = [0.02, 0.02, 0.02, 0.5, 0.5, 0.5];
    let mut h = new_homing(&cfg);
    let mut s = Sensing::new(
        RsprGeometry::reference(),
        Branch::OUTER,
        &EncoderConfig::default(),
        Default::default(),
    )
    .unwrap();
    s.boot(hw.counts());
    start(&mut h, &s, 0);
    hw.enable();
    let mut t = 0;
    let mut done = None;
    for _ in 0..60_000 {
        t += 1000;
        s.update(&mut hw);
        match h.step(&mut hw, &mut s, t) {
            HomingStatus::Running(_) => {}
            st => {
                done = Some(st);
                break;
            }
        }
        hw.step_ms();
    }
    let Some(HomingStatus::Done) = done else {
        panic!("{done:?} in {:?}", h.phase())
    };
    let q = s.joints();
    let truth = hw.plant.joint_positions();
    println!(
        "homing took {:.1} s; encoder vs load-side truth:",
        t as f64 * 1e-6
    );
    for j in 0..6 {
        println!("  q{j}: {:+.6} vs {:+.6}", q[j], truth[j]);
    }
    // The encoders sit on the motor side: the reference is good to the backlash
    // (0.12 mm on the legs, 20 arcsec on the links) plus a few counts.
    for j in 0..3 {
        assert!((q[j] - truth[j]).abs() < 0.15e-3, "leg {j}");
        assert!((truth[j] - c[j]).abs() < 0.4e-3, "leg {j} parked");
    }
    for j in 3..6 {
        assert!((q[j] - truth[j]).abs() < 0.002, "link {j}");
        assert!((truth[j] - c[j]).abs() < 0.01, "link {j} parked");
    }
}

// ---------------------------------------------------------------------------------------
// The runtime: boot, home, enable, follow
// ---------------------------------------------------------------------------------------

fn runtime_and_plant() -> (Runtime<f64, RsprGeometry<f64>>, PlantHw) {
    let (hw, _, cfg) = common::homing_fixture([0.160, 0.161, 0.159], [0.2, 0.25, 0.15]);
    let rt = Runtime::new(RsprGeometry::reference(), cfg, 0).unwrap();
    (rt, hw)
}

fn run(rt: &mut Runtime<f64, RsprGeometry<f64>>, hw: &mut PlantHw, t: &mut u64, ms: u64) {
    for _ in 0..ms {
        *t += 1000;
        rt.command(&Command::Heartbeat, *t).unwrap();
        rt.tick(hw, *t);
        hw.step_ms();
    }
}

#[test]
fn runtime_boots_homes_enables_and_follows() {
    let (mut rt, mut hw) = runtime_and_plant();
    let mut t = 0;
    assert_eq!(rt.state(), State::Boot);
    assert_eq!(rt.command(&Command::Home, t), Err(NackReason::Busy));
    rt.boot_done(hw.counts(), t).unwrap();
    assert_eq!(rt.state(), State::Disabled);
    assert_eq!(rt.command(&Command::Enable, t), Err(NackReason::NotHomed));
    rt.command(&Command::Home, t).unwrap();
    let mut ms = 0;
    while rt.state() == State::Homing && ms < 60_000 {
        run(&mut rt, &mut hw, &mut t, 1);
        ms += 1;
    }
    assert_eq!(rt.state(), State::Ready, "{:?}", rt.homing().phase());
    assert!(!hw.enabled, "drives off once homed");
    rt.command(&Command::Enable, t).unwrap();
    assert_eq!(rt.state(), State::Enabled);
    let target = Pose {
        t: Vector3::new(0.004, -0.003, 0.162),
        r: Rotation3::from_scaled_axis(Vector3::new(0.02, 0.0, -0.01)),
    };
    let (p, r) = control::wire::pose_to_wire(&target);
    let cmd = Command::Target {
        stamp_us: 5_000_000,
        position_m: p,
        rotation_vector_rad: r,
    };
    rt.command(&cmd, t).unwrap();
    run(&mut rt, &mut hw, &mut t, 1500);
    assert_eq!(rt.state(), State::Enabled);
    let err = (rt.measured().pose.unwrap().t - target.t).norm();
    assert!(
        err < 0.2e-3,
        "measured pose {:?}, error {err}",
        rt.measured().pose.unwrap().t
    );
    // Clutch engaged: targets refused, the robot holds.
    rt.command(&Command::Clutch { engaged: true }, t).unwrap();
    let cmd2 = Command::Target {
        stamp_us: 5_100_000,
        position_m: [0.0, 0.0, 0.160],
        rotation_vector_rad: [0.0; 3],
    };
    assert_eq!(rt.command(&cmd2, t), Err(NackReason::InvalidState));
    run(&mut rt, &mut hw, &mut t, 200);
    assert!((rt.measured().pose.unwrap().t - target.t).norm() < 0.2e-3);
    rt.command(&Command::Clutch { engaged: false }, t).unwrap();
    // Disable: drives off, homing kept.
    rt.command(&Command::Disable, t).unwrap();
    run(&mut rt, &mut hw, &mut t, 2);
    assert_eq!(rt.state(), State::Ready);
    assert!(!hw.enabled);
    assert!(rt.controller().is_none());
    let st = rt.status();
    assert_eq!(st.state, master_link::RobotState::Ready);
    assert!((f64::from(st.position_m[2]) - target.t.z).abs() < 0.3e-3);
}

/// Jog moves one joint through the supervisor: repeated Jogs of l1 at 5 mm/s for 1 s move
/// l1 by about 5 mm while the other joints stay (within the servo's following error); when
/// the Jogs stop, the robot stops within the 0.1 s dead-man horizon; jogs are refused
/// outside Enabled and for a bad joint or value.
#[test]
fn jog_moves_one_joint_and_stops_when_the_jogs_stop() {
    let (mut rt, mut hw) = runtime_and_plant();
    let mut t = 0;
    rt.boot_done(hw.counts(), t).unwrap();
    let jog = |v: f32| Command::Jog {
        joint: 0,
        velocity: v,
    };
    assert_eq!(rt.command(&jog(0.005), t), Err(NackReason::NotHomed));
    rt.command(&Command::Home, t).unwrap();
    let mut ms = 0;
    while rt.state() == State::Homing && ms < 60_000 {
        run(&mut rt, &mut hw, &mut t, 1);
        ms += 1;
    }
    rt.command(&Command::Enable, t).unwrap();
    run(&mut rt, &mut hw, &mut t, 50);
    let q0 = rt.measured().q;
    assert_eq!(
        rt.command(
            &Command::Jog {
                joint: 6,
                velocity: 0.001
            },
            t
        ),
        Err(NackReason::InvalidJoint)
    );
    assert_eq!(rt.command(&jog(f32::NAN), t), Err(NackReason::InvalidValue));
    // A jog stream at 20 Hz for 1 s.
    for _ in 0..20 {
        rt.command(&jog(0.005), t).unwrap();
        run(&mut rt, &mut hw, &mut t, 50);
    }
    let q1 = rt.measured().q;
    run(&mut rt, &mut hw, &mut t, 500);
    let q2 = rt.measured().q;
    let moved = q1[0] - q0[0];
    println!(
        "jog: l1 moved {:.3} mm in 1 s, {:.3} mm more after the jogs stopped",
        moved * 1e3,
        (q2[0] - q1[0]) * 1e3
    );
    assert!((moved - 0.005).abs() < 0.001, "l1 moved {moved}");
    assert!((q2[0] - q1[0]).abs() < 0.0006, "coasted {}", q2[0] - q1[0]);
    for j in 1..6 {
        assert!(
            (q2[j] - q0[j]).abs() < 2e-4,
            "joint {} moved {}",
            j + 1,
            q2[j] - q0[j]
        );
    }
}
