//! The board's named state machine.
//!
//! ## States (the protocol's [`RobotState`])
//! `Boot -> Disabled -> Homing -> Ready -> Enabling -> Enabled -> Fault`:
//! * `Boot`: power-up; drives off; only the e-stop and the clutch pedal are taken.
//! * `Disabled`: drives off, brakes applied, **not homed** (the encoders are incremental).
//! * `Homing`: the board homes the joints one by one ([`crate::homing::Homing`]), drives on.
//! * `Ready`: homed, drives off, brakes applied.
//! * `Enabling`: drives on, the brakes checked and released while the robot holds
//!   ([`crate::brakes`]).
//! * `Enabled`: drives on, following the master's targets, or holding (clutch engaged,
//!   operator absent or heartbeat late: targets refused, the robot stops and holds).
//! * `Fault`: latched until `ClearFault` (refused while the cause is still present); what
//!   the drives do is the stop the fault called for ([`crate::stops`]). Clearing returns to
//!   `Ready` if the homing is still trusted (an e-stop keeps it; tracking, encoder and
//!   homing faults lose it), else to `Disabled`.
//!
//! The table is [`next_state`], a pure function; [`StateMachine`] adds the flags (homed,
//! clutch, operator presence, heartbeat hold, latched faults). `Disable` leaves the homing
//! valid: from `Enabled` it goes to `Ready` (drives off, homed).

use master_link::{FaultCause, Faults, NackReason, RobotState};

/// The state names are the protocol's.
pub type State = RobotState;

/// Every state, in order.
pub const ALL_STATES: [State; 7] = [
    State::Boot,
    State::Disabled,
    State::Homing,
    State::Ready,
    State::Enabling,
    State::Enabled,
    State::Fault,
];

/// What can happen to the state machine.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Event {
    /// Power-up self test finished.
    BootDone,
    /// Master: enable the drives (Ready -> Enabling).
    Enable,
    /// The brakes were checked and released (Enabling -> Enabled).
    EnableDone,
    /// Master: drives off.
    Disable,
    /// Master: start homing (`rehome` confirms homing a homed robot again).
    Home {
        /// Confirms rehoming.
        rehome: bool,
    },
    /// The homing procedure finished.
    HomingDone,
    /// Master clutch pedal. Engaged: the master is decoupled, targets are refused and the
    /// robot holds.
    Clutch {
        /// Pedal pressed.
        engaged: bool,
    },
    /// Operator presence (dead-man). Absent: targets are refused and the robot holds.
    OperatorPresent {
        /// Present.
        present: bool,
    },
    /// Heartbeat late: hold.
    HeartbeatLost,
    /// A heartbeat arrived again (ends a heartbeat hold).
    HeartbeatRestored,
    /// A fault (homing failures, the heartbeat lost, the e-stop included).
    Fault(FaultCause),
    /// Master: clear the latched fault; `cause_active` when its cause is still present
    /// (e.g. the e-stop button is still pressed).
    ClearFault {
        /// The cause is still present.
        cause_active: bool,
    },
}

impl Event {
    /// One of each event (both values of the flags, a few faults), for exhaustive tests.
    pub const ALL: [Event; 19] = [
        Event::BootDone,
        Event::Enable,
        Event::EnableDone,
        Event::Disable,
        Event::Home { rehome: false },
        Event::Home { rehome: true },
        Event::HomingDone,
        Event::Clutch { engaged: true },
        Event::Clutch { engaged: false },
        Event::OperatorPresent { present: true },
        Event::OperatorPresent { present: false },
        Event::HeartbeatLost,
        Event::HeartbeatRestored,
        Event::Fault(FaultCause::EmergencyStopButton),
        Event::Fault(FaultCause::FollowingError),
        Event::Fault(FaultCause::HomingFailed),
        Event::Fault(FaultCause::HeartbeatTimeout),
        Event::ClearFault {
            cause_active: false,
        },
        Event::ClearFault { cause_active: true },
    ];

    /// The fault bits this event latches, if it is a fault.
    pub fn fault_bits(&self) -> Option<Faults> {
        match self {
            Event::Fault(FaultCause::None) => Some(Faults::INTERNAL),
            Event::Fault(c) => Some(c.bit()),
            _ => None,
        }
    }
}

/// Why an event was refused (the state does not change).
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
    /// Not allowed in this state (e.g. `Home` while enabled; `HomingDone` when not homing).
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
        }
    }
}

impl From<Refusal> for NackReason {
    fn from(r: Refusal) -> Self {
        r.nack_reason()
    }
}

/// The transition table: the state after `event` in `state` (`homed`: whether the
/// homing is trusted, which matters for `ClearFault` and `Home`), or why it is refused.
/// Events that only set a flag (clutch, operator presence, heartbeat hold) keep the state.
pub const fn next_state(state: State, event: Event, homed: bool) -> Result<State, Refusal> {
    use Event as E;
    use State as S;
    match (event, state) {
        // The heartbeat lost while the drives move is a fault; otherwise nothing moves.
        (
            E::Fault(FaultCause::HeartbeatTimeout),
            S::Homing | S::Enabling | S::Enabled | S::Fault,
        ) => Ok(S::Fault),
        (E::Fault(FaultCause::HeartbeatTimeout), s) => Ok(s),
        // Faults win everywhere, e-stop included.
        (E::Fault(_), _) => Ok(S::Fault),
        // Flags only.
        (
            E::Clutch { .. } | E::OperatorPresent { .. } | E::HeartbeatLost | E::HeartbeatRestored,
            s,
        ) => Ok(s),

        (E::BootDone, S::Boot) => Ok(S::Disabled),
        (E::BootDone, _) => Err(Refusal::NotAllowed),

        (_, S::Boot) => Err(Refusal::Booting),

        (E::Enable, S::Ready) => Ok(S::Enabling),
        (E::Enable, S::Enabling | S::Enabled) => Ok(state),
        (E::Enable, S::Disabled) => Err(Refusal::NotHomed),
        (E::Enable, S::Homing) => Err(Refusal::Busy),
        (E::Enable, S::Fault) => Err(Refusal::Faulted),

        (E::EnableDone, S::Enabling) => Ok(S::Enabled),
        (E::EnableDone, _) => Err(Refusal::NotAllowed),

        (E::Disable, S::Disabled | S::Homing) => Ok(S::Disabled),
        (E::Disable, S::Ready | S::Enabling | S::Enabled) => Ok(S::Ready),
        (E::Disable, S::Fault) => Err(Refusal::Faulted),

        (E::Home { rehome: false }, S::Ready) if homed => Err(Refusal::AlreadyHomed),
        (E::Home { .. }, S::Disabled | S::Ready) => Ok(S::Homing),
        (E::Home { .. }, S::Homing) => Err(Refusal::Busy),
        (E::Home { .. }, S::Enabling | S::Enabled) => Err(Refusal::NotAllowed),
        (E::Home { .. }, S::Fault) => Err(Refusal::Faulted),

        (E::HomingDone, S::Homing) => Ok(S::Ready),
        (E::HomingDone, _) => Err(Refusal::NotAllowed),

        (E::ClearFault { cause_active: true }, S::Fault) => Err(Refusal::FaultStillActive),
        (E::ClearFault { .. }, S::Fault) => Ok(if homed { S::Ready } else { S::Disabled }),
        (E::ClearFault { .. }, s) => Ok(s),
    }
}

/// An accepted event.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Transition {
    /// State before.
    pub from: State,
    /// State after (may equal `from`).
    pub to: State,
    /// The event.
    pub event: Event,
}

impl Transition {
    /// The state changed.
    pub fn changed(&self) -> bool {
        self.from != self.to
    }
}

/// Why the robot holds while enabled.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Hold {
    /// The clutch is engaged.
    pub clutch: bool,
    /// The operator is absent (dead-man released).
    pub operator_absent: bool,
    /// The heartbeat is late.
    pub heartbeat: bool,
}

/// The state machine with its flags.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct StateMachine {
    state: State,
    homed: bool,
    faults: Faults,
    clutch: bool,
    operator_present: bool,
    heartbeat_late: bool,
    transitions: u32,
    refusals: u32,
}

impl Default for StateMachine {
    fn default() -> Self {
        Self::new()
    }
}

impl StateMachine {
    /// In `Boot`, not homed, no fault, clutch released, the operator present (a master
    /// without a dead-man never sends `OperatorPresent`).
    pub const fn new() -> Self {
        StateMachine {
            state: State::Boot,
            homed: false,
            faults: Faults::NONE,
            clutch: false,
            operator_present: true,
            heartbeat_late: false,
            transitions: 0,
            refusals: 0,
        }
    }

    /// A master session starts (`Hello`): the previous master's clutch and presence are
    /// forgotten (clutch released, operator present, as at power-up); the new master sends
    /// its own.
    pub fn new_master(&mut self) {
        self.clutch = false;
        self.operator_present = true;
    }

    /// Applies an event (see [`next_state`]).
    pub fn handle(&mut self, event: Event) -> Result<Transition, Refusal> {
        let from = self.state;
        let to = match next_state(from, event, self.homed) {
            Ok(to) => to,
            Err(r) => {
                self.refusals = self.refusals.wrapping_add(1);
                return Err(r);
            }
        };
        if to == State::Fault {
            if let Some(bits) = event.fault_bits() {
                self.faults.insert(bits);
                // Faults that make the encoder reference doubtful lose the homing.
                if bits.intersects(
                    Faults::FOLLOWING_ERROR
                        | Faults::ENCODER
                        | Faults::HOMING_FAILED
                        | Faults::INTERNAL,
                ) {
                    self.homed = false;
                }
            }
        }
        match event {
            Event::Clutch { engaged } => self.clutch = engaged,
            Event::OperatorPresent { present } => self.operator_present = present,
            Event::HeartbeatLost if to == State::Enabled => self.heartbeat_late = true,
            Event::HeartbeatRestored => self.heartbeat_late = false,
            Event::HomingDone => self.homed = true,
            Event::Home { .. } => self.homed = false,
            Event::ClearFault { .. } if from == State::Fault => self.faults = Faults::NONE,
            _ => {}
        }
        if to != State::Enabled {
            self.heartbeat_late = false;
        }
        if from != to {
            self.transitions = self.transitions.wrapping_add(1);
        }
        self.state = to;
        Ok(Transition { from, to, event })
    }

    /// The state.
    pub fn state(&self) -> State {
        self.state
    }
    /// The homing is trusted.
    pub fn homed(&self) -> bool {
        self.homed
    }
    /// The latched faults (empty unless in `Fault`).
    pub fn faults(&self) -> Faults {
        self.faults
    }
    /// The clutch pedal is pressed.
    pub fn clutch_engaged(&self) -> bool {
        self.clutch
    }
    /// The operator is present.
    pub fn operator_present(&self) -> bool {
        self.operator_present
    }
    /// Enabled and holding: why.
    pub fn hold(&self) -> Option<Hold> {
        let hold = Hold {
            clutch: self.clutch,
            operator_absent: !self.operator_present,
            heartbeat: self.heartbeat_late,
        };
        (self.state == State::Enabled && (hold.clutch || hold.operator_absent || hold.heartbeat))
            .then_some(hold)
    }
    /// Enabled and following the master.
    pub fn following(&self) -> bool {
        self.state == State::Enabled && self.hold().is_none()
    }
    /// The drives may produce torque (homing, enabling or enabled); in every other state
    /// they are off unless a stop in progress still holds the robot.
    pub fn drives_on(&self) -> bool {
        matches!(self.state, State::Homing | State::Enabling | State::Enabled)
    }
    /// Whether a pose target is taken now, or why not.
    pub fn target_gate(&self) -> Result<(), Refusal> {
        match self.state {
            State::Enabled => match self.hold() {
                Some(h) if h.operator_absent && !h.clutch && !h.heartbeat => {
                    Err(Refusal::OperatorAbsent)
                }
                Some(_) => Err(Refusal::Holding),
                None => Ok(()),
            },
            State::Boot => Err(Refusal::Booting),
            State::Disabled => Err(Refusal::NotHomed),
            State::Homing | State::Enabling => Err(Refusal::Busy),
            State::Ready => Err(Refusal::NotAllowed),
            State::Fault => Err(Refusal::Faulted),
        }
    }
    /// State changes so far.
    pub fn transitions(&self) -> u32 {
        self.transitions
    }
    /// Refused events so far.
    pub fn refusals(&self) -> u32 {
        self.refusals
    }
}
