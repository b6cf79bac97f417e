//! The board side of the master link.
//!
//! ```text
//! UART bytes -> LinkRx (BoardDecoder: COBS, CRC, version, sequence) -> Inbound
//!     Inbound::Reply    answered by the link itself (HelloReply, Nack NotConnected /
//!                       UnsupportedVersion)
//!     Inbound::Request  a Command for the runtime (state-machine event, pose target,
//!                       heartbeat, status request); its result becomes Ack / Nack
//! replies -> LinkTx (sequence numbers, encode into the caller's buffer) -> UART
//! ```
//! Malformed, oversized, wrong-version, bad-checksum and out-of-order (replayed) frames are
//! counted by the decoder ([`LinkCounters`]) and dropped. Before a `Hello` with the
//! board's protocol version only `Hello` and `EmergencyStop` are taken (the e-stop is
//! always taken); everything else is refused with `NotConnected`. Every accepted master
//! frame gets exactly one reply: `HelloReply`, `Status` (for `StatusRequest`), `Ack` or
//! `Nack` carrying the frame's sequence number.

use kinematics_core::guards::Guard;
use kinematics_core::supervisor::Refusal as SupervisorRefusal;
use kinematics_core::{inverse, measures, scalar, Branch, Mechanism, Pose};
use master_link::{
    encode, BoardDecoder, BoardToMaster, EncodeError, Faults, FirmwareVersion, FrameError,
    LinkCounters, MasterToBoard, NackReason, Seq, SeqCounter, StatusReport, Warnings,
    PROTOCOL_VERSION,
};
use nalgebra::Vector3;

use crate::controller::Scalar;

/// A master request for the runtime.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Command {
    /// Enable the drives.
    Enable,
    /// Drives off.
    Disable,
    /// Start homing.
    Home,
    /// Clutch pedal.
    Clutch {
        /// Pressed.
        engaged: bool,
    },
    /// Emergency stop.
    EmergencyStop,
    /// Clear the latched fault.
    ClearFault,
    /// Keep-alive.
    Heartbeat,
    /// One `Status` reply.
    StatusRequest,
    /// Pose target (wire units: m, rotation vector rad; master clock µs).
    Target {
        /// Master timestamp, µs.
        stamp_us: u64,
        /// Position, m.
        position_m: [f32; 3],
        /// Rotation vector, rad.
        rotation_vector_rad: [f32; 3],
    },
    /// Jog one joint.
    Jog {
        /// Joint index.
        joint: u8,
        /// m/s or rad/s.
        velocity: f32,
    },
}

/// A request with the sequence number its reply carries.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Request {
    /// Sequence number of the master frame.
    pub seq: Seq,
    /// What to do.
    pub command: Command,
}

impl Request {
    /// The reply to this request given its outcome (`Status` for a status request).
    pub fn reply(&self, result: Result<(), NackReason>, status: &StatusReport) -> BoardToMaster {
        match (result, self.command) {
            (Ok(()), Command::StatusRequest) => BoardToMaster::Status(*status),
            (Ok(()), _) => BoardToMaster::Ack { seq: self.seq },
            (Err(reason), _) => BoardToMaster::Nack {
                seq: self.seq,
                reason,
            },
        }
    }
}

/// What one received frame gives.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Inbound {
    /// For the runtime; reply with [`Request::reply`].
    Request(Request),
    /// The link answered itself: send this.
    Reply(BoardToMaster),
}

/// Firmware version of this crate's release (the board passes its own).
pub const FIRMWARE_VERSION: FirmwareVersion = FirmwareVersion {
    major: 0,
    minor: 1,
    patch: 0,
};

/// The receiving side: decoder, connection state.
pub struct LinkRx {
    decoder: BoardDecoder,
    connected: bool,
    firmware: FirmwareVersion,
    last_error: Option<FrameError>,
    refused_not_connected: u32,
}

impl LinkRx {
    /// Not connected, zero counters.
    pub const fn new(firmware: FirmwareVersion) -> Self {
        LinkRx {
            decoder: BoardDecoder::new(),
            connected: false,
            firmware,
            last_error: None,
            refused_not_connected: 0,
        }
    }

    /// Feeds one received byte.
    pub fn push(&mut self, byte: u8) -> Option<Inbound> {
        match self.decoder.push(byte)? {
            Ok((seq, msg)) => Some(self.dispatch(seq, msg)),
            Err(e) => {
                self.last_error = Some(e);
                None
            }
        }
    }

    /// Feeds bytes, handing every result to `f`.
    pub fn feed(&mut self, bytes: &[u8], mut f: impl FnMut(Inbound)) {
        for b in bytes {
            if let Some(i) = self.push(*b) {
                f(i);
            }
        }
    }

    fn dispatch(&mut self, seq: Seq, msg: MasterToBoard) -> Inbound {
        let command = match msg {
            MasterToBoard::Hello { protocol_version } => {
                return Inbound::Reply(if protocol_version == PROTOCOL_VERSION {
                    self.connected = true;
                    BoardToMaster::HelloReply {
                        firmware_version: self.firmware,
                        protocol_version: PROTOCOL_VERSION,
                    }
                } else {
                    self.connected = false;
                    BoardToMaster::Nack {
                        seq,
                        reason: NackReason::UnsupportedVersion,
                    }
                });
            }
            MasterToBoard::EmergencyStop => Command::EmergencyStop,
            _ if !self.connected => {
                self.refused_not_connected = self.refused_not_connected.wrapping_add(1);
                return Inbound::Reply(BoardToMaster::Nack {
                    seq,
                    reason: NackReason::NotConnected,
                });
            }
            MasterToBoard::Enable => Command::Enable,
            MasterToBoard::Disable => Command::Disable,
            MasterToBoard::Home => Command::Home,
            MasterToBoard::PoseTarget {
                timestamp_us,
                position_m,
                rotation_vector_rad,
            } => Command::Target {
                stamp_us: timestamp_us,
                position_m,
                rotation_vector_rad,
            },
            MasterToBoard::Jog { joint, velocity } => Command::Jog { joint, velocity },
            MasterToBoard::Clutch { engaged } => Command::Clutch { engaged },
            MasterToBoard::Heartbeat => Command::Heartbeat,
            MasterToBoard::ClearFault => Command::ClearFault,
            MasterToBoard::StatusRequest => Command::StatusRequest,
        };
        Inbound::Request(Request { seq, command })
    }

    /// A `Hello` with the right version was received.
    pub fn connected(&self) -> bool {
        self.connected
    }
    /// Forgets the connection and the sequence reference (e.g. after a long silence):
    /// the master must send `Hello` again.
    pub fn disconnect(&mut self) {
        self.connected = false;
        self.decoder.reset_sequence();
    }
    /// Drops a partial frame after a UART framing/overrun error.
    pub fn resync(&mut self) {
        self.decoder.resync();
    }
    /// The decoder's counters.
    pub fn counters(&self) -> LinkCounters {
        *self.decoder.counters()
    }
    /// The last rejected frame's error.
    pub fn last_error(&self) -> Option<FrameError> {
        self.last_error
    }
    /// Requests refused because no `Hello` was received.
    pub fn refused_not_connected(&self) -> u32 {
        self.refused_not_connected
    }
}

/// The sending side: the board's sequence numbers.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LinkTx {
    seq: SeqCounter,
    sent: u32,
    errors: u32,
}

impl LinkTx {
    /// Starts at sequence number 0.
    pub const fn new() -> Self {
        LinkTx {
            seq: SeqCounter::new(0),
            sent: 0,
            errors: 0,
        }
    }
    /// Encodes `msg` as one frame (delimiter included) into `buf` (use
    /// `MAX_FRAME_LEN` bytes); returns its length.
    pub fn encode(&mut self, msg: &BoardToMaster, buf: &mut [u8]) -> Result<usize, EncodeError> {
        match encode(msg, self.seq.peek(), buf) {
            Ok(n) => {
                self.seq.next();
                self.sent = self.sent.wrapping_add(1);
                Ok(n)
            }
            Err(e) => {
                self.errors = self.errors.wrapping_add(1);
                Err(e)
            }
        }
    }
    /// Frames encoded.
    pub fn sent(&self) -> u32 {
        self.sent
    }
    /// Encode failures.
    pub fn errors(&self) -> u32 {
        self.errors
    }
}

// ---------------------------------------------------------------------------------------
// Target timestamps
// ---------------------------------------------------------------------------------------

/// Target timestamp checks.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TargetClockConfig {
    /// Largest extra delay of a target over the fastest one seen recently, µs (default
    /// 50 ms).
    pub max_latency_us: u64,
    /// Length of the window over which the fastest delay is tracked, µs (default 1 s;
    /// bounds the effect of clock drift).
    pub window_us: u64,
}

impl Default for TargetClockConfig {
    fn default() -> Self {
        TargetClockConfig {
            max_latency_us: 50_000,
            window_us: 1_000_000,
        }
    }
}

/// Relates the master's timestamps to the board clock without synchronised clocks: the
/// smallest `board time - master stamp` over the last one or two windows is taken as the
/// pure link delay; a target delayed by more than `max_latency_us` beyond it is stale,
/// one not newer than the last is out of order (both `StaleTarget`). Accepted targets get
/// a strictly increasing board timestamp for the supervisor.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TargetClock {
    cfg: TargetClockConfig,
    last_master_us: Option<u64>,
    last_board_us: u64,
    min_now: Option<i128>,
    min_prev: Option<i128>,
    window_start_us: u64,
}

impl TargetClock {
    /// Fresh (the first target is always in time).
    pub const fn new(cfg: TargetClockConfig) -> Self {
        TargetClock {
            cfg,
            last_master_us: None,
            last_board_us: 0,
            min_now: None,
            min_prev: None,
            window_start_us: 0,
        }
    }

    /// Forgets the master's timing (on enable); board stamps stay increasing.
    pub fn reset(&mut self) {
        self.last_master_us = None;
        self.min_now = None;
        self.min_prev = None;
    }

    /// A strictly increasing board timestamp at `now_us`.
    pub fn board_stamp(&mut self, now_us: u64) -> u64 {
        let s = now_us.max(self.last_board_us.saturating_add(1));
        self.last_board_us = s;
        s
    }

    /// Checks a master target stamped `master_us` arriving at board time `now_us`;
    /// returns the board timestamp to submit it with.
    pub fn accept(&mut self, master_us: u64, now_us: u64) -> Result<u64, NackReason> {
        if self.last_master_us.is_some_and(|last| master_us <= last) {
            return Err(NackReason::StaleTarget);
        }
        let offset = i128::from(now_us) - i128::from(master_us);
        if now_us.saturating_sub(self.window_start_us) >= self.cfg.window_us {
            self.min_prev = self.min_now;
            self.min_now = None;
            self.window_start_us = now_us;
        }
        let m = self.min_now.map_or(offset, |m| m.min(offset));
        self.min_now = Some(m);
        let fastest = self.min_prev.map_or(m, |p| p.min(m));
        if offset - fastest > i128::from(self.cfg.max_latency_us) {
            return Err(NackReason::StaleTarget);
        }
        self.last_master_us = Some(master_us);
        Ok(self.board_stamp(now_us))
    }
}

// ---------------------------------------------------------------------------------------
// Conversions
// ---------------------------------------------------------------------------------------

/// `f32` of a scalar (NaN if it does not convert).
pub fn to_f32<S: Scalar>(x: S) -> f32 {
    num_traits::ToPrimitive::to_f32(&x).unwrap_or(f32::NAN)
}

/// A pose from wire units; `InvalidValue` if a component is not finite.
pub fn pose_from_wire<S: Scalar>(
    position_m: [f32; 3],
    rotation_vector_rad: [f32; 3],
) -> Result<Pose<S>, NackReason> {
    let v = |a: [f32; 3]| {
        let [x, y, z] = a.map(|c| scalar::lit::<S>(f64::from(c)));
        Vector3::new(x, y, z)
    };
    Pose::from_position_rotation_vector(v(position_m), v(rotation_vector_rad))
        .map_err(|_| NackReason::InvalidValue)
}

/// A pose in wire units (position m, rotation vector rad).
pub fn pose_to_wire<S: Scalar>(pose: &Pose<S>) -> ([f32; 3], [f32; 3]) {
    let r = pose.rotation_vector();
    (
        [to_f32(pose.t.x), to_f32(pose.t.y), to_f32(pose.t.z)],
        [to_f32(r.x), to_f32(r.y), to_f32(r.z)],
    )
}

/// The Nack reason for a supervisor refusal.
pub fn refusal_reason<S: Scalar>(r: &SupervisorRefusal<S>) -> NackReason {
    match r {
        SupervisorRefusal::NonFinite => NackReason::InvalidValue,
        SupervisorRefusal::Stale { .. } | SupervisorRefusal::OutOfOrder => NackReason::StaleTarget,
        // Farther from the setpoint than one target may jump.
        SupervisorRefusal::TooFar { .. } => NackReason::VelocityLimit,
        SupervisorRefusal::Path { reading, .. } => guard_reason(reading.guard),
        SupervisorRefusal::Latched => NackReason::Faulted,
    }
}

/// The Nack reason for a violated guard.
pub fn guard_reason(g: Guard) -> NackReason {
    match g {
        Guard::Stroke | Guard::LinkAngle | Guard::Yaw | Guard::Pitch | Guard::Tilt => {
            NackReason::JointLimit
        }
        Guard::SerialSingularity | Guard::ParallelSingularity => NackReason::NearSingularity,
        Guard::TipSpeed
        | Guard::AngularSpeed
        | Guard::TipAccel
        | Guard::AngularAccel
        | Guard::JointSpeed
        | Guard::JointAccel => NackReason::VelocityLimit,
        Guard::Reach
        | Guard::Collision
        | Guard::Workspace
        | Guard::TiltCone
        | Guard::Force
        | Guard::Torque => NackReason::OutOfWorkspace,
    }
}

/// The fault bit latched when the supervisor stops on a guard.
pub fn guard_fault(g: Guard) -> Faults {
    match guard_reason(g) {
        NackReason::JointLimit => Faults::JOINT_LIMIT,
        NackReason::NearSingularity => Faults::SINGULARITY,
        _ => Faults::KINEMATICS,
    }
}

/// A status about to go out: the singularity margins at its pose ([`fill_margins`]) and,
/// when the link has counted anything, its counters with the `LINK_ERRORS` warning set
/// while any frame was rejected. (The boards' telemetry tasks send this.)
pub fn complete_status<S: Scalar, M: Mechanism<S>>(
    status: &mut StatusReport,
    robot: &M,
    branch: Branch,
    warn: (S, S),
    link: Option<LinkCounters>,
) {
    fill_margins(status, robot, branch, warn);
    if let Some(c) = link {
        status.link = c;
        status.warnings.set(Warnings::LINK_ERRORS, c.rejected() > 0);
    }
}

/// Singularity margins at the status pose: (serial: smallest dimensionless serial
/// measure, parallel: inverse condition number), `(0, 0)` where the pose has no
/// inverse kinematics. Sets the near-singularity warnings against `warn` levels
/// (serial, parallel).
pub fn fill_margins<S: Scalar, M: Mechanism<S>>(
    status: &mut StatusReport,
    robot: &M,
    branch: Branch,
    warn: (S, S),
) {
    let pose = pose_from_wire::<S>(status.position_m, status.rotation_vector_rad);
    let m = pose
        .ok()
        .and_then(|p| inverse(robot, &p, branch).ok())
        .and_then(|sol| measures(robot, &sol).ok());
    let (serial, parallel) = match m {
        Some(m) => {
            let mut s: S = scalar::lit(1e30);
            for (_, r) in m.serial_relative.iter() {
                s = num_traits::Float::min(s, *r);
            }
            (s, m.parallel_inv_cond)
        }
        None => (S::zero(), S::zero()),
    };
    status.serial_singularity_margin = to_f32(serial);
    status.parallel_singularity_margin = to_f32(parallel);
    status
        .warnings
        .set(Warnings::NEAR_SERIAL_SINGULARITY, serial < warn.0);
    status
        .warnings
        .set(Warnings::NEAR_PARALLEL_SINGULARITY, parallel < warn.1);
}
