#![allow(clippy::unwrap_used, clippy::expect_used)]
//! A board that answers Hello late (still booting, or an emulator behind the wall clock)
//! still opens the session: the master takes a HelloReply for its own nonce that comes
//! after its request timed out, and the console, left without a session by the timeout,
//! says Hello again.
//!
//! The fake board here (the board side of the real link, `control::link`) answers a Hello
//! only 1.5 s after it arrived, by its own clock, and the master's request times out after
//! 1 s ([`operator::board::REPLY_TIMEOUT_S`]) by the master's. On a loaded host the
//! timeout may come after the answer: then the answer is an ordinary one, and the property
//! checked (one HelloReply reaches the front end, after any NoReply) holds the same.

use control::link::{Answer, Inbound, LinkRx, LinkTx};
use master_link::{
    BoardToMaster, FirmwareVersion, MasterToBoard, ResetCause, ResetStatus, StatusReport,
    MAX_FRAME_LEN,
};
use operator::board::REPLY_TIMEOUT_S;
use operator::{Board, BoardEvent, Outcome};
use std::io::{Read, Write};
use std::os::unix::net::{UnixListener, UnixStream};
use std::time::{Duration, Instant};

/// Answers every Hello 1.5 s after it arrived; nothing else.
fn slow_board(mut stream: UnixStream) {
    let mut rx = LinkRx::new();
    let mut tx = LinkTx::new();
    let version = FirmwareVersion {
        major: 1,
        minor: 0,
        patch: 0,
    };
    let _ = stream.set_read_timeout(Some(Duration::from_millis(5)));
    let mut due: Vec<(Instant, BoardToMaster)> = Vec::new();
    let mut buf = [0u8; 512];
    let mut frame = [0u8; MAX_FRAME_LEN];
    loop {
        match stream.read(&mut buf) {
            Ok(0) => return,
            Ok(n) => rx.feed(&buf[..n], |inbound| {
                if let Inbound::Request(req) = inbound {
                    if let MasterToBoard::Hello { nonce, .. } = req.message {
                        let reply = req.reply(
                            Ok(Answer::Hello {
                                nonce,
                                reset: ResetStatus {
                                    cause: ResetCause::PowerOn,
                                    acknowledged: true,
                                },
                                geometry_version: 0,
                            }),
                            &StatusReport::default(),
                            version,
                        );
                        due.push((Instant::now() + Duration::from_millis(1500), reply));
                    }
                }
            }),
            Err(e)
                if e.kind() == std::io::ErrorKind::WouldBlock
                    || e.kind() == std::io::ErrorKind::TimedOut => {}
            Err(_) => return,
        }
        let now = Instant::now();
        while let Some(i) = due.iter().position(|(t, _)| *t <= now) {
            let (_, m) = due.remove(i);
            let Ok(n) = tx.encode(&m, &mut frame) else {
                continue;
            };
            if stream.write_all(&frame[..n]).is_err() {
                return;
            }
        }
    }
}

/// What the front end saw of its Hello: (NoReply times, HelloReply times), s.
fn hello_outcomes(events: &[BoardEvent]) -> (Vec<f64>, Vec<f64>) {
    let mut none = Vec::new();
    let mut replies = Vec::new();
    for e in events {
        if let BoardEvent::Reply(r) = e {
            if matches!(r.request, MasterToBoard::Hello { .. }) {
                match r.outcome {
                    Outcome::NoReply => none.push(r.t_s),
                    Outcome::HelloReply(_) => replies.push(r.t_s),
                    o => panic!("a Hello answered with {o:?}"),
                }
            }
        }
    }
    (none, replies)
}

/// The master's side: one Hello, then 3 s of polling. Exactly one HelloReply reaches the
/// front end, after any NoReply, and the session is known (`hello_info`).
#[test]
fn a_late_hello_reply_still_opens_the_session() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("board.sock");
    let listener = UnixListener::bind(&path).unwrap();
    let board_thread = std::thread::spawn(move || {
        let (s, _) = listener.accept().unwrap();
        slow_board(s);
    });
    let mut board = Board::open(&path, 0, Duration::from_secs(5)).unwrap();
    board.set_heartbeat(false);
    board.send_hello().unwrap();
    let mut events = Vec::new();
    let end = board.now_s() + 3.0;
    while board.now_s() < end {
        events.extend(board.poll(Duration::from_millis(10)).unwrap());
    }
    let (none, replies) = hello_outcomes(&events);
    assert_eq!(replies.len(), 1, "HelloReplies seen: {replies:?}");
    assert!(none.len() <= 1, "NoReply seen: {none:?}");
    if let Some(t) = none.first() {
        assert!(
            *t < replies[0],
            "the NoReply at {t} s came after the answer"
        );
        assert!(*t >= REPLY_TIMEOUT_S);
    }
    assert!(board.hello_info().is_some(), "the session is not known");
    // The board took the Hello's clock as the master's when it read it, 1.5 s late: a
    // target sent now is stamped no later than that clock plus the time since the
    // answer came (else the board would find it 1.5 s in its future).
    let (clock_us, answered_s) = events
        .iter()
        .find_map(|e| match e {
            BoardEvent::Reply(operator::board::Reply {
                request: MasterToBoard::Hello { clock_us, .. },
                outcome: Outcome::HelloReply(_),
                t_s,
                ..
            }) => Some((*clock_us, *t_s)),
            _ => None,
        })
        .unwrap();
    let pose = masters::CartesianPose::identity();
    let (_, stamp_us) = board.send_target(&pose).unwrap();
    let since_us = ((board.now_s() - answered_s) * 1e6) as u64;
    assert!(
        stamp_us <= clock_us + since_us + 1,
        "target stamped {stamp_us} µs; the Hello's clock {clock_us} µs, {since_us} µs since its answer"
    );
    drop(board);
    board_thread.join().unwrap();
}

/// The console, given the Hello's NoReply while it has no session, says Hello again; with
/// a session, it does not.
#[test]
fn the_console_says_hello_again_until_it_has_a_session() {
    let hello = MasterToBoard::Hello {
        protocol_version: master_link::PROTOCOL_VERSION,
        nonce: 7,
        clock_us: 0,
    };
    let no_reply = BoardEvent::Reply(operator::board::Reply {
        request: hello,
        seq: 1,
        sent_s: 0.0,
        t_s: 1.0,
        outcome: Outcome::NoReply,
    });
    let mut c = operator::console::Console::new("test");
    assert!(matches!(
        c.board_event(&no_reply),
        Some(MasterToBoard::Hello { .. })
    ));
    c.hello = Some(operator::board::HelloInfo {
        firmware: FirmwareVersion {
            major: 1,
            minor: 0,
            patch: 0,
        },
        protocol_version: master_link::PROTOCOL_VERSION,
        session: 1,
        reset: ResetStatus {
            cause: ResetCause::PowerOn,
            acknowledged: true,
        },
        geometry_version: 0,
    });
    assert_eq!(c.board_event(&no_reply), None);
}
