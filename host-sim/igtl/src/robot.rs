//! The robot side of the server: what it is asked and what it tells.

use crate::pose::PoseSi;
use crate::status::StatusCode;
use crate::timestamp::Timestamp;
use nalgebra::{Rotation3, Vector3};
use std::net::SocketAddr;

/// A target pose for the platform, in the robot base frame {0}, SI units.
#[derive(Clone, Debug, PartialEq)]
pub struct TargetPose {
    /// Target position of the platform centre o_p in {0}, metres.
    pub t: Vector3<f64>,
    /// Target orientation wRp, or `None` for a position-only target (a 12-byte POSITION):
    /// keep the current orientation.
    pub r: Option<Rotation3<f64>>,
    /// The header timestamp of the message that carried it (0 when the client left it
    /// unused).
    pub timestamp: Timestamp,
    /// The client that sent it.
    pub peer: SocketAddr,
}

impl TargetPose {
    /// The full pose when the orientation is given.
    pub fn pose(&self) -> Option<PoseSi> {
        self.r.map(|r| PoseSi { t: self.t, r })
    }
}

/// Why a robot refuses a target; each maps to a STATUS code.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum RefusalReason {
    /// Outside the workspace, the task box or another geometric limit (code 8, "overflow /
    /// can't be reached").
    Unreachable,
    /// Starting up, not homed (code 13, "device not ready").
    NotReady,
    /// Drives disabled (code 15, "device disabled").
    Disabled,
    /// Cannot take a target now (code 6, "busy").
    Busy,
    /// Under manual control (code 14, "manual mode").
    ManualMode,
    /// A latched safety stop (code 3, "panic mode (emergency)").
    SafetyStop,
    /// A hardware fault (code 18, "hardware failure").
    HardwareFailure,
    /// Any other reason (code 2, "unknown error").
    Other,
}

impl RefusalReason {
    /// The STATUS code sent back.
    pub fn status_code(self) -> StatusCode {
        match self {
            RefusalReason::Unreachable => StatusCode::Overflow,
            RefusalReason::NotReady => StatusCode::NotReady,
            RefusalReason::Disabled => StatusCode::Disabled,
            RefusalReason::Busy => StatusCode::Busy,
            RefusalReason::ManualMode => StatusCode::ManualMode,
            RefusalReason::SafetyStop => StatusCode::PanicMode,
            RefusalReason::HardwareFailure => StatusCode::HardwareFailure,
            RefusalReason::Other => StatusCode::UnknownError,
        }
    }

    /// The STATUS error name sent back (at most 20 characters).
    pub fn error_name(self) -> &'static str {
        match self {
            RefusalReason::Unreachable => "Unreachable",
            RefusalReason::NotReady => "NotReady",
            RefusalReason::Disabled => "Disabled",
            RefusalReason::Busy => "Busy",
            RefusalReason::ManualMode => "ManualMode",
            RefusalReason::SafetyStop => "SafetyStop",
            RefusalReason::HardwareFailure => "HardwareFailure",
            RefusalReason::Other => "Refused",
        }
    }
}

/// A refused target: the reason and a text for the person at the client.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Refusal {
    /// The reason.
    pub reason: RefusalReason,
    /// What is wrong, in words (the STATUS message).
    pub detail: String,
}

impl Refusal {
    /// A refusal.
    pub fn new(reason: RefusalReason, detail: impl Into<String>) -> Self {
        Refusal {
            reason,
            detail: detail.into(),
        }
    }
}

/// The robot's condition, as reported in STATUS and STRING messages.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Condition {
    /// Enabled, holding its pose, accepting targets (code 1).
    Ready,
    /// Moving to a target (code 1).
    Moving,
    /// Starting up or homing (code 13).
    NotReady,
    /// Drives disabled (code 15).
    Disabled,
    /// Under manual control (code 14).
    ManualMode,
    /// A latched safety stop (code 3).
    SafetyStop,
    /// A hardware fault (code 18).
    HardwareFailure,
    /// Shutting down (code 19).
    ShuttingDown,
}

impl Condition {
    /// The STATUS code.
    pub fn status_code(self) -> StatusCode {
        match self {
            Condition::Ready | Condition::Moving => StatusCode::Ok,
            Condition::NotReady => StatusCode::NotReady,
            Condition::Disabled => StatusCode::Disabled,
            Condition::ManualMode => StatusCode::ManualMode,
            Condition::SafetyStop => StatusCode::PanicMode,
            Condition::HardwareFailure => StatusCode::HardwareFailure,
            Condition::ShuttingDown => StatusCode::ShutDown,
        }
    }

    /// The name used as STATUS error name and at the start of the STRING.
    pub fn name(self) -> &'static str {
        match self {
            Condition::Ready => "Ready",
            Condition::Moving => "Moving",
            Condition::NotReady => "NotReady",
            Condition::Disabled => "Disabled",
            Condition::ManualMode => "ManualMode",
            Condition::SafetyStop => "SafetyStop",
            Condition::HardwareFailure => "HardwareFailure",
            Condition::ShuttingDown => "ShuttingDown",
        }
    }
}

/// The robot's state for the clients.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RobotState {
    /// The condition.
    pub condition: Condition,
    /// Details in words (the STATUS message; the STRING is `"<condition>: <detail>"`).
    pub detail: String,
}

impl RobotState {
    /// The STRING text: `"<condition>"` or `"<condition>: <detail>"`.
    pub fn text(&self) -> String {
        if self.detail.is_empty() {
            self.condition.name().to_owned()
        } else {
            format!("{}: {}", self.condition.name(), self.detail)
        }
    }
}

/// What the server needs from the robot. Called from [`crate::server::Server::poll`] on
/// the caller's thread; every call should return quickly (no waiting for motion).
pub trait Robot {
    /// Takes a target pose in {0} (SI), or refuses it with a reason the client is told.
    fn submit_target(&mut self, target: &TargetPose) -> Result<(), Refusal>;

    /// The measured platform pose in {0} (SI), `None` while unknown (e.g. before homing).
    fn measured_pose(&self) -> Option<PoseSi>;

    /// The current state.
    fn state(&self) -> RobotState;

    /// Targets taken earlier and refused since by the robot's own later check (a path
    /// check that runs after the target was taken), each with the client that sent it: the
    /// server answers each with a STATUS to that client. None by default.
    fn take_later_refusals(&mut self) -> Vec<(std::net::SocketAddr, Refusal)> {
        Vec::new()
    }
}
