//! The content (protocol-2 body) of the message types this crate handles, as wire values.
//!
//! - TRANSFORM (48 bytes): 12 float32, `R11 R21 R31 R12 R22 R32 R13 R23 R33 TX TY TZ`, the
//!   upper 3x4 of the 4x4 matrix column by column; translation in millimetres.
//! - POSITION, alias QTRANS (28, 24 or 12 bytes): `X Y Z` in millimetres, then the
//!   quaternion `OX OY OZ W` (28 bytes), only `OX OY OZ` with `W = sqrt(1 - |v|^2)` (24
//!   bytes) or nothing (12 bytes, position only); the sizes of the reference library's
//!   `ALL`, `WITH_QUATERNION3` and `POSITION_ONLY`.
//! - STATUS (30 bytes or more): `C` uint16 status code, sub code int64, error name
//!   char\[20\], then the status message; written NUL-terminated as the reference does.
//! - STRING (4 bytes or more): encoding uint16 (IANA MIBenum, 3 = US-ASCII), length uint16,
//!   then exactly that many bytes.
//! - RTS_ (1 byte): 0 success, 1 error.
//!
//! Every number is big-endian. Decoding checks sizes only; what the values mean (a rigid
//! transform, a unit quaternion) is checked where they are used ([`crate::pose`]).

use thiserror::Error;

/// Size of TRANSFORM content.
pub const TRANSFORM_SIZE: usize = 48;
/// Size of POSITION content with the full quaternion.
pub const POSITION_SIZE: usize = 28;
/// Size of POSITION content with three quaternion elements.
pub const POSITION_QUATERNION3_SIZE: usize = 24;
/// Size of POSITION content without orientation.
pub const POSITION_ONLY_SIZE: usize = 12;
/// Size of the fixed part of STATUS content.
pub const STATUS_HEADER_SIZE: usize = 30;
/// Size of the STATUS error name field.
pub const STATUS_ERROR_NAME_SIZE: usize = 20;
/// Longest STRING text, in bytes.
pub const STRING_MAX_LEN: usize = u16::MAX as usize;

/// Content whose size or layout does not match its type.
#[derive(Clone, Debug, PartialEq, Eq, Error)]
pub enum ContentError {
    /// The content size is not one the type allows.
    #[error("{type_name} content of {size} bytes, the protocol defines {allowed}")]
    Size {
        /// Type name.
        type_name: &'static str,
        /// Content size.
        size: usize,
        /// The sizes allowed, in words.
        allowed: &'static str,
    },
    /// A STRING whose length field does not match its content.
    #[error("STRING length field says {declared} bytes, {available} follow the 4-byte header")]
    StringLength {
        /// The LENGTH field.
        declared: u16,
        /// Bytes after the 4-byte string header.
        available: usize,
    },
    /// A STRING too long to write.
    #[error("STRING of {0} bytes, at most 65535")]
    StringTooLong(usize),
}

fn be_f32(b: &[u8], at: usize) -> f32 {
    f32::from_be_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]])
}

/// TRANSFORM content: the upper 3x4 of a homogeneous matrix.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TransformContent {
    /// The 3x3 upper-left block, row-major (`rotation[row][col]`).
    pub rotation: [[f32; 3]; 3],
    /// The translation column, millimetres.
    pub translation_mm: [f32; 3],
}

impl TransformContent {
    /// Decodes 48 bytes.
    pub fn decode(content: &[u8]) -> Result<Self, ContentError> {
        if content.len() != TRANSFORM_SIZE {
            return Err(ContentError::Size {
                type_name: "TRANSFORM",
                size: content.len(),
                allowed: "48 bytes",
            });
        }
        let v = |i: usize| be_f32(content, 4 * i);
        let mut rotation = [[0f32; 3]; 3];
        for (col, c) in (0..3).zip([0usize, 3, 6]) {
            for (row, r) in rotation.iter_mut().enumerate() {
                r[col] = v(c + row);
            }
        }
        Ok(TransformContent {
            rotation,
            translation_mm: [v(9), v(10), v(11)],
        })
    }

    /// Encodes into 48 bytes.
    pub fn encode(&self) -> Vec<u8> {
        let mut out = Vec::with_capacity(TRANSFORM_SIZE);
        for col in 0..3 {
            for row in &self.rotation {
                out.extend_from_slice(&row[col].to_be_bytes());
            }
        }
        for t in self.translation_mm {
            out.extend_from_slice(&t.to_be_bytes());
        }
        out
    }
}

/// The orientation part of POSITION content.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PositionOrientation {
    /// 12-byte content: position only.
    None,
    /// 24-byte content: `OX OY OZ`, `W = sqrt(1 - OX^2 - OY^2 - OZ^2)`.
    Quaternion3([f32; 3]),
    /// 28-byte content: `OX OY OZ W`.
    Quaternion([f32; 4]),
}

/// POSITION (or QTRANS) content.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PositionContent {
    /// Position, millimetres.
    pub position_mm: [f32; 3],
    /// Orientation as sent.
    pub orientation: PositionOrientation,
}

impl PositionContent {
    /// Decodes 12, 24 or 28 bytes.
    pub fn decode(content: &[u8], type_name: &'static str) -> Result<Self, ContentError> {
        let v = |i: usize| be_f32(content, 4 * i);
        let orientation = match content.len() {
            POSITION_ONLY_SIZE => PositionOrientation::None,
            POSITION_QUATERNION3_SIZE => PositionOrientation::Quaternion3([v(3), v(4), v(5)]),
            POSITION_SIZE => PositionOrientation::Quaternion([v(3), v(4), v(5), v(6)]),
            size => {
                return Err(ContentError::Size {
                    type_name,
                    size,
                    allowed: "12, 24 or 28 bytes",
                })
            }
        };
        Ok(PositionContent {
            position_mm: [v(0), v(1), v(2)],
            orientation,
        })
    }

    /// Encodes into 12, 24 or 28 bytes, following the orientation variant.
    pub fn encode(&self) -> Vec<u8> {
        let mut out = Vec::with_capacity(POSITION_SIZE);
        let mut put = |x: f32| out.extend_from_slice(&x.to_be_bytes());
        self.position_mm.iter().for_each(|&x| put(x));
        match self.orientation {
            PositionOrientation::None => {}
            PositionOrientation::Quaternion3(q) => q.iter().for_each(|&x| put(x)),
            PositionOrientation::Quaternion(q) => q.iter().for_each(|&x| put(x)),
        }
        out
    }
}

/// STATUS content.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct StatusContent {
    /// Status code (see [`crate::status::StatusCode`]); any value is kept as received.
    pub code: u16,
    /// Device-specific sub code.
    pub subcode: i64,
    /// Error name, at most 20 bytes (longer names are cut on a character boundary).
    pub error_name: String,
    /// Status message.
    pub message: String,
}

/// The text of `bytes` up to the first NUL, invalid UTF-8 replaced (display text only).
fn text_to_nul(bytes: &[u8]) -> String {
    let end = bytes.iter().position(|&b| b == 0).unwrap_or(bytes.len());
    String::from_utf8_lossy(&bytes[..end]).into_owned()
}

/// `s` cut to at most `max` bytes on a character boundary.
pub(crate) fn truncate_utf8(s: &str, max: usize) -> &str {
    if s.len() <= max {
        return s;
    }
    let mut end = max;
    while !s.is_char_boundary(end) {
        end -= 1;
    }
    &s[..end]
}

impl StatusContent {
    /// Decodes 30 or more bytes. The message ends at the first NUL or at the end of the
    /// content (the reference writes a terminating NUL; a missing one is tolerated).
    pub fn decode(content: &[u8]) -> Result<Self, ContentError> {
        if content.len() < STATUS_HEADER_SIZE {
            return Err(ContentError::Size {
                type_name: "STATUS",
                size: content.len(),
                allowed: "30 bytes or more",
            });
        }
        let mut sub = [0u8; 8];
        sub.copy_from_slice(&content[2..10]);
        Ok(StatusContent {
            code: u16::from_be_bytes([content[0], content[1]]),
            subcode: i64::from_be_bytes(sub),
            error_name: text_to_nul(&content[10..STATUS_HEADER_SIZE]),
            message: text_to_nul(&content[STATUS_HEADER_SIZE..]),
        })
    }

    /// Encodes: the error name cut to 20 bytes, the message NUL-terminated (a NUL inside
    /// the message would end it early for every reader, so the message is cut there).
    pub fn encode(&self) -> Vec<u8> {
        let message = self.message.split('\0').next().unwrap_or("");
        let mut out = Vec::with_capacity(STATUS_HEADER_SIZE + message.len() + 1);
        out.extend_from_slice(&self.code.to_be_bytes());
        out.extend_from_slice(&self.subcode.to_be_bytes());
        let mut name = [0u8; STATUS_ERROR_NAME_SIZE];
        let n = truncate_utf8(
            self.error_name.split('\0').next().unwrap_or(""),
            STATUS_ERROR_NAME_SIZE,
        );
        name[..n.len()].copy_from_slice(n.as_bytes());
        out.extend_from_slice(&name);
        out.extend_from_slice(message.as_bytes());
        out.push(0);
        out
    }
}

/// STRING content.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct StringContent {
    /// IANA MIBenum of the encoding (3 = US-ASCII, 106 = UTF-8).
    pub encoding: u16,
    /// The string bytes, at most 65535.
    pub bytes: Vec<u8>,
}

impl StringContent {
    /// A text, US-ASCII when it is ASCII, else UTF-8.
    pub fn text(s: &str) -> Self {
        StringContent {
            encoding: if s.is_ascii() {
                crate::metadata::ENCODING_US_ASCII
            } else {
                crate::metadata::ENCODING_UTF8
            },
            bytes: s.as_bytes().to_vec(),
        }
    }

    /// The bytes as text when they are valid UTF-8.
    pub fn as_text(&self) -> Option<&str> {
        std::str::from_utf8(&self.bytes).ok()
    }

    /// Decodes: the length field must match the bytes that follow exactly.
    pub fn decode(content: &[u8]) -> Result<Self, ContentError> {
        if content.len() < 4 {
            return Err(ContentError::Size {
                type_name: "STRING",
                size: content.len(),
                allowed: "4 bytes or more",
            });
        }
        let declared = u16::from_be_bytes([content[2], content[3]]);
        if usize::from(declared) != content.len() - 4 {
            return Err(ContentError::StringLength {
                declared,
                available: content.len() - 4,
            });
        }
        Ok(StringContent {
            encoding: u16::from_be_bytes([content[0], content[1]]),
            bytes: content[4..].to_vec(),
        })
    }

    /// Encodes; refuses more than 65535 bytes.
    pub fn encode(&self) -> Result<Vec<u8>, ContentError> {
        let len = u16::try_from(self.bytes.len())
            .map_err(|_| ContentError::StringTooLong(self.bytes.len()))?;
        let mut out = Vec::with_capacity(4 + self.bytes.len());
        out.extend_from_slice(&self.encoding.to_be_bytes());
        out.extend_from_slice(&len.to_be_bytes());
        out.extend_from_slice(&self.bytes);
        Ok(out)
    }
}
