//! A master in the same process as the simulated board ([`crate::board::BoardSim`]),
//! speaking the wire protocol in virtual time: a session, sequence numbers, heartbeats
//! every 50 ms, requests matched with their replies, the status reports recorded. The
//! campaigns and the tests drive the board through it exactly as a master on the serial
//! line would.

use std::collections::HashMap;

use master_link::{
    encode_with, BoardToMaster, EventEntry, EventLogPage, FaultLogPage, Header, LinkKey,
    MasterDecoder, MasterToBoard, NackReason, RobotState, Seq, SeqCounter, StatusReport,
    EVENT_LOG_PAGE, MAX_FRAME_LEN, PROTOCOL_VERSION,
};
use thiserror::Error;

use crate::board::{BoardSim, BoardSimError};

/// Why a bench step failed.
#[derive(Debug, Error)]
pub enum BenchError {
    #[error(transparent)]
    Board(#[from] BoardSimError),
    #[error("no reply to {request} within {timeout_ms} ms")]
    NoReply { request: String, timeout_ms: u64 },
    #[error("{request} refused: {reason:?}")]
    Refused { request: String, reason: NackReason },
    #[error("{what} not reached within {timeout_ms} ms (state {state:?}, fault {fault})")]
    Timeout {
        what: &'static str,
        timeout_ms: u64,
        state: RobotState,
        fault: String,
    },
}

/// One status report and when the master received it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StatusRow {
    /// Virtual time, µs.
    pub t_us: u64,
    /// The report.
    pub status: StatusReport,
}

/// The master's side of the link.
pub struct SimMaster {
    /// The master's nonce (its identity for the connection).
    pub nonce: u32,
    /// The session the board issued (its `HelloReply`; 0 before one).
    pub session: u32,
    /// The link key, if the link has one.
    pub key: Option<LinkKey>,
    seq: SeqCounter,
    rx: MasterDecoder,
    /// Every status report received.
    pub statuses: Vec<StatusRow>,
    /// Replies by the sequence number of the request they answer.
    pub replies: HashMap<Seq, (u64, BoardToMaster)>,
    /// The last `HelloReply`.
    pub hello: Option<BoardToMaster>,
    /// `HelloReply`s received.
    pub hellos: usize,
    /// Fault-log pages received.
    pub fault_logs: Vec<FaultLogPage>,
    /// Event-log pages received.
    pub event_logs: Vec<EventLogPage>,
    /// The commissioning records received (answers to `Commission`), in order.
    pub commissioning: Vec<master_link::CommissionRecord>,
    /// Every refused target, with what refused it.
    pub refused: Vec<master_link::RefusedTarget>,
}

impl SimMaster {
    /// A master with the nonce `nonce`, without a key.
    pub fn new(nonce: u32) -> Self {
        Self::with_key(nonce, None)
    }

    /// A master with the nonce `nonce` and the link key `key`.
    pub fn with_key(nonce: u32, key: Option<LinkKey>) -> Self {
        SimMaster {
            nonce,
            session: 0,
            rx: MasterDecoder::with_key(key.clone()),
            key,
            seq: SeqCounter::new(1),
            statuses: Vec::new(),
            replies: HashMap::new(),
            hello: None,
            hellos: 0,
            fault_logs: Vec::new(),
            event_logs: Vec::new(),
            commissioning: Vec::new(),
            refused: Vec::new(),
        }
    }

    /// `msg` as the next frame: its sequence number and bytes.
    pub fn frame(&mut self, msg: &MasterToBoard) -> (Seq, Vec<u8>) {
        let seq = self.seq.next();
        (seq, frame_keyed(msg, self.session, seq, self.key.as_ref()))
    }

    /// The sequence number the next frame gets.
    pub fn next_seq(&self) -> Seq {
        self.seq.peek()
    }

    /// Bytes from the board at `t_us`.
    pub fn receive(&mut self, t_us: u64, bytes: &[u8]) {
        // Byte by byte: a HelloReply opens its session before the frames after it.
        for &byte in bytes {
            let Some(Ok((reply_seq, msg))) = self.rx.push(byte) else {
                continue;
            };
            match msg {
                BoardToMaster::Status(status) => self.statuses.push(StatusRow { t_us, status }),
                // Its own HelloReply (the nonce echoed) opens the session the board issued.
                BoardToMaster::HelloReply { session, nonce, .. } if nonce == self.nonce => {
                    self.session = session;
                    self.rx.open_session(session, reply_seq);
                    self.hello = Some(msg);
                    self.hellos += 1;
                }
                BoardToMaster::HelloReply { .. } => {}
                BoardToMaster::HelloRefused { seq, nonce, .. } if nonce == self.nonce => {
                    self.replies.insert(seq, (t_us, msg));
                }
                BoardToMaster::HelloRefused { .. } => {}
                BoardToMaster::Ack { seq }
                | BoardToMaster::Nack { seq, .. }
                | BoardToMaster::GeometryStored { seq, .. }
                | BoardToMaster::GeometryRefused { seq, .. } => {
                    self.replies.insert(seq, (t_us, msg));
                }
                BoardToMaster::FaultLog(page) => self.fault_logs.push(page),
                BoardToMaster::EventLog(page) => self.event_logs.push(page),
                BoardToMaster::Commissioning(record) => self.commissioning.push(record),
                BoardToMaster::TargetRefused(r) => {
                    if let Some(seq) = r.reply_to {
                        self.replies.insert(seq, (t_us, msg));
                    }
                    self.refused.push(r);
                }
            }
        }
    }

    /// The last status report.
    pub fn last_status(&self) -> Option<&StatusReport> {
        self.statuses.last().map(|r| &r.status)
    }
}

/// `msg` framed in `session` with sequence number `seq` (replays, old sessions).
pub fn frame_in(msg: &MasterToBoard, session: u32, seq: Seq) -> Vec<u8> {
    frame_keyed(msg, session, seq, None)
}

/// `msg` framed in `session` with sequence number `seq`, tagged with `key` if any.
pub fn frame_keyed(msg: &MasterToBoard, session: u32, seq: Seq, key: Option<&LinkKey>) -> Vec<u8> {
    let mut buf = [0u8; MAX_FRAME_LEN];
    match encode_with(msg, Header { session, seq }, key, &mut buf) {
        Ok(n) => buf.get(..n).unwrap_or_default().to_vec(),
        Err(_) => Vec::new(),
    }
}

/// The board and the master, in lockstep: the master's frames reach the board before the
/// board's next tick, the board's reach the master after it.
pub struct Bench {
    /// The board.
    pub board: BoardSim,
    /// The master.
    pub master: SimMaster,
    /// Other masters on the same line: they hear everything the board sends, and what
    /// they send goes through [`Bench::send_raw`] (a shared serial line, a second
    /// connection).
    pub others: Vec<SimMaster>,
    /// The master sends heartbeats (every 50 ms).
    pub heartbeat: bool,
    /// Bytes are delivered (false: the cable is cut both ways).
    pub link_up: bool,
    last_beat_us: u64,
}

/// The heartbeat period of the bench's master, µs.
pub const HEARTBEAT_US: u64 = 50_000;

impl Bench {
    /// The master around `board`, with the nonce `nonce` and the board's link key.
    pub fn new(board: BoardSim, nonce: u32) -> Self {
        let key = board.config().key.clone();
        Bench {
            board,
            master: SimMaster::with_key(nonce, key),
            others: Vec::new(),
            heartbeat: true,
            link_up: true,
            last_beat_us: 0,
        }
    }

    /// Virtual time, µs.
    pub fn now_us(&self) -> u64 {
        self.board.now_us()
    }

    /// Sends raw bytes to the board (garbage, replays).
    pub fn send_raw(&mut self, bytes: &[u8]) {
        if self.link_up {
            self.board.receive(bytes);
        }
    }

    /// Sends `msg`; its sequence number.
    pub fn send(&mut self, msg: &MasterToBoard) -> Seq {
        let (seq, bytes) = self.master.frame(msg);
        self.send_raw(&bytes);
        seq
    }

    /// One control period: a heartbeat when due, the board's tick, its output to the
    /// master.
    pub fn tick(&mut self) -> Result<(), BenchError> {
        let now = self.now_us();
        if self.heartbeat && now >= self.last_beat_us + HEARTBEAT_US {
            self.last_beat_us = now;
            self.send(&MasterToBoard::Heartbeat);
        }
        self.board.tick()?;
        let out = self.board.take_output();
        if self.link_up {
            let now = self.board.now_us();
            self.master.receive(now, &out);
            for m in &mut self.others {
                m.receive(now, &out);
            }
        }
        Ok(())
    }

    /// Runs `ms` control periods (1 kHz).
    pub fn run_ms(&mut self, ms: u64) -> Result<(), BenchError> {
        for _ in 0..ms {
            self.tick()?;
        }
        Ok(())
    }

    /// Sends `msg` and runs until its reply (at most `timeout_ms`): `None` for an Ack (or
    /// the answer of a `Hello` / `StatusRequest` / `FaultLogRequest` / `EventLogRequest`),
    /// the reason of a Nack.
    pub fn request(
        &mut self,
        msg: &MasterToBoard,
        timeout_ms: u64,
    ) -> Result<Option<NackReason>, BenchError> {
        let answered_by_kind = matches!(
            msg,
            MasterToBoard::Hello { .. }
                | MasterToBoard::StatusRequest
                | MasterToBoard::FaultLogRequest { .. }
                | MasterToBoard::EventLogRequest { .. }
        );
        let (hellos, logs, events, statuses) = (
            self.master.hellos,
            self.master.fault_logs.len(),
            self.master.event_logs.len(),
            self.master.statuses.len(),
        );
        let seq = self.send(msg);
        for _ in 0..timeout_ms {
            self.tick()?;
            if let Some((_, reply)) = self.master.replies.get(&seq) {
                return Ok(match reply {
                    BoardToMaster::Nack { reason, .. }
                    | BoardToMaster::HelloRefused { reason, .. } => Some(*reason),
                    BoardToMaster::TargetRefused(r) => Some(r.reason),
                    _ => None,
                });
            }
            if answered_by_kind {
                let answered = match msg {
                    MasterToBoard::Hello { .. } => self.master.hellos > hellos,
                    MasterToBoard::FaultLogRequest { .. } => self.master.fault_logs.len() > logs,
                    MasterToBoard::EventLogRequest { .. } => self.master.event_logs.len() > events,
                    _ => self.master.statuses.len() > statuses,
                };
                if answered {
                    return Ok(None);
                }
            }
        }
        Err(BenchError::NoReply {
            request: format!("{msg:?}"),
            timeout_ms,
        })
    }

    /// Sends `msg`; an error unless the board acknowledges it.
    pub fn command(&mut self, msg: &MasterToBoard) -> Result<(), BenchError> {
        match self.request(msg, 200)? {
            None => Ok(()),
            Some(reason) => Err(BenchError::Refused {
                request: format!("{msg:?}"),
                reason,
            }),
        }
    }

    /// Runs until `done` holds for the runtime's state (at most `timeout_ms`).
    pub fn run_until(
        &mut self,
        what: &'static str,
        timeout_ms: u64,
        mut done: impl FnMut(&BoardSim) -> bool,
    ) -> Result<u64, BenchError> {
        for ms in 0..timeout_ms {
            if done(&self.board) {
                return Ok(ms);
            }
            self.tick()?;
        }
        let st = self.board.runtime().status();
        Err(BenchError::Timeout {
            what,
            timeout_ms,
            state: st.state,
            fault: format!("{:?}", st.fault),
        })
    }

    /// The master's `Hello` now (its clock: the board's virtual time).
    pub fn hello_msg(&self) -> MasterToBoard {
        MasterToBoard::Hello {
            protocol_version: PROTOCOL_VERSION,
            nonce: self.master.nonce,
            clock_us: self.now_us(),
        }
    }

    /// Hello, Home (with the park move), the operator present, Enable (brake check and
    /// release): the robot following, at the park pose.
    pub fn bring_up(&mut self) -> Result<(), BenchError> {
        let hello = self.hello_msg();
        if let Some(reason) = self.request(&hello, 100)? {
            return Err(BenchError::Refused {
                request: format!("{hello:?}"),
                reason,
            });
        }
        self.command(&MasterToBoard::Home { rehome: false })?;
        self.run_until("homed", 120_000, |b| {
            b.runtime().state() != RobotState::Homing
        })?;
        if self.board.runtime().state() != RobotState::Ready {
            let st = self.board.runtime().status();
            return Err(BenchError::Timeout {
                what: "Ready after homing",
                timeout_ms: 0,
                state: st.state,
                fault: format!("{:?}", st.fault),
            });
        }
        // The stop that ends homing applies the brakes first.
        self.run_ms(100)?;
        self.command(&MasterToBoard::OperatorPresent { present: true })?;
        self.command(&MasterToBoard::Enable)?;
        self.run_until("Enabled", 2_000, |b| {
            b.runtime().state() == RobotState::Enabled
        })?;
        Ok(())
    }

    /// Opens a session (`Hello`) and reads the board's event log page by page: every
    /// entry the board holds, oldest first, and the last page's header.
    pub fn read_event_log(&mut self) -> Result<(Vec<EventEntry>, EventLogPage), BenchError> {
        let hello = self.hello_msg();
        self.request(&hello, 100)?;
        let mut entries = Vec::new();
        let mut first = 0u16;
        loop {
            self.request(&MasterToBoard::EventLogRequest { first }, 100)?;
            let Some(page) = self.master.event_logs.last().copied() else {
                return Err(BenchError::NoReply {
                    request: "EventLogRequest".into(),
                    timeout_ms: 100,
                });
            };
            let n = usize::from(page.count).min(EVENT_LOG_PAGE);
            entries.extend(page.entries.iter().take(n).copied());
            first = first.saturating_add(u16::from(page.count));
            if page.count == 0 || first >= page.len {
                return Ok((entries, page));
            }
        }
    }

    /// A power cycle of the board (`BoardSim::power_cycle`: a new board on the same flash)
    /// with a new master of session `session` (nothing said yet).
    pub fn power_cycle(self, session: u32) -> Result<Bench, BenchError> {
        Ok(Bench::new(self.board.power_cycle()?, session))
    }
}
