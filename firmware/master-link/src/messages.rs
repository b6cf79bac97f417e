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
    /// A handshake message (`Hello`; `HelloReply`, `HelloRefused`): the receiver takes it
    /// whatever its frame's session and sequence number, and it changes neither: the
    /// receiver's owner decides whether a session opens
    /// ([`FrameDecoder::open_session`](crate::FrameDecoder::open_session)).
    fn is_handshake(&self) -> bool;
    /// `true` for a message no session or sequence check may drop (`EmergencyStop`): it
    /// is taken whenever its frame is intact.
    fn bypasses_sequence(&self) -> bool;
}

/// Messages from the host master to the actuator-controller board.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "arbitrary", derive(arbitrary::Arbitrary))]
pub enum MasterToBoard {
    /// Handshake: asks the board for a session. The board answers `HelloReply` with a
    /// session it chose (fresh for every accepted `Hello`), or `HelloRefused` (another
    /// master owns the board, an old `Hello` replayed, another protocol version).
    Hello {
        /// Protocol version spoken by the master.
        protocol_version: u8,
        /// The master's identity for this connection (a fresh random value per
        /// connection, echoed in the answer): the board's owner is the master whose nonce
        /// it accepted last.
        nonce: u32,
        /// The master's clock when it sent the `Hello`, µs (the clock of its target
        /// stamps): the board keeps it to refuse targets from the future, and refuses a
        /// `Hello` of the owner's nonce that is not newer than the last (a replay).
        clock_us: u64,
    },
    /// Enable the drives (Ready -> Enabled).
    Enable,
    /// Disable the drives (-> Disabled).
    Disable,
    /// Start the homing sequence. A robot that is homed already is homed again only
    /// with `rehome` set (an explicit confirmation); otherwise the board refuses
    /// (`NackReason::AlreadyHomed`).
    Home {
        /// Confirms homing a robot that is homed already.
        rehome: bool,
    },
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
    /// Master clutch (indexing), as on a da Vinci: while the clutch is **engaged** (pedal
    /// pressed) the master is decoupled from the robot and the robot **holds** (targets are
    /// refused); releasing it couples them again.
    Clutch {
        /// Clutch pedal pressed: master decoupled, robot holding.
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
    /// Operator present (the dead-man): released, the robot holds (targets refused).
    OperatorPresent {
        /// The operator's hand is on the master.
        present: bool,
    },
    /// Acknowledges the board's last reset (needed before `Enable` after a watchdog or
    /// brown-out reset).
    AcknowledgeReset,
    /// Ask for the fault log's entries from index `first` (oldest kept = 0).
    FaultLogRequest {
        /// First entry wanted.
        first: u16,
    },
    /// Store a calibrated geometry in the board's flash. Taken only while the
    /// drives are off (`Disabled`, `Ready`); answered `GeometryStored` or
    /// `GeometryRefused` with the reason.
    StoreGeometry(GeometryRecord),
    /// Ask for the event log's entries from index `first` (oldest kept = 0), answered
    /// `EventLog`.
    EventLogRequest {
        /// First entry wanted.
        first: u16,
    },
    /// Commissioning (protocol version 9): test the wiring of joint `joint` (0..=5) in
    /// the board's commissioning mode. Taken from `Disabled` (not homed); from `Ready` or
    /// from a fault whose stop has ended only with `confirm` (the robot was homed, or a
    /// fault is latched: a person at the robot confirms). Answered `Commissioning` with the
    /// joint's record: sent again for the same joint, it reads the record (`done` once the
    /// test has ended); for another joint once the test has ended, it tests that joint.
    Commission {
        /// The joint to test (l1, l2, l3, theta1, theta2, theta3).
        joint: u8,
        /// A person at the robot confirms commissioning a homed or faulted robot.
        confirm: bool,
    },
}

/// The record layout [`GeometryRecord::layout`] this crate writes.
pub const GEOMETRY_LAYOUT: u8 = 1;

/// Values per chain in a [`GeometryRecord`], in this order (SI; base quantities in {0},
/// platform ones in {p}; `kinematics-core`'s `ChainDimensions`): base pivot x, y, z (m);
/// base axis x, y, z; link length (m); platform joint x, y, z (m); platform axis x, y, z;
/// leg offset (m); leg encoder zero (m); link encoder zero (rad).
pub const GEOMETRY_CHAIN_VALUES: usize = 16;

/// A calibrated per-chain geometry on the wire and in the board's flash: the nominal
/// robot (e, rb, rp, hc in m), the three chains ([`GEOMETRY_CHAIN_VALUES`] each), the
/// calibration's version and a CRC-32 (the frame's, ISO-HDLC) over the layout byte, the
/// version and every value, little-endian: the record is checked end to end, from the
/// host's file to the flash and back at boot.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "arbitrary", derive(arbitrary::Arbitrary))]
pub struct GeometryRecord {
    /// The layout ([`GEOMETRY_LAYOUT`]).
    pub layout: u8,
    /// The calibration's version (reported in `HelloReply::geometry_version`; 0 is "none").
    pub version: u32,
    /// e, rb, rp, hc of the nominal robot, m.
    pub nominal: [f32; 4],
    /// The chains, chain 1 first.
    pub chains: [[f32; GEOMETRY_CHAIN_VALUES]; 3],
    /// CRC-32 of the rest ([`GeometryRecord::compute_crc`]).
    pub crc: u32,
}

impl GeometryRecord {
    /// The bytes the CRC covers: layout, version (LE), nominal and chain values (LE).
    pub fn payload(&self) -> [u8; 5 + 4 * (4 + 3 * GEOMETRY_CHAIN_VALUES)] {
        let mut out = [0u8; 5 + 4 * (4 + 3 * GEOMETRY_CHAIN_VALUES)];
        let values = self.nominal.iter().chain(self.chains.iter().flatten());
        let head = core::iter::once(self.layout).chain(self.version.to_le_bytes());
        for (o, b) in out
            .iter_mut()
            .zip(head.chain(values.flat_map(|v| v.to_le_bytes())))
        {
            *o = b;
        }
        out
    }

    /// The CRC-32 of [`GeometryRecord::payload`].
    pub fn compute_crc(&self) -> u32 {
        crate::CRC32.checksum(&self.payload())
    }

    /// The record with its CRC set.
    pub fn sealed(mut self) -> Self {
        self.crc = self.compute_crc();
        self
    }

    /// The CRC matches the contents.
    pub fn crc_ok(&self) -> bool {
        self.crc == self.compute_crc()
    }
}

/// Why the board refused a geometry (`BoardToMaster::GeometryRefused`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum GeometryRefusal {
    /// The record's CRC does not match its contents.
    Crc,
    /// A layout this firmware does not read.
    Layout {
        /// The layout received.
        found: u8,
    },
    /// Version 0 is reserved for "no stored geometry".
    Version,
    /// A value is NaN or infinite (index: 0..=3 nominal, then 4 + 16 × chain + value).
    NonFinite {
        /// The value's index.
        index: u8,
    },
    /// The nominal robot is not the board's.
    Nominal {
        /// The value's index (0..=3: e, rb, rp, hc).
        index: u8,
    },
    /// A value is further from the nominal than a calibration can move it (index as for
    /// `NonFinite`).
    OutOfTolerance {
        /// The value's index.
        index: u8,
    },
    /// The geometry is invalid (an axis not a unit vector, a link length not positive) or
    /// cannot be assembled in its central configuration.
    NotAssemblable,
    /// The inverse kinematics of the central pose fails on the board's branch.
    CentralPose,
    /// The drives are on (or homing): store only in `Disabled` or `Ready`.
    InvalidState,
    /// Writing or verifying the flash failed.
    Flash,
    /// This board cannot store a geometry.
    Unsupported,
}

impl WireMessage for MasterToBoard {
    fn is_handshake(&self) -> bool {
        matches!(self, Self::Hello { .. })
    }
    fn bypasses_sequence(&self) -> bool {
        matches!(self, Self::EmergencyStop)
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
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum NackReason {
    /// `Hello` carried a protocol version the board does not speak.
    UnsupportedVersion,
    /// No `Hello` received yet.
    NotConnected,
    /// Command not allowed in the current state.
    #[default]
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
    /// The robot is homed already: `Home` needs `rehome` set.
    AlreadyHomed,
    /// The last reset (watchdog, brown-out) must be acknowledged first.
    ResetNotAcknowledged,
    /// The e-stop button and the safety relay's feedback disagree.
    SafetyRelayMismatch,
    /// The holding brakes did not hold in the brake check.
    BrakeCheckFailed,
    /// The operator is not present (dead-man released).
    OperatorAbsent,
    /// Another master owns the board (a `Hello` while the robot is not disabled).
    NotOwner,
    /// A target stamped further ahead of the master's clock (from its `Hello`) than the
    /// board allows: never taken, never adopted as the clock.
    TargetFromFuture,
    /// A `Hello` with the owner's nonce whose clock is not newer than the owner's last:
    /// a recording replayed.
    ReplayedHello,
}

/// The guard or rule that refused a target, on the wire ([`Breach::guard`]): the
/// supervisor's guards (`kinematics-core::guards::Guard`, same names) and the admission
/// rules of a target.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum GuardId {
    /// Nothing measured: the [`NackReason`] is the whole answer.
    #[default]
    None,
    /// The pose has no inverse-kinematics solution (subject: the chain that fails).
    Reach,
    /// Prismatic stroke l_i, m (subject: the chain).
    Stroke,
    /// Rotating-link angle θ_i from its central value, rad (subject: the chain).
    LinkAngle,
    /// USR lower-link yaw α_i from its central value, rad (subject: the chain).
    Yaw,
    /// USR lower-link pitch β_i from its central value, rad (subject: the chain).
    Pitch,
    /// Spherical-joint tilt, rad (subject: the chain).
    Tilt,
    /// Piercing radius of the leg axis in the plane of the central motors' tops, m
    /// (subject: the chain).
    Collision,
    /// The platform centre's coordinate in {0} against the face of the task box with its
    /// margin, m (subject: the axis, 0 = x, 1 = y, 2 = z).
    Workspace,
    /// Platform tilt (angle between its normal and z0), rad.
    TiltCone,
    /// Serial singularity measure, dimensionless (subject: the chain).
    SerialSingularity,
    /// Parallel singularity measure (inverse condition number), dimensionless.
    ParallelSingularity,
    /// Prismatic actuator force for the declared payload, N (subject: the joint).
    Force,
    /// Revolute actuator torque for the declared payload, N m (subject: the joint).
    Torque,
    /// Speed of the platform centre, m/s.
    TipSpeed,
    /// Angular speed of the platform, rad/s.
    AngularSpeed,
    /// Acceleration of the platform centre, m/s².
    TipAccel,
    /// Angular acceleration of the platform, rad/s².
    AngularAccel,
    /// Joint speed, m/s or rad/s (subject: the joint).
    JointSpeed,
    /// Joint acceleration, m/s² or rad/s² (subject: the joint).
    JointAccel,
    /// The distance of the target from the setpoint against the longest step one target
    /// may make, m.
    Step,
    /// The rotation of the target from the setpoint against the largest one target may
    /// make, rad.
    StepAngle,
    /// The target's age against the staleness limit, s (negative: from the future).
    Age,
}

/// What refused a target, measured: the guard or rule, what it concerns, the value and
/// the limit it broke, SI (the host formats them with units: [`GuardId`] says which).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Breach {
    /// The guard or rule.
    pub guard: GuardId,
    /// What it concerns: a chain (0..=2: leg, link, spherical joint i + 1), a joint
    /// (0..=5, joint order), an axis (0..=2: x, y, z) as [`GuardId`] says, or
    /// [`NO_JOINT`].
    pub subject: u8,
    /// The measured value, SI.
    pub value: f32,
    /// The limit it broke, SI.
    pub limit: f32,
}

impl Breach {
    /// Nothing measured.
    pub const NONE: Breach = Breach {
        guard: GuardId::None,
        subject: NO_JOINT,
        value: 0.0,
        limit: 0.0,
    };
}

/// A refused target (`BoardToMaster::TargetRefused`): which, why and what was measured.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RefusedTarget {
    /// `Some(seq)`: the reply to the target's frame (refused at submission); `None`: the
    /// supervisor's path check refused it after its `Ack`.
    pub reply_to: Option<Seq>,
    /// The target's master timestamp, µs (a jog: 0).
    pub timestamp_us: u64,
    /// The rule, as a `Nack` would give it.
    pub reason: NackReason,
    /// What was measured ([`Breach::NONE`] when the reason is the whole answer).
    pub breach: Breach,
}

/// What commissioning found on one joint ([`CommissionRecord::findings`]): one bit per
/// finding, each implying its fix (`host-sim commission` words them).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct CommissionFindings(pub u16);

impl CommissionFindings {
    /// Nothing wrong.
    pub const NONE: Self = Self(0);
    /// A positive duty moved the joint towards -q (by the reference): the motor's leads are
    /// reversed.
    pub const MOTOR_REVERSED: Self = Self(1 << 0);
    /// The encoder counts against the joint's motion (by the reference).
    pub const ENCODER_REVERSED: Self = Self(1 << 1);
    /// The encoder counted down under a positive duty and there is no reference to say
    /// whether the motor or the encoder is reversed (the person at the robot tells).
    pub const DIRECTION_MISMATCH: Self = Self(1 << 2);
    /// Another joint's encoder counted this joint's motion (`moved_encoder`): the
    /// encoders' cables are swapped.
    pub const ENCODER_SWAPPED: Self = Self(1 << 3);
    /// The encoder's counts per unit differ from the profile's by more than the tolerance
    /// (`scale`): the gear ratio or the encoder's resolution is not the profile's.
    pub const SCALE: Self = Self(1 << 4);
    /// The home switch reads actuated where the joint is away from it: a normally open
    /// switch (or a cut wire) where a normally closed one is expected.
    pub const SWITCH_INVERTED: Self = Self(1 << 5);
    /// The joint moved with its brake applied and stood with it released: the brake's
    /// coil or output is inverted.
    pub const BRAKE_INVERTED: Self = Self(1 << 6);
    /// The joint moved with its brake applied and with it released: the brake does not
    /// hold.
    pub const BRAKE_NOT_HOLDING: Self = Self(1 << 7);
    /// Nothing moved at the test's torque with the brake released: a brake that does not
    /// release, a motor not connected, or a dead encoder.
    pub const NO_MOTION: Self = Self(1 << 8);
    /// The current sense reads more than its tolerance at zero current (`current_offset_a`).
    pub const CURRENT_OFFSET: Self = Self(1 << 9);
    /// The current sense reads against the duty while the joint moves: its sign is
    /// inverted.
    pub const CURRENT_SIGN: Self = Self(1 << 10);
    /// The drivers' fault line reads a fault with the drives off: the driver failed or the
    /// line is miswired (no pull-up); the test did not drive.
    pub const DRIVER_FAULT_LINE: Self = Self(1 << 11);
    /// A joint moved beyond the test's travel limit: the test stopped at once.
    pub const TRAVEL_EXCEEDED: Self = Self(1 << 12);
    /// The home switch reads actuated at rest and there is no reference to say whether the
    /// joint is at its switch (the person at the robot tells).
    pub const SWITCH_ACTUATED: Self = Self(1 << 13);
    /// Every finding, in bit order.
    pub const ALL: [Self; 14] = [
        Self::MOTOR_REVERSED,
        Self::ENCODER_REVERSED,
        Self::DIRECTION_MISMATCH,
        Self::ENCODER_SWAPPED,
        Self::SCALE,
        Self::SWITCH_INVERTED,
        Self::BRAKE_INVERTED,
        Self::BRAKE_NOT_HOLDING,
        Self::NO_MOTION,
        Self::CURRENT_OFFSET,
        Self::CURRENT_SIGN,
        Self::DRIVER_FAULT_LINE,
        Self::TRAVEL_EXCEEDED,
        Self::SWITCH_ACTUATED,
    ];
    /// Every bit of `other` is set.
    pub const fn contains(self, other: Self) -> bool {
        self.0 & other.0 == other.0
    }
    /// Sets the bits of `other`.
    pub fn insert(&mut self, other: Self) {
        self.0 |= other.0;
    }
    /// No bit set.
    pub const fn is_empty(self) -> bool {
        self.0 == 0
    }
}

/// One joint's commissioning record: what the board measured and what it found
/// (`BoardToMaster::Commissioning`, protocol version 9). Motions are in joint units (m,
/// rad) of the profile's scale; NaN where nothing was measured.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct CommissionRecord {
    /// The joint tested.
    pub joint: u8,
    /// The test has ended (the drives are off, the brakes applied).
    pub done: bool,
    /// The board read its second position channel as the reference.
    pub reference: bool,
    /// What it found.
    pub findings: CommissionFindings,
    /// The encoder that counted the joint's motion (0..=5; 255: none).
    pub moved_encoder: u8,
    /// Its motion under the positive push (its own joint's units).
    pub encoder_motion: f32,
    /// The joint's motion by the second channel (NaN without it).
    pub reference_motion: f32,
    /// The encoder's counts per unit over the profile's, by the reference (NaN without).
    pub scale: f32,
    /// The current sense's reading at zero current, A.
    pub current_offset_a: f32,
    /// The mean current while the joint moved under the positive push, offset removed, A.
    pub current_a: f32,
    /// The largest motion with the brake applied (any sensor, the joint's units).
    pub applied_motion: f32,
    /// The largest motion of any joint during the test, by any sensor, as a fraction of
    /// that joint's travel limit (1: at the limit).
    pub peak_travel: f32,
    /// The duty at which the joint moved (0: it did not).
    pub breakaway_duty: f32,
    /// The home switch at the start and at the end of the test (bit 0, bit 1: actuated).
    pub switch: u8,
    /// The channel's position where the home switch changed during the test (NaN: it did
    /// not, or no reference).
    pub switch_position: f32,
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
    /// Latched fault; the stop in force says what the drives do (`StatusReport::stop`).
    Fault,
    /// Enabling: the drives hold the robot while the holding brakes are checked and
    /// released (protocol version 4); `Enabled` follows.
    Enabling,
    /// Commissioning: one joint's wiring test, or its record waiting to be read (protocol
    /// version 9).
    Commissioning,
}

/// Link statistics of one receiving direction (see `FrameDecoder`).
///
/// Every non-empty delimiter-terminated frame increments exactly one of
/// `frames_ok`, `bad_checksum`, `malformed`, `oversized`, `wrong_version`,
/// `out_of_order`, `wrong_session`, `bad_tag`; `dropped` counts sequence numbers skipped between
/// accepted frames (frames lost on the way). All counters wrap.
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
    /// Frames of another session than the current one (protocol version 4).
    pub wrong_session: u32,
    /// Frames without a valid authentication tag on a link with a key (protocol
    /// version 5).
    pub bad_tag: u32,
}

impl LinkCounters {
    /// Sum of all rejected frames (everything except `frames_ok`/`dropped`).
    pub const fn rejected(&self) -> u32 {
        self.bad_checksum
            .wrapping_add(self.malformed)
            .wrapping_add(self.oversized)
            .wrapping_add(self.wrong_version)
            .wrapping_add(self.out_of_order)
            .wrapping_add(self.wrong_session)
            .wrapping_add(self.bad_tag)
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
    /// The stop in force (protocol version 4).
    pub stop: StopStatus,
    /// The latched fault that caused it: cause, joint, value (protocol version 4).
    pub fault: FaultRecord,
    /// Why the board last reset, and whether the master acknowledged it.
    pub reset: ResetStatus,
    /// The setpoint pose: position, m.
    pub setpoint_position_m: [f32; 3],
    /// The setpoint pose: rotation vector, rad.
    pub setpoint_rotation_vector_rad: [f32; 3],
    /// The guard margins at the setpoint, each as a fraction of its range (1 = far, 0 = at
    /// the stop level, NaN while the supervisor does not run).
    pub margins: GuardMargins,
    /// Measured motor currents, A, joint order.
    pub currents_a: [f32; JOINT_COUNT],
    /// Supply voltage of the power stage, V.
    pub supply_v: f32,
    /// Entries in the fault log since boot (read them with `FaultLogRequest`).
    pub fault_log_len: u16,
    /// Missed control periods since boot (late ticks not run back to back).
    pub missed_ticks: u32,
    /// Times another master took the board over since boot (wrapping; protocol version 5).
    pub owner_changes: u16,
    /// The board has the second position channel (an absolute position sensor per joint):
    /// `Home` restores the encoders' references from it and only verifies them with a move
    /// of a few mm or degrees per joint, no sweep to the switches. Without it `Home` sweeps
    /// every joint to its switch or stop (protocol version 7).
    pub position_channel: bool,
}

/// The stop in force and how far it has got (IEC 60204-1 stop categories; IEC 61800-5-2
/// safety functions).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum StopStatus {
    /// No stop: the drives follow (or are off because the robot is not enabled).
    #[default]
    None,
    /// Safe torque off (stop category 0): torque removed at once, brakes applied.
    SafeTorqueOff,
    /// Safe stop 1, decelerating under power.
    SafeStop1Decelerating,
    /// Safe stop 1: at rest, brakes engaging before the torque goes off.
    SafeStop1Braking,
    /// Safe stop 1 done: brakes applied, torque off.
    SafeStop1Done,
    /// Safe stop 2, decelerating under power.
    SafeStop2Decelerating,
    /// Safe operating stop (after SS2): holding position under power, standstill monitored.
    SafeOperatingStop,
}

/// Why a fault was latched: one cause per kind of failure (never merged).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum FaultCause {
    /// No fault.
    #[default]
    None,
    /// The e-stop button (hard-wired chain, read by the MCU).
    EmergencyStopButton,
    /// An `EmergencyStop` message.
    EmergencyStopMessage,
    /// The e-stop button and the safety relay's feedback disagree (value: 1 = button
    /// pressed, relay closed; 2 = button released, relay open).
    SafetyRelayMismatch,
    /// The master's heartbeat stayed away longer than the disable time (value: ms).
    HeartbeatTimeout,
    /// A measured joint left its range (value: the joint position, m or rad).
    JointLimit,
    /// A limit switch closed outside homing (value: the joint position).
    LimitSwitch,
    /// The following error stayed outside its window (value: the error, m or rad).
    FollowingError,
    /// Driven hard without moving: stuck encoder, open motor, jam (value: the duty).
    NoMotion,
    /// The encoder count jumped beyond the joint's top speed (value: counts in one tick).
    EncoderJump,
    /// Current without the motion the motor model expects: a dead encoder (value: the
    /// expected motion, counts).
    EncoderDead,
    /// Voltage applied and no current flows: the motor circuit is open (a broken lead or
    /// connector; value: the duty).
    MotorOpen,
    /// The measured current is far above what the motor model expects for the duty at
    /// the measured speed: a shorted winding, a failed driver stage (value: the current,
    /// A).
    CurrentImplausible,
    /// Motor current above the trip level (value: A).
    Overcurrent,
    /// The current limit held the command for longer than the overload time: the joint
    /// pushes against something with its rated force (value: the current, A).
    Overload,
    /// The motor's I²t model exceeded its continuous rating (value: the heat, fraction of
    /// the limit).
    OverTemperature,
    /// The motor driver's fault output (value: 1).
    DriverFault,
    /// Supply voltage out of range (value: V).
    SupplyVoltage,
    /// Homing failed (value: the homing error code).
    HomingFailed,
    /// The supervisor stopped at a singularity guard (value: the measure).
    Singularity,
    /// The supervisor stopped at another guard (value: the guard's value).
    GuardStop,
    /// Forward kinematics failed repeatedly (value: consecutive failures).
    ForwardKinematics,
    /// The control tick missed its deadline (value: µs late).
    DeadlineMissed,
    /// Standstill monitoring during a safe operating stop (value: the motion, m or rad).
    StandstillLost,
    /// The holding brakes let the joint move in the brake check (value: the motion).
    BrakeCheck,
    /// A non-finite value reached the servo (value: 0).
    NonFiniteInput,
    /// An internal error (value: a code).
    Internal,
    /// The joint's encoder counted less motion than its absolute position sensor (the
    /// second channel) saw: a stuck, dead or miscounting encoder (value: the disagreement,
    /// m or rad).
    EncoderDisagree,
    /// The joint's absolute position sensor (the second channel) failed: no reading, a
    /// reading at a rail (an open wire), a jump beyond the joint's speed, a drift, or less
    /// motion than the encoder counted (value: the reading in counts at a rail or for a
    /// jump, else the disagreement, m or rad).
    PositionSensor,
}

impl FaultCause {
    /// The fault bit of the cause (the bits group causes: e.g. `ENCODER` for a jump, a
    /// dead encoder and no motion).
    pub const fn bit(self) -> Faults {
        match self {
            FaultCause::None => Faults::NONE,
            FaultCause::EmergencyStopButton | FaultCause::EmergencyStopMessage => {
                Faults::EMERGENCY_STOP
            }
            FaultCause::SafetyRelayMismatch => Faults::SAFETY_RELAY,
            FaultCause::HeartbeatTimeout => Faults::HEARTBEAT_TIMEOUT,
            FaultCause::JointLimit | FaultCause::LimitSwitch => Faults::JOINT_LIMIT,
            FaultCause::FollowingError => Faults::FOLLOWING_ERROR,
            FaultCause::NoMotion | FaultCause::EncoderJump | FaultCause::EncoderDead => {
                Faults::ENCODER
            }
            FaultCause::MotorOpen | FaultCause::CurrentImplausible => Faults::MOTOR,
            FaultCause::Overcurrent | FaultCause::Overload => Faults::OVERCURRENT,
            FaultCause::OverTemperature => Faults::OVER_TEMPERATURE,
            FaultCause::DriverFault => Faults::DRIVER,
            FaultCause::SupplyVoltage => Faults::SUPPLY_VOLTAGE,
            FaultCause::HomingFailed => Faults::HOMING_FAILED,
            FaultCause::Singularity => Faults::SINGULARITY,
            FaultCause::GuardStop => Faults::KINEMATICS,
            FaultCause::ForwardKinematics => Faults::FORWARD_KINEMATICS,
            FaultCause::DeadlineMissed => Faults::WATCHDOG,
            FaultCause::StandstillLost => Faults::STANDSTILL,
            FaultCause::BrakeCheck => Faults::BRAKE,
            FaultCause::NonFiniteInput | FaultCause::Internal => Faults::INTERNAL,
            FaultCause::EncoderDisagree => Faults::ENCODER,
            FaultCause::PositionSensor => Faults::POSITION_SENSOR,
        }
    }

    /// A short readable name (the fault log, the firmware README's stop table, the
    /// console).
    pub const fn name(self) -> &'static str {
        match self {
            FaultCause::None => "none",
            FaultCause::EmergencyStopButton => "e-stop button",
            FaultCause::EmergencyStopMessage => "e-stop message",
            FaultCause::SafetyRelayMismatch => "safety relay mismatch",
            FaultCause::HeartbeatTimeout => "heartbeat lost (500 ms)",
            FaultCause::JointLimit => "joint out of range",
            FaultCause::LimitSwitch => "limit switch",
            FaultCause::FollowingError => "following error",
            FaultCause::NoMotion => "no motion under drive",
            FaultCause::EncoderJump => "encoder jump",
            FaultCause::EncoderDead => "encoder dead",
            FaultCause::MotorOpen => "motor circuit open",
            FaultCause::CurrentImplausible => "current implausible (short)",
            FaultCause::Overcurrent => "overcurrent",
            FaultCause::Overload => "overload (at the limit)",
            FaultCause::OverTemperature => "over-temperature (I2t)",
            FaultCause::DriverFault => "driver fault",
            FaultCause::SupplyVoltage => "supply voltage",
            FaultCause::HomingFailed => "homing failed",
            FaultCause::Singularity => "singularity guard",
            FaultCause::GuardStop => "guard stop",
            FaultCause::ForwardKinematics => "forward kinematics",
            FaultCause::DeadlineMissed => "deadline missed",
            FaultCause::StandstillLost => "standstill lost",
            FaultCause::BrakeCheck => "brake check",
            FaultCause::NonFiniteInput => "non-finite input",
            FaultCause::Internal => "internal",
            FaultCause::EncoderDisagree => "encoder disagrees (second channel)",
            FaultCause::PositionSensor => "position sensor (second channel)",
        }
    }

    /// Every cause but `None`, in declaration order (at most 31: the runtime keeps the
    /// causes raised in one 32-bit set).
    pub const ALL: [FaultCause; 28] = [
        FaultCause::EmergencyStopButton,
        FaultCause::EmergencyStopMessage,
        FaultCause::SafetyRelayMismatch,
        FaultCause::HeartbeatTimeout,
        FaultCause::JointLimit,
        FaultCause::LimitSwitch,
        FaultCause::FollowingError,
        FaultCause::NoMotion,
        FaultCause::EncoderJump,
        FaultCause::EncoderDead,
        FaultCause::MotorOpen,
        FaultCause::CurrentImplausible,
        FaultCause::Overcurrent,
        FaultCause::Overload,
        FaultCause::OverTemperature,
        FaultCause::DriverFault,
        FaultCause::SupplyVoltage,
        FaultCause::HomingFailed,
        FaultCause::Singularity,
        FaultCause::GuardStop,
        FaultCause::ForwardKinematics,
        FaultCause::DeadlineMissed,
        FaultCause::StandstillLost,
        FaultCause::BrakeCheck,
        FaultCause::NonFiniteInput,
        FaultCause::Internal,
        FaultCause::EncoderDisagree,
        FaultCause::PositionSensor,
    ];
}

/// A fault with what it concerned: the cause, the joint and the value.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FaultRecord {
    /// The cause.
    pub cause: FaultCause,
    /// The joint (0..=5, joint order), or [`NO_JOINT`].
    pub joint: u8,
    /// The value that tripped it (units: see [`FaultCause`]).
    pub value: f32,
    /// Board time when it was detected, ms since boot.
    pub time_ms: u32,
}

/// `FaultRecord::joint` of a fault that concerns no joint.
pub const NO_JOINT: u8 = u8::MAX;

impl FaultRecord {
    /// No fault.
    pub const NONE: FaultRecord = FaultRecord {
        cause: FaultCause::None,
        joint: NO_JOINT,
        value: 0.0,
        time_ms: 0,
    };
}

impl Default for FaultRecord {
    fn default() -> Self {
        FaultRecord::NONE
    }
}

/// Why the board last reset (the MCU's reset flags, read at boot).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ResetCause {
    /// Power-on (or the flags were not readable).
    #[default]
    PowerOn,
    /// The reset pin (NRST).
    Pin,
    /// A software reset.
    Software,
    /// The independent watchdog.
    Watchdog,
    /// The window watchdog.
    WindowWatchdog,
    /// A brown-out (supply dip).
    BrownOut,
    /// A low-power management reset.
    LowPower,
}

impl ResetCause {
    /// A reset the master must acknowledge before the board enables again.
    pub const fn needs_acknowledgement(self) -> bool {
        matches!(
            self,
            ResetCause::Watchdog | ResetCause::WindowWatchdog | ResetCause::BrownOut
        )
    }
}

/// The last reset and its acknowledgement.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ResetStatus {
    /// Why the board last reset.
    pub cause: ResetCause,
    /// The master acknowledged it (or it needed no acknowledgement).
    pub acknowledged: bool,
}

/// The guard margins at the setpoint as fractions of their ranges (1 = far from the
/// limit, 0 = at the stop level; NaN while the supervisor does not run).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct GuardMargins {
    /// The smallest of all below.
    pub nearest: f32,
    /// Serial singularity (dimensionless measure).
    pub serial: f32,
    /// Parallel singularity (inverse condition number).
    pub parallel: f32,
    /// Prismatic stroke (distance to the nearer end over half the stroke).
    pub stroke: f32,
    /// Spherical-joint tilt.
    pub tilt: f32,
    /// Collision circle.
    pub collision: f32,
    /// The task box with its margin.
    pub workspace: f32,
}

/// One entry of the fault log.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FaultLogEntry {
    /// The fault (its first occurrence).
    pub record: FaultRecord,
    /// The stop it caused.
    pub stop: StopStatus,
    /// How many times it occurred in a row (same cause and joint).
    pub count: u16,
}

/// Entries of the fault log per `FaultLog` message.
pub const FAULT_LOG_PAGE: usize = 12;

/// A page of the fault log.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FaultLogPage {
    /// Entries in the log (kept), oldest first.
    pub len: u16,
    /// Entries ever logged (since the log was cleared; survives a watchdog reset).
    pub total: u32,
    /// Index of `entries[0]`.
    pub first: u16,
    /// How many of `entries` are valid.
    pub count: u8,
    /// The entries.
    pub entries: [FaultLogEntry; FAULT_LOG_PAGE],
}

/// Why a stop that is not a fault began (the event log's [`EventKind::Stop`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum StopReason {
    /// The master's `Disable` while the drives were on (SS1).
    Disable,
    /// The master's heartbeat late: hold (SS2).
    HeartbeatLate,
    /// The master's clutch engaged: hold (SS2).
    ClutchEngaged,
    /// The operator let go of the dead-man: hold (SS2).
    OperatorAbsent,
}

impl StopReason {
    /// Every reason, in declaration order.
    pub const ALL: [StopReason; 4] = [
        StopReason::Disable,
        StopReason::HeartbeatLate,
        StopReason::ClutchEngaged,
        StopReason::OperatorAbsent,
    ];
}

/// What one entry of the board's event log records.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum EventKind {
    /// A fault: its cause, joint ([`NO_JOINT`] for none) and value (units: see
    /// [`FaultCause`]), and the stop it caused.
    Fault {
        /// The cause.
        cause: FaultCause,
        /// The joint, or [`NO_JOINT`].
        joint: u8,
        /// The value that tripped it.
        value: f32,
        /// The stop in force after it.
        stop: StopStatus,
    },
    /// A stop that is not a fault (a disable, a hold).
    Stop {
        /// Why.
        reason: StopReason,
        /// The stop in force after it.
        stop: StopStatus,
    },
    /// The board started (the entry's `time_ms` is 0 of its boot).
    Reset {
        /// Why it last reset.
        cause: ResetCause,
    },
    /// A master took charge of the board (today: a `Hello` opened a session; `id` is its
    /// nonce).
    Master {
        /// The master's identifier.
        id: u32,
    },
    /// A calibrated geometry was written to the board's flash.
    GeometryStored {
        /// Its version.
        version: u32,
    },
    /// The safety chain's relay test: latched pending by a safety-chain fault (only a
    /// power cycle and a passed test end it), or passed.
    RelayTest {
        /// Pending (else passed).
        pending: bool,
    },
    /// Events the board could not keep in flash (they left its RAM view before they were
    /// written).
    Lost {
        /// How many.
        count: u32,
    },
}

/// One entry of the board's event log.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct EventEntry {
    /// The entry's number (increasing over the log's life; a repeat keeps it).
    pub seq: u32,
    /// The boot it happened in (the board counts its boots).
    pub boot: u16,
    /// When it first happened: ms since that boot.
    pub time_ms: u32,
    /// What happened.
    pub event: EventKind,
    /// How many times it happened (a repeat of the newest entry of its kind in the same
    /// boot counts here; 0: an empty slot).
    pub count: u16,
    /// The safety chain's relay test was pending when it was recorded.
    pub relay_test_pending: bool,
}

impl EventEntry {
    /// An empty slot of a page (`count` 0).
    pub const EMPTY: EventEntry = EventEntry {
        seq: 0,
        boot: 0,
        time_ms: 0,
        event: EventKind::Lost { count: 0 },
        count: 0,
        relay_test_pending: false,
    };
}

impl Default for EventEntry {
    fn default() -> Self {
        EventEntry::EMPTY
    }
}

/// Entries of the event log per `EventLog` message.
pub const EVENT_LOG_PAGE: usize = 8;

/// A page of the board's event log (answer to `EventLogRequest`).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct EventLogPage {
    /// Entries the board holds for the link (its RAM view of the log), oldest first.
    pub len: u16,
    /// Entries ever logged (over every boot the flash remembers).
    pub total: u32,
    /// Index of `entries[0]`.
    pub first: u16,
    /// How many of `entries` are valid.
    pub count: u8,
    /// Events of this boot that could not be written to flash.
    pub lost: u32,
    /// The entries.
    pub entries: [EventEntry; EVENT_LOG_PAGE],
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
        /// The session the board issued for this `Hello` (never 0): every later frame of
        /// both sides carries it.
        session: u32,
        /// The `Hello`'s nonce, echoed.
        nonce: u32,
        /// Why the board last reset, and whether that was acknowledged.
        reset: ResetStatus,
        /// The version of the calibrated geometry stored in the board's flash (0: none).
        geometry_version: u32,
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
    /// A page of the fault log (answer to `FaultLogRequest`).
    FaultLog(FaultLogPage),
    /// The geometry of a `StoreGeometry` was checked and stored.
    GeometryStored {
        /// Sequence number of the master frame.
        seq: Seq,
        /// The stored calibration's version.
        version: u32,
    },
    /// The geometry of a `StoreGeometry` was refused; nothing was stored.
    GeometryRefused {
        /// Sequence number of the master frame.
        seq: Seq,
        /// Why.
        reason: GeometryRefusal,
    },
    /// A page of the event log (answer to `EventLogRequest`).
    EventLog(EventLogPage),
    /// A `Hello` was refused (sent outside any session: frame session 0); the session in
    /// force, if any, is unchanged.
    HelloRefused {
        /// Sequence number of the `Hello`.
        seq: Seq,
        /// The `Hello`'s nonce, echoed.
        nonce: u32,
        /// Why (`NotOwner`, `ReplayedHello`, `UnsupportedVersion`, `Busy`).
        reason: NackReason,
    },
    /// A pose target (or jog) refused, with the guard or rule and what it measured: the
    /// reply to the target's frame when refused at submission (instead of a `Nack`), or
    /// sent on its own when the supervisor's path check refuses a target it had
    /// acknowledged (protocol version 7).
    TargetRefused(RefusedTarget),
    /// The answer to `Commission`: the joint's commissioning record (protocol version 9).
    Commissioning(CommissionRecord),
}

impl WireMessage for BoardToMaster {
    fn is_handshake(&self) -> bool {
        matches!(self, Self::HelloReply { .. } | Self::HelloRefused { .. })
    }
    fn bypasses_sequence(&self) -> bool {
        false
    }
}
