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
//! +---------+-----------+-----------+---------------------------+-----------+
//! | version | session   | sequence  | body                      | CRC-32    |
//! | u8      | u32 LE    | u16 LE    | postcard(MasterToBoard |  | u32 LE    |
//! |         |           |           |          BoardToMaster)   |           |
//! +---------+-----------+-----------+---------------------------+-----------+
//!   1 byte    4 bytes     2 bytes     1..=242 bytes               4 bytes
//!   \______________ CRC-32/ISO-HDLC covers these ______________/
//! ```
//!
//! * **version**: [`PROTOCOL_VERSION`]; frames of another version are
//!   counted (`wrong_version`) and dropped. The version byte position, COBS
//!   and the CRC are frozen across protocol versions.
//! * **session**: the master's `Hello` carries a fresh nonce and opens a session; the
//!   board's `HelloReply` confirms it, and every later frame of both directions carries
//!   it. A receiver refuses frames of another session as `wrong_session` (an earlier
//!   connection's frames, replayed).
//! * **sequence**: per direction, incremented by the sender for every frame
//!   ([`SeqCounter`]), wrapping. The receiver rejects numbers that are not
//!   newer than the last accepted one (serial-number arithmetic, window
//!   [`SEQ_WINDOW`]) as `out_of_order`, accepts gaps and counts the skipped
//!   numbers as `dropped`. `Hello` / `HelloReply` restart the sequence.
//!   `Ack`/`Nack` carry the sequence number of the master frame they answer.
//!   An `EmergencyStop` is never dropped by the session or sequence checks: an intact
//!   frame carrying it is always taken.
//! * **body**: postcard encoding of the message enum; the message kind is the
//!   enum variant index (first varint). Variants and fields are append-only.
//! * **CRC**: CRC-32/ISO-HDLC (zlib/Ethernet) of version + sequence + body,
//!   checked before the version.
//! * **framing**: the raw frame is COBS-encoded (so it contains no `0x00`)
//!   and terminated by one `0x00`. Extra `0x00` bytes (empty frames) are
//!   ignored and may be sent to resynchronise a receiver.
//!
//! Frames longer than the decoder capacity `N` are discarded up to the
//! next delimiter and counted as `oversized`.
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

pub mod cobs;
mod decoder;
mod flags;
mod frame;
mod messages;

pub use decoder::{
    seq_is_newer, BoardDecoder, Feed, FrameDecoder, MasterDecoder, SeqCounter, SEQ_WINDOW,
};
pub use flags::{Faults, Warnings};
pub use frame::{
    decode_frame, encode, EncodeError, FrameError, Header, Malformed, CRC32, CRC_LEN, HEADER_LEN,
    MAX_BODY_LEN, MAX_FRAME_LEN, MAX_RAW_LEN, MIN_RAW_LEN, PROTOCOL_VERSION,
};
pub use messages::{
    BoardToMaster, EventEntry, EventKind, EventLogPage, FaultCause, FaultLogEntry, FaultLogPage,
    FaultRecord, FirmwareVersion, GeometryRecord, GeometryRefusal, GuardMargins, LinkCounters,
    MasterToBoard, NackReason, ResetCause, ResetStatus, RobotState, Seq, StatusReport, StopReason,
    StopStatus, WireMessage, EVENT_LOG_PAGE, FAULT_LOG_PAGE, GEOMETRY_CHAIN_VALUES,
    GEOMETRY_LAYOUT, JOINT_COUNT, JOINT_L1, JOINT_L2, JOINT_L3, JOINT_THETA1, JOINT_THETA2,
    JOINT_THETA3, NO_JOINT,
};
