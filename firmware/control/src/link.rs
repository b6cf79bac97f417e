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

use master_link::{
    encode, BoardDecoder, BoardToMaster, EncodeError, FirmwareVersion, FrameError, LinkCounters,
    MasterToBoard, NackReason, Seq, SeqCounter, StatusReport, PROTOCOL_VERSION,
};

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
