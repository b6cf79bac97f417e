//! The server over loopback TCP, with a client made of this crate's codec and the simulated
//! robot: targets, refusals, queries, streaming, bad input, versions, registration and
//! several clients.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use igtl::content::{PositionContent, PositionOrientation, StatusContent};
use igtl::fake_robot::{FakeRobot, FakeRobotConfig};
use igtl::metadata::MetadataEntry;
use igtl::pose::{pose_from_transform, transform_from_pose};
use igtl::stream::{DecoderLimits, Event, StreamDecoder};
use igtl::{
    Body, Counters, DataType, HeaderVersion, MalformedKind, Message, QueryKind, Registration,
    Server, ServerConfig, StatusCode, Timestamp,
};
use kinematics_core::pose::{rotation_angle, Pose};
use nalgebra::{Rotation3, Vector3};
use std::io::{ErrorKind, Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

const WAIT: Duration = Duration::from_secs(3);

struct Harness {
    addr: SocketAddr,
    robot: Arc<Mutex<FakeRobot>>,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<Counters>>,
}

impl Harness {
    /// A server with `config` in front of a fast fake robot (1 m/s, 10 rad/s), polled every
    /// 200 us on a thread.
    fn start(config: ServerConfig) -> Self {
        let mut server = Server::bind_with("127.0.0.1:0", config).unwrap();
        let addr = server.local_addr();
        let robot = Arc::new(Mutex::new(FakeRobot::new(FakeRobotConfig {
            speed: 1.0,
            angular_speed: 10.0,
            ..FakeRobotConfig::default()
        })));
        let stop = Arc::new(AtomicBool::new(false));
        let (r, s) = (robot.clone(), stop.clone());
        let thread = std::thread::spawn(move || {
            let mut last = Instant::now();
            while !s.load(Ordering::Relaxed) {
                let now = Instant::now();
                let mut robot = r.lock().unwrap();
                robot.step(now - last);
                last = now;
                server.poll(&mut *robot);
                drop(robot);
                std::thread::sleep(Duration::from_micros(200));
            }
            server.counters().clone()
        });
        Harness {
            addr,
            robot,
            stop,
            thread: Some(thread),
        }
    }

    fn counters(mut self) -> Counters {
        self.stop.store(true, Ordering::Relaxed);
        self.thread.take().unwrap().join().unwrap()
    }
}

impl Drop for Harness {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

struct Client {
    stream: TcpStream,
    decoder: StreamDecoder,
    version: HeaderVersion,
}

impl Client {
    fn connect(addr: SocketAddr) -> Self {
        let stream = TcpStream::connect(addr).unwrap();
        stream
            .set_read_timeout(Some(Duration::from_millis(20)))
            .unwrap();
        Client {
            stream,
            decoder: StreamDecoder::new(DecoderLimits::default()),
            version: HeaderVersion::V1,
        }
    }

    fn send(&mut self, device: &str, body: Body) {
        let m = Message {
            version: self.version,
            timestamp: Timestamp::now(),
            ..Message::new(device, body)
        };
        self.send_message(&m);
    }

    fn send_message(&mut self, m: &Message) {
        self.stream.write_all(&m.encode().unwrap()).unwrap();
    }

    fn send_raw(&mut self, bytes: &[u8]) {
        self.stream.write_all(bytes).unwrap();
    }

    /// The next message for which `want` is true, within `timeout`; `None` on timeout or
    /// when the server closes the connection.
    fn wait_for(
        &mut self,
        timeout: Duration,
        mut want: impl FnMut(&Message) -> bool,
    ) -> Option<Message> {
        let end = Instant::now() + timeout;
        let mut buf = [0u8; 4096];
        loop {
            while let Some(e) = self.decoder.next_event() {
                match e {
                    Event::Message(m) if want(&m) => return Some(m),
                    Event::Message(_) => {}
                    Event::Malformed(m) => panic!("server sent bad bytes: {:?}", m.error),
                }
            }
            if Instant::now() > end {
                return None;
            }
            match self.stream.read(&mut buf) {
                Ok(0) => return None,
                Ok(n) => self.decoder.push(&buf[..n]),
                Err(e) if matches!(e.kind(), ErrorKind::WouldBlock | ErrorKind::TimedOut) => {}
                Err(e) if e.kind() == ErrorKind::ConnectionReset => return None,
                Err(e) => panic!("read: {e}"),
            }
        }
    }

    fn expect(&mut self, what: &str, want: impl FnMut(&Message) -> bool) -> Message {
        self.wait_for(WAIT, want)
            .unwrap_or_else(|| panic!("no {what} within {WAIT:?}"))
    }

    fn query(&mut self, kind: QueryKind, suffix: &str, device: &str) {
        self.send(
            device,
            Body::Query {
                kind,
                suffix: suffix.to_owned(),
                content: vec![],
            },
        );
    }

    fn counters_json(&mut self) -> String {
        self.query(QueryKind::Get, "STRING", "Counters");
        let m = self.expect("counters", |m| {
            m.device_name == "Counters" && matches!(m.body, Body::String(_))
        });
        let Body::String(s) = m.body else {
            unreachable!()
        };
        s.as_text().unwrap().to_owned()
    }
}

fn pose_mm(x: f64, y: f64, z: f64, r: Rotation3<f64>) -> Pose<f64> {
    Pose {
        t: Vector3::new(x, y, z) / 1000.0,
        r,
    }
}

fn target(p: &Pose<f64>) -> Body {
    Body::Transform(transform_from_pose(p))
}

fn status_of(m: &Message) -> &StatusContent {
    match &m.body {
        Body::Status(s) => s,
        other => panic!("not a STATUS: {other:?}"),
    }
}

/// True when `m` is a TRANSFORM from `device` within 1 um and 1e-5 rad of `p`.
fn transform_near(m: &Message, device: &str, p: &Pose<f64>) -> bool {
    match &m.body {
        Body::Transform(t) if m.device_name == device => {
            let q = pose_from_transform(t).unwrap();
            (q.t - p.t).norm() < 1e-6 && rotation_angle(&(q.r.inverse() * p.r)) < 1e-5
        }
        _ => false,
    }
}

#[test]
fn an_accepted_target_moves_the_robot_and_its_pose_streams_back() {
    let h = Harness::start(ServerConfig::default());
    let mut c = Client::connect(h.addr);
    // Pushed on connection: pose, STATUS and STRING, header version 1.
    let first = c.expect("pose", |m| m.device_name == "Robot");
    assert_eq!(first.version, HeaderVersion::V1);
    let state = c.expect("state STATUS", |m| m.device_name == "RobotStatus");
    assert_eq!(status_of(&state).code, StatusCode::Ok.wire());

    let goal = pose_mm(
        10.0,
        -5.0,
        165.0,
        Rotation3::from_euler_angles(0.1, -0.05, 0.3),
    );
    c.send("Target", target(&goal));
    c.expect("the pose at the target", |m| {
        transform_near(m, "Robot", &goal)
    });
    let robot_target = *h.robot.lock().unwrap().target().unwrap();
    assert!((robot_target.t - goal.t).norm() < 1e-6);
    let counters = h.counters();
    assert_eq!(counters.targets_accepted, 1);
    assert_eq!(counters.received_of("TRANSFORM"), 1);
    assert!(counters.sent_of("TRANSFORM") >= 2);
}

#[test]
fn a_refused_target_is_answered_with_a_status_code_and_the_reason() {
    let h = Harness::start(ServerConfig::default());
    let mut c = Client::connect(h.addr);
    let far = pose_mm(0.0, 0.0, 200.0, Rotation3::identity());
    c.send("Target", target(&far));
    let m = c.expect("refusal", |m| m.device_name == "Target");
    let s = status_of(&m);
    assert_eq!(s.code, StatusCode::Overflow.wire());
    assert_eq!(s.error_name, "Unreachable");
    assert!(s.message.contains("z_mm=200.000"), "{}", s.message);
    assert!(h.robot.lock().unwrap().target().is_none());
    let counters = h.counters();
    assert_eq!(counters.targets_refused, 1);
    assert_eq!(counters.targets_accepted, 0);
}

#[test]
fn a_version_3_client_is_answered_in_version_3_with_its_message_id() {
    let h = Harness::start(ServerConfig::default());
    let mut c = Client::connect(h.addr);
    c.version = HeaderVersion::V2;
    let get = Message {
        version: HeaderVersion::V2,
        message_id: 1234,
        metadata: vec![MetadataEntry::text("Origin", "test")],
        ..Message::new(
            "Robot",
            Body::Query {
                kind: QueryKind::Get,
                suffix: "TRANS".to_owned(),
                content: vec![],
            },
        )
    };
    c.send_message(&get);
    let reply = c.expect("GET_TRANS reply", |m| m.message_id == 1234);
    assert_eq!(reply.version, HeaderVersion::V2);
    assert!(matches!(reply.body, Body::Transform(_)));
    // The stream follows the client's version from now on.
    c.expect("a version-3 pushed pose", |m| {
        m.device_name == "Robot" && m.version == HeaderVersion::V2 && m.message_id == 0
    });
    // A refused version-3 target: STATUS in version 3 with the target's message id.
    let far = Message {
        version: HeaderVersion::V2,
        message_id: 77,
        ..Message::new(
            "Target",
            target(&pose_mm(50.0, 0.0, 160.0, Rotation3::identity())),
        )
    };
    c.send_message(&far);
    let refusal = c.expect("refusal", |m| m.device_name == "Target");
    assert_eq!(refusal.version, HeaderVersion::V2);
    assert_eq!(refusal.message_id, 77);
}

#[test]
fn garbage_leaves_the_connection_open_and_is_counted() {
    let h = Harness::start(ServerConfig::default());
    let mut c = Client::connect(h.addr);
    let garbage: Vec<u8> = (0..2000u32).map(|i| (i * 7919 % 251) as u8).collect();
    c.send_raw(&garbage);
    let json = c.counters_json();
    assert!(json.contains("\"bad_header\":1"), "{json}");
    // The connection still serves targets.
    let goal = pose_mm(1.0, 2.0, 161.0, Rotation3::identity());
    c.send("Target", target(&goal));
    c.expect("the pose at the target", |m| {
        transform_near(m, "Robot", &goal)
    });
    let counters = h.counters();
    assert_eq!(counters.malformed_of(MalformedKind::BadHeader), 1);
    assert_eq!(counters.discarded_bytes, 2000);
    assert_eq!(counters.connections_closed, 0);
}

#[test]
fn corrupt_and_invalid_targets_are_answered_and_counted() {
    let h = Harness::start(ServerConfig::default());
    let mut c = Client::connect(h.addr);
    let goal = pose_mm(1.0, 2.0, 161.0, Rotation3::identity());
    // A bit flipped in the body: CRC mismatch, STATUS 9.
    let mut bytes = Message::new("Target", target(&goal)).encode().unwrap();
    let n = bytes.len();
    bytes[n - 3] ^= 0x10;
    c.send_raw(&bytes);
    let m = c.expect("checksum error", |m| m.device_name == "Target");
    assert_eq!(status_of(&m).code, StatusCode::ChecksumError.wire());
    // A scaled matrix: not a pose, STATUS 12.
    let mut scaled = transform_from_pose(&goal);
    scaled.rotation[0][0] = 2.0;
    c.send("Target", Body::Transform(scaled));
    let m = c.expect("invalid pose", |m| m.device_name == "Target");
    assert_eq!(status_of(&m).code, StatusCode::IllegalInstruction.wire());
    assert_eq!(status_of(&m).error_name, "InvalidPose");
    // 40 bytes of TRANSFORM content: malformed, STATUS 12.
    c.send(
        "Target",
        Body::Other {
            type_name: "TRANSFORM".to_owned(),
            content: vec![0; 40],
        },
    );
    let m = c.expect("malformed", |m| m.device_name == "Target");
    assert_eq!(status_of(&m).error_name, "Malformed");
    // A TRANSFORM for another device and an unknown type: counted, not answered.
    c.send("Other", target(&goal));
    c.send(
        "Img",
        Body::Other {
            type_name: "IMAGE".to_owned(),
            content: vec![1; 10],
        },
    );
    let json = c.counters_json();
    assert!(json.contains("\"unknown_type\":1"), "{json}");
    assert!(h.robot.lock().unwrap().target().is_none());
    let counters = h.counters();
    assert_eq!(counters.malformed_of(MalformedKind::BadCrc), 1);
    assert_eq!(counters.malformed_of(MalformedKind::InvalidPose), 1);
    assert_eq!(counters.malformed_of(MalformedKind::BadContent), 1);
    assert_eq!(counters.malformed_of(MalformedKind::UnknownType), 1);
    assert_eq!(counters.received_of("IMAGE"), 1);
    assert_eq!(counters.targets_accepted, 0);
}

#[test]
fn queries_are_answered_as_the_protocol_says() {
    let h = Harness::start(ServerConfig {
        stream_on_connect: false,
        ..ServerConfig::default()
    });
    let mut c = Client::connect(h.addr);
    // Nothing is pushed without STT_.
    assert!(c.wait_for(Duration::from_millis(150), |_| true).is_none());

    c.query(QueryKind::Get, "STATUS", "");
    let m = c.expect("STATUS", |m| matches!(m.body, Body::Status(_)));
    assert_eq!(m.device_name, "RobotStatus");
    assert_eq!(status_of(&m).error_name, "Ready");

    c.query(QueryKind::Get, "STRING", "RobotState");
    let m = c.expect("STRING", |m| matches!(m.body, Body::String(_)));
    let Body::String(s) = &m.body else {
        unreachable!()
    };
    assert_eq!(s.as_text(), Some("Ready: holding"));

    c.query(QueryKind::Get, "POSITION", "Robot");
    let m = c.expect("POSITION", |m| matches!(m.body, Body::Position(_)));
    let Body::Position(p) = m.body else {
        unreachable!()
    };
    assert_eq!(p.position_mm, [0.0, 0.0, 160.0]);
    c.query(QueryKind::Get, "QTRANS", "");
    c.expect("QTRANS", |m| matches!(m.body, Body::QTrans(_)));
    // The protocol-3 table's spelling of GET_TRANS.
    c.query(QueryKind::Get, "TRANSFOR", "Robot");
    c.expect("TRANSFORM", |m| matches!(m.body, Body::Transform(_)));

    // No data for another device or an unhandled type: a message of the type, empty body.
    c.query(QueryKind::Get, "TRANS", "Nobody");
    let m = c.expect("null TRANSFORM", |m| m.device_name == "Nobody");
    assert_eq!(m.body, Body::Null(DataType::Transform));
    c.query(QueryKind::Get, "IMAGE", "Volume");
    let m = c.expect("null IMAGE", |m| m.device_name == "Volume");
    assert_eq!(
        m.body,
        Body::Other {
            type_name: "IMAGE".to_owned(),
            content: vec![]
        }
    );

    // STT_/STP_: RTS_ with status 0, and the stream starts and stops.
    c.query(QueryKind::Start, "TRANS", "Robot");
    let m = c.expect("RTS_TRANS", |m| matches!(m.body, Body::Rts { .. }));
    assert_eq!(
        m.body,
        Body::Rts {
            suffix: "TRANS".to_owned(),
            status: 0
        }
    );
    for _ in 0..3 {
        c.expect("streamed TRANSFORM", |m| {
            matches!(m.body, Body::Transform(_))
        });
    }
    c.query(QueryKind::Stop, "TRANS", "Robot");
    c.expect("RTS_TRANS", |m| {
        matches!(m.body, Body::Rts { status: 0, .. })
    });
    assert!(c
        .wait_for(Duration::from_millis(150), |m| matches!(
            m.body,
            Body::Transform(_)
        ))
        .is_none());
    c.query(QueryKind::Start, "POSITION", "Robot");
    c.expect("RTS_POSITION", |m| {
        matches!(m.body, Body::Rts { status: 0, .. })
    });
    c.expect("streamed POSITION", |m| matches!(m.body, Body::Position(_)));
    // An unhandled type: RTS_ with status 1 (error).
    c.query(QueryKind::Start, "TDATA", "Robot");
    let m = c.expect(
        "RTS_TDATA",
        |m| matches!(&m.body, Body::Rts { suffix, .. } if suffix == "TDATA"),
    );
    assert_eq!(
        m.body,
        Body::Rts {
            suffix: "TDATA".to_owned(),
            status: 1
        }
    );
}

#[test]
fn position_targets_in_all_three_sizes() {
    let h = Harness::start(ServerConfig::default());
    let mut c = Client::connect(h.addr);
    let turned = Rotation3::from_axis_angle(&Vector3::z_axis(), 0.5);
    let q = nalgebra::UnitQuaternion::from_rotation_matrix(&turned);
    let (x, y, z, w) = (q.i as f32, q.j as f32, q.k as f32, q.w as f32);
    c.send(
        "Target",
        Body::Position(PositionContent {
            position_mm: [3.0, 0.0, 160.0],
            orientation: PositionOrientation::Quaternion([x, y, z, w]),
        }),
    );
    let goal = pose_mm(3.0, 0.0, 160.0, turned);
    c.expect("28-byte target reached", |m| {
        transform_near(m, "Robot", &goal)
    });
    // Position only: the orientation is kept.
    c.send(
        "Target",
        Body::Position(PositionContent {
            position_mm: [-3.0, 1.0, 158.0],
            orientation: PositionOrientation::None,
        }),
    );
    let goal = pose_mm(-3.0, 1.0, 158.0, turned);
    c.expect("12-byte target reached", |m| {
        transform_near(m, "Robot", &goal)
    });
    // QTRANS with three quaternion elements: back to the identity.
    c.send(
        "Target",
        Body::QTrans(PositionContent {
            position_mm: [0.0, 0.0, 160.0],
            orientation: PositionOrientation::Quaternion3([0.0, 0.0, 0.0]),
        }),
    );
    let goal = pose_mm(0.0, 0.0, 160.0, Rotation3::identity());
    c.expect("24-byte target reached", |m| {
        transform_near(m, "Robot", &goal)
    });
    assert_eq!(h.counters().targets_accepted, 3);
}

#[test]
fn the_registration_is_applied_to_targets_and_inverted_for_poses() {
    // Client frame: turned 90 deg about z0 and 160 mm lower than {0}.
    let registration =
        Registration::parse_numbers_mm("0 -1 0 0  1 0 0 0  0 0 1 160  0 0 0 1").unwrap();
    let h = Harness::start(ServerConfig {
        registration,
        ..ServerConfig::default()
    });
    let mut c = Client::connect(h.addr);
    // The central pose of the robot, seen from the client frame: at the origin, turned -90.
    let central_in_client = pose_mm(
        0.0,
        0.0,
        0.0,
        Rotation3::from_axis_angle(&Vector3::z_axis(), -std::f64::consts::FRAC_PI_2),
    );
    c.expect("the central pose in the client frame", |m| {
        transform_near(m, "Robot", &central_in_client)
    });
    let goal_client = pose_mm(5.0, 0.0, 2.0, Rotation3::identity());
    c.send("Target", target(&goal_client));
    c.expect("the pose at the target, client frame", |m| {
        transform_near(m, "Robot", &goal_client)
    });
    // The robot got it in {0}: x_client -> y_base, +160 mm in z.
    let t = *h.robot.lock().unwrap().target().unwrap();
    assert!(
        (t.t - Vector3::new(0.0, 0.005, 0.162)).norm() < 1e-9,
        "{:?}",
        t.t
    );
    let expected_r = Rotation3::from_axis_angle(&Vector3::z_axis(), std::f64::consts::FRAC_PI_2);
    assert!(rotation_angle(&(t.r.inverse() * expected_r)) < 1e-6);
}

#[test]
fn several_clients_are_served_and_one_too_many_is_told_why() {
    let h = Harness::start(ServerConfig {
        max_clients: 2,
        ..ServerConfig::default()
    });
    let mut a = Client::connect(h.addr);
    let mut b = Client::connect(h.addr);
    a.expect("pose on a", |m| m.device_name == "Robot");
    b.expect("pose on b", |m| m.device_name == "Robot");
    let mut c = Client::connect(h.addr);
    let m = c.expect("busy", |m| matches!(m.body, Body::Status(_)));
    assert_eq!(status_of(&m).code, StatusCode::Busy.wire());
    assert!(c.wait_for(Duration::from_millis(300), |_| true).is_none());
    // A target from b reaches the robot; a sees the motion.
    let goal = pose_mm(4.0, 4.0, 162.0, Rotation3::identity());
    b.send("Target", target(&goal));
    a.expect("the pose at b's target on a", |m| {
        transform_near(m, "Robot", &goal)
    });
    drop(a);
    let counters = h.counters();
    assert_eq!(counters.connections_refused, 1);
    assert_eq!(counters.connections_accepted, 2);
}

#[test]
fn accepted_targets_are_acknowledged_when_asked() {
    let h = Harness::start(ServerConfig {
        acknowledge_targets: true,
        ..ServerConfig::default()
    });
    let mut c = Client::connect(h.addr);
    c.send(
        "Target",
        target(&pose_mm(0.0, 0.0, 161.0, Rotation3::identity())),
    );
    let m = c.expect("acknowledgement", |m| m.device_name == "Target");
    assert_eq!(status_of(&m).code, StatusCode::Ok.wire());
}

#[test]
fn a_message_cut_by_the_disconnection_is_counted_as_truncated() {
    let h = Harness::start(ServerConfig::default());
    let mut c = Client::connect(h.addr);
    let bytes = Message::new(
        "Target",
        target(&pose_mm(0.0, 0.0, 161.0, Rotation3::identity())),
    )
    .encode()
    .unwrap();
    c.send_raw(&bytes[..70]);
    // The client closes its side after the 70 bytes (FIN), then goes. Dropped at once
    // with the server's stream unread in its buffer, its socket would send a reset, which
    // may overtake the bytes (the kernel discards what the server has not read yet).
    c.stream.shutdown(std::net::Shutdown::Write).unwrap();
    let end = Instant::now() + WAIT;
    let mut buf = [0u8; 4096];
    loop {
        match c.stream.read(&mut buf) {
            Ok(0) => break,
            Ok(_) => {}
            Err(e) if matches!(e.kind(), ErrorKind::WouldBlock | ErrorKind::TimedOut) => {}
            Err(_) => break,
        }
        assert!(
            Instant::now() < end,
            "the server did not close the cut connection"
        );
    }
    drop(c);
    let mut watcher = Client::connect(h.addr);
    let end = Instant::now() + WAIT;
    while !watcher.counters_json().contains("\"connections_closed\":1") {
        assert!(Instant::now() < end, "the cut connection was not closed");
        std::thread::sleep(Duration::from_millis(10));
    }
    let counters = h.counters();
    assert_eq!(counters.malformed_of(MalformedKind::Truncated), 1);
}

#[test]
fn the_server_can_connect_out_to_a_listening_client() {
    // Slicer's OpenIGTLinkIF in server mode listens; the robot side connects to it.
    let slicer = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let mut server = Server::bind("127.0.0.1:0").unwrap();
    server
        .connect_to(slicer.local_addr().unwrap(), Duration::from_secs(1))
        .unwrap();
    let (stream, _) = slicer.accept().unwrap();
    stream
        .set_read_timeout(Some(Duration::from_millis(20)))
        .unwrap();
    let mut c = Client {
        stream,
        decoder: StreamDecoder::new(DecoderLimits::default()),
        version: HeaderVersion::V1,
    };
    let mut robot = FakeRobot::new(FakeRobotConfig::default());
    let goal = pose_mm(1.0, 0.0, 160.0, Rotation3::identity());
    c.send("Target", target(&goal));
    let end = Instant::now() + WAIT;
    let mut accepted = 0;
    while accepted == 0 && Instant::now() < end {
        accepted += server.poll(&mut robot).targets_accepted;
        std::thread::sleep(Duration::from_millis(1));
    }
    assert_eq!(accepted, 1);
    server.poll(&mut robot);
    c.expect("the pose pushed to the listening client", |m| {
        m.device_name == "Robot"
    });
}

/// With a token required, a client gets nothing before it sends the token as a STRING to
/// device `Token`, and then is served; a target before the token, and a wrong token, close
/// the connection and are counted as refused.
#[test]
fn a_required_token_comes_first_or_the_client_is_closed() {
    let h = Harness::start(ServerConfig {
        token: Some("s3cret".into()),
        ..ServerConfig::default()
    });
    let goal = pose_mm(1.0, 2.0, 161.0, Rotation3::identity());

    let mut good = Client::connect(h.addr);
    assert!(
        good.wait_for(Duration::from_millis(200), |_| true)
            .is_none(),
        "nothing is sent before the token"
    );
    good.send(
        igtl::server::TOKEN_DEVICE,
        Body::String(igtl::content::StringContent::text("s3cret")),
    );
    good.expect("the pose stream after the token", |m| {
        m.device_name == "Robot"
    });
    good.send("Target", target(&goal));
    good.expect("the pose at the target", |m| {
        transform_near(m, "Robot", &goal)
    });

    let mut early = Client::connect(h.addr);
    early.send("Target", target(&goal));
    assert!(early.wait_for(WAIT, |_| false).is_none());
    let mut wrong = Client::connect(h.addr);
    wrong.send(
        igtl::server::TOKEN_DEVICE,
        Body::String(igtl::content::StringContent::text("guess")),
    );
    assert!(wrong.wait_for(WAIT, |_| false).is_none());
    let counters = h.counters();
    assert_eq!(counters.targets_accepted, 1);
    assert_eq!(counters.connections_refused, 2);
    assert_eq!(counters.connections_closed, 2);
}

/// A client whose address is not in the allow-list is closed before anything is read or
/// sent; an allowed one is served.
#[test]
fn an_address_outside_the_allow_list_is_closed() {
    let h = Harness::start(ServerConfig {
        allow: vec!["10.9.8.7".parse().unwrap()],
        ..ServerConfig::default()
    });
    let mut c = Client::connect(h.addr);
    assert!(c.wait_for(WAIT, |_| true).is_none());
    assert_eq!(h.counters().connections_refused, 1);

    let h = Harness::start(ServerConfig {
        allow: vec!["127.0.0.1".parse().unwrap()],
        ..ServerConfig::default()
    });
    let mut c = Client::connect(h.addr);
    c.expect("the pose stream", |m| m.device_name == "Robot");
    assert_eq!(h.counters().connections_refused, 0);
}
