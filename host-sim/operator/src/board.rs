//! A live board for the operator's front ends: the link of the `teleop` crate (a Unix
//! socket or a serial device, the same code path for the simulated board, the emulator and
//! a real board), every request tracked until the board answers it, the latest status,
//! and the heartbeats.
//!
//! Unlike the scripted session of `host-sim teleop`, nothing here waits unless asked: a
//! front end sends requests, keeps polling, and receives each answer as a [`Reply`] when
//! it comes ([`Board::poll`]). [`Board::request`] waits for one answer (the bring-up
//! steps, the OpenIGTLink bridge's targets).
//!
//! The connection's clock is paced by the board's telemetry (`teleop::pacing`; the host's
//! with [`Board::set_paced`]`(false)`): the heartbeats, the stream, the target stamps, the
//! timeouts and the arrival times recorded follow the board's own time, so that an
//! emulated board that its host stalls never sees this master's targets as coming from
//! its future (its bound is 50 ms), nor its heartbeats late. On a real board the two
//! clocks agree. An emulated board that shares its clock beside its socket
//! (`board-emulator serve --clock-lead-ms`) gives this connection the board's own time,
//! and with [`Board::set_lockstep`] the board waits for this master as this master waits
//! for it (`teleop::pacing`).

use crate::conversions::wire_pose;
use master_link::{
    BoardToMaster, FaultLogPage, FirmwareVersion, MasterToBoard, NackReason, ResetCause,
    ResetStatus, RobotState, Seq, StatusReport, Warnings, PROTOCOL_VERSION,
};
use masters::CartesianPose;
use std::collections::VecDeque;
use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Duration;
use teleop::link::{self, Link, Received};
use teleop::pacing::{BoardClock, SharedClock, SILENCE_LIMIT_S};
use teleop::start::{self, StartOptions};
use thiserror::Error;

/// How long a request waits for its answer before it counts as unanswered, s.
pub const REPLY_TIMEOUT_S: f64 = 1.0;
/// Heartbeat period, s (the board holds after 100 ms without one while enabled).
pub const HEARTBEAT_PERIOD_S: f64 = 0.02;
/// In lockstep with a board that shares its clock, the longest a wait for the board's
/// messages lasts before this connection reads the clock again (and so tells the board it
/// runs), s: well under the board's lead over its master (2 ms in the tests).
pub const LOCKSTEP_WAIT_S: f64 = 0.0005;
/// How long the board refuses `Enable` with `Busy` after homing or a disable while its
/// brakes engage, with margin, s: [`Board::enable`] sends `Enable` again within it.
pub const ENABLE_BUSY_WINDOW_S: f64 = 1.0;

/// Why the board could not be brought up or could not serve a request.
#[derive(Debug, Error)]
pub enum BoardError {
    /// The link to the board (open, write, closed, silent).
    #[error(transparent)]
    Link(#[from] teleop::TeleopError),
    #[error("the board did not answer Hello within {timeout_s} s")]
    NoHello { timeout_s: f64 },
    #[error("the board speaks protocol version {board}, this master {master}")]
    Protocol { board: u8, master: u8 },
    #[error("no status from the board")]
    NoStatus,
    #[error("the board refused {request}: {}", refusal_text(*reason))]
    Refused { request: String, reason: NackReason },
    #[error("no answer to {request} within {} s", REPLY_TIMEOUT_S)]
    NoReply { request: String },
    #[error("{what} did not finish within {timeout_s} s")]
    Timeout { what: &'static str, timeout_s: f64 },
    #[error("the board is {state}, not Enabled: enable it first")]
    NotEnabled { state: String },
    #[error("the board is in Fault: {cause}")]
    Faulted { cause: String },
    /// A stop asked from outside (SIGINT, SIGTERM: [`crate::shutdown`]).
    #[error("stopped on request (a signal)")]
    Interrupted,
    /// The board's last reset is not acknowledged, and the person did not allow it.
    #[error("{}", teleop::start::unacknowledged_reset_text(*.0))]
    ResetNotAcknowledged(ResetCause),
    /// A latched fault the person did not allow to clear, or that would not clear.
    #[error("{0}")]
    FaultLatched(String),
    /// The robot runs under another master.
    #[error("{0}")]
    Busy(String),
    /// The board refused this master's Hello.
    #[error("{}", teleop::start::hello_refused_text(*.0))]
    HelloRefused(NackReason),
}

/// What a request came to.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Outcome {
    /// Accepted.
    Ack,
    /// Refused, with the board's reason.
    Refused(NackReason),
    /// A target refused at once by the board's supervisor, with the guard or rule and
    /// what it measured (`board_words::refusal` says it in words).
    TargetRefused(master_link::RefusedTarget),
    /// The answer to `Hello`.
    HelloReply(HelloInfo),
    /// The answer to `FaultLogRequest`.
    FaultLog(FaultLogPage),
    /// The answer to `EventLogRequest`.
    EventLog(master_link::EventLogPage),
    /// A calibrated geometry stored, with its version.
    GeometryStored(u32),
    /// A calibrated geometry refused, with the board's reason.
    GeometryRefused(master_link::GeometryRefusal),
    /// No answer within [`REPLY_TIMEOUT_S`].
    NoReply,
}

impl Outcome {
    /// The answer in words, for a person.
    pub fn words(&self) -> String {
        match self {
            Outcome::Ack => "accepted".into(),
            Outcome::Refused(r) => format!("refused: {}", board_words::reason(*r)),
            Outcome::TargetRefused(t) => format!("refused: {}", board_words::refusal(t)),
            Outcome::HelloReply(h) => format!(
                "hello: firmware {}.{}.{}, protocol {}",
                h.firmware.major, h.firmware.minor, h.firmware.patch, h.protocol_version
            ),
            Outcome::FaultLog(p) => format!("a fault log page of {} entries", p.count),
            Outcome::EventLog(p) => format!("an event log page of {} entries", p.count),
            Outcome::GeometryStored(v) => format!("calibrated geometry version {v} stored"),
            Outcome::GeometryRefused(r) => {
                format!("geometry refused: {}", board_words::geometry_refusal(*r))
            }
            Outcome::NoReply => format!("no answer within {REPLY_TIMEOUT_S} s"),
        }
    }
}

/// The board's `HelloReply`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HelloInfo {
    /// Firmware version.
    pub firmware: FirmwareVersion,
    /// Protocol version the board speaks.
    pub protocol_version: u8,
    /// The session it confirmed.
    pub session: u32,
    /// Its last reset and whether it was acknowledged.
    pub reset: ResetStatus,
    /// The version of its stored calibrated geometry (0: none, the nominal robot).
    pub geometry_version: u32,
}

/// A request and what it came to.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Reply {
    /// The request.
    pub request: MasterToBoard,
    /// Its sequence number.
    pub seq: Seq,
    /// When it was sent, s (the link's clock).
    pub sent_s: f64,
    /// When the answer came (or the request timed out), s.
    pub t_s: f64,
    /// The answer.
    pub outcome: Outcome,
}

/// Something the board sent, as a front end sees it. (Copy and a few hundred per second:
/// the size of its largest variant, a reply that may carry a calibrated geometry, is kept
/// inline rather than boxed.)
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum BoardEvent {
    /// A status report and its arrival time, s.
    Status(f64, StatusReport),
    /// The answer to a request.
    Reply(Reply),
    /// A target acknowledged before and refused by the board's path check since, with its
    /// arrival time, s.
    TargetRefused(f64, master_link::RefusedTarget),
}

/// A connected board.
pub struct Board {
    link: Link,
    name: String,
    pending: Vec<(Seq, MasterToBoard, f64)>,
    status: Option<(f64, StatusReport)>,
    hello: Option<HelloInfo>,
    heartbeat: bool,
    last_beat_s: f64,
    last_stamp_us: u64,
    /// How far this connection's clock ran past its `Hello`'s stamp before the board's
    /// answer came, µs: the board takes the `Hello`'s clock as the master's when it reads
    /// it, so a board that reads it late (still booting, an emulator stalled by its host)
    /// would find every later target that much in its future. Target stamps are taken
    /// back by it.
    stamp_offset_us: u64,
    backlog: VecDeque<BoardEvent>,
    deferred: VecDeque<BoardEvent>,
    statuses: u64,
    /// The clock is paced by the board's telemetry.
    paced: bool,
    clock: BoardClock,
    /// The longest interval between two heartbeats sent, s.
    beat_gap_max_s: f64,
    /// Set from outside (a signal): every wait ends with [`BoardError::Interrupted`].
    interrupt: Option<Arc<AtomicBool>>,
    /// Why the board refused this master's last Hello.
    hello_refused: Option<NackReason>,
    /// The last Hello sent (sequence number, message, when): a HelloReply for this
    /// connection's nonce that comes after the request timed out answers it still.
    last_hello: Option<(Seq, MasterToBoard, f64)>,
    /// Host times of the `StatusRequest`s sent and not answered yet.
    status_requests: VecDeque<f64>,
}

impl Board {
    /// Opens the board at `path`: a Unix socket (waited for until `timeout`: a board may
    /// still be starting) or a serial device at `baud`.
    pub fn open(path: &Path, baud: u32, timeout: Duration) -> Result<Self, BoardError> {
        Self::open_with_key(path, baud, timeout, None)
    }

    /// [`Board::open`] on a link with the pre-shared key `key` (None: no tags).
    pub fn open_with_key(
        path: &Path,
        baud: u32,
        timeout: Duration,
        key: Option<master_link::LinkKey>,
    ) -> Result<Self, BoardError> {
        let link = link::open_with_key(path, baud, timeout, key)?;
        Ok(Board {
            link,
            name: path.display().to_string(),
            pending: Vec::new(),
            status: None,
            hello: None,
            heartbeat: true,
            last_beat_s: f64::NEG_INFINITY,
            last_stamp_us: 0,
            stamp_offset_us: 0,
            backlog: VecDeque::new(),
            deferred: VecDeque::new(),
            statuses: 0,
            paced: true,
            // An emulated board may share its clock beside its socket; a serial device or
            // another board has none.
            clock: SharedClock::beside(path)
                .map_or_else(BoardClock::default, BoardClock::with_shared),
            beat_gap_max_s: 0.0,
            interrupt: None,
            hello_refused: None,
            last_hello: None,
            status_requests: VecDeque::new(),
        })
    }

    /// The socket or device.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// The clock of this connection, s since it was opened: the host's, or paced by the
    /// board ([`Board::set_paced`]).
    pub fn now_s(&self) -> f64 {
        self.clock.now_s(self.link.now_s(), self.paced)
    }

    /// Paces this connection's clock by the board's telemetry (`teleop::pacing`; on from
    /// the start): for an emulated board, whose virtual time slips behind the wall clock
    /// when its host stalls it. A board silent for [`SILENCE_LIMIT_S`] of host time then
    /// ends every wait with an error. Off: the host's clock.
    pub fn set_paced(&mut self, on: bool) {
        self.paced = on;
    }

    /// Lockstep with a board that shares its clock (`teleop::pacing`; off by default): this
    /// connection writes back every reading of the board's clock, and the board runs at
    /// most its lead beyond the last one, so that the board stands while this master's
    /// host holds it up. Every wait of this connection then lasts at most
    /// [`LOCKSTEP_WAIT_S`] at a time; a front end must keep polling (it does anyway, for
    /// the heartbeats). Without a shared clock (a real board, the simulated one), nothing.
    pub fn set_lockstep(&mut self, on: bool) {
        self.clock.set_lockstep(on);
    }

    /// The connection's clock is the board's own (a shared clock, paced).
    pub fn on_board_time(&self) -> bool {
        self.paced && self.clock.shares_board_time()
    }

    /// Ends every wait with [`BoardError::Interrupted`] once `flag` is set (None: never);
    /// [`Board::disable_within`] takes it off.
    pub fn set_interrupt(&mut self, flag: Option<Arc<AtomicBool>>) {
        self.interrupt = flag;
    }

    /// The latest status and its arrival time.
    pub fn status(&self) -> Option<&(f64, StatusReport)> {
        self.status.as_ref()
    }

    /// Statuses received so far.
    pub fn statuses_received(&self) -> u64 {
        self.statuses
    }

    /// The board's `HelloReply`, once received.
    pub fn hello_info(&self) -> Option<HelloInfo> {
        self.hello
    }

    /// The link: frames sent, the counters of the board → master direction.
    pub fn link(&self) -> &Link {
        &self.link
    }

    /// Heartbeats on (the default) or off.
    pub fn set_heartbeat(&mut self, on: bool) {
        if on && !self.heartbeat {
            // The pause is not a gap of this side's loop.
            self.last_beat_s = f64::NEG_INFINITY;
        }
        self.heartbeat = on;
    }

    /// The longest interval between two heartbeats sent so far, s (this connection's
    /// clock; due every [`HEARTBEAT_PERIOD_S`]): how long this side's loop went without
    /// polling. The board holds after 100 ms without a heartbeat and turns the drives off
    /// after 500 ms.
    pub fn heartbeat_gap_max_s(&self) -> f64 {
        self.beat_gap_max_s
    }

    /// Requests sent and not answered yet.
    pub fn pending(&self) -> usize {
        self.pending.len()
    }

    /// Sends `msg` and tracks it until its answer; its sequence number. A `Hello` always
    /// goes out with this connection's nonce and clock (never less than one after the last
    /// target stamp, so that it is newer than anything this master sent).
    pub fn send(&mut self, msg: MasterToBoard) -> Result<Seq, BoardError> {
        let msg = match msg {
            MasterToBoard::Hello { .. } => {
                let stamp = ((self.now_s() * 1e6) as u64).max(self.last_stamp_us + 1);
                self.last_stamp_us = stamp;
                self.link.hello_message(stamp)
            }
            other => other,
        };
        let seq = self.link.send(&msg)?;
        let sent = (seq, msg, self.now_s());
        if matches!(msg, MasterToBoard::Hello { .. }) {
            self.last_hello = Some(sent);
        }
        self.pending.push(sent);
        Ok(seq)
    }

    /// Sends `Hello` with this connection's nonce and clock.
    pub fn send_hello(&mut self) -> Result<Seq, BoardError> {
        self.send(self.link.hello_message(0))
    }

    /// Sends a pose target (CRTK `servo_cp`) stamped with this connection's clock; its
    /// sequence number and stamp, µs.
    pub fn send_target(&mut self, pose: &CartesianPose) -> Result<(Seq, u64), BoardError> {
        let (position_m, rotation_vector_rad) = wire_pose(pose);
        let stamp = ((self.now_s() * 1e6) as u64)
            .saturating_sub(self.stamp_offset_us)
            .max(self.last_stamp_us + 1);
        self.last_stamp_us = stamp;
        let seq = self.send(MasterToBoard::PoseTarget {
            timestamp_us: stamp,
            position_m,
            rotation_vector_rad,
        })?;
        Ok((seq, stamp))
    }

    /// Asks the board for its status now (`StatusRequest`), untracked: the board answers
    /// with a `Status` like its periodic ones (every 20 ms), so a front end that needs a
    /// faster view of the robot (the ROS 2 node's 100 Hz) asks between them.
    ///
    /// The paced clock advances one status period per *periodic* status; a status that
    /// answers a request does not advance it. A status carries no stamp, so the first
    /// status after a request counts as its answer (the board answers every
    /// `StatusRequest`, within a tick); a request not answered within [`REPLY_TIMEOUT_S`] of
    /// host time (a frame lost on a serial line) is forgotten, at the cost of one periodic
    /// status taken for its answer: the clock then lags one period (20 ms), once.
    pub fn request_status(&mut self) -> Result<(), BoardError> {
        self.link.send(&MasterToBoard::StatusRequest)?;
        self.status_requests.push_back(self.link.now_s());
        Ok(())
    }

    /// Whether a status arriving now answers a `StatusRequest` ([`Board::request_status`]).
    fn answers_status_request(&mut self) -> bool {
        let now = self.link.now_s();
        while self
            .status_requests
            .front()
            .is_some_and(|sent| now - sent > REPLY_TIMEOUT_S)
        {
            self.status_requests.pop_front();
        }
        self.status_requests.pop_front().is_some()
    }

    fn beat(&mut self) -> Result<(), BoardError> {
        let now = self.now_s();
        if self.heartbeat && now - self.last_beat_s >= HEARTBEAT_PERIOD_S {
            if self.last_beat_s.is_finite() {
                self.beat_gap_max_s = self.beat_gap_max_s.max(now - self.last_beat_s);
            }
            // Untracked: its Ack is not a front end's business.
            self.link.send(&MasterToBoard::Heartbeat)?;
            self.last_beat_s = now;
        }
        Ok(())
    }

    fn handle(&mut self, mut r: Received) {
        let periodic = matches!(r.msg, BoardToMaster::Status(_)) && !self.answers_status_request();
        self.clock.received(r.t_s, periodic);
        if self.paced {
            r.t_s = self.now_s();
        }
        let answer = |pending: &mut Vec<(Seq, MasterToBoard, f64)>,
                      matches: &dyn Fn(&(Seq, MasterToBoard, f64)) -> bool,
                      outcome: Outcome|
         -> Option<Reply> {
            let i = pending.iter().position(matches)?;
            let (seq, request, sent_s) = pending.remove(i);
            Some(Reply {
                request,
                seq,
                sent_s,
                t_s: r.t_s,
                outcome,
            })
        };
        let reply = match r.msg {
            BoardToMaster::Status(s) => {
                self.status = Some((r.t_s, s));
                self.statuses += 1;
                self.backlog.push_back(BoardEvent::Status(r.t_s, s));
                None
            }
            // Another master's answer (on a shared line) is not this one's.
            BoardToMaster::HelloReply { nonce, .. } | BoardToMaster::HelloRefused { nonce, .. }
                if nonce != self.link.nonce() =>
            {
                None
            }
            BoardToMaster::HelloRefused { reason, .. } => {
                self.hello_refused = Some(reason);
                answer(
                    &mut self.pending,
                    &|p| matches!(p.1, MasterToBoard::Hello { .. }),
                    Outcome::Refused(reason),
                )
            }
            BoardToMaster::HelloReply {
                firmware_version,
                protocol_version,
                session,
                reset,
                geometry_version,
                ..
            } => {
                let info = HelloInfo {
                    firmware: firmware_version,
                    protocol_version,
                    session,
                    reset,
                    geometry_version,
                };
                let late = self.hello.is_none();
                self.hello = Some(info);
                if let Some((_, MasterToBoard::Hello { clock_us, .. }, _)) = self.last_hello {
                    self.stamp_offset_us = ((r.t_s * 1e6) as u64).saturating_sub(clock_us);
                }
                answer(
                    &mut self.pending,
                    &|p| matches!(p.1, MasterToBoard::Hello { .. }),
                    Outcome::HelloReply(info),
                )
                .or_else(|| {
                    // The first answer to this connection's nonce after its request timed
                    // out (a board still booting, an emulator behind the wall clock): the
                    // session is confirmed all the same, and a front end must know it.
                    let (seq, request, sent_s) = self.last_hello.filter(|_| late)?;
                    Some(Reply {
                        request,
                        seq,
                        sent_s,
                        t_s: r.t_s,
                        outcome: Outcome::HelloReply(info),
                    })
                })
            }
            // The console sends no `Commission` (`host-sim commission` does).
            BoardToMaster::Commissioning(_) => None,
            BoardToMaster::Ack { seq } => answer(&mut self.pending, &|p| p.0 == seq, Outcome::Ack),
            BoardToMaster::Nack { seq, reason } => {
                answer(&mut self.pending, &|p| p.0 == seq, Outcome::Refused(reason))
            }
            BoardToMaster::TargetRefused(refused) => match refused.reply_to {
                Some(seq) => answer(
                    &mut self.pending,
                    &|p| p.0 == seq,
                    Outcome::TargetRefused(refused),
                ),
                None => {
                    self.backlog
                        .push_back(BoardEvent::TargetRefused(r.t_s, refused));
                    None
                }
            },
            BoardToMaster::FaultLog(page) => answer(
                &mut self.pending,
                &|p| matches!(p.1, MasterToBoard::FaultLogRequest { first } if first == page.first),
                Outcome::FaultLog(page),
            ),
            BoardToMaster::EventLog(page) => answer(
                &mut self.pending,
                &|p| matches!(p.1, MasterToBoard::EventLogRequest { first } if first == page.first),
                Outcome::EventLog(page),
            ),
            BoardToMaster::GeometryStored { seq, version } => answer(
                &mut self.pending,
                &|p| p.0 == seq,
                Outcome::GeometryStored(version),
            ),
            BoardToMaster::GeometryRefused { seq, reason } => answer(
                &mut self.pending,
                &|p| p.0 == seq,
                Outcome::GeometryRefused(reason),
            ),
        };
        if let Some(reply) = reply {
            // Every Hello sent before the answer is answered by it.
            if matches!(reply.outcome, Outcome::HelloReply(_)) {
                self.pending
                    .retain(|p| !matches!(p.1, MasterToBoard::Hello { .. }));
            }
            self.backlog.push_back(BoardEvent::Reply(reply));
        }
    }

    fn expire(&mut self) {
        let now = self.now_s();
        let mut i = 0;
        while let Some(&(seq, request, sent_s)) = self.pending.get(i) {
            if now - sent_s > REPLY_TIMEOUT_S {
                self.pending.remove(i);
                self.backlog.push_back(BoardEvent::Reply(Reply {
                    request,
                    seq,
                    sent_s,
                    t_s: now,
                    outcome: Outcome::NoReply,
                }));
            } else {
                i += 1;
            }
        }
    }

    /// Receives for at most `wait` (returning as soon as something came), sends the
    /// heartbeat that falls due, and hands over what arrived, oldest first.
    pub fn poll(&mut self, wait: Duration) -> Result<Vec<BoardEvent>, BoardError> {
        self.receive(wait)?;
        let mut out: Vec<BoardEvent> = self.deferred.drain(..).collect();
        out.extend(self.backlog.drain(..));
        Ok(out)
    }

    /// Receives into the backlog: waits at most `wait` for the first message when nothing
    /// is there yet.
    fn receive(&mut self, wait: Duration) -> Result<(), BoardError> {
        if self
            .interrupt
            .as_ref()
            .is_some_and(|f| f.load(Ordering::Relaxed))
        {
            return Err(BoardError::Interrupted);
        }
        if self.paced && self.clock.silent_too_long(self.link.now_s()) {
            return Err(teleop::TeleopError::Silent(SILENCE_LIMIT_S).into());
        }
        self.beat()?;
        if self.backlog.is_empty() {
            let most = if self.paced && self.clock.in_lockstep() {
                LOCKSTEP_WAIT_S
            } else {
                HEARTBEAT_PERIOD_S / 2.0
            };
            let wait = wait.min(Duration::from_secs_f64(most));
            if let Some(r) = self.link.recv(wait)? {
                self.handle(r);
            }
        }
        while let Some(r) = self.link.recv(Duration::ZERO)? {
            self.handle(r);
        }
        self.beat()?;
        self.expire();
        Ok(())
    }

    /// Receives for at most `wait`; the first new event `pick` takes, the others kept for
    /// the next [`Board::poll`].
    fn receive_picking<T>(
        &mut self,
        wait: Duration,
        pick: &mut dyn FnMut(&BoardEvent) -> Option<T>,
    ) -> Result<Option<T>, BoardError> {
        self.receive(wait)?;
        let mut found = None;
        while let Some(e) = self.backlog.pop_front() {
            if found.is_none() {
                if let Some(x) = pick(&e) {
                    found = Some(x);
                    if matches!(e, BoardEvent::Reply(_)) {
                        continue;
                    }
                }
            }
            self.deferred.push_back(e);
        }
        Ok(found)
    }

    /// Polls until the link's clock reaches `t_s`; everything that arrived.
    pub fn poll_until(&mut self, t_s: f64) -> Result<Vec<BoardEvent>, BoardError> {
        let mut events = self.poll(Duration::ZERO)?;
        loop {
            let left = t_s - self.now_s();
            if left <= 0.0 {
                return Ok(events);
            }
            events.extend(self.poll(Duration::from_secs_f64(left))?);
        }
    }

    /// Keeps receiving (events kept for the next [`Board::poll`]) until the clock reaches
    /// `t_s`.
    fn idle_until(&mut self, t_s: f64) -> Result<(), BoardError> {
        while self.now_s() < t_s {
            let left = Duration::from_secs_f64((t_s - self.now_s()).max(0.0));
            self.receive_picking::<()>(left, &mut |_| None)?;
        }
        Ok(())
    }

    /// Sends `msg` and waits for its answer (other events stay queued for the next
    /// [`Board::poll`]).
    pub fn request(&mut self, msg: MasterToBoard) -> Result<Outcome, BoardError> {
        let seq = self.send(msg)?;
        self.answer_to(seq)
    }

    /// Sends a pose target and waits for the board's answer.
    pub fn request_target(&mut self, pose: &CartesianPose) -> Result<Outcome, BoardError> {
        Ok(self.request_target_stamped(pose)?.0)
    }

    /// Sends a target and waits for its answer, as [`Board::request_target`]; the answer
    /// and the target's stamp, µs (the board names a target its path check refuses later
    /// by it).
    pub fn request_target_stamped(
        &mut self,
        pose: &CartesianPose,
    ) -> Result<(Outcome, u64), BoardError> {
        let (seq, stamp) = self.send_target(pose)?;
        Ok((self.answer_to(seq)?, stamp))
    }

    /// Waits for the answer to request `seq` (at most [`REPLY_TIMEOUT_S`]: then
    /// `Outcome::NoReply`).
    fn answer_to(&mut self, seq: Seq) -> Result<Outcome, BoardError> {
        loop {
            let got = self.receive_picking(Duration::from_millis(5), &mut |e| match e {
                BoardEvent::Reply(r) if r.seq == seq => Some(r.outcome),
                _ => None,
            })?;
            if let Some(o) = got {
                return Ok(o);
            }
        }
    }

    /// Waits at most `timeout_s` for a status that satisfies `pred` (received after this
    /// call); the status.
    pub fn wait_status(
        &mut self,
        timeout_s: f64,
        pred: impl Fn(&StatusReport) -> bool,
    ) -> Result<Option<StatusReport>, BoardError> {
        let end = self.now_s() + timeout_s;
        while self.now_s() < end {
            let got = self.receive_picking(Duration::from_millis(5), &mut |e| match e {
                BoardEvent::Status(_, s) if pred(s) => Some(*s),
                _ => None,
            })?;
            if got.is_some() {
                return Ok(got);
            }
        }
        Ok(None)
    }

    /// The reason of a `HelloRefused` received since the last call (or since
    /// [`Board::hello`] looked), taken.
    pub fn take_hello_refused(&mut self) -> Option<NackReason> {
        self.hello_refused.take()
    }

    /// Hello until the board answers (it may still be booting), at most `timeout_s`.
    /// A Hello the board refuses (another master owns the robot) is an error.
    pub fn hello(&mut self, timeout_s: f64) -> Result<HelloInfo, BoardError> {
        let end = self.now_s() + timeout_s;
        self.hello_refused = None;
        let mut refused_since = None;
        while self.now_s() < end {
            self.send_hello()?;
            let until = (self.now_s() + 0.5).min(end);
            while self.now_s() < until {
                self.receive_picking::<()>(Duration::from_millis(10), &mut |_| None)?;
                if let Some(reason) = self.hello_refused.take() {
                    // The last owner's stop may still be ending: asked again for a while.
                    let first = *refused_since.get_or_insert(self.now_s());
                    if reason != NackReason::NotOwner
                        || self.now_s() - first > teleop::session::HELLO_RETRY_S
                    {
                        return Err(BoardError::HelloRefused(reason));
                    }
                    let again = self.now_s() + 0.1;
                    self.idle_until(again)?;
                    break;
                }
                if let Some(h) = self.hello {
                    // A new owner starts with the operator absent; the operator at this
                    // front end is present until its dead-man says otherwise.
                    self.request(MasterToBoard::OperatorPresent { present: true })?;
                    return Ok(h);
                }
            }
        }
        Err(BoardError::NoHello { timeout_s })
    }

    /// Sends `Enable`, again while the board answers `Busy` (its brakes still engage after
    /// homing or a disable: about 100 ms), for at most [`ENABLE_BUSY_WINDOW_S`]; the last
    /// outcome.
    pub fn enable(&mut self) -> Result<Outcome, BoardError> {
        let end = self.now_s() + ENABLE_BUSY_WINDOW_S;
        loop {
            let outcome = self.request(MasterToBoard::Enable)?;
            if outcome != Outcome::Refused(NackReason::Busy) || self.now_s() >= end {
                return Ok(outcome);
            }
            let t = self.now_s() + 0.05;
            self.idle_until(t)?;
        }
    }

    /// Brings the board to following from whatever state it is in (`teleop::start`):
    /// hello; an unacknowledged reset acknowledged only with `options.acknowledge_reset`;
    /// a latched fault cleared only with `options.clear_fault`; a robot running under
    /// another master refused; homing when not homed (never re-homing); enable, and the
    /// `Enabled` state. `log` hears each step.
    pub fn bring_up(
        &mut self,
        timeouts: &BringUpTimeouts,
        options: StartOptions,
        log: &mut dyn FnMut(&str),
    ) -> Result<StatusReport, BoardError> {
        let status = self.connect(timeouts.hello_s, options, log)?;
        if status.warnings.contains(Warnings::NOT_HOMED) {
            self.home(timeouts.home_s, log)?;
        } else {
            log("already homed: homing skipped");
        }
        self.enable_and_wait(timeouts.enable_s, log)
    }

    /// The first half of [`Board::bring_up`]: hello, the reset, the fault, the state
    /// checked; the board's status, with the drives off (`Ready`, or `Disabled` when not
    /// homed).
    pub fn connect(
        &mut self,
        hello_timeout_s: f64,
        options: StartOptions,
        log: &mut dyn FnMut(&str),
    ) -> Result<StatusReport, BoardError> {
        self.greet(hello_timeout_s, options, log)?;
        let mut status = self
            .wait_status(2.0, |_| true)?
            .ok_or(BoardError::NoStatus)?;
        if status.state == RobotState::Fault {
            let text = start::latched_fault_text(&status.fault);
            if !options.clear_fault {
                return Err(BoardError::FaultLatched(text));
            }
            log(&format!("{text}: clearing it (--clear-fault)"));
            let outcome = self.request(MasterToBoard::ClearFault)?;
            let cleared = match outcome {
                Outcome::Ack => self.wait_status(1.0, |s| s.state != RobotState::Fault)?,
                _ => None,
            };
            status = cleared.ok_or_else(|| {
                BoardError::FaultLatched(format!(
                    "{text}; Clear fault: {}: the fault stays",
                    outcome.words()
                ))
            })?;
            log("fault cleared");
        }
        if let Some(text) = start::busy_text(status.state) {
            return Err(BoardError::Busy(text));
        }
        Ok(status)
    }

    /// Hello (at most `timeout_s`), logged; the protocol version checked; the board's
    /// last reset acknowledged when it is not yet, only with `options.acknowledge_reset`.
    fn greet(
        &mut self,
        timeout_s: f64,
        options: StartOptions,
        log: &mut dyn FnMut(&str),
    ) -> Result<(), BoardError> {
        let h = self.hello(timeout_s)?;
        log(&format!(
            "hello: firmware {}.{}.{}, protocol {}, last reset {}{}",
            h.firmware.major,
            h.firmware.minor,
            h.firmware.patch,
            h.protocol_version,
            board_words::reset_cause(h.reset.cause),
            if h.reset.acknowledged {
                ""
            } else {
                " (not acknowledged)"
            }
        ));
        if h.protocol_version != PROTOCOL_VERSION {
            return Err(BoardError::Protocol {
                board: h.protocol_version,
                master: PROTOCOL_VERSION,
            });
        }
        if !h.reset.acknowledged {
            if !options.acknowledge_reset {
                return Err(BoardError::ResetNotAcknowledged(h.reset.cause));
            }
            self.expect_ack(MasterToBoard::AcknowledgeReset)?;
            log(&format!(
                "{} reset acknowledged (--acknowledge-reset)",
                board_words::reset_cause(h.reset.cause)
            ));
        }
        Ok(())
    }

    /// Sends `Disable` and waits at most `timeout_s` of host time for its answer (None
    /// came: `Outcome::NoReply`); the interrupt is taken off first, so that this is the
    /// way out after a signal too.
    pub fn disable_within(&mut self, timeout_s: f64) -> Result<Outcome, BoardError> {
        self.interrupt = None;
        let seq = self.send(MasterToBoard::Disable)?;
        let end = self.link.now_s() + timeout_s;
        while self.link.now_s() < end {
            let got = self.receive_picking(Duration::from_millis(5), &mut |e| match e {
                BoardEvent::Reply(r) if r.seq == seq => Some(r.outcome),
                _ => None,
            })?;
            if let Some(o) = got {
                return Ok(o);
            }
        }
        Ok(Outcome::NoReply)
    }

    /// Homes (never re-homing) and waits at most `timeout_s` for `Ready` and homed.
    fn home(&mut self, timeout_s: f64, log: &mut dyn FnMut(&str)) -> Result<(), BoardError> {
        self.expect_ack(MasterToBoard::Home { rehome: false })?;
        log("homing");
        let homed = self.wait_status(timeout_s, |s| {
            (s.state == RobotState::Ready && !s.warnings.contains(Warnings::NOT_HOMED))
                || s.state == RobotState::Fault
        })?;
        match homed {
            Some(s) if s.state == RobotState::Ready => {
                log("homed");
                Ok(())
            }
            Some(s) => Err(BoardError::Faulted {
                cause: format!(
                    "{} while homing",
                    board_words::fault(&s.fault).unwrap_or_else(|| "no fault cause".into())
                ),
            }),
            None => Err(BoardError::Timeout {
                what: "homing",
                timeout_s,
            }),
        }
    }

    /// Enables ([`Board::enable`]) and waits at most `timeout_s` for `Enabled`; the front
    /// end starts from there (what came before is dropped).
    fn enable_and_wait(
        &mut self,
        timeout_s: f64,
        log: &mut dyn FnMut(&str),
    ) -> Result<StatusReport, BoardError> {
        match self.enable()? {
            Outcome::Ack => {}
            Outcome::Refused(reason) => {
                return Err(BoardError::Refused {
                    request: "Enable".into(),
                    reason,
                })
            }
            _ => {
                return Err(BoardError::NoReply {
                    request: "Enable".into(),
                })
            }
        }
        let enabled = self.wait_status(timeout_s, |s| {
            matches!(s.state, RobotState::Enabled | RobotState::Fault)
        })?;
        match enabled {
            Some(s) if s.state == RobotState::Enabled => {
                log("enabled");
                // What came during the bring-up is history: the front end starts now.
                self.discard_events();
                Ok(s)
            }
            Some(s) => Err(BoardError::Faulted {
                cause: format!(
                    "{} while enabling",
                    board_words::fault(&s.fault).unwrap_or_else(|| "no fault cause".into())
                ),
            }),
            None => Err(BoardError::Timeout {
                what: "enabling",
                timeout_s,
            }),
        }
    }

    /// Drops the events received and not handed over yet (a front end that starts now).
    pub fn discard_events(&mut self) {
        self.deferred.clear();
        self.backlog.clear();
    }

    /// Sends `msg` and requires its Ack.
    pub fn expect_ack(&mut self, msg: MasterToBoard) -> Result<(), BoardError> {
        match self.request(msg)? {
            Outcome::Ack => Ok(()),
            Outcome::Refused(reason) => Err(BoardError::Refused {
                request: request_name(&msg).into(),
                reason,
            }),
            _ => Err(BoardError::NoReply {
                request: request_name(&msg).into(),
            }),
        }
    }
}

/// The bring-up's time limits, s.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BringUpTimeouts {
    /// Hello answered.
    pub hello_s: f64,
    /// Homing done.
    pub home_s: f64,
    /// `Enabled` after the Ack (the brake check takes about 140 ms).
    pub enable_s: f64,
}

impl Default for BringUpTimeouts {
    /// 15 s, 60 s, 2 s.
    fn default() -> Self {
        BringUpTimeouts {
            hello_s: 15.0,
            home_s: 60.0,
            enable_s: 2.0,
        }
    }
}

/// A request's name, as the console and the logs show it.
pub fn request_name(msg: &MasterToBoard) -> &'static str {
    match msg {
        MasterToBoard::Hello { .. } => "Hello",
        MasterToBoard::Enable => "Enable",
        MasterToBoard::Disable => "Disable",
        MasterToBoard::Home { rehome: false } => "Home",
        MasterToBoard::Home { rehome: true } => "Re-home",
        MasterToBoard::PoseTarget { .. } => "PoseTarget",
        MasterToBoard::Jog { .. } => "Jog",
        MasterToBoard::Clutch { engaged: true } => "Clutch engaged",
        MasterToBoard::Clutch { engaged: false } => "Clutch released",
        MasterToBoard::Heartbeat => "Heartbeat",
        MasterToBoard::EmergencyStop => "Stop",
        MasterToBoard::ClearFault => "Clear fault",
        MasterToBoard::StatusRequest => "Status request",
        MasterToBoard::OperatorPresent { present: true } => "Operator present",
        MasterToBoard::OperatorPresent { present: false } => "Operator absent",
        MasterToBoard::AcknowledgeReset => "Acknowledge reset",
        MasterToBoard::FaultLogRequest { .. } => "Fault log",
        MasterToBoard::StoreGeometry(_) => "Store geometry",
        MasterToBoard::EventLogRequest { .. } => "Event log",
        MasterToBoard::Commission { .. } => "Commission",
    }
}

/// Why the board refused, in words a person at the robot can act on (at most 44
/// characters: the console shows it on one line); `board_words::reason`.
pub fn refusal_text(reason: NackReason) -> &'static str {
    board_words::reason(reason)
}
