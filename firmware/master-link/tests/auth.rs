#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
//! Authenticated links: with a key every frame carries a truncated HMAC-SHA256 tag; a
//! receiver with the key drops frames with a wrong or missing tag (`bad_tag`), and the
//! largest frames still fit.

use crate::common;
use common::*;
use master_link::*;

fn key(b: u8) -> LinkKey {
    LinkKey::new(&[b; KEY_LEN])
}

fn enc_key<M: WireMessage>(msg: &M, session: u32, seq: Seq, k: Option<&LinkKey>) -> Vec<u8> {
    let mut buf = [0u8; MAX_FRAME_LEN];
    let n = encode_with(msg, Header { session, seq }, k, &mut buf).expect("encode");
    buf[..n].to_vec()
}

/// Every sample of both directions, tagged, round-trips through a decoder with the same
/// key; the largest frames (status, fault log, geometry) still fit in `MAX_FRAME_LEN`
/// with their tag.
#[test]
fn tagged_frames_round_trip_and_fit() {
    let k = key(7);
    let mut board = BoardDecoder::with_key(Some(k.clone()));
    for (i, m) in master_samples().iter().enumerate() {
        let f = enc_key(m, 0, i as Seq + 1, Some(&k));
        assert!(f.len() <= MAX_FRAME_LEN);
        assert_eq!(decode_all(&mut board, &f), vec![Ok((i as Seq + 1, *m))]);
    }
    let mut host = MasterDecoder::with_key(Some(k.clone()));
    for (i, m) in board_samples().iter().enumerate() {
        let f = enc_key(m, 0, i as Seq + 1, Some(&k));
        assert_eq!(decode_all(&mut host, &f).len(), 1);
    }
    assert_eq!(host.counters().rejected(), 0);
    let status = enc_key(&BoardToMaster::Status(max_status()), 1, 1, Some(&k)).len();
    let log = enc_key(&BoardToMaster::FaultLog(max_fault_log()), 1, 1, Some(&k)).len();
    let geometry = enc_key(
        &MasterToBoard::StoreGeometry(max_geometry()),
        1,
        1,
        Some(&k),
    )
    .len();
    println!("tagged: status {status} B, fault log {log} B, geometry {geometry} B");
    assert_eq!(status, 247 + TAG_LEN);
    assert!(status <= MAX_FRAME_LEN && log <= MAX_FRAME_LEN && geometry <= MAX_FRAME_LEN);
}

/// A receiver with a key drops a frame without a tag, one tagged with another key, and
/// one whose tag or header was changed (the CRC recomputed, as a forger would): each is
/// counted as `bad_tag`, handshakes and emergency stops included; the good frame after
/// them is taken.
#[test]
fn wrong_or_missing_tags_are_dropped_and_counted() {
    let k = key(1);
    let mut dec = BoardDecoder::with_key(Some(k.clone()));
    let hello = MasterToBoard::Hello {
        protocol_version: PROTOCOL_VERSION,
        nonce: 9,
        clock_us: 1,
    };
    let forged = |msg: &MasterToBoard, flip: usize| {
        let good = enc_key(msg, 0, 2, Some(&k));
        let mut raw = good[..good.len() - 1].to_vec();
        let n = cobs::decode_in_place(&mut raw).unwrap();
        raw.truncate(n - CRC_LEN);
        raw[flip] ^= 0x01;
        let crc = CRC32.checksum(&raw);
        raw.extend_from_slice(&crc.to_le_bytes());
        cobs_frame(&raw)
    };
    let bad = [
        enc_key(&hello, 0, 1, None),
        enc_key(&MasterToBoard::EmergencyStop, 0, 1, None),
        enc_key(&hello, 0, 1, Some(&key(2))),
        forged(&MasterToBoard::Enable, 6), // the sequence number's high byte
        forged(&MasterToBoard::Enable, 1), // the session
        forged(&hello, HEADER_LEN + 2),    // the body
    ];
    for f in &bad {
        assert_eq!(decode_all(&mut dec, f), vec![Err(FrameError::BadTag)]);
    }
    // A frame cut to less than a tag.
    let short = cobs_frame(&{
        let mut raw = vec![PROTOCOL_VERSION, 0, 0, 0, 0, 1, 0, 7];
        let crc = CRC32.checksum(&raw);
        raw.extend_from_slice(&crc.to_le_bytes());
        raw
    });
    assert_eq!(decode_all(&mut dec, &short), vec![Err(FrameError::BadTag)]);
    assert_eq!(dec.counters().bad_tag, bad.len() as u32 + 1);
    assert_eq!(
        decode_all(&mut dec, &enc_key(&hello, 0, 3, Some(&k))),
        vec![Ok((3, hello))]
    );
    // A receiver without a key cannot read a tagged frame (trailing bytes): a keyed and a
    // keyless side never understand each other.
    let mut plain = BoardDecoder::new();
    assert!(decode_all(&mut plain, &enc_key(&hello, 0, 3, Some(&k)))[0].is_err());
}
