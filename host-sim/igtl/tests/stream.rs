//! The stream decoder on every class of bad input: what it reports and that the stream is in
//! step again afterwards.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use common::proptest_config;
use igtl::content::{StringContent, TransformContent};
use igtl::header::{Header, HEADER_SIZE};
use igtl::stream::{DecoderLimits, Event, MalformedKind, StreamDecoder, StreamError};
use igtl::{Body, HeaderVersion, Message, Timestamp};
use proptest::prelude::*;

fn transform(device: &str, x: f32) -> Message {
    Message {
        timestamp: Timestamp(42),
        ..Message::new(
            device,
            Body::Transform(TransformContent {
                rotation: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
                translation_mm: [x, 0.0, 160.0],
            }),
        )
    }
}

fn string(device: &str, text: &str) -> Message {
    Message::new(device, Body::String(StringContent::text(text)))
}

/// Feeds `bytes` in one push, then ends the stream; returns every event.
fn run(limits: DecoderLimits, bytes: &[u8]) -> Vec<Event> {
    let mut d = StreamDecoder::new(limits);
    d.push(bytes);
    let mut events: Vec<Event> = std::iter::from_fn(|| d.next_event()).collect();
    events.extend(d.finish().map(Event::Malformed));
    events
}

/// "M" for a message (with its device name), or the malformed kind's name.
fn summary(events: &[Event]) -> Vec<String> {
    events
        .iter()
        .map(|e| match e {
            Event::Message(m) => format!("M:{}", m.device_name),
            Event::Malformed(m) => m.kind().name().to_owned(),
        })
        .collect()
}

fn limits() -> DecoderLimits {
    DecoderLimits::default()
}

#[test]
fn garbage_before_between_and_after_messages_is_one_bad_header_per_run() {
    let mut bytes = b"\xde\xad\xbe\xef garbage".to_vec();
    bytes.extend(transform("A", 1.0).encode().unwrap());
    bytes.extend([0u8; 100]); // zeros: version 0 is not a header
    bytes.extend(transform("B", 2.0).encode().unwrap());
    bytes.extend(b"trailing junk");
    assert_eq!(
        summary(&run(limits(), &bytes)),
        ["bad_header", "M:A", "bad_header", "M:B", "bad_header"]
    );
}

#[test]
fn a_truncated_header_or_body_is_reported_when_the_stream_ends() {
    let bytes = transform("A", 1.0).encode().unwrap();
    assert_eq!(summary(&run(limits(), &bytes[..30])), ["truncated"]);
    assert_eq!(
        summary(&run(limits(), &bytes[..HEADER_SIZE + 10])),
        ["truncated"]
    );
    assert_eq!(summary(&run(limits(), &bytes)), ["M:A"]);
}

#[test]
fn a_bad_crc_drops_that_message_only() {
    let mut bytes = transform("A", 1.0).encode().unwrap();
    let n = bytes.len();
    bytes[n - 1] ^= 0x80;
    bytes.extend(transform("B", 2.0).encode().unwrap());
    let events = run(limits(), &bytes);
    assert_eq!(summary(&events), ["bad_crc", "M:B"]);
    let Event::Malformed(m) = &events[0] else {
        unreachable!()
    };
    assert_eq!(m.header.as_ref().unwrap().device_name, "A");
}

#[test]
fn a_body_size_that_lies_larger_swallows_what_follows_then_recovers() {
    // Header A claims 48 + 58 + 48 bytes: it takes B as part of its body, fails the CRC;
    // C is decoded.
    let mut a = transform("A", 1.0).encode().unwrap();
    let lie = (48 + 106) as u64;
    a[42..50].copy_from_slice(&lie.to_be_bytes());
    let mut bytes = a;
    bytes.extend(transform("B", 2.0).encode().unwrap());
    bytes.extend(transform("C", 3.0).encode().unwrap());
    assert_eq!(summary(&run(limits(), &bytes)), ["bad_crc", "M:C"]);
}

#[test]
fn a_body_size_that_lies_smaller_leaves_garbage_then_recovers() {
    let mut a = transform("A", 1.0).encode().unwrap();
    a[42..50].copy_from_slice(&20u64.to_be_bytes());
    let mut bytes = a;
    bytes.extend(transform("B", 2.0).encode().unwrap());
    assert_eq!(
        summary(&run(limits(), &bytes)),
        ["bad_crc", "bad_header", "M:B"]
    );
}

#[test]
fn an_unknown_type_is_a_well_formed_message_of_type_other() {
    let m = Message::new(
        "Img",
        Body::Other {
            type_name: "IMAGE".to_owned(),
            content: vec![7; 100],
        },
    );
    let events = run(limits(), &m.encode().unwrap());
    assert_eq!(events, vec![Event::Message(m)]);
}

#[test]
fn version_3_metadata_sizes_that_lie_drop_the_message() {
    let mut m = transform("A", 1.0);
    m.version = HeaderVersion::V2;
    let mut bytes = m.encode().unwrap();
    // METADATA_SIZE (body bytes 4..8) made 1000: beyond the body. Fix the CRC so that the
    // metadata check is what fails.
    bytes[HEADER_SIZE + 4..HEADER_SIZE + 8].copy_from_slice(&1000u32.to_be_bytes());
    let crc = igtl::crc::body_crc(&bytes[HEADER_SIZE..]);
    bytes[50..58].copy_from_slice(&crc.to_be_bytes());
    bytes.extend(transform("B", 2.0).encode().unwrap());
    assert_eq!(summary(&run(limits(), &bytes)), ["bad_metadata", "M:B"]);
}

#[test]
fn content_of_the_wrong_size_drops_the_message() {
    let m = Message::new(
        "A",
        Body::Other {
            type_name: "TRANSFORM".to_owned(),
            content: vec![0; 40],
        },
    );
    let mut bytes = m.encode().unwrap();
    bytes.extend(transform("B", 2.0).encode().unwrap());
    assert_eq!(summary(&run(limits(), &bytes)), ["bad_content", "M:B"]);
}

#[test]
fn an_oversized_body_is_skipped_without_buffering_and_the_next_message_decoded() {
    let small = DecoderLimits {
        max_body_size: 100,
        max_skip_size: 10_000,
        check_crc: true,
    };
    let big = string("Big", &"x".repeat(5_000)).encode().unwrap();
    let mut d = StreamDecoder::new(small);
    let mut events = Vec::new();
    for chunk in big.chunks(512) {
        d.push(chunk);
        events.extend(std::iter::from_fn(|| d.next_event()));
        assert!(
            d.buffered() <= HEADER_SIZE + 100,
            "{} bytes buffered",
            d.buffered()
        );
    }
    d.push(&transform("B", 2.0).encode().unwrap());
    events.extend(std::iter::from_fn(|| d.next_event()));
    assert_eq!(summary(&events), ["oversized_body", "M:B"]);
    let Event::Malformed(m) = &events[0] else {
        unreachable!()
    };
    assert!(matches!(
        m.error,
        StreamError::Oversized { skipped: true, .. }
    ));
    assert_eq!(d.discarded_bytes(), big.len() as u64);
}

#[test]
fn a_body_size_beyond_the_skip_limit_is_distrusted_and_the_stream_resynchronised() {
    let mut a = transform("A", 1.0).encode().unwrap();
    a[42..50].copy_from_slice(&(1u64 << 40).to_be_bytes());
    let mut bytes = a;
    bytes.extend(transform("B", 2.0).encode().unwrap());
    let events = run(limits(), &bytes);
    // The distrusted header, then its remaining bytes as garbage, then B.
    assert_eq!(summary(&events), ["oversized_body", "M:B"]);
    let Event::Malformed(m) = &events[0] else {
        unreachable!()
    };
    assert!(matches!(
        m.error,
        StreamError::Oversized { skipped: false, .. }
    ));
}

#[test]
fn crc_checking_can_be_turned_off() {
    let mut bytes = transform("A", 1.0).encode().unwrap();
    bytes[50..58].copy_from_slice(&[0; 8]); // a sender that leaves the CRC at 0
    let no_crc = DecoderLimits {
        check_crc: false,
        ..limits()
    };
    assert_eq!(summary(&run(no_crc, &bytes)), ["M:A"]);
    assert_eq!(summary(&run(limits(), &bytes)), ["bad_crc"]);
}

fn messages() -> impl Strategy<Value = Vec<Message>> {
    proptest::collection::vec(
        prop_oneof![
            (
                any::<f32>().prop_filter("finite", |v| v.is_finite()),
                "[A-Za-z]{0,20}"
            )
                .prop_map(|(x, d)| transform(&d, x)),
            ("[ -~]{0,300}", "[A-Za-z]{1,20}").prop_map(|(t, d)| string(&d, &t)),
        ],
        1..6,
    )
}

/// Messages in full, bad input by kind.
fn comparable(events: &[Event]) -> Vec<Result<Message, MalformedKind>> {
    events
        .iter()
        .map(|e| match e {
            Event::Message(m) => Ok(m.clone()),
            Event::Malformed(m) => Err(m.kind()),
        })
        .collect()
}

/// True when a valid header starts in `bytes` at an index below `n`.
fn header_starts(bytes: &[u8], n: usize) -> bool {
    (0..n).any(|i| {
        bytes
            .get(i..i + HEADER_SIZE)
            .and_then(|h| h.first_chunk::<HEADER_SIZE>())
            .is_some_and(|h| Header::decode(h).is_ok())
    })
}

proptest! {
    #![proptest_config(proptest_config(256))]

    /// The events do not depend on how the bytes are split into pushes: the same messages
    /// and the same kinds of bad input in the same order (only a garbage report's
    /// diagnostic, the first bytes seen, depends on what had arrived).
    #[test]
    fn chunking_does_not_change_the_events(
        ms in messages(),
        garbage in proptest::collection::vec(any::<u8>(), 0..64),
        cuts in proptest::collection::vec(any::<prop::sample::Index>(), 0..12),
    ) {
        let mut bytes = garbage.clone();
        for m in &ms {
            bytes.extend(m.encode().unwrap());
        }
        let whole = run(limits(), &bytes);
        let mut points: Vec<usize> = cuts.iter().map(|c| c.index(bytes.len() + 1)).collect();
        points.sort_unstable();
        let mut d = StreamDecoder::new(limits());
        let mut pieces = Vec::new();
        let mut at = 0;
        for p in points.into_iter().chain([bytes.len()]) {
            d.push(&bytes[at..p]);
            at = p;
            pieces.extend(std::iter::from_fn(|| d.next_event()));
        }
        pieces.extend(d.finish().map(Event::Malformed));
        prop_assert_eq!(comparable(&whole), comparable(&pieces));
    }

    /// After random garbage in which no valid header starts, every following message is
    /// decoded, in order, after exactly one bad-header report (none for no garbage).
    #[test]
    fn messages_after_garbage_are_recovered(
        ms in messages(),
        garbage in proptest::collection::vec(any::<u8>(), 0..300),
    ) {
        let mut bytes = garbage.clone();
        for m in &ms {
            bytes.extend(m.encode().unwrap());
        }
        prop_assume!(!header_starts(&bytes, garbage.len()));
        let events = run(limits(), &bytes);
        let got_messages: Vec<&Message> = events
            .iter()
            .filter_map(|e| match e { Event::Message(m) => Some(m), _ => None })
            .collect();
        prop_assert_eq!(got_messages, ms.iter().collect::<Vec<_>>());
        let bad = events.len() - ms.len();
        prop_assert_eq!(bad, usize::from(!garbage.is_empty()));
    }

    /// Random bytes: no panic, at most one event per byte plus the end-of-stream report,
    /// and never more buffered than one message's header and body.
    #[test]
    fn random_bytes_are_bounded_work(
        bytes in proptest::collection::vec(any::<u8>(), 0..4096),
        chunk in 1usize..700,
        max_body in 0u64..512,
    ) {
        let small = DecoderLimits { max_body_size: max_body, max_skip_size: 4 * max_body, check_crc: true };
        let mut d = StreamDecoder::new(small);
        let mut events = 0usize;
        for c in bytes.chunks(chunk) {
            d.push(c);
            while d.next_event().is_some() {
                events += 1;
                prop_assert!(events <= bytes.len());
            }
            prop_assert!(d.buffered() < HEADER_SIZE + max_body as usize);
        }
        events += usize::from(d.finish().is_some());
        prop_assert!(events <= bytes.len() + 1);
    }

    /// A message inside random bytes with valid headers forced in: the decoder still never
    /// panics and keeps within its buffer bound (headers with random body sizes and CRCs).
    #[test]
    fn random_headers_with_lying_sizes_are_bounded_work(
        parts in proptest::collection::vec(
            (any::<bool>(), any::<u64>(), proptest::collection::vec(any::<u8>(), 0..80)), 1..20),
    ) {
        let mut bytes = Vec::new();
        for (v3, size, junk) in &parts {
            let mut h = transform("A", 1.0).encode().unwrap();
            h.truncate(HEADER_SIZE);
            h[1] = if *v3 { 2 } else { 1 };
            h[42..50].copy_from_slice(&(size % 200).to_be_bytes());
            bytes.extend(h);
            bytes.extend(junk);
        }
        let small = DecoderLimits { max_body_size: 150, max_skip_size: 180, check_crc: true };
        let mut d = StreamDecoder::new(small);
        for c in bytes.chunks(37) {
            d.push(c);
            while d.next_event().is_some() {}
            prop_assert!(d.buffered() < HEADER_SIZE + 150);
        }
        let _ = d.finish();
    }
}

#[test]
fn every_malformed_kind_has_a_distinct_name() {
    let names: std::collections::BTreeSet<_> =
        MalformedKind::ALL.iter().map(|k| k.name()).collect();
    assert_eq!(names.len(), MalformedKind::ALL.len());
}
