#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]
//! The modes' transition table ([`control::modes::next`]) against a copy written out by
//! hand, and carried out on the runtime: every mode times every master command and every
//! fault, and random sequences of commands, faults and hardware events, each checked for
//! the properties the table promises (a stop in force is never weakened; the drives are on
//! only in the modes that allow it).

use control::modes::{next, Context, Event, Hold, ModeKind, Refusal, State};
use control::monitors::Finding;
use control::runtime::Runtime;
use control::stops::StopPhase;
use hal::QuadratureCounter;
use kinematics_core::RsprGeometry;
use master_link::{
    FaultCause, Faults, MasterToBoard, NackReason, ResetCause, StopStatus, PROTOCOL_VERSION,
};
use proptest::prelude::*;

use crate::common;
use common::PlantHw;

type Rt = Runtime<f64, RsprGeometry<f64>>;

// ---------------------------------------------------------------------------------------
// The table, written out
// ---------------------------------------------------------------------------------------

/// The columns: a mode and the context it is in.
const COLUMNS: [(ModeKind, &str); 15] = [
    (ModeKind::Boot, "Boot"),
    (ModeKind::Disabled, "Disabled"),
    (ModeKind::Homing, "Homing"),
    (ModeKind::Parking, "Parking"),
    (ModeKind::Ready, "Ready"),
    (ModeKind::Enabling, "Enabling"),
    (ModeKind::Following, "Following"),
    (ModeKind::Holding, "Holding (clutch)"),
    (ModeKind::Stopping, "Stopping (homed)"),
    (ModeKind::Stopping, "Stopping (not homed)"),
    (ModeKind::Fault, "Fault (homed, off)"),
    (ModeKind::Fault, "Fault (not homed, off)"),
    (ModeKind::Fault, "Fault (under power)"),
    (ModeKind::Fault, "Fault (cause present)"),
    (ModeKind::Commissioning, "Commissioning"),
];

/// The context of a column before the event.
fn column_context(i: usize) -> Context {
    let clutch = Hold {
        clutch: true,
        ..Hold::default()
    };
    let mut cx = Context {
        homed: COLUMNS[i].0.implies_homed(),
        ..Context::default()
    };
    match i {
        7 => cx.hold = clutch,
        8 | 10 => cx.homed = true,
        12 => {
            cx.homed = true;
            cx.powered = true;
        }
        13 => {
            cx.homed = true;
            cx.cause_active = true;
        }
        _ => {}
    }
    cx
}

/// The session's flags after `event` (what the runtime's master session does).
fn after(mut cx: Context, mode: ModeKind, event: Event) -> Context {
    let enabled = matches!(mode, ModeKind::Following | ModeKind::Holding);
    match event {
        Event::Clutch { engaged } => cx.hold.clutch = engaged,
        Event::OperatorPresent { present } => cx.hold.operator_absent = !present,
        Event::HeartbeatLate if enabled => cx.hold.heartbeat = true,
        Event::HeartbeatRestored => cx.hold.heartbeat = false,
        _ => {}
    }
    cx
}

/// The expected table, one row per event, one cell per column. `=` keeps the mode, `!X`
/// refuses with X.
const TABLE: [(Event, [&str; 15]); 30] = {
    use Event as E;
    const R: [&str; 15] = ["="; 15];
    const FLT: [&str; 15] = ["Flt"; 15];
    const NA: [&str; 15] = [
        "!Boot", "!NA", "!NA", "!NA", "!NA", "!NA", "!NA", "!NA", "!NA", "!NA", "!NA", "!NA",
        "!NA", "!NA", "!NA",
    ];
    const FAULTED: &str = "!Faulted";
    [
        (
            E::BootDone,
            [
                "Dis", "!NA", "!NA", "!NA", "!NA", "!NA", "!NA", "!NA", "!NA", "!NA", "!NA", "!NA",
                "!NA", "!NA", "!NA",
            ],
        ),
        (E::Hello { owner: true }, R),
        (
            E::Hello { owner: false },
            [
                "=",
                "=",
                "!NotOwner",
                "!NotOwner",
                "=",
                "!NotOwner",
                "!NotOwner",
                "!NotOwner",
                "!NotOwner",
                "!NotOwner",
                "=",
                "=",
                "!NotOwner",
                "=",
                "!NotOwner",
            ],
        ),
        (
            E::Enable,
            [
                "!Boot",
                "!NotHomed",
                "!Busy",
                "!Busy",
                "Enb",
                "=",
                "=",
                "=",
                "!Busy",
                "!NotHomed",
                FAULTED,
                FAULTED,
                FAULTED,
                FAULTED,
                "!Busy",
            ],
        ),
        (
            E::Disable,
            [
                "!Boot", "=", "Stp", "Stp", "=", "Stp", "Stp", "Stp", "=", "=", FAULTED, FAULTED,
                FAULTED, FAULTED, "Stp",
            ],
        ),
        (
            E::Home { rehome: false },
            [
                "!Boot", "Hom", "!Busy", "!Busy", "!Homed", "!NA", "!NA", "!NA", "!Busy", "!Busy",
                FAULTED, FAULTED, FAULTED, FAULTED, "!Busy",
            ],
        ),
        (
            E::Home { rehome: true },
            [
                "!Boot", "Hom", "!Busy", "!Busy", "Hom", "!NA", "!NA", "!NA", "!Busy", "!Busy",
                FAULTED, FAULTED, FAULTED, FAULTED, "!Busy",
            ],
        ),
        (
            E::Target,
            [
                "!Boot",
                "!NotHomed",
                "!Busy",
                "!Busy",
                "!NA",
                "!Busy",
                "=",
                "!Holding",
                "!NA",
                "!NotHomed",
                FAULTED,
                FAULTED,
                FAULTED,
                FAULTED,
                "!Busy",
            ],
        ),
        (
            E::Clutch { engaged: true },
            [
                "=", "=", "=", "=", "=", "=", "Hol", "=", "=", "=", "=", "=", "=", "=", "=",
            ],
        ),
        (
            E::Clutch { engaged: false },
            [
                "=", "=", "=", "=", "=", "=", "=", "Fol", "=", "=", "=", "=", "=", "=", "=",
            ],
        ),
        (
            E::OperatorPresent { present: false },
            [
                "=", "=", "=", "=", "=", "=", "Hol", "=", "=", "=", "=", "=", "=", "=", "=",
            ],
        ),
        (E::OperatorPresent { present: true }, R),
        (E::Heartbeat, R),
        (E::EmergencyStop, FLT),
        (
            E::ClearFault,
            [
                "!Boot",
                "=",
                "=",
                "=",
                "=",
                "=",
                "=",
                "=",
                "=",
                "=",
                "Rdy",
                "Dis",
                "Stp",
                "!StillActive",
                "=",
            ],
        ),
        (E::StatusRequest, R),
        (
            E::AcknowledgeReset,
            [
                "!Boot", "=", "!NA", "!NA", "=", "!NA", "!NA", "!NA", "!NA", "!NA", "=", "=",
                "!NA", "=", "!NA",
            ],
        ),
        (E::FaultLogRequest, R),
        (
            E::StoreGeometry,
            [
                "!Boot", "=", "!NA", "!NA", "=", "!NA", "!NA", "!NA", "!NA", "!NA", "!NA", "!NA",
                "!NA", "!NA", "!NA",
            ],
        ),
        (
            E::Commission { confirm: false },
            [
                "!Boot", "Com", "!Busy", "!Busy", "!Homed", "!NA", "!NA", "!NA", "!Busy", "!Busy",
                FAULTED, FAULTED, FAULTED, FAULTED, "=",
            ],
        ),
        (
            E::Commission { confirm: true },
            [
                "!Boot", "Com", "!Busy", "!Busy", "Com", "!NA", "!NA", "!NA", "!Busy", "!Busy",
                "Com", "Com", FAULTED, "Com", "=",
            ],
        ),
        (
            E::HeartbeatLate,
            [
                "=", "=", "=", "=", "=", "=", "Hol", "=", "=", "=", "=", "=", "=", "=", "=",
            ],
        ),
        (E::HeartbeatRestored, R),
        (E::Referenced, {
            let mut r = NA;
            r[2] = "Park";
            r
        }),
        (E::Parked, {
            let mut r = NA;
            r[2] = "Stp";
            r[3] = "Stp";
            r
        }),
        (E::BrakesReleased, {
            let mut r = NA;
            r[5] = "Fol";
            r
        }),
        (E::StopComplete, {
            let mut r = NA;
            r[8] = "Rdy";
            r[9] = "Dis";
            r[10] = "=";
            r[11] = "=";
            r[12] = "=";
            r[13] = "=";
            r
        }),
        (
            E::Fault(FaultCause::HeartbeatTimeout),
            [
                "=", "=", "Flt", "Flt", "=", "Flt", "Flt", "Flt", "=", "=", "=", "=", "=", "=",
                "Flt",
            ],
        ),
        (E::Fault(FaultCause::Overcurrent), FLT),
        (E::Fault(FaultCause::GuardStop), FLT),
    ]
};

fn parse(code: &str, mode: ModeKind) -> Result<ModeKind, Refusal> {
    Ok(match code {
        "=" => mode,
        "Dis" => ModeKind::Disabled,
        "Hom" => ModeKind::Homing,
        "Park" => ModeKind::Parking,
        "Rdy" => ModeKind::Ready,
        "Enb" => ModeKind::Enabling,
        "Fol" => ModeKind::Following,
        "Hol" => ModeKind::Holding,
        "Stp" => ModeKind::Stopping,
        "Flt" => ModeKind::Fault,
        "Com" => ModeKind::Commissioning,
        "!NA" => return Err(Refusal::NotAllowed),
        "!Boot" => return Err(Refusal::Booting),
        "!NotHomed" => return Err(Refusal::NotHomed),
        "!Homed" => return Err(Refusal::AlreadyHomed),
        "!Busy" => return Err(Refusal::Busy),
        "!Faulted" => return Err(Refusal::Faulted),
        "!StillActive" => return Err(Refusal::FaultStillActive),
        "!Holding" => return Err(Refusal::Holding),
        "!NotOwner" => return Err(Refusal::NotOwner),
        other => panic!("bad table code {other}"),
    })
}

/// Property: every mode (in every context that changes the answer) times every event
/// gives the written-out table's mode or refusal; the table covers every master command
/// and condition the README prints.
#[test]
fn every_mode_times_every_event_is_the_written_table() {
    let mut checked = 0;
    for (event, row) in TABLE {
        for (i, code) in row.iter().enumerate() {
            let mode = COLUMNS[i].0;
            let cx = after(column_context(i), mode, event);
            let expected = parse(code, mode);
            assert_eq!(
                next(mode, event, cx),
                expected,
                "{event:?} in {} ({cx:?})",
                COLUMNS[i].1
            );
            checked += 1;
        }
    }
    assert_eq!(checked, 30 * 15);
    for e in Event::COMMANDS.iter().chain(Event::CONDITIONS.iter()) {
        assert!(TABLE.iter().any(|(t, _)| t == e), "{e:?} not in the table");
    }
    // The restart interlocks: nothing moves before a person acknowledged a watchdog or
    // brown-out reset, nor while the safety chain awaits its relay test; the reset is
    // acknowledged only with the drives off.
    for (cx, refusal) in [
        (
            Context {
                reset_pending: true,
                ..Context::default()
            },
            Refusal::ResetNotAcknowledged,
        ),
        (
            Context {
                chain_untrusted: true,
                ..Context::default()
            },
            Refusal::SafetyRelayMismatch,
        ),
    ] {
        for (mode, event) in [
            (ModeKind::Disabled, Event::Home { rehome: false }),
            (ModeKind::Ready, Event::Home { rehome: true }),
            (ModeKind::Ready, Event::Enable),
        ] {
            assert_eq!(next(mode, event, cx), Err(refusal), "{event:?} in {mode:?}");
        }
        for event in [
            Event::Disable,
            Event::AcknowledgeReset,
            Event::StoreGeometry,
        ] {
            assert!(next(ModeKind::Ready, event, cx).is_ok(), "{event:?}");
        }
    }
    // The dead-man alone gives its own refusal.
    let absent = Context {
        hold: Hold {
            operator_absent: true,
            ..Hold::default()
        },
        homed: true,
        ..Context::default()
    };
    assert_eq!(
        next(ModeKind::Holding, Event::Target, absent),
        Err(Refusal::OperatorAbsent)
    );
    // A new owner starts with the operator absent: no Enable until it says otherwise.
    assert_eq!(
        next(ModeKind::Ready, Event::Enable, absent),
        Err(Refusal::OperatorAbsent)
    );
    // Every fault cause but the heartbeat's latches from every mode.
    for cause in FaultCause::ALL {
        if cause == FaultCause::HeartbeatTimeout {
            continue;
        }
        for m in ModeKind::ALL {
            assert_eq!(
                next(m, Event::Fault(cause), Context::default()),
                Ok(ModeKind::Fault)
            );
        }
    }
}

#[test]
fn refusals_map_to_nack_reasons() {
    let pairs = [
        (Refusal::Booting, NackReason::Busy),
        (Refusal::Busy, NackReason::Busy),
        (Refusal::NotHomed, NackReason::NotHomed),
        (Refusal::AlreadyHomed, NackReason::AlreadyHomed),
        (Refusal::Faulted, NackReason::Faulted),
        (Refusal::FaultStillActive, NackReason::FaultStillActive),
        (Refusal::NotAllowed, NackReason::InvalidState),
        (Refusal::Holding, NackReason::InvalidState),
        (Refusal::OperatorAbsent, NackReason::OperatorAbsent),
        (Refusal::UnsafeStart, NackReason::OutOfWorkspace),
        (
            Refusal::ResetNotAcknowledged,
            NackReason::ResetNotAcknowledged,
        ),
        (
            Refusal::SafetyRelayMismatch,
            NackReason::SafetyRelayMismatch,
        ),
    ];
    for (r, n) in pairs {
        assert_eq!(NackReason::from(r), n);
    }
}

// ---------------------------------------------------------------------------------------
// The runtime in every mode
// ---------------------------------------------------------------------------------------

/// A runtime with its plant, at board time `t` (µs).
#[derive(Clone)]
struct Bench {
    rt: Rt,
    hw: PlantHw,
    t: u64,
    /// The master's last target stamp (strictly increasing).
    stamp: u64,
}

impl Bench {
    /// One millisecond: a heartbeat (unless `silent`), the tick, the plant.
    fn tick(&mut self, silent: bool) {
        self.t += 1000;
        if !silent {
            self.rt.command(&MasterToBoard::Heartbeat, self.t).unwrap();
        }
        self.rt.tick(&mut self.hw, self.t);
        self.hw.step_ms();
    }
    fn run(&mut self, ms: u32) {
        for _ in 0..ms {
            self.tick(false);
        }
    }
    fn run_until(&mut self, max_ms: u32, mut done: impl FnMut(&Rt) -> bool) {
        for _ in 0..max_ms {
            if done(&self.rt) {
                return;
            }
            self.tick(false);
        }
        assert!(
            done(&self.rt),
            "not reached in {max_ms} ms: {:?}",
            self.rt.status()
        );
    }
    fn kind(&self) -> ModeKind {
        self.rt.mode().kind()
    }
    fn send(&mut self, msg: &MasterToBoard) -> Result<(), NackReason> {
        self.rt.command(msg, self.t).map(|_| ())
    }
}

/// The runtime in every mode of the table's columns (in `COLUMNS` order), homed on the
/// plant with the reference mechanics.
fn benches() -> Vec<Bench> {
    let (hw, _, cfg) = common::homing_fixture([0.160, 0.161, 0.159], [0.2, 0.25, 0.15]);
    let rt = Runtime::new(RsprGeometry::reference(), cfg, 0).unwrap();
    let boot = Bench {
        rt,
        hw,
        t: 0,
        stamp: 1_000_000,
    };
    let mut b = boot.clone();
    let counts = b.hw.counts();
    b.rt.boot_done(counts, 0, ResetCause::PowerOn, None)
        .unwrap();
    let disabled = b.clone();
    b.send(&MasterToBoard::Home { rehome: false }).unwrap();
    b.run(5);
    let homing = b.clone();
    b.run_until(60_000, |rt| rt.mode().kind() == ModeKind::Parking);
    b.run(2);
    let parking = b.clone();
    b.run_until(60_000, |rt| rt.mode().kind() == ModeKind::Stopping);
    let stopping_homed = b.clone();
    b.run_until(1_000, |rt| rt.mode().kind() == ModeKind::Ready);
    b.run(50);
    let ready = b.clone();
    b.send(&MasterToBoard::Enable).unwrap();
    b.run(2);
    let enabling = b.clone();
    b.run_until(2_000, |rt| rt.mode().kind() == ModeKind::Following);
    b.run(50);
    let following = b.clone();
    let mut holding = b.clone();
    holding
        .send(&MasterToBoard::Clutch { engaged: true })
        .unwrap();
    holding.run(20);
    let mut stopping = homing.clone();
    stopping.send(&MasterToBoard::Disable).unwrap();
    let mut fault_homed = ready.clone();
    fault_homed.send(&MasterToBoard::EmergencyStop).unwrap();
    fault_homed.run(2);
    let mut fault_unhomed = following.clone();
    fault_unhomed.rt.fault(
        Finding::joint(FaultCause::FollowingError, 0, 1e-3f64),
        fault_unhomed.t,
    );
    fault_unhomed.run(2);
    let mut fault_powered = following.clone();
    fault_powered.rt.fault(
        Finding::board(FaultCause::GuardStop, 0.0f64),
        fault_powered.t,
    );
    fault_powered.run(2);
    let mut fault_active = ready.clone();
    fault_active.hw.press_estop(true);
    fault_active.run(2);
    let all = vec![
        boot,
        disabled,
        homing,
        parking,
        ready,
        enabling,
        following,
        holding,
        stopping_homed,
        stopping,
        fault_homed,
        fault_unhomed,
        fault_powered,
        fault_active,
    ];
    for (i, b) in all.iter().enumerate() {
        assert_eq!(b.kind(), COLUMNS[i].0, "{}", COLUMNS[i].1);
        let cx = column_context(i);
        if matches!(b.kind(), ModeKind::Stopping | ModeKind::Fault) {
            assert_eq!(b.rt.homed(), cx.homed, "{}", COLUMNS[i].1);
        }
        if b.kind() == ModeKind::Fault {
            let powered = !matches!(b.rt.stop_phase(), StopPhase::TorqueOff { .. });
            assert_eq!(powered, cx.powered, "{}", COLUMNS[i].1);
        }
    }
    all
}

/// Every master command, with the event the table knows it by.
fn commands(b: &mut Bench) -> Vec<(MasterToBoard, Event)> {
    b.stamp += 10_000;
    let pose = b.rt.setpoint_joints().map_or([0.0, 0.0, 0.160], |_| {
        let s = b.rt.status();
        s.setpoint_position_m
    });
    vec![
        (
            MasterToBoard::Hello {
                protocol_version: PROTOCOL_VERSION,
                nonce: 7,
                clock_us: 1,
            },
            // The benches never said Hello: nobody owns the board, so it is another
            // master's.
            Event::Hello { owner: false },
        ),
        (MasterToBoard::Enable, Event::Enable),
        (MasterToBoard::Disable, Event::Disable),
        (
            MasterToBoard::Home { rehome: false },
            Event::Home { rehome: false },
        ),
        (
            MasterToBoard::Home { rehome: true },
            Event::Home { rehome: true },
        ),
        (
            MasterToBoard::PoseTarget {
                timestamp_us: b.stamp,
                position_m: pose,
                rotation_vector_rad: [0.0; 3],
            },
            Event::Target,
        ),
        (
            MasterToBoard::Jog {
                joint: 0,
                velocity: 0.001,
            },
            Event::Target,
        ),
        (
            MasterToBoard::Clutch { engaged: true },
            Event::Clutch { engaged: true },
        ),
        (
            MasterToBoard::Clutch { engaged: false },
            Event::Clutch { engaged: false },
        ),
        (
            MasterToBoard::OperatorPresent { present: false },
            Event::OperatorPresent { present: false },
        ),
        (
            MasterToBoard::OperatorPresent { present: true },
            Event::OperatorPresent { present: true },
        ),
        (MasterToBoard::Heartbeat, Event::Heartbeat),
        (MasterToBoard::EmergencyStop, Event::EmergencyStop),
        (MasterToBoard::ClearFault, Event::ClearFault),
        (MasterToBoard::StatusRequest, Event::StatusRequest),
        (MasterToBoard::AcknowledgeReset, Event::AcknowledgeReset),
        (
            MasterToBoard::FaultLogRequest { first: 0 },
            Event::FaultLogRequest,
        ),
    ]
}

/// A stop's strength: none 0, SS2 1, SS1 2, STO 3.
fn rank(phase: StopPhase) -> u8 {
    use control::stops::StopCategory as C;
    match phase {
        StopPhase::Running => 0,
        StopPhase::Holding
        | StopPhase::Decelerating {
            category: C::Ss2, ..
        } => 1,
        StopPhase::Decelerating { .. } | StopPhase::Braking { .. } => 2,
        StopPhase::TorqueOff { sto: false } => 2,
        StopPhase::TorqueOff { sto: true } => 3,
    }
}

/// The drives may be on in this mode and stop phase.
fn drives_allowed(rt: &Rt) -> bool {
    match rt.mode().kind() {
        m if m.drives() => true,
        ModeKind::Stopping | ModeKind::Fault => {
            !matches!(rt.stop_phase(), StopPhase::TorqueOff { .. })
        }
        _ => false,
    }
}

/// The properties every state of the board must have: the drives on only where the mode
/// allows; the brakes released only with the drives on; a latched fault named in
/// `Fault` and nowhere else.
fn check_state(b: &Bench, ctx: &str) {
    assert!(
        !b.hw.enabled || drives_allowed(&b.rt),
        "{ctx}: drives on in {:?} ({:?})",
        b.kind(),
        b.rt.stop_phase()
    );
    assert!(
        !b.hw.brakes_released || b.hw.enabled,
        "{ctx}: brakes released without torque"
    );
    let st = b.rt.status();
    if b.kind() == ModeKind::Fault {
        assert_ne!(st.fault.cause, FaultCause::None, "{ctx}");
        assert!(!st.faults.is_empty(), "{ctx}");
    } else {
        assert_eq!(st.fault.cause, FaultCause::None, "{ctx}");
        assert_eq!(st.faults, Faults::NONE, "{ctx}");
    }
    assert_eq!(
        st.state,
        b.kind().state(b.rt.homed()),
        "{ctx}: reported state"
    );
}

/// Checks that a stop in force before was not weakened after: its strength did not drop,
/// unless the hold ended with its cause (`Holding` -> `Following`), or the stop has done
/// its work (torque off, brakes applied) and the mode has none (`Ready`, `Disabled`).
fn check_not_weakened(before: (ModeKind, StopPhase), b: &Bench, ctx: &str) {
    let (mode, phase) = before;
    let now = b.rt.stop_phase();
    let hold_ended = mode == ModeKind::Holding
        && b.kind() == ModeKind::Following
        && !b.rt.session().hold().any();
    let idle = matches!(b.kind(), ModeKind::Ready | ModeKind::Disabled);
    let completed = matches!(phase, StopPhase::TorqueOff { .. }) && idle;
    let off = !b.rt.outputs().torque_on() && !b.rt.outputs().brakes_released() && idle;
    if rank(phase) > 0 && !hold_ended && !completed && !off {
        assert!(
            rank(now) >= rank(phase),
            "{ctx}: the stop {phase:?} in {mode:?} became {now:?} in {:?}",
            b.kind()
        );
    }
}

/// Property: on the runtime, every mode times every master command and every fault ends
/// in the table's mode (or is refused with the table's reason), and afterwards, over the
/// next ticks, the drives are on only where the mode allows and a stop in force was not
/// weakened.
#[test]
fn every_mode_times_every_command_and_fault_on_the_runtime() {
    let benches = benches();
    let mut pairs = 0;
    for (i, b0) in benches.iter().enumerate() {
        let col = COLUMNS[i].1;
        let mut base = b0.clone();
        let cmds = commands(&mut base);
        for (msg, event) in cmds {
            let mut b = base.clone();
            let before = (b.kind(), b.rt.stop_phase());
            let hold = b.rt.session().hold();
            let cx = after(
                Context {
                    hold,
                    ..context_of(&b)
                },
                before.0,
                event,
            );
            let expected = next(before.0, event, cx);
            let got = b.send(&msg);
            let ctx = format!("{msg:?} in {col}");
            match expected {
                Ok(to) => {
                    // A target the supervisor refuses is still a target the gate took.
                    if event != Event::Target {
                        assert_eq!(got, Ok(()), "{ctx}");
                    }
                    let settled = to == ModeKind::Stopping
                        && matches!(b.kind(), ModeKind::Ready | ModeKind::Disabled);
                    assert!(
                        b.kind() == to || settled,
                        "{ctx}: {:?} not {to:?}",
                        b.kind()
                    );
                }
                Err(r) => {
                    assert_eq!(got, Err(r.nack_reason()), "{ctx}");
                    assert_eq!(b.kind(), before.0, "{ctx}: refused, yet the mode changed");
                }
            }
            check_not_weakened(before, &b, &ctx);
            for k in 0..30 {
                b.tick(false);
                check_state(&b, &format!("{ctx}, tick {k}"));
            }
            pairs += 1;
        }
        for cause in FaultCause::ALL {
            let mut b = base.clone();
            let before = (b.kind(), b.rt.stop_phase());
            let expected = next(before.0, Event::Fault(cause), context_of(&b)).unwrap();
            b.rt.fault(Finding::board(cause, 1.0f64), b.t);
            let ctx = format!("fault {cause:?} in {col}");
            assert_eq!(b.kind(), expected, "{ctx}");
            if expected == ModeKind::Fault {
                let st = b.rt.status();
                assert!(st.faults.intersects(cause_bits(cause)), "{ctx}");
                let lost = cause_bits(cause).intersects(control::modes::LOSE_HOMING);
                if lost {
                    assert!(!b.rt.homed(), "{ctx}: the homing is lost");
                }
            }
            check_not_weakened(before, &b, &ctx);
            b.tick(false);
            check_state(&b, &ctx);
            pairs += 1;
        }
        // StoreGeometry: the mode gate of `check_geometry` is the table's.
        let record = master_link::GeometryRecord {
            layout: 0,
            version: 1,
            nominal: [0.0; 4],
            chains: [[0.0; master_link::GEOMETRY_CHAIN_VALUES]; 3],
            crc: 0,
        };
        let gate = next(b0.kind(), Event::StoreGeometry, context_of(b0));
        let got = b0.rt.check_geometry(&record);
        assert_eq!(
            got == Err(master_link::GeometryRefusal::InvalidState),
            gate.is_err(),
            "StoreGeometry in {col}: {got:?}"
        );
    }
    assert_eq!(pairs, 14 * (17 + FaultCause::ALL.len()));
}

fn cause_bits(cause: FaultCause) -> Faults {
    Event::Fault(cause).fault_bits().unwrap()
}

/// The table's context of a bench (the holds as they stand).
fn context_of(b: &Bench) -> Context {
    let i = b.rt.inputs();
    Context {
        homed: b.rt.homed(),
        powered: b.kind() == ModeKind::Fault
            && !matches!(b.rt.stop_phase(), StopPhase::TorqueOff { .. }),
        cause_active: i.estop_pressed || i.relay_open != i.estop_pressed,
        hold: b.rt.session().hold(),
        reset_pending: !b.rt.reset().acknowledged,
        chain_untrusted: b.rt.relay_test_pending(),
        emergency_stop: b.rt.emergency_stop_latched(),
        unreported: b.rt.fault_unreported(),
    }
}

/// Property: every fault cause latches its own bit; the causes that make the encoder
/// reference doubtful lose the homing, the others keep it; with its condition gone,
/// clearing returns to `Ready` or `Disabled` once the stop has ended (a missed deadline is
/// never cleared: the watchdog resets the board); faults add up while latched.
#[test]
fn fault_bits_and_homing_validity() {
    let benches = benches();
    let following = &benches[6];
    for cause in FaultCause::ALL {
        let mut b = following.clone();
        b.rt.fault(Finding::board(cause, 1.0f64), b.t);
        assert_eq!(b.rt.state(), State::Fault, "{cause:?}");
        assert_eq!(b.rt.status().faults, cause_bits(cause), "{cause:?}");
        let loses = cause_bits(cause).intersects(control::modes::LOSE_HOMING);
        assert_eq!(b.rt.homed(), !loses, "{cause:?}");
        b.run_until(2_000, |rt| {
            matches!(
                rt.stop_phase(),
                StopPhase::TorqueOff { .. } | StopPhase::Holding
            )
        });
        if cause == FaultCause::DeadlineMissed {
            // The watchdog resets the board: nothing clears it before.
            assert_eq!(
                b.send(&MasterToBoard::ClearFault),
                Err(NackReason::FaultStillActive)
            );
            continue;
        }
        // The master clears what a status has reported: after a tick.
        b.tick(false);
        b.send(&MasterToBoard::ClearFault).unwrap();
        b.run_until(2_000, |rt| rt.mode().kind() != ModeKind::Stopping);
        let back = if loses { State::Disabled } else { State::Ready };
        let st = b.rt.status();
        assert_eq!((st.state, st.faults), (back, Faults::NONE), "{cause:?}");
        assert_eq!(st.stop, StopStatus::None, "{cause:?}");
    }
    // Faults add up while latched; the cause present refuses the clear.
    let mut b = following.clone();
    b.hw.press_estop(true);
    b.tick(false);
    b.rt.fault(Finding::board(FaultCause::Overcurrent, 9.0f64), b.t);
    assert_eq!(
        b.rt.status().faults,
        Faults::EMERGENCY_STOP | Faults::OVERCURRENT
    );
    assert_eq!(
        b.send(&MasterToBoard::ClearFault),
        Err(NackReason::FaultStillActive)
    );
    // `None` latches INTERNAL.
    let mut b = benches[4].clone();
    b.rt.fault(Finding::board(FaultCause::None, 0.0f64), b.t);
    assert_eq!(b.rt.status().faults, Faults::INTERNAL);
}

/// Property: the clutch, the dead-man and the heartbeat hold an enabled robot (SS2) and
/// only while enabled; each hold refuses targets with its reason and ends with its cause;
/// a heartbeat lost after it is a fault (SS1) that keeps the homing.
#[test]
fn clutch_operator_and_heartbeat_hold_while_enabled() {
    let benches = benches();
    let mut b = benches[4].clone();
    // The pedal is remembered in any mode; it only holds while enabled.
    b.send(&MasterToBoard::Clutch { engaged: true }).unwrap();
    assert!(b.rt.session().clutch_engaged());
    assert_eq!(b.kind(), ModeKind::Ready);
    b.send(&MasterToBoard::Enable).unwrap();
    assert_eq!(b.kind(), ModeKind::Enabling, "enabling: no hold yet");
    b.run_until(2_000, |rt| rt.mode().kind() != ModeKind::Enabling);
    assert_eq!(b.kind(), ModeKind::Holding);
    assert!(b.rt.session().hold().clutch);
    let target = |b: &mut Bench| {
        b.stamp += 10_000;
        MasterToBoard::PoseTarget {
            timestamp_us: b.stamp,
            position_m: [0.0, 0.0, 0.160],
            rotation_vector_rad: [0.0; 3],
        }
    };
    let t = target(&mut b);
    assert_eq!(b.send(&t), Err(NackReason::InvalidState));
    b.send(&MasterToBoard::Clutch { engaged: false }).unwrap();
    assert_eq!(b.kind(), ModeKind::Following);
    let t = target(&mut b);
    assert_eq!(b.send(&t), Ok(()));
    // The operator lets go: hold, with its own refusal.
    b.send(&MasterToBoard::OperatorPresent { present: false })
        .unwrap();
    assert_eq!(b.kind(), ModeKind::Holding);
    let t = target(&mut b);
    assert_eq!(b.send(&t), Err(NackReason::OperatorAbsent));
    b.send(&MasterToBoard::OperatorPresent { present: true })
        .unwrap();
    assert_eq!(b.kind(), ModeKind::Following);
    // Heartbeat hold, ended by a heartbeat.
    let hold_ms = b.rt.config().heartbeat.hold_after_us / 1000;
    for _ in 0..hold_ms {
        b.tick(true);
    }
    assert_eq!(b.kind(), ModeKind::Holding);
    assert!(b.rt.session().hold().heartbeat);
    assert_eq!(b.rt.state(), State::Enabled);
    b.send(&MasterToBoard::Heartbeat).unwrap();
    assert_eq!(b.kind(), ModeKind::Following);
    // Hold then loss: a fault (its stop is SS1), homing kept.
    let lost_ms = b.rt.config().heartbeat.disable_after_us / 1000;
    for _ in 0..lost_ms {
        b.tick(true);
    }
    assert_eq!(b.rt.state(), State::Fault);
    assert_eq!(b.rt.status().faults, Faults::HEARTBEAT_TIMEOUT);
    assert!(b.rt.homed());
    assert!(!b.rt.session().hold().heartbeat);
}

// ---------------------------------------------------------------------------------------
// Random sequences
// ---------------------------------------------------------------------------------------

/// One thing that happens to the board.
#[derive(Clone, Debug)]
enum Action {
    /// A master command (an index into `commands`).
    Command(usize),
    /// A fault (an index into `FaultCause::ALL`).
    Fault(usize),
    /// Ticks with heartbeats.
    Ticks(u8),
    /// Ticks without heartbeats.
    Silence(u8),
    /// The e-stop button pressed or released.
    Button(bool),
}

fn action() -> impl Strategy<Value = Action> {
    prop_oneof![
        4 => (0usize..17).prop_map(Action::Command),
        2 => (0usize..FaultCause::ALL.len()).prop_map(Action::Fault),
        4 => (1u8..60).prop_map(Action::Ticks),
        1 => (1u8..200).prop_map(Action::Silence),
        1 => any::<bool>().prop_map(Action::Button),
    ]
}

/// The benches, built once for every case.
fn shared_benches() -> &'static Vec<Bench> {
    static BENCHES: std::sync::OnceLock<Vec<Bench>> = std::sync::OnceLock::new();
    BENCHES.get_or_init(benches)
}

proptest! {
    #![proptest_config(proptest_config::cases(256))]

    /// Property: from any mode, any sequence of master commands, faults, silences and
    /// e-stop presses keeps, at every step and every tick, the drives on only where the
    /// mode allows, the brakes released only with torque, the reported state the mode's,
    /// and a stop in force never weakened (SR-3, SR-4, on the runtime alone; the search
    /// checks them on the whole board).
    #[test]
    fn random_sequences_never_weaken_a_stop(
        start in 0usize..14,
        actions in proptest::collection::vec(action(), 1..24),
    ) {
        let mut b = shared_benches()[start].clone();
        for (n, a) in actions.iter().enumerate() {
            let ctx = format!("step {n} {a:?} from {}", COLUMNS[start].1);
            let before = (b.kind(), b.rt.stop_phase());
            match a {
                Action::Command(i) => {
                    let cmds = commands(&mut b);
                    let _ = b.send(&cmds[*i % cmds.len()].0);
                    check_not_weakened(before, &b, &ctx);
                }
                Action::Fault(i) => {
                    b.rt.fault(Finding::board(FaultCause::ALL[*i], 1.0f64), b.t);
                    check_not_weakened(before, &b, &ctx);
                }
                Action::Ticks(k) | Action::Silence(k) => {
                    let silent = matches!(a, Action::Silence(_));
                    for _ in 0..*k {
                        let before = (b.kind(), b.rt.stop_phase());
                        b.tick(silent);
                        check_not_weakened(before, &b, &ctx);
                        check_state(&b, &ctx);
                    }
                }
                Action::Button(p) => b.hw.press_estop(*p),
            }
        }
    }
}
