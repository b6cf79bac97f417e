//! The board's named state machine, the homing procedure and the runtime that drives both
//! from the control tick.
//!
//! ## States (the protocol's [`RobotState`])
//! `Boot -> Disabled -> Homing -> Ready -> Enabled -> Fault`:
//! * `Boot`: power-up; drives off; only the e-stop and the clutch pedal are taken.
//! * `Disabled`: drives off, **not homed** (the encoders are incremental).
//! * `Homing`: the board homes the joints one by one ([`Homing`]), drives on.
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

use crate::controller::{Controller, ControllerConfig, ControllerError, Scalar, TickReport};
use crate::failsafe::{HeartbeatConfig, HeartbeatMonitor};
use crate::link::{self, Command, TargetClock, TargetClockConfig};
use kinematics_core::{forward, FkConfig, Joints, Mechanism, Pose};
use master_link::{Faults, NackReason, RobotState, StatusReport, Warnings};
use num_traits::Float;
use servo::config::ConfigError;
use servo::encoder::{EncoderConfig, Encoders};
use servo::hal::{CurrentSense, MotorOutputs, QuadratureCounter};
use servo::joint_servo::JointServo;
use servo::{ServoConfig, NUM_JOINTS};

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

// ---------------------------------------------------------------------------------------
// Homing
// ---------------------------------------------------------------------------------------

/// The home/limit switches, one per joint (e.g. GPIO inputs).
pub trait LimitSwitches {
    /// Each joint's switch, `true` when actuated, joint order.
    fn switches(&mut self) -> [bool; NUM_JOINTS];
}

impl<T: LimitSwitches + ?Sized> LimitSwitches for &mut T {
    fn switches(&mut self) -> [bool; NUM_JOINTS] {
        (**self).switches()
    }
}

/// How a joint finds its reference.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum HomeMethod {
    /// Drive to the home switch; a stall before it is a failure.
    Switch,
    /// Drive into the mechanical stop under the current/duty limit; the stall is the
    /// reference.
    HardStop,
}

/// Homing of one joint. Joint units: m (legs), rad (links); currents in A.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct JointHoming<S> {
    /// Switch or hard stop.
    pub method: HomeMethod,
    /// Approach towards `+q` (else towards `-q`).
    pub towards_positive: bool,
    /// Joint position at the switch point or the stop.
    pub home_position: S,
    /// |duty| while approaching (slow), within the duty limit.
    pub approach_duty: S,
    /// |duty| while backing off.
    pub backoff_duty: S,
    /// Distance to back off from the reference.
    pub backoff_distance: S,
    /// Largest travel while searching before giving up.
    pub max_travel: S,
    /// Above this |current| the duty is cut for the tick (the current limit); lasting
    /// for the stall time it counts as a stall. Infinite disables it.
    pub current_limit: S,
}

/// Homing settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HomingConfig<S> {
    /// Per joint.
    pub joints: [JointHoming<S>; NUM_JOINTS],
    /// Joints in the order they are homed (each index once).
    pub order: [u8; NUM_JOINTS],
    /// Largest |duty| of any homing move.
    pub duty_limit: S,
    /// No motion of at least `stall_counts` for this long while driving is a stall, µs.
    pub stall_time_us: u64,
    /// Counts that make "motion".
    pub stall_counts: i64,
    /// Longest time of one phase of one joint, µs.
    pub phase_timeout_us: u64,
    /// After homing, move in joint space to these positions (e.g. the central
    /// configuration), or stay where the last back-off ended.
    pub park: Option<[S; NUM_JOINTS]>,
    /// Park move speed per joint (m/s, rad/s).
    pub park_speed: [S; NUM_JOINTS],
    /// Park done when every |error| is within this (m, rad).
    pub park_tolerance: [S; NUM_JOINTS],
}

impl<S: Float> HomingConfig<S> {
    /// Placeholder settings for the reference robot (to be confirmed on the mechanics):
    /// legs home on a switch at the short end of the stroke (150 mm), links against a
    /// hard stop 60 deg below the central angle (`link_centre` is the central θ of each
    /// link, rad); park at `park`.
    pub fn reference(link_centre: [S; 3], park: Option<[S; NUM_JOINTS]>) -> Self {
        let lit = |x: f64| S::from(x).unwrap_or_else(S::zero);
        let leg = JointHoming {
            method: HomeMethod::Switch,
            towards_positive: false,
            home_position: lit(0.150),
            approach_duty: lit(0.03),
            backoff_duty: lit(0.04),
            backoff_distance: lit(0.002),
            max_travel: lit(0.080),
            current_limit: lit(3.0),
        };
        let link = |centre: S| JointHoming {
            method: HomeMethod::HardStop,
            towards_positive: false,
            home_position: centre - lit(60f64.to_radians()),
            approach_duty: lit(0.02),
            backoff_duty: lit(0.03),
            backoff_distance: lit(0.05),
            max_travel: lit(3.5),
            current_limit: lit(0.6),
        };
        let [c1, c2, c3] = link_centre;
        HomingConfig {
            joints: [leg, leg, leg, link(c1), link(c2), link(c3)],
            order: [0, 1, 2, 3, 4, 5],
            duty_limit: lit(0.3),
            stall_time_us: 150_000,
            stall_counts: 4,
            phase_timeout_us: 30_000_000,
            park,
            park_speed: [
                lit(0.005),
                lit(0.005),
                lit(0.005),
                lit(0.1),
                lit(0.1),
                lit(0.1),
            ],
            park_tolerance: [
                lit(0.2e-3),
                lit(0.2e-3),
                lit(0.2e-3),
                lit(0.005),
                lit(0.005),
                lit(0.005),
            ],
        }
    }

    /// Checks the settings.
    pub fn validate(&self) -> Result<(), HomingError> {
        let bad = |joint: usize| Err(HomingError::Config { joint });
        let mut seen = [false; NUM_JOINTS];
        for j in self.order {
            match seen.get_mut(usize::from(j)) {
                Some(s) if !*s => *s = true,
                _ => return bad(usize::from(j)),
            }
        }
        let pos = |x: S| x.is_finite() && x > S::zero();
        if !(pos(self.duty_limit) && self.duty_limit <= S::one()) || self.stall_time_us == 0 {
            return bad(0);
        }
        for (j, h) in self.joints.iter().enumerate() {
            let ok = h.home_position.is_finite()
                && pos(h.approach_duty)
                && pos(h.backoff_duty)
                && pos(h.backoff_distance)
                && pos(h.max_travel)
                && h.current_limit > S::zero()
                && !h.current_limit.is_nan();
            if !ok {
                return bad(j);
            }
        }
        for j in 0..NUM_JOINTS {
            let speed = self.park_speed.get(j).copied().unwrap_or_else(S::zero);
            let tol = self.park_tolerance.get(j).copied().unwrap_or_else(S::zero);
            let park_ok = match self.park {
                Some(p) => p.get(j).is_some_and(|x| x.is_finite()),
                None => true,
            };
            if !(pos(speed) && pos(tol) && park_ok) {
                return bad(j);
            }
        }
        Ok(())
    }
}

/// Why homing failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum HomingError {
    /// A setting is invalid (the joint it concerns).
    Config {
        /// Joint.
        joint: usize,
    },
    /// A phase took longer than `phase_timeout_us`.
    Timeout {
        /// Joint.
        joint: usize,
    },
    /// Travelled `max_travel` without finding the reference.
    NotFound {
        /// Joint.
        joint: usize,
    },
    /// Stalled before reaching its switch (obstacle, jam).
    StalledBeforeSwitch {
        /// Joint.
        joint: usize,
    },
    /// The switch stayed actuated after backing off.
    SwitchStuck {
        /// Joint.
        joint: usize,
    },
    /// The park move tripped the tracking monitor or did not settle.
    Park,
}

/// The homing procedure's phase.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum HomingPhase {
    /// Not started.
    Idle,
    /// Driving off a switch that was already actuated at the start.
    LeaveSwitch {
        /// Joint.
        joint: usize,
    },
    /// Driving slowly towards the switch or stop.
    Approach {
        /// Joint.
        joint: usize,
    },
    /// Backing off from the reference.
    BackOff {
        /// Joint.
        joint: usize,
    },
    /// Joint-space move to the park position.
    Park,
    /// Finished.
    Done,
    /// Failed.
    Failed(HomingError),
}

/// What one homing step reports.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum HomingStatus<S> {
    /// Still going.
    Running(HomingPhase),
    /// Homed: the raw counters `raw` read the joint positions `q`.
    Done {
        /// Raw counters.
        raw: [u16; NUM_JOINTS],
        /// Joint positions.
        q: [S; NUM_JOINTS],
    },
    /// Failed; every output is off.
    Failed(HomingError),
}

/// The homing procedure, one [`Homing::step`] per control tick.
#[derive(Clone, Debug)]
pub struct Homing<S> {
    cfg: HomingConfig<S>,
    encoders: Encoders<S>,
    servo: JointServo<S>,
    phase: HomingPhase,
    /// Index into `order`.
    index: usize,
    phase_start_us: u64,
    phase_start_q: S,
    motion_count: i64,
    motion_us: u64,
    over_current_since: Option<u64>,
    /// Current limiting: the factor on the commanded duty.
    duty_scale: S,
    park_from: [S; NUM_JOINTS],
    park_duration_s: S,
    park_start_us: u64,
    last_us: u64,
    raw: [u16; NUM_JOINTS],
    /// First step of the phase.
    fresh: bool,
}

fn joint_of<S>(cfg: &HomingConfig<S>, index: usize) -> Option<usize> {
    cfg.order.get(index).map(|j| usize::from(*j))
}

impl<S: Float> Homing<S> {
    /// A homing procedure (validates `cfg`; the servo settings are for the park move).
    pub fn new(
        cfg: &HomingConfig<S>,
        encoders: &EncoderConfig<S>,
        servo: &ServoConfig<S>,
    ) -> Result<Self, HomingSetupError> {
        cfg.validate().map_err(HomingSetupError::Homing)?;
        Ok(Homing {
            cfg: *cfg,
            encoders: Encoders::new(encoders).map_err(HomingSetupError::Servo)?,
            servo: JointServo::new(servo).map_err(HomingSetupError::Servo)?,
            phase: HomingPhase::Idle,
            index: 0,
            phase_start_us: 0,
            phase_start_q: S::zero(),
            motion_count: 0,
            motion_us: 0,
            over_current_since: None,
            duty_scale: S::one(),
            park_from: [S::zero(); NUM_JOINTS],
            park_duration_s: S::zero(),
            park_start_us: 0,
            last_us: 0,
            raw: [0; NUM_JOINTS],
            fresh: false,
        })
    }

    /// The settings.
    pub fn config(&self) -> &HomingConfig<S> {
        &self.cfg
    }
    /// The phase.
    pub fn phase(&self) -> HomingPhase {
        self.phase
    }
    /// The encoders as homed so far (joints not yet homed read relative positions).
    pub fn encoders(&self) -> &Encoders<S> {
        &self.encoders
    }

    /// Starts homing with the board's encoders as they are (their extension continues).
    pub fn start(&mut self, encoders: &Encoders<S>, now_us: u64) {
        self.encoders = *encoders;
        self.index = 0;
        self.last_us = now_us;
        match joint_of(&self.cfg, 0) {
            Some(j) => self.enter(HomingPhase::Approach { joint: j }, now_us),
            None => self.phase = HomingPhase::Failed(HomingError::Config { joint: 0 }),
        }
    }

    /// The raw counters at the last step.
    pub fn raw(&self) -> [u16; NUM_JOINTS] {
        self.raw
    }

    /// Aborts: the phase becomes `Idle` (the caller turns the outputs off).
    pub fn abort(&mut self) {
        self.phase = HomingPhase::Idle;
    }

    fn enter(&mut self, phase: HomingPhase, now_us: u64) {
        self.phase = phase;
        self.fresh = true;
        self.phase_start_us = now_us;
        self.motion_us = now_us;
        self.over_current_since = None;
        self.duty_scale = S::one();
        if let HomingPhase::LeaveSwitch { joint }
        | HomingPhase::Approach { joint }
        | HomingPhase::BackOff { joint } = phase
        {
            self.phase_start_q = self
                .encoders
                .positions()
                .get(joint)
                .copied()
                .unwrap_or_else(S::zero);
            self.motion_count = self.encoders.counts().get(joint).copied().unwrap_or(0);
        }
    }

    fn fail<H: MotorOutputs<S>>(&mut self, hw: &mut H, e: HomingError) -> HomingStatus<S> {
        hw.set_duties(&[S::zero(); NUM_JOINTS]);
        hw.disable();
        self.phase = HomingPhase::Failed(e);
        HomingStatus::Failed(e)
    }

    fn next_joint(&mut self, now_us: u64) {
        self.index += 1;
        match joint_of(&self.cfg, self.index) {
            Some(j) => self.enter(HomingPhase::Approach { joint: j }, now_us),
            None => match self.cfg.park {
                Some(_) => self.start_park(now_us),
                None => self.phase = HomingPhase::Done,
            },
        }
    }

    fn start_park(&mut self, now_us: u64) {
        let q = self.encoders.positions();
        self.park_from = q;
        self.servo.reset(&q);
        let mut t = S::zero();
        if let Some(park) = self.cfg.park {
            for ((p, q0), v) in park.iter().zip(q.iter()).zip(self.cfg.park_speed.iter()) {
                t = t.max((*p - *q0).abs() / *v);
            }
        }
        self.park_duration_s = t;
        self.park_start_us = now_us;
        self.enter(HomingPhase::Park, now_us);
    }

    /// One step: reads the encoders, switches and currents, drives the outputs.
    pub fn step<H>(&mut self, hw: &mut H, now_us: u64) -> HomingStatus<S>
    where
        H: QuadratureCounter + MotorOutputs<S> + LimitSwitches + CurrentSense<S>,
    {
        let dt_us = now_us.saturating_sub(self.last_us);
        self.last_us = now_us;
        self.raw = hw.counts();
        let q = self.encoders.update(&self.raw);
        let counts = self.encoders.counts();
        let switches = hw.switches();
        let currents = hw.currents();
        let elapsed = now_us.saturating_sub(self.phase_start_us);
        let mut duty = [S::zero(); NUM_JOINTS];
        match self.phase {
            HomingPhase::Idle => {
                hw.set_duties(&duty);
                return HomingStatus::Running(HomingPhase::Idle);
            }
            HomingPhase::Failed(e) => return self.fail(hw, e),
            HomingPhase::Done => {
                hw.set_duties(&duty);
                return HomingStatus::Done { raw: self.raw, q };
            }
            HomingPhase::LeaveSwitch { joint }
            | HomingPhase::Approach { joint }
            | HomingPhase::BackOff { joint } => {
                let (Some(h), Some(&qj), Some(&cj), Some(&sw), Some(&ij)) = (
                    self.cfg.joints.get(joint).copied(),
                    q.get(joint),
                    counts.get(joint),
                    switches.get(joint),
                    currents.get(joint),
                ) else {
                    return self.fail(hw, HomingError::Config { joint });
                };
                let fresh = core::mem::replace(&mut self.fresh, false);
                if elapsed > self.cfg.phase_timeout_us {
                    return self.fail(hw, HomingError::Timeout { joint });
                }
                // Motion / stall tracking.
                if (cj - self.motion_count).abs() >= self.cfg.stall_counts {
                    self.motion_count = cj;
                    self.motion_us = now_us;
                }
                // Current limit: scale the duty down while above it, relax back
                // slowly; running at (90 % of) the limit for the stall time is a stall.
                let i_abs = ij.abs();
                if i_abs > h.current_limit {
                    self.duty_scale = (self.duty_scale * h.current_limit / i_abs).min(S::one());
                } else {
                    let relax = S::from(1.05).unwrap_or_else(S::one);
                    self.duty_scale = (self.duty_scale * relax).min(S::one());
                }
                let near = S::from(0.9).unwrap_or_else(S::one);
                if i_abs >= h.current_limit * near {
                    self.over_current_since.get_or_insert(now_us);
                } else {
                    self.over_current_since = None;
                }
                let stalled = now_us.saturating_sub(self.motion_us) >= self.cfg.stall_time_us
                    || self
                        .over_current_since
                        .is_some_and(|t| now_us.saturating_sub(t) >= self.cfg.stall_time_us);
                let scale = self.duty_scale;
                let travel = (qj - self.phase_start_q).abs();
                let sign = if h.towards_positive {
                    S::one()
                } else {
                    -S::one()
                };
                let limit = self.cfg.duty_limit;
                match self.phase {
                    HomingPhase::Approach { .. } => {
                        if h.method == HomeMethod::Switch && sw && fresh {
                            // Already on the switch at the start: leave it first.
                            self.enter(HomingPhase::LeaveSwitch { joint }, now_us);
                        } else if h.method == HomeMethod::Switch && sw {
                            // The reference: the position where the switch closes.
                            self.encoders.set_position(joint, h.home_position);
                            self.enter(HomingPhase::BackOff { joint }, now_us);
                        } else if stalled {
                            if h.method == HomeMethod::HardStop {
                                self.encoders.set_position(joint, h.home_position);
                                self.enter(HomingPhase::BackOff { joint }, now_us);
                            } else {
                                return self.fail(hw, HomingError::StalledBeforeSwitch { joint });
                            }
                        } else if travel > h.max_travel {
                            return self.fail(hw, HomingError::NotFound { joint });
                        } else {
                            set(&mut duty, joint, sign * h.approach_duty.min(limit) * scale);
                        }
                    }
                    HomingPhase::LeaveSwitch { .. } => {
                        if !sw {
                            self.enter(HomingPhase::Approach { joint }, now_us);
                        } else if travel > h.max_travel || stalled {
                            return self.fail(hw, HomingError::SwitchStuck { joint });
                        } else {
                            set(&mut duty, joint, -sign * h.backoff_duty.min(limit) * scale);
                        }
                    }
                    _ => {
                        // Back off.
                        if travel >= h.backoff_distance {
                            if h.method == HomeMethod::Switch && sw {
                                return self.fail(hw, HomingError::SwitchStuck { joint });
                            }
                            self.next_joint(now_us);
                        } else if stalled {
                            return self.fail(hw, HomingError::Timeout { joint });
                        } else {
                            set(&mut duty, joint, -sign * h.backoff_duty.min(limit) * scale);
                        }
                    }
                }
            }
            HomingPhase::Park => {
                let Some(park) = self.cfg.park else {
                    self.phase = HomingPhase::Done;
                    hw.set_duties(&duty);
                    return HomingStatus::Running(self.phase);
                };
                let us = S::from(1e-6).unwrap_or_else(S::zero);
                let t =
                    S::from(now_us.saturating_sub(self.park_start_us)).unwrap_or_else(S::zero) * us;
                let total = self.park_duration_s;
                let s = if total > S::zero() {
                    (t / total).min(S::one())
                } else {
                    S::one()
                };
                let mut sp = [S::zero(); NUM_JOINTS];
                let mut spd = [S::zero(); NUM_JOINTS];
                for j in 0..NUM_JOINTS {
                    let (Some(a), Some(b)) = (self.park_from.get(j), park.get(j)) else {
                        continue;
                    };
                    set(&mut sp, j, *a + (*b - *a) * s);
                    if s < S::one() && total > S::zero() {
                        set(&mut spd, j, (*b - *a) / total);
                    }
                }
                let dt = S::from(dt_us.max(1)).unwrap_or_else(S::one) * us;
                let out = self.servo.update(&sp, &spd, &q, dt);
                if out.fault.is_some() {
                    return self.fail(hw, HomingError::Park);
                }
                let settled = park
                    .iter()
                    .zip(q.iter())
                    .zip(self.cfg.park_tolerance.iter())
                    .all(|((p, m), tol)| (*p - *m).abs() <= *tol);
                if s >= S::one() && settled {
                    self.phase = HomingPhase::Done;
                    hw.set_duties(&duty);
                    return HomingStatus::Done { raw: self.raw, q };
                }
                if elapsed > self.cfg.phase_timeout_us {
                    return self.fail(hw, HomingError::Park);
                }
                for (d, o) in duty.iter_mut().zip(out.duty.iter()) {
                    *d = o.max(-self.cfg.duty_limit).min(self.cfg.duty_limit);
                }
            }
        }
        hw.set_duties(&duty);
        match self.phase {
            HomingPhase::Done => HomingStatus::Done { raw: self.raw, q },
            p => HomingStatus::Running(p),
        }
    }
}

fn set<S: Copy>(a: &mut [S; NUM_JOINTS], j: usize, v: S) {
    if let Some(x) = a.get_mut(j) {
        *x = v;
    }
}

/// Why a [`Homing`] or [`Runtime`] cannot be set up.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum HomingSetupError {
    /// Homing settings.
    Homing(HomingError),
    /// Servo or encoder settings.
    Servo(ConfigError),
}

// ---------------------------------------------------------------------------------------
// Runtime
// ---------------------------------------------------------------------------------------

/// Everything the runtime needs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RuntimeConfig<S: Scalar> {
    /// The control application.
    pub controller: ControllerConfig<S>,
    /// Homing.
    pub homing: HomingConfig<S>,
    /// Heartbeat hold / disable times.
    pub heartbeat: HeartbeatConfig,
    /// Master target timestamps.
    pub targets: TargetClockConfig,
    /// Consecutive forward-kinematics failures that latch `FORWARD_KINEMATICS`.
    pub fk_failures_to_fault: u32,
}

/// What one runtime tick did.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RuntimeTick<S: Scalar> {
    /// The state after the tick.
    pub state: State,
    /// The controller's report, when it ran.
    pub control: Option<TickReport<S>>,
    /// The homing status, when homing.
    pub homing: Option<HomingStatus<S>>,
    /// Outputs were driven (else they were forced off).
    pub drives_on: bool,
}

/// The board application: the state machine, the fail-safe timers, homing and the
/// controller, driven by [`Runtime::tick`] (every control period) and
/// [`Runtime::command`] (every master request).
#[derive(Clone, Debug)]
pub struct Runtime<S: Scalar, M: Mechanism<S> + Clone> {
    robot: M,
    cfg: RuntimeConfig<S>,
    sm: StateMachine,
    encoders: Encoders<S>,
    raw: [u16; NUM_JOINTS],
    homing: Homing<S>,
    controller: Option<Controller<S, M>>,
    /// The jog stream in progress: (joint, time of the last Jog, the joints it aims at).
    jog: Option<(usize, u64, Joints<S>)>,
    heartbeat: HeartbeatMonitor,
    targets: TargetClock,
    measured_q: [S; NUM_JOINTS],
    measured_pose: Pose<S>,
    fk_failures_in_row: u32,
    warnings: Warnings,
    /// Worst tick jitter and execution time, µs (from the board).
    tick_timing: (u32, u32),
    estop_input: bool,
    was_holding: bool,
    outputs_on: bool,
}

impl<S: Scalar, M: Mechanism<S> + Clone> Runtime<S, M> {
    /// In `Boot`; call [`Runtime::boot_done`] once the hardware is up.
    pub fn new(robot: M, cfg: RuntimeConfig<S>, now_us: u64) -> Result<Self, HomingSetupError> {
        let homing = Homing::new(&cfg.homing, &cfg.controller.encoders, &cfg.controller.servo)?;
        let encoders = Encoders::new(&cfg.controller.encoders).map_err(HomingSetupError::Servo)?;
        cfg.heartbeat
            .validate()
            .map_err(|_| HomingSetupError::Homing(HomingError::Config { joint: 0 }))?;
        let central = Pose::central(robot.hc());
        Ok(Runtime {
            robot,
            sm: StateMachine::new(),
            encoders,
            raw: [0; NUM_JOINTS],
            homing,
            controller: None,
            jog: None,
            heartbeat: HeartbeatMonitor::new(cfg.heartbeat, now_us),
            targets: TargetClock::new(cfg.targets),
            measured_q: [S::zero(); NUM_JOINTS],
            measured_pose: central,
            fk_failures_in_row: 0,
            warnings: Warnings::NOT_HOMED,
            tick_timing: (0, 0),
            estop_input: false,
            was_holding: false,
            outputs_on: false,
            cfg,
        })
    }

    /// The state machine.
    pub fn machine(&self) -> &StateMachine {
        &self.sm
    }
    /// The state.
    pub fn state(&self) -> State {
        self.sm.state()
    }
    /// The controller, while enabled.
    pub fn controller(&self) -> Option<&Controller<S, M>> {
        self.controller.as_ref()
    }
    /// The homing procedure.
    pub fn homing(&self) -> &Homing<S> {
        &self.homing
    }
    /// The heartbeat monitor.
    pub fn heartbeat(&self) -> &HeartbeatMonitor {
        &self.heartbeat
    }
    /// The board's encoders (joint positions while no controller runs).
    pub fn encoders(&self) -> &Encoders<S> {
        &self.encoders
    }
    /// The robot.
    pub fn robot(&self) -> &M {
        &self.robot
    }
    /// The configuration.
    pub fn config(&self) -> &RuntimeConfig<S> {
        &self.cfg
    }

    /// Applies an event and its side effects (controller, homing, heartbeat).
    pub fn event(&mut self, ev: Event, now_us: u64) -> Result<Transition, Refusal> {
        // Building the controller may refuse the enable (unsafe start pose).
        if ev == Event::Enable && self.sm.state() == State::Ready {
            let q = self.encoders.positions();
            match Controller::new(self.robot.clone(), self.cfg.controller, self.raw, q) {
                Ok(c) => self.controller = Some(c),
                Err(ControllerError::StartPose(_) | ControllerError::Supervisor(_)) => {
                    return Err(Refusal::UnsafeStart)
                }
                Err(_) => {
                    let _ = self.sm.handle(Event::Fault(Faults::INTERNAL));
                    return Err(Refusal::NotAllowed);
                }
            }
        }
        let t = self.sm.handle(ev)?;
        if t.changed() {
            if t.to == State::Enabled {
                self.heartbeat.rearm(now_us);
                self.targets.reset();
                self.was_holding = false;
            }
            if t.to == State::Homing {
                // The master just spoke: the heartbeat timing restarts.
                self.heartbeat.rearm(now_us);
                self.homing.start(&self.encoders, now_us);
            }
            if t.from == State::Homing && t.to != State::Ready {
                self.homing.abort();
            }
        }
        if t.to != State::Enabled {
            self.controller = None;
            self.jog = None;
        }
        Ok(t)
    }

    /// The e-stop input level (asserted = pressed or wire broken), sampled every tick;
    /// while asserted the robot is in `Fault` and `ClearFault` is refused.
    pub fn set_estop_input(&mut self, asserted: bool, now_us: u64) {
        self.estop_input = asserted;
        if asserted && !self.sm.faults().contains(Faults::EMERGENCY_STOP) {
            let _ = self.event(Event::EmergencyStop, now_us);
        }
    }

    /// Power-up done: the encoders' current counters become the (unhomed) reference.
    pub fn boot_done(
        &mut self,
        raw: [u16; NUM_JOINTS],
        now_us: u64,
    ) -> Result<Transition, Refusal> {
        if let Ok(e) = Encoders::starting_at(&self.cfg.controller.encoders, &raw) {
            self.encoders = e;
        }
        self.raw = raw;
        self.event(Event::BootDone, now_us)
    }

    /// A master request (after the link layer): `Ok` to Ack, `Err` to Nack with.
    pub fn command(&mut self, cmd: &Command, now_us: u64) -> Result<(), NackReason> {
        let ev = match *cmd {
            Command::Enable => Event::Enable,
            Command::Disable => Event::Disable,
            Command::Home => Event::Home,
            Command::Clutch { engaged } => Event::Clutch { engaged },
            Command::EmergencyStop => Event::EmergencyStop,
            Command::ClearFault => Event::ClearFault {
                cause_active: self.estop_input,
            },
            Command::Heartbeat => {
                if let Some(ev) = self.heartbeat.beat(now_us) {
                    let _ = self.event(ev, now_us);
                }
                return Ok(());
            }
            Command::StatusRequest => return Ok(()),
            Command::Jog { joint, velocity } => return self.jog(joint, velocity, now_us),
            Command::Target {
                stamp_us,
                position_m,
                rotation_vector_rad,
            } => return self.target(stamp_us, position_m, rotation_vector_rad, now_us),
        };
        let cleared = matches!(ev, Event::ClearFault { .. }) && self.sm.state() == State::Fault;
        self.event(ev, now_us).map_err(NackReason::from)?;
        if cleared {
            self.warnings.remove(Warnings::HEARTBEAT_LATE);
        }
        Ok(())
    }

    /// Jog: while following (Enabled, not clutched), move joint `joint` at `velocity`
    /// (m/s or rad/s). The joint's target advances by velocity × the time since the last
    /// Jog of the same stream, and never leads the setpoint by more than velocity ×
    /// JOG_HORIZON_S: the master's repeated Jog is a dead-man, and when Jogs stop the robot
    /// stops within that horizon. The target passes the supervisor like any other (speed
    /// limits, path check, guards).
    fn jog(&mut self, joint: u8, velocity: f32, now_us: u64) -> Result<(), NackReason> {
        let j = usize::from(joint);
        if j >= NUM_JOINTS {
            return Err(NackReason::InvalidJoint);
        }
        if !velocity.is_finite() {
            return Err(NackReason::InvalidValue);
        }
        self.sm.target_gate().map_err(NackReason::from)?;
        let ctl = self.controller.as_mut().ok_or(NackReason::InvalidState)?;
        let setpoint = ctl.setpoint_joints().map_err(jog_reason)?;
        let horizon_us = (JOG_HORIZON_S * 1e6) as u64;
        // The other joints stay where the stream started, the jogged one advances.
        let (mut target, elapsed_us) = match self.jog {
            Some((jj, last, q)) if jj == j && now_us.saturating_sub(last) <= horizon_us => {
                (q, now_us.saturating_sub(last))
            }
            _ => (setpoint, horizon_us),
        };
        let here = setpoint.get(j).copied().ok_or(NackReason::InvalidJoint)?;
        let lit = kinematics_core::scalar::lit::<S>;
        let lead = lit(f64::from(velocity).abs() * JOG_HORIZON_S);
        let slot = target.get_mut(j).ok_or(NackReason::InvalidJoint)?;
        let advanced = *slot + lit(f64::from(velocity)) * lit(elapsed_us as f64 * 1e-6);
        *slot = num_traits::Float::min(num_traits::Float::max(advanced, here - lead), here + lead);
        let pose = ctl.joints_target(&target).map_err(jog_reason)?;
        let stamp = self.targets.board_stamp(now_us);
        ctl.submit(&pose, stamp, now_us)
            .map_err(|r| link::refusal_reason(&r))?;
        self.jog = Some((j, now_us, target));
        Ok(())
    }

    fn target(
        &mut self,
        stamp_us: u64,
        position_m: [f32; 3],
        rotation_vector_rad: [f32; 3],
        now_us: u64,
    ) -> Result<(), NackReason> {
        let pose = link::pose_from_wire::<S>(position_m, rotation_vector_rad)?;
        self.sm.target_gate().map_err(NackReason::from)?;
        let ctl = self.controller.as_mut().ok_or(NackReason::InvalidState)?;
        let board_stamp = self.targets.accept(stamp_us, now_us)?;
        ctl.submit(&pose, board_stamp, now_us)
            .map_err(|r| link::refusal_reason(&r))?;
        // A Cartesian target ends any jog stream.
        self.jog = None;
        Ok(())
    }

    /// One control tick: fail-safe timers, then homing or the controller, and the
    /// outputs (forced off in every state but `Homing` and `Enabled`).
    pub fn tick<H>(&mut self, hw: &mut H, now_us: u64) -> RuntimeTick<S>
    where
        H: QuadratureCounter + MotorOutputs<S> + LimitSwitches + CurrentSense<S>,
    {
        if let Some(ev) = self.heartbeat.poll(now_us) {
            let _ = self.event(ev, now_us);
        }
        let mut control = None;
        let mut homing = None;
        if self.sm.drives_on() && !self.outputs_on {
            hw.enable();
            self.outputs_on = true;
        }
        match self.sm.state() {
            State::Homing => {
                let st = self.homing.step(hw, now_us);
                homing = Some(st);
                self.encoders = *self.homing.encoders();
                self.raw = self.homing.raw();
                self.measured_q = self.encoders.positions();
                match st {
                    HomingStatus::Done { raw, q } => {
                        self.raw = raw;
                        self.measured_q = q;
                        let _ = self.event(Event::HomingDone, now_us);
                        self.update_measured_pose();
                    }
                    HomingStatus::Failed(_) => {
                        let _ = self.event(Event::HomingFailed, now_us);
                    }
                    HomingStatus::Running(_) => {}
                }
            }
            State::Enabled => control = self.control_tick(hw, now_us),
            _ => {}
        }
        let drives_on = self.sm.drives_on();
        if !drives_on {
            hw.disable();
            self.outputs_on = false;
            // Keep measuring (the master sees the robot moved by hand, the encoders keep
            // their extension).
            if self.sm.state() != State::Homing {
                self.raw = hw.counts();
                self.measured_q = self.encoders.update(&self.raw);
                if self.sm.homed() {
                    self.update_measured_pose();
                }
            }
        }
        self.update_warnings(now_us);
        RuntimeTick {
            state: self.sm.state(),
            control,
            homing,
            drives_on,
        }
    }

    fn control_tick<H>(&mut self, hw: &mut H, now_us: u64) -> Option<TickReport<S>>
    where
        H: QuadratureCounter + MotorOutputs<S>,
    {
        // Brake to a stop when a hold starts.
        let holding = self.sm.hold().is_some();
        if holding && !self.was_holding {
            if let Some(ctl) = self.controller.as_mut() {
                ctl.hold();
            }
        }
        self.was_holding = holding;
        let Some(ctl) = self.controller.as_mut() else {
            let _ = self.event(Event::Fault(Faults::INTERNAL), now_us);
            return None;
        };
        let mut tap = Tap { hw, raw: None };
        let report = ctl.tick(&mut tap);
        if let Some(raw) = tap.raw {
            self.raw = raw;
            self.measured_q = self.encoders.update(&raw);
        }
        self.measured_pose = report.measured_pose;
        if report.fk.is_err() {
            self.fk_failures_in_row = self.fk_failures_in_row.saturating_add(1);
        } else {
            self.fk_failures_in_row = 0;
        }
        if report.servo.fault.is_some() {
            let _ = self.event(Event::TrackingFault, now_us);
        } else if let Some(stop) = report.setpoint.stop {
            let _ = self.event(Event::Fault(link::guard_fault(stop.guard)), now_us);
        } else if self.fk_failures_in_row >= self.cfg.fk_failures_to_fault {
            let _ = self.event(Event::Fault(Faults::FORWARD_KINEMATICS), now_us);
        }
        Some(report)
    }

    fn update_measured_pose(&mut self) {
        let q = Joints::from_row_slice(&self.measured_q);
        let fk: FkConfig<S> = self.cfg.controller.fk;
        if let Ok(sol) = forward(
            &self.robot,
            &q,
            self.cfg.controller.branch,
            &self.measured_pose,
            &fk,
        ) {
            self.measured_pose = sol.pose;
        } else if let Ok(sol) = forward(
            &self.robot,
            &q,
            self.cfg.controller.branch,
            &Pose::central(self.robot.hc()),
            &fk,
        ) {
            self.measured_pose = sol.pose;
        }
    }

    fn update_warnings(&mut self, now_us: u64) {
        let w = &mut self.warnings;
        w.set(Warnings::NOT_HOMED, !self.sm.homed());
        w.set(
            Warnings::HEARTBEAT_LATE,
            self.sm.state() == State::Enabled && self.heartbeat.is_late(now_us),
        );
    }

    /// Records the control tick's worst start jitter and execution time (µs), measured by
    /// the board (DWT cycle counter), for the status report.
    pub fn set_tick_timing(&mut self, worst_jitter_us: u32, worst_exec_us: u32) {
        self.tick_timing = (worst_jitter_us, worst_exec_us);
    }

    /// Sets or clears extra warnings (e.g. `CYCLE_OVERRUN`, `LINK_ERRORS` from the board).
    pub fn set_warning(&mut self, w: Warnings, on: bool) {
        self.warnings.set(w, on);
    }

    /// The status report (singularity margins and link counters left at their defaults:
    /// see [`link::fill_margins`] and the link layer's counters).
    pub fn status(&self) -> StatusReport {
        let (position_m, rotation_vector_rad) = link::pose_to_wire(&self.measured_pose);
        let mut joints = [0f32; NUM_JOINTS];
        for (o, q) in joints.iter_mut().zip(self.measured_q.iter()) {
            *o = link::to_f32(*q);
        }
        StatusReport {
            state: self.sm.state(),
            position_m,
            rotation_vector_rad,
            joints,
            warnings: self.warnings,
            faults: self.sm.faults(),
            serial_singularity_margin: 0.0,
            parallel_singularity_margin: 0.0,
            link: Default::default(),
            tick_jitter_max_us: self.tick_timing.0,
            tick_exec_max_us: self.tick_timing.1,
            targets_refused: self
                .controller
                .as_ref()
                .map_or(0, |c| c.supervisor().counters().refused()),
        }
    }

    /// The measured pose (forward kinematics of the encoders).
    pub fn measured_pose(&self) -> &Pose<S> {
        &self.measured_pose
    }
    /// The measured joints.
    pub fn measured_q(&self) -> [S; NUM_JOINTS] {
        self.measured_q
    }
}

fn jog_reason(e: crate::JogError) -> NackReason {
    match e {
        crate::JogError::NonFinite => NackReason::InvalidValue,
        crate::JogError::NoSolution => NackReason::OutOfWorkspace,
    }
}

/// How far ahead of the setpoint a Jog aims at most, s: the dead-man time of a jog stream.
pub const JOG_HORIZON_S: f64 = 0.1;

/// A default configuration for the reference robot: homing placeholders parking at the
/// central configuration `central_q`.
pub fn reference_config<S: Scalar>(central_q: [S; NUM_JOINTS]) -> RuntimeConfig<S> {
    let [_, _, _, t1, t2, t3] = central_q;
    RuntimeConfig {
        controller: ControllerConfig::default(),
        homing: HomingConfig::reference([t1, t2, t3], Some(central_q)),
        heartbeat: HeartbeatConfig::default(),
        targets: TargetClockConfig::default(),
        fk_failures_to_fault: 10,
    }
}

/// Records the raw counts the controller reads, forwarding everything to the hardware.
struct Tap<'a, H> {
    hw: &'a mut H,
    raw: Option<[u16; NUM_JOINTS]>,
}

impl<H: QuadratureCounter> QuadratureCounter for Tap<'_, H> {
    fn counts(&mut self) -> [u16; NUM_JOINTS] {
        let c = self.hw.counts();
        self.raw = Some(c);
        c
    }
}

impl<S: Float, H: MotorOutputs<S>> MotorOutputs<S> for Tap<'_, H> {
    fn set_duties(&mut self, duty: &[S; NUM_JOINTS]) {
        self.hw.set_duties(duty)
    }
    fn disable(&mut self) {
        self.hw.disable()
    }
    fn enable(&mut self) {
        self.hw.enable()
    }
}
