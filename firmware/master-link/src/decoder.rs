//! Streaming frame decoder with link statistics and sequence checking.

use core::marker::PhantomData;

use crate::frame::{decode_frame, FrameError, Header, MAX_FRAME_LEN};
use crate::messages::{BoardToMaster, LinkCounters, MasterToBoard, Seq, WireMessage};

/// Half of the sequence space: `seq` is newer than `last` when
/// `seq - last` (wrapping) is in `1..=SEQ_WINDOW`.
pub const SEQ_WINDOW: Seq = Seq::MAX / 2;

/// Serial-number arithmetic (RFC 1982 style) on the wrapping `u16` sequence:
/// `true` when `seq` is strictly newer than `last`.
pub const fn seq_is_newer(seq: Seq, last: Seq) -> bool {
    let delta = seq.wrapping_sub(last);
    delta != 0 && delta <= SEQ_WINDOW
}

/// Sequence number generator for the sending side (wraps at `u16::MAX`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SeqCounter {
    next: Seq,
}

impl SeqCounter {
    /// Starts at `first`.
    pub const fn new(first: Seq) -> Self {
        Self { next: first }
    }

    /// Returns the next sequence number to send and advances.
    #[allow(clippy::should_implement_trait)]
    pub fn next(&mut self) -> Seq {
        let seq = self.next;
        self.next = self.next.wrapping_add(1);
        seq
    }

    /// The number the next call to [`SeqCounter::next`] returns.
    pub const fn peek(&self) -> Seq {
        self.next
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum RxState {
    /// Accumulating bytes of a frame.
    Collecting,
    /// The frame outgrew the buffer: discard up to the delimiter, then count.
    Overflow,
    /// Resynchronising after `resync()`: discard silently up to the delimiter.
    Resync,
}

/// Streaming decoder for frames carrying messages of type `M`, with a
/// receive buffer of `N` bytes (COBS-encoded frame without delimiter).
///
/// Feed it bytes from the UART ([`push`](Self::push) or
/// [`feed`](Self::feed)); it yields one result per non-empty frame (empty
/// frames, i.e. consecutive `0x00`, are ignored and may be used as sync
/// bytes). Rejected frames are counted in [`LinkCounters`] and returned as
/// `Err` so the caller can log them; the caller simply continues feeding.
///
/// Session rule: a message that opens a session (`Hello` / `HelloReply`) is accepted
/// whatever its header and sets the current session; once there is one, frames of any
/// other session are rejected as `WrongSession` (an earlier connection's frames, replayed).
///
/// Sequence rule: the first frame after construction / [`reset`](Self::reset)
/// and every session-opening message are accepted whatever their sequence number and
/// become the reference; any other frame must be newer than the last accepted one
/// ([`seq_is_newer`]), else it is rejected as `OutOfOrder`. Skipped numbers are counted
/// in `dropped`.
///
/// A message that bypasses the sequence (`EmergencyStop`) is accepted whenever its frame
/// is intact (CRC, version, body): in session and order like any frame, and otherwise
/// too, leaving the reference as it was. No filter drops an emergency stop.
pub struct FrameDecoder<M, const N: usize = MAX_FRAME_LEN> {
    buf: [u8; N],
    len: usize,
    state: RxState,
    last_seq: Option<Seq>,
    session: Option<u32>,
    counters: LinkCounters,
    _msg: PhantomData<fn() -> M>,
}

/// Decoder running on the board (receives master messages).
pub type BoardDecoder = FrameDecoder<MasterToBoard, MAX_FRAME_LEN>;
/// Decoder running on the host master (receives board messages).
pub type MasterDecoder = FrameDecoder<BoardToMaster, MAX_FRAME_LEN>;

impl<M: WireMessage, const N: usize> Default for FrameDecoder<M, N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<M: WireMessage, const N: usize> FrameDecoder<M, N> {
    /// Empty decoder, zero counters, no sequence reference.
    pub const fn new() -> Self {
        Self {
            buf: [0; N],
            len: 0,
            state: RxState::Collecting,
            last_seq: None,
            session: None,
            counters: LinkCounters {
                frames_ok: 0,
                bad_checksum: 0,
                malformed: 0,
                oversized: 0,
                wrong_version: 0,
                out_of_order: 0,
                dropped: 0,
                wrong_session: 0,
            },
            _msg: PhantomData,
        }
    }

    /// Link statistics so far.
    pub const fn counters(&self) -> &LinkCounters {
        &self.counters
    }

    /// Zeroes the link statistics.
    pub fn reset_counters(&mut self) {
        self.counters = LinkCounters::default();
    }

    /// Last accepted sequence number, if any.
    pub const fn last_seq(&self) -> Option<Seq> {
        self.last_seq
    }

    /// The current session (opened by the last `Hello` / `HelloReply`), if any.
    pub const fn session(&self) -> Option<u32> {
        self.session
    }

    /// Forgets the sequence reference: the next frame is accepted whatever
    /// its number (e.g. after a link timeout).
    pub fn reset_sequence(&mut self) {
        self.last_seq = None;
    }

    /// Drops the partially received frame and ignores bytes up to the next
    /// delimiter, without counting (call on UART framing/overrun errors).
    pub fn resync(&mut self) {
        self.len = 0;
        self.state = RxState::Resync;
    }

    /// Drops any partial frame, the sequence reference and the session (counters kept).
    pub fn reset(&mut self) {
        self.len = 0;
        self.state = RxState::Collecting;
        self.last_seq = None;
        self.session = None;
    }

    /// Feeds one byte. Returns `Some` when it completed a non-empty frame.
    pub fn push(&mut self, byte: u8) -> Option<Result<(Seq, M), FrameError>> {
        if byte != 0 {
            if self.state == RxState::Collecting {
                match self.buf.get_mut(self.len) {
                    Some(slot) => {
                        *slot = byte;
                        self.len += 1;
                    }
                    None => self.state = RxState::Overflow,
                }
            }
            return None;
        }

        let result = match self.state {
            RxState::Overflow => Some(Err(FrameError::Oversized)),
            RxState::Resync => None,
            RxState::Collecting if self.len == 0 => None,
            RxState::Collecting => Some(self.process()),
        };
        self.len = 0;
        self.state = RxState::Collecting;
        if let Some(result) = &result {
            self.count(result);
        }
        result
    }

    /// Iterator over the frames completed by `bytes` (lazy: bytes after the
    /// last yielded frame are consumed only when iterating further; use
    /// `for _ in dec.feed(bytes)` or `.count()` to consume everything).
    pub fn feed<'d, 'b>(&'d mut self, bytes: &'b [u8]) -> Feed<'d, 'b, M, N> {
        Feed {
            decoder: self,
            bytes: bytes.iter(),
        }
    }

    fn process(&mut self) -> Result<(Seq, M), FrameError> {
        let frame = self.buf.get_mut(..self.len).ok_or(FrameError::Oversized)?;
        let (Header { session, seq }, msg) = decode_frame::<M>(frame)?;
        if let Some(opened) = msg.opens_session() {
            self.session = Some(opened);
            self.last_seq = Some(seq);
            return Ok((seq, msg));
        }
        match self.check(session, seq) {
            Ok(()) => {
                if let Some(last) = self.last_seq {
                    let lost = u32::from(seq.wrapping_sub(last).wrapping_sub(1));
                    self.counters.dropped = self.counters.dropped.wrapping_add(lost);
                }
                self.last_seq = Some(seq);
                Ok((seq, msg))
            }
            // An emergency stop of another session or out of order is still taken; it
            // leaves the reference as it was.
            Err(_) if msg.bypasses_sequence() => Ok((seq, msg)),
            Err(e) => Err(e),
        }
    }

    /// The session and sequence checks of a frame that opens no session.
    fn check(&self, session: u32, seq: Seq) -> Result<(), FrameError> {
        if let Some(expected) = self.session {
            if session != expected {
                return Err(FrameError::WrongSession {
                    received: session,
                    expected,
                });
            }
        }
        match self.last_seq {
            Some(last) if !seq_is_newer(seq, last) => Err(FrameError::OutOfOrder { seq, last }),
            _ => Ok(()),
        }
    }

    fn count(&mut self, result: &Result<(Seq, M), FrameError>) {
        let c = &mut self.counters;
        let counter = match result {
            Ok(_) => &mut c.frames_ok,
            Err(FrameError::Malformed(_)) => &mut c.malformed,
            Err(FrameError::Oversized) => &mut c.oversized,
            Err(FrameError::BadChecksum) => &mut c.bad_checksum,
            Err(FrameError::WrongVersion { .. }) => &mut c.wrong_version,
            Err(FrameError::OutOfOrder { .. }) => &mut c.out_of_order,
            Err(FrameError::WrongSession { .. }) => &mut c.wrong_session,
        };
        *counter = counter.wrapping_add(1);
    }
}

/// Iterator returned by [`FrameDecoder::feed`].
pub struct Feed<'d, 'b, M, const N: usize> {
    decoder: &'d mut FrameDecoder<M, N>,
    bytes: core::slice::Iter<'b, u8>,
}

impl<M: WireMessage, const N: usize> Iterator for Feed<'_, '_, M, N> {
    type Item = Result<(Seq, M), FrameError>;

    fn next(&mut self) -> Option<Self::Item> {
        for &byte in self.bytes.by_ref() {
            if let Some(result) = self.decoder.push(byte) {
                return Some(result);
            }
        }
        None
    }
}
