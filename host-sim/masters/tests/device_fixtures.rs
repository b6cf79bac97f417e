#![allow(clippy::unwrap_used, clippy::expect_used)]
//! Recorded device streams replayed through the real parsers, byte for byte: the
//! fixtures (built by `tests/fixtures/make_fixtures.py` at test time from literal values, which
//! it also writes to `expected.json`) must decode to exactly those values, malformed
//! input included; and the same bytes fed in pieces of any size decode the same.
#![cfg(target_endian = "little")]

mod common;

use common::{expected, fixture, ints};
use masters::evdev::{EvdevDecoder, EvdevMaster, InputEvent, Report, INPUT_EVENT_BYTES};
use masters::rate::{RateMapping, RateMappingConfig};
use masters::spacenav::{decode_packet, PacketReader, SpnavEvent, SpnavPacket, PACKET_BYTES};
use masters::udp::{DatagramError, DatagramGate, GateConfig, Verdict};
use masters::{Master, MasterInput};
use serde_json::Value;

fn check_spnav_packet(got: &SpnavPacket, want: &Value) {
    if let Some(m) = want.get("motion") {
        let m = ints(m);
        let period = want["period_ms"].as_i64().unwrap();
        match got {
            SpnavPacket::Event(SpnavEvent::Motion { axes, period_ms }) => {
                assert_eq!(axes.iter().map(|a| i64::from(*a)).collect::<Vec<_>>(), m);
                assert_eq!(i64::from(*period_ms), period);
            }
            other => panic!("expected motion {m:?}, got {other:?}"),
        }
    } else if let Some(b) = want.get("button") {
        let pressed_want = want["pressed"].as_bool().unwrap();
        assert_eq!(
            *got,
            SpnavPacket::Event(SpnavEvent::Button {
                index: b.as_i64().unwrap() as i32,
                pressed: pressed_want
            })
        );
    } else if let Some(u) = want.get("unknown") {
        assert_eq!(
            *got,
            SpnavPacket::Unknown {
                word0: u.as_i64().unwrap() as i32
            }
        );
    } else if let Some(r) = want.get("response") {
        let data = ints(&want["data"]);
        match got {
            SpnavPacket::Response { request, data: d } => {
                assert_eq!(i64::from(*request), r.as_i64().unwrap());
                assert_eq!(d.iter().map(|a| i64::from(*a)).collect::<Vec<_>>(), data);
            }
            other => panic!("expected response {r}, got {other:?}"),
        }
    } else if let Some(d) = want.get("device") {
        let i = |k: &str| d[k].as_i64().unwrap() as i32;
        assert_eq!(
            *got,
            SpnavPacket::Event(SpnavEvent::Device {
                op: i("op"),
                id: i("id"),
                device_type: i("type"),
                usb_vendor: i("vendor"),
                usb_product: i("product"),
            })
        );
    } else {
        panic!("unknown expectation {want}");
    }
}

/// Reads every packet out of `bytes` fed in pieces of `piece` bytes.
fn spnav_packets(bytes: &[u8], piece: usize) -> (Vec<SpnavPacket>, usize) {
    let mut r = PacketReader::default();
    let mut out = Vec::new();
    for chunk in bytes.chunks(piece) {
        r.push(chunk);
        while let Some(p) = r.next_packet() {
            out.push(p);
        }
    }
    (out, r.pending_bytes())
}

/// spacenavd protocol 0: motion, press, release (both press forms), an unknown packet,
/// a cut packet left pending; the same whatever the read sizes.
#[test]
fn spacenavd_protocol_0_stream() {
    let want = &expected()["spacenavd_v0"];
    let bytes = fixture("spacenavd_v0.bin");
    let packets = want["packets"].as_array().unwrap();
    for piece in [1, 3, 7, 32, 33, 1000] {
        let (got, pending) = spnav_packets(&bytes, piece);
        assert_eq!(got.len(), packets.len(), "piece {piece}");
        for (g, w) in got.iter().zip(packets) {
            check_spnav_packet(g, w);
        }
        assert_eq!(pending as u64, want["trailing_bytes"].as_u64().unwrap());
    }
}

/// spacenavd protocol 1: the handshake answer, then responses and events sharing the
/// stream, told apart by word 0.
#[test]
fn spacenavd_protocol_1_stream() {
    let want = &expected()["spacenavd_v1"];
    let bytes = fixture("spacenavd_v1.bin");
    let reply = i32::from_le_bytes(bytes[..4].try_into().unwrap());
    assert_eq!(i64::from(reply), want["handshake_reply"].as_i64().unwrap());
    assert_eq!(reply & 0xff, 1, "protocol version 1");
    let (got, pending) = spnav_packets(&bytes[4..], 5);
    assert_eq!(pending, 0);
    let packets = want["packets"].as_array().unwrap();
    assert_eq!(got.len(), packets.len());
    for (g, w) in got.iter().zip(packets) {
        check_spnav_packet(g, w);
    }
    // A single packet decodes on its own too.
    let first: [u8; PACKET_BYTES] = bytes[4..4 + PACKET_BYTES].try_into().unwrap();
    check_spnav_packet(&decode_packet(&first), &packets[0]);
}

fn check_reports(got: &[Report], want: &Value) {
    let want = want.as_array().unwrap();
    assert_eq!(got.len(), want.len(), "{got:?}");
    for (g, w) in got.iter().zip(want) {
        let axes: Vec<i64> = g.state.axes.iter().map(|a| *a as i64).collect();
        assert_eq!(axes, ints(&w["axes"]));
        assert_eq!(i64::from(g.state.buttons), w["buttons"].as_i64().unwrap());
        assert_eq!(g.time_us, w["time_us"].as_u64());
    }
}

/// evdev with EV_REL axes: the 24-byte events decode field by field, each SYN_REPORT
/// applies its report, axes keep their last value, EV_MSC is skipped, autorepeat (2)
/// keeps a button pressed.
#[test]
fn evdev_rel_stream() {
    let want = &expected()["evdev_rel"];
    let bytes = fixture("evdev_rel.bin");
    assert_eq!(bytes.len() % INPUT_EVENT_BYTES, 0);
    let first = InputEvent::from_bytes(bytes[..24].try_into().unwrap());
    assert_eq!(
        first,
        InputEvent {
            sec: 1_700_000_000,
            usec: 1000,
            kind: 2,
            code: 0,
            value: 12
        }
    );
    assert_eq!(first.to_bytes().as_slice(), &bytes[..24]);
    for piece in [1, 5, 24, 25, 4096] {
        let mut d = EvdevDecoder::new();
        let mut reports = Vec::new();
        for c in bytes.chunks(piece) {
            d.push_bytes(c, &mut reports);
        }
        check_reports(&reports, &want["reports"]);
        assert_eq!(d.counters().events, want["events"].as_u64().unwrap());
        assert_eq!(d.counters().other_types, 2, "two EV_MSC");
    }
}

/// evdev with EV_ABS axes and trouble: SYN_DROPPED releases the state and discards up to
/// the next SYN_REPORT; an unused axis code and a key outside the button range are
/// skipped and counted; a key value 5 is malformed; a cut event stays pending.
#[test]
fn evdev_abs_stream_with_drop_and_malformed() {
    let want = &expected()["evdev_abs"];
    let bytes = fixture("evdev_abs.bin");
    assert_eq!(bytes.len() % INPUT_EVENT_BYTES, 10);
    let mut d = EvdevDecoder::new();
    let mut reports = Vec::new();
    d.push_bytes(&bytes, &mut reports);
    check_reports(&reports, &want["reports"]);
    let c = d.counters();
    let wc = &want["counters"];
    let n = |k: &str| wc[k].as_u64().unwrap();
    assert_eq!(c.events, n("events"));
    assert_eq!(c.reports, n("reports"));
    assert_eq!(c.dropped, n("dropped"));
    assert_eq!(c.discarded, n("discarded"));
    assert_eq!(c.unused_codes, n("unused_codes"));
    assert_eq!(c.malformed, n("malformed"));
}

/// The evdev master reads the fixture file through its real open/read path (a regular
/// file reads like a device that has queued these events) and maps the last state to a
/// twist and buttons: the last report of evdev_rel.bin has x = 1 count (inside the
/// deadzone: zero twist) and no button.
#[test]
fn evdev_master_replays_a_fixture_file() {
    let path = common::fixtures_dir().join("evdev_rel.bin");
    let mapping = RateMapping::new(RateMappingConfig::spacemouse_evdev()).unwrap();
    let mut m = EvdevMaster::open(&path, mapping).unwrap();
    let s = m.poll(1.0).unwrap().unwrap();
    assert_eq!(s.deflection, Some([1.0, -34.0, 56.0, -7.0, 8.0, -9.0]));
    assert_eq!(s.device_time_us, Some(1_700_000_000_049_000));
    assert!(!s.buttons.clutch && !s.buttons.operator_present);
    let MasterInput::Twist(t) = s.input else {
        panic!("rate master")
    };
    // y = -34 and z = 56 counts are 0.097 and 0.16 of full scale, outside the 0.08
    // deadzone; x = 1 count is inside it.
    assert_eq!(t.linear_m_s.x, 0.0);
    assert!(
        t.linear_m_s.y > 0.0,
        "device y is towards the user: robot -y"
    );
    assert!(t.linear_m_s.z < 0.0, "device z is down: robot -z");
    assert_eq!(m.counters().reports, 7);
}

fn f32s(v: &Value) -> Vec<f32> {
    v.as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap() as f32)
        .collect()
}

/// UDP datagrams as received, with their arrival times: each verdict as expected
/// (accepted with its fields, duplicate, out of order, stale, each malformed kind,
/// another session while the current one is live, a sender restart, a sequence wrap),
/// and the counters add up.
#[test]
fn udp_datagram_verdicts() {
    let want = &expected()["udp_datagrams"];
    let bytes = fixture("udp_datagrams.bin");
    let mut gate = DatagramGate::new(GateConfig {
        max_age_s: want["max_age_s"].as_f64().unwrap(),
        session_switch_s: want["session_switch_s"].as_f64().unwrap(),
        ..GateConfig::default()
    });
    let verdicts = want["verdicts"].as_array().unwrap();
    let mut at = 0;
    let mut seen = 0;
    while at < bytes.len() {
        let t = f64::from_le_bytes(bytes[at..at + 8].try_into().unwrap());
        let n = usize::from(u16::from_le_bytes(
            bytes[at + 8..at + 10].try_into().unwrap(),
        ));
        let d = &bytes[at + 10..at + 10 + n];
        at += 10 + n;
        let w = &verdicts[seen];
        seen += 1;
        let v = gate.judge(d, t);
        match (v, w.as_object().unwrap().keys().next().unwrap().as_str()) {
            (Verdict::Accepted(got), "accepted") => {
                let a = &w["accepted"];
                assert_eq!(u64::from(got.sequence), a["seq"].as_u64().unwrap());
                assert_eq!(got.position_mm.to_vec(), f32s(&a["pos_mm"]));
                assert_eq!(got.orientation_wxyz.to_vec(), f32s(&a["quat"]));
                assert_eq!(u64::from(got.buttons), a["buttons"].as_u64().unwrap());
                let tracking = a.get("tracking").and_then(Value::as_bool).unwrap_or(true);
                assert_eq!(
                    got.operator_buttons().operator_present,
                    tracking && got.buttons & 2 != 0
                );
                let p = got.pose();
                assert!((p.position_m.x * 1e3 - f64::from(got.position_mm[0])).abs() < 1e-9);
            }
            (Verdict::Duplicate(s), "duplicate") => {
                assert_eq!(u64::from(s), w["duplicate"].as_u64().unwrap())
            }
            (Verdict::OutOfOrder { sequence, .. }, "out_of_order") => {
                assert_eq!(u64::from(sequence), w["out_of_order"].as_u64().unwrap())
            }
            (Verdict::Stale { age_s }, "stale") => assert!(age_s > 0.05 && age_s < 0.1, "{age_s}"),
            (Verdict::OtherSession { session, .. }, "other_session") => {
                assert_eq!(u64::from(session), w["other_session"].as_u64().unwrap())
            }
            (Verdict::Malformed(e), "malformed") => {
                let kind = match e {
                    DatagramError::WrongSize(_) => "wrong_size",
                    DatagramError::BadMagic(_) => "bad_magic",
                    DatagramError::UnsupportedVersion(_) => "unsupported_version",
                    DatagramError::LengthMismatch { .. } => "length_mismatch",
                    DatagramError::ReservedFlags(_) => "reserved_flags",
                    DatagramError::NonFinite(_) => "non_finite",
                    DatagramError::NotUnitQuaternion(_) => "not_unit_quaternion",
                };
                assert_eq!(kind, w["malformed"].as_str().unwrap());
            }
            (v, k) => panic!("datagram {seen}: expected {k}, got {v:?}"),
        }
    }
    assert_eq!(seen, verdicts.len());
    let c = gate.counts();
    assert_eq!(gate.accepted(), 6);
    assert_eq!((c.duplicate, c.out_of_order, c.stale), (1, 1, 1));
    assert_eq!(
        (
            c.wrong_size,
            c.bad_magic,
            c.unsupported_version,
            c.length_mismatch,
            c.reserved_flags,
            c.non_finite,
            c.not_unit_quaternion
        ),
        (1, 1, 1, 1, 1, 1, 1)
    );
    assert_eq!(c.other_session, 1);
    assert_eq!(c.total(), 11);
    assert_eq!(gate.sessions(), 3);
}
