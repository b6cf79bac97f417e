//! A master session on an open [`Link`]: the `Hello` (the board issues the session and
//! echoes this connection's nonce; another master's `HelloReply` or `HelloRefused` on a
//! shared line is not this one's), heartbeats at 50 Hz (unless paused), requests and
//! their replies (matched by sequence number), the status telemetry recorded with the
//! phase it arrived in, the targets sent (for the tracking figures) and the refusals.
//!
//! The session's clock: the host's (`paced = false`), or paced by the board (the default):
//! [`crate::pacing`]. (A `Status` answering a `StatusRequest` would count too; the session
//! sends none.)

use crate::error::TeleopError;
use crate::link::{Link, Received};
use crate::pacing::{BoardClock, SharedClock, SILENCE_LIMIT_S};
use kinematics_core::Pose;
use master_link::{
    BoardToMaster, FirmwareVersion, GeometryRecord, GeometryRefusal, MasterToBoard, NackReason,
    Seq, StatusReport,
};
use std::collections::HashMap;
use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Duration;

/// The board's answer to a `StoreGeometry`.
#[derive(Clone, Debug, PartialEq)]
pub enum GeometryAnswer {
    /// Stored, with this version.
    Stored(u32),
    /// Refused, nothing stored.
    Refused(GeometryRefusal),
    /// The request was refused by the link or the queue (`NotConnected`, `Busy`).
    Nack(NackReason),
    /// Another reply (a defect).
    Unexpected(String),
}

/// Heartbeat period, s (the board holds after 100 ms of silence; 20 ms leaves room for
/// the delays of a loaded host).
pub const HEARTBEAT_PERIOD_S: f64 = 0.02;

/// A status as received.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StatusRow {
    /// Arrival, s (master clock).
    pub t_s: f64,
    /// Index of the phase it arrived in.
    pub phase: usize,
    /// The report.
    pub status: StatusReport,
}

/// A refused request.
#[derive(Clone, Debug, PartialEq)]
pub struct Refused {
    /// When the Nack arrived, s.
    pub t_s: f64,
    /// Phase index.
    pub phase: usize,
    /// What was refused.
    pub request: MasterToBoard,
    /// Why.
    pub reason: NackReason,
    /// Why in words, with what the board measured (`board_words::refusal`): "workspace z
    /// 177.0 mm > 175.0 mm", "not homed: home the robot first".
    pub words: String,
    /// Refused by the board's path check after its `Ack` (not at submission).
    pub later: bool,
}

/// How long a `Hello` refused with `NotOwner` is sent again, s: the stop that ends the
/// last master's session (brakes engaging, about 100 ms) with margin.
pub const HELLO_RETRY_S: f64 = 1.0;

/// The master.
pub struct Session {
    /// The link.
    pub link: Link,
    /// Heartbeats are sent.
    pub heartbeat: bool,
    /// Time of the last heartbeat sent, s.
    pub last_beat_s: f64,
    /// Phase names; the current phase is the last.
    pub phases: Vec<String>,
    /// Every status received.
    pub statuses: Vec<StatusRow>,
    /// Targets sent: (time, pose).
    pub targets: Vec<(f64, Pose<f64>)>,
    /// Requests refused.
    pub refused: Vec<Refused>,
    /// Fault-log pages received.
    pub fault_log: Vec<master_link::FaultLogPage>,
    /// Event-log pages received.
    pub event_log: Vec<master_link::EventLogPage>,
    /// The board's `HelloReply`.
    pub hello: Option<(FirmwareVersion, u8)>,
    /// The reset the board reported in its `HelloReply`.
    pub reset: Option<master_link::ResetStatus>,
    /// The calibrated geometry version the last `HelloReply` reported (0: none).
    pub geometry_version: Option<u32>,
    /// Requests in flight and answered: seq -> (request, reply and its time).
    requests: HashMap<Seq, (MasterToBoard, Option<(f64, BoardToMaster)>)>,
    /// Acks received.
    pub acks: u64,
    /// The clock is paced by the board's telemetry.
    pub paced: bool,
    /// The session's clock.
    clock: BoardClock,
    /// The last target stamp sent, µs.
    last_stamp_us: u64,
    /// Why the board refused this master's last `Hello`, if it did.
    pub hello_refused: Option<NackReason>,
    /// Set from outside (a signal) to end every wait with [`TeleopError::Interrupted`].
    pub stop: Option<Arc<AtomicBool>>,
}

impl Session {
    /// A session on `link`, phase "connect", heartbeats on.
    pub fn new(link: Link) -> Self {
        Session {
            link,
            heartbeat: true,
            last_beat_s: f64::NEG_INFINITY,
            phases: vec!["connect".into()],
            statuses: Vec::new(),
            targets: Vec::new(),
            refused: Vec::new(),
            fault_log: Vec::new(),
            event_log: Vec::new(),
            hello: None,
            reset: None,
            geometry_version: None,
            requests: HashMap::new(),
            acks: 0,
            paced: true,
            clock: BoardClock::default(),
            last_stamp_us: 0,
            hello_refused: None,
            stop: None,
        }
    }

    /// Takes the board's own clock from the file an emulated board shares beside its
    /// socket `socket` (`board-emulator serve --clock-lead-ms`), when there is one: paced,
    /// this session's clock is then the board's from the first reading on, before the
    /// first status too. Without it the paced clock runs on the host's time until the
    /// first status, and an emulated board that its host holds up while it boots (the
    /// emulator translating the image's code) receives the `Hello`s and heartbeats of that
    /// host time all at once: a second `Hello` of the same connection is a reconnect that
    /// opens a new session, and the requests sent in the first are refused. Returns
    /// whether the board shares its clock.
    pub fn share_board_clock(&mut self, socket: &Path) -> bool {
        match SharedClock::beside(socket) {
            Some(shared) => {
                self.clock = BoardClock::with_shared(shared);
                true
            }
            None => false,
        }
    }

    /// Starts a new phase; returns its index.
    pub fn phase(&mut self, name: &str) -> usize {
        self.phases.push(name.into());
        self.phases.len() - 1
    }

    fn current_phase(&self) -> usize {
        self.phases.len().saturating_sub(1)
    }

    /// The session's clock, s (see the module documentation).
    pub fn now_s(&self) -> f64 {
        self.clock.now_s(self.link.now_s(), self.paced)
    }

    /// The latest status.
    pub fn last_status(&self) -> Option<&StatusRow> {
        self.statuses.last()
    }

    /// The statuses received during phase `phase`.
    pub fn phase_rows(&self, phase: usize) -> Vec<StatusRow> {
        self.statuses
            .iter()
            .filter(|r| r.phase == phase)
            .copied()
            .collect()
    }

    /// Sends a request and remembers it; returns its sequence number.
    pub fn send(&mut self, msg: MasterToBoard) -> Result<Seq, TeleopError> {
        let seq = self.link.send(&msg)?;
        self.requests.insert(seq, (msg, None));
        Ok(seq)
    }

    /// The master's clock now as a stamp, µs: never less than one after the last stamp
    /// (targets and `Hello`s alike, so that a later `Hello` is always newer).
    fn clock_stamp_us(&mut self) -> u64 {
        let stamp = ((self.now_s() * 1e6) as u64).max(self.last_stamp_us + 1);
        self.last_stamp_us = stamp;
        stamp
    }

    /// Sends a target pose stamped with the master clock and records it.
    pub fn send_target(&mut self, pose: &Pose<f64>) -> Result<Seq, TeleopError> {
        let r = pose.rotation_vector();
        let stamp = self.clock_stamp_us();
        let msg = MasterToBoard::PoseTarget {
            timestamp_us: stamp,
            position_m: [pose.t.x as f32, pose.t.y as f32, pose.t.z as f32],
            rotation_vector_rad: [r.x as f32, r.y as f32, r.z as f32],
        };
        let t = self.now_s();
        self.targets.push((t, *pose));
        self.send(msg)
    }

    /// Sends a target and waits for its Ack (`None`) or Nack (the reason).
    pub fn request_target(&mut self, pose: &Pose<f64>) -> Result<Option<NackReason>, TeleopError> {
        let seq = self.send_target(pose)?;
        match self.reply(seq, 1.0)? {
            BoardToMaster::Nack { reason, .. } => Ok(Some(reason)),
            BoardToMaster::TargetRefused(r) => Ok(Some(r.reason)),
            _ => Ok(None),
        }
    }

    fn handle(&mut self, mut r: Received) {
        let phase = self.current_phase();
        self.clock
            .received(r.t_s, matches!(r.msg, BoardToMaster::Status(_)));
        if self.paced {
            r.t_s = self.now_s();
        }
        match r.msg {
            BoardToMaster::Status(status) => self.statuses.push(StatusRow {
                t_s: r.t_s,
                phase,
                status,
            }),
            // Another master's HelloReply (on a shared line) is not this one's.
            BoardToMaster::HelloReply { nonce, .. } if nonce != self.link.nonce() => {}
            BoardToMaster::HelloRefused { nonce, .. } if nonce != self.link.nonce() => {}
            BoardToMaster::HelloRefused { reason, .. } => self.hello_refused = Some(reason),
            BoardToMaster::HelloReply {
                firmware_version,
                protocol_version,
                reset,
                geometry_version,
                ..
            } => {
                self.hello = Some((firmware_version, protocol_version));
                self.reset = Some(reset);
                self.geometry_version = Some(geometry_version);
            }
            BoardToMaster::Ack { seq } => {
                self.acks += 1;
                if let Some((_, reply)) = self.requests.get_mut(&seq) {
                    *reply = Some((r.t_s, r.msg));
                }
            }
            BoardToMaster::Nack { seq, reason } => {
                if let Some((request, reply)) = self.requests.get_mut(&seq) {
                    *reply = Some((r.t_s, r.msg));
                    self.refused.push(Refused {
                        t_s: r.t_s,
                        phase,
                        request: *request,
                        reason,
                        words: board_words::reason(reason).to_string(),
                        later: false,
                    });
                }
            }
            BoardToMaster::TargetRefused(refused) => {
                let words = board_words::refusal(&refused);
                let request = match refused.reply_to {
                    Some(seq) => self.requests.get_mut(&seq).map(|(request, reply)| {
                        *reply = Some((r.t_s, r.msg));
                        *request
                    }),
                    // The path check's refusal of a target acknowledged before: the
                    // target is the one with its stamp.
                    None => self.requests.values().map(|(req, _)| *req).find(|req| {
                        matches!(req, MasterToBoard::PoseTarget { timestamp_us, .. }
                            if *timestamp_us == refused.timestamp_us)
                    }),
                };
                if let Some(request) = request {
                    self.refused.push(Refused {
                        t_s: r.t_s,
                        phase,
                        request,
                        reason: refused.reason,
                        words,
                        later: refused.reply_to.is_none(),
                    });
                }
            }
            BoardToMaster::FaultLog(page) => {
                self.fault_log.push(page);
                // A fault-log page answers the oldest open request for one.
                if let Some((_, reply)) = self
                    .requests
                    .values_mut()
                    .filter(|(req, reply)| {
                        reply.is_none() && matches!(req, MasterToBoard::FaultLogRequest { .. })
                    })
                    .min_by_key(|(req, _)| match req {
                        MasterToBoard::FaultLogRequest { first } => *first,
                        _ => u16::MAX,
                    })
                {
                    *reply = Some((r.t_s, r.msg));
                }
            }
            BoardToMaster::EventLog(page) => {
                self.event_log.push(page);
                // An event-log page answers the open request for its first entry.
                if let Some((_, reply)) = self.requests.values_mut().find(|(req, reply)| {
                    reply.is_none()
                        && matches!(req, MasterToBoard::EventLogRequest { first } if *first == page.first)
                }) {
                    *reply = Some((r.t_s, r.msg));
                }
            }
            BoardToMaster::GeometryStored { seq, .. }
            | BoardToMaster::GeometryRefused { seq, .. } => {
                if let Some((_, reply)) = self.requests.get_mut(&seq) {
                    *reply = Some((r.t_s, r.msg));
                }
            }
            BoardToMaster::Commissioning(record) => {
                // A record answers the oldest open `Commission` of its joint.
                if let Some((_, reply)) = self.requests.values_mut().find(|(req, reply)| {
                    reply.is_none()
                        && matches!(req, MasterToBoard::Commission { joint, .. } if *joint == record.joint)
                }) {
                    *reply = Some((r.t_s, r.msg));
                }
            }
        }
    }

    /// Receives and records until the master clock reaches `t_end_s`, sending the
    /// heartbeats that fall due.
    pub fn poll_until(&mut self, t_end_s: f64) -> Result<(), TeleopError> {
        loop {
            if self
                .stop
                .as_ref()
                .is_some_and(|s| s.load(Ordering::Relaxed))
            {
                return Err(TeleopError::Interrupted);
            }
            let now = self.now_s();
            if self.heartbeat && now - self.last_beat_s >= HEARTBEAT_PERIOD_S {
                self.link.send(&MasterToBoard::Heartbeat)?;
                self.last_beat_s = now;
            }
            if now >= t_end_s {
                return Ok(());
            }
            if !self.statuses.is_empty() && self.clock.silent_too_long(self.link.now_s()) {
                return Err(TeleopError::Silent(SILENCE_LIMIT_S));
            }
            let mut wait = t_end_s - now;
            if self.heartbeat {
                wait = wait.min(self.last_beat_s + HEARTBEAT_PERIOD_S - now);
            }
            let wait = Duration::from_secs_f64(wait.clamp(0.0, 0.005));
            if let Some(r) = self.link.recv(wait)? {
                self.handle(r);
            }
        }
    }

    /// Polls for `seconds`.
    pub fn wait(&mut self, seconds: f64) -> Result<(), TeleopError> {
        let end = self.now_s() + seconds;
        self.poll_until(end)
    }

    /// The reply to request `seq`, waiting at most `timeout_s`.
    pub fn reply(&mut self, seq: Seq, timeout_s: f64) -> Result<BoardToMaster, TeleopError> {
        let end = self.now_s() + timeout_s;
        loop {
            if let Some((_, Some((_, reply)))) = self.requests.get(&seq) {
                return Ok(*reply);
            }
            if self.now_s() >= end {
                return Err(TeleopError::NoReply { seq, timeout_s });
            }
            let step = (self.now_s() + 0.005).min(end);
            self.poll_until(step)?;
        }
    }

    /// Sends `msg` and waits for its Ack (`Ok(None)`) or Nack (`Ok(Some(reason))`).
    pub fn request(
        &mut self,
        msg: MasterToBoard,
        timeout_s: f64,
    ) -> Result<Option<NackReason>, TeleopError> {
        let seq = self.send(msg)?;
        match self.reply(seq, timeout_s)? {
            BoardToMaster::Nack { reason, .. } => Ok(Some(reason)),
            BoardToMaster::TargetRefused(r) => Ok(Some(r.reason)),
            _ => Ok(None),
        }
    }

    /// Sends a calibrated geometry and waits up to `timeout_s` for the board's answer (it
    /// may erase its flash sector first: allow seconds).
    pub fn store_geometry(
        &mut self,
        record: GeometryRecord,
        timeout_s: f64,
    ) -> Result<GeometryAnswer, TeleopError> {
        let seq = self.send(MasterToBoard::StoreGeometry(record))?;
        Ok(match self.reply(seq, timeout_s)? {
            BoardToMaster::GeometryStored { version, .. } => GeometryAnswer::Stored(version),
            BoardToMaster::GeometryRefused { reason, .. } => GeometryAnswer::Refused(reason),
            BoardToMaster::Nack { reason, .. } => GeometryAnswer::Nack(reason),
            other => GeometryAnswer::Unexpected(format!("{other:?}")),
        })
    }

    /// Sends `Commission { joint, confirm }` and waits up to `timeout_s` for the joint's
    /// record, or the refusal.
    pub fn commission(
        &mut self,
        joint: u8,
        confirm: bool,
        timeout_s: f64,
    ) -> Result<Result<master_link::CommissionRecord, NackReason>, TeleopError> {
        let seq = self.send(MasterToBoard::Commission { joint, confirm })?;
        Ok(match self.reply(seq, timeout_s)? {
            BoardToMaster::Commissioning(record) => Ok(record),
            BoardToMaster::Nack { reason, .. } => Err(reason),
            _ => Err(NackReason::InvalidState),
        })
    }

    /// Hello until the board answers (it may still be booting), then `OperatorPresent {
    /// present: true }` (this master has no dead-man); the firmware version. A refused
    /// `Hello` (another master owns the board) is an error.
    pub fn hello(&mut self, timeout_s: f64) -> Result<(FirmwareVersion, u8), TeleopError> {
        let end = self.now_s() + timeout_s;
        self.hello = None;
        self.hello_refused = None;
        let mut refused_since = None;
        while self.now_s() < end {
            let stamp = self.clock_stamp_us();
            let hello = self.link.hello_message(stamp);
            self.link.send(&hello)?;
            let t = (self.now_s() + 0.5).min(end);
            while self.now_s() < t {
                if let Some(h) = self.hello {
                    // A master without a dead-man: its operator is present from the start
                    // (a new owner starts absent, and no Enable is taken before this).
                    self.request(MasterToBoard::OperatorPresent { present: true }, 1.0)?;
                    return Ok(h);
                }
                if let Some(reason) = self.hello_refused.take() {
                    // The owner's robot may be in the last instants of its stop (brakes
                    // engaging after a Disable): asked again within HELLO_RETRY_S.
                    let first = *refused_since.get_or_insert(self.now_s());
                    if reason != NackReason::NotOwner || self.now_s() - first > HELLO_RETRY_S {
                        return Err(TeleopError::HelloRefused(reason));
                    }
                    let again = self.now_s() + 0.1;
                    self.poll_until(again)?;
                    break;
                }
                let step = (self.now_s() + 0.01).min(t);
                self.poll_until(step)?;
            }
        }
        self.hello.ok_or(TeleopError::NoHello(timeout_s))
    }

    /// Waits (at most `timeout_s`) for a status, from the `since`-th recorded on, that
    /// satisfies `pred`.
    pub fn wait_for(
        &mut self,
        since: usize,
        timeout_s: f64,
        pred: impl Fn(&StatusReport) -> bool,
    ) -> Result<Option<StatusRow>, TeleopError> {
        let mut seen = since;
        let end = self.now_s() + timeout_s;
        loop {
            if let Some(row) = self
                .statuses
                .get(seen..)
                .and_then(|new| new.iter().find(|r| pred(&r.status)).copied())
            {
                return Ok(Some(row));
            }
            seen = self.statuses.len();
            if self.now_s() >= end {
                return Ok(None);
            }
            let step = (self.now_s() + 0.01).min(end);
            self.poll_until(step)?;
        }
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used)]
    use super::*;
    use crate::link::Medium;
    use master_link::{shared_clock, LinkCounters};
    use std::os::unix::fs::FileExt;
    use std::sync::Mutex;

    /// A board that says nothing, on a host clock the test sets; it counts the frames
    /// written to it.
    struct Silent {
        host_s: Arc<Mutex<f64>>,
        writes: Arc<Mutex<usize>>,
    }

    impl Medium for Silent {
        fn write_all(&mut self, _bytes: &[u8]) -> std::io::Result<()> {
            *self.writes.lock().unwrap() += 1;
            Ok(())
        }
        fn recv(&mut self, _timeout: Duration) -> Result<Option<Received>, TeleopError> {
            Ok(None)
        }
        fn now_s(&self) -> f64 {
            *self.host_s.lock().unwrap()
        }
        fn counters(&self) -> LinkCounters {
            LinkCounters::default()
        }
    }

    /// Before the board's first status (while an emulated board boots), a paced session
    /// that takes the board's shared clock sends its heartbeats by the board's time: two
    /// seconds of host time while the board stands send nothing more (on the host's time
    /// they would send 100 heartbeats and four `Hello` retries that reach the board all at
    /// once), and the next heartbeat is due one period of the board's time later.
    #[test]
    fn before_any_status_a_shared_clock_paces_the_heartbeats_by_the_boards_time() {
        for share in [true, false] {
            let (socket, f) = crate::pacing::tests::shared_file(&format!("beats-{share}"), 1_000);
            let host_s = Arc::new(Mutex::new(0.0));
            let writes = Arc::new(Mutex::new(0));
            let medium = Silent {
                host_s: Arc::clone(&host_s),
                writes: Arc::clone(&writes),
            };
            let mut s = Session::new(Link::over(Box::new(medium), 7));
            if share {
                assert!(s.share_board_clock(&socket));
            }
            let now = s.now_s();
            s.poll_until(now).unwrap();
            assert_eq!(*writes.lock().unwrap(), 1, "the first heartbeat at once");
            // The host runs 2 s; the board stands (still booting).
            *host_s.lock().unwrap() = 2.0;
            let now = s.now_s();
            s.poll_until(now).unwrap();
            let beats = *writes.lock().unwrap();
            if share {
                assert_eq!(now, 0.0, "the board's clock stood");
                assert_eq!(beats, 1, "no heartbeat while the board stands");
                // The board runs one heartbeat period.
                let period_us = (HEARTBEAT_PERIOD_S * 1e6).round() as u64;
                f.write_all_at(
                    &shared_clock::encode(1_000 + period_us),
                    shared_clock::BOARD_US,
                )
                .unwrap();
                let now = s.now_s();
                assert!((now - HEARTBEAT_PERIOD_S).abs() < 1e-9);
                s.poll_until(now).unwrap();
                assert_eq!(*writes.lock().unwrap(), 2, "the next heartbeat on time");
            } else {
                assert_eq!(now, 2.0, "the host's clock");
                assert_eq!(beats, 2, "a heartbeat due on the host's time");
            }
            drop(f);
            let mut path = socket.as_os_str().to_owned();
            path.push(shared_clock::SUFFIX);
            let _ = std::fs::remove_file(path);
        }
        // No shared clock beside a socket: none taken.
        let socket =
            std::env::temp_dir().join(format!("rspr-session-{}-none.sock", std::process::id()));
        let medium = Silent {
            host_s: Arc::new(Mutex::new(0.0)),
            writes: Arc::new(Mutex::new(0)),
        };
        assert!(!Session::new(Link::over(Box::new(medium), 7)).share_board_clock(&socket));
    }
}
