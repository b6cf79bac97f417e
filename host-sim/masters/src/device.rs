//! The master device trait: what every input device hands the teleoperation mapping.
//!
//! A master is polled by the host's stream loop with the master clock (`now_s`, the
//! session's clock in seconds). It drains whatever input arrived since the last poll
//! without blocking and answers with its current state:
//!
//! - a **rate** master (SpaceMouse, keyboard) answers with a twist in the robot frame
//!   {0} (CRTK `servo_cv`-like command) every time it is polled and its connection is
//!   alive; the sample's `t_s` is `now_s`;
//! - a **position** master (tracked stylus, another lab's master arm) answers with its
//!   pose (CRTK `measured_cp` of the master) only when a new pose arrived; the sample's
//!   `t_s` is the arrival time.
//!
//! Either way `t_s` says when the state was last known to be current: the mapping holds
//! the robot when the newest sample is older than its timeout (master lost).

use crate::pose::{CartesianPose, Twist};
use std::path::PathBuf;
use thiserror::Error;

/// The two buttons the teleoperation semantics needs (dVRK: the clutch pedal and the
/// operator-present sensor, i.e. the dead-man).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct OperatorButtons {
    /// Clutch pressed: the master is decoupled from the robot (indexing).
    pub clutch: bool,
    /// Operator present (dead-man held): without it the robot holds.
    pub operator_present: bool,
}

/// What kind of command a master produces.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MasterKind {
    /// Deflection → velocity (SpaceMouse, keyboard).
    Rate,
    /// Absolute pose (tracked stylus, master arm).
    Position,
}

/// A master's command.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum MasterInput {
    /// Velocity command in the robot frame {0}.
    Twist(Twist),
    /// Pose of the master in its own (tracker) frame.
    Pose(CartesianPose),
}

/// One reading of a master.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MasterSample {
    /// Master-clock time at which this state was known to be current, s.
    pub t_s: f64,
    /// The command.
    pub input: MasterInput,
    /// Clutch and operator presence.
    pub buttons: OperatorButtons,
    /// The device's own time stamp of the newest input, µs, when it has one (the kernel's
    /// event time for evdev, the sender's time stamp for UDP).
    pub device_time_us: Option<u64>,
    /// Rate devices: the raw deflection `[x, y, z, rx, ry, rz]` in device counts, for the
    /// recording.
    pub deflection: Option<[f64; 6]>,
}

/// An input device the surgeon holds.
pub trait Master {
    /// A short name for logs and recordings ("spacenavd", "evdev:/dev/input/event5", ...).
    fn name(&self) -> &str;

    /// Rate or position.
    fn kind(&self) -> MasterKind;

    /// Drains pending input without blocking; the current sample (see the module
    /// documentation), `None` when a position master has nothing new.
    fn poll(&mut self, now_s: f64) -> Result<Option<MasterSample>, DeviceError>;
}

/// Why a device could not be read.
#[derive(Debug, Error)]
pub enum DeviceError {
    /// An I/O operation failed.
    #[error("{device}: {operation} {path}: {source}")]
    Io {
        /// The device.
        device: String,
        /// What was being done ("connect", "read", ...).
        operation: &'static str,
        /// The file or socket.
        path: PathBuf,
        /// The error.
        #[source]
        source: std::io::Error,
    },
    /// The device or daemon closed the connection or went away.
    #[error("{device}: disconnected ({detail})")]
    Disconnected {
        /// The device.
        device: String,
        /// What was seen.
        detail: String,
    },
    /// The device spoke something its protocol does not allow.
    #[error("{device}: protocol error: {detail}")]
    Protocol {
        /// The device.
        device: String,
        /// What was wrong.
        detail: String,
    },
    /// No device matched.
    #[error("no input device matches {wanted} (looked in {searched})")]
    NotFound {
        /// What was looked for.
        wanted: String,
        /// Where.
        searched: String,
    },
}
