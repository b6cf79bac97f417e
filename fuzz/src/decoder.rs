//! The `decoder` target: arbitrary bytes, one at a time, into the board's decoder
//! (`BoardDecoder`, master messages) and the master's (`MasterDecoder`, board messages),
//! each without a key and with the fuzzing key ([`FUZZ_KEY`]).
//!
//! Invariants, each an assertion:
//! * no panic;
//! * a byte other than the delimiter never completes a frame; a delimiter after a
//!   non-empty frame gives exactly one result, after an empty one none (so every completed
//!   frame gives at most one result);
//! * the result is the one the documented rules give: frames longer than the decoder's
//!   buffer are `Oversized`; otherwise `decode_frame_with` (COBS, length, CRC, the tag with
//!   a key, version, body), then the session rule (a handshake is accepted whatever its
//!   header and changes nothing; the harness then opens the session it names, as the
//!   board does for an accepted `Hello` and the master for its `HelloReply`; frames of
//!   another session are `WrongSession`), the sequence rule (not newer than the last
//!   accepted, or newer by more than the window: `OutOfOrder`, the reference kept) and the
//!   emergency-stop bypass (an intact `EmergencyStop` is accepted whatever its session and
//!   sequence, leaving the reference as it was);
//! * the counters: each result increments exactly its own counter by one, `dropped` grows
//!   by exactly the sequence numbers skipped, nothing else changes (so no counter ever
//!   decreases), and `frames_ok + rejected() ==` the results returned;
//! * an accepted frame is at most `MAX_FRAME_LEN` bytes on the wire, delimiter included;
//! * an accepted message re-encoded with its header decodes to the same header and the
//!   same message (compared as encoded bytes, so that NaN payloads compare too), in at most
//!   `MAX_FRAME_LEN` bytes.

use master_link::{
    decode_frame_with, encode_with, seq_is_newer, BoardToMaster, FrameDecoder, FrameError, Header,
    LinkCounters, LinkKey, MasterToBoard, Seq, WireMessage, MAX_FRAME_LEN,
};

/// The key of the keyed runs (and of the keyed seeds).
pub const FUZZ_KEY: [u8; 32] = [0x42; 32];

/// The fuzzing key.
pub fn fuzz_key() -> LinkKey {
    LinkKey::new(&FUZZ_KEY)
}

/// Runs both decoders over `data` with every check, without a key and with
/// [`FUZZ_KEY`]; returns their counters (board's, master's, then the keyed board's and
/// master's).
pub fn check(data: &[u8]) -> [LinkCounters; 4] {
    let k = fuzz_key();
    [
        check_stream::<MasterToBoard>(data, None),
        check_stream::<BoardToMaster>(data, None),
        check_stream::<MasterToBoard>(data, Some(&k)),
        check_stream::<BoardToMaster>(data, Some(&k)),
    ]
}

/// The session a handshake names: a `Hello`'s nonce, a `HelloReply`'s session (a
/// `HelloRefused` names none). The harness opens it once the decoder has taken the frame,
/// as the board does when its runtime accepts a `Hello`.
pub trait NamedSession {
    /// The session, if the message names one.
    fn named_session(&self) -> Option<u32>;
}

impl NamedSession for MasterToBoard {
    fn named_session(&self) -> Option<u32> {
        match self {
            MasterToBoard::Hello { nonce, .. } => Some(*nonce),
            _ => None,
        }
    }
}

impl NamedSession for BoardToMaster {
    fn named_session(&self) -> Option<u32> {
        match self {
            BoardToMaster::HelloReply { session, .. } => Some(*session),
            _ => None,
        }
    }
}

/// The documented rules, as a model of the decoder's session and sequence state.
#[derive(Default)]
struct Model {
    session: Option<u32>,
    last_seq: Option<Seq>,
}

/// What the model expects of one complete frame: the result, and the sequence numbers the
/// decoder counts as dropped.
type Expected<M> = (Result<(Header, M), FrameError>, u32);

impl Model {
    fn expect<M: WireMessage>(
        &mut self,
        frame: &[u8],
        buffer: usize,
        key: Option<&LinkKey>,
    ) -> Expected<M> {
        if frame.len() > buffer {
            return (Err(FrameError::Oversized), 0);
        }
        let mut copy = frame.to_vec();
        let (header, msg) = match decode_frame_with::<M>(&mut copy, key) {
            Ok(x) => x,
            Err(e) => return (Err(e), 0),
        };
        if msg.is_handshake() {
            return (Ok((header, msg)), 0);
        }
        let refused = match (self.session, self.last_seq) {
            (Some(expected), _) if header.session != expected => Some(FrameError::WrongSession {
                received: header.session,
                expected,
            }),
            (_, Some(last)) if !seq_is_newer(header.seq, last) => Some(FrameError::OutOfOrder {
                seq: header.seq,
                last,
            }),
            _ => None,
        };
        match refused {
            Some(_) if msg.bypasses_sequence() => (Ok((header, msg)), 0),
            Some(e) => (Err(e), 0),
            None => {
                let lost = self.last_seq.map_or(0, |last| {
                    u32::from(header.seq.wrapping_sub(last).wrapping_sub(1))
                });
                self.last_seq = Some(header.seq);
                (Ok((header, msg)), lost)
            }
        }
    }
}

/// The encoded frame of `msg` with `header`; panics if an accepted message does not encode.
fn reencode<M: WireMessage + core::fmt::Debug>(
    msg: &M,
    header: Header,
    key: Option<&LinkKey>,
) -> Vec<u8> {
    let mut buf = [0u8; MAX_FRAME_LEN];
    match encode_with(msg, header, key, &mut buf) {
        Ok(n) => {
            assert!(n <= MAX_FRAME_LEN, "re-encoded frame of {n} bytes: {msg:?}");
            buf.get(..n).map(<[u8]>::to_vec).unwrap_or_default()
        }
        Err(e) => panic!("an accepted message does not encode again ({e:?}): {msg:?}"),
    }
}

/// The counters after one result, as the model expects them from `before`.
fn counted<M>(
    before: &LinkCounters,
    result: &Result<(Seq, M), FrameError>,
    lost: u32,
) -> LinkCounters {
    let mut c = *before;
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
    *counter += 1;
    c.dropped = c.dropped.wrapping_add(lost);
    c
}

fn check_stream<M: WireMessage + NamedSession + core::fmt::Debug>(
    data: &[u8],
    key: Option<&LinkKey>,
) -> LinkCounters {
    let mut dec = FrameDecoder::<M, MAX_FRAME_LEN>::with_key(key.cloned());
    let mut model = Model::default();
    // The bytes since the last delimiter (all of them: a frame may outgrow the buffer).
    let mut frame: Vec<u8> = Vec::with_capacity(MAX_FRAME_LEN + 1);
    let mut results: u32 = 0;
    for &byte in data {
        let before = *dec.counters();
        let result = dec.push(byte);
        if byte != 0 {
            assert!(
                result.is_none(),
                "a non-delimiter byte completed a frame: {result:?}"
            );
            assert_eq!(*dec.counters(), before, "a non-delimiter byte was counted");
            frame.push(byte);
            continue;
        }
        let Some(result) = result else {
            assert!(
                frame.is_empty(),
                "a non-empty frame of {} bytes gave no result",
                frame.len()
            );
            assert_eq!(*dec.counters(), before, "an empty frame was counted");
            continue;
        };
        assert!(
            !frame.is_empty(),
            "an empty frame gave a result: {result:?}"
        );
        results += 1;
        let (expected, lost) = model.expect::<M>(&frame, MAX_FRAME_LEN, key);
        match (&result, &expected) {
            (Ok((seq, msg)), Ok((header, model_msg))) => {
                assert_eq!(*seq, header.seq, "sequence number of an accepted frame");
                // One byte of delimiter follows the frame on the wire.
                assert!(
                    frame.len() < MAX_FRAME_LEN,
                    "a frame of {} bytes (+ delimiter) was accepted",
                    frame.len()
                );
                let wire = reencode(msg, *header, key);
                assert_eq!(
                    wire,
                    reencode(model_msg, *header, key),
                    "decoder and decode_frame disagree on the message"
                );
                let mut again = wire;
                again.pop();
                match decode_frame_with::<M>(&mut again, key) {
                    Ok((h, m)) => {
                        assert_eq!(h, *header, "header after a round trip");
                        assert_eq!(
                            reencode(&m, h, key),
                            reencode(msg, *header, key),
                            "message after a round trip: {msg:?} -> {m:?}"
                        );
                    }
                    Err(e) => panic!("a re-encoded accepted message does not decode: {e:?}"),
                }
            }
            (Err(got), Err(want)) => assert_eq!(got, want, "rejection reason"),
            _ => panic!("decoder gave {result:?}, the documented rules {expected:?}"),
        }
        // The owner opens the session a handshake names (the board: an accepted Hello;
        // the master: its HelloReply).
        if let Ok((seq, msg)) = &result {
            if let Some(session) = msg.named_session() {
                dec.open_session(session, *seq);
                model.session = Some(session);
                model.last_seq = Some(*seq);
            }
        }
        let after = *dec.counters();
        assert_eq!(
            after,
            counted(&before, &result, lost),
            "counters after {result:?}"
        );
        assert_eq!(
            dec.last_seq(),
            model.last_seq,
            "sequence reference after {result:?}"
        );
        assert_eq!(dec.session(), model.session, "session after {result:?}");
        frame.clear();
    }
    let c = *dec.counters();
    assert_eq!(
        c.frames_total(),
        results,
        "frames_ok + rejected() against the results returned"
    );
    c
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::frames;

    /// The sample streams pass every check (and are accepted frame by frame).
    #[test]
    fn sample_streams_pass() {
        let m = frames::stream(&frames::master_messages(), 100);
        let b = frames::stream(&frames::board_messages(), 100);
        let [on_board, _, keyed_board, _] = check(&m);
        assert_eq!(on_board.frames_ok as usize, frames::master_messages().len());
        // A keyed decoder drops every untagged frame.
        assert_eq!(
            keyed_board.bad_tag as usize,
            frames::master_messages().len()
        );
        let [_, on_master, _, _] = check(&b);
        assert_eq!(on_master.frames_ok as usize, frames::board_messages().len());
        // Tagged with the fuzzing key: the keyed decoders take them all.
        let k = fuzz_key();
        let mt = frames::stream_keyed(&frames::master_messages(), 100, Some(&k));
        let [plain, _, keyed, _] = check(&mt);
        assert_eq!(keyed.frames_ok as usize, frames::master_messages().len());
        assert_eq!(plain.frames_ok, 0);
        let mut rx = master_link::BoardDecoder::new();
        let n = rx.feed(&m).filter(Result::is_ok).count();
        assert_eq!(n, frames::master_messages().len());
        let mut rx = master_link::MasterDecoder::new();
        let n = rx.feed(&b).filter(Result::is_ok).count();
        assert_eq!(n, frames::board_messages().len());
    }

    /// Garbage, an over-long frame and a replay pass the checks.
    #[test]
    fn garbage_passes() {
        let mut data = vec![0x11; 600];
        data.push(0);
        data.extend(frames::stream(&frames::master_messages(), 5));
        data.extend(frames::stream(&frames::master_messages()[1..], 5));
        data.extend([1, 2, 3, 0, 0, 0, 9]);
        let [c, _, _, _] = check(&data);
        assert_eq!(c.oversized, 1, "{c:?}");
        // The replay: 16 frames not newer than the last, all refused but the
        // EmergencyStop, which bypasses the sequence check.
        assert_eq!(c.out_of_order, 15, "{c:?}");
        assert_eq!(c.frames_ok, 17 + 1, "{c:?}");
        assert_eq!(c.malformed, 1, "{c:?}");
    }
}
