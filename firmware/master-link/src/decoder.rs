//! Streaming frame decoder with link statistics and sequence checking.

use core::marker::PhantomData;

use crate::auth::LinkKey;
use crate::frame::{decode_frame_with, FrameError, Header, MAX_FRAME_LEN};
use crate::messages::{BoardToMaster, LinkCounters, MasterToBoard, Seq, WireMessage};

/// The sequence window: a frame is taken when `seq - last` (wrapping) is in
/// `1..=SEQ_WINDOW`. Older numbers are replays or reordered frames; numbers further ahead
/// are refused without moving the reference, so that one stray frame cannot lock the
/// sender out (the sender's next frames stay in the window).
///
/// **Why 256.** The host masters send at most about 200 frames a second (targets at
/// 100 Hz, heartbeats at 50 Hz, requests); a gap of 256 lost frames is more than a second
/// of silence, while the board holds after 100 ms and stops after 500 ms without a
/// heartbeat, so a live session never skips that many (a master that was cut off longer
/// says `Hello` again). A frame with a random number falls in the window with probability
/// 256 / 65,536 = 0.4 %.
pub const SEQ_WINDOW: Seq = 256;

/// Serial-number arithmetic (RFC 1982 style) on the wrapping `u16` sequence:
/// `true` when `seq` is newer than `last` by at most [`SEQ_WINDOW`].
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
/// Key rule: a decoder with the link's key ([`with_key`](Self::with_key)) drops every
/// frame whose authentication tag does not verify (`BadTag`), handshakes and emergency
/// stops included.
///
/// Session rule: a handshake message (`Hello`; `HelloReply`, `HelloRefused`) is accepted
/// whatever its header and changes nothing: the decoder's owner opens a session when it
/// accepts one ([`open_session`](Self::open_session): the board when its runtime accepted
/// a `Hello`, the master when the board's `HelloReply` echoes its nonce). While a session
/// is open, frames of any other session are rejected as `WrongSession` (an earlier
/// connection's frames replayed, a master that does not own the board); before one, every
/// frame passes this check.
///
/// Sequence rule: the first frame after construction / [`reset`](Self::reset) is accepted
/// whatever its sequence number and becomes the reference, and so does the number given
/// to [`open_session`](Self::open_session); any other frame must be newer than the last
/// accepted one by at most [`SEQ_WINDOW`] ([`seq_is_newer`]), else it is rejected as
/// `OutOfOrder` and the reference stays. Skipped numbers are counted in `dropped`.
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
    key: Option<LinkKey>,
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
            key: None,
            counters: LinkCounters {
                frames_ok: 0,
                bad_checksum: 0,
                malformed: 0,
                oversized: 0,
                wrong_version: 0,
                out_of_order: 0,
                dropped: 0,
                wrong_session: 0,
                bad_tag: 0,
            },
            _msg: PhantomData,
        }
    }

    /// Empty decoder of a link with the key `key` (`None`: no key, no tags).
    pub fn with_key(key: Option<LinkKey>) -> Self {
        let mut d = Self::new();
        d.key = key;
        d
    }

    /// The link has a key: frames must carry a valid tag.
    pub const fn has_key(&self) -> bool {
        self.key.is_some()
    }

    /// Opens `session`: from now on only its frames pass, and `seq` (the number of the
    /// frame that opened it: the `Hello`, or the `HelloReply`) is the sequence reference.
    pub fn open_session(&mut self, session: u32, seq: Seq) {
        self.session = Some(session);
        self.last_seq = Some(seq);
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

    /// The current session ([`open_session`](Self::open_session)), if any.
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
        let (Header { session, seq }, msg) = decode_frame_with::<M>(frame, self.key.as_ref())?;
        if msg.is_handshake() {
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

    /// The session and sequence checks of a frame that is no handshake.
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
            Err(FrameError::BadTag) => &mut c.bad_tag,
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
