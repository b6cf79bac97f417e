#![allow(clippy::unwrap_used, clippy::expect_used)]
//! The real spacenavd client against a fake daemon: this test's own code speaks the
//! daemon's side on a Unix socket in a temporary directory (protocol 1 with requests,
//! an old protocol-0 daemon that never answers the handshake, and one that sends an event
//! before reading it). The daemon side is driven step by step over a channel, so each
//! state the client reports is checked after exactly the events sent so far.
#![cfg(target_endian = "little")]

use masters::rate::{RateMapping, RateMappingConfig};
use masters::spacenav::{SpaceNavMaster, SpnavDeviceInfo, SpnavOptions, DEV_REMOVE, REQ_TAG};
use masters::{DeviceError, Master, MasterInput, MasterSample};
use std::io::{Read, Write};
use std::os::unix::net::{UnixListener, UnixStream};
use std::sync::mpsc;
use std::thread;
use std::time::{Duration, Instant};

fn packet(words: [i32; 8]) -> Vec<u8> {
    words.iter().flat_map(|w| w.to_le_bytes()).collect()
}

fn read_words<const N: usize>(s: &mut UnixStream) -> [i32; N] {
    let mut b = vec![0u8; 4 * N];
    s.read_exact(&mut b).unwrap();
    let mut w = [0i32; N];
    for (i, c) in b.chunks_exact(4).enumerate() {
        w[i] = i32::from_le_bytes(c.try_into().unwrap());
    }
    w
}

fn mapping() -> RateMapping {
    RateMapping::new(RateMappingConfig::spacemouse_spacenavd()).unwrap()
}

/// Polls until `done` holds for a sample (at most 2 s); the last sample.
fn poll_until(m: &mut SpaceNavMaster, done: impl Fn(&MasterSample) -> bool) -> MasterSample {
    let end = Instant::now() + Duration::from_secs(2);
    loop {
        let s = m.poll(0.0).unwrap().unwrap();
        if done(&s) {
            return s;
        }
        assert!(
            Instant::now() < end,
            "condition not reached; last sample {s:?}"
        );
        thread::sleep(Duration::from_millis(2));
    }
}

/// Protocol 1: handshake, client name, the four device queries (with an event arriving
/// in the middle of a request, which must be kept), then motion and buttons step by
/// step, a device removal (everything released) and the daemon closing (an error).
#[test]
fn protocol_1_daemon() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("spnav.sock");
    let listener = UnixListener::bind(&path).unwrap();
    let (step_tx, step_rx) = mpsc::channel::<()>();
    let daemon = thread::spawn(move || {
        let (mut s, _) = listener.accept().unwrap();
        let [hs] = read_words::<1>(&mut s);
        assert_eq!(hs, REQ_TAG | 0x5500 | 1, "handshake word");
        s.write_all(&(REQ_TAG | 0x5500 | 1).to_le_bytes()).unwrap();
        let name = read_words::<8>(&mut s);
        assert_eq!(name[0], REQ_TAG | 0x1000, "set name");
        let name_bytes: Vec<u8> = name[1..7].iter().flat_map(|w| w.to_le_bytes()).collect();
        let len = name[7] as usize;
        assert_eq!(&name_bytes[..len], b"fake-test");
        let mut answered = Vec::new();
        for _ in 0..4 {
            let q = read_words::<8>(&mut s);
            let req = q[0] & 0xffff;
            answered.push(req);
            let data = match req {
                0x2002 => {
                    // an event overtakes the response
                    s.write_all(&packet([0, 1, 2, 3, 4, 5, 6, 8])).unwrap();
                    [6, 0, 0, 0, 0, 0, 0]
                }
                0x2003 => [2, 0, 0, 0, 0, 0, 0],
                0x2004 => [0x046d, 0xc626, 0, 0, 0, 0, 0],
                0x2005 => [0x206, 0, 0, 0, 0, 0, 0],
                other => panic!("unexpected request {other:#x}"),
            };
            let mut w = [0i32; 8];
            w[0] = q[0];
            w[1..].copy_from_slice(&data);
            s.write_all(&packet(w)).unwrap();
        }
        assert_eq!(answered, [0x2002, 0x2003, 0x2004, 0x2005]);
        let steps: Vec<Vec<[i32; 8]>> = vec![
            // full deflection along the daemon's z (away from the user), operator present (button 1)
            vec![[0, 0, 0, 350, 0, 0, 0, 8], [1, 1, 1, 0, 0, 0, 0, 0]],
            // clutch (button 0)
            vec![[1, 0, 1, 0, 0, 0, 0, 0]],
            // device removed
            vec![[3, DEV_REMOVE, 0, 0x206, 0x046d, 0xc626, 0, 0]],
        ];
        for batch in steps {
            step_rx.recv().unwrap();
            let bytes: Vec<u8> = batch.into_iter().flat_map(packet).collect();
            // written in two pieces to split a packet across reads
            let (a, b) = bytes.split_at(bytes.len() / 2 + 3);
            s.write_all(a).unwrap();
            s.flush().unwrap();
            thread::sleep(Duration::from_millis(5));
            s.write_all(b).unwrap();
        }
        step_rx.recv().unwrap();
        // closing the socket ends the session
    });
    let options = SpnavOptions {
        client_name: "fake-test".into(),
        ..SpnavOptions::default()
    };
    let mut m = SpaceNavMaster::connect(&path, &options, mapping()).unwrap();
    assert_eq!(m.client().protocol(), 1);
    assert_eq!(
        m.client().device(),
        Some(SpnavDeviceInfo {
            axes: 6,
            buttons: 2,
            usb_id: Some((0x046d, 0xc626)),
            device_type: Some(0x206),
        })
    );
    // The motion event that overtook a response was kept.
    let s = poll_until(&mut m, |s| s.deflection.is_some_and(|d| d[0] == 1.0));
    assert_eq!(s.deflection, Some([1.0, 2.0, 3.0, 4.0, 5.0, 6.0]));
    step_tx.send(()).unwrap();
    let s = poll_until(&mut m, |s| s.buttons.operator_present);
    let MasterInput::Twist(t) = s.input else {
        panic!("rate master")
    };
    // the daemon's z is away from the user, as the robot's y: +10 mm/s.
    assert!((t.linear_m_s.y - 0.010).abs() < 1e-12, "{t:?}");
    assert_eq!(t.linear_m_s.x, 0.0);
    assert!(!s.buttons.clutch);
    step_tx.send(()).unwrap();
    let s = poll_until(&mut m, |s| s.buttons.clutch);
    assert!(s.buttons.operator_present);
    step_tx.send(()).unwrap();
    let s = poll_until(&mut m, |s| !s.buttons.operator_present);
    assert_eq!(s.deflection, Some([0.0; 6]), "released on removal");
    assert!(!s.buttons.clutch);
    step_tx.send(()).unwrap();
    daemon.join().unwrap();
    let end = Instant::now() + Duration::from_secs(2);
    let err = loop {
        match m.poll(0.0) {
            Err(e) => break e,
            Ok(_) => {
                assert!(Instant::now() < end, "no error after the daemon closed");
                thread::sleep(Duration::from_millis(2));
            }
        }
    };
    assert!(matches!(err, DeviceError::Disconnected { .. }), "{err}");
    let c = m.counters();
    assert_eq!((c.motion, c.buttons, c.other_events), (2, 2, 1));
}

/// An old protocol-0 daemon reads the handshake word as a (NaN) sensitivity and never
/// answers: the client falls back to protocol 0 after its timeout and sets the
/// sensitivity back to 1.0.
#[test]
fn protocol_0_daemon_without_answer() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("spnav.sock");
    let listener = UnixListener::bind(&path).unwrap();
    let daemon = thread::spawn(move || {
        let (mut s, _) = listener.accept().unwrap();
        let [hs] = read_words::<1>(&mut s);
        assert!(
            f32::from_bits(hs as u32).is_nan(),
            "the handshake word is a NaN float"
        );
        let [sens] = read_words::<1>(&mut s);
        assert_eq!(f32::from_bits(sens as u32), 1.0);
        s.write_all(&packet([0, -350, 0, 0, 0, 0, 0, 8])).unwrap();
        s.write_all(&packet([1, 1, 0, 0, 0, 0, 0, 0])).unwrap();
        thread::sleep(Duration::from_millis(300));
    });
    let options = SpnavOptions {
        handshake_timeout: Duration::from_millis(100),
        ..SpnavOptions::default()
    };
    let mut m = SpaceNavMaster::connect(&path, &options, mapping()).unwrap();
    assert_eq!(m.client().protocol(), 0);
    assert_eq!(m.client().device(), None);
    let s = poll_until(&mut m, |s| s.buttons.operator_present);
    let MasterInput::Twist(t) = s.input else {
        panic!("rate master")
    };
    assert!((t.linear_m_s.x + 0.010).abs() < 1e-12);
    daemon.join().unwrap();
}

/// An old daemon that sends an event before reading the handshake: the first 4 bytes
/// the client reads are not a handshake answer but the start of an event, which must
/// still be decoded whole.
#[test]
fn protocol_0_daemon_sending_first() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("spnav.sock");
    let listener = UnixListener::bind(&path).unwrap();
    let daemon = thread::spawn(move || {
        let (mut s, _) = listener.accept().unwrap();
        s.write_all(&packet([0, 0, 175, 0, 0, 0, 0, 8])).unwrap();
        let [_hs, sens] = read_words::<2>(&mut s);
        assert_eq!(f32::from_bits(sens as u32), 1.0);
        thread::sleep(Duration::from_millis(300));
    });
    let mut m = SpaceNavMaster::connect(&path, &SpnavOptions::default(), mapping()).unwrap();
    assert_eq!(m.client().protocol(), 0);
    let s = poll_until(&mut m, |s| s.deflection.is_some_and(|d| d[1] != 0.0));
    assert_eq!(s.deflection, Some([0.0, 175.0, 0.0, 0.0, 0.0, 0.0]));
    daemon.join().unwrap();
}
