//! The board's modes and the one table of their transitions.
//!
//! The runtime ([`crate::runtime::Runtime`]) is always in one mode; each mode owns the
//! data valid in it ([`crate::runtime::Mode`]). This module is the pure part: the modes'
//! names ([`ModeKind`]), everything that can happen ([`Event`]: the master's commands, the
//! procedures' milestones, the conditions of the master session and the faults), and
//! [`next`], the function from (mode, event) to the next mode or the reason the event is
//! refused. The runtime asks [`next`] before it changes anything, so the table is the
//! behaviour: the firmware README prints it ([`write_table`]) and a test checks the copy,
//! another carries every (mode, command) and (mode, fault) pair out on the runtime.
//!
//! | mode | drives | brakes | reported state |
//! | --- | --- | --- | --- |
//! | `Boot` | off | applied | `Boot` |
//! | `Disabled` | off | applied | `Disabled` (not homed) |
//! | `Homing` | on | released | `Homing` |
//! | `Parking` | on | released | `Homing` (the move to the park joints) |
//! | `Ready` | off | applied | `Ready` (homed) |
//! | `Enabling` | on | checked, then released | `Enabling` |
//! | `Following` | on | released | `Enabled` |
//! | `Holding` | on (SS2: decelerate, hold) | released | `Enabled` (clutch, dead-man, heartbeat late) |
//! | `Stopping` | on until the stop ends (SS1) | applied at rest | `Ready` or `Disabled` |
//! | `Fault` | as the fault's stop says | as the stop says | `Fault` |
//! | `Commissioning` | on while a joint's test pushes | as the test says | `Commissioning` |
//!
//! **A stop in force is never weakened.** `Stopping` and `Fault` carry a stop: no command
//! ends it early (`Home`, `Enable` and `StoreGeometry` are refused until it has ended,
//! `ClearFault` of a stop under power continues it as an SS1 to rest, and no command
//! answered before a status reported the fault ends its stop: it was sent before its
//! master could know of the stop), and a new stop
//! replaces it only if it is stronger ([`crate::stops::Stopper::request`]). The holds of
//! `Holding` are ended by their own cause going away (the clutch released, the operator's
//! hand back, the heartbeat back).
//!
//! **One owner.** A `Hello` from the master that owns the board (its nonce) keeps the
//! mode and the holds; one from another master is refused (`NotOwner`) unless the robot is
//! disabled (`Boot`, `Disabled`, `Ready`, or `Fault` with torque off), and then the new
//! master starts with the clutch released and the operator absent: `Enable` is refused
//! (`OperatorAbsent`) until it says `OperatorPresent { present: true }`.

use master_link::{FaultCause, Faults, NackReason, RobotState};

/// The state names of the protocol.
pub type State = RobotState;

/// Every reported state, in order.
pub const ALL_STATES: [State; 8] = [
    State::Boot,
    State::Disabled,
    State::Homing,
    State::Ready,
    State::Enabling,
    State::Enabled,
    State::Fault,
    State::Commissioning,
];

/// The board's modes (the names of [`crate::runtime::Mode`]'s variants).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ModeKind {
    /// Power-up: nothing driven until the hardware is up.
    Boot,
    /// Drives off, brakes applied, not homed.
    Disabled,
    /// The joints home one by one; the others hold under servo.
    Homing,
    /// The park move after the references, checked against the guards first.
    Parking,
    /// Homed, drives off, brakes applied.
    Ready,
    /// The brake check against the closed brakes, then the release under servo.
    Enabling,
    /// Following the master's targets.
    Following,
    /// Enabled, holding under power (SS2) while the clutch is engaged, the operator is
    /// absent or the heartbeat is late; targets are refused.
    Holding,
    /// A stop without a fault: `Disable`, or the stop that ends homing or a cleared
    /// fault's stop (SS1: decelerate, brakes, torque off).
    Stopping,
    /// A fault is latched; its stop is carried out, then torque stays off.
    Fault,
    /// One joint's wiring test at a time (`crate::commissioning`), or its record waiting
    /// to be read; entered unhomed, or homed or from a fault with torque off when a person
    /// confirms; it always ends unhomed.
    Commissioning,
}

impl ModeKind {
    /// Every mode, in the table's order.
    pub const ALL: [ModeKind; 11] = [
        ModeKind::Boot,
        ModeKind::Disabled,
        ModeKind::Homing,
        ModeKind::Parking,
        ModeKind::Ready,
        ModeKind::Enabling,
        ModeKind::Following,
        ModeKind::Holding,
        ModeKind::Stopping,
        ModeKind::Fault,
        ModeKind::Commissioning,
    ];

    /// The name in the table.
    pub const fn name(self) -> &'static str {
        match self {
            ModeKind::Boot => "Boot",
            ModeKind::Disabled => "Disabled",
            ModeKind::Homing => "Homing",
            ModeKind::Parking => "Parking",
            ModeKind::Ready => "Ready",
            ModeKind::Enabling => "Enabling",
            ModeKind::Following => "Following",
            ModeKind::Holding => "Holding",
            ModeKind::Stopping => "Stopping",
            ModeKind::Fault => "Fault",
            ModeKind::Commissioning => "Commissioning",
        }
    }

    /// The state the status reports (`homed`: only `Stopping` depends on it).
    pub const fn state(self, homed: bool) -> State {
        match self {
            ModeKind::Boot => State::Boot,
            ModeKind::Disabled => State::Disabled,
            ModeKind::Homing | ModeKind::Parking => State::Homing,
            ModeKind::Ready => State::Ready,
            ModeKind::Enabling => State::Enabling,
            ModeKind::Following | ModeKind::Holding => State::Enabled,
            ModeKind::Stopping if homed => State::Ready,
            ModeKind::Stopping => State::Disabled,
            ModeKind::Fault => State::Fault,
            ModeKind::Commissioning => State::Commissioning,
        }
    }

    /// The drives may produce torque in this mode without a stop (the stop modes drive as
    /// their stop says).
    pub const fn drives(self) -> bool {
        matches!(
            self,
            ModeKind::Homing
                | ModeKind::Parking
                | ModeKind::Enabling
                | ModeKind::Following
                | ModeKind::Holding
                | ModeKind::Commissioning
        )
    }

    /// The mode implies a trusted homing (`Stopping` and `Fault` say it themselves).
    pub const fn implies_homed(self) -> bool {
        matches!(
            self,
            ModeKind::Ready | ModeKind::Enabling | ModeKind::Following | ModeKind::Holding
        )
    }
}

/// Why the robot holds while enabled (the master session's conditions).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Hold {
    /// The clutch is engaged.
    pub clutch: bool,
    /// The operator is absent (dead-man released).
    pub operator_absent: bool,
    /// The heartbeat is late.
    pub heartbeat: bool,
}

impl Hold {
    /// Any reason to hold.
    pub const fn any(&self) -> bool {
        self.clutch || self.operator_absent || self.heartbeat
    }

    /// Every reason at once.
    pub const ALL: Hold = Hold {
        clutch: true,
        operator_absent: true,
        heartbeat: true,
    };

    /// The holds after `event` (`enabled`: the robot is enabled, where a late heartbeat
    /// holds): the clutch and the dead-man as the master sends them, a late heartbeat until
    /// a heartbeat arrives (a `Hello` changes none: the owner's keeps them, and a new
    /// owner's starts from its own, `MasterSession::take_over`).
    pub const fn after(self, event: Event, enabled: bool) -> Hold {
        let mut h = self;
        match event {
            Event::Clutch { engaged } => h.clutch = engaged,
            Event::OperatorPresent { present } => h.operator_absent = !present,
            Event::HeartbeatLate => h.heartbeat = h.heartbeat || enabled,
            Event::HeartbeatRestored => h.heartbeat = false,
            _ => {}
        }
        if !enabled {
            h.heartbeat = false;
        }
        h
    }
}

/// Everything that can happen to the board.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Event {
    /// Power-up done.
    BootDone,
    /// Master: `Hello` (a session opens), from the master that owns the board (`owner`: a
    /// reconnect) or from another.
    Hello {
        /// The `Hello`'s nonce is the owner's.
        owner: bool,
    },
    /// Master: enable the drives.
    Enable,
    /// Master: drives off.
    Disable,
    /// Master: home (`rehome` confirms homing a homed robot again).
    Home {
        /// Confirms rehoming.
        rehome: bool,
    },
    /// Master: a pose target or a joint jog.
    Target,
    /// Master: the clutch pedal.
    Clutch {
        /// Pressed: the master is decoupled.
        engaged: bool,
    },
    /// Master: the dead-man.
    OperatorPresent {
        /// The hand is on the master.
        present: bool,
    },
    /// Master: keep-alive.
    Heartbeat,
    /// Master: emergency stop (latches `EmergencyStopMessage`).
    EmergencyStop,
    /// Master: clear the latched fault.
    ClearFault,
    /// Master: one status.
    StatusRequest,
    /// Master: acknowledge the last reset.
    AcknowledgeReset,
    /// Master: a page of the fault log or of the event log.
    FaultLogRequest,
    /// Master: store a calibrated geometry (drives off only).
    StoreGeometry,
    /// Master: commission a joint (`confirm`: a person confirms commissioning a homed or
    /// faulted robot).
    Commission {
        /// The confirmation.
        confirm: bool,
    },
    /// The heartbeat is later than the hold time.
    HeartbeatLate,
    /// A heartbeat arrived after a late or lost one.
    HeartbeatRestored,
    /// Homing found every joint's reference: the park move is next.
    Referenced,
    /// The park move arrived (or there is none): homing is done.
    Parked,
    /// The brake check passed and the brakes are released.
    BrakesReleased,
    /// The stop in force reached torque off.
    StopComplete,
    /// A fault (a monitor's finding, a procedure's failure).
    Fault(FaultCause),
}

impl Event {
    /// The master's commands, one of each (both values of their flags), in the table's
    /// order.
    pub const COMMANDS: [Event; 21] = [
        Event::Hello { owner: true },
        Event::Hello { owner: false },
        Event::Enable,
        Event::Disable,
        Event::Home { rehome: false },
        Event::Home { rehome: true },
        Event::Target,
        Event::Clutch { engaged: true },
        Event::Clutch { engaged: false },
        Event::OperatorPresent { present: false },
        Event::OperatorPresent { present: true },
        Event::Heartbeat,
        Event::EmergencyStop,
        Event::ClearFault,
        Event::StatusRequest,
        Event::AcknowledgeReset,
        Event::FaultLogRequest,
        Event::StoreGeometry,
        Event::Commission { confirm: false },
        Event::Commission { confirm: true },
        Event::BootDone,
    ];

    /// The conditions and milestones, in the table's order.
    pub const CONDITIONS: [Event; 7] = [
        Event::HeartbeatLate,
        Event::HeartbeatRestored,
        Event::Referenced,
        Event::Parked,
        Event::BrakesReleased,
        Event::StopComplete,
        Event::Fault(FaultCause::HeartbeatTimeout),
    ];

    /// The event's name in the table.
    pub fn name(&self) -> &'static str {
        match self {
            Event::BootDone => "boot done",
            Event::Hello { owner: true } => "`Hello`, the owner's",
            Event::Hello { owner: false } => "`Hello`, another master's",
            Event::Enable => "`Enable`",
            Event::Disable => "`Disable`",
            Event::Home { rehome: false } => "`Home`",
            Event::Home { rehome: true } => "`Home { rehome }`",
            Event::Target => "`PoseTarget`, `Jog`",
            Event::Clutch { engaged: true } => "`Clutch` engaged",
            Event::Clutch { engaged: false } => "`Clutch` released",
            Event::OperatorPresent { present: false } => "`OperatorPresent` false",
            Event::OperatorPresent { present: true } => "`OperatorPresent` true",
            Event::Heartbeat => "`Heartbeat`",
            Event::EmergencyStop => "`EmergencyStop`",
            Event::ClearFault => "`ClearFault`",
            Event::StatusRequest => "`StatusRequest`",
            Event::AcknowledgeReset => "`AcknowledgeReset`",
            Event::FaultLogRequest => "`FaultLogRequest`, `EventLogRequest`",
            Event::StoreGeometry => "`StoreGeometry`",
            Event::Commission { confirm: false } => "`Commission`",
            Event::Commission { confirm: true } => "`Commission { confirm }`",
            Event::HeartbeatLate => "heartbeat late (100 ms)",
            Event::HeartbeatRestored => "heartbeat back",
            Event::Referenced => "every joint referenced",
            Event::Parked => "park move arrived",
            Event::BrakesReleased => "brake check passed, brakes released",
            Event::StopComplete => "the stop reached torque off",
            Event::Fault(FaultCause::HeartbeatTimeout) => "heartbeat lost (500 ms)",
            Event::Fault(_) => "any other fault",
        }
    }

    /// The fault bits this event latches, if it is a fault.
    pub fn fault_bits(&self) -> Option<Faults> {
        match self {
            Event::Fault(FaultCause::None) => Some(Faults::INTERNAL),
            Event::Fault(c) => Some(c.bit()),
            Event::EmergencyStop => Some(FaultCause::EmergencyStopMessage.bit()),
            _ => None,
        }
    }
}

/// Faults whose cause makes the encoders' reference doubtful: they lose the homing.
pub const LOSE_HOMING: Faults = Faults::FOLLOWING_ERROR
    .union(Faults::ENCODER)
    .union(Faults::HOMING_FAILED)
    .union(Faults::INTERNAL);

/// Why an event was refused (the mode does not change).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Refusal {
    /// The board is still booting.
    Booting,
    /// Homing, enabling or a stop is in progress.
    Busy,
    /// Home first.
    NotHomed,
    /// The robot is homed already: `Home` needs the rehoming confirmation.
    AlreadyHomed,
    /// A fault is latched: send `ClearFault`.
    Faulted,
    /// The fault's cause is still present.
    FaultStillActive,
    /// Not allowed in this mode (e.g. `Home` while enabled).
    NotAllowed,
    /// Enabled but holding (clutch engaged or heartbeat late): targets are refused.
    Holding,
    /// Enabled but the operator is absent (dead-man released): targets are refused.
    OperatorAbsent,
    /// The robot is at a pose the setpoint supervisor refuses to start from.
    UnsafeStart,
    /// The last reset (watchdog, brown-out) is not acknowledged yet.
    ResetNotAcknowledged,
    /// The e-stop button and the safety relay's feedback disagree.
    SafetyRelayMismatch,
    /// Another master owns the board and the robot is not disabled.
    NotOwner,
}

impl Refusal {
    /// The reason sent to the master.
    pub const fn nack_reason(self) -> NackReason {
        match self {
            Refusal::Booting | Refusal::Busy => NackReason::Busy,
            Refusal::NotHomed => NackReason::NotHomed,
            Refusal::AlreadyHomed => NackReason::AlreadyHomed,
            Refusal::Faulted => NackReason::Faulted,
            Refusal::FaultStillActive => NackReason::FaultStillActive,
            Refusal::NotAllowed | Refusal::Holding => NackReason::InvalidState,
            Refusal::OperatorAbsent => NackReason::OperatorAbsent,
            Refusal::UnsafeStart => NackReason::OutOfWorkspace,
            Refusal::ResetNotAcknowledged => NackReason::ResetNotAcknowledged,
            Refusal::SafetyRelayMismatch => NackReason::SafetyRelayMismatch,
            Refusal::NotOwner => NackReason::NotOwner,
        }
    }

    /// The name in the table.
    pub const fn name(self) -> &'static str {
        match self {
            Refusal::Booting => "Booting",
            Refusal::Busy => "Busy",
            Refusal::NotHomed => "NotHomed",
            Refusal::AlreadyHomed => "AlreadyHomed",
            Refusal::Faulted => "Faulted",
            Refusal::FaultStillActive => "FaultStillActive",
            Refusal::NotAllowed => "NotAllowed",
            Refusal::Holding => "Holding",
            Refusal::OperatorAbsent => "OperatorAbsent",
            Refusal::UnsafeStart => "UnsafeStart",
            Refusal::ResetNotAcknowledged => "ResetNotAcknowledged",
            Refusal::SafetyRelayMismatch => "SafetyRelayMismatch",
            Refusal::NotOwner => "NotOwner",
        }
    }
}

impl From<Refusal> for NackReason {
    fn from(r: Refusal) -> Self {
        r.nack_reason()
    }
}

/// What the table needs to know beyond the mode.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Context {
    /// The homing is trusted (read in `Stopping` and `Fault`; the other modes imply it).
    pub homed: bool,
    /// `Fault`: its stop still drives (decelerating, braking or holding under power).
    pub powered: bool,
    /// `Fault`: the latched fault's cause is still present.
    pub cause_active: bool,
    /// The holds in force after the event (the master session's conditions).
    pub hold: Hold,
    /// The last reset (watchdog, brown-out) is not acknowledged by a person yet.
    pub reset_pending: bool,
    /// The safety chain is not trusted: a relay test is pending.
    pub chain_untrusted: bool,
    /// `Fault`: a person stopped the robot (the emergency-stop button or message is among
    /// the latched causes). Only `ClearFault` ends such a stop: no command that moves a
    /// joint also resets it (ISO 13850's restart interlock).
    pub emergency_stop: bool,
    /// `Fault`: a fault was latched since the last tick ended (the e-stop latch taken at
    /// the start of the tick that answers the command, an earlier request of that tick).
    /// No status has reported it yet, so the command was sent before its master could
    /// know of the stop: it does not end that stop (`ClearFault`, `Commission { confirm }`
    /// refused as `Busy`; the master sends it again once it has seen the fault).
    pub unreported: bool,
}

/// The transition table: the mode after `event` in `mode`, or why the event is refused.
/// Events that change nothing but a flag or a counter keep the mode.
pub const fn next(mode: ModeKind, event: Event, cx: Context) -> Result<ModeKind, Refusal> {
    use Event as E;
    use ModeKind as M;
    match (event, mode) {
        // Faults win everywhere; the heartbeat lost matters only while something drives.
        (E::Fault(FaultCause::HeartbeatTimeout), m) => Ok(if m.drives() || matches!(m, M::Fault) {
            M::Fault
        } else {
            m
        }),
        (E::Fault(_) | E::EmergencyStop, _) => Ok(M::Fault),

        // One owner: another master takes over only while the robot is disabled (torque
        // off, nothing moving); the owner's own Hello (a reconnect) changes nothing.
        (E::Hello { owner: true }, m) => Ok(m),
        (E::Hello { owner: false }, M::Boot | M::Disabled | M::Ready) => Ok(mode),
        (E::Hello { owner: false }, M::Fault) if !cx.powered => Ok(mode),
        (E::Hello { owner: false }, _) => Err(Refusal::NotOwner),

        // The master session's conditions: holds begin and end while enabled.
        (
            E::Clutch { .. } | E::OperatorPresent { .. } | E::HeartbeatLate | E::HeartbeatRestored,
            m,
        ) => Ok(match m {
            M::Following if cx.hold.any() => M::Holding,
            M::Holding if !cx.hold.any() => M::Following,
            m => m,
        }),
        (E::Heartbeat | E::StatusRequest | E::FaultLogRequest, m) => Ok(m),

        // Commissioning owns the drives while it runs; it ends only by `Disable` (a stop to
        // torque off) or a fault, and always unhomed.
        (E::Enable | E::Home { .. } | E::Target, M::Commissioning) => Err(Refusal::Busy),
        (E::Disable, M::Commissioning) => Ok(M::Stopping),
        (E::ClearFault | E::Commission { .. }, M::Commissioning) => Ok(mode),
        (E::AcknowledgeReset | E::StoreGeometry | E::BootDone, M::Commissioning) => {
            Err(Refusal::NotAllowed)
        }
        (E::Referenced | E::Parked | E::BrakesReleased | E::StopComplete, M::Commissioning) => {
            Err(Refusal::NotAllowed)
        }

        (E::BootDone, M::Boot) => Ok(M::Disabled),
        (E::BootDone, _) => Err(Refusal::NotAllowed),
        (_, M::Boot) => Err(Refusal::Booting),

        // A reset is acknowledged only with the drives off.
        (E::AcknowledgeReset, M::Disabled | M::Ready) => Ok(mode),
        (E::AcknowledgeReset, M::Fault) if !cx.powered => Ok(mode),
        (E::AcknowledgeReset, _) => Err(Refusal::NotAllowed),

        // Nothing moves before a person acknowledged a watchdog or brown-out reset, nor
        // while the safety chain awaits its relay test.
        (E::Enable, M::Ready) | (E::Home { .. } | E::Commission { .. }, M::Disabled | M::Ready)
            if cx.reset_pending =>
        {
            Err(Refusal::ResetNotAcknowledged)
        }
        (E::Enable, M::Ready) | (E::Home { .. } | E::Commission { .. }, M::Disabled | M::Ready)
            if cx.chain_untrusted =>
        {
            Err(Refusal::SafetyRelayMismatch)
        }

        // Commissioning: unhomed and drives off; a homed robot, or one with a fault whose
        // stop has ended, only when a person at the robot confirms.
        (E::Commission { .. }, M::Disabled) => Ok(M::Commissioning),
        (E::Commission { confirm: true }, M::Ready) => Ok(M::Commissioning),
        (E::Commission { confirm: false }, M::Ready) => Err(Refusal::AlreadyHomed),
        (E::Commission { confirm: true }, M::Fault) if !cx.powered && cx.emergency_stop => {
            Err(Refusal::Faulted)
        }
        (E::Commission { confirm: true }, M::Fault) if !cx.powered && cx.unreported => {
            Err(Refusal::Busy)
        }
        (E::Commission { confirm: true }, M::Fault) if !cx.powered && cx.reset_pending => {
            Err(Refusal::ResetNotAcknowledged)
        }
        (E::Commission { confirm: true }, M::Fault) if !cx.powered && cx.chain_untrusted => {
            Err(Refusal::SafetyRelayMismatch)
        }
        (E::Commission { confirm: true }, M::Fault) if !cx.powered => Ok(M::Commissioning),
        (E::Commission { .. }, M::Fault) => Err(Refusal::Faulted),
        (E::Commission { .. }, M::Homing | M::Parking | M::Stopping) => Err(Refusal::Busy),
        (E::Commission { .. }, M::Enabling | M::Following | M::Holding) => Err(Refusal::NotAllowed),

        // A new owner must say its operator is present before the robot moves.
        (E::Enable, M::Ready) if cx.hold.operator_absent => Err(Refusal::OperatorAbsent),
        (E::Enable, M::Ready) => Ok(M::Enabling),
        (E::Enable, M::Enabling | M::Following | M::Holding) => Ok(mode),
        (E::Enable, M::Disabled) => Err(Refusal::NotHomed),
        (E::Enable, M::Stopping) if !cx.homed => Err(Refusal::NotHomed),
        (E::Enable, M::Homing | M::Parking | M::Stopping) => Err(Refusal::Busy),
        (E::Enable, M::Fault) => Err(Refusal::Faulted),

        (E::Disable, M::Disabled | M::Ready | M::Stopping) => Ok(mode),
        (E::Disable, M::Homing | M::Parking | M::Enabling | M::Following | M::Holding) => {
            Ok(M::Stopping)
        }
        (E::Disable, M::Fault) => Err(Refusal::Faulted),

        (E::Home { .. }, M::Disabled) => Ok(M::Homing),
        (E::Home { rehome: true }, M::Ready) => Ok(M::Homing),
        (E::Home { rehome: false }, M::Ready) => Err(Refusal::AlreadyHomed),
        (E::Home { .. }, M::Homing | M::Parking | M::Stopping) => Err(Refusal::Busy),
        (E::Home { .. }, M::Enabling | M::Following | M::Holding) => Err(Refusal::NotAllowed),
        (E::Home { .. }, M::Fault) => Err(Refusal::Faulted),

        (E::Target, M::Following) => Ok(M::Following),
        (E::Target, M::Holding) => Err(
            if cx.hold.operator_absent && !cx.hold.clutch && !cx.hold.heartbeat {
                Refusal::OperatorAbsent
            } else {
                Refusal::Holding
            },
        ),
        (E::Target, M::Disabled) => Err(Refusal::NotHomed),
        (E::Target, M::Stopping) if !cx.homed => Err(Refusal::NotHomed),
        (E::Target, M::Homing | M::Parking | M::Enabling) => Err(Refusal::Busy),
        (E::Target, M::Ready | M::Stopping) => Err(Refusal::NotAllowed),
        (E::Target, M::Fault) => Err(Refusal::Faulted),

        (E::ClearFault, M::Fault) if cx.cause_active => Err(Refusal::FaultStillActive),
        (E::ClearFault, M::Fault) if cx.unreported => Err(Refusal::Busy),
        (E::ClearFault, M::Fault) if cx.powered => Ok(M::Stopping),
        (E::ClearFault, M::Fault) if cx.homed => Ok(M::Ready),
        (E::ClearFault, M::Fault) => Ok(M::Disabled),
        (E::ClearFault, m) => Ok(m),

        (E::StoreGeometry, M::Disabled | M::Ready) => Ok(mode),
        (E::StoreGeometry, _) => Err(Refusal::NotAllowed),

        (E::Referenced, M::Homing) => Ok(M::Parking),
        (E::Parked, M::Homing | M::Parking) => Ok(M::Stopping),
        (E::BrakesReleased, M::Enabling) => Ok(if cx.hold.any() {
            M::Holding
        } else {
            M::Following
        }),
        (E::StopComplete, M::Stopping) if cx.homed => Ok(M::Ready),
        (E::StopComplete, M::Stopping) => Ok(M::Disabled),
        (E::StopComplete, M::Fault) => Ok(M::Fault),
        (E::Referenced | E::Parked | E::BrakesReleased | E::StopComplete, _) => {
            Err(Refusal::NotAllowed)
        }
    }
}

/// The events that begin or end a hold.
const fn is_hold_event(event: Event) -> bool {
    matches!(
        event,
        Event::Clutch { .. }
            | Event::OperatorPresent { .. }
            | Event::HeartbeatLate
            | Event::HeartbeatRestored
    )
}

/// The word for an outcome in a cell: `=`, the next mode, or the refusal.
fn word(mode: ModeKind, r: Result<ModeKind, Refusal>) -> &'static str {
    match r {
        Ok(m) if m == mode => "=",
        Ok(m) => m.name(),
        Err(r) => r.name(),
    }
}

/// The contexts a mode can be in that may change the answer to `event`, with the words
/// that name them.
fn contexts(mode: ModeKind, event: Event) -> &'static [(Context, &'static str)] {
    const BASE: Context = Context {
        homed: false,
        powered: false,
        cause_active: false,
        hold: Hold {
            clutch: false,
            operator_absent: false,
            heartbeat: false,
        },
        reset_pending: false,
        chain_untrusted: false,
        emergency_stop: false,
        unreported: false,
    };
    const NOW: Context = Context {
        unreported: true,
        ..BASE
    };
    const RESET: Context = Context {
        reset_pending: true,
        ..BASE
    };
    const CHAIN: Context = Context {
        chain_untrusted: true,
        ..BASE
    };
    const HOMED: Context = Context {
        homed: true,
        ..BASE
    };
    const CLUTCH: Context = Context {
        hold: Hold {
            clutch: true,
            operator_absent: false,
            heartbeat: false,
        },
        ..BASE
    };
    const ABSENT: Context = Context {
        hold: Hold {
            clutch: false,
            operator_absent: true,
            heartbeat: false,
        },
        ..BASE
    };
    match (mode, event) {
        (ModeKind::Ready, Event::Enable) => &[
            (RESET, "reset not acknowledged"),
            (CHAIN, "relay test pending"),
            (ABSENT, "operator absent"),
            (BASE, "otherwise"),
        ],
        (ModeKind::Fault, Event::Hello { owner: false }) => &[
            (
                Context {
                    powered: true,
                    ..BASE
                },
                "stop under power",
            ),
            (BASE, "torque off"),
        ],
        (ModeKind::Disabled | ModeKind::Ready, Event::Home { .. }) => &[
            (RESET, "reset not acknowledged"),
            (CHAIN, "relay test pending"),
            (BASE, "otherwise"),
        ],
        (ModeKind::Fault, Event::Commission { .. }) => &[
            (
                Context {
                    powered: true,
                    ..BASE
                },
                "stop under power",
            ),
            (
                Context {
                    emergency_stop: true,
                    ..BASE
                },
                "after an emergency stop",
            ),
            (NOW, "not reported yet"),
            (RESET, "reset not acknowledged"),
            (CHAIN, "relay test pending"),
            (BASE, "otherwise, torque off"),
        ],
        (ModeKind::Disabled | ModeKind::Ready, Event::Commission { .. }) => &[
            (RESET, "reset not acknowledged"),
            (CHAIN, "relay test pending"),
            (BASE, "otherwise"),
        ],
        (ModeKind::Fault, Event::AcknowledgeReset) => &[
            (
                Context {
                    powered: true,
                    ..BASE
                },
                "stop under power",
            ),
            (BASE, "torque off"),
        ],
        (ModeKind::Fault, Event::ClearFault) => &[
            (
                Context {
                    cause_active: true,
                    ..BASE
                },
                "cause present",
            ),
            (NOW, "not reported yet"),
            (
                Context {
                    powered: true,
                    homed: true,
                    ..BASE
                },
                "stop under power",
            ),
            (HOMED, "homed"),
            (BASE, "not homed"),
        ],
        (ModeKind::Stopping, _) => &[(HOMED, "homed"), (BASE, "not homed")],
        (ModeKind::Enabling, _) => &[
            (CLUTCH, "clutch, dead-man or heartbeat held"),
            (BASE, "no hold"),
        ],
        (ModeKind::Holding, Event::Target) => {
            &[(CLUTCH, "clutch or heartbeat"), (ABSENT, "dead-man only")]
        }
        _ => &[(BASE, "")],
    }
}

/// A cell of an event that begins or ends a hold, in `Following` (from no hold) or
/// `Holding` (from every hold, or from only those the event ends).
fn hold_cell(out: &mut impl core::fmt::Write, mode: ModeKind, event: Event) -> core::fmt::Result {
    let ctx = |h: Hold| Context {
        hold: h.after(event, true),
        ..Context::default()
    };
    if mode == ModeKind::Following {
        return out.write_str(word(mode, next(mode, event, ctx(Hold::default()))));
    }
    let alone = Hold::ALL.after(event, true);
    let only = Hold {
        clutch: !alone.clutch,
        operator_absent: !alone.operator_absent,
        heartbeat: !alone.heartbeat,
    };
    let (others, ended) = (
        word(mode, next(mode, event, ctx(Hold::ALL))),
        word(mode, next(mode, event, ctx(only))),
    );
    if others == ended {
        return out.write_str(others);
    }
    write!(
        out,
        "{ended} (no other hold); {others} (another hold remains)"
    )
}

/// One cell of the printed table: the outcome in every context the mode can be in.
fn cell(out: &mut impl core::fmt::Write, mode: ModeKind, event: Event) -> core::fmt::Result {
    if matches!(mode, ModeKind::Following | ModeKind::Holding) && is_hold_event(event) {
        return hold_cell(out, mode, event);
    }
    let cases = contexts(mode, event);
    let mut words = cases
        .iter()
        .map(|(cx, _)| word(mode, next(mode, event, *cx)));
    let first = words.next().unwrap_or("");
    if words.all(|w| w == first) {
        return out.write_str(first);
    }
    for (i, (cx, label)) in cases.iter().enumerate() {
        if i > 0 {
            out.write_str("; ")?;
        }
        write!(out, "{} ({label})", word(mode, next(mode, event, *cx)))?;
    }
    Ok(())
}

/// Writes [`next`] as a Markdown table, one row per event and one column per mode (the
/// firmware README prints it; a test checks that the README's copy is this one). `=`
/// keeps the mode; a refusal is named by its reason.
pub fn write_table(out: &mut impl core::fmt::Write) -> core::fmt::Result {
    out.write_str("| event |")?;
    for m in ModeKind::ALL {
        write!(out, " {} |", m.name())?;
    }
    out.write_str("\n| --- |")?;
    for _ in ModeKind::ALL {
        out.write_str(" --- |")?;
    }
    out.write_str("\n")?;
    let rows = Event::COMMANDS
        .iter()
        .chain(Event::CONDITIONS.iter())
        .chain([Event::Fault(FaultCause::Overcurrent)].iter());
    for e in rows {
        write!(out, "| {} |", e.name())?;
        for m in ModeKind::ALL {
            out.write_str(" ")?;
            cell(out, m, *e)?;
            out.write_str(" |")?;
        }
        out.write_str("\n")?;
    }
    Ok(())
}
