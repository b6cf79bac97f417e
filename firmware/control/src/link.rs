//! The board side of the master link.
//!
//! ```text
//! UART bytes -> LinkRx (BoardDecoder: COBS, CRC, tag, version, session, sequence) -> Inbound
//!     Inbound::Reply    answered by the link itself (Nack NotConnected, HelloRefused
//!                       UnsupportedVersion)
//!     Inbound::Request  a Command for the runtime (a Hello with the session the link
//!                       issued for it, state-machine event, pose target, heartbeat, status,
//!                       fault-log or event-log request); its outcome becomes HelloReply /
//!                       HelloRefused / Status / FaultLog / EventLog / Ack / Nack
//!     Inbound::Geometry a calibrated geometry: checked by the runtime, stored by the
//!                       target; GeometryStored / GeometryRefused
//! replies -> LinkTx (the session, sequence numbers, tag, encode into the caller's buffer)
//!     -> UART
//! ```
//! Malformed, oversized, wrong-version, bad-checksum, untagged or wrongly tagged (on a
//! link with a key), out-of-order (replayed, or beyond the sequence window) frames and
//! frames of another session are counted by the decoder ([`LinkCounters`]) and dropped; an
//! intact (and, with a key, authentic) `EmergencyStop` frame is never dropped.
//!
//! **Sessions.** The board issues them: every `Hello` with the board's protocol version
//! goes to the runtime with a fresh session id ([`SessionIssuer`]: SHA-256 of a counter,
//! the uptime, the `Hello`'s nonce and clock, and the board's identity, which holds the
//! chip's unique id and the link key when there is one). The runtime decides whether the
//! master may have it (one owner, `control::modes::next`); if it may, the reply is the
//! `HelloReply` with that session, and the target opens it on the receiving side
//! ([`LinkRx::open_session`], with the `Hello`'s sequence number as the reference) before
//! the reply goes out, so the master's first frame of the session finds it open. A refused
//! `Hello` changes nothing on the link: the owner's session and sequence reference stay.
//! Before any session only `Hello` and `EmergencyStop` are taken; everything else is
//! refused with `NotConnected`. Every accepted master frame gets exactly one reply carrying
//! its sequence number.
//!
//! **Keys.** With a link key ([`LinkRx::with`], [`LinkTx::with_key`]) every frame both ways
//! carries the truncated HMAC-SHA256 tag (`master_link::auth`), checked and computed here,
//! in the link's tasks, never in the control tick.

use sha2::{Digest, Sha256};

use master_link::{
    encode_with, BoardDecoder, BoardToMaster, EncodeError, EventLogPage, FaultLogPage,
    FirmwareVersion, FrameError, GeometryRecord, GeometryRefusal, Header, LinkCounters, LinkKey,
    MasterToBoard, NackReason, ResetStatus, Seq, SeqCounter, StatusReport, PROTOCOL_VERSION,
};

/// A request with the sequence number its reply carries.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Request {
    /// Sequence number of the master frame.
    pub seq: Seq,
    /// The master's message (never a `StoreGeometry`: that is [`Inbound::Geometry`]).
    pub message: MasterToBoard,
    /// For a `Hello`: the session the link issued for it, the `HelloReply`'s if the
    /// runtime accepts the `Hello`. For any other frame: the session it came in, so that
    /// a frame the link took before another master's `Hello` was accepted is refused when
    /// its turn comes ([`crate::service::TickService::request`]). 0: a request made on the
    /// board (tests, the targets' own), not checked.
    pub session: u32,
}

impl Request {
    /// A request that is no `Hello` (tests, and the targets' own requests).
    pub const fn new(seq: Seq, message: MasterToBoard) -> Self {
        Request {
            seq,
            message,
            session: 0,
        }
    }
}

/// What the runtime answers to a request it accepted.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Answer {
    /// `Ack`.
    Ack,
    /// The status.
    Status,
    /// The `Hello` is accepted: `HelloReply` with the session the link issued, the
    /// nonce echoed and the reset status.
    Hello {
        /// The `Hello`'s nonce.
        nonce: u32,
        /// The last reset and its acknowledgement.
        reset: ResetStatus,
        /// The stored calibrated geometry's version (0: none).
        geometry_version: u32,
    },
    /// A page of the fault log.
    FaultLog(FaultLogPage),
    /// A page of the event log.
    EventLog(EventLogPage),
    /// A joint's commissioning record.
    Commission(master_link::CommissionRecord),
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
                nonce,
                reset,
                geometry_version,
            }) => BoardToMaster::HelloReply {
                firmware_version: firmware,
                protocol_version: PROTOCOL_VERSION,
                session: self.session,
                nonce,
                reset,
                geometry_version,
            },
            Ok(Answer::FaultLog(page)) => BoardToMaster::FaultLog(page),
            Ok(Answer::EventLog(page)) => BoardToMaster::EventLog(page),
            Ok(Answer::Commission(record)) => BoardToMaster::Commissioning(record),
            Err(reason) => match self.message {
                MasterToBoard::Hello { nonce, .. } => BoardToMaster::HelloRefused {
                    seq: self.seq,
                    nonce,
                    reason,
                },
                _ => BoardToMaster::Nack {
                    seq: self.seq,
                    reason,
                },
            },
        }
    }
}

/// The session a reply opens: a `HelloReply`'s (the target opens it on the receiving side
/// with the `Hello`'s sequence number before the reply goes out).
pub const fn opened_session(reply: &BoardToMaster) -> Option<u32> {
    match reply {
        BoardToMaster::HelloReply { session, .. } => Some(*session),
        _ => None,
    }
}

/// The board's identity for session ids: 32 bytes no master can read off the link,
/// hashed from the chip's unique id and the link key when there is one.
#[derive(Clone, Copy, PartialEq, Eq)]
pub struct BoardIdentity([u8; 32]);

impl core::fmt::Debug for BoardIdentity {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str("BoardIdentity(..)")
    }
}

impl BoardIdentity {
    /// SHA-256 of the chip's unique id `chip_id` and, with a link key, the key's tag of a
    /// constant (a secret only the key's holders can compute).
    pub fn new(chip_id: &[u8], key: Option<&LinkKey>) -> Self {
        let mut h = Sha256::new();
        h.update(b"rspr-board-identity");
        h.update(chip_id);
        if let Some(k) = key {
            h.update(k.tag(b"rspr-board-identity"));
        }
        BoardIdentity(h.finalize().into())
    }
}

/// Issues the board's session ids: the first 4 bytes of SHA-256 over a counter, the
/// uptime (µs), the `Hello`'s nonce and clock, and the board's identity; never 0 (0 is
/// "outside any session"). Fresh for every `Hello`; from the outside not predictable
/// without the identity (with a key: not at all), and not repeated across a reboot unless
/// a `Hello` arrives at the very microsecond with the same counter, nonce and clock.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SessionIssuer {
    identity: BoardIdentity,
    counter: u32,
    uptime_us: u64,
}

impl SessionIssuer {
    /// For the board `identity`.
    pub const fn new(identity: BoardIdentity) -> Self {
        SessionIssuer {
            identity,
            counter: 0,
            uptime_us: 0,
        }
    }
    /// The uptime now, µs (the receiving task sets it as bytes arrive).
    pub fn set_uptime(&mut self, now_us: u64) {
        self.uptime_us = now_us;
    }
    /// A fresh session id for a `Hello` with `nonce` and `clock_us`.
    pub fn issue(&mut self, nonce: u32, clock_us: u64) -> u32 {
        self.counter = self.counter.wrapping_add(1);
        let mut h = Sha256::new();
        h.update(self.counter.to_le_bytes());
        h.update(self.uptime_us.to_le_bytes());
        h.update(nonce.to_le_bytes());
        h.update(clock_us.to_le_bytes());
        h.update(self.identity.0);
        let d: [u8; 32] = h.finalize().into();
        let [a, b, c, e, ..] = d;
        u32::from_le_bytes([a, b, c, e]).max(1)
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
    /// A calibrated geometry to check (`Runtime::check_geometry`) and store;
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

/// The receiving side: decoder (with the link key, if any), the session issuer.
pub struct LinkRx {
    decoder: BoardDecoder,
    issuer: SessionIssuer,
    last_error: Option<FrameError>,
    refused_not_connected: u32,
}

impl Default for LinkRx {
    fn default() -> Self {
        Self::new()
    }
}

impl LinkRx {
    /// Not connected, zero counters, no key, an identity of zeros (tests, a board on a
    /// desk without a chip id).
    pub const fn new() -> Self {
        LinkRx {
            decoder: BoardDecoder::new(),
            issuer: SessionIssuer::new(BoardIdentity([0; 32])),
            last_error: None,
            refused_not_connected: 0,
        }
    }

    /// Not connected, for the board `identity`, with the link key `key` (None: frames
    /// carry no tag).
    pub fn with(identity: BoardIdentity, key: Option<LinkKey>) -> Self {
        LinkRx {
            decoder: BoardDecoder::with_key(key),
            issuer: SessionIssuer::new(identity),
            last_error: None,
            refused_not_connected: 0,
        }
    }

    /// The uptime now, µs: mixed into the next session ids.
    pub fn set_uptime(&mut self, now_us: u64) {
        self.issuer.set_uptime(now_us);
    }

    /// The runtime accepted the `Hello` of sequence number `seq` and the board answers it
    /// with `session`: from now on only that session's frames pass, counted from `seq`.
    pub fn open_session(&mut self, session: u32, seq: Seq) {
        self.decoder.open_session(session, seq);
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
                protocol_version,
                nonce,
                clock_us,
            } => {
                if protocol_version != PROTOCOL_VERSION {
                    return Inbound::Reply(BoardToMaster::HelloRefused {
                        seq,
                        nonce,
                        reason: NackReason::UnsupportedVersion,
                    });
                }
                let session = self.issuer.issue(nonce, clock_us);
                return Inbound::Request(Request {
                    seq,
                    message: msg,
                    session,
                });
            }
            MasterToBoard::EmergencyStop => {}
            _ if !self.connected() => {
                self.refused_not_connected = self.refused_not_connected.wrapping_add(1);
                return Inbound::Reply(BoardToMaster::Nack {
                    seq,
                    reason: NackReason::NotConnected,
                });
            }
            MasterToBoard::StoreGeometry(record) => return Inbound::Geometry { seq, record },
            _ => {}
        }
        Inbound::Request(Request {
            seq,
            message: msg,
            session: self.decoder.session().unwrap_or(0),
        })
    }

    /// A session is open (a `Hello` was accepted).
    pub fn connected(&self) -> bool {
        self.decoder.session().is_some()
    }
    /// The session open, if any.
    pub fn session(&self) -> Option<u32> {
        self.decoder.session()
    }
    /// Forgets the session and the sequence reference (e.g. after a long silence): the
    /// master must send `Hello` again.
    pub fn disconnect(&mut self) {
        self.decoder.reset();
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

/// The sending side: the session, the board's sequence numbers, the link key.
#[derive(Clone, Debug, Default)]
pub struct LinkTx {
    session: u32,
    seq: SeqCounter,
    sent: u32,
    errors: u32,
    key: Option<LinkKey>,
}

impl LinkTx {
    /// Starts at sequence number 0, before any session.
    pub const fn new() -> Self {
        LinkTx {
            session: 0,
            seq: SeqCounter::new(0),
            sent: 0,
            errors: 0,
            key: None,
        }
    }
    /// Starts at sequence number 0, before any session, with the link key `key`.
    pub fn with_key(key: Option<LinkKey>) -> Self {
        LinkTx {
            key,
            ..LinkTx::new()
        }
    }
    /// Encodes `msg` as one frame (delimiter included) into `buf` (use
    /// `MAX_FRAME_LEN` bytes); returns its length. A `HelloReply` switches to its
    /// session: it and every later frame carry it. A `HelloRefused` goes out outside any
    /// session (session 0): the refused master has none, and the owner's stays.
    pub fn encode(&mut self, msg: &BoardToMaster, buf: &mut [u8]) -> Result<usize, EncodeError> {
        if let Some(session) = opened_session(msg) {
            self.session = session;
        }
        let session = match msg {
            BoardToMaster::HelloRefused { .. } => 0,
            _ => self.session,
        };
        let header = Header {
            session,
            seq: self.seq.peek(),
        };
        match encode_with(msg, header, self.key.as_ref(), buf) {
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
