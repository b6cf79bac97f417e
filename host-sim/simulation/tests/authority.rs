#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
//! Command authority on the master link, on the simulated board (`BoardSim`: the whole
//! board application on the plant, its link included), with the platform's motion measured
//! on the plant (the true pose of the load-side joints), not what the code intended:
//! one master owns the board, recordings cannot act, a stray sequence number locks nobody
//! out, a target from the future poisons no clock, and a keyed link drops every frame
//! without a valid tag.

use master_link::{
    BoardToMaster, LinkKey, MasterToBoard, NackReason, ResetCause, RobotState, Seq, StopStatus,
    PROTOCOL_VERSION,
};
use simulation::bench::{frame_in, frame_keyed, Bench, SimMaster};
use simulation::board::{BoardSim, BoardSimConfig};

/// The owner's nonce, and the others'.
const OWNER: u32 = 0x0A11_CE00;
const INTRUDER: u32 = 0x0BAD_0BAD;

/// Largest platform motion the properties allow, m.
const STILL_M: f64 = 0.01e-3;

fn bench_with(key: Option<LinkKey>, nonce: u32) -> Bench {
    let mut cfg = BoardSimConfig::reference(None).unwrap();
    cfg.key = key;
    Bench::new(
        BoardSim::new(cfg, ResetCause::PowerOn, None).unwrap(),
        nonce,
    )
}

/// Runs `ms` milliseconds; the largest distance of the true platform position from where
/// it was at the start, m.
fn motion_over(b: &mut Bench, ms: u64) -> f64 {
    let p0 = b.board.truth().pose.t;
    let mut max = 0.0f64;
    for _ in 0..ms {
        b.tick().unwrap();
        max = max.max((b.board.truth().pose.t - p0).norm());
    }
    max
}

/// A target `dx` m off the current setpoint, stamped with the board's virtual time (the
/// master's clock in this bench).
fn target_at(b: &Bench, dx: f32, stamp_us: u64) -> MasterToBoard {
    let s = b.board.runtime().status();
    MasterToBoard::PoseTarget {
        timestamp_us: stamp_us,
        position_m: [
            s.setpoint_position_m[0] + dx,
            s.setpoint_position_m[1],
            s.setpoint_position_m[2],
        ],
        rotation_vector_rad: s.setpoint_rotation_vector_rad,
    }
}

/// Another master's frame of `msg` (its own session and sequence) onto the line; its
/// sequence number.
fn other_sends(b: &mut Bench, i: usize, msg: &MasterToBoard) -> Seq {
    let (seq, bytes) = b.others[i].frame(msg);
    b.send_raw(&bytes);
    seq
}

/// Runs until another master `i` has the reply to `seq` (at most 100 ms).
fn other_reply(b: &mut Bench, i: usize, seq: Seq) -> Option<BoardToMaster> {
    for _ in 0..100 {
        b.tick().unwrap();
        if let Some((_, r)) = b.others[i].replies.get(&seq) {
            return Some(*r);
        }
    }
    None
}

/// Property: while the owner's operator has let go of the dead-man (the robot holds), a
/// second master's `Hello` is refused with `NotOwner` and ends no hold; the second
/// master's targets (4 mm away), its `OperatorPresent` and `Enable` are refused; the
/// platform moves at most 0.01 mm; and the owner's next frames are taken (its hand back:
/// the hold ends and its target is followed).
#[test]
fn a_second_masters_hello_during_a_dead_man_hold_changes_nothing() {
    let mut b = bench_with(None, OWNER);
    b.bring_up().unwrap();
    b.command(&MasterToBoard::OperatorPresent { present: false })
        .unwrap();
    b.run_ms(300).unwrap();
    assert_eq!(
        b.board.runtime().status().stop,
        StopStatus::SafeOperatingStop
    );
    let before = b.board.runtime().status().link;
    b.others.push(SimMaster::new(INTRUDER));
    let start = b.board.truth().pose.t;
    let hello = MasterToBoard::Hello {
        protocol_version: PROTOCOL_VERSION,
        nonce: INTRUDER,
        clock_us: b.now_us(),
    };
    let seq = other_sends(&mut b, 0, &hello);
    let reply = other_reply(&mut b, 0, seq);
    assert!(
        matches!(
            reply,
            Some(BoardToMaster::HelloRefused {
                nonce: INTRUDER,
                reason: NackReason::NotOwner,
                ..
            })
        ),
        "{reply:?}"
    );
    assert_eq!(b.others[0].session, 0, "no session for the second master");
    let session = b.board.runtime().session();
    assert!(!session.operator_present(), "the hold stays");
    assert_eq!(session.owner().map(|o| o.nonce), Some(OWNER));
    assert_eq!(b.board.link_rx().session(), Some(b.master.session));
    // Its commands and targets: of no session the board has open.
    for msg in [
        MasterToBoard::OperatorPresent { present: true },
        MasterToBoard::Clutch { engaged: false },
        MasterToBoard::Enable,
    ] {
        other_sends(&mut b, 0, &msg);
    }
    let mut moved = 0.0f64;
    for k in 0..50 {
        let t = target_at(&b, 0.004 * (k as f32 + 1.0) / 50.0, b.now_us());
        other_sends(&mut b, 0, &t);
        moved = moved.max(motion_over(&mut b, 10));
    }
    let after = b.board.runtime().status();
    let refused = b.board.link_rx().counters().wrong_session - before.wrong_session;
    println!(
        "second master: Hello refused (NotOwner), {refused} frames refused as wrong_session, \
         platform moved {:.4} mm (from the start {:.4} mm)",
        moved * 1e3,
        (b.board.truth().pose.t - start).norm() * 1e3
    );
    assert_eq!(refused, 53);
    assert_eq!(after.stop, StopStatus::SafeOperatingStop);
    assert!(!b.board.runtime().session().operator_present());
    assert!(moved <= STILL_M, "moved {moved} m");
    assert!((b.board.truth().pose.t - start).norm() <= STILL_M);
    // The owner's next frames are taken.
    b.command(&MasterToBoard::OperatorPresent { present: true })
        .unwrap();
    b.run_ms(50).unwrap();
    let t = target_at(&b, 0.002, b.now_us());
    b.command(&t).unwrap();
    b.run_ms(1500).unwrap();
    assert_eq!(b.board.runtime().status().stop, StopStatus::None);
    let moved = (b.board.truth().pose.t - start).norm();
    assert!(
        (moved - 0.002).abs() < 0.1e-3,
        "the owner's target: {moved} m"
    );
}

/// Property: the bytes of a `[Hello, Enable]` recorded from an earlier connection and
/// replayed from a new one, while another master owns the enabled robot, enable nothing
/// and move nothing (the recorded `Hello` is another master's: `NotOwner`; the recorded
/// `Enable` is of a session the board no longer has); the owner's own `Hello` replayed is
/// refused as `ReplayedHello` and its session stays; the owner keeps control. Replayed
/// while the robot is disabled, the recording still enables nothing.
#[test]
fn a_recorded_hello_and_enable_replayed_from_a_new_connection_cannot_act() {
    const EARLIER: u32 = 0x0E44_11E4;
    let mut b = bench_with(None, EARLIER);
    // The earlier connection: its Hello and Enable, recorded on the wire.
    let hello = b.hello_msg();
    let (_, hello_bytes) = b.master.frame(&hello);
    b.send_raw(&hello_bytes);
    b.run_ms(20).unwrap();
    b.command(&MasterToBoard::Home { rehome: false }).unwrap();
    b.run_until("homed", 120_000, |s| {
        s.runtime().state() == RobotState::Ready
    })
    .unwrap();
    b.run_ms(100).unwrap();
    b.command(&MasterToBoard::OperatorPresent { present: true })
        .unwrap();
    let (_, enable_bytes) = b.master.frame(&MasterToBoard::Enable);
    b.send_raw(&enable_bytes);
    b.run_until("enabled", 2_000, |s| {
        s.runtime().state() == RobotState::Enabled
    })
    .unwrap();
    // It leaves: disable; the owner (a new master) takes over and enables.
    b.command(&MasterToBoard::Disable).unwrap();
    b.run_until("ready", 3_000, |s| {
        s.runtime().mode().kind() == control::modes::ModeKind::Ready
    })
    .unwrap();
    b.master = SimMaster::new(OWNER);
    let hello = b.hello_msg();
    assert_eq!(b.request(&hello, 100).unwrap(), None);
    let (_, owner_hello_bytes) = {
        // (The owner's Hello bytes as an eavesdropper records them.)
        let seq = b.master.next_seq().wrapping_sub(1);
        (seq, frame_in(&hello, 0, seq))
    };
    b.command(&MasterToBoard::OperatorPresent { present: true })
        .unwrap();
    b.command(&MasterToBoard::Enable).unwrap();
    b.run_until("enabled", 2_000, |s| {
        s.runtime().state() == RobotState::Enabled
    })
    .unwrap();
    b.run_ms(200).unwrap();
    let owner_session = b.master.session;
    let refusals = b.board.runtime().refusals();
    let wrong = b.board.link_rx().counters().wrong_session;
    // The replay, from a new connection: the recorded bytes as they were.
    let mut moved = 0.0f64;
    for bytes in [&hello_bytes, &enable_bytes, &owner_hello_bytes] {
        b.send_raw(bytes);
        moved = moved.max(motion_over(&mut b, 100));
    }
    let rt = b.board.runtime();
    println!(
        "replayed [Hello, Enable] and the owner's Hello: refusals +{}, wrong_session +{}, \
         moved {:.4} mm",
        rt.refusals() - refusals,
        b.board.link_rx().counters().wrong_session - wrong,
        moved * 1e3
    );
    assert_eq!(rt.refusals() - refusals, 2, "NotOwner and ReplayedHello");
    assert_eq!(b.board.link_rx().counters().wrong_session - wrong, 1);
    assert_eq!(rt.session().owner().map(|o| o.nonce), Some(OWNER));
    assert_eq!(b.board.link_rx().session(), Some(owner_session));
    assert!(moved <= STILL_M, "moved {moved} m");
    // The owner keeps control: its target is taken and followed.
    let start = b.board.truth().pose.t;
    let t = target_at(&b, 0.002, b.now_us());
    b.command(&t).unwrap();
    b.run_ms(1500).unwrap();
    let d = (b.board.truth().pose.t - start).norm();
    assert!((d - 0.002).abs() < 0.1e-3, "the owner's target: {d} m");

    // Replayed while the robot is disabled: the earlier master's Hello may take the board
    // (nobody is moving it), but its recorded Enable is of a dead session.
    b.command(&MasterToBoard::Disable).unwrap();
    b.run_until("ready", 3_000, |s| {
        s.runtime().mode().kind() == control::modes::ModeKind::Ready
    })
    .unwrap();
    b.run_ms(100).unwrap();
    b.send_raw(&hello_bytes);
    b.run_ms(20).unwrap();
    b.send_raw(&enable_bytes);
    let moved = motion_over(&mut b, 500);
    assert_eq!(b.board.runtime().state(), RobotState::Ready);
    assert!(moved <= STILL_M, "moved {moved} m");
}

/// Property: one frame in the owner's session with a sequence number 30,000 ahead is
/// refused (`out_of_order`) without moving the reference: the owner's next frames are
/// taken, its stream goes on, and the robot does not stop.
#[test]
fn a_frame_far_ahead_locks_nobody_out() {
    let mut b = bench_with(None, OWNER);
    b.bring_up().unwrap();
    let ooo = b.board.link_rx().counters().out_of_order;
    let far = b.master.next_seq().wrapping_add(30_000);
    b.send_raw(&frame_in(&MasterToBoard::Heartbeat, b.master.session, far));
    b.tick().unwrap();
    assert_eq!(b.board.link_rx().counters().out_of_order, ooo + 1);
    // The owner streams on for a second (heartbeats every 50 ms, targets at 100 Hz).
    let mut acked = 0;
    for k in 0..100 {
        let t = target_at(&b, 0.00002 * k as f32, b.now_us());
        if b.request(&t, 10).unwrap().is_none() {
            acked += 1;
        }
    }
    b.run_ms(600).unwrap();
    let st = b.board.runtime().status();
    println!(
        "after a frame 30,000 ahead: {acked} of 100 targets taken, state {:?}, stop {:?}",
        st.state, st.stop
    );
    assert_eq!(acked, 100);
    assert_eq!(st.state, RobotState::Enabled);
    assert_eq!(st.stop, StopStatus::None);
    assert_eq!(st.fault.cause, master_link::FaultCause::None);
}

/// Property: a target stamped `u64::MAX`, and one stamped 1 s ahead of the master's
/// clock, are refused with `TargetFromFuture`; the next 300 valid targets are all taken.
#[test]
fn targets_from_the_future_are_refused_and_poison_nothing() {
    let mut b = bench_with(None, OWNER);
    b.bring_up().unwrap();
    for stamp in [u64::MAX, b.now_us() + 1_000_000] {
        let t = target_at(&b, 0.0, stamp);
        assert_eq!(
            b.request(&t, 10).unwrap(),
            Some(NackReason::TargetFromFuture),
            "stamp {stamp}"
        );
    }
    let mut taken = 0;
    for k in 0..300 {
        let t = target_at(&b, 0.00001 * (k % 50) as f32, b.now_us());
        if b.request(&t, 10).unwrap().is_none() {
            taken += 1;
        }
    }
    println!("after two targets from the future: {taken} of the next 300 taken");
    assert_eq!(taken, 300);
    assert_eq!(b.board.runtime().state(), RobotState::Enabled);
}

fn key(b: u8) -> LinkKey {
    LinkKey::new(&[b; master_link::KEY_LEN])
}

/// Property: on a board with a key, a master with the key works end to end (hello, home,
/// enable, a target followed); frames with a wrong tag, without a tag, or of a master
/// without the key are dropped and counted (`bad_tag`) and change nothing; a master
/// without the key gets no answer at all.
#[test]
fn a_keyed_link_takes_only_tagged_frames() {
    let mut b = bench_with(Some(key(0x5a)), OWNER);
    b.bring_up().unwrap();
    let start = b.board.truth().pose.t;
    let t = target_at(&b, 0.002, b.now_us());
    b.command(&t).unwrap();
    b.run_ms(1500).unwrap();
    let d = (b.board.truth().pose.t - start).norm();
    assert!((d - 0.002).abs() < 0.1e-3, "followed: {d} m");
    let bad0 = b.board.link_rx().counters().bad_tag;
    // Without a tag, with another key, and the owner's own frame with its tag cut.
    let session = b.master.session;
    let seq = b.master.next_seq();
    let disable = MasterToBoard::Disable;
    let wrong_key = key(0x5b);
    b.send_raw(&frame_in(&disable, session, seq));
    b.send_raw(&frame_keyed(&disable, session, seq, Some(&wrong_key)));
    b.others.push(SimMaster::new(INTRUDER));
    b.others
        .push(SimMaster::with_key(INTRUDER + 1, Some(wrong_key)));
    let hello = MasterToBoard::Hello {
        protocol_version: PROTOCOL_VERSION,
        nonce: INTRUDER,
        clock_us: b.now_us(),
    };
    let s0 = other_sends(&mut b, 0, &hello);
    let s1 = other_sends(&mut b, 1, &hello);
    let moved = motion_over(&mut b, 300);
    assert!(!b.others[0].replies.contains_key(&s0) && b.others[0].hello.is_none());
    assert!(!b.others[1].replies.contains_key(&s1) && b.others[1].hello.is_none());
    let c = b.board.link_rx().counters();
    println!(
        "keyed link: {} frames dropped for their tag, moved {:.4} mm",
        c.bad_tag - bad0,
        moved * 1e3
    );
    assert_eq!(c.bad_tag - bad0, 4);
    assert_eq!(b.board.runtime().state(), RobotState::Enabled);
    assert!(moved <= STILL_M);
    // The status reports the count; the owner carries on.
    b.run_ms(40).unwrap();
    assert_eq!(b.master.last_status().unwrap().link.bad_tag, c.bad_tag);
    b.command(&MasterToBoard::Disable).unwrap();

    // A master without the key, alone on a keyed board: its Hello goes unanswered.
    let mut lone = bench_with(Some(key(0x5a)), OWNER);
    lone.master = SimMaster::new(OWNER);
    let hello = lone.hello_msg();
    assert!(lone.request(&hello, 200).is_err(), "no answer");
    // (Its Hello and its heartbeats, all dropped.)
    assert!(lone.board.link_rx().counters().bad_tag >= 1);
    assert!(!lone.board.link_rx().connected());
}

/// Property: frames the link took in the owner's session before another master's `Hello`
/// was accepted, but that the runtime reaches after it (both queued for the same tick),
/// are refused (`NotOwner`): a `Home` or an `Enable` of the displaced owner starts no
/// motion, and the new owner holds the board.
#[test]
fn the_displaced_owners_frames_queued_with_the_takeover_are_refused() {
    let mut b = bench_with(None, OWNER);
    b.bring_up().unwrap();
    b.command(&MasterToBoard::Disable).unwrap();
    b.run_ms(1_500).unwrap();
    assert_eq!(b.board.runtime().status().state, RobotState::Ready);
    b.others.push(SimMaster::new(INTRUDER));
    let hello = MasterToBoard::Hello {
        protocol_version: PROTOCOL_VERSION,
        nonce: INTRUDER,
        clock_us: b.now_us(),
    };
    let start = b.board.truth().pose.t;
    let hello_seq = other_sends(&mut b, 0, &hello);
    // The owner's frames on the line in the same period, after the Hello.
    let home = b.send(&MasterToBoard::Home { rehome: true });
    let enable = b.send(&MasterToBoard::Enable);
    b.tick().unwrap();
    assert!(
        matches!(
            b.others[0].hello,
            Some(BoardToMaster::HelloReply {
                nonce: INTRUDER,
                ..
            })
        ),
        "the second master's Hello {hello_seq}: {:?}",
        b.others[0].hello
    );
    // The answers go out in the new session (the displaced owner's link no longer
    // decodes them): read on the new owner's side.
    for seq in [home, enable] {
        let r = b.others[0].replies.get(&seq).map(|r| r.1);
        assert_eq!(
            r,
            Some(BoardToMaster::Nack {
                seq,
                reason: NackReason::NotOwner
            }),
            "the displaced owner's frame {seq}"
        );
    }
    let moved = motion_over(&mut b, 500);
    let status = b.board.runtime().status();
    println!(
        "displaced owner's Home and Enable: refused (NotOwner); state {:?}, platform moved {:.4} mm",
        status.state,
        moved.max((b.board.truth().pose.t - start).norm()) * 1e3
    );
    assert_eq!(status.state, RobotState::Ready);
    assert_eq!(
        b.board.runtime().session().owner().map(|o| o.nonce),
        Some(INTRUDER)
    );
    assert!(moved <= STILL_M, "moved {moved} m");
}
