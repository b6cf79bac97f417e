//! How the robot stops: the stop categories of IEC 60204-1 (§9.2.2) and the safe stop
//! functions of IEC 61800-5-2 (§4.2.2), one table that maps every fault and every stopping
//! command to its reaction ([`TABLE`], [`reaction`]), and the sequencer that carries a
//! stop out on the outputs ([`Stopper`]).
//!
//! * **STO** (safe torque off, stop category 0): torque removed at once, the holding
//!   brakes applied at the same instant (their springs close in the engage time).
//! * **SS1** (safe stop 1, category 1): controlled deceleration under power to standstill,
//!   then the brakes applied while the drives still hold, then torque off once the brakes
//!   have engaged.
//! * **SS2 / SOS** (safe stop 2, category 2, then safe operating stop): controlled
//!   deceleration to standstill, then the position held under power with standstill
//!   monitoring; if the robot leaves the standstill window, STO with brakes.
//!
//! Faults that mean the power stage or the sensing cannot be trusted get STO; control-level
//! events get SS1 or SS2, so that the tool stays where it is.

use master_link::{FaultCause, StopStatus};

/// A stop category.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum StopCategory {
    /// Safe torque off (category 0) with the brakes applied.
    Sto,
    /// Safe stop 1: decelerate, apply the brakes, then torque off.
    Ss1,
    /// Safe stop 2: decelerate, then hold under power (safe operating stop).
    Ss2,
}

impl StopCategory {
    /// The IEC name.
    pub const fn name(self) -> &'static str {
        match self {
            StopCategory::Sto => "STO (category 0) + brakes",
            StopCategory::Ss1 => "SS1 (category 1): decelerate, brakes, torque off",
            StopCategory::Ss2 => "SS2 (category 2): decelerate, hold under power (SOS)",
        }
    }
}

/// Everything that stops the robot: a latched fault, or a command or condition that only
/// holds or disables it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum StopEvent {
    /// A fault (latched until `ClearFault`).
    Fault(FaultCause),
    /// The master's `Disable` while enabled.
    Disable,
    /// The master's heartbeat is late (not yet lost): hold.
    HeartbeatLate,
    /// The master's clutch is engaged: the master is decoupled, the robot holds.
    ClutchEngaged,
    /// The operator let go of the dead-man: hold.
    OperatorAbsent,
}

/// The reaction to one event.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Reaction {
    /// The stop.
    pub category: StopCategory,
    /// Why this category (printed in the firmware README).
    pub why: &'static str,
}

const fn sto(why: &'static str) -> Reaction {
    Reaction {
        category: StopCategory::Sto,
        why,
    }
}
const fn ss1(why: &'static str) -> Reaction {
    Reaction {
        category: StopCategory::Ss1,
        why,
    }
}
const fn ss2(why: &'static str) -> Reaction {
    Reaction {
        category: StopCategory::Ss2,
        why,
    }
}

/// The reaction to `event`: the one table of the firmware.
pub const fn reaction(event: StopEvent) -> Reaction {
    use FaultCause as F;
    match event {
        StopEvent::Fault(cause) => match cause {
            F::EmergencyStopButton => {
                sto("the hard-wired chain removes the drivers' power; the MCU does the same")
            }
            F::EmergencyStopMessage => {
                sto("an emergency stop: the fastest stop, torque off and brakes")
            }
            F::SafetyRelayMismatch => sto("the safety chain itself is in doubt"),
            F::HeartbeatTimeout => {
                ss1("the master is gone: stop under control, then brakes and torque off")
            }
            F::JointLimit => {
                sto("a joint is where it must not be: the servo may be pushing it there")
            }
            F::LimitSwitch => sto("a limit switch closed outside homing: mechanical end of travel"),
            F::FollowingError => sto("the servo cannot follow: jam, collision or a drive failure"),
            F::NoMotion => sto("driven hard without motion: stuck encoder, open motor or jam"),
            F::EncoderJump => sto("the encoder reading cannot be trusted"),
            F::EncoderDead => sto("the encoder stopped counting while the motor turns"),
            F::EncoderDisagree => {
                sto("the encoder lost counts the second channel saw: the servo's feedback fails")
            }
            F::PositionSensor => {
                ss1("the second channel is lost; the encoders still serve: stop, then off")
            }
            F::MotorOpen => sto("the motor cannot hold its joint: only the brakes can"),
            F::CurrentImplausible => sto("the motor circuit or its driver cannot be trusted"),
            F::Overcurrent => sto("the power stage cannot be trusted"),
            F::Overload => {
                sto("pushing against something with the rated force: take the force away")
            }
            F::OverTemperature => {
                ss1("the motor is too hot but healthy: stop under control, then off")
            }
            F::DriverFault => sto("the power stage reports a fault"),
            F::SupplyVoltage => sto("the power stage cannot be trusted"),
            F::HomingFailed => sto("homing moves are slow; the reference is unknown"),
            F::Singularity => ss2("a guard stop of the supervisor: hold the tool where it is"),
            F::GuardStop => ss2("a guard stop of the supervisor: hold the tool where it is"),
            F::ForwardKinematics => {
                ss1("the measured pose is unknown; the joints still servo: stop, then off")
            }
            F::DeadlineMissed => {
                sto("the control loop cannot be trusted (the watchdog is starved)")
            }
            F::StandstillLost => sto("the safe operating stop did not hold"),
            F::BrakeCheck => {
                ss2("the brakes may not hold: keep holding under power, never rely on them")
            }
            F::NonFiniteInput => sto("an internal error reached the servo"),
            F::Internal => sto("an internal error"),
            F::None => sto("(not a fault)"),
        },
        StopEvent::Disable => ss1("drives off on request: decelerate, brakes, torque off"),
        StopEvent::HeartbeatLate => ss2("the master is late: hold until it is back or lost"),
        StopEvent::ClutchEngaged => ss2("the master is decoupled: hold"),
        StopEvent::OperatorAbsent => ss2("the operator let go: hold"),
    }
}

/// Every row of the table, in the README's order: every fault cause, then the commands
/// and conditions that stop without a fault.
pub const TABLE: [StopEvent; 32] = [
    StopEvent::Fault(FaultCause::EmergencyStopButton),
    StopEvent::Fault(FaultCause::EmergencyStopMessage),
    StopEvent::Fault(FaultCause::SafetyRelayMismatch),
    StopEvent::Fault(FaultCause::HeartbeatTimeout),
    StopEvent::Fault(FaultCause::JointLimit),
    StopEvent::Fault(FaultCause::LimitSwitch),
    StopEvent::Fault(FaultCause::FollowingError),
    StopEvent::Fault(FaultCause::NoMotion),
    StopEvent::Fault(FaultCause::EncoderJump),
    StopEvent::Fault(FaultCause::EncoderDead),
    StopEvent::Fault(FaultCause::EncoderDisagree),
    StopEvent::Fault(FaultCause::PositionSensor),
    StopEvent::Fault(FaultCause::MotorOpen),
    StopEvent::Fault(FaultCause::CurrentImplausible),
    StopEvent::Fault(FaultCause::Overcurrent),
    StopEvent::Fault(FaultCause::Overload),
    StopEvent::Fault(FaultCause::OverTemperature),
    StopEvent::Fault(FaultCause::DriverFault),
    StopEvent::Fault(FaultCause::SupplyVoltage),
    StopEvent::Fault(FaultCause::HomingFailed),
    StopEvent::Fault(FaultCause::Singularity),
    StopEvent::Fault(FaultCause::GuardStop),
    StopEvent::Fault(FaultCause::ForwardKinematics),
    StopEvent::Fault(FaultCause::DeadlineMissed),
    StopEvent::Fault(FaultCause::StandstillLost),
    StopEvent::Fault(FaultCause::BrakeCheck),
    StopEvent::Fault(FaultCause::NonFiniteInput),
    StopEvent::Fault(FaultCause::Internal),
    StopEvent::Disable,
    StopEvent::HeartbeatLate,
    StopEvent::ClutchEngaged,
    StopEvent::OperatorAbsent,
];

impl StopEvent {
    /// The event's name in the table: the fault cause's, or the command's.
    pub fn name(&self) -> &'static str {
        match self {
            StopEvent::Fault(c) => c.name(),
            StopEvent::Disable => "Disable (command)",
            StopEvent::HeartbeatLate => "heartbeat late (100 ms)",
            StopEvent::ClutchEngaged => "clutch engaged",
            StopEvent::OperatorAbsent => "operator absent (dead-man)",
        }
    }
}

impl StopCategory {
    /// Short name.
    pub const fn short(self) -> &'static str {
        match self {
            StopCategory::Sto => "STO",
            StopCategory::Ss1 => "SS1",
            StopCategory::Ss2 => "SS2",
        }
    }
    /// What the outputs do, in order.
    pub const fn outputs(self) -> &'static str {
        match self {
            StopCategory::Sto => "torque off and brakes applied at once",
            StopCategory::Ss1 => {
                "decelerate under power; at rest, brakes applied; torque off once they hold"
            }
            StopCategory::Ss2 => "decelerate under power; hold under power, standstill monitored",
        }
    }
}

/// Writes [`TABLE`] as a Markdown table (the firmware README prints it; a test checks
/// that the README's copy is this one).
pub fn write_table(out: &mut impl core::fmt::Write) -> core::fmt::Result {
    writeln!(out, "| event | stop | the outputs | why |")?;
    writeln!(out, "| --- | --- | --- | --- |")?;
    for e in TABLE {
        let r = reaction(e);
        writeln!(
            out,
            "| {} | {} | {} | {} |",
            e.name(),
            r.category.short(),
            r.category.outputs(),
            r.why
        )?;
    }
    Ok(())
}

/// Timing of the stops, µs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct StopConfig {
    /// Longest controlled deceleration before the stop escalates to STO (default 500 ms:
    /// 25 mm/s at the 0.25 m/s² braking deceleration takes 100 ms).
    pub decel_timeout_us: u64,
    /// Engage time of the spring-applied brakes: how long the drives keep holding after
    /// the brakes are applied (default 30 ms, a small spring-applied brake's data sheet).
    pub brake_engage_us: u64,
    /// Release time of the brakes: how long the drives hold before following (default
    /// 60 ms).
    pub brake_release_us: u64,
}

impl Default for StopConfig {
    fn default() -> Self {
        StopConfig {
            decel_timeout_us: 500_000,
            brake_engage_us: 30_000,
            brake_release_us: 60_000,
        }
    }
}

/// Where a stop is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StopPhase {
    /// No stop in force.
    Running,
    /// Decelerating under power (SS1 or SS2), since `since_us`.
    Decelerating {
        /// SS1 or SS2.
        category: StopCategory,
        /// Start, µs.
        since_us: u64,
    },
    /// SS1 at standstill: the brakes applied, the drives still holding until they engage.
    Braking {
        /// When the brakes were applied, µs.
        since_us: u64,
    },
    /// Torque off, brakes applied (STO, or SS1 done).
    TorqueOff {
        /// STO (else SS1 done).
        sto: bool,
    },
    /// Safe operating stop (SS2 done): holding under power, standstill monitored.
    Holding,
}

/// What the outputs do in a phase.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Outputs {
    /// The drives produce torque.
    pub torque: bool,
    /// The brakes may be released (else applied).
    pub brakes_released: bool,
    /// The motion decelerates (the supervisor brakes; no new targets).
    pub decelerate: bool,
}

/// Carries stops out: from a requested category through its phases to torque off or a
/// monitored hold. The runtime asks it each tick what the outputs do
/// ([`Stopper::outputs`]) and tells it when the robot stands ([`Stopper::standstill`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Stopper {
    cfg: StopConfig,
    phase: StopPhase,
    /// The event that started the stop in force.
    event: Option<StopEvent>,
}

impl Stopper {
    /// No stop in force.
    pub const fn new(cfg: StopConfig) -> Self {
        Stopper {
            cfg,
            phase: StopPhase::Running,
            event: None,
        }
    }

    /// The settings.
    pub fn config(&self) -> &StopConfig {
        &self.cfg
    }
    /// The phase.
    pub fn phase(&self) -> StopPhase {
        self.phase
    }
    /// The event that started the stop in force.
    pub fn event(&self) -> Option<StopEvent> {
        self.event
    }

    /// Requests the stop of `event` at `now_us` (`torque_on`: whether the drives produce
    /// torque now). A stop never weakens one in force: STO wins over SS1, SS1 over SS2;
    /// a stop of the same or a weaker category keeps the one in force.
    pub fn request(&mut self, event: StopEvent, now_us: u64, torque_on: bool) {
        let category = reaction(event).category;
        let rank = |c: StopCategory| match c {
            StopCategory::Sto => 3,
            StopCategory::Ss1 => 2,
            StopCategory::Ss2 => 1,
        };
        let current = match self.phase {
            StopPhase::Running => 0,
            StopPhase::Decelerating { category, .. } => rank(category),
            StopPhase::Braking { .. } => rank(StopCategory::Ss1),
            StopPhase::TorqueOff { sto: true } => rank(StopCategory::Sto),
            StopPhase::TorqueOff { sto: false } => rank(StopCategory::Ss1),
            StopPhase::Holding => rank(StopCategory::Ss2),
        };
        if rank(category) <= current {
            return;
        }
        self.event = Some(event);
        self.phase = match category {
            StopCategory::Sto => StopPhase::TorqueOff { sto: true },
            // Without torque there is nothing to decelerate: the brakes are applied already.
            _ if !torque_on => StopPhase::TorqueOff { sto: false },
            StopCategory::Ss1 if matches!(self.phase, StopPhase::Holding) => {
                StopPhase::Braking { since_us: now_us }
            }
            c => StopPhase::Decelerating {
                category: c,
                since_us: now_us,
            },
        };
    }

    /// Advances the stop at `now_us`; `standstill`: the motion has come to rest. A
    /// deceleration that outlasts its timeout escalates to STO (returns `true` then).
    pub fn advance(&mut self, now_us: u64, standstill: bool) -> bool {
        match self.phase {
            StopPhase::Decelerating { category, since_us } => {
                if standstill {
                    self.phase = match category {
                        StopCategory::Ss2 => StopPhase::Holding,
                        _ => StopPhase::Braking { since_us: now_us },
                    };
                } else if now_us.saturating_sub(since_us) > self.cfg.decel_timeout_us {
                    self.phase = StopPhase::TorqueOff { sto: true };
                    return true;
                }
            }
            // Strictly after the engage time: the pins change at a varying point within
            // their ticks, so the first tick past it keeps the drives on for at least the
            // engage time after the brakes' pins changed (the board emulator measures it).
            StopPhase::Braking { since_us }
                if now_us.saturating_sub(since_us) > self.cfg.brake_engage_us =>
            {
                self.phase = StopPhase::TorqueOff { sto: false };
            }
            _ => {}
        }
        false
    }

    /// Ends the stop (a cleared fault, a hold that is over): back to running. The caller
    /// decides what running means (drives off unless enabled).
    pub fn clear(&mut self) {
        self.phase = StopPhase::Running;
        self.event = None;
    }

    /// What the outputs do now (`running_torque`: what they do with no stop in force).
    pub fn outputs(&self, running_torque: bool) -> Outputs {
        match self.phase {
            StopPhase::Running => Outputs {
                torque: running_torque,
                brakes_released: running_torque,
                decelerate: false,
            },
            StopPhase::Decelerating { .. } => Outputs {
                torque: true,
                brakes_released: true,
                decelerate: true,
            },
            StopPhase::Braking { .. } => Outputs {
                torque: true,
                brakes_released: false,
                decelerate: true,
            },
            StopPhase::TorqueOff { .. } => Outputs {
                torque: false,
                brakes_released: false,
                decelerate: true,
            },
            StopPhase::Holding => Outputs {
                torque: true,
                brakes_released: true,
                decelerate: true,
            },
        }
    }

    /// The stop in force, for the status.
    pub fn status(&self) -> StopStatus {
        match self.phase {
            StopPhase::Running => StopStatus::None,
            StopPhase::Decelerating {
                category: StopCategory::Ss2,
                ..
            } => StopStatus::SafeStop2Decelerating,
            StopPhase::Decelerating { .. } => StopStatus::SafeStop1Decelerating,
            StopPhase::Braking { .. } => StopStatus::SafeStop1Braking,
            StopPhase::TorqueOff { sto: true } => StopStatus::SafeTorqueOff,
            StopPhase::TorqueOff { sto: false } => StopStatus::SafeStop1Done,
            StopPhase::Holding => StopStatus::SafeOperatingStop,
        }
    }
}
