//! The body of a version-3 message (header version 2): extended header, content,
//! metadata header and metadata.
//!
//! ```text
//! extended header (12 bytes, big-endian)
//!   0..2   EXT_HEADER_SIZE        uint16  12 (larger values: the extra bytes are skipped)
//!   2..4   METADATA_HEADER_SIZE   uint16  2 + 8 * INDEX_COUNT (0: no metadata)
//!   4..8   METADATA_SIZE          uint32  total bytes of keys and values
//!   8..12  MSG_ID                 uint32  message id
//! content  BODY_SIZE - EXT_HEADER_SIZE - METADATA_HEADER_SIZE - METADATA_SIZE bytes
//! metadata header: INDEX_COUNT uint16, then per entry KEY_SIZE uint16,
//!                  VALUE_ENCODING uint16 (IANA MIBenum), VALUE_SIZE uint32
//! metadata: KEY_0 VALUE_0 KEY_1 VALUE_1 ...
//! ```
//! This is the layout of the reference library (`igtl_extended_header`,
//! `MessageBase::PackMetaData`) and pyigtl; the earlier draft in the protocol's
//! `v3_proposal.md` (MSG_ID then a reserved word) is not what implementations send.
//! The sizes are checked against each other and against the body before anything is read.

use thiserror::Error;

/// Size of the extended header written by this crate (and by every implementation).
pub const EXTENDED_HEADER_SIZE: usize = 12;
/// IANA MIBenum of US-ASCII, the default text encoding.
pub const ENCODING_US_ASCII: u16 = 3;
/// IANA MIBenum of UTF-8.
pub const ENCODING_UTF8: u16 = 106;
/// Most metadata entries a message can hold (the metadata header size is a uint16).
pub const MAX_METADATA_ENTRIES: usize = (u16::MAX as usize - 2) / 8;

/// One metadata key/value pair.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct MetadataEntry {
    /// The key (ASCII in practice; UTF-8 accepted).
    pub key: String,
    /// IANA MIBenum of the value's character encoding (3 = US-ASCII, 106 = UTF-8).
    pub encoding: u16,
    /// The value bytes.
    pub value: Vec<u8>,
}

impl MetadataEntry {
    /// A text value, encoded as US-ASCII when it is ASCII, else UTF-8.
    pub fn text(key: &str, value: &str) -> Self {
        MetadataEntry {
            key: key.to_owned(),
            encoding: if value.is_ascii() {
                ENCODING_US_ASCII
            } else {
                ENCODING_UTF8
            },
            value: value.as_bytes().to_vec(),
        }
    }

    /// The value as text when it is valid UTF-8 (US-ASCII is a subset).
    pub fn value_text(&self) -> Option<&str> {
        std::str::from_utf8(&self.value).ok()
    }
}

/// A version-3 body whose sizes do not add up.
#[derive(Clone, Debug, PartialEq, Eq, Error)]
pub enum MetadataError {
    /// Fewer than 12 body bytes: no room for the extended header.
    #[error("body of {body} bytes is shorter than the 12-byte extended header")]
    ExtendedHeaderTruncated {
        /// Body size.
        body: usize,
    },
    /// EXT_HEADER_SIZE below 12.
    #[error("extended header size {0} is below 12")]
    ExtendedHeaderTooSmall(u16),
    /// The extended header, metadata header and metadata sizes exceed the body.
    #[error(
        "extended header {ext} + metadata header {meta_header} + metadata {meta} bytes exceed the body of {body} bytes"
    )]
    SizesExceedBody {
        /// EXT_HEADER_SIZE.
        ext: u16,
        /// METADATA_HEADER_SIZE.
        meta_header: u16,
        /// METADATA_SIZE.
        meta: u32,
        /// Body size.
        body: usize,
    },
    /// METADATA_HEADER_SIZE is 1, or is not 2 + 8 * INDEX_COUNT.
    #[error("metadata header size {size} does not hold INDEX_COUNT {count} entries (2 + 8 * count bytes)")]
    HeaderSizeMismatch {
        /// METADATA_HEADER_SIZE.
        size: u16,
        /// INDEX_COUNT (0 when the header is too small to hold it).
        count: u16,
    },
    /// Metadata bytes without a metadata header.
    #[error("{0} bytes of metadata without a metadata header")]
    MetadataWithoutHeader(u32),
    /// The key and value sizes do not add up to METADATA_SIZE.
    #[error("metadata entries add up to {entries} bytes, METADATA_SIZE says {size}")]
    SizeMismatch {
        /// Sum of the key and value sizes.
        entries: u64,
        /// METADATA_SIZE.
        size: u32,
    },
    /// A key is not UTF-8.
    #[error("metadata key {index} is not UTF-8")]
    KeyNotUtf8 {
        /// Entry index.
        index: usize,
    },
}

/// Metadata that cannot be written.
#[derive(Clone, Debug, PartialEq, Eq, Error)]
pub enum MetadataEncodeError {
    /// More entries than the uint16 metadata header size can describe.
    #[error("{0} metadata entries, at most {MAX_METADATA_ENTRIES} fit")]
    TooManyEntries(usize),
    /// A key longer than 65535 bytes.
    #[error("metadata key of {0} bytes, at most 65535")]
    KeyTooLong(usize),
    /// The keys and values exceed 4 GiB.
    #[error("metadata of {0} bytes, at most 4294967295")]
    TooLarge(u64),
}

/// A version-3 body split into its parts.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct V3Body<'a> {
    /// MSG_ID.
    pub message_id: u32,
    /// The content (the body of protocol version 2).
    pub content: &'a [u8],
    /// The metadata entries, in their order on the wire.
    pub metadata: Vec<MetadataEntry>,
}

fn be_u16(b: &[u8], at: usize) -> u16 {
    u16::from_be_bytes([b[at], b[at + 1]])
}

fn be_u32(b: &[u8], at: usize) -> u32 {
    u32::from_be_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]])
}

/// Splits a version-3 body, checking every size before reading.
pub fn split_v3_body(body: &[u8]) -> Result<V3Body<'_>, MetadataError> {
    if body.len() < EXTENDED_HEADER_SIZE {
        return Err(MetadataError::ExtendedHeaderTruncated { body: body.len() });
    }
    let ext = be_u16(body, 0);
    let meta_header = be_u16(body, 2);
    let meta = be_u32(body, 4);
    let message_id = be_u32(body, 8);
    if usize::from(ext) < EXTENDED_HEADER_SIZE {
        return Err(MetadataError::ExtendedHeaderTooSmall(ext));
    }
    let tail = u64::from(ext) + u64::from(meta_header) + u64::from(meta);
    if tail > body.len() as u64 {
        return Err(MetadataError::SizesExceedBody {
            ext,
            meta_header,
            meta,
            body: body.len(),
        });
    }
    // All three sizes fit in the body, so these offsets are in range.
    let meta_start = body.len() - meta as usize;
    let meta_header_start = meta_start - usize::from(meta_header);
    let content = &body[usize::from(ext)..meta_header_start];
    let header = &body[meta_header_start..meta_start];
    let values = &body[meta_start..];

    if header.is_empty() {
        if meta != 0 {
            return Err(MetadataError::MetadataWithoutHeader(meta));
        }
        return Ok(V3Body {
            message_id,
            content,
            metadata: Vec::new(),
        });
    }
    let sizes = entry_sizes(header, meta_header, meta)?;
    Ok(V3Body {
        message_id,
        content,
        metadata: entries(values, sizes)?,
    })
}

/// The (key size, encoding, value size) of every entry of the metadata header `header`
/// (`meta_header` bytes), checked against the metadata's size `meta`.
fn entry_sizes(
    header: &[u8],
    meta_header: u16,
    meta: u32,
) -> Result<Vec<(u16, u16, u32)>, MetadataError> {
    if header.len() < 2 {
        return Err(MetadataError::HeaderSizeMismatch {
            size: meta_header,
            count: 0,
        });
    }
    let count = be_u16(header, 0);
    if header.len() != 2 + 8 * usize::from(count) {
        return Err(MetadataError::HeaderSizeMismatch {
            size: meta_header,
            count,
        });
    }
    let mut sizes = Vec::with_capacity(usize::from(count));
    let mut total: u64 = 0;
    for i in 0..usize::from(count) {
        let at = 2 + 8 * i;
        let key_size = be_u16(header, at);
        let encoding = be_u16(header, at + 2);
        let value_size = be_u32(header, at + 4);
        total += u64::from(key_size) + u64::from(value_size);
        sizes.push((key_size, encoding, value_size));
    }
    if total != u64::from(meta) {
        return Err(MetadataError::SizeMismatch {
            entries: total,
            size: meta,
        });
    }
    Ok(sizes)
}

/// The entries of the metadata `values`, of the checked `sizes` (they add up to its
/// length).
fn entries(
    values: &[u8],
    sizes: Vec<(u16, u16, u32)>,
) -> Result<Vec<MetadataEntry>, MetadataError> {
    let mut metadata = Vec::with_capacity(sizes.len());
    let mut at = 0usize;
    for (index, (key_size, encoding, value_size)) in sizes.into_iter().enumerate() {
        let key_end = at + usize::from(key_size);
        let value_end = key_end + value_size as usize;
        let key = std::str::from_utf8(&values[at..key_end])
            .map_err(|_| MetadataError::KeyNotUtf8 { index })?
            .to_owned();
        metadata.push(MetadataEntry {
            key,
            encoding,
            value: values[key_end..value_end].to_vec(),
        });
        at = value_end;
    }
    Ok(metadata)
}

/// Writes a version-3 body: extended header, content, metadata header (always present,
/// as the reference library writes it, so INDEX_COUNT may be 0) and metadata.
pub fn write_v3_body(
    message_id: u32,
    content: &[u8],
    metadata: &[MetadataEntry],
) -> Result<Vec<u8>, MetadataEncodeError> {
    if metadata.len() > MAX_METADATA_ENTRIES {
        return Err(MetadataEncodeError::TooManyEntries(metadata.len()));
    }
    let mut meta_size: u64 = 0;
    for e in metadata {
        if e.key.len() > usize::from(u16::MAX) {
            return Err(MetadataEncodeError::KeyTooLong(e.key.len()));
        }
        meta_size += (e.key.len() + e.value.len()) as u64;
    }
    let meta_size =
        u32::try_from(meta_size).map_err(|_| MetadataEncodeError::TooLarge(meta_size))?;
    // Both fit: at most MAX_METADATA_ENTRIES entries; each value is part of meta_size.
    let meta_header_size = (2 + 8 * metadata.len()) as u16;

    let mut out = Vec::with_capacity(
        EXTENDED_HEADER_SIZE + content.len() + usize::from(meta_header_size) + meta_size as usize,
    );
    out.extend_from_slice(&(EXTENDED_HEADER_SIZE as u16).to_be_bytes());
    out.extend_from_slice(&meta_header_size.to_be_bytes());
    out.extend_from_slice(&meta_size.to_be_bytes());
    out.extend_from_slice(&message_id.to_be_bytes());
    out.extend_from_slice(content);
    out.extend_from_slice(&(metadata.len() as u16).to_be_bytes());
    for e in metadata {
        out.extend_from_slice(&(e.key.len() as u16).to_be_bytes());
        out.extend_from_slice(&e.encoding.to_be_bytes());
        out.extend_from_slice(&(e.value.len() as u32).to_be_bytes());
    }
    for e in metadata {
        out.extend_from_slice(e.key.as_bytes());
        out.extend_from_slice(&e.value);
    }
    Ok(out)
}
