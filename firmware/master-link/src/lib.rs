//! `master-link`: the binary serial protocol between the host master
//! (`host-sim`) and the STM32F4 actuator-controller board of the 6-DOF RSPR
//! parallel robot.
//!
//! `no_std`, allocation-free and panic-free: every byte sequence fed to the
//! [`FrameDecoder`] is handled without panicking, and encoding into a buffer
//! that is too small returns [`EncodeError::BufferTooSmall`].
//!
//! # Frame layout
//!
//! ```text
//! on the wire:   COBS(raw) 0x00            (<= MAX_FRAME_LEN = 255 bytes)
//!
//! raw (un-stuffed, 12..=253 bytes):
//! +---------+-----------+-----------+------------------------+-----------+-----------+
//! | version | session   | sequence  | body                   | tag       | CRC-32    |
//! | u8      | u32 LE    | u16 LE    | postcard(MasterToBoard | (keyed    | u32 LE    |
//! |         |           |           |  | BoardToMaster)      |  links)   |           |
//! +---------+-----------+-----------+------------------------+-----------+-----------+
//!   1 byte    4 bytes     2 bytes     1..=242 bytes            8 bytes     4 bytes
//!   \_______ the tag (HMAC-SHA256, truncated) covers these ______/
//!   \______________________ CRC-32/ISO-HDLC covers these ______________________/
//! ```
//!
//! * **version**: [`PROTOCOL_VERSION`]; frames of another version are
//!   counted (`wrong_version`) and dropped. The version byte position, COBS
//!   and the CRC are frozen across protocol versions.
//! * **session**: the board issues it. The master's `Hello` carries its nonce (its
//!   identity for the connection) and its clock; the board answers `HelloReply` with a
//!   session it chose, fresh for every accepted `Hello` and echoing the nonce, or
//!   `HelloRefused` (another master owns the board, a replayed `Hello`). Every later frame
//!   of both directions carries the session; a receiver with a session open refuses frames
//!   of any other as `wrong_session` (a recording replayed from an earlier connection, a
//!   master that does not own the board). Session 0 is "outside any session" (the board's
//!   `HelloRefused`). The decoder takes handshakes whatever their header and opens a
//!   session only when told ([`FrameDecoder::open_session`]).
//! * **sequence**: per direction, incremented by the sender for every frame
//!   ([`SeqCounter`]), wrapping. The receiver takes a number newer than the last taken
//!   one by at most [`SEQ_WINDOW`] (256; serial-number arithmetic), counts the skipped
//!   numbers as `dropped`, and refuses older ones (replays) and ones further ahead as
//!   `out_of_order` without moving its reference, so that a stray frame cannot lock the
//!   sender out. Opening a session sets the reference to the handshake's number.
//!   `Ack`/`Nack` carry the sequence number of the master frame they answer.
//!   An `EmergencyStop` is never dropped by the session or sequence checks: an intact
//!   frame carrying it is always taken.
//! * **body**: postcard encoding of the message enum; the message kind is the
//!   enum variant index (first varint). Variants and fields are append-only within a
//!   protocol version.
//! * **tag** (only on a link with a pre-shared key, [`LinkKey`]): the first 8 bytes of
//!   HMAC-SHA256 over version, session, sequence and body ([`auth`]); a receiver with
//!   the key drops frames with a wrong or missing tag (`bad_tag`), emergency stops and
//!   handshakes included. Without a key there is no tag (a board on a desk).
//! * **CRC**: CRC-32/ISO-HDLC (zlib/Ethernet) of everything before it,
//!   checked first.
//! * **framing**: the raw frame is COBS-encoded (so it contains no `0x00`)
//!   and terminated by one `0x00`. Extra `0x00` bytes (empty frames) are
//!   ignored and may be sent to resynchronise a receiver.
//!
//! Frames longer than the decoder capacity `N` are discarded up to the
//! next delimiter and counted as `oversized`. The largest frame, a status report with
//! every varint at its maximum, is 247 bytes on the wire, 255 with its tag (`MAX_FRAME_LEN`: no byte to spare).
//!
//! # Example
//!
//! ```
//! use master_link::{encode, BoardDecoder, Header, MasterToBoard, MAX_FRAME_LEN};
//!
//! let mut wire = [0u8; MAX_FRAME_LEN];
//! let header = Header { session: 0, seq: 7 };
//! let n = encode(&MasterToBoard::Clutch { engaged: true }, header, &mut wire).unwrap();
//!
//! let mut rx = BoardDecoder::new();
//! let mut got = None;
//! for byte in &wire[..n] {
//!     if let Some(result) = rx.push(*byte) {
//!         got = Some(result);
//!     }
//! }
//! assert_eq!(got, Some(Ok((7, MasterToBoard::Clutch { engaged: true }))));
//! assert_eq!(rx.counters().frames_ok, 1);
//! ```
#![cfg_attr(not(test), no_std)]
#![deny(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::indexing_slicing
)]
#![warn(missing_docs)]

// The `arbitrary` feature (the fuzz harness's, on the host only) derives
// `arbitrary::Arbitrary`, whose code names `std`.
#[cfg(all(feature = "arbitrary", not(test)))]
extern crate std;

pub mod auth;
pub mod cobs;
mod decoder;
mod flags;
mod frame;
mod messages;
pub mod shared_clock;

pub use auth::{KeyError, LinkKey, KEY_LEN, TAG_LEN};
pub use decoder::{
    seq_is_newer, BoardDecoder, Feed, FrameDecoder, MasterDecoder, SeqCounter, SEQ_WINDOW,
};
pub use flags::{Faults, Warnings};
pub use frame::{
    decode_frame, decode_frame_with, encode, encode_with, EncodeError, FrameError, Header,
    Malformed, CRC32, CRC_LEN, HEADER_LEN, MAX_BODY_LEN, MAX_FRAME_LEN, MAX_RAW_LEN, MIN_RAW_LEN,
    PROTOCOL_VERSION,
};
pub use messages::{
    BoardToMaster, Breach, CommissionFindings, CommissionRecord, EventEntry, EventKind,
    EventLogPage, FaultCause, FaultLogEntry, FaultLogPage, FaultRecord, FirmwareVersion,
    GeometryRecord, GeometryRefusal, GuardId, GuardMargins, LinkCounters, MasterToBoard,
    NackReason, RefusedTarget, ResetCause, ResetStatus, RobotState, Seq, StatusReport, StopReason,
    StopStatus, WireMessage, EVENT_LOG_PAGE, FAULT_LOG_PAGE, GEOMETRY_CHAIN_VALUES,
    GEOMETRY_LAYOUT, JOINT_COUNT, JOINT_L1, JOINT_L2, JOINT_L3, JOINT_THETA1, JOINT_THETA2,
    JOINT_THETA3, NO_JOINT,
};
