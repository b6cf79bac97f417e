//! The codec against test vectors from the reference implementations, and round trips.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use common::{hex, proptest_config};
use igtl::content::{
    PositionContent, PositionOrientation, StatusContent, StringContent, TransformContent,
};
use igtl::crc::body_crc;
use igtl::header::{Header, HeaderError, HEADER_SIZE};
use igtl::message::{DecodeError, EncodeError};
use igtl::metadata::{split_v3_body, MetadataEntry, MetadataError};
use igtl::{Body, DataType, HeaderVersion, Message, QueryKind, Timestamp};
use proptest::prelude::*;
use std::time::Duration;

// ---------------------------------------------------------------------------------------
// CRC-64: the catalogue check value and values computed on 2026-11-22 with pyigtl 0.3.4
// (`pyigtl.messages.CRC64`, crcmod) and with libOpenIGTLink 1.11 (`crc64(data, len,
// crc64(0, 0, 0))` of igtl_util.h, Debian's libopenigtlink-dev); both gave the same.

#[test]
fn crc_matches_the_ecma_182_check_value_and_the_reference_implementations() {
    assert_eq!(body_crc(b"123456789"), 0x6C40_DF5F_0B49_7347);
    assert_eq!(body_crc(b"OpenIGTLink"), 0x7079_2326_F2A3_8CE7);
    let all: Vec<u8> = (0..=255u8).collect();
    assert_eq!(body_crc(&all), 0x62B0_DA1C_1B13_0A91);
    assert_eq!(body_crc(b""), 0);
}

// ---------------------------------------------------------------------------------------
// Whole messages written by pyigtl 0.3.4 and libOpenIGTLink 1.11.

/// `pyigtl.TransformMessage(M, timestamp=1700000000.5, device_name="Target").pack()` with
/// M = [[0,-1,0,10.5],[1,0,0,-20.25],[0,0,1,160],[0,0,0,1]].
const PYIGTL_TRANSFORM: &str = "00015452414e53464f524d00000054617267657400000000000000000000000000006553f10080000000000000000000003058bf76fa111f942f000000003f80000000000000bf800000000000000000000000000000000000003f80000041280000c1a2000043200000";
/// `pyigtl.StringMessage("hello robot", timestamp=1700000000.25, device_name="Note")` with
/// header_version = 2, message_id = 7, metadata {"Priority": "high"}.
const PYIGTL_STRING_V3: &str = "0002535452494e470000000000004e6f7465000000000000000000000000000000006553f100400000000000000000000031b4e18a3fa46256c1000c000a0000000c000000070003000b68656c6c6f20726f626f74000100080003000000045072696f7269747968696768";
/// libOpenIGTLink 1.11 `TransformMessage`, the same matrix, device "Target", timestamp
/// (1700000003, 0x80000000).
const LIBIGTL_TRANSFORM: &str = "00015452414e53464f524d00000054617267657400000000000000000000000000006553f10380000000000000000000003058bf76fa111f942f000000003f80000000000000bf800000000000000000000000000000000000003f80000041280000c1a2000043200000";
/// libOpenIGTLink 1.11 `PositionMessage` (pack type ALL), device "Tool", position
/// (1.5, -2.25, 160), quaternion (0, 0, 0.70710678, 0.70710678), timestamp (1700000001, 0).
const LIBIGTL_POSITION_28: &str = "0001504f534954494f4e00000000546f6f6c000000000000000000000000000000006553f10100000000000000000000001c2a4dbd821cdbb58d3fc00000c01000004320000000000000000000003f3504f33f3504f3";
/// The same with pack type WITH_QUATERNION3 and quaternion (0, 0, 0.6, 0.8).
const LIBIGTL_POSITION_24: &str = "0001504f534954494f4e00000000546f6f6c000000000000000000000000000000006553f1010000000000000000000000189dfde19445a46ca13fc00000c01000004320000000000000000000003f19999a";
/// libOpenIGTLink 1.11 `GetTransformMessage`, device "Robot", timestamp (1700000002, 0).
const LIBIGTL_GET_TRANS: &str = "00014745545f5452414e53000000526f626f740000000000000000000000000000006553f1020000000000000000000000000000000000000000";

/// Decodes a whole vector, checks it re-encodes to the same bytes, returns the message.
fn decode_exact(vector: &str) -> Message {
    let bytes = hex(vector);
    let (m, used) = Message::decode(&bytes).unwrap();
    assert_eq!(used, bytes.len());
    assert_eq!(m.encode().unwrap(), bytes, "re-encoding changes the bytes");
    m
}

#[test]
fn transform_from_pyigtl_and_libopenigtlink_decodes_and_reencodes_byte_for_byte() {
    for (vector, seconds, fraction) in [
        (PYIGTL_TRANSFORM, 1_700_000_000, 0x8000_0000),
        (LIBIGTL_TRANSFORM, 1_700_000_003, 0x8000_0000),
    ] {
        let m = decode_exact(vector);
        assert_eq!(m.version, HeaderVersion::V1);
        assert_eq!(m.device_name, "Target");
        assert_eq!(m.timestamp, Timestamp::from_parts(seconds, fraction));
        let Body::Transform(t) = m.body else {
            panic!("not a TRANSFORM: {:?}", m.body)
        };
        assert_eq!(
            t.rotation,
            [[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]
        );
        assert_eq!(t.translation_mm, [10.5, -20.25, 160.0]);
    }
}

#[test]
fn version_3_string_with_metadata_from_pyigtl_decodes_and_reencodes_byte_for_byte() {
    let m = decode_exact(PYIGTL_STRING_V3);
    assert_eq!(m.version, HeaderVersion::V2);
    assert_eq!(m.device_name, "Note");
    assert_eq!(m.message_id, 7);
    assert_eq!(m.metadata, vec![MetadataEntry::text("Priority", "high")]);
    assert_eq!(m.body, Body::String(StringContent::text("hello robot")));
}

#[test]
fn position_in_its_28_and_24_byte_forms_from_libopenigtlink() {
    let m = decode_exact(LIBIGTL_POSITION_28);
    assert_eq!(
        m.body,
        Body::Position(PositionContent {
            position_mm: [1.5, -2.25, 160.0],
            orientation: PositionOrientation::Quaternion([0.0, 0.0, 0.707_106_77, 0.707_106_77]),
        })
    );
    let m = decode_exact(LIBIGTL_POSITION_24);
    assert_eq!(
        m.body,
        Body::Position(PositionContent {
            position_mm: [1.5, -2.25, 160.0],
            orientation: PositionOrientation::Quaternion3([0.0, 0.0, 0.6]),
        })
    );
}

#[test]
fn get_trans_from_libopenigtlink_is_a_transform_query() {
    let m = decode_exact(LIBIGTL_GET_TRANS);
    assert_eq!(m.device_name, "Robot");
    assert_eq!(
        m.body,
        Body::Query {
            kind: QueryKind::Get,
            suffix: "TRANS".to_owned(),
            content: vec![]
        }
    );
}

#[test]
fn status_is_written_as_the_protocol_lays_it_out() {
    // Code 8, sub code -2, error name "Unreachable" NUL-padded to 20, message + NUL.
    let body = StatusContent {
        code: 8,
        subcode: -2,
        error_name: "Unreachable".to_owned(),
        message: "outside the box".to_owned(),
    }
    .encode();
    let mut expected = vec![0x00, 0x08];
    expected.extend_from_slice(&(-2i64).to_be_bytes());
    expected.extend_from_slice(b"Unreachable\0\0\0\0\0\0\0\0\0");
    expected.extend_from_slice(b"outside the box\0");
    assert_eq!(body, expected);
    // A status message without its NUL (libOpenIGTLink 1.11 sizes the body without it) is
    // read to the end of the content.
    let decoded = StatusContent::decode(&expected[..expected.len() - 1]).unwrap();
    assert_eq!(decoded.message, "outside the box");
    assert_eq!(decoded.error_name, "Unreachable");
}

// ---------------------------------------------------------------------------------------
// Header.

fn header_bytes(version: u16, type_name: &[u8], device: &[u8]) -> [u8; HEADER_SIZE] {
    let mut b = [0u8; HEADER_SIZE];
    b[0..2].copy_from_slice(&version.to_be_bytes());
    b[2..2 + type_name.len()].copy_from_slice(type_name);
    b[14..14 + device.len()].copy_from_slice(device);
    b
}

#[test]
fn header_rejects_versions_other_than_1_and_2_and_badly_padded_names() {
    for v in [0u16, 3, 0x0100, 0xFFFF] {
        assert_eq!(
            Header::decode(&header_bytes(v, b"TRANSFORM", b"X")),
            Err(HeaderError::UnsupportedVersion(v))
        );
    }
    for bad_type in [&b""[..], b"TRANS FORM", b"A\0B", b"\x01ABC", b"\xC3\xA4"] {
        assert!(matches!(
            Header::decode(&header_bytes(1, bad_type, b"X")),
            Err(HeaderError::BadTypeName(_))
        ));
    }
    for bad_device in [&b"A\0B"[..], b"\x07bell", b"\xFF\xFE"] {
        assert!(matches!(
            Header::decode(&header_bytes(1, b"STATUS", bad_device)),
            Err(HeaderError::BadDeviceName(_))
        ));
    }
    // An empty device name and a UTF-8 one are fine.
    assert!(Header::decode(&header_bytes(1, b"GET_STATUS", b"")).is_ok());
    let h = Header::decode(&header_bytes(2, b"STRING", "Zielpunkt-\u{e4}".as_bytes())).unwrap();
    assert_eq!(h.device_name, "Zielpunkt-\u{e4}");
}

#[test]
fn names_that_do_not_fit_are_refused_when_encoding() {
    let long = Message::new("a device name of 21 b", Body::Null(DataType::Status));
    assert!(matches!(long.encode(), Err(EncodeError::Name(_))));
    let query = Message::new(
        "X",
        Body::Query {
            kind: QueryKind::Get,
            suffix: "TRANSFORM".to_owned(), // GET_TRANSFORM is 13 characters
            content: vec![],
        },
    );
    assert!(matches!(query.encode(), Err(EncodeError::Name(_))));
    let v1_with_metadata = Message {
        metadata: vec![MetadataEntry::text("k", "v")],
        ..Message::new("X", Body::Null(DataType::String))
    };
    assert!(matches!(
        v1_with_metadata.encode(),
        Err(EncodeError::V3FieldsOnV1 { .. })
    ));
}

// ---------------------------------------------------------------------------------------
// Version-3 bodies whose sizes lie.

fn v3_body(ext: u16, meta_header: u16, meta: u32, rest: &[u8]) -> Vec<u8> {
    let mut b = Vec::new();
    b.extend_from_slice(&ext.to_be_bytes());
    b.extend_from_slice(&meta_header.to_be_bytes());
    b.extend_from_slice(&meta.to_be_bytes());
    b.extend_from_slice(&9u32.to_be_bytes());
    b.extend_from_slice(rest);
    b
}

#[test]
fn version_3_size_lies_are_each_reported() {
    assert_eq!(
        split_v3_body(&[0, 12, 0]),
        Err(MetadataError::ExtendedHeaderTruncated { body: 3 })
    );
    assert_eq!(
        split_v3_body(&v3_body(8, 0, 0, &[])),
        Err(MetadataError::ExtendedHeaderTooSmall(8))
    );
    assert!(matches!(
        split_v3_body(&v3_body(12, 2, 40, &[0, 0])),
        Err(MetadataError::SizesExceedBody { .. })
    ));
    assert!(matches!(
        split_v3_body(&v3_body(u16::MAX, 0, 0, &[])),
        Err(MetadataError::SizesExceedBody { .. })
    ));
    // INDEX_COUNT 2 but room for one entry.
    assert_eq!(
        split_v3_body(&v3_body(12, 10, 0, &[0, 2, 0, 0, 0, 3, 0, 0, 0, 0])),
        Err(MetadataError::HeaderSizeMismatch { size: 10, count: 2 })
    );
    // One entry: key 1 byte + value 5 bytes, but METADATA_SIZE 4.
    assert_eq!(
        split_v3_body(&v3_body(
            12,
            10,
            4,
            &[0, 1, 0, 1, 0, 3, 0, 0, 0, 5, b'k', b'v', b'v', b'v']
        )),
        Err(MetadataError::SizeMismatch {
            entries: 6,
            size: 4
        })
    );
    assert_eq!(
        split_v3_body(&v3_body(12, 0, 3, b"abc")),
        Err(MetadataError::MetadataWithoutHeader(3))
    );
    // An extended header larger than 12: the extra bytes are skipped.
    let body = v3_body(14, 0, 0, &[0xEE, 0xEE, 1, 2, 3]);
    let parts = split_v3_body(&body).unwrap();
    assert_eq!(parts.content, &[1, 2, 3]);
    assert_eq!(parts.message_id, 9);
}

#[test]
fn a_crc_mismatch_is_reported_with_both_values() {
    let mut bytes = hex(PYIGTL_TRANSFORM);
    let last = bytes.len() - 1;
    bytes[last] ^= 0x01;
    match Message::decode(&bytes) {
        Err(DecodeError::Crc { header, computed }) => assert_ne!(header, computed),
        other => panic!("expected a CRC mismatch, got {other:?}"),
    }
}

#[test]
fn content_of_the_wrong_size_is_refused_per_type() {
    assert!(TransformContent::decode(&[0; 47]).is_err());
    assert!(TransformContent::decode(&[0; 49]).is_err());
    for size in [1, 11, 13, 16, 20, 23, 25, 27, 29, 32] {
        assert!(
            PositionContent::decode(&vec![0; size], "POSITION").is_err(),
            "{size} bytes"
        );
    }
    assert!(StatusContent::decode(&[0; 29]).is_err());
    // STRING length field 5 with 4 bytes following, and with 6.
    assert!(StringContent::decode(&[0, 3, 0, 5, b'a', b'b', b'c', b'd']).is_err());
    assert!(StringContent::decode(&[0, 3, 0, 5, b'a', b'b', b'c', b'd', b'e', b'f']).is_err());
}

// ---------------------------------------------------------------------------------------
// Round trips.

fn finite_f32() -> impl Strategy<Value = f32> {
    prop_oneof![
        -1.0e6f32..1.0e6,
        any::<f32>().prop_filter("finite", |v| v.is_finite()),
    ]
}

fn text(max: usize) -> impl Strategy<Value = String> {
    proptest::string::string_regex(&format!("[ -~\u{e4}\u{e9}]{{0,{max}}}"))
        .unwrap()
        .prop_filter("fits", move |s| s.len() <= max)
}

fn data_type() -> impl Strategy<Value = DataType> {
    prop_oneof![
        Just(DataType::Transform),
        Just(DataType::Position),
        Just(DataType::QTrans),
        Just(DataType::Status),
        Just(DataType::String),
    ]
}

fn position() -> impl Strategy<Value = PositionContent> {
    let orientation = prop_oneof![
        Just(PositionOrientation::None),
        [finite_f32(), finite_f32(), finite_f32()].prop_map(PositionOrientation::Quaternion3),
        [finite_f32(), finite_f32(), finite_f32(), finite_f32()]
            .prop_map(PositionOrientation::Quaternion),
    ];
    ([finite_f32(), finite_f32(), finite_f32()], orientation).prop_map(
        |(position_mm, orientation)| PositionContent {
            position_mm,
            orientation,
        },
    )
}

fn body() -> impl Strategy<Value = Body> {
    let type_suffix = "[A-Z][A-Z0-9]{0,7}";
    prop_oneof![
        (
            [
                [finite_f32(), finite_f32(), finite_f32()],
                [finite_f32(), finite_f32(), finite_f32()],
                [finite_f32(), finite_f32(), finite_f32()]
            ],
            [finite_f32(), finite_f32(), finite_f32()]
        )
            .prop_map(
                |(rotation, translation_mm)| Body::Transform(TransformContent {
                    rotation,
                    translation_mm
                })
            ),
        position().prop_map(Body::Position),
        position().prop_map(Body::QTrans),
        (any::<u16>(), any::<i64>(), text(20), text(200)).prop_map(
            |(code, subcode, error_name, message)| Body::Status(StatusContent {
                code,
                subcode,
                error_name,
                message
            })
        ),
        (
            prop_oneof![Just(3u16), Just(106u16), any::<u16>()],
            proptest::collection::vec(any::<u8>(), 0..300)
        )
            .prop_map(|(encoding, bytes)| Body::String(StringContent { encoding, bytes })),
        data_type().prop_map(Body::Null),
        (
            prop_oneof![
                Just(QueryKind::Get),
                Just(QueryKind::Start),
                Just(QueryKind::Stop)
            ],
            type_suffix,
            proptest::collection::vec(any::<u8>(), 0..16)
        )
            .prop_map(|(kind, suffix, content)| Body::Query {
                kind,
                suffix,
                content
            }),
        (type_suffix, any::<u8>()).prop_map(|(suffix, status)| Body::Rts { suffix, status }),
        // "X..." collides with no type or prefix handled here.
        (
            "X[A-Z0-9_]{0,11}",
            proptest::collection::vec(any::<u8>(), 0..64)
        )
            .prop_map(|(type_name, content)| Body::Other { type_name, content }),
    ]
}

fn metadata() -> impl Strategy<Value = Vec<MetadataEntry>> {
    proptest::collection::vec(
        (
            text(12),
            any::<u16>(),
            proptest::collection::vec(any::<u8>(), 0..24),
        )
            .prop_map(|(key, encoding, value)| MetadataEntry {
                key,
                encoding,
                value,
            }),
        0..5,
    )
}

fn message() -> impl Strategy<Value = Message> {
    let v3 = (any::<u32>(), metadata());
    (
        any::<bool>(),
        v3,
        text(20).prop_filter("no control characters", |s| {
            !s.chars().any(char::is_control)
        }),
        any::<u64>(),
        body(),
    )
        .prop_map(|(is_v3, (message_id, metadata), device_name, ts, body)| {
            let (version, message_id, metadata) = if is_v3 {
                (HeaderVersion::V2, message_id, metadata)
            } else {
                (HeaderVersion::V1, 0, Vec::new())
            };
            Message {
                version,
                device_name,
                timestamp: Timestamp(ts),
                message_id,
                metadata,
                body,
            }
        })
}

proptest! {
    #![proptest_config(proptest_config(512))]

    /// decode(encode(m)) == m for every message this crate can write, in both header
    /// versions, and the CRC in the header is that of the body.
    #[test]
    fn messages_round_trip(m in message()) {
        let bytes = m.encode().unwrap();
        let (back, used) = Message::decode(&bytes).unwrap();
        prop_assert_eq!(used, bytes.len());
        prop_assert_eq!(&back, &m);
        let header = Header::decode(bytes[..HEADER_SIZE].try_into().unwrap()).unwrap();
        prop_assert_eq!(header.crc, body_crc(&bytes[HEADER_SIZE..]));
        prop_assert_eq!(header.body_size as usize, bytes.len() - HEADER_SIZE);
    }

    /// Every strict prefix of a message is reported as truncated, never decoded.
    #[test]
    fn prefixes_are_truncated(m in message(), cut in 0.0f64..1.0) {
        let bytes = m.encode().unwrap();
        let n = ((bytes.len() as f64) * cut) as usize;
        let truncated = matches!(Message::decode(&bytes[..n]), Err(DecodeError::Truncated { .. }));
        prop_assert!(truncated);
    }

    /// Any bit flipped in the body of a message is caught by the CRC.
    #[test]
    fn body_bit_flips_fail_the_crc(m in message(), at in any::<prop::sample::Index>(), bit in 0u8..8) {
        let mut bytes = m.encode().unwrap();
        prop_assume!(bytes.len() > HEADER_SIZE);
        let i = HEADER_SIZE + at.index(bytes.len() - HEADER_SIZE);
        bytes[i] ^= 1 << bit;
        let crc_failed = matches!(Message::decode(&bytes), Err(DecodeError::Crc { .. }));
        prop_assert!(crc_failed);
    }

    /// Timestamp: nanoseconds -> 32.32 fixed point -> nanoseconds is exact (the fraction's
    /// unit, 2^-32 s = 0.23 ns, is finer than a nanosecond).
    #[test]
    fn timestamps_keep_their_nanoseconds(secs in 0u64..=u64::from(u32::MAX), nanos in 0u32..1_000_000_000) {
        let d = Duration::new(secs, nanos);
        let ts = Timestamp::from_since_epoch(d).unwrap();
        prop_assert_eq!(ts.since_epoch(), d);
        prop_assert_eq!(u64::from(ts.seconds()), secs);
    }

    /// Decoding arbitrary bytes as one message never panics, and claims no more bytes than
    /// it was given.
    #[test]
    fn arbitrary_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..512)) {
        if let Ok((_, used)) = Message::decode(&bytes) {
            prop_assert!(used <= bytes.len());
        }
    }

    /// Arbitrary bytes after a valid header with a matching CRC: any body decodes to a
    /// message or a typed error, for every type and both versions, never a panic.
    #[test]
    fn arbitrary_bodies_under_valid_headers_never_panic(
        v3 in any::<bool>(),
        type_name in prop_oneof![
            Just("TRANSFORM"), Just("POSITION"), Just("QTRANS"), Just("STATUS"),
            Just("STRING"), Just("GET_TRANS"), Just("RTS_TRANS"), Just("XYZ")
        ],
        body in proptest::collection::vec(any::<u8>(), 0..200),
    ) {
        let header = Header {
            version: if v3 { HeaderVersion::V2 } else { HeaderVersion::V1 },
            type_name: type_name.to_owned(),
            device_name: "D".to_owned(),
            timestamp: Timestamp::UNUSED,
            body_size: body.len() as u64,
            crc: body_crc(&body),
        };
        let _ = Message::decode_body(&header, &body, true);
    }
}
