#![allow(clippy::unwrap_used, clippy::expect_used)]
//! The UDP pose master on a real loopback socket: datagrams from a sender socket are
//! received, judged and turned into pose samples; a foreign sender is counted and
//! ignored when a peer is configured. (All traffic stays on 127.0.0.1.)

use masters::udp::{GateConfig, PoseDatagram, UdpPoseMaster, FLAG_TRACKING_VALID};
use masters::{Master, MasterInput};
use std::net::UdpSocket;
use std::time::{Duration, Instant};

fn datagram(sequence: u32, x_mm: f32, buttons: u32) -> [u8; 56] {
    PoseDatagram {
        flags: FLAG_TRACKING_VALID,
        session: 7,
        sequence,
        timestamp_us: 1_000_000 + u64::from(sequence) * 10_000,
        position_mm: [x_mm, 0.0, 100.0],
        orientation_wxyz: [1.0, 0.0, 0.0, 0.0],
        buttons,
    }
    .encode()
}

/// Polls until a sample arrives (at most 2 s).
fn next_sample(m: &mut UdpPoseMaster, now_s: f64) -> masters::MasterSample {
    let end = Instant::now() + Duration::from_secs(2);
    loop {
        if let Some(s) = m.poll(now_s).unwrap() {
            return s;
        }
        assert!(Instant::now() < end, "no datagram arrived");
        std::thread::sleep(Duration::from_millis(1));
    }
}

#[test]
fn loopback_stream() {
    let sender = UdpSocket::bind("127.0.0.1:0").unwrap();
    let stranger = UdpSocket::bind("127.0.0.1:0").unwrap();
    let mut m = UdpPoseMaster::bind(
        "127.0.0.1:0".parse().unwrap(),
        Some(sender.local_addr().unwrap()),
        GateConfig::default(),
    )
    .unwrap();
    let to = m.local_addr().unwrap();
    assert_eq!(m.poll(0.0).unwrap(), None, "nothing yet");
    sender.send_to(&datagram(1, 12.5, 0b10), to).unwrap();
    let s = next_sample(&mut m, 0.5);
    let MasterInput::Pose(p) = s.input else {
        panic!("position master")
    };
    assert!((p.position_m.x - 0.0125).abs() < 1e-9);
    assert!(s.buttons.operator_present && !s.buttons.clutch);
    assert_eq!(s.device_time_us, Some(1_010_000));
    assert_eq!(s.t_s, 0.5);
    // a stranger's datagram, a duplicate and a newer one in one burst: the newest wins
    stranger.send_to(&datagram(9, 99.0, 0b10), to).unwrap();
    sender.send_to(&datagram(1, 12.5, 0b10), to).unwrap();
    sender.send_to(&datagram(2, 13.0, 0b11), to).unwrap();
    let end = Instant::now() + Duration::from_secs(2);
    let s = loop {
        if let Some(s) = m.poll(0.51).unwrap() {
            if m.gate().counts().wrong_peer == 1 && m.gate().counts().duplicate == 1 {
                break s;
            }
        }
        assert!(
            Instant::now() < end,
            "burst not received: {:?}",
            m.gate().counts()
        );
        std::thread::sleep(Duration::from_millis(1));
    };
    let MasterInput::Pose(p) = s.input else {
        panic!("position master")
    };
    assert!((p.position_m.x - 0.013).abs() < 1e-9);
    assert!(s.buttons.clutch);
    assert_eq!(m.gate().accepted(), 2);
}
