//! Frame encoding and single-frame decoding.

use crc::{Crc, CRC_32_ISO_HDLC};

use crate::auth::{LinkKey, TAG_LEN};
use crate::cobs;
use crate::messages::{Seq, WireMessage};

/// Protocol version carried in every frame header (and in `Hello`).
/// Version 2 added the control tick's worst jitter and execution time to `StatusReport`;
/// 3 the refused targets; 4 the session nonce, the stop in force, fault causes with joint
/// and value, the reset cause, guard margins, currents, the fault log, rehoming
/// confirmation and frames of up to 255 bytes; 5 the session the board issues, one owner
/// (`HelloRefused`, `NotOwner`), the master's clock in `Hello`, the sequence window, targets
/// from the future refused and the authentication tag; 6 the non-volatile event log
/// (`EventLogRequest`, `EventLog`); 7 the second position channel
/// (`StatusReport::position_channel`, the causes `EncoderDisagree` and `PositionSensor`,
/// the fault flag `POSITION_SENSOR`); 8 refused targets with the guard or rule, subject,
/// value and limit (`TargetRefused`: the reply to a target refused at submission, and a
/// message of its own for every target the path check refuses).
pub const PROTOCOL_VERSION: u8 = 9;

/// Header length: version (1 byte) + session (4 bytes, little endian) + sequence number
/// (2 bytes, little endian).
pub const HEADER_LEN: usize = 7;
/// Checksum length: CRC-32 (little endian).
pub const CRC_LEN: usize = 4;
/// Maximum size of one frame on the wire, COBS overhead and the `0x00`
/// delimiter included. An encode buffer of this size always suffices, and a
/// [`FrameDecoder`](crate::FrameDecoder) with `N = MAX_FRAME_LEN` accepts
/// every valid frame.
pub const MAX_FRAME_LEN: usize = 255;
/// Maximum un-stuffed frame length (header + body + CRC): `MAX_FRAME_LEN`
/// minus one delimiter byte and the COBS overhead (1 byte up to 254 bytes).
pub const MAX_RAW_LEN: usize = MAX_FRAME_LEN - 2;
/// Maximum postcard body length (of a frame without a tag; an authenticated frame's body
/// is [`TAG_LEN`] bytes shorter at most).
pub const MAX_BODY_LEN: usize = MAX_RAW_LEN - HEADER_LEN - CRC_LEN;
/// Minimum un-stuffed frame length (the body has at least the enum tag).
pub const MIN_RAW_LEN: usize = HEADER_LEN + 1 + CRC_LEN;

/// CRC-32/ISO-HDLC (the Ethernet/zlib CRC-32) over header + body.
pub const CRC32: Crc<u32> = Crc::<u32>::new(&CRC_32_ISO_HDLC);

const _: () = assert!(cobs::max_encoded_len(MAX_RAW_LEN) + 1 == MAX_FRAME_LEN);

/// Error of [`encode`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum EncodeError {
    /// The output buffer is too small for this frame (use `MAX_FRAME_LEN`).
    BufferTooSmall,
    /// The body does not fit into `MAX_BODY_LEN` bytes.
    MessageTooLarge,
    /// postcard refused to serialize the message.
    Serialize,
}

/// Why a received frame is malformed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Malformed {
    /// Not valid COBS.
    Cobs,
    /// Shorter than header + 1 body byte + CRC.
    Truncated,
    /// The body is not a valid postcard message.
    Body,
    /// Bytes left over after the message body.
    TrailingBytes,
}

/// Why a received frame was dropped. Each case increments one counter of
/// [`LinkCounters`](crate::LinkCounters).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum FrameError {
    /// Structurally invalid frame (`malformed`).
    Malformed(Malformed),
    /// Longer than the receive buffer or than `MAX_RAW_LEN` (`oversized`).
    Oversized,
    /// CRC mismatch (`bad_checksum`).
    BadChecksum,
    /// The link has a key and the frame's tag does not verify, or it has none
    /// (`bad_tag`).
    BadTag,
    /// Valid frame of another protocol version (`wrong_version`).
    WrongVersion {
        /// Version found in the header.
        received: u8,
    },
    /// Sequence number not newer than the last accepted one, or newer by more than the
    /// window ([`SEQ_WINDOW`](crate::SEQ_WINDOW)) (`out_of_order`).
    OutOfOrder {
        /// Sequence number of the rejected frame.
        seq: Seq,
        /// Last accepted sequence number.
        last: Seq,
    },
    /// A frame of another session than the one open (`wrong_session`): e.g. replayed
    /// from an earlier connection, or sent by a master that does not own the board.
    WrongSession {
        /// Session in the frame's header.
        received: u32,
        /// The current session.
        expected: u32,
    },
}

/// The header of a frame: the session it belongs to and its sequence number.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Header {
    /// The session (the board issues it in `HelloReply`; 0: outside any session).
    pub session: u32,
    /// The sequence number.
    pub seq: Seq,
}

/// Encodes `msg` with the header `header` into `buf` as one complete frame
/// (COBS + trailing `0x00`). Returns the number of bytes written, delimiter
/// included; at most [`MAX_FRAME_LEN`].
pub fn encode<M: WireMessage>(
    msg: &M,
    header: Header,
    buf: &mut [u8],
) -> Result<usize, EncodeError> {
    encode_with(msg, header, None, buf)
}

/// [`encode`] with the link's key: with one, the frame carries the tag of its header and
/// body ([`crate::auth`]).
pub fn encode_with<M: WireMessage>(
    msg: &M,
    header: Header,
    key: Option<&LinkKey>,
    buf: &mut [u8],
) -> Result<usize, EncodeError> {
    let mut raw = [0u8; MAX_RAW_LEN];
    let [version, s0, s1, s2, s3, seq_lo, seq_hi, body_and_crc @ ..] = &mut raw;
    *version = PROTOCOL_VERSION;
    [*s0, *s1, *s2, *s3] = header.session.to_le_bytes();
    [*seq_lo, *seq_hi] = header.seq.to_le_bytes();

    let body_buf = body_and_crc
        .get_mut(..MAX_BODY_LEN)
        .ok_or(EncodeError::MessageTooLarge)?;
    let body_len = postcard::to_slice(msg, body_buf)
        .map_err(|e| match e {
            postcard::Error::SerializeBufferFull => EncodeError::MessageTooLarge,
            _ => EncodeError::Serialize,
        })?
        .len();

    let mut content_len = HEADER_LEN + body_len;
    if let Some(key) = key {
        let tag = key.tag(raw.get(..content_len).ok_or(EncodeError::MessageTooLarge)?);
        let slot = raw
            .get_mut(content_len..content_len + TAG_LEN)
            .ok_or(EncodeError::MessageTooLarge)?;
        slot.copy_from_slice(&tag);
        content_len += TAG_LEN;
    }
    let crc = CRC32.checksum(raw.get(..content_len).ok_or(EncodeError::MessageTooLarge)?);
    let crc_slot = raw
        .get_mut(content_len..content_len + CRC_LEN)
        .ok_or(EncodeError::MessageTooLarge)?;
    for (dst, src) in crc_slot.iter_mut().zip(crc.to_le_bytes()) {
        *dst = src;
    }

    let raw = raw
        .get(..content_len + CRC_LEN)
        .ok_or(EncodeError::MessageTooLarge)?;
    let n = cobs::encode(raw, buf).ok_or(EncodeError::BufferTooSmall)?;
    *buf.get_mut(n).ok_or(EncodeError::BufferTooSmall)? = 0;
    Ok(n + 1)
}

/// Decodes one frame **without** its `0x00` delimiter. `encoded` is
/// COBS-decoded in place (its content is destroyed). Checks, in order: COBS,
/// length, CRC, protocol version, body. Does *not* check the sequence number
/// nor the session (that is the job of [`FrameDecoder`](crate::FrameDecoder)).
pub fn decode_frame<M: WireMessage>(encoded: &mut [u8]) -> Result<(Header, M), FrameError> {
    decode_frame_with(encoded, None)
}

/// [`decode_frame`] with the link's key: with one, the tag is checked after the CRC and
/// before anything else is read.
pub fn decode_frame_with<M: WireMessage>(
    encoded: &mut [u8],
    key: Option<&LinkKey>,
) -> Result<(Header, M), FrameError> {
    let n = cobs::decode_in_place(encoded).ok_or(FrameError::Malformed(Malformed::Cobs))?;
    if n > MAX_RAW_LEN {
        return Err(FrameError::Oversized);
    }
    if n < MIN_RAW_LEN {
        return Err(FrameError::Malformed(Malformed::Truncated));
    }
    let raw = encoded
        .get(..n)
        .ok_or(FrameError::Malformed(Malformed::Truncated))?;
    let (content, crc_bytes) = raw
        .split_at_checked(n - CRC_LEN)
        .ok_or(FrameError::Malformed(Malformed::Truncated))?;
    let crc_bytes: [u8; CRC_LEN] = crc_bytes
        .try_into()
        .map_err(|_| FrameError::Malformed(Malformed::Truncated))?;
    if CRC32.checksum(content) != u32::from_le_bytes(crc_bytes) {
        return Err(FrameError::BadChecksum);
    }
    let content = match key {
        None => content,
        Some(key) => {
            let (signed, tag) = content
                .split_at_checked(content.len().saturating_sub(TAG_LEN))
                .ok_or(FrameError::BadTag)?;
            if signed.len() <= HEADER_LEN || !key.verify(signed, tag) {
                return Err(FrameError::BadTag);
            }
            signed
        }
    };
    let [version, s0, s1, s2, s3, seq_lo, seq_hi, body @ ..] = content else {
        return Err(FrameError::Malformed(Malformed::Truncated));
    };
    if *version != PROTOCOL_VERSION {
        return Err(FrameError::WrongVersion { received: *version });
    }
    let header = Header {
        session: u32::from_le_bytes([*s0, *s1, *s2, *s3]),
        seq: Seq::from_le_bytes([*seq_lo, *seq_hi]),
    };
    let (msg, rest) =
        postcard::take_from_bytes::<M>(body).map_err(|_| FrameError::Malformed(Malformed::Body))?;
    if !rest.is_empty() {
        return Err(FrameError::Malformed(Malformed::TrailingBytes));
    }
    Ok((header, msg))
}
