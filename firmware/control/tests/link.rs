#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::needless_range_loop
)]
//! The protocol through the link layer: every master message in, its reply out and
//! decoded by the master; malformed, oversized, wrong-version, bad-checksum, replayed and
//! old-session frames counted and ignored (never an emergency stop); the connection and
//! session rules; the clutch, the reset acknowledgement and the fault log at the wire
//! level; timestamps; status contents.

use control::link::{
    geometry_reply, opened_session, Inbound, LinkRx, LinkTx, Request, FIRMWARE_VERSION,
};
use control::modes::State;
use control::runtime::Runtime;
use control::targets::{TargetClock, TargetClockConfig};
use control::telemetry::with_link;
use control::wire::{guard_reason, pose_from_wire, refusal_reason};
use hal::QuadratureCounter;
use kinematics_core::guards::Guard;
use kinematics_core::supervisor::Refusal;
use kinematics_core::RsprGeometry;
use master_link::{
    cobs, encode, BoardToMaster, FaultCause, FrameError, Header, MasterDecoder, MasterToBoard,
    NackReason, ResetCause, ResetStatus, RobotState, Seq, SeqCounter, StatusReport, CRC32,
    MAX_FRAME_LEN, PROTOCOL_VERSION,
};

use crate::common;
use common::PlantHw;

// ---------------------------------------------------------------------------------------
// Helpers
// ---------------------------------------------------------------------------------------

/// The session of the tests' frames built by hand (and the nonce of the tests' master).
const SESSION: u32 = 0x5e55_1011;

fn frame_in<M: master_link::WireMessage>(msg: &M, session: u32, seq: Seq) -> Vec<u8> {
    let mut buf = [0u8; MAX_FRAME_LEN];
    let n = encode(msg, Header { session, seq }, &mut buf).unwrap();
    buf[..n].to_vec()
}

fn frame<M: master_link::WireMessage>(msg: &M, seq: Seq) -> Vec<u8> {
    frame_in(msg, SESSION, seq)
}

/// The raw (un-stuffed) content of an encoded frame: version, session, seq, body, CRC.
fn raw_of(frame: &[u8]) -> Vec<u8> {
    let mut f = frame[..frame.len() - 1].to_vec();
    let n = cobs::decode_in_place(&mut f).unwrap();
    f.truncate(n);
    f
}

/// Re-frames raw content (COBS + delimiter), recomputing the CRC unless told not to.
fn reframe(mut raw: Vec<u8>, fix_crc: bool) -> Vec<u8> {
    if fix_crc {
        let n = raw.len() - 4;
        let crc = CRC32.checksum(&raw[..n]);
        raw[n..].copy_from_slice(&crc.to_le_bytes());
    }
    let mut out = vec![0u8; cobs::max_encoded_len(raw.len()) + 1];
    let n = cobs::encode(&raw, &mut out).unwrap();
    out.truncate(n);
    out.push(0);
    out
}

fn feed(rx: &mut LinkRx, bytes: &[u8]) -> Vec<Inbound> {
    let mut v = Vec::new();
    rx.feed(bytes, |i| v.push(i));
    v
}

/// The master side: its nonce, the session the board issued it, its sequence and clock;
/// decodes the board's replies.
struct Master {
    nonce: u32,
    session: u32,
    seq: SeqCounter,
    rx: MasterDecoder,
    clock_us: u64,
}

impl Master {
    fn new() -> Self {
        Master {
            nonce: SESSION,
            session: 0,
            seq: SeqCounter::new(100),
            rx: MasterDecoder::new(),
            clock_us: 1_000,
        }
    }
    /// The master's `Hello` now (its clock advances).
    fn hello_msg(&mut self) -> MasterToBoard {
        self.clock_us += 1_000;
        MasterToBoard::Hello {
            protocol_version: PROTOCOL_VERSION,
            nonce: self.nonce,
            clock_us: self.clock_us,
        }
    }
    fn send(&mut self, msg: &MasterToBoard) -> (Seq, Vec<u8>) {
        let s = self.seq.next();
        (s, frame_in(msg, self.session, s))
    }
    fn receive(&mut self, bytes: &[u8]) -> Vec<BoardToMaster> {
        self.rx.feed(bytes).map(|r| r.unwrap().1).collect()
    }
}

/// The board: link + runtime, answering every frame like the firmware does.
struct Board<H> {
    rx: LinkRx,
    tx: LinkTx,
    rt: Runtime<f64, RsprGeometry<f64>>,
    hw: H,
    now: u64,
}

impl<H> Board<H> {
    fn receive(&mut self, bytes: &[u8]) -> Vec<u8> {
        let mut out = Vec::new();
        for inbound in feed(&mut self.rx, bytes) {
            let reply = match inbound {
                Inbound::Reply(r) => r,
                Inbound::Request(req) => {
                    let result = self.rt.command(&req.message, self.now);
                    let mut status = self.rt.status();
                    status.link = self.rx.counters();
                    let reply = req.reply(result, &status, FIRMWARE_VERSION);
                    if let Some(session) = opened_session(&reply) {
                        self.rx.open_session(session, req.seq);
                    }
                    reply
                }
                // A target without flash answers the runtime's verdict.
                Inbound::Geometry { seq, record } => {
                    geometry_reply(seq, self.rt.check_geometry(&record))
                }
            };
            let mut buf = [0u8; MAX_FRAME_LEN];
            let n = self.tx.encode(&reply, &mut buf).unwrap();
            out.extend_from_slice(&buf[..n]);
        }
        out
    }
}

/// Sends one message and returns the single reply.
fn exchange<H>(m: &mut Master, b: &mut Board<H>, msg: &MasterToBoard) -> (Seq, BoardToMaster) {
    let (seq, bytes) = m.send(msg);
    let replies = m.receive(&b.receive(&bytes));
    assert_eq!(replies.len(), 1, "{msg:?} -> {replies:?}");
    (seq, replies[0])
}

fn board_after(reset: ResetCause) -> Board<PlantHw> {
    let g = RsprGeometry::<f64>::reference();
    // The plant fixture (switches on the legs, stops on the links).
    let (mut hw, _, mut cfg) = common::homing_fixture([0.16; 3], [0.2; 3]);
    cfg.heartbeat.hold_after_us = 1_000_000_000;
    cfg.heartbeat.disable_after_us = 2_000_000_000;
    let mut rt = Runtime::new(g, cfg, 0).unwrap();
    rt.boot_done(hw.counts(), 0, reset, None).unwrap();
    Board {
        rx: LinkRx::new(),
        tx: LinkTx::new(),
        rt,
        hw,
        now: 0,
    }
}

fn board() -> Board<PlantHw> {
    board_after(ResetCause::PowerOn)
}

fn run(b: &mut Board<PlantHw>, ms: u64) {
    for _ in 0..ms {
        b.now += 1000;
        b.rt.tick(&mut b.hw, b.now);
        b.hw.step_ms();
    }
}

fn home_with(m: &mut Master, b: &mut Board<PlantHw>, rehome: bool) {
    let (s, r) = exchange(m, b, &MasterToBoard::Home { rehome });
    assert_eq!(r, BoardToMaster::Ack { seq: s });
    let mut ms = 0;
    while b.rt.state() == State::Homing {
        run(b, 1);
        ms += 1;
        assert!(ms < 60_000);
    }
    assert_eq!(b.rt.state(), State::Ready, "{:?}", b.rt.status().fault);
    // The stop after homing: brakes, then the drives off.
    run(b, 100);
}

fn home(m: &mut Master, b: &mut Board<PlantHw>) {
    home_with(m, b, false)
}

/// Says the operator is present, sends `Enable` and runs the brake check and release.
fn enable(m: &mut Master, b: &mut Board<PlantHw>) {
    let present = MasterToBoard::OperatorPresent { present: true };
    let (s, r) = exchange(m, b, &present);
    assert_eq!(r, BoardToMaster::Ack { seq: s });
    let (s, r) = exchange(m, b, &MasterToBoard::Enable);
    assert_eq!(r, BoardToMaster::Ack { seq: s });
    let mut ms = 0;
    while b.rt.state() == State::Enabling {
        run(b, 1);
        ms += 1;
        assert!(ms < 1_000);
    }
    assert_eq!(b.rt.state(), State::Enabled, "{:?}", b.rt.status().fault);
}

/// Opens the master's session (the board issues it, echoing the nonce); returns the
/// reply's reset status.
fn hello(m: &mut Master, b: &mut Board<PlantHw>) -> ResetStatus {
    match hello_reply(m, b) {
        BoardToMaster::HelloReply { reset, .. } => reset,
        r => panic!("{r:?}"),
    }
}

/// Opens the master's session; returns the `HelloReply`.
fn hello_reply(m: &mut Master, b: &mut Board<PlantHw>) -> BoardToMaster {
    let msg = m.hello_msg();
    let (seq, bytes) = m.send(&msg);
    let out = b.receive(&bytes);
    let got: Vec<_> = m.rx.feed(&out).map(|r| r.unwrap()).collect();
    assert_eq!(got.len(), 1, "{got:?}");
    let (reply_seq, r) = got[0];
    let BoardToMaster::HelloReply {
        firmware_version,
        protocol_version,
        session,
        nonce,
        reset,
        ..
    } = r
    else {
        panic!("{r:?}")
    };
    assert_eq!(firmware_version, FIRMWARE_VERSION);
    assert_eq!(protocol_version, PROTOCOL_VERSION);
    assert_eq!(nonce, m.nonce);
    assert_ne!(session, 0);
    assert_eq!(b.rx.session(), Some(session), "opened for {seq}");
    let _ = reset;
    m.session = session;
    m.rx.open_session(session, reply_seq);
    r
}

// ---------------------------------------------------------------------------------------
// Round trips
// ---------------------------------------------------------------------------------------

#[test]
fn every_message_round_trips_with_its_reply() {
    let mut m = Master::new();
    let mut b = board();
    let reset = hello(&mut m, &mut b);
    assert_eq!(
        reset,
        ResetStatus {
            cause: ResetCause::PowerOn,
            acknowledged: true
        }
    );
    assert!(b.rx.connected());
    assert_eq!(b.rx.session(), Some(m.session));
    let ack = |s| BoardToMaster::Ack { seq: s };
    let nack = |s, reason| BoardToMaster::Nack { seq: s, reason };
    // Disabled, not homed.
    let (s, r) = exchange(&mut m, &mut b, &MasterToBoard::Enable);
    assert_eq!(r, nack(s, NackReason::NotHomed));
    let (s, r) = exchange(&mut m, &mut b, &MasterToBoard::Heartbeat);
    assert_eq!(r, ack(s));
    let (s, r) = exchange(&mut m, &mut b, &MasterToBoard::Clutch { engaged: false });
    assert_eq!(r, ack(s));
    let (s, r) = exchange(&mut m, &mut b, &MasterToBoard::Disable);
    assert_eq!(r, ack(s));
    let (s, r) = exchange(&mut m, &mut b, &MasterToBoard::ClearFault);
    assert_eq!(r, ack(s), "nothing to clear is fine");
    let target = MasterToBoard::PoseTarget {
        timestamp_us: 1_000,
        position_m: [0.0, 0.0, 0.161],
        rotation_vector_rad: [0.0; 3],
    };
    let (s, r) = exchange(&mut m, &mut b, &target);
    assert_eq!(r, nack(s, NackReason::NotHomed));
    let (s, r) = exchange(
        &mut m,
        &mut b,
        &MasterToBoard::Jog {
            joint: 7,
            velocity: 0.01,
        },
    );
    assert_eq!(r, nack(s, NackReason::InvalidJoint));
    let (s, r) = exchange(
        &mut m,
        &mut b,
        &MasterToBoard::Jog {
            joint: 1,
            velocity: f32::NAN,
        },
    );
    assert_eq!(r, nack(s, NackReason::InvalidValue));
    let (s, r) = exchange(
        &mut m,
        &mut b,
        &MasterToBoard::Jog {
            joint: 1,
            velocity: 0.01,
        },
    );
    // A valid jog in Disabled (not homed) is refused by the state machine.
    assert_eq!(r, nack(s, NackReason::NotHomed));
    let (_, r) = exchange(&mut m, &mut b, &MasterToBoard::StatusRequest);
    let BoardToMaster::Status(st) = r else {
        panic!("{r:?}")
    };
    assert_eq!(st.state, RobotState::Disabled);
    assert_eq!(st.link, b.rx.counters());
    assert!(st.link.frames_ok >= 10);
    // Home, enable, follow.
    home(&mut m, &mut b);
    let (s, r) = exchange(&mut m, &mut b, &MasterToBoard::Home { rehome: false });
    assert_eq!(
        r,
        nack(s, NackReason::AlreadyHomed),
        "re-homing needs the confirmation"
    );
    home_with(&mut m, &mut b, true);
    enable(&mut m, &mut b);
    let (s, r) = exchange(&mut m, &mut b, &MasterToBoard::Home { rehome: true });
    assert_eq!(r, nack(s, NackReason::InvalidState));
    b.now += 1000;
    let stamp = 50_000_000;
    // The master's clock: `stamp` now.
    let now0 = b.now;
    let target = MasterToBoard::PoseTarget {
        timestamp_us: stamp,
        position_m: [0.003, 0.002, 0.162],
        rotation_vector_rad: [0.0, 0.02, 0.0],
    };
    let (s, r) = exchange(&mut m, &mut b, &target);
    assert_eq!(r, ack(s));
    // The same timestamp again (new frame): stale.
    let (s, r) = exchange(&mut m, &mut b, &target);
    assert_eq!(r, nack(s, NackReason::StaleTarget));
    // Non-finite: invalid value.
    let bad = MasterToBoard::PoseTarget {
        timestamp_us: stamp + 1000,
        position_m: [f32::INFINITY, 0.0, 0.16],
        rotation_vector_rad: [0.0; 3],
    };
    let (s, r) = exchange(&mut m, &mut b, &bad);
    assert_eq!(r, nack(s, NackReason::InvalidValue));
    // Too far in one jump, and outside the workspace: the workspace is named first.
    let far = MasterToBoard::PoseTarget {
        timestamp_us: stamp + 2000,
        position_m: [0.0, 0.0, 0.25],
        rotation_vector_rad: [0.0; 3],
    };
    let (s, r) = exchange(&mut m, &mut b, &far);
    assert_eq!(r, nack(s, NackReason::OutOfWorkspace));
    run(&mut b, 1500);
    let (_, r) = exchange(&mut m, &mut b, &MasterToBoard::StatusRequest);
    let BoardToMaster::Status(st) = r else {
        panic!("{r:?}")
    };
    assert_eq!(st.state, RobotState::Enabled);
    assert!(
        (st.position_m[0] - 0.003).abs() < 0.2e-3,
        "{:?}",
        st.position_m
    );
    assert!(
        (st.position_m[2] - 0.162).abs() < 0.2e-3,
        "{:?}",
        st.position_m
    );
    assert!((st.rotation_vector_rad[1] - 0.02).abs() < 2e-3);
    assert!(st.faults.is_empty());
    // The margins the supervisor measured at its setpoint (the tick's, not a second
    // evaluation), the setpoint, the stop and fault fields.
    assert!(st.serial_singularity_margin > 0.15, "{st:?}");
    assert!(st.parallel_singularity_margin > 0.03, "{st:?}");
    assert!(
        st.margins.nearest > 0.0 && st.margins.nearest <= 1.0,
        "{st:?}"
    );
    assert!((st.setpoint_position_m[0] - 0.003).abs() < 1e-6, "{st:?}");
    assert_eq!(st.stop, master_link::StopStatus::None);
    assert_eq!(st.fault.cause, FaultCause::None);
    assert!((st.supply_v - 24.0).abs() < 1e-3);
    // Clutch engaged (pedal pressed): the master is decoupled, the robot holds and
    // targets are refused; released, targets move the robot again.
    let (s, r) = exchange(&mut m, &mut b, &MasterToBoard::Clutch { engaged: true });
    assert_eq!(r, ack(s));
    let t2 = MasterToBoard::PoseTarget {
        timestamp_us: stamp + 3000,
        position_m: [0.0, 0.0, 0.162],
        rotation_vector_rad: [0.0; 3],
    };
    let (s, r) = exchange(&mut m, &mut b, &t2);
    assert_eq!(r, nack(s, NackReason::InvalidState));
    run(&mut b, 300);
    let held = b.rt.status().position_m;
    assert!((held[0] - 0.003).abs() < 0.2e-3, "held at {held:?}");
    assert_eq!(
        b.rt.status().stop,
        master_link::StopStatus::SafeOperatingStop
    );
    let (s, r) = exchange(&mut m, &mut b, &MasterToBoard::Clutch { engaged: false });
    assert_eq!(r, ack(s));
    run(&mut b, 2);
    let t3 = MasterToBoard::PoseTarget {
        timestamp_us: stamp + (b.now - now0),
        position_m: [0.0, 0.0, 0.162],
        rotation_vector_rad: [0.0; 3],
    };
    let (s, r) = exchange(&mut m, &mut b, &t3);
    assert_eq!(r, ack(s), "clutch released: targets move the robot");
    run(&mut b, 1500);
    let moved = b.rt.status().position_m;
    assert!(moved[0].abs() < 0.2e-3, "followed to {moved:?}");
    // E-stop, refusals while faulted, clear.
    let (s, r) = exchange(&mut m, &mut b, &MasterToBoard::EmergencyStop);
    assert_eq!(r, ack(s));
    let (s, r) = exchange(&mut m, &mut b, &MasterToBoard::Enable);
    assert_eq!(r, nack(s, NackReason::Faulted));
    let (s, r) = exchange(&mut m, &mut b, &t2);
    assert_eq!(r, nack(s, NackReason::Faulted));
    let (_, r) = exchange(&mut m, &mut b, &MasterToBoard::StatusRequest);
    let BoardToMaster::Status(st) = r else {
        panic!()
    };
    assert_eq!(st.state, RobotState::Fault);
    assert!(st.faults.contains(master_link::Faults::EMERGENCY_STOP));
    assert_eq!(st.fault.cause, FaultCause::EmergencyStopMessage);
    assert_eq!(st.stop, master_link::StopStatus::SafeTorqueOff);
    // The fault log holds the e-stop.
    let (_, r) = exchange(&mut m, &mut b, &MasterToBoard::FaultLogRequest { first: 0 });
    let BoardToMaster::FaultLog(page) = r else {
        panic!("{r:?}")
    };
    assert_eq!(page.total, 1);
    assert_eq!(
        page.entries[0].record.cause,
        FaultCause::EmergencyStopMessage
    );
    // Cleared once a tick has reported the stop.
    run(&mut b, 1);
    let (s, r) = exchange(&mut m, &mut b, &MasterToBoard::ClearFault);
    assert_eq!(r, ack(s));
    assert_eq!(b.rt.state(), State::Ready);
    // Every reply was accepted by the master's decoder, in sequence.
    let c = m.rx.counters();
    assert_eq!(c.rejected(), 0);
    assert_eq!(c.dropped, 0);
    assert_eq!(c.frames_ok, b.tx.sent());
}

#[test]
fn commands_before_hello_are_refused_except_the_emergency_stop() {
    let mut m = Master::new();
    let mut b = board();
    let (s, r) = exchange(&mut m, &mut b, &MasterToBoard::Home { rehome: false });
    assert_eq!(
        r,
        BoardToMaster::Nack {
            seq: s,
            reason: NackReason::NotConnected
        }
    );
    assert_eq!(b.rt.state(), State::Disabled);
    assert_eq!(b.rx.refused_not_connected(), 1);
    // A Hello with another protocol version: refused, still not connected.
    let (s, r) = exchange(
        &mut m,
        &mut b,
        &MasterToBoard::Hello {
            protocol_version: 10,
            nonce: SESSION,
            clock_us: 0,
        },
    );
    assert_eq!(
        r,
        BoardToMaster::HelloRefused {
            seq: s,
            nonce: SESSION,
            reason: NackReason::UnsupportedVersion
        }
    );
    assert!(!b.rx.connected());
    let (s, r) = exchange(&mut m, &mut b, &MasterToBoard::EmergencyStop);
    assert_eq!(r, BoardToMaster::Ack { seq: s });
    assert_eq!(b.rt.state(), State::Fault);
    hello(&mut m, &mut b);
    // Cleared once a tick has reported the stop.
    run(&mut b, 1);
    let (s, r) = exchange(&mut m, &mut b, &MasterToBoard::ClearFault);
    assert_eq!(r, BoardToMaster::Ack { seq: s });
    assert_eq!(b.rt.state(), State::Disabled);
    // After a disconnect the master must say Hello again.
    b.rx.disconnect();
    m.rx = MasterDecoder::new();
    let (s, r) = exchange(&mut m, &mut b, &MasterToBoard::Heartbeat);
    assert_eq!(
        r,
        BoardToMaster::Nack {
            seq: s,
            reason: NackReason::NotConnected
        }
    );
}

// ---------------------------------------------------------------------------------------
// Bad frames
// ---------------------------------------------------------------------------------------

#[test]
fn bad_frames_are_counted_and_dropped() {
    let mut rx = LinkRx::new();
    let good = frame(
        &MasterToBoard::Hello {
            protocol_version: PROTOCOL_VERSION,
            nonce: SESSION,
            clock_us: 0,
        },
        1,
    );
    assert_eq!(feed(&mut rx, &good).len(), 1);
    // (The runtime accepted it: the board opens the session.)
    rx.open_session(SESSION, 1);
    // Malformed: garbage, invalid COBS, a truncated frame.
    assert!(feed(&mut rx, &[0x13, 0x37, 0xff, 0x00]).is_empty());
    assert!(feed(&mut rx, &[0x05, 0x01, 0x00]).is_empty());
    let hb = frame(&MasterToBoard::Heartbeat, 2);
    let raw = raw_of(&hb);
    assert!(feed(&mut rx, &reframe(raw[..5].to_vec(), false)).is_empty());
    let c = rx.counters();
    assert_eq!(c.malformed, 3, "{c:?}");
    assert!(matches!(rx.last_error(), Some(FrameError::Malformed(_))));
    // Bad checksum.
    let mut corrupt = raw.clone();
    corrupt[3] ^= 0x40;
    assert!(feed(&mut rx, &reframe(corrupt, false)).is_empty());
    assert_eq!(rx.counters().bad_checksum, 1);
    assert_eq!(rx.last_error(), Some(FrameError::BadChecksum));
    // Wrong version (a valid frame of the next protocol version).
    let next = master_link::PROTOCOL_VERSION + 1;
    let mut v2 = raw.clone();
    v2[0] = next;
    assert!(feed(&mut rx, &reframe(v2, true)).is_empty());
    assert_eq!(rx.counters().wrong_version, 1);
    assert_eq!(
        rx.last_error(),
        Some(FrameError::WrongVersion { received: next })
    );
    // Oversized.
    let mut big = vec![0x55u8; 300];
    big.push(0);
    assert!(feed(&mut rx, &big).is_empty());
    assert_eq!(rx.counters().oversized, 1);
    // The good heartbeat goes through, with the session it came in; replaying it is
    // counted and ignored.
    let got = feed(&mut rx, &hb);
    assert_eq!(
        got,
        vec![Inbound::Request(Request {
            seq: 2,
            message: MasterToBoard::Heartbeat,
            session: SESSION,
        })]
    );
    assert!(feed(&mut rx, &hb).is_empty());
    let old = frame(&MasterToBoard::Enable, 1);
    assert!(feed(&mut rx, &old).is_empty());
    assert_eq!(rx.counters().out_of_order, 2);
    // A gap is accepted and counted as dropped.
    assert_eq!(feed(&mut rx, &frame(&MasterToBoard::Heartbeat, 6)).len(), 1);
    let c = rx.counters();
    assert_eq!(c.dropped, 3);
    assert_eq!(c.frames_ok, 3);
    assert_eq!(c.rejected(), 3 + 1 + 1 + 1 + 2);
    // Garbage in between frames does not lose the next good frame.
    let mut mixed = vec![0xde, 0xad, 0x00];
    mixed.extend_from_slice(&frame(&MasterToBoard::StatusRequest, 7));
    let got = feed(&mut rx, &mixed);
    assert_eq!(got.len(), 1);
    // resync drops a partial frame silently.
    assert!(feed(&mut rx, &[0x22, 0x33]).is_empty());
    rx.resync();
    assert_eq!(feed(&mut rx, &frame(&MasterToBoard::Heartbeat, 8)).len(), 0);
    assert_eq!(feed(&mut rx, &frame(&MasterToBoard::Heartbeat, 9)).len(), 1);
}

#[test]
fn bad_frames_do_not_reach_the_runtime() {
    let mut m = Master::new();
    let mut b = board();
    hello(&mut m, &mut b);
    // A Home frame with a bad checksum, then replayed Home: neither homes.
    let (_, home) = m.send(&MasterToBoard::Home { rehome: false });
    let mut raw = raw_of(&home);
    let n = raw.len();
    raw[n - 1] ^= 1;
    assert!(b.receive(&reframe(raw, false)).is_empty());
    assert_eq!(b.rt.state(), State::Disabled);
    let out = b.receive(&home);
    assert_eq!(m.receive(&out).len(), 1);
    assert_eq!(b.rt.state(), State::Homing);
    b.rt.command(&MasterToBoard::Disable, 0).unwrap();
    assert!(b.receive(&home).is_empty(), "replay ignored");
    assert_eq!(b.rt.state(), State::Disabled);
    assert_eq!(b.rx.counters().out_of_order, 1);
    assert_eq!(b.rx.counters().bad_checksum, 1);
}

// ---------------------------------------------------------------------------------------
// Pieces
// ---------------------------------------------------------------------------------------

#[test]
fn target_clock_checks_order_and_latency() {
    let mut c = TargetClock::new(TargetClockConfig {
        max_latency_us: 5_000,
        window_us: 100_000,
        ..TargetClockConfig::default()
    });
    // Master clock 1 s ahead of the board's.
    let s1 = c.accept(1_001_000, 1_000).unwrap();
    let s2 = c.accept(1_002_000, 2_000).unwrap();
    assert!(s2 > s1);
    assert_eq!(c.accept(1_002_000, 2_500), Err(NackReason::StaleTarget));
    assert_eq!(c.accept(1_001_500, 2_500), Err(NackReason::StaleTarget));
    // 4 ms late: fine; 6 ms late: stale.
    assert!(c.accept(1_003_000, 7_000).is_ok());
    assert_eq!(c.accept(1_004_000, 10_001), Err(NackReason::StaleTarget));
    // Board stamps strictly increase even within one microsecond.
    let a = c.board_stamp(10_001);
    let b2 = c.board_stamp(10_001);
    assert!(b2 > a);
    // Drift: the reference follows within two windows.
    let mut now = 20_000u64;
    let mut master = 1_020_000u64;
    for _ in 0..400 {
        now += 1_000;
        master += 990; // the master's clock runs 1 % slow
        assert!(c.accept(master, now).is_ok(), "at {now}");
    }
    c.reset();
    assert!(c.accept(5, now + 1).is_ok(), "fresh after reset");
}

/// Property: targets sent now and then (a navigation system) are judged against the link's
/// delay of the last two windows of the board clock, not against the delay of the last
/// target however long ago. After a silence of two windows or more, during which the
/// master's clock drifted by more than the latency bound (here 1 % over 2 s: 20 ms
/// against 5 ms), the next target is in time; two windows later the clocks have drifted
/// again and the next target is again in time; a target that is late against one sent
/// just before it is still stale.
#[test]
fn target_clock_forgets_windows_older_than_two() {
    // The master's clock runs 1 % slow: the board-minus-master offset grows by 10 ms a
    // second, so each target looks later than the last by the drift.
    let slow_at = |board_us: u64| 7_000_000 + board_us - board_us / 100;
    let mut c = TargetClock::new(TargetClockConfig {
        max_latency_us: 5_000,
        window_us: 100_000,
        ..TargetClockConfig::default()
    });
    assert!(c.accept(slow_at(1_000), 1_000).is_ok());
    for k in 1..=5u64 {
        let now = 1_000 + k * 2_000_000;
        assert!(
            c.accept(slow_at(now), now).is_ok(),
            "a target after {k} silences of 2 s (drift {} ms) is in time",
            now / 100 / 1000
        );
        // Right after it, a target 6 ms later than its stamp says: stale.
        assert_eq!(
            c.accept(slow_at(now + 1_000), now + 1_000 + 6_000),
            Err(NackReason::StaleTarget),
            "6 ms late against the target just before"
        );
    }
}

#[test]
fn refusals_and_guards_map_to_nack_reasons() {
    assert_eq!(
        refusal_reason::<f64>(&Refusal::NonFinite),
        NackReason::InvalidValue
    );
    assert_eq!(
        refusal_reason::<f64>(&Refusal::Stale { age_us: 5 }),
        NackReason::StaleTarget
    );
    assert_eq!(
        refusal_reason::<f64>(&Refusal::OutOfOrder),
        NackReason::StaleTarget
    );
    assert_eq!(
        refusal_reason::<f64>(&Refusal::TooFar {
            distance: 1.0,
            angle: 0.0,
            breaks: None,
        }),
        NackReason::VelocityLimit
    );
    assert_eq!(
        refusal_reason::<f64>(&Refusal::Latched),
        NackReason::Faulted
    );
    assert_eq!(guard_reason(Guard::Stroke), NackReason::JointLimit);
    assert_eq!(
        guard_reason(Guard::SerialSingularity),
        NackReason::NearSingularity
    );
    assert_eq!(
        guard_reason(Guard::ParallelSingularity),
        NackReason::NearSingularity
    );
    assert_eq!(guard_reason(Guard::Workspace), NackReason::OutOfWorkspace);
    assert_eq!(guard_reason(Guard::JointSpeed), NackReason::VelocityLimit);
    for g in Guard::ALL {
        let _ = guard_reason(g);
    }
    assert!(pose_from_wire::<f32>([0.0, 0.0, 0.16], [0.0, 0.0, f32::NAN]).is_err());
    let p = pose_from_wire::<f32>([0.01, 0.0, 0.16], [0.0, 0.1, 0.0]).unwrap();
    let (t, r) = control::wire::pose_to_wire(&p);
    assert_eq!(t, [0.01, 0.0, 0.16]);
    assert!((r[1] - 0.1).abs() < 1e-6);
}

#[test]
fn tx_sequence_and_status_encoding() {
    let mut tx = LinkTx::new();
    let mut dec = MasterDecoder::new();
    let mut buf = [0u8; MAX_FRAME_LEN];
    let status = BoardToMaster::Status(StatusReport {
        state: RobotState::Enabled,
        position_m: [0.001, -0.002, 0.16],
        rotation_vector_rad: [0.01, 0.02, 0.03],
        joints: [0.17, 0.171, 0.169, 0.1, -0.1, 0.0],
        warnings: master_link::Warnings::NEAR_JOINT_LIMIT,
        faults: master_link::Faults::NONE,
        serial_singularity_margin: 0.4,
        parallel_singularity_margin: 0.1,
        link: master_link::LinkCounters {
            frames_ok: u32::MAX,
            bad_checksum: u32::MAX,
            malformed: u32::MAX,
            oversized: u32::MAX,
            wrong_version: u32::MAX,
            out_of_order: u32::MAX,
            dropped: u32::MAX,
            wrong_session: u32::MAX,
            bad_tag: u32::MAX,
        },
        tick_jitter_max_us: 12,
        tick_exec_max_us: 431,
        targets_refused: u32::MAX,
        ..StatusReport::default()
    });
    for k in 0..3u16 {
        let n = tx.encode(&status, &mut buf).unwrap();
        assert!(n <= MAX_FRAME_LEN);
        let got: Vec<_> = dec.feed(&buf[..n]).collect();
        assert_eq!(got, vec![Ok((k, status))]);
    }
    assert_eq!(tx.sent(), 3);
    // A buffer too small is an error, counted, and the sequence does not advance.
    assert!(tx.encode(&status, &mut buf[..10]).is_err());
    assert_eq!(tx.errors(), 1);
    let n = tx.encode(&BoardToMaster::Ack { seq: 1 }, &mut buf).unwrap();
    let got: Vec<_> = dec.feed(&buf[..n]).collect();
    assert_eq!(got, vec![Ok((3, BoardToMaster::Ack { seq: 1 }))]);
}

/// The status the boards send: the link counters with `LINK_ERRORS` raised exactly while a
/// frame has been rejected; without counters the link fields stay as they were. (The
/// singularity margins come with the runtime's status: see the enabled robot's test.)
#[test]
fn with_link_adds_the_counters_and_the_link_warning() {
    let base = StatusReport {
        position_m: [0.0, 0.0, 0.16],
        ..StatusReport::default()
    };
    let clean = master_link::LinkCounters {
        frames_ok: 40,
        ..Default::default()
    };
    let bad = master_link::LinkCounters {
        malformed: 1,
        ..clean
    };
    let mut st = base;
    with_link(&mut st, Some(clean));
    assert_eq!(st.link, clean);
    assert!(!st.warnings.contains(master_link::Warnings::LINK_ERRORS));
    with_link(&mut st, Some(bad));
    assert_eq!(st.link, bad);
    assert!(st.warnings.contains(master_link::Warnings::LINK_ERRORS));
    let mut untouched = base;
    with_link(&mut untouched, None);
    assert_eq!(untouched.link, base.link);
    assert!(!untouched
        .warnings
        .contains(master_link::Warnings::LINK_ERRORS));
}

// ---------------------------------------------------------------------------------------
// Sessions, the emergency stop, resets
// ---------------------------------------------------------------------------------------

/// Property: after a new `Hello` (a new nonce), frames of the older session never reach
/// the runtime (counted as `wrong_session`), whatever their sequence numbers; an intact
/// `EmergencyStop` is taken from any session and out of order.
#[test]
fn an_older_session_is_refused_but_never_an_emergency_stop() {
    let mut m = Master::new();
    let mut b = board();
    hello(&mut m, &mut b);
    // A frame recorded in this session...
    let (_, old_home) = m.send(&MasterToBoard::Home { rehome: false });
    // ... then the master reconnects with a new nonce.
    let mut m2 = Master::new();
    m2.nonce = SESSION ^ 0xffff_0000;
    m2.seq = SeqCounter::new(5);
    hello(&mut m2, &mut b);
    assert_eq!(b.rx.session(), Some(m2.session));
    assert_ne!(m2.session, m.session, "a fresh session");
    // The old frame, replayed (its sequence number is far ahead): refused.
    assert!(b.receive(&old_home).is_empty());
    assert_eq!(b.rt.state(), State::Disabled);
    assert_eq!(b.rx.counters().wrong_session, 1);
    assert_eq!(
        b.rx.last_error(),
        Some(FrameError::WrongSession {
            received: m.session,
            expected: m2.session
        })
    );
    // The new session works.
    let (s, r) = exchange(&mut m2, &mut b, &MasterToBoard::Heartbeat);
    assert_eq!(r, BoardToMaster::Ack { seq: s });
    // An emergency stop of the old session, with a stale sequence number: taken.
    let estop = frame_in(&MasterToBoard::EmergencyStop, m.session, 1);
    let replies = m2.receive(&b.receive(&estop));
    assert_eq!(replies.len(), 1);
    assert_eq!(b.rt.state(), State::Fault);
    assert_eq!(b.rt.status().fault.cause, FaultCause::EmergencyStopMessage);
    // And a replayed emergency stop of the current session, out of order: taken too
    // (after a tick has reported the first and the master cleared it).
    run(&mut b, 1);
    let (s, r) = exchange(&mut m2, &mut b, &MasterToBoard::ClearFault);
    assert_eq!(r, BoardToMaster::Ack { seq: s });
    let replay = frame_in(&MasterToBoard::EmergencyStop, m2.session, 0);
    assert_eq!(m2.receive(&b.receive(&replay)).len(), 1);
    assert_eq!(b.rt.state(), State::Fault);
}

/// Property: after a watchdog or brown-out reset, the hello reply and the status report
/// the cause unacknowledged, and `Home` and `Enable` are refused with
/// `ResetNotAcknowledged` until the master acknowledges (nothing moves before a person
/// has); after a power-on or pin reset nothing needs acknowledging.
#[test]
fn a_watchdog_reset_must_be_acknowledged_before_enabling() {
    for cause in [
        ResetCause::Watchdog,
        ResetCause::BrownOut,
        ResetCause::Software,
        ResetCause::Pin,
        ResetCause::PowerOn,
    ] {
        let mut m = Master::new();
        let mut b = board_after(cause);
        let reset = hello(&mut m, &mut b);
        assert_eq!(reset.cause, cause);
        let needs = cause.needs_acknowledgement();
        assert_eq!(reset.acknowledged, !needs, "{cause:?}");
        assert_eq!(b.rt.status().reset, reset);
        if needs {
            for cmd in [MasterToBoard::Home { rehome: false }, MasterToBoard::Enable] {
                let (s, r) = exchange(&mut m, &mut b, &cmd);
                let reason = if cmd == MasterToBoard::Enable {
                    NackReason::NotHomed
                } else {
                    NackReason::ResetNotAcknowledged
                };
                assert_eq!(r, BoardToMaster::Nack { seq: s, reason }, "{cause:?}");
            }
            let (s, r) = exchange(&mut m, &mut b, &MasterToBoard::AcknowledgeReset);
            assert_eq!(r, BoardToMaster::Ack { seq: s });
            assert!(b.rt.status().reset.acknowledged);
        }
        home(&mut m, &mut b);
        let present = MasterToBoard::OperatorPresent { present: true };
        exchange(&mut m, &mut b, &present);
        let (s, r) = exchange(&mut m, &mut b, &MasterToBoard::Enable);
        assert_eq!(r, BoardToMaster::Ack { seq: s }, "{cause:?}");
    }
}

// ---------------------------------------------------------------------------------------
// The calibrated geometry
// ---------------------------------------------------------------------------------------

/// A `StoreGeometry` with the drives off is checked and accepted; a corrupted, a version-0
/// or an implausible record, and any record while the drives are on, is refused with the
/// reason; the hello reply reports the stored version.
#[test]
fn a_calibrated_geometry_is_checked_before_it_is_stored() {
    use control::geometry_store::record_of;
    use kinematics_core::{Chain, ChainDimensions, PerChainGeometry};
    use master_link::GeometryRefusal;
    let mut m = Master::new();
    let mut b = board();
    hello(&mut m, &mut b);
    let g = RsprGeometry::<f64>::reference();
    let sym = PerChainGeometry::from(g);
    let with_offset = |mm: f64| {
        let mut chains = *sym.chains();
        chains[Chain::Two] = ChainDimensions {
            leg_offset: mm * 1e-3,
            ..chains[Chain::Two]
        };
        PerChainGeometry::new(g, chains).unwrap()
    };
    let good = record_of(&with_offset(0.3), 3);
    let (seq, r) = exchange(&mut m, &mut b, &MasterToBoard::StoreGeometry(good));
    assert_eq!(r, BoardToMaster::GeometryStored { seq, version: 3 });
    let refused = |m: &mut Master, b: &mut Board<PlantHw>, rec| {
        let (seq, r) = exchange(m, b, &MasterToBoard::StoreGeometry(rec));
        match r {
            BoardToMaster::GeometryRefused { seq: s, reason } if s == seq => reason,
            other => panic!("{other:?}"),
        }
    };
    let mut corrupt = good;
    corrupt.chains[0][0] += 1e-4;
    assert_eq!(refused(&mut m, &mut b, corrupt), GeometryRefusal::Crc);
    assert_eq!(
        refused(&mut m, &mut b, record_of(&with_offset(0.3), 0)),
        GeometryRefusal::Version
    );
    // A 5 mm leg offset is beyond any calibration (chain 2's value 13: index 4 + 16 + 13).
    assert_eq!(
        refused(&mut m, &mut b, record_of(&with_offset(5.0), 4)),
        GeometryRefusal::OutOfTolerance { index: 33 }
    );
    let mut nan = good;
    nan.chains[2][6] = f32::NAN;
    assert_eq!(
        refused(&mut m, &mut b, nan.sealed()),
        GeometryRefusal::NonFinite { index: 42 }
    );
    // The stored version is what the hello reply reports.
    b.rt.set_geometry_version(3);
    let r = hello_reply(&mut m, &mut b);
    assert!(
        matches!(
            r,
            BoardToMaster::HelloReply {
                geometry_version: 3,
                ..
            }
        ),
        "{r:?}"
    );
    // With the drives on, nothing is stored.
    home(&mut m, &mut b);
    enable(&mut m, &mut b);
    assert_eq!(refused(&mut m, &mut b, good), GeometryRefusal::InvalidState);
}
