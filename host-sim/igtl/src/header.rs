//! The 58-byte message header common to every protocol version.
//!
//! ```text
//! bytes 0..2    V            uint16   header version: 1 (protocols 1 and 2), 2 (protocol 3)
//! bytes 2..14   TYPE         char[12] type name, NUL-padded
//! bytes 14..34  DEVICE_NAME  char[20] device name, NUL-padded
//! bytes 34..42  TIME_STAMP   uint64   32.32 fixed point seconds since 1970, 0 = unused
//! bytes 42..50  BODY_SIZE    uint64   bytes that follow the header
//! bytes 50..58  CRC64        uint64   CRC-64/ECMA-182 of those bytes
//! ```
//! Every number is big-endian. Version-3 messages (header version 2) begin their body with
//! the extended header ([`crate::metadata`]).
//!
//! Decoding is strict so that a byte stream can be resynchronised after garbage: the
//! version must be 1 or 2, the type name 1 to 12 printable ASCII characters (no space)
//! followed only by NUL bytes, and the device name 0 to 20 bytes of UTF-8 without control
//! characters, also followed only by NUL bytes. This is what the reference library
//! (`strncpy`), pyigtl (`struct.pack("12s")`) and Slicer write.

use crate::timestamp::Timestamp;
use thiserror::Error;

/// Size of the header in bytes.
pub const HEADER_SIZE: usize = 58;
/// Size of the type name field in bytes.
pub const TYPE_NAME_SIZE: usize = 12;
/// Size of the device name field in bytes.
pub const DEVICE_NAME_SIZE: usize = 20;

/// The header version field.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum HeaderVersion {
    /// Header version 1: protocol versions 1 and 2 (the body is the content).
    V1,
    /// Header version 2: protocol version 3 (extended header, content, metadata).
    V2,
}

impl HeaderVersion {
    /// The value of the version field.
    pub fn wire(self) -> u16 {
        match self {
            HeaderVersion::V1 => 1,
            HeaderVersion::V2 => 2,
        }
    }

    /// The version for a field value, `None` for values other than 1 and 2.
    pub fn from_wire(v: u16) -> Option<Self> {
        match v {
            1 => Some(HeaderVersion::V1),
            2 => Some(HeaderVersion::V2),
            _ => None,
        }
    }
}

/// A decoded header.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Header {
    /// Header version.
    pub version: HeaderVersion,
    /// Type name, e.g. `TRANSFORM` or `GET_STATUS`.
    pub type_name: String,
    /// Device name (may be empty).
    pub device_name: String,
    /// Timestamp.
    pub timestamp: Timestamp,
    /// Bytes of body that follow the header.
    pub body_size: u64,
    /// CRC-64 of the body as written by the sender.
    pub crc: u64,
}

/// Why 58 bytes are not a header.
#[derive(Clone, Debug, PartialEq, Eq, Error)]
pub enum HeaderError {
    /// The version field is neither 1 nor 2.
    #[error("header version {0} is neither 1 (protocols 1 and 2) nor 2 (protocol 3)")]
    UnsupportedVersion(u16),
    /// The type name field is not 1..=12 printable ASCII characters padded with NUL.
    #[error("type name field {0:02x?} is not 1 to 12 printable ASCII characters padded with NUL")]
    BadTypeName([u8; TYPE_NAME_SIZE]),
    /// The device name field is not UTF-8 text without control characters padded with NUL.
    #[error(
        "device name field {0:02x?} is not UTF-8 text without control characters padded with NUL"
    )]
    BadDeviceName([u8; DEVICE_NAME_SIZE]),
}

/// A type or device name that cannot be written into a header.
#[derive(Clone, Debug, PartialEq, Eq, Error)]
pub enum NameError {
    /// The type name is empty, longer than 12 bytes or not printable ASCII without space.
    #[error("type name {0:?} is not 1 to 12 printable ASCII characters without space")]
    TypeName(String),
    /// The device name is longer than 20 bytes or holds control characters.
    #[error("device name {0:?} is longer than 20 bytes or holds control characters")]
    DeviceName(String),
}

/// True for a valid type name: 1 to 12 printable ASCII characters, no space.
pub fn is_valid_type_name(name: &str) -> bool {
    !name.is_empty()
        && name.len() <= TYPE_NAME_SIZE
        && name.bytes().all(|b| (0x21..=0x7E).contains(&b))
}

/// True for a valid device name: at most 20 bytes of UTF-8 without control characters.
pub fn is_valid_device_name(name: &str) -> bool {
    name.len() <= DEVICE_NAME_SIZE && !name.chars().any(char::is_control)
}

/// The text of a NUL-padded field: the bytes before the first NUL, `None` when a non-NUL
/// byte follows a NUL.
fn padded_text(field: &[u8]) -> Option<&[u8]> {
    let end = field.iter().position(|&b| b == 0).unwrap_or(field.len());
    let (text, pad) = field.split_at(end);
    pad.iter().all(|&b| b == 0).then_some(text)
}

fn be_u64(b: &[u8], at: usize) -> u64 {
    let mut a = [0u8; 8];
    a.copy_from_slice(&b[at..at + 8]);
    u64::from_be_bytes(a)
}

/// A cheap test of whether a header may start at `bytes[0]`, on the bytes available (at
/// most the first three are looked at): version 0x0001 or 0x0002 and a printable first
/// type-name character. Used to skip garbage quickly before a full [`Header::decode`].
pub fn may_start_header(bytes: &[u8]) -> bool {
    let ok0 = bytes.first().is_none_or(|&b| b == 0);
    let ok1 = bytes.get(1).is_none_or(|&b| b == 1 || b == 2);
    let ok2 = bytes.get(2).is_none_or(|b| (0x21..=0x7E).contains(b));
    ok0 && ok1 && ok2
}

impl Header {
    /// Decodes and validates a header.
    pub fn decode(bytes: &[u8; HEADER_SIZE]) -> Result<Header, HeaderError> {
        let raw_version = u16::from_be_bytes([bytes[0], bytes[1]]);
        let version = HeaderVersion::from_wire(raw_version)
            .ok_or(HeaderError::UnsupportedVersion(raw_version))?;

        let mut type_field = [0u8; TYPE_NAME_SIZE];
        type_field.copy_from_slice(&bytes[2..14]);
        let type_name = padded_text(&type_field)
            .filter(|t| !t.is_empty() && t.iter().all(|b| (0x21..=0x7E).contains(b)))
            .and_then(|t| std::str::from_utf8(t).ok())
            .ok_or(HeaderError::BadTypeName(type_field))?
            .to_owned();

        let mut device_field = [0u8; DEVICE_NAME_SIZE];
        device_field.copy_from_slice(&bytes[14..34]);
        let device_name = padded_text(&device_field)
            .and_then(|t| std::str::from_utf8(t).ok())
            .filter(|t| !t.chars().any(char::is_control))
            .ok_or(HeaderError::BadDeviceName(device_field))?
            .to_owned();

        Ok(Header {
            version,
            type_name,
            device_name,
            timestamp: Timestamp(be_u64(bytes, 34)),
            body_size: be_u64(bytes, 42),
            crc: be_u64(bytes, 50),
        })
    }

    /// Encodes the header; the names are checked.
    pub fn encode(&self) -> Result<[u8; HEADER_SIZE], NameError> {
        if !is_valid_type_name(&self.type_name) {
            return Err(NameError::TypeName(self.type_name.clone()));
        }
        if !is_valid_device_name(&self.device_name) {
            return Err(NameError::DeviceName(self.device_name.clone()));
        }
        let mut out = [0u8; HEADER_SIZE];
        out[0..2].copy_from_slice(&self.version.wire().to_be_bytes());
        out[2..2 + self.type_name.len()].copy_from_slice(self.type_name.as_bytes());
        out[14..14 + self.device_name.len()].copy_from_slice(self.device_name.as_bytes());
        out[34..42].copy_from_slice(&self.timestamp.0.to_be_bytes());
        out[42..50].copy_from_slice(&self.body_size.to_be_bytes());
        out[50..58].copy_from_slice(&self.crc.to_be_bytes());
        Ok(out)
    }
}
