//! The board's named state machine.
//!
//! ## States (the protocol's [`RobotState`])
//! `Boot -> Disabled -> Homing -> Ready -> Enabled -> Fault`:
//! * `Boot`: power-up; drives off; only the e-stop and the clutch pedal are taken.
//! * `Disabled`: drives off, **not homed** (the encoders are incremental).
//! * `Homing`: the board homes the joints one by one ([`crate::homing::Homing`]), drives on.
//! * `Ready`: homed, drives off.
//! * `Enabled`: drives on, following the master's targets, or holding (clutch engaged or
//!   heartbeat late: targets refused, the robot stops at its current setpoint).
//! * `Fault`: latched until `ClearFault` (refused while the cause is still present);
//!   drives off. Clearing returns to `Ready` if the homing is still trusted (an e-stop
//!   keeps it; tracking, encoder and homing faults lose it), else to `Disabled`.
//!
//! The table is [`next_state`], a pure function; [`StateMachine`] adds the flags (homed,
//! clutch, heartbeat hold, latched faults). `Disable` leaves the homing valid: from
//! `Enabled` it goes to `Ready` (drives off, homed), the protocol's "-> Disabled" meaning
//! "drives off".

use master_link::{Faults, NackReason, RobotState};

/// The state names are the protocol's.
pub type State = RobotState;

/// Every state, in order.
pub const ALL_STATES: [State; 6] = [
    State::Boot,
    State::Disabled,
    State::Homing,
    State::Ready,
    State::Enabled,
    State::Fault,
];

/// What can happen to the state machine.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Event {
    /// Power-up self test finished.
    BootDone,
    /// Master: enable the drives (Ready -> Enabled).
    Enable,
    /// Master: drives off.
    Disable,
    /// Master: start homing.
    Home,
    /// The homing procedure finished.
    HomingDone,
    /// The homing procedure failed.
    HomingFailed,
    /// Master clutch pedal. Engaged: targets are ignored and the robot holds while the
    /// master repositions.
    Clutch {
        /// Pedal pressed.
        engaged: bool,
    },
    /// Heartbeat late: hold.
    HeartbeatLost,
    /// Heartbeat lost for longer: drives off.
    HeartbeatLostLong,
    /// A heartbeat arrived again (ends a heartbeat hold; not a lost one).
    HeartbeatRestored,
    /// Emergency stop (message or input).
    EmergencyStop,
    /// The servo's tracking-error monitor tripped.
    TrackingFault,
    /// Any other detected fault (the bits to latch; empty means `INTERNAL`).
    Fault(Faults),
    /// Master: clear the latched fault; `cause_active` when its cause is still present
    /// (e.g. the e-stop input is still pressed).
    ClearFault {
        /// The cause is still present.
        cause_active: bool,
    },
}

impl Event {
    /// One of each event (both values of the flags), for exhaustive tests.
    pub const ALL: [Event; 16] = [
        Event::BootDone,
        Event::Enable,
        Event::Disable,
        Event::Home,
        Event::HomingDone,
        Event::HomingFailed,
        Event::Clutch { engaged: true },
        Event::Clutch { engaged: false },
        Event::HeartbeatLost,
        Event::HeartbeatLostLong,
        Event::HeartbeatRestored,
        Event::EmergencyStop,
        Event::TrackingFault,
        Event::Fault(Faults::OVERCURRENT),
        Event::ClearFault {
            cause_active: false,
        },
        Event::ClearFault { cause_active: true },
    ];

    /// The fault bits this event latches, if it is a fault.
    pub fn fault_bits(&self) -> Option<Faults> {
        match self {
            Event::EmergencyStop => Some(Faults::EMERGENCY_STOP),
            Event::TrackingFault => Some(Faults::FOLLOWING_ERROR),
            Event::HomingFailed => Some(Faults::HOMING_FAILED),
            Event::Fault(f) if f.is_empty() => Some(Faults::INTERNAL),
            Event::Fault(f) => Some(*f),
            _ => None,
        }
    }
}

/// Why an event was refused (the state does not change).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Refusal {
    /// The board is still booting.
    Booting,
    /// Homing is in progress.
    Busy,
    /// Home first.
    NotHomed,
    /// A fault is latched: send `ClearFault`.
    Faulted,
    /// The fault's cause is still present.
    FaultStillActive,
    /// Not allowed in this state (e.g. `Home` while enabled; `HomingDone` when not homing).
    NotAllowed,
    /// Enabled but holding (clutch engaged or heartbeat late): targets are refused.
    Holding,
    /// The robot is at a pose the setpoint supervisor refuses to start from.
    UnsafeStart,
}

impl Refusal {
    /// The reason sent to the master.
    pub const fn nack_reason(self) -> NackReason {
        match self {
            Refusal::Booting | Refusal::Busy => NackReason::Busy,
            Refusal::NotHomed => NackReason::NotHomed,
            Refusal::Faulted => NackReason::Faulted,
            Refusal::FaultStillActive => NackReason::FaultStillActive,
            Refusal::NotAllowed | Refusal::Holding => NackReason::InvalidState,
            Refusal::UnsafeStart => NackReason::OutOfWorkspace,
        }
    }
}

impl From<Refusal> for NackReason {
    fn from(r: Refusal) -> Self {
        r.nack_reason()
    }
}

/// The transition table: the state after `event` in `state` (`homed`: whether the
/// homing is trusted, which only matters for `ClearFault`), or why it is refused.
/// Events that only set a flag (clutch, heartbeat hold) keep the state.
pub const fn next_state(state: State, event: Event, homed: bool) -> Result<State, Refusal> {
    use Event as E;
    use State as S;
    match (event, state) {
        // Faults win everywhere, e-stop included.
        (E::EmergencyStop | E::TrackingFault | E::Fault(_), _) => Ok(S::Fault),
        // Flags only.
        (E::Clutch { .. } | E::HeartbeatLost | E::HeartbeatRestored, s) => Ok(s),

        (E::BootDone, S::Boot) => Ok(S::Disabled),
        (E::BootDone, _) => Err(Refusal::NotAllowed),

        (E::HeartbeatLostLong, S::Enabled) => Ok(S::Ready),
        (E::HeartbeatLostLong, S::Homing) => Ok(S::Disabled),
        (E::HeartbeatLostLong, s) => Ok(s),

        (_, S::Boot) => Err(Refusal::Booting),

        (E::Enable, S::Ready | S::Enabled) => Ok(S::Enabled),
        (E::Enable, S::Disabled) => Err(Refusal::NotHomed),
        (E::Enable, S::Homing) => Err(Refusal::Busy),
        (E::Enable, S::Fault) => Err(Refusal::Faulted),

        (E::Disable, S::Disabled | S::Homing) => Ok(S::Disabled),
        (E::Disable, S::Ready | S::Enabled) => Ok(S::Ready),
        (E::Disable, S::Fault) => Err(Refusal::Faulted),

        (E::Home, S::Disabled | S::Ready) => Ok(S::Homing),
        (E::Home, S::Homing) => Err(Refusal::Busy),
        (E::Home, S::Enabled) => Err(Refusal::NotAllowed),
        (E::Home, S::Fault) => Err(Refusal::Faulted),

        (E::HomingDone, S::Homing) => Ok(S::Ready),
        (E::HomingFailed, S::Homing) => Ok(S::Fault),
        (E::HomingDone | E::HomingFailed, _) => Err(Refusal::NotAllowed),

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
    /// In `Boot`, not homed, no fault, clutch released.
    pub const fn new() -> Self {
        StateMachine {
            state: State::Boot,
            homed: false,
            faults: Faults::NONE,
            clutch: false,
            heartbeat_late: false,
            transitions: 0,
            refusals: 0,
        }
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
        match event {
            Event::Clutch { engaged } => self.clutch = engaged,
            Event::HeartbeatLost if to == State::Enabled => self.heartbeat_late = true,
            Event::HeartbeatRestored => self.heartbeat_late = false,
            Event::HomingDone => self.homed = true,
            Event::Home => self.homed = false,
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
    /// Enabled and holding: why.
    pub fn hold(&self) -> Option<Hold> {
        let hold = Hold {
            clutch: self.clutch,
            heartbeat: self.heartbeat_late,
        };
        (self.state == State::Enabled && (hold.clutch || hold.heartbeat)).then_some(hold)
    }
    /// Enabled and following the master.
    pub fn following(&self) -> bool {
        self.state == State::Enabled && self.hold().is_none()
    }
    /// The drives may be on (homing or enabled); in every other state all outputs are off.
    pub fn drives_on(&self) -> bool {
        matches!(self.state, State::Homing | State::Enabled)
    }
    /// Whether a pose target is taken now, or why not.
    pub fn target_gate(&self) -> Result<(), Refusal> {
        match self.state {
            State::Enabled if self.hold().is_some() => Err(Refusal::Holding),
            State::Enabled => Ok(()),
            State::Boot => Err(Refusal::Booting),
            State::Disabled => Err(Refusal::NotHomed),
            State::Homing => Err(Refusal::Busy),
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
