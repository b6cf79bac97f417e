//! Whole messages: header, body and, for protocol version 3, message id and metadata.

use crate::content::{
    ContentError, PositionContent, StatusContent, StringContent, TransformContent,
};
use crate::crc::body_crc;
use crate::header::{Header, HeaderError, HeaderVersion, NameError, HEADER_SIZE};
use crate::metadata::{
    split_v3_body, write_v3_body, MetadataEncodeError, MetadataEntry, MetadataError,
};
use crate::timestamp::Timestamp;
use thiserror::Error;

/// The data types this crate decodes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum DataType {
    /// TRANSFORM.
    Transform,
    /// POSITION.
    Position,
    /// QTRANS (the protocol-3 name of POSITION, same content).
    QTrans,
    /// STATUS.
    Status,
    /// STRING.
    String,
}

impl DataType {
    /// The type name of a data message.
    pub fn type_name(self) -> &'static str {
        match self {
            DataType::Transform => "TRANSFORM",
            DataType::Position => "POSITION",
            DataType::QTrans => "QTRANS",
            DataType::Status => "STATUS",
            DataType::String => "STRING",
        }
    }

    /// The data type of a query suffix (the type name after `GET_`, `STT_`, `STP_` or
    /// `RTS_`). TRANSFORM's queries are `GET_TRANS`, `STT_TRANS`, `STP_TRANS` and
    /// `RTS_TRANS` in the reference library and the protocol's transform page;
    /// `..._TRANSFOR` (the protocol-3 overview table) is accepted too.
    pub fn from_query_suffix(suffix: &str) -> Option<Self> {
        match suffix {
            "TRANS" | "TRANSFOR" => Some(DataType::Transform),
            "POSITION" => Some(DataType::Position),
            "QTRANS" => Some(DataType::QTrans),
            "STATUS" => Some(DataType::Status),
            "STRING" => Some(DataType::String),
            _ => None,
        }
    }

    /// The query suffix this crate writes for the data type.
    pub fn query_suffix(self) -> &'static str {
        match self {
            DataType::Transform => "TRANS",
            other => other.type_name(),
        }
    }

    /// The data type of a data message's type name.
    pub fn from_type_name(name: &str) -> Option<Self> {
        match name {
            "TRANSFORM" => Some(DataType::Transform),
            "POSITION" => Some(DataType::Position),
            "QTRANS" => Some(DataType::QTrans),
            "STATUS" => Some(DataType::Status),
            "STRING" => Some(DataType::String),
            _ => None,
        }
    }
}

/// The query prefixes of protocol version 2.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum QueryKind {
    /// `GET_`: one message of the data type.
    Get,
    /// `STT_`: start streaming the data type.
    Start,
    /// `STP_`: stop streaming the data type.
    Stop,
}

impl QueryKind {
    /// The prefix, with its underscore.
    pub fn prefix(self) -> &'static str {
        match self {
            QueryKind::Get => "GET_",
            QueryKind::Start => "STT_",
            QueryKind::Stop => "STP_",
        }
    }
}

/// A message body, by type.
#[derive(Clone, Debug, PartialEq)]
pub enum Body {
    /// TRANSFORM.
    Transform(TransformContent),
    /// POSITION.
    Position(PositionContent),
    /// QTRANS (same content as POSITION).
    QTrans(PositionContent),
    /// STATUS.
    Status(StatusContent),
    /// STRING.
    String(StringContent),
    /// A data message of one of the [`DataType`]s with no content: the answer to a `GET_`
    /// query when no data is available (protocol page "Query").
    Null(DataType),
    /// A `GET_`, `STT_` or `STP_` query. `suffix` is the rest of the type name (`TRANS`,
    /// `POSITION`, `IMAGE` ...). The protocol defines no content for the queries of the
    /// types handled here; any content is kept but not interpreted.
    Query {
        /// The prefix.
        kind: QueryKind,
        /// The type name after the prefix (1 to 8 characters).
        suffix: String,
        /// Content, normally empty.
        content: Vec<u8>,
    },
    /// An `RTS_` answer with its 1-byte status (0 success, 1 error).
    Rts {
        /// The type name after `RTS_`.
        suffix: String,
        /// The status byte.
        status: u8,
    },
    /// Any other type, its content kept as received.
    Other {
        /// Type name.
        type_name: String,
        /// Content.
        content: Vec<u8>,
    },
}

impl Body {
    /// The type name written in the header.
    pub fn type_name(&self) -> String {
        match self {
            Body::Transform(_) => "TRANSFORM".to_owned(),
            Body::Position(_) => "POSITION".to_owned(),
            Body::QTrans(_) => "QTRANS".to_owned(),
            Body::Status(_) => "STATUS".to_owned(),
            Body::String(_) => "STRING".to_owned(),
            Body::Null(t) => t.type_name().to_owned(),
            Body::Query { kind, suffix, .. } => format!("{}{}", kind.prefix(), suffix),
            Body::Rts { suffix, .. } => format!("RTS_{suffix}"),
            Body::Other { type_name, .. } => type_name.clone(),
        }
    }

    /// The content bytes.
    fn content(&self) -> Result<Vec<u8>, ContentError> {
        Ok(match self {
            Body::Transform(t) => t.encode(),
            Body::Position(p) | Body::QTrans(p) => p.encode(),
            Body::Status(s) => s.encode(),
            Body::String(s) => s.encode()?,
            Body::Null(_) => Vec::new(),
            Body::Query { content, .. } => content.clone(),
            Body::Rts { status, .. } => vec![*status],
            Body::Other { content, .. } => content.clone(),
        })
    }

    /// Decodes the content of a message of type `type_name`.
    pub fn decode(type_name: &str, content: &[u8]) -> Result<Body, ContentError> {
        if let Some(data) = DataType::from_type_name(type_name) {
            if content.is_empty() {
                return Ok(Body::Null(data));
            }
            return Ok(match data {
                DataType::Transform => Body::Transform(TransformContent::decode(content)?),
                DataType::Position => Body::Position(PositionContent::decode(content, "POSITION")?),
                DataType::QTrans => Body::QTrans(PositionContent::decode(content, "QTRANS")?),
                DataType::Status => Body::Status(StatusContent::decode(content)?),
                DataType::String => Body::String(StringContent::decode(content)?),
            });
        }
        for kind in [QueryKind::Get, QueryKind::Start, QueryKind::Stop] {
            if let Some(suffix) = type_name.strip_prefix(kind.prefix()) {
                if !suffix.is_empty() {
                    return Ok(Body::Query {
                        kind,
                        suffix: suffix.to_owned(),
                        content: content.to_vec(),
                    });
                }
            }
        }
        if let (Some(suffix), [status]) = (type_name.strip_prefix("RTS_"), content) {
            if !suffix.is_empty() {
                return Ok(Body::Rts {
                    suffix: suffix.to_owned(),
                    status: *status,
                });
            }
        }
        Ok(Body::Other {
            type_name: type_name.to_owned(),
            content: content.to_vec(),
        })
    }
}

/// A whole message.
#[derive(Clone, Debug, PartialEq)]
pub struct Message {
    /// Header version: V1 for protocols 1 and 2, V2 for protocol 3.
    pub version: HeaderVersion,
    /// Device name (at most 20 bytes).
    pub device_name: String,
    /// Timestamp.
    pub timestamp: Timestamp,
    /// Message id (protocol 3 only; 0 otherwise).
    pub message_id: u32,
    /// Metadata (protocol 3 only).
    pub metadata: Vec<MetadataEntry>,
    /// The body.
    pub body: Body,
}

/// A message that cannot be written.
#[derive(Clone, Debug, PartialEq, Eq, Error)]
pub enum EncodeError {
    /// A name does not fit the header.
    #[error(transparent)]
    Name(#[from] NameError),
    /// The content cannot be written.
    #[error(transparent)]
    Content(#[from] ContentError),
    /// The metadata cannot be written.
    #[error(transparent)]
    Metadata(#[from] MetadataEncodeError),
    /// Metadata or a message id on a header-version-1 message, which has no room for them.
    #[error("header version 1 has no room for metadata or a message id (message id {message_id}, {entries} metadata entries)")]
    V3FieldsOnV1 {
        /// The message id.
        message_id: u32,
        /// The number of metadata entries.
        entries: usize,
    },
}

/// Why bytes are not a valid message.
#[derive(Clone, Debug, PartialEq, Eq, Error)]
pub enum DecodeError {
    /// Fewer bytes than the header and its stated body size.
    #[error("truncated message: {needed} bytes needed, {available} available")]
    Truncated {
        /// Bytes the header (and body size) call for.
        needed: u64,
        /// Bytes available.
        available: usize,
    },
    /// The first 58 bytes are not a header.
    #[error("bad header: {0}")]
    Header(#[from] HeaderError),
    /// The body's CRC differs from the header's.
    #[error("CRC mismatch: header says {header:#018x}, body gives {computed:#018x}")]
    Crc {
        /// CRC in the header.
        header: u64,
        /// CRC of the body received.
        computed: u64,
    },
    /// A protocol-3 body whose sizes do not add up.
    #[error("bad version-3 body: {0}")]
    Metadata(#[from] MetadataError),
    /// Content that does not match its type.
    #[error("bad content: {0}")]
    Content(#[from] ContentError),
}

impl Message {
    /// A header-version-1 message without timestamp.
    pub fn new(device_name: &str, body: Body) -> Self {
        Message {
            version: HeaderVersion::V1,
            device_name: device_name.to_owned(),
            timestamp: Timestamp::UNUSED,
            message_id: 0,
            metadata: Vec::new(),
            body,
        }
    }

    /// The type name written in the header.
    pub fn type_name(&self) -> String {
        self.body.type_name()
    }

    /// Encodes header and body, the CRC computed over the whole body.
    pub fn encode(&self) -> Result<Vec<u8>, EncodeError> {
        let content = self.body.content()?;
        let body = match self.version {
            HeaderVersion::V1 => {
                if self.message_id != 0 || !self.metadata.is_empty() {
                    return Err(EncodeError::V3FieldsOnV1 {
                        message_id: self.message_id,
                        entries: self.metadata.len(),
                    });
                }
                content
            }
            HeaderVersion::V2 => write_v3_body(self.message_id, &content, &self.metadata)?,
        };
        let header = Header {
            version: self.version,
            type_name: self.type_name(),
            device_name: self.device_name.clone(),
            timestamp: self.timestamp,
            body_size: body.len() as u64,
            crc: body_crc(&body),
        };
        let mut out = Vec::with_capacity(HEADER_SIZE + body.len());
        out.extend_from_slice(&header.encode()?);
        out.extend_from_slice(&body);
        Ok(out)
    }

    /// Decodes the body that followed `header` (`body.len()` must be its body size; the
    /// caller frames it). With `check_crc`, a CRC mismatch is an error.
    pub fn decode_body(header: &Header, body: &[u8], check_crc: bool) -> Result<Self, DecodeError> {
        if check_crc {
            let computed = body_crc(body);
            if computed != header.crc {
                return Err(DecodeError::Crc {
                    header: header.crc,
                    computed,
                });
            }
        }
        let (message_id, content, metadata) = match header.version {
            HeaderVersion::V1 => (0, body, Vec::new()),
            HeaderVersion::V2 => {
                let parts = split_v3_body(body)?;
                (parts.message_id, parts.content, parts.metadata)
            }
        };
        Ok(Message {
            version: header.version,
            device_name: header.device_name.clone(),
            timestamp: header.timestamp,
            message_id,
            metadata,
            body: Body::decode(&header.type_name, content)?,
        })
    }

    /// Decodes the message at the start of `bytes`, CRC checked; returns it and the bytes
    /// it took.
    pub fn decode(bytes: &[u8]) -> Result<(Self, usize), DecodeError> {
        let Some(head) = bytes.first_chunk::<HEADER_SIZE>() else {
            return Err(DecodeError::Truncated {
                needed: HEADER_SIZE as u64,
                available: bytes.len(),
            });
        };
        let header = Header::decode(head)?;
        let needed = (HEADER_SIZE as u64).saturating_add(header.body_size);
        if needed > bytes.len() as u64 {
            return Err(DecodeError::Truncated {
                needed,
                available: bytes.len(),
            });
        }
        // needed <= bytes.len(), so it fits in usize.
        let end = needed as usize;
        let message = Message::decode_body(&header, &bytes[HEADER_SIZE..end], true)?;
        Ok((message, end))
    }
}
