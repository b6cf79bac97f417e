#![allow(clippy::unwrap_used, clippy::expect_used)]
//! Round trips of every message variant, frame size limits, encoder errors.

use crate::common;
use common::*;
use master_link::*;

/// Every master -> board variant survives encode -> byte-wise decode with
/// its sequence number, and the samples cover all variants.
#[test]
fn every_master_to_board_variant_round_trips() {
    let samples = master_samples();
    let mut seen = [false; MASTER_VARIANTS];
    let mut dec = BoardDecoder::new();
    let mut session = 0u32;
    for (i, msg) in samples.iter().enumerate() {
        seen[master_variant(msg)] = true;
        let seq = 100 + i as Seq;
        // Every frame in the session the last Hello opened.
        session = session.wrapping_add(u32::from(msg.is_handshake()));
        let frame = enc_in(msg, session, seq);
        assert_eq!(frame.last(), Some(&0));
        assert!(!frame[..frame.len() - 1].contains(&0), "COBS removes zeros");
        assert_eq!(decode_all(&mut dec, &frame), vec![Ok((seq, *msg))]);
    }
    assert!(seen.iter().all(|s| *s), "a variant has no sample: {seen:?}");
    assert_eq!(dec.counters().frames_ok as usize, samples.len());
    assert_eq!(dec.counters().rejected(), 0);
    assert_eq!(dec.counters().dropped, 0);
}

/// Every board -> master variant (all Nack reasons, all robot states,
/// extreme status values) round-trips.
#[test]
fn every_board_to_master_variant_round_trips() {
    let samples = board_samples();
    let mut seen = [false; BOARD_VARIANTS];
    let mut dec = MasterDecoder::new();
    let mut session = 0u32;
    for (i, msg) in samples.iter().enumerate() {
        seen[board_variant(msg)] = true;
        let seq = (u16::MAX - 3).wrapping_add(i as Seq); // also crosses the wrap
        session = session.wrapping_add(u32::from(msg.is_handshake()));
        let frame = enc_in(msg, session, seq);
        assert_eq!(decode_all(&mut dec, &frame), vec![Ok((seq, *msg))]);
    }
    assert!(seen.iter().all(|s| *s), "a variant has no sample: {seen:?}");
    assert_eq!(dec.counters().frames_ok as usize, samples.len());
    assert_eq!(dec.counters().rejected(), 0);
}

/// The largest messages (Status with every varint maximal, the fullest fault-log page;
/// PoseTarget with a u64::MAX timestamp) fit into MAX_FRAME_LEN, and so does every sample.
#[test]
fn largest_message_fits_in_max_frame() {
    let status = enc(&BoardToMaster::Status(max_status()), u16::MAX).len();
    let log = enc(&BoardToMaster::FaultLog(max_fault_log()), u16::MAX).len();
    let pose_msg = master_samples()
        .into_iter()
        .find(|m| matches!(m, MasterToBoard::PoseTarget { .. }))
        .unwrap();
    let pose = enc(&pose_msg, u16::MAX).len();
    let geometry = enc(&MasterToBoard::StoreGeometry(max_geometry()), u16::MAX).len();
    let all_master = master_samples().iter().map(|m| enc(m, 1).len()).max();
    let all_board = board_samples().iter().map(|m| enc(m, 1).len()).max();
    println!(
        "largest frames: Status {status} B (body {} B), fault log {log} B (body {} B), PoseTarget {pose} B (limit {MAX_FRAME_LEN} B, body {MAX_BODY_LEN} B)",
        body(&BoardToMaster::Status(max_status())).len(),
        body(&BoardToMaster::FaultLog(max_fault_log())).len(),
    );
    assert_eq!(
        all_board,
        Some(status.max(log)),
        "max Status or log page is the largest"
    );
    assert_eq!(
        all_master,
        Some(geometry),
        "StoreGeometry is the largest master message"
    );
    assert!(pose < geometry && geometry <= MAX_FRAME_LEN);
    assert!(status <= MAX_FRAME_LEN && log <= MAX_FRAME_LEN);
    // Documented sizes (update the README/report if the messages change).
    assert_eq!(status, STATUS_FRAME_LEN);
    assert_eq!(log, LOG_FRAME_LEN);
    assert_eq!(pose, 48);
}

/// The largest Status frame on the wire, bytes (documented in firmware/README.md).
const STATUS_FRAME_LEN: usize = 247;
/// The largest fault-log frame on the wire, bytes.
const LOG_FRAME_LEN: usize = 206;

/// encode() into a buffer that is too small returns BufferTooSmall for
/// every length short of the frame, never panics; the exact size works.
#[test]
fn encode_into_too_small_buffer_is_an_error() {
    let msg = BoardToMaster::Status(max_status());
    let needed = enc(&msg, 9).len();
    for len in 0..needed {
        let mut buf = vec![0u8; len];
        assert_eq!(
            encode(&msg, Header { session: 0, seq: 9 }, &mut buf),
            Err(EncodeError::BufferTooSmall)
        );
    }
    let mut buf = vec![0u8; needed];
    assert_eq!(
        encode(&msg, Header { session: 0, seq: 9 }, &mut buf),
        Ok(needed)
    );
}

/// decode_frame() (single frame, no sequence check) inverts encode().
#[test]
fn decode_frame_inverts_encode() {
    for msg in master_samples() {
        let mut frame = enc(&msg, 42);
        frame.pop(); // delimiter
        assert_eq!(
            decode_frame::<MasterToBoard>(&mut frame),
            Ok((
                Header {
                    session: 0,
                    seq: 42
                },
                msg
            ))
        );
    }
}

/// feed() over slices yields the same results as push() byte by byte, and
/// a frame split across feed() calls is reassembled.
#[test]
fn feed_by_slices_equals_push_by_bytes() {
    let mut stream = Vec::new();
    for (i, m) in master_samples().iter().enumerate() {
        stream.extend(enc(m, i as Seq + 1));
    }
    let mut a = BoardDecoder::new();
    let expected = decode_all(&mut a, &stream);
    let mut b = BoardDecoder::new();
    let mut got = Vec::new();
    for chunk in stream.chunks(7) {
        got.extend(b.feed(chunk));
    }
    assert_eq!(got, expected);
    assert_eq!(a.counters(), b.counters());
}

/// The frame header is version | session LE | seq LE, and the CRC is CRC-32/ISO-HDLC
/// (check value 0xCBF43926) in little endian at the end.
#[test]
fn frame_layout_matches_documentation() {
    assert_eq!(CRC32.checksum(b"123456789"), 0xCBF4_3926);
    let mut frame = enc_in(&MasterToBoard::Heartbeat, 0x0A0B_0C0D, 0x0201);
    frame.pop();
    let n = cobs::decode_in_place(&mut frame).unwrap();
    let raw = &frame[..n];
    assert_eq!(raw.len(), HEADER_LEN + 1 + CRC_LEN);
    assert_eq!(
        &raw[..7],
        &[PROTOCOL_VERSION, 0x0D, 0x0C, 0x0B, 0x0A, 0x01, 0x02]
    );
    assert_eq!(raw[7], 7, "Heartbeat is variant index 7");
    let crc = CRC32.checksum(&raw[..8]);
    assert_eq!(&raw[8..], &crc.to_le_bytes());
}

/// SeqCounter wraps and seq_is_newer follows serial-number arithmetic.
#[test]
fn seq_counter_and_serial_arithmetic() {
    let mut s = SeqCounter::new(u16::MAX);
    assert_eq!(s.next(), u16::MAX);
    assert_eq!(s.next(), 0);
    assert_eq!(s.peek(), 1);
    assert!(seq_is_newer(0, u16::MAX));
    assert!(seq_is_newer(SEQ_WINDOW, 0));
    assert!(!seq_is_newer(SEQ_WINDOW + 1, 0));
    assert!(!seq_is_newer(5, 5));
    assert!(!seq_is_newer(4, 5));
}

/// The messages added for the calibrated geometry are appended: every earlier
/// variant keeps its index (postcard's first byte), so its encoding is unchanged.
#[test]
fn geometry_messages_are_appended() {
    let tag = |m: &MasterToBoard| body(m)[0];
    assert_eq!(tag(&MasterToBoard::FaultLogRequest { first: 0 }), 13);
    assert_eq!(tag(&MasterToBoard::StoreGeometry(max_geometry())), 14);
    let btag = |m: &BoardToMaster| body(m)[0];
    assert_eq!(btag(&BoardToMaster::FaultLog(FaultLogPage::default())), 4);
    assert_eq!(
        btag(&BoardToMaster::GeometryStored { seq: 0, version: 1 }),
        5
    );
    assert_eq!(
        btag(&BoardToMaster::GeometryRefused {
            seq: 0,
            reason: GeometryRefusal::Crc
        }),
        6
    );
    // The record's CRC covers every value: one flipped bit of one value is detected.
    let g = max_geometry();
    assert!(g.crc_ok());
    let mut bad = g;
    bad.chains[2][15] = f32::from_bits(bad.chains[2][15].to_bits() ^ 1);
    assert!(!bad.crc_ok());
    let mut bad = g;
    bad.version ^= 1 << 20;
    assert!(!bad.crc_ok());
}

/// The event log's request and page are appended after the geometry's: every earlier
/// variant keeps its index, and a page of eight of the largest entries (faults with
/// maximal varints) fits one frame.
#[test]
fn event_log_messages_are_appended_and_fit_a_frame() {
    let tag = |m: &MasterToBoard| body(m)[0];
    assert_eq!(tag(&MasterToBoard::StoreGeometry(max_geometry())), 14);
    assert_eq!(tag(&MasterToBoard::EventLogRequest { first: 0 }), 15);
    let btag = |m: &BoardToMaster| body(m)[0];
    assert_eq!(
        btag(&BoardToMaster::GeometryRefused {
            seq: 0,
            reason: GeometryRefusal::Crc
        }),
        6
    );
    assert_eq!(btag(&BoardToMaster::EventLog(EventLogPage::default())), 7);
    let largest = body(&BoardToMaster::EventLog(max_event_log())).len();
    assert!(largest <= MAX_BODY_LEN, "{largest} > {MAX_BODY_LEN}");
    // One more entry would not fit: the page is as large as a frame allows.
    let mut buf = [0u8; 64];
    let entry = postcard::to_slice(&max_event_log().entries[0], &mut buf)
        .expect("postcard")
        .len();
    assert!(largest + entry > MAX_BODY_LEN, "{largest} + {entry}");
}
