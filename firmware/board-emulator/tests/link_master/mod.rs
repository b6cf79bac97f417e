//! A small master for the emulator's own tests, on the board's clock: it speaks the wire
//! protocol (`master-link`: a `Hello`, then frames of the session the board issued, a
//! `Heartbeat` every 20 ms of board time) through the bench's link, turn by turn, and keeps
//! the latest `Status` and every other reply. No key: the images the tests run are built
//! without `RSPR_LINK_KEY`.
#![allow(dead_code, clippy::unwrap_used, clippy::expect_used)]

use board_emulator::bench::{Action, Bench, BenchError};
use master_link::{
    decode_frame, encode, BoardToMaster, Header, MasterToBoard, SeqCounter, StatusReport,
    MAX_FRAME_LEN, PROTOCOL_VERSION,
};
use rigless::time::VirtualNanos;

/// Nanoseconds per millisecond.
pub const MS: u64 = 1_000_000;

/// The master: the bench, its session, its sequence numbers and what the board said.
pub struct Master {
    /// The bench.
    pub bench: Bench,
    /// The session the board issued (0 before `HelloReply`).
    pub session: u32,
    seq: SeqCounter,
    rx: Vec<u8>,
    /// The latest status.
    pub status: Option<StatusReport>,
    /// Every message but `Status`, with its instant, not yet taken.
    pub replies: Vec<(VirtualNanos, BoardToMaster)>,
    last_heartbeat: u64,
    /// The master's turn, ns of board time.
    pub turn_ns: u64,
    /// A jog sent with every heartbeat, while set.
    pub jog: Option<(u8, f32)>,
    /// The outputs on the pins at the end of every turn, with its instant (kept while
    /// `sampling`).
    pub samples: Vec<(u64, board_emulator::board::Outputs)>,
    /// Keep `samples`.
    pub sampling: bool,
}

impl Master {
    /// Wraps a started bench.
    pub fn new(bench: Bench) -> Self {
        Master {
            bench,
            session: 0,
            seq: SeqCounter::new(1),
            rx: Vec::new(),
            status: None,
            replies: Vec::new(),
            last_heartbeat: 0,
            turn_ns: MS,
            jog: None,
            samples: Vec::new(),
            sampling: false,
        }
    }

    /// Board time now, ns.
    pub fn now(&self) -> u64 {
        self.bench.now().0
    }

    /// Queues `msg` for the link, in the session.
    pub fn send(&mut self, msg: &MasterToBoard) {
        let header = Header {
            session: self.session,
            seq: self.seq.next(),
        };
        let mut buf = [0u8; MAX_FRAME_LEN];
        let n = encode(msg, header, &mut buf).expect("a master frame encodes");
        self.bench.act(Action::Send(buf[..n].to_vec()));
    }

    fn take_bytes(&mut self) {
        for (at, b) in std::mem::take(&mut self.bench.received) {
            if b != 0 {
                self.rx.push(b);
                continue;
            }
            let mut frame = std::mem::take(&mut self.rx);
            if frame.is_empty() {
                continue;
            }
            if let Ok((_, msg)) = decode_frame::<BoardToMaster>(&mut frame) {
                match msg {
                    BoardToMaster::Status(s) => self.status = Some(s),
                    other => self.replies.push((at, other)),
                }
            }
        }
    }

    /// One turn: the heartbeat (and the jog) when due, then the board runs `turn_ns`.
    pub fn turn(&mut self) -> Result<(), BenchError> {
        let now = self.now();
        if self.session != 0 && now >= self.last_heartbeat + 20 * MS {
            self.last_heartbeat = now;
            self.send(&MasterToBoard::Heartbeat);
            if let Some((joint, velocity)) = self.jog {
                self.send(&MasterToBoard::Jog { joint, velocity });
            }
        }
        self.bench.run_for(self.turn_ns)?;
        if self.sampling {
            self.samples.push((self.now(), self.bench.last.outputs));
        }
        self.take_bytes();
        Ok(())
    }

    /// Runs `ms` of board time.
    pub fn run_ms(&mut self, ms: u64) -> Result<(), BenchError> {
        let until = self.now() + ms * MS;
        while self.now() < until {
            self.turn()?;
        }
        Ok(())
    }

    /// Runs until `done` holds of the master (checked every turn), at most `ms` of board
    /// time; true if it held.
    pub fn run_until(
        &mut self,
        ms: u64,
        mut done: impl FnMut(&Master) -> bool,
    ) -> Result<bool, BenchError> {
        let until = self.now() + ms * MS;
        while self.now() < until {
            self.turn()?;
            if done(self) {
                return Ok(true);
            }
        }
        Ok(false)
    }

    /// `Hello` until the board answers (the image boots meanwhile): the session, and the
    /// reply.
    pub fn hello(&mut self, nonce: u32) -> Result<BoardToMaster, BenchError> {
        let deadline = self.now() + 2_000 * MS;
        while self.now() < deadline {
            let clock_us = self.now() / 1_000;
            self.session = 0;
            self.send(&MasterToBoard::Hello {
                protocol_version: PROTOCOL_VERSION,
                nonce,
                clock_us,
            });
            let answered = self.run_until(100, |m| {
                m.replies
                    .iter()
                    .any(|(_, r)| matches!(r, BoardToMaster::HelloReply { .. }))
            })?;
            if answered {
                let i = self
                    .replies
                    .iter()
                    .position(|(_, r)| matches!(r, BoardToMaster::HelloReply { .. }))
                    .expect("answered");
                let (_, reply) = self.replies.remove(i);
                if let BoardToMaster::HelloReply { session, .. } = reply {
                    self.session = session;
                }
                return Ok(reply);
            }
        }
        panic!("no HelloReply within 2 s of board time");
    }

    /// Sends `msg` and runs until the board answers it (its `Ack`, `Nack` or other reply
    /// naming the frame's sequence number, or any `Geometry*`), at most `ms`.
    pub fn command(
        &mut self,
        msg: &MasterToBoard,
        ms: u64,
    ) -> Result<Option<BoardToMaster>, BenchError> {
        let seq = self.seq.peek();
        self.send(msg);
        let answers = |r: &BoardToMaster| match r {
            BoardToMaster::Ack { seq: s } | BoardToMaster::Nack { seq: s, .. } => *s == seq,
            BoardToMaster::GeometryStored { seq: s, .. }
            | BoardToMaster::GeometryRefused { seq: s, .. } => *s == seq,
            _ => false,
        };
        self.run_until(ms, |m| m.replies.iter().any(|(_, r)| answers(r)))?;
        Ok(self
            .replies
            .iter()
            .position(|(_, r)| answers(r))
            .map(|i| self.replies.remove(i).1))
    }

    /// The state in the latest status.
    pub fn state(&self) -> Option<master_link::RobotState> {
        self.status.map(|s| s.state)
    }
}
