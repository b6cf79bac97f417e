#![allow(clippy::unwrap_used, clippy::expect_used)]
//! Rejected frames: each is dropped, counted once in the right counter, and
//! the decoder keeps working afterwards.

use crate::common;
use common::*;
use master_link::*;

const HB: MasterToBoard = MasterToBoard::Heartbeat;

/// Asserts the decoder yields exactly one result for `frame`, returns it.
fn one<const N: usize>(
    dec: &mut FrameDecoder<MasterToBoard, N>,
    frame: &[u8],
) -> Result<(Seq, MasterToBoard), FrameError> {
    let mut r = decode_all(dec, frame);
    assert_eq!(r.len(), 1, "one result per frame");
    r.remove(0)
}

/// Invalid COBS (code byte pointing past the end) -> Malformed(Cobs).
#[test]
fn garbage_cobs_is_malformed() {
    let mut dec = BoardDecoder::new();
    assert_eq!(
        one(&mut dec, &[0x09, 1, 2, 3, 0]),
        Err(FrameError::Malformed(Malformed::Cobs))
    );
    assert_eq!(dec.counters().malformed, 1);
    assert_eq!(one(&mut dec, &enc(&HB, 1)), Ok((1, HB)));
}

/// A frame shorter than header + tag + CRC (but valid COBS) -> Truncated.
#[test]
fn too_short_frame_is_malformed_truncated() {
    let mut dec = BoardDecoder::new();
    for len in 1..MIN_RAW_LEN {
        let raw = vec![0x55; len];
        assert_eq!(
            one(&mut dec, &cobs_frame(&raw)),
            Err(FrameError::Malformed(Malformed::Truncated))
        );
    }
    // Header + CRC with an empty body: too short as well.
    assert_eq!(
        one(&mut dec, &raw_frame(PROTOCOL_VERSION, 1, &[], None)),
        Err(FrameError::Malformed(Malformed::Truncated))
    );
    assert_eq!(dec.counters().malformed as usize, MIN_RAW_LEN);
}

/// A real frame cut short anywhere (bytes lost before the delimiter) is
/// never accepted: it is malformed or fails the CRC.
#[test]
fn truncated_frames_are_rejected() {
    let msg = MasterToBoard::PoseTarget {
        timestamp_us: 123_456_789,
        position_m: [0.01, 0.02, 0.1],
        rotation_vector_rad: [0.0, 0.1, 0.2],
    };
    let full = enc(&msg, 5);
    let body_len = full.len() - 1;
    for keep in 1..body_len {
        let mut dec = BoardDecoder::new();
        let mut frame = full[..keep].to_vec();
        frame.push(0);
        let r = one(&mut dec, &frame);
        assert!(
            matches!(
                r,
                Err(FrameError::Malformed(_)) | Err(FrameError::BadChecksum)
            ),
            "keep={keep}: {r:?}"
        );
        assert_eq!(dec.counters().rejected(), 1);
    }
}

/// Flipping any single bit of the raw frame (header, body or CRC) gives
/// BadChecksum; the next good frame still decodes.
#[test]
fn any_single_bit_flip_is_a_bad_checksum() {
    let msg = MasterToBoard::Jog {
        joint: 3,
        velocity: 0.25,
    };
    let mut frame = enc(&msg, 77);
    frame.pop();
    let n = cobs::decode_in_place(&mut frame).unwrap();
    let raw = frame[..n].to_vec();
    let mut dec = BoardDecoder::new();
    let mut flips = 0;
    for byte in 0..raw.len() {
        for bit in 0..8 {
            let mut bad = raw.clone();
            bad[byte] ^= 1 << bit;
            assert_eq!(
                one(&mut dec, &cobs_frame(&bad)),
                Err(FrameError::BadChecksum)
            );
            flips += 1;
        }
    }
    assert_eq!(dec.counters().bad_checksum, flips);
    assert_eq!(one(&mut dec, &enc(&msg, 78)), Ok((78, msg)));
}

/// A correctly checksummed frame of another protocol version is dropped
/// as WrongVersion.
#[test]
fn wrong_protocol_version_is_rejected() {
    let mut dec = BoardDecoder::new();
    let b = body(&HB);
    for v in [0u8, PROTOCOL_VERSION + 1, 0xFF] {
        assert_eq!(
            one(&mut dec, &raw_frame(v, 1, &b, None)),
            Err(FrameError::WrongVersion { received: v })
        );
    }
    assert_eq!(dec.counters().wrong_version, 3);
    assert_eq!(dec.counters().frames_ok, 0);
    assert_eq!(
        dec.last_seq(),
        None,
        "rejected frames do not set the sequence"
    );
}

/// Valid CRC but an unknown enum tag, or bytes after the message -> Body /
/// TrailingBytes, counted as malformed.
#[test]
fn undecodable_body_and_trailing_bytes_are_malformed() {
    let mut dec = BoardDecoder::new();
    assert_eq!(
        one(&mut dec, &raw_frame(PROTOCOL_VERSION, 1, &[200], None)),
        Err(FrameError::Malformed(Malformed::Body))
    );
    // Jog with a missing f32 byte.
    let mut short = body(&MasterToBoard::Jog {
        joint: 1,
        velocity: 1.0,
    });
    short.pop();
    assert_eq!(
        one(&mut dec, &raw_frame(PROTOCOL_VERSION, 1, &short, None)),
        Err(FrameError::Malformed(Malformed::Body))
    );
    let mut long = body(&HB);
    long.push(0);
    assert_eq!(
        one(&mut dec, &raw_frame(PROTOCOL_VERSION, 1, &long, None)),
        Err(FrameError::Malformed(Malformed::TrailingBytes))
    );
    // Board messages are not master messages: Status tag 3 = Home with extra bytes.
    let status = raw_frame(
        PROTOCOL_VERSION,
        1,
        &body(&BoardToMaster::Status(max_status())),
        None,
    );
    assert!(matches!(
        one(&mut dec, &status),
        Err(FrameError::Malformed(_))
    ));
    assert_eq!(dec.counters().malformed, 4);
}

/// The same sequence number twice (replay) and an older one (out of order)
/// are rejected; newer ones are still accepted.
#[test]
fn replayed_and_out_of_order_frames_are_rejected() {
    let mut dec = BoardDecoder::new();
    assert_eq!(one(&mut dec, &enc(&HB, 5)), Ok((5, HB)));
    assert_eq!(
        one(&mut dec, &enc(&HB, 5)),
        Err(FrameError::OutOfOrder { seq: 5, last: 5 })
    );
    assert_eq!(
        one(&mut dec, &enc(&HB, 4)),
        Err(FrameError::OutOfOrder { seq: 4, last: 5 })
    );
    // Far in the "past" half of the window is out of order too.
    assert!(one(&mut dec, &enc(&HB, 5u16.wrapping_sub(SEQ_WINDOW))).is_err());
    assert_eq!(one(&mut dec, &enc(&HB, 6)), Ok((6, HB)));
    let c = dec.counters();
    assert_eq!((c.frames_ok, c.out_of_order, c.dropped), (2, 3, 0));
}

/// Sequence numbers wrap: 65534, 65535, 0, 1 are in order (nothing
/// dropped) and 65535 after 1 is a replay.
#[test]
fn sequence_wraps_around() {
    let mut dec = BoardDecoder::new();
    for seq in [65534u16, 65535, 0, 1] {
        assert_eq!(one(&mut dec, &enc(&HB, seq)), Ok((seq, HB)));
    }
    assert!(matches!(
        one(&mut dec, &enc(&HB, 65535)),
        Err(FrameError::OutOfOrder { .. })
    ));
    // Gap across the wrap: 65533 missing numbers... 1 -> 3 drops 1.
    assert_eq!(one(&mut dec, &enc(&HB, 3)), Ok((3, HB)));
    assert_eq!(dec.counters().dropped, 1);
    assert_eq!(dec.counters().frames_ok, 5);
}

/// Gaps (lost frames) are accepted and the missing numbers are counted as
/// dropped, including a gap across the wrap.
#[test]
fn gaps_are_accepted_and_counted_as_dropped() {
    let mut dec = BoardDecoder::new();
    for seq in [10u16, 13, 14, 65530] {
        let _ = one(&mut dec, &enc(&HB, seq));
    }
    // 10 -> 13 drops 2; 14 -> 65530 is more than half the space: rejected.
    assert_eq!(dec.counters().dropped, 2);
    assert_eq!(dec.counters().out_of_order, 1);
    let mut dec = BoardDecoder::new();
    one(&mut dec, &enc(&HB, 65530)).unwrap();
    one(&mut dec, &enc(&HB, 4)).unwrap(); // 65531..=65535, 0..=3 lost
    assert_eq!(dec.counters().dropped, 9);
}

/// A Hello is taken whatever its number and moves nothing: the reference stays where the
/// session's frames left it. Opening a session sets the reference; reset_sequence()
/// forgets it.
#[test]
fn hello_is_taken_whatever_its_number_and_moves_nothing() {
    let hello = MasterToBoard::Hello {
        protocol_version: PROTOCOL_VERSION,
        nonce: 0,
        clock_us: 0,
    };
    let mut dec = BoardDecoder::new();
    one(&mut dec, &enc(&HB, 40_000)).unwrap();
    assert_eq!(one(&mut dec, &enc(&hello, 3)), Ok((3, hello)));
    assert_eq!(
        one(&mut dec, &enc(&hello, 3)),
        Ok((3, hello)),
        "twice: still taken"
    );
    assert!(one(&mut dec, &enc(&HB, 4)).is_err(), "the reference stayed");
    assert_eq!(one(&mut dec, &enc(&HB, 40_001)), Ok((40_001, HB)));
    // The board accepted the Hello of seq 3: it opens the session there.
    dec.open_session(0, 3);
    assert!(one(&mut dec, &enc(&HB, 2)).is_err());
    assert_eq!(one(&mut dec, &enc(&HB, 4)), Ok((4, HB)));
    assert_eq!(dec.counters().dropped, 0, "opening is not a gap");

    dec.reset_sequence();
    assert_eq!(one(&mut dec, &enc(&HB, 1)), Ok((1, HB)));

    // Master side: a HelloReply is taken whatever its number, and so is a HelloRefused.
    let mut host = MasterDecoder::new();
    let reply = board_samples()[0];
    decode_all(&mut host, &enc(&BoardToMaster::Ack { seq: 0 }, 900));
    assert_eq!(decode_all(&mut host, &enc(&reply, 1)), vec![Ok((1, reply))]);
    let refused = board_samples()[1];
    assert!(matches!(refused, BoardToMaster::HelloRefused { .. }));
    assert_eq!(
        decode_all(&mut host, &enc(&refused, 2)),
        vec![Ok((2, refused))]
    );
}

/// A frame far ahead of the window (a stray or forged number) is refused and does not
/// move the reference: the sender's next frame is taken.
#[test]
fn a_frame_beyond_the_window_is_refused_without_moving_the_reference() {
    let mut dec = BoardDecoder::new();
    assert_eq!(one(&mut dec, &enc(&HB, 100)), Ok((100, HB)));
    for ahead in [SEQ_WINDOW + 1, 30_000, 32_767] {
        assert_eq!(
            one(&mut dec, &enc(&HB, 100u16.wrapping_add(ahead))),
            Err(FrameError::OutOfOrder {
                seq: 100u16.wrapping_add(ahead),
                last: 100
            })
        );
    }
    assert_eq!(one(&mut dec, &enc(&HB, 101)), Ok((101, HB)));
    assert_eq!(
        one(&mut dec, &enc(&HB, 101 + SEQ_WINDOW)),
        Ok((101 + SEQ_WINDOW, HB)),
        "the window's edge is in"
    );
    assert_eq!(dec.counters().out_of_order, 3);
}

/// A frame longer than the buffer is discarded up to the next delimiter,
/// reported once as Oversized, and the next good frame decodes.
#[test]
fn oversized_frame_is_dropped_and_decoder_recovers() {
    let mut dec = BoardDecoder::new();
    let mut stream = vec![0x42u8; 3 * MAX_FRAME_LEN];
    stream.push(0);
    stream.extend(enc(&HB, 1));
    let r = decode_all(&mut dec, &stream);
    assert_eq!(r, vec![Err(FrameError::Oversized), Ok((1, HB))]);
    assert_eq!(dec.counters().oversized, 1);

    // Small receive buffer: a PoseTarget does not fit, a Heartbeat does.
    let mut small = FrameDecoder::<MasterToBoard, 16>::new();
    let pose = master_samples()
        .into_iter()
        .find(|m| matches!(m, MasterToBoard::PoseTarget { .. }))
        .unwrap();
    let mut stream = enc(&pose, 1);
    stream.extend(enc(&HB, 2));
    assert_eq!(
        decode_all(&mut small, &stream),
        vec![Err(FrameError::Oversized), Ok((2, HB))]
    );

    // Exactly N encoded bytes fit, N + 1 do not.
    let frame = enc(&pose, 3);
    let n = frame.len() - 1;
    let mut exact = FrameDecoder::<MasterToBoard, 47>::new();
    assert_eq!(n, 47);
    assert_eq!(decode_all(&mut exact, &frame), vec![Ok((3, pose))]);
    let mut tight = FrameDecoder::<MasterToBoard, 46>::new();
    assert_eq!(
        decode_all(&mut tight, &frame),
        vec![Err(FrameError::Oversized)]
    );

    // A zero-capacity decoder never panics.
    let mut zero = FrameDecoder::<MasterToBoard, 0>::new();
    assert_eq!(
        decode_all(&mut zero, &frame),
        vec![Err(FrameError::Oversized)]
    );
}

/// With a buffer bigger than MAX_FRAME_LEN, a valid-COBS frame whose raw
/// part exceeds MAX_RAW_LEN is still rejected as Oversized.
#[test]
fn raw_frame_longer_than_protocol_limit_is_oversized() {
    let mut dec = FrameDecoder::<MasterToBoard, 512>::new();
    let raw = vec![1u8; MAX_RAW_LEN + 1];
    assert_eq!(
        decode_all(&mut dec, &cobs_frame(&raw)),
        vec![Err(FrameError::Oversized)]
    );
    assert_eq!(dec.counters().oversized, 1);
}

/// Garbage between frames (delimited by 0x00) costs one rejected frame;
/// repeated delimiters are ignored; all real frames decode.
#[test]
fn garbage_between_frames_is_skipped() {
    let mut stream = vec![0, 0, 0]; // leading sync zeros: ignored
    stream.extend(enc(&HB, 1));
    stream.extend([0x13, 0x37, 0xFF, 0x01, 0x02, 0x00]); // garbage frame
    stream.extend([0x00, 0x00]);
    stream.extend(enc(&MasterToBoard::Enable, 2));
    stream.extend([0xDE, 0xAD, 0xBE, 0xEF, 0x00]);
    stream.extend(enc(&MasterToBoard::Disable, 3));
    let mut dec = BoardDecoder::new();
    let oks: Vec<_> = decode_all(&mut dec, &stream)
        .into_iter()
        .filter_map(Result::ok)
        .collect();
    assert_eq!(
        oks,
        vec![
            (1, HB),
            (2, MasterToBoard::Enable),
            (3, MasterToBoard::Disable)
        ]
    );
    assert_eq!(dec.counters().frames_ok, 3);
    assert_eq!(dec.counters().rejected(), 2);
}

/// resync() drops the partial frame silently (no counter), the following
/// frame decodes.
#[test]
fn resync_discards_partial_frame_silently() {
    let mut dec = BoardDecoder::new();
    let frame = enc(&HB, 1);
    decode_all(&mut dec, &frame[..3]);
    dec.resync();
    let mut rest = frame[3..].to_vec();
    rest.extend(enc(&HB, 2));
    assert_eq!(decode_all(&mut dec, &rest), vec![Ok((2, HB))]);
    assert_eq!(dec.counters().frames_total(), 1);
}

/// An open session refuses frames of any other: the session before it (replayed from an
/// earlier connection, whatever their sequence numbers) is refused and counted as
/// `wrong_session`; frames of the new session are taken. A Hello alone opens nothing.
#[test]
fn frames_of_an_older_session_are_refused() {
    let mut dec = BoardDecoder::new();
    let new = MasterToBoard::Hello {
        protocol_version: PROTOCOL_VERSION,
        nonce: 0x2222,
        clock_us: 5,
    };
    dec.open_session(0x1111, 1);
    assert_eq!(one(&mut dec, &enc_in(&HB, 0x1111, 2)), Ok((2, HB)));
    assert!(one(&mut dec, &enc_in(&new, 0x1111, 3)).is_ok());
    assert_eq!(
        dec.session(),
        Some(0x1111),
        "a Hello opens nothing by itself"
    );
    dec.open_session(0x2222, 3);
    assert_eq!(dec.session(), Some(0x2222));
    // The old session's next frames, newer sequence numbers and all.
    for seq in [4, 5, 1000] {
        assert_eq!(
            one(&mut dec, &enc_in(&HB, 0x1111, seq)),
            Err(FrameError::WrongSession {
                received: 0x1111,
                expected: 0x2222
            })
        );
    }
    assert_eq!(dec.counters().wrong_session, 3);
    assert_eq!(one(&mut dec, &enc_in(&HB, 0x2222, 4)), Ok((4, HB)));
    assert_eq!(dec.counters().dropped, 0);
}

/// No filter drops an emergency stop: out of order, replayed, of another session or
/// before any Hello, an intact EmergencyStop frame is taken; it leaves the session and
/// the sequence reference as they were.
#[test]
fn an_emergency_stop_is_never_dropped_by_the_session_or_sequence_checks() {
    let stop = MasterToBoard::EmergencyStop;
    let mut dec = BoardDecoder::new();
    assert_eq!(one(&mut dec, &enc_in(&stop, 77, 9)), Ok((9, stop)));
    let hello = MasterToBoard::Hello {
        protocol_version: PROTOCOL_VERSION,
        nonce: 5,
        clock_us: 0,
    };
    assert!(one(&mut dec, &enc_in(&hello, 0, 100)).is_ok());
    dec.open_session(5, 100);
    assert_eq!(one(&mut dec, &enc_in(&HB, 5, 101)), Ok((101, HB)));
    // Out of order, same session.
    assert_eq!(one(&mut dec, &enc_in(&stop, 5, 50)), Ok((50, stop)));
    // Of another session.
    assert_eq!(one(&mut dec, &enc_in(&stop, 6, 102)), Ok((102, stop)));
    // Replayed: the same frame twice.
    let f = enc_in(&stop, 5, 101);
    assert_eq!(one(&mut dec, &f), Ok((101, stop)));
    assert_eq!(one(&mut dec, &f), Ok((101, stop)));
    assert_eq!(dec.counters().rejected(), 0);
    // The reference stayed at 101: the next heartbeat continues the sequence.
    assert_eq!(one(&mut dec, &enc_in(&HB, 5, 102)), Ok((102, HB)));
    assert_eq!(dec.counters().dropped, 0);
    // A corrupted one is still a bad frame (the CRC protects it like any other).
    let mut bad = enc_in(&stop, 5, 103);
    bad[2] ^= 0x40;
    assert!(one(&mut dec, &bad).is_err());
}
