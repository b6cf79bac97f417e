//! The runtime's mode and the data each mode owns. The transitions between them are
//! [`crate::modes::next`]'s table; the runtime carries them out (`transitions.rs`).

use kinematics_core::{Joints, Mechanism, Pose};
use master_link::{FaultCause, FaultRecord, Faults, StopStatus};
use servo::NUM_JOINTS;

use crate::brakes::BrakeCheck;
use crate::commissioning::JointTest;
use crate::controller::Controller;
use crate::homing::Homing;
use crate::modes::ModeKind;
use crate::monitors::Standstill;
use crate::park::ParkMove;
use crate::scalar::Scalar;
use crate::stops::{StopConfig, StopEvent, StopPhase, Stopper};

/// Where the last controller held the robot when its stop completed: an enable may start
/// there instead of at the measured pose (see `Runtime::held_start`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Held<S: Scalar> {
    /// The setpoint pose.
    pub pose: Pose<S>,
    /// Its joints.
    pub q: [S; NUM_JOINTS],
}

/// A jog stream in progress.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Jog<S: Scalar> {
    /// The jogged joint.
    pub joint: usize,
    /// When the last `Jog` of the stream arrived, µs.
    pub last_us: u64,
    /// The joints it aims at.
    pub target: Joints<S>,
}

/// A stop's sequence: its phases ([`Stopper`]) and, in the safe operating stop, the
/// position whose standstill is monitored.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StopSequence<S> {
    /// The phases.
    pub stopper: Stopper,
    /// The standstill reference while the phase is `Holding`.
    pub standstill: Standstill<S>,
}

impl<S: num_traits::Float> StopSequence<S> {
    /// The stop of `event` requested at `now_us` (`torque_on`: whether the drives produce
    /// torque now).
    pub fn start(cfg: StopConfig, event: StopEvent, now_us: u64, torque_on: bool) -> Self {
        let mut stopper = Stopper::new(cfg);
        stopper.request(event, now_us, torque_on);
        StopSequence {
            stopper,
            standstill: Standstill::reference(),
        }
    }
}

/// What carries a stop out besides its sequence.
// The board has no heap: the controller lives in the variant that uses it.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug)]
pub enum StopDrive<S: Scalar, M: Mechanism<S> + Clone> {
    /// The controller brakes its setpoint to rest within its limits and holds it.
    Controller(Controller<S, M>),
    /// There is no setpoint to brake (a stop during homing or the park move): zero duty
    /// until the brakes hold.
    ZeroDuty,
    /// Torque is off. `held`: where the last controller held, while the reference stands.
    Off(Option<Held<S>>),
}

/// A stop in force.
#[derive(Clone, Debug)]
pub struct Stop<S: Scalar, M: Mechanism<S> + Clone> {
    /// Its sequence.
    pub sequence: StopSequence<S>,
    /// What carries it out.
    pub drive: StopDrive<S, M>,
}

impl<S: Scalar, M: Mechanism<S> + Clone> Stop<S, M> {
    /// The controller braking or holding, if any.
    pub fn controller(&self) -> Option<&Controller<S, M>> {
        match &self.drive {
            StopDrive::Controller(c) => Some(c),
            _ => None,
        }
    }
    /// The stop still drives: decelerating, braking or holding under power.
    pub fn powered(&self) -> bool {
        !matches!(self.sequence.stopper.phase(), StopPhase::TorqueOff { .. })
    }
}

/// The latched fault.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Latched {
    /// The first fault since the mode was entered: the status's `fault`.
    pub record: FaultRecord,
    /// Every cause latched since, as the status's bits.
    pub faults: Faults,
    /// The causes raised since (bit = index in `FaultCause::ALL` + 1): a lasting condition
    /// is acted on and logged once.
    pub raised: u32,
    /// The last fault handled: cause, joint, time (one fault reported twice in a tick is
    /// one).
    pub last: (FaultCause, u8, u64),
}

/// The index of `cause` in `FaultCause::ALL` (+1; `None` is 0): its bit in the raised set.
pub fn cause_bit(cause: FaultCause) -> u32 {
    let index = FaultCause::ALL
        .iter()
        .position(|c| *c == cause)
        .map_or(0, |i| i + 1)
        .min(31);
    1u32 << index
}

impl Latched {
    /// A fault `record` of `cause` latched now.
    pub fn new(cause: FaultCause, record: FaultRecord, now_us: u64) -> Self {
        Latched {
            record,
            faults: Faults::NONE,
            raised: 0,
            last: (cause, record.joint, now_us),
        }
        .with(cause, record, now_us)
    }

    /// The same latch with one more fault.
    pub fn with(mut self, cause: FaultCause, record: FaultRecord, now_us: u64) -> Self {
        self.faults.insert(match cause {
            FaultCause::None => Faults::INTERNAL,
            c => c.bit(),
        });
        self.raised |= cause_bit(cause);
        self.last = (cause, record.joint, now_us);
        self
    }
}

/// The board's mode, with the data valid in it (see [`crate::modes`] for the table).
// The board has no heap: each mode's data lives in its variant.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug)]
pub enum Mode<S: Scalar, M: Mechanism<S> + Clone> {
    /// Power-up.
    Boot,
    /// Drives off, brakes applied, not homed.
    Disabled,
    /// Homing: the procedure with its servo.
    Homing(Homing<S>),
    /// The park move after the references, under the homing's servo.
    Parking {
        /// The homing (its servo follows the move).
        homing: Homing<S>,
        /// The move.
        park: ParkMove<S, M>,
    },
    /// Homed, drives off, brakes applied.
    Ready {
        /// Where the last controller held, if an enable may resume there.
        held: Option<Held<S>>,
    },
    /// The brake check, then the release under servo.
    Enabling {
        /// The check.
        check: BrakeCheck<S>,
        /// The controller that holds the robot while the brakes open.
        ctl: Controller<S, M>,
    },
    /// Following the master.
    Following {
        /// The controller.
        ctl: Controller<S, M>,
        /// A jog stream in progress.
        jog: Option<Jog<S>>,
    },
    /// Enabled and holding under power (SS2) for the master session's holds.
    Holding {
        /// The controller (its supervisor brakes and holds).
        ctl: Controller<S, M>,
        /// The hold's stop.
        sequence: StopSequence<S>,
    },
    /// A stop without a fault (SS1).
    Stopping {
        /// The stop.
        stop: Stop<S, M>,
        /// The homing is trusted (the mode it ends in: `Ready`, else `Disabled`).
        homed: bool,
    },
    /// Commissioning: one joint's wiring test, or its record waiting to be read.
    Commissioning(JointTest<S>),
    /// A latched fault and its stop.
    Fault {
        /// The fault.
        latched: Latched,
        /// Its stop.
        stop: Stop<S, M>,
        /// The homing is still trusted.
        homed: bool,
    },
}

impl<S: Scalar, M: Mechanism<S> + Clone> Mode<S, M> {
    /// The mode's name.
    pub fn kind(&self) -> ModeKind {
        match self {
            Mode::Boot => ModeKind::Boot,
            Mode::Disabled => ModeKind::Disabled,
            Mode::Homing(_) => ModeKind::Homing,
            Mode::Parking { .. } => ModeKind::Parking,
            Mode::Ready { .. } => ModeKind::Ready,
            Mode::Enabling { .. } => ModeKind::Enabling,
            Mode::Following { .. } => ModeKind::Following,
            Mode::Holding { .. } => ModeKind::Holding,
            Mode::Stopping { .. } => ModeKind::Stopping,
            Mode::Fault { .. } => ModeKind::Fault,
            Mode::Commissioning(_) => ModeKind::Commissioning,
        }
    }

    /// The homing is trusted.
    pub fn homed(&self) -> bool {
        match self {
            Mode::Stopping { homed, .. } | Mode::Fault { homed, .. } => *homed,
            m => m.kind().implies_homed(),
        }
    }

    /// The controller, in the modes that have one.
    pub fn controller(&self) -> Option<&Controller<S, M>> {
        match self {
            Mode::Enabling { ctl, .. }
            | Mode::Following { ctl, .. }
            | Mode::Holding { ctl, .. } => Some(ctl),
            Mode::Stopping { stop, .. } | Mode::Fault { stop, .. } => stop.controller(),
            _ => None,
        }
    }

    /// The controller, mutably.
    pub fn controller_mut(&mut self) -> Option<&mut Controller<S, M>> {
        match self {
            Mode::Enabling { ctl, .. }
            | Mode::Following { ctl, .. }
            | Mode::Holding { ctl, .. } => Some(ctl),
            Mode::Stopping { stop, .. } | Mode::Fault { stop, .. } => match &mut stop.drive {
                StopDrive::Controller(c) => Some(c),
                _ => None,
            },
            _ => None,
        }
    }

    /// The stop in force, if any.
    pub fn stop_sequence(&self) -> Option<&StopSequence<S>> {
        match self {
            Mode::Holding { sequence, .. } => Some(sequence),
            Mode::Stopping { stop, .. } | Mode::Fault { stop, .. } => Some(&stop.sequence),
            _ => None,
        }
    }

    /// The stop in force, mutably.
    pub fn stop_sequence_mut(&mut self) -> Option<&mut StopSequence<S>> {
        match self {
            Mode::Holding { sequence, .. } => Some(sequence),
            Mode::Stopping { stop, .. } | Mode::Fault { stop, .. } => Some(&mut stop.sequence),
            _ => None,
        }
    }

    /// The stop's phase (`Running` without a stop).
    pub fn stop_phase(&self) -> StopPhase {
        self.stop_sequence()
            .map_or(StopPhase::Running, |s| s.stopper.phase())
    }

    /// The stop in force, for the status.
    pub fn stop_status(&self) -> StopStatus {
        self.stop_sequence()
            .map_or(StopStatus::None, |s| s.stopper.status())
    }

    /// The latched fault, in `Fault`.
    pub fn latched(&self) -> Option<&Latched> {
        match self {
            Mode::Fault { latched, .. } => Some(latched),
            _ => None,
        }
    }

    /// The homing procedure, while homing or parking.
    pub fn homing(&self) -> Option<&Homing<S>> {
        match self {
            Mode::Homing(h) | Mode::Parking { homing: h, .. } => Some(h),
            _ => None,
        }
    }
}
