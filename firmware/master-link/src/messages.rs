//! Message bodies (postcard + serde).
//!
//! Wire-compatibility rules: postcard encodes an enum variant by its index,
//! so variants and struct fields are **append-only**; any other change needs a
//! new [`PROTOCOL_VERSION`](crate::PROTOCOL_VERSION).

use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};

use crate::flags::{Faults, Warnings};

/// Sequence number type of the frame header (per direction, wrapping).
pub type Seq = u16;

/// Number of actuated joints.
pub const JOINT_COUNT: usize = 6;
/// Index of prismatic joint l1 (metres) in `joints` arrays.
pub const JOINT_L1: usize = 0;
/// Index of prismatic joint l2 (metres).
pub const JOINT_L2: usize = 1;
/// Index of prismatic joint l3 (metres).
pub const JOINT_L3: usize = 2;
/// Index of revolute joint theta1 (radians).
pub const JOINT_THETA1: usize = 3;
/// Index of revolute joint theta2 (radians).
pub const JOINT_THETA2: usize = 4;
/// Index of revolute joint theta3 (radians).
pub const JOINT_THETA3: usize = 5;

/// A message type that can travel in a frame.
pub trait WireMessage: Serialize + DeserializeOwned {
    /// `true` for the handshake message (`Hello` / `HelloReply`): it is
    /// accepted whatever its sequence number and restarts the receiver's
    /// sequence tracking from it.
    fn resets_sequence(&self) -> bool;
}

/// Messages from the host master to the actuator-controller board.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum MasterToBoard {
    /// Handshake; (re)starts the board's sequence tracking of this direction.
    Hello {
        /// Protocol version spoken by the master.
        protocol_version: u8,
    },
    /// Enable the drives (Ready -> Enabled).
    Enable,
    /// Disable the drives (-> Disabled).
    Disable,
    /// Start the homing sequence.
    Home,
    /// Cartesian pose set-point of the end effector.
    PoseTarget {
        /// Master timestamp of the target, microseconds.
        timestamp_us: u64,
        /// Position, metres.
        position_m: [f32; 3],
        /// Orientation as rotation vector (axis * angle), radians.
        rotation_vector_rad: [f32; 3],
    },
    /// Jog one joint at a constant velocity.
    Jog {
        /// Joint index 0..=5 (l1, l2, l3, theta1, theta2, theta3).
        joint: u8,
        /// m/s for prismatic joints 0..=2, rad/s for revolute joints 3..=5.
        velocity: f32,
    },
    /// Master clutch: while engaged, master motion moves the robot.
    Clutch {
        /// Clutch pedal state.
        engaged: bool,
    },
    /// Keep-alive; the board faults when heartbeats stop while enabled.
    Heartbeat,
    /// Emergency stop (latched fault).
    EmergencyStop,
    /// Clear latched faults (if their cause has gone).
    ClearFault,
    /// Ask for one `Status` message.
    StatusRequest,
}

impl WireMessage for MasterToBoard {
    fn resets_sequence(&self) -> bool {
        matches!(self, Self::Hello { .. })
    }
}

/// Firmware version, semantic versioning.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FirmwareVersion {
    /// Major.
    pub major: u8,
    /// Minor.
    pub minor: u8,
    /// Patch.
    pub patch: u8,
}

/// Why a command was refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum NackReason {
    /// `Hello` carried a protocol version the board does not speak.
    UnsupportedVersion,
    /// No `Hello` received yet.
    NotConnected,
    /// Command not allowed in the current state.
    InvalidState,
    /// The robot must be homed first.
    NotHomed,
    /// A fault is latched (send `ClearFault`).
    Faulted,
    /// The fault cause is still present; cannot clear.
    FaultStillActive,
    /// Joint index out of range.
    InvalidJoint,
    /// A value is NaN/infinite or otherwise invalid.
    InvalidValue,
    /// Target outside the reachable workspace.
    OutOfWorkspace,
    /// Target violates a joint limit.
    JointLimit,
    /// Target too close to a singular configuration.
    NearSingularity,
    /// Velocity above the allowed limit.
    VelocityLimit,
    /// Target timestamp older than the last accepted one.
    StaleTarget,
    /// Clutch not engaged.
    ClutchDisengaged,
    /// Board busy (e.g. homing in progress).
    Busy,
}

/// Controller state machine state.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum RobotState {
    /// Power-up, self test.
    #[default]
    Boot,
    /// Drives off.
    Disabled,
    /// Homing sequence running.
    Homing,
    /// Homed, drives off, ready to enable.
    Ready,
    /// Drives on, following targets.
    Enabled,
    /// Latched fault, drives off.
    Fault,
}

/// Link statistics of one receiving direction (see `FrameDecoder`).
///
/// Every non-empty delimiter-terminated frame increments exactly one of
/// `frames_ok`, `bad_checksum`, `malformed`, `oversized`, `wrong_version`,
/// `out_of_order`; `dropped` counts sequence numbers skipped between accepted
/// frames (frames lost on the way). All counters wrap.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct LinkCounters {
    /// Frames accepted.
    pub frames_ok: u32,
    /// Frames with a CRC mismatch.
    pub bad_checksum: u32,
    /// Invalid COBS, too short, or undecodable body.
    pub malformed: u32,
    /// Frames longer than the receive buffer (discarded up to the delimiter).
    pub oversized: u32,
    /// Frames with another protocol version.
    pub wrong_version: u32,
    /// Replayed / out-of-order sequence numbers.
    pub out_of_order: u32,
    /// Frames lost (gaps in the sequence numbers of accepted frames).
    pub dropped: u32,
}

impl LinkCounters {
    /// Sum of all rejected frames (everything except `frames_ok`/`dropped`).
    pub const fn rejected(&self) -> u32 {
        self.bad_checksum
            .wrapping_add(self.malformed)
            .wrapping_add(self.oversized)
            .wrapping_add(self.wrong_version)
            .wrapping_add(self.out_of_order)
    }

    /// Every frame seen, accepted or rejected.
    pub const fn frames_total(&self) -> u32 {
        self.frames_ok.wrapping_add(self.rejected())
    }
}

/// Periodic / requested board status.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct StatusReport {
    /// State machine state.
    pub state: RobotState,
    /// Measured end-effector position (forward kinematics), metres.
    pub position_m: [f32; 3],
    /// Measured orientation as rotation vector, radians.
    pub rotation_vector_rad: [f32; 3],
    /// Measured joints: l1, l2, l3 (metres), theta1, theta2, theta3 (radians).
    pub joints: [f32; JOINT_COUNT],
    /// Active warnings.
    pub warnings: Warnings,
    /// Latched faults.
    pub faults: Faults,
    /// Distance to the serial (inverse-kinematics) singularity, dimensionless
    /// (e.g. normalised min singular value; 0 = singular).
    pub serial_singularity_margin: f32,
    /// Distance to the parallel (direct-kinematics) singularity, same scale.
    pub parallel_singularity_margin: f32,
    /// Counters of the master -> board direction as seen by the board.
    pub link: LinkCounters,
    /// Worst start jitter of the control tick since boot, µs (protocol version 2).
    pub tick_jitter_max_us: u32,
    /// Worst execution time of the control tick since boot, µs (protocol version 2).
    pub tick_exec_max_us: u32,
    /// Pose targets the supervisor refused since the controller started (homing): at
    /// submission (also answered by a `Nack`) or later, when the straight path to an
    /// acknowledged target crosses a stop-level guard (protocol version 3).
    pub targets_refused: u32,
}

/// Messages from the board to the host master.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum BoardToMaster {
    /// Reply to `Hello`; (re)starts the master's sequence tracking.
    HelloReply {
        /// Firmware version.
        firmware_version: FirmwareVersion,
        /// Protocol version spoken by the board.
        protocol_version: u8,
    },
    /// Command accepted.
    Ack {
        /// Sequence number of the acknowledged master frame.
        seq: Seq,
    },
    /// Command refused.
    Nack {
        /// Sequence number of the refused master frame.
        seq: Seq,
        /// Why.
        reason: NackReason,
    },
    /// Status report.
    Status(StatusReport),
}

impl WireMessage for BoardToMaster {
    fn resets_sequence(&self) -> bool {
        matches!(self, Self::HelloReply { .. })
    }
}
