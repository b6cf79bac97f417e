//! Framing of a byte stream (a TCP connection) into messages, with recovery from bad input.
//!
//! What happens to each kind of bad input (none closes the connection):
//!
//! | input | counted as | what the decoder does |
//! | --- | --- | --- |
//! | bytes that are not a header (garbage, a stream entered mid-message) | [`MalformedKind::BadHeader`], once per run | drops one byte at a time until a plausible header (version 1 or 2, valid type and device names, see [`crate::header`]) starts: the stream is resynchronised |
//! | body size above `max_body_size` but at most `max_skip_size` | [`MalformedKind::OversizedBody`] | skips exactly that many bytes without buffering them (what the reference library's `Socket::Skip` does for types it does not read), then goes on |
//! | body size above `max_skip_size` | [`MalformedKind::OversizedBody`] | distrusts the header: drops its first byte and resynchronises as for garbage |
//! | CRC mismatch | [`MalformedKind::BadCrc`] | drops the whole message (header and stated body), as the reference's `Unpack(1)` does |
//! | version-3 sizes that do not add up | [`MalformedKind::BadMetadata`] | drops the message |
//! | content of the wrong size for its type | [`MalformedKind::BadContent`] | drops the message |
//! | connection closed inside a message | [`MalformedKind::Truncated`] | reported by [`StreamDecoder::finish`] |
//!
//! A body size that lies can only be detected afterwards: a larger one swallows the
//! messages that follow (they fail the CRC and are dropped together), a smaller one leaves
//! the rest of the body to be skipped as garbage. Either way the stream is in step again
//! at the next genuine header.
//!
//! Work is bounded: each call of [`StreamDecoder::next_event`] looks at each buffered byte
//! a bounded number of times (at most the 58 bytes of a candidate header per byte dropped),
//! and at most one message (58 + `max_body_size` bytes) is ever buffered beyond the bytes
//! last pushed.

use crate::header::{may_start_header, Header, HeaderError, HEADER_SIZE};
use crate::message::{DecodeError, Message};
use std::ops::ControlFlow;
use thiserror::Error;

/// Limits of a [`StreamDecoder`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DecoderLimits {
    /// Largest body buffered and decoded, bytes.
    pub max_body_size: u64,
    /// Largest body skipped when above `max_body_size`; larger headers are distrusted.
    pub max_skip_size: u64,
    /// Check the CRC of every body.
    pub check_crc: bool,
}

impl Default for DecoderLimits {
    /// 1 MiB decoded (a STRING is at most 64 KiB, the other types handled here are
    /// smaller), 256 MiB skipped (an image a client pushes to every connection), CRC on.
    fn default() -> Self {
        DecoderLimits {
            max_body_size: 1 << 20,
            max_skip_size: 256 << 20,
            check_crc: true,
        }
    }
}

/// The kinds of bad input, for counting.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum MalformedKind {
    /// Bytes that are not a header; one count per run of such bytes.
    BadHeader,
    /// A body size above the decoder's maximum.
    OversizedBody,
    /// A body whose CRC differs from the header's.
    BadCrc,
    /// A protocol-3 body whose extended header or metadata sizes do not add up.
    BadMetadata,
    /// Content of the wrong size or layout for its type.
    BadContent,
    /// Content of the right size whose values are not a pose (non-finite numbers, a matrix
    /// that is not a rotation, a quaternion that is not a unit quaternion).
    InvalidPose,
    /// A well-formed message of a type the server does not handle.
    UnknownType,
    /// The connection closed inside a message.
    Truncated,
}

impl MalformedKind {
    /// Every kind.
    pub const ALL: [MalformedKind; 8] = [
        MalformedKind::BadHeader,
        MalformedKind::OversizedBody,
        MalformedKind::BadCrc,
        MalformedKind::BadMetadata,
        MalformedKind::BadContent,
        MalformedKind::InvalidPose,
        MalformedKind::UnknownType,
        MalformedKind::Truncated,
    ];

    /// A snake_case name for reports.
    pub fn name(self) -> &'static str {
        match self {
            MalformedKind::BadHeader => "bad_header",
            MalformedKind::OversizedBody => "oversized_body",
            MalformedKind::BadCrc => "bad_crc",
            MalformedKind::BadMetadata => "bad_metadata",
            MalformedKind::BadContent => "bad_content",
            MalformedKind::InvalidPose => "invalid_pose",
            MalformedKind::UnknownType => "unknown_type",
            MalformedKind::Truncated => "truncated",
        }
    }
}

/// What was wrong with a stretch of the stream.
#[derive(Clone, Debug, PartialEq, Eq, Error)]
pub enum StreamError {
    /// The start of a run of bytes that are not a header.
    #[error("bytes that are not a header (starting {first_bytes:02x?}{}), skipped until the next header", reason.as_ref().map(|r| format!(": {r}")).unwrap_or_default())]
    Garbage {
        /// The first bytes of the run (up to 8).
        first_bytes: Vec<u8>,
        /// Why they are not a header, when 58 bytes were there to decode.
        reason: Option<HeaderError>,
    },
    /// A body size above the limit.
    #[error("body size {body_size} above the maximum {max_body_size}: {}", if *skipped { "body skipped" } else { "header distrusted, resynchronising" })]
    Oversized {
        /// The stated body size.
        body_size: u64,
        /// The decoder's `max_body_size`.
        max_body_size: u64,
        /// True when the body is skipped, false when the header is distrusted.
        skipped: bool,
    },
    /// A framed message that failed to decode.
    #[error(transparent)]
    Decode(DecodeError),
    /// The stream ended inside a message.
    #[error("stream ended {pending} bytes into a message")]
    Truncated {
        /// Bytes of the unfinished message received.
        pending: u64,
    },
}

/// Bad input found in the stream.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Malformed {
    /// The header of the message, when one was decoded.
    pub header: Option<Header>,
    /// What was wrong.
    pub error: StreamError,
}

impl Malformed {
    /// The kind, for counting.
    pub fn kind(&self) -> MalformedKind {
        match &self.error {
            StreamError::Garbage { .. } => MalformedKind::BadHeader,
            StreamError::Oversized { .. } => MalformedKind::OversizedBody,
            StreamError::Truncated { .. } => MalformedKind::Truncated,
            StreamError::Decode(DecodeError::Crc { .. }) => MalformedKind::BadCrc,
            StreamError::Decode(DecodeError::Metadata(_)) => MalformedKind::BadMetadata,
            StreamError::Decode(DecodeError::Content(_)) => MalformedKind::BadContent,
            // Framed messages never fail as Truncated or Header; counted as content.
            StreamError::Decode(DecodeError::Truncated { .. } | DecodeError::Header(_)) => {
                MalformedKind::BadContent
            }
        }
    }
}

/// One result of decoding.
#[derive(Clone, Debug, PartialEq)]
pub enum Event {
    /// A valid message.
    Message(Message),
    /// Bad input.
    Malformed(Malformed),
}

#[derive(Clone, Debug)]
enum State {
    /// Waiting for (or scanning for) a header.
    Header,
    /// Header read; waiting for its body.
    Body(Header),
    /// Dropping the body of an oversized message.
    Skip { total: u64, remaining: u64 },
}

/// Incremental decoder of a byte stream.
#[derive(Clone, Debug)]
pub struct StreamDecoder {
    limits: DecoderLimits,
    buf: Vec<u8>,
    start: usize,
    state: State,
    in_garbage: bool,
    discarded: u64,
}

impl StreamDecoder {
    /// A decoder with the given limits.
    pub fn new(limits: DecoderLimits) -> Self {
        StreamDecoder {
            limits,
            buf: Vec::new(),
            start: 0,
            state: State::Header,
            in_garbage: false,
            discarded: 0,
        }
    }

    /// Appends received bytes.
    pub fn push(&mut self, bytes: &[u8]) {
        if self.start > 0 && self.start >= self.buf.len() / 2 {
            self.buf.drain(..self.start);
            self.start = 0;
        }
        self.buf.extend_from_slice(bytes);
    }

    /// Bytes buffered and not yet decoded.
    pub fn buffered(&self) -> usize {
        self.buf.len() - self.start
    }

    /// Bytes dropped unframed so far: garbage, skipped oversized messages and the unfinished
    /// message at the end of the stream. Messages dropped for a CRC, metadata or content
    /// error are not included (they were framed, and are counted as messages).
    pub fn discarded_bytes(&self) -> u64 {
        self.discarded
    }

    fn available(&self) -> &[u8] {
        &self.buf[self.start..]
    }

    fn consume(&mut self, n: usize) {
        self.start += n;
    }

    fn drop_garbage_byte(&mut self) {
        self.start += 1;
        self.discarded += 1;
    }

    /// The next message or bad input, `None` when more bytes are needed.
    pub fn next_event(&mut self) -> Option<Event> {
        loop {
            let step = match self.state.clone() {
                State::Skip { total, remaining } => self.skip(total, remaining),
                State::Body(header) => self.body(header),
                State::Header => self.header(),
            };
            if let ControlFlow::Break(event) = step {
                return event;
            }
        }
    }

    /// Skips what is there of an oversized message's body; the header is next once all
    /// of it went.
    fn skip(&mut self, total: u64, remaining: u64) -> ControlFlow<Option<Event>> {
        let n = remaining.min(self.available().len() as u64);
        // n <= available length, so it fits in usize.
        self.consume(n as usize);
        self.discarded += n;
        if n < remaining {
            self.state = State::Skip {
                total,
                remaining: remaining - n,
            };
            return ControlFlow::Break(None);
        }
        self.state = State::Header;
        ControlFlow::Continue(())
    }

    /// Decodes the body of `header` once all of it is there: the message, or why it is
    /// malformed.
    fn body(&mut self, header: Header) -> ControlFlow<Option<Event>> {
        let available = self.available();
        if (available.len() as u64) < header.body_size {
            return ControlFlow::Break(None);
        }
        // body_size <= available length (<= max_body_size), fits in usize.
        let size = header.body_size as usize;
        let result = Message::decode_body(&header, &available[..size], self.limits.check_crc);
        self.consume(size);
        self.state = State::Header;
        ControlFlow::Break(Some(match result {
            Ok(message) => Event::Message(message),
            Err(e) => Event::Malformed(Malformed {
                header: Some(header),
                error: StreamError::Decode(e),
            }),
        }))
    }

    /// Looks for a header: a byte that cannot start one is garbage; a header whose body
    /// is too large is reported (and its body skipped when not too large to skip).
    fn header(&mut self) -> ControlFlow<Option<Event>> {
        let available = self.available();
        if available.is_empty() {
            return ControlFlow::Break(None);
        }
        if !may_start_header(&available[..available.len().min(3)]) {
            // Cheap rejection of the first byte.
            return self.garbage_byte();
        }
        let Some(head) = available.first_chunk::<HEADER_SIZE>() else {
            return ControlFlow::Break(None);
        };
        match Header::decode(head) {
            Err(_) => self.garbage_byte(),
            Ok(header) if header.body_size <= self.limits.max_body_size => {
                self.in_garbage = false;
                self.consume(HEADER_SIZE);
                self.state = State::Body(header);
                ControlFlow::Continue(())
            }
            Ok(header) => ControlFlow::Break(Some(self.oversized(header))),
        }
    }

    /// Drops the first byte as garbage; the first of a run of garbage is reported.
    fn garbage_byte(&mut self) -> ControlFlow<Option<Event>> {
        let report = (!self.in_garbage).then(|| garbage(self.available()));
        self.drop_garbage_byte();
        self.in_garbage = true;
        match report {
            Some(event) => ControlFlow::Break(Some(event)),
            None => ControlFlow::Continue(()),
        }
    }

    /// A header whose body exceeds the limit: its body skipped when within the skip
    /// limit, else the header's first byte dropped as garbage.
    fn oversized(&mut self, header: Header) -> Event {
        let skipped = header.body_size <= self.limits.max_skip_size;
        let error = StreamError::Oversized {
            body_size: header.body_size,
            max_body_size: self.limits.max_body_size,
            skipped,
        };
        if skipped {
            self.in_garbage = false;
            self.consume(HEADER_SIZE);
            self.discarded += HEADER_SIZE as u64;
            self.state = State::Skip {
                total: header.body_size,
                remaining: header.body_size,
            };
        } else {
            self.drop_garbage_byte();
            self.in_garbage = true;
        }
        Event::Malformed(Malformed {
            header: Some(header),
            error,
        })
    }

    /// Call when the stream has ended: reports a message cut short, if any.
    pub fn finish(&mut self) -> Option<Malformed> {
        let pending = self.available().len() as u64;
        let event = match &self.state {
            State::Header if pending > 0 && !self.in_garbage => Some(Malformed {
                header: None,
                error: StreamError::Truncated { pending },
            }),
            State::Body(header) => Some(Malformed {
                header: Some(header.clone()),
                error: StreamError::Truncated {
                    pending: HEADER_SIZE as u64 + pending,
                },
            }),
            State::Skip { total, remaining } => Some(Malformed {
                header: None,
                error: StreamError::Truncated {
                    pending: HEADER_SIZE as u64 + (total - remaining),
                },
            }),
            State::Header => None,
        };
        self.discarded += pending;
        self.start = self.buf.len();
        self.state = State::Header;
        event
    }
}

/// The report of a run of garbage starting at `bytes[0]`.
fn garbage(bytes: &[u8]) -> Event {
    Event::Malformed(Malformed {
        header: None,
        error: StreamError::Garbage {
            first_bytes: bytes.iter().take(8).copied().collect(),
            reason: bytes
                .first_chunk::<HEADER_SIZE>()
                .and_then(|h| Header::decode(h).err()),
        },
    })
}
