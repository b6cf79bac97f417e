//! The board side of the master link.
//!
//! ```text
//! UART bytes -> LinkRx (BoardDecoder: COBS, CRC, version, session, sequence) -> Inbound
//!     Inbound::Reply    answered by the link itself (Nack NotConnected /
//!                       UnsupportedVersion)
//!     Inbound::Request  a Command for the runtime (a session opened, state-machine event,
//!                       pose target, heartbeat, status, fault-log or event-log request);
//!                       its outcome becomes HelloReply / Status / FaultLog / EventLog /
//!                       Ack / Nack
//!     Inbound::Geometry a calibrated geometry: checked by the runtime, stored by the
//!                       target; GeometryStored / GeometryRefused
//! replies -> LinkTx (the session, sequence numbers, encode into the caller's buffer) -> UART
//! ```
//! Malformed, oversized, wrong-version, bad-checksum, out-of-order (replayed) frames and
//! frames of an older session are counted by the decoder ([`LinkCounters`]) and dropped; an
//! intact `EmergencyStop` frame is never dropped. Before a `Hello` with the board's
//! protocol version only `Hello` and `EmergencyStop` are taken; everything else is refused
//! with `NotConnected`. Every accepted master frame gets exactly one reply carrying its
//! sequence number (the `HelloReply` opens the session for the master).

use master_link::{
    encode, BoardDecoder, BoardToMaster, EncodeError, EventLogPage, FaultLogPage, FirmwareVersion,
    FrameError, GeometryRecord, GeometryRefusal, Header, LinkCounters, MasterToBoard, NackReason,
    ResetStatus, Seq, SeqCounter, StatusReport, PROTOCOL_VERSION,
};

/// A request with the sequence number its reply carries.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Request {
    /// Sequence number of the master frame.
    pub seq: Seq,
    /// The master's message (never a `StoreGeometry`: that is [`Inbound::Geometry`]).
    pub message: MasterToBoard,
}

/// What the runtime answers to a request it accepted.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Answer {
    /// `Ack`.
    Ack,
    /// The status.
    Status,
    /// The session is open: `HelloReply` with the reset status.
    Hello {
        /// The session.
        session: u32,
        /// The last reset and its acknowledgement.
        reset: ResetStatus,
        /// The stored calibrated geometry's version (0: none).
        geometry_version: u32,
    },
    /// A page of the fault log.
    FaultLog(FaultLogPage),
    /// A page of the event log.
    EventLog(EventLogPage),
}

impl Request {
    /// The reply to this request given its outcome.
    pub fn reply(
        &self,
        result: Result<Answer, NackReason>,
        status: &StatusReport,
        firmware: FirmwareVersion,
    ) -> BoardToMaster {
        match result {
            Ok(Answer::Ack) => BoardToMaster::Ack { seq: self.seq },
            Ok(Answer::Status) => BoardToMaster::Status(*status),
            Ok(Answer::Hello {
                session,
                reset,
                geometry_version,
            }) => BoardToMaster::HelloReply {
                firmware_version: firmware,
                protocol_version: PROTOCOL_VERSION,
                session,
                reset,
                geometry_version,
            },
            Ok(Answer::FaultLog(page)) => BoardToMaster::FaultLog(page),
            Ok(Answer::EventLog(page)) => BoardToMaster::EventLog(page),
            Err(reason) => BoardToMaster::Nack {
                seq: self.seq,
                reason,
            },
        }
    }
}

/// The reply to a `StoreGeometry` of sequence number `seq`: `GeometryStored` with the
/// version, or `GeometryRefused` with the reason.
pub fn geometry_reply(seq: Seq, result: Result<u32, GeometryRefusal>) -> BoardToMaster {
    match result {
        Ok(version) => BoardToMaster::GeometryStored { seq, version },
        Err(reason) => BoardToMaster::GeometryRefused { seq, reason },
    }
}

/// What one received frame gives.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Inbound {
    /// For the runtime; reply with [`Request::reply`].
    Request(Request),
    /// The link answered itself: send this.
    Reply(BoardToMaster),
    /// A calibrated geometry to check (`Runtime::check_geometry`) and store (issue 19);
    /// answer with [`geometry_reply`]. It does not travel in the request queue (a record
    /// is 220 bytes, every other request at most 48): a target keeps one in a mailbox.
    Geometry {
        /// Sequence number of the master frame.
        seq: Seq,
        /// The record.
        record: GeometryRecord,
    },
}

/// Firmware version of this crate's release (the boards pass their own).
pub const FIRMWARE_VERSION: FirmwareVersion = FirmwareVersion {
    major: 0,
    minor: 1,
    patch: 0,
};

/// The receiving side: decoder, connection state.
pub struct LinkRx {
    decoder: BoardDecoder,
    connected: bool,
    last_error: Option<FrameError>,
    refused_not_connected: u32,
}

impl Default for LinkRx {
    fn default() -> Self {
        Self::new()
    }
}

impl LinkRx {
    /// Not connected, zero counters.
    pub const fn new() -> Self {
        LinkRx {
            decoder: BoardDecoder::new(),
            connected: false,
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
        match msg {
            MasterToBoard::Hello {
                protocol_version, ..
            } => {
                self.connected = protocol_version == PROTOCOL_VERSION;
                if !self.connected {
                    return Inbound::Reply(BoardToMaster::Nack {
                        seq,
                        reason: NackReason::UnsupportedVersion,
                    });
                }
            }
            MasterToBoard::EmergencyStop => {}
            _ if !self.connected => {
                self.refused_not_connected = self.refused_not_connected.wrapping_add(1);
                return Inbound::Reply(BoardToMaster::Nack {
                    seq,
                    reason: NackReason::NotConnected,
                });
            }
            MasterToBoard::StoreGeometry(record) => return Inbound::Geometry { seq, record },
            _ => {}
        }
        Inbound::Request(Request { seq, message: msg })
    }

    /// A `Hello` with the right version was received.
    pub fn connected(&self) -> bool {
        self.connected
    }
    /// The session the last `Hello` opened.
    pub fn session(&self) -> Option<u32> {
        self.decoder.session()
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

/// The sending side: the session and the board's sequence numbers.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LinkTx {
    session: u32,
    seq: SeqCounter,
    sent: u32,
    errors: u32,
}

impl LinkTx {
    /// Starts at sequence number 0, before any session.
    pub const fn new() -> Self {
        LinkTx {
            session: 0,
            seq: SeqCounter::new(0),
            sent: 0,
            errors: 0,
        }
    }
    /// Encodes `msg` as one frame (delimiter included) into `buf` (use
    /// `MAX_FRAME_LEN` bytes); returns its length. A `HelloReply` switches to its
    /// session: it and every later frame carry it.
    pub fn encode(&mut self, msg: &BoardToMaster, buf: &mut [u8]) -> Result<usize, EncodeError> {
        if let BoardToMaster::HelloReply { session, .. } = msg {
            self.session = *session;
        }
        let header = Header {
            session: self.session,
            seq: self.seq.peek(),
        };
        match encode(msg, header, buf) {
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
