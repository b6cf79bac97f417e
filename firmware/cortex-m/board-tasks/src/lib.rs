//! The embassy tasks every board target runs, written once. A target's `main.rs` brings
//! the hardware up, implements the small traits below for it, and spawns three tasks that
//! call these functions:
//!
//! * [`run_control`] (an interrupt executor above the link): the control tick every
//!   period, around [`TickService`]: the e-stop latch, the queued master requests and
//!   their replies, the runtime's tick (which reads the safety chain, the power stage and
//!   every sensor), timing, the deadline policy, the watchdog, the fault log and the event
//!   log's view kept across resets, the status; then, after them, the event log's flash
//!   writer (a few words per period, an erase only with the drives off);
//! * [`run_link_rx`] (thread mode): bytes -> frames -> requests for the control tick; an
//!   `EmergencyStop` message forces the outputs safe at once, before it is queued; the
//!   link key's tags checked and the session ids issued here (SHA-256, HMAC-SHA256), never
//!   in the control tick;
//! * [`run_link_tx`] (thread mode): replies, and the status every telemetry period once a
//!   session is open, with the receiving side's link counters, tagged with the key.
//!
//! **Sessions.** The control tick decides whether a `Hello` is accepted (one owner,
//! `control::modes::next`); when it is, the tick leaves the session and the `Hello`'s
//! sequence number in [`Shared::session`] before it queues the `HelloReply`, and the
//! receive task opens it before it decodes the next bytes: the master's first frame of the
//! session, sent after the reply, always finds it open.
//!
//! The tasks meet in one [`Shared`] (channels, the latest status, the e-stop latch).
#![no_std]

use core::cell::Cell;
use core::sync::atomic::{AtomicBool, AtomicU32, Ordering};

use control::estop::{emergency_stop_message, EStopLatch};
use control::event_log::{EventLog, Step};
use control::faults::FaultLog;
use control::link::{opened_session, BoardIdentity, Inbound, LinkRx, LinkTx, Request};
use control::service::{TickOutcome, TickService};
use control::telemetry::with_link;
use control::Scalar;
use embassy_futures::select::{select, Either};
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::blocking_mutex::Mutex;
use embassy_sync::channel::Channel;
use embassy_time::{Duration, Instant, Ticker, Timer};
use hal::{Hardware, SafeOutputs};
use kinematics_core::Mechanism;
use master_link::{
    BoardToMaster, FaultCause, FaultRecord, GeometryRecord, GeometryRefusal, LinkCounters, LinkKey,
    NackReason, ResetCause, ResetStatus, StatusReport, MAX_FRAME_LEN,
};

/// The firmware version sent in `HelloReply` (see [`firmware_version!`]).
pub use master_link::FirmwareVersion;

/// Requests queued for the control tick (the tick drains the queue every millisecond; a
/// 100 Hz target stream with heartbeats brings two per 10 ms).
pub const COMMAND_QUEUE: usize = 8;
/// Replies queued for the link.
pub const REPLY_QUEUE: usize = 8;

/// What the tasks share.
pub struct Shared {
    /// Master requests for the control tick.
    pub commands: Channel<CriticalSectionRawMutex, Request, COMMAND_QUEUE>,
    /// Replies for the link.
    pub replies: Channel<CriticalSectionRawMutex, BoardToMaster, REPLY_QUEUE>,
    /// The latest status from the control tick (valid once `has_status`).
    pub status: Mutex<CriticalSectionRawMutex, Cell<StatusReport>>,
    /// The control tick has published a status.
    pub has_status: AtomicBool,
    /// The receiving side's counters.
    pub link: Mutex<CriticalSectionRawMutex, Cell<Option<LinkCounters>>>,
    /// A session is open: telemetry flows.
    pub connected: AtomicBool,
    /// A session the control tick accepted, with the `Hello`'s sequence number, for the
    /// receive task to open.
    pub session: Mutex<CriticalSectionRawMutex, Cell<Option<(u32, master_link::Seq)>>>,
    /// Replies dropped because the reply queue was full.
    pub replies_dropped: AtomicU32,
    /// Frames that could not be encoded.
    pub encode_errors: AtomicU32,
    /// The e-stop latch: tripped by the e-stop interrupt and the `EmergencyStop` message,
    /// taken by the control tick.
    pub estop: EStopLatch,
    /// A received calibrated geometry for the control task (one at a time: a second one
    /// before the first is handled is answered `Busy`).
    pub geometry: Mutex<CriticalSectionRawMutex, Cell<Option<(master_link::Seq, GeometryRecord)>>>,
}

impl Shared {
    /// Empty queues, no status, not connected.
    pub const fn new() -> Self {
        Shared {
            commands: Channel::new(),
            replies: Channel::new(),
            // All zero bits (state Boot), so that `Shared` is zero-initialised (.bss).
            status: Mutex::new(Cell::new(EMPTY_STATUS)),
            has_status: AtomicBool::new(false),
            link: Mutex::new(Cell::new(None)),
            connected: AtomicBool::new(false),
            session: Mutex::new(Cell::new(None)),
            replies_dropped: AtomicU32::new(0),
            encode_errors: AtomicU32::new(0),
            estop: EStopLatch::new(),
            geometry: Mutex::new(Cell::new(None)),
        }
    }

    /// Queues a reply for the link (counted when the queue is full).
    pub fn reply(&self, reply: BoardToMaster) {
        if self.replies.try_send(reply).is_err() {
            self.replies_dropped.fetch_add(1, Ordering::Relaxed);
        }
    }
}

/// A status of all zero bits (before the first tick).
const EMPTY_STATUS: StatusReport = StatusReport {
    state: master_link::RobotState::Boot,
    position_m: [0.0; 3],
    rotation_vector_rad: [0.0; 3],
    joints: [0.0; master_link::JOINT_COUNT],
    warnings: master_link::Warnings::NONE,
    faults: master_link::Faults::NONE,
    serial_singularity_margin: 0.0,
    parallel_singularity_margin: 0.0,
    link: LinkCounters {
        frames_ok: 0,
        bad_checksum: 0,
        malformed: 0,
        oversized: 0,
        wrong_version: 0,
        out_of_order: 0,
        dropped: 0,
        wrong_session: 0,
        bad_tag: 0,
    },
    tick_jitter_max_us: 0,
    tick_exec_max_us: 0,
    targets_refused: 0,
    stop: master_link::StopStatus::None,
    fault: FaultRecord {
        cause: FaultCause::None,
        joint: 0,
        value: 0.0,
        time_ms: 0,
    },
    reset: ResetStatus {
        cause: ResetCause::PowerOn,
        acknowledged: false,
    },
    setpoint_position_m: [0.0; 3],
    setpoint_rotation_vector_rad: [0.0; 3],
    margins: master_link::GuardMargins {
        nearest: 0.0,
        serial: 0.0,
        parallel: 0.0,
        stroke: 0.0,
        tilt: 0.0,
        collision: 0.0,
        workspace: 0.0,
    },
    currents_a: [0.0; master_link::JOINT_COUNT],
    supply_v: 0.0,
    fault_log_len: 0,
    missed_ticks: 0,
    owner_changes: 0,
    position_channel: false,
};

impl Default for Shared {
    fn default() -> Self {
        Self::new()
    }
}

/// The firmware version of the calling crate (its `Cargo.toml`), for `HelloReply`.
#[macro_export]
macro_rules! firmware_version {
    () => {
        $crate::FirmwareVersion {
            major: $crate::parse_version(env!("CARGO_PKG_VERSION_MAJOR")),
            minor: $crate::parse_version(env!("CARGO_PKG_VERSION_MINOR")),
            patch: $crate::parse_version(env!("CARGO_PKG_VERSION_PATCH")),
        }
    };
}

/// One component of a version number (255 if it is not a decimal number below 256).
pub const fn parse_version(s: &str) -> u8 {
    let mut rest = s.as_bytes();
    if rest.is_empty() {
        return u8::MAX;
    }
    let mut v: u32 = 0;
    while let [d, tail @ ..] = rest {
        if *d < b'0' || *d > b'9' || v > 25 {
            return u8::MAX;
        }
        v = v * 10 + (*d - b'0') as u32;
        rest = tail;
    }
    if v > 255 {
        u8::MAX
    } else {
        v as u8
    }
}

/// The board around the control tick.
pub trait ControlBoard<S: Scalar> {
    /// The hardware the runtime drives and reads.
    type Hardware: Hardware<S>;
    /// The hardware.
    fn hardware(&mut self) -> &mut Self::Hardware;
    /// A free-running core cycle counter (e.g. the DWT's).
    fn cycles(&mut self) -> u32;
    /// Feeds the independent watchdog.
    fn feed_watchdog(&mut self);
    /// Keeps the fault log for the next reset (RAM the start-up code does not clear),
    /// after every tick that logged a fault. The default keeps nothing.
    fn persist_fault_log(&mut self, log: &FaultLog) {
        let _ = log;
    }
    /// Keeps the event log's RAM view for the next reset (RAM the start-up code does not
    /// clear), after every tick that changed it. The default keeps nothing.
    fn persist_events(&mut self, log: &EventLog) {
        let _ = log;
    }
    /// Writes the event log to the board's flash (`control::event_log::EventStore::step`):
    /// at most `words` words of its oldest pending entry at `now_ms`; an erase only when
    /// `may_erase` (the drives off and the brakes applied; the board keeps its watchdog
    /// alive through it, and the control task restarts its schedule after it). The default:
    /// this board has no flash for it.
    fn store_events(
        &mut self,
        log: &mut EventLog,
        now_ms: u32,
        words: usize,
        may_erase: bool,
    ) -> Step {
        let _ = (log, now_ms, words, may_erase);
        Step::Idle
    }
    /// The part of the control period after which the tick leaves no room for programming
    /// flash in it, µs (the default: none).
    fn program_window_us(&self) -> u32 {
        0
    }
    /// Writes a calibrated geometry the runtime accepted (its checks passed, the drives are
    /// off) to the board's flash and reads it back. The core may stall for the erase of a
    /// full sector (seconds): the board keeps its watchdog alive through it, and the
    /// control task resumes its schedule afterwards without counting the pause as a missed
    /// deadline. The default: this board cannot store one.
    fn store_geometry(&mut self, record: &GeometryRecord) -> Result<(), GeometryRefusal> {
        let _ = record;
        Err(GeometryRefusal::Unsupported)
    }
    /// Before the tick at `now_us` (an emulated plant advances to it).
    fn before_tick(&mut self, now_us: u64) {
        let _ = now_us;
    }
    /// After the tick (status LED, logs).
    fn after_tick<M: Mechanism<S> + Clone>(
        &mut self,
        service: &TickService<S, M>,
        outcome: &TickOutcome,
    );
}

/// The control task: a tick every control period of `service`, forever. A tick that
/// starts more than a period late does not run the missed periods back to back: they are
/// counted ([`TickService::missed_periods`]) and the watchdog is not fed for the late tick.
pub async fn run_control<S, M, B>(
    shared: &'static Shared,
    board: &mut B,
    service: &mut TickService<S, M>,
) -> !
where
    S: Scalar,
    M: Mechanism<S> + Clone,
    B: ControlBoard<S>,
{
    let period = u64::from(service.config().watchdog.period_us);
    let mut next = Instant::now().as_micros() + period;
    loop {
        Timer::at(Instant::from_micros(next)).await;
        let c0 = board.cycles();
        let now = Instant::now().as_micros();
        next += period;
        let missed = if now >= next {
            (now - next) / period + 1
        } else {
            0
        };
        next += missed * period;
        board.before_tick(now);
        service.begin(now, missed, shared.estop.take());
        while let Ok(req) = shared.commands.try_receive() {
            let reply = service.request(&req, now);
            // An accepted Hello: the receive task opens its session before the reply
            // can reach the master.
            if let Some(session) = opened_session(&reply) {
                shared.session.lock(|c| c.set(Some((session, req.seq))));
            }
            shared.reply(reply);
        }
        // A geometry the runtime accepts is written after the tick (flash stalls the core).
        let mut accepted_geometry = None;
        if let Some((seq, record)) = shared.geometry.lock(|g| g.take()) {
            match service.check_geometry(&record) {
                Ok(_) => accepted_geometry = Some((seq, record)),
                Err(reason) => shared.reply(BoardToMaster::GeometryRefused { seq, reason }),
            }
        }
        service.tick(board.hardware(), now);
        let cycles = board.cycles().wrapping_sub(c0);
        let outcome = service.finish(now, cycles);
        if let Some(refused) = outcome.refused {
            shared.reply(BoardToMaster::TargetRefused(refused));
        }
        shared.status.lock(|s| s.set(outcome.status));
        shared.has_status.store(true, Ordering::Release);
        if outcome.feed_watchdog {
            board.feed_watchdog();
        }
        if outcome.log_changed {
            board.persist_fault_log(service.runtime().fault_log());
        }
        if outcome.events_changed {
            board.persist_events(service.runtime().events());
        }
        board.after_tick(service, &outcome);
        // The event log to flash: a few words when the tick left room for the stall, an
        // erase only with the drives off (a pause, like the geometry's store below).
        let in_window = outcome.exec_us <= board.program_window_us();
        if in_window || outcome.drives_off {
            let words = if in_window {
                control::event_log::WORDS_PER_PERIOD
            } else {
                0
            };
            let now_ms = (now / 1000) as u32;
            let events = service.runtime_mut().events_mut();
            if let Step::Erased { .. } =
                board.store_events(events, now_ms, words, outcome.drives_off)
            {
                service.resume_after_pause();
            }
        }
        if let Some((seq, record)) = accepted_geometry {
            let reply = match board.store_geometry(&record) {
                Ok(()) => {
                    service.runtime_mut().geometry_stored(record.version, now);
                    BoardToMaster::GeometryStored {
                        seq,
                        version: record.version,
                    }
                }
                Err(reason) => BoardToMaster::GeometryRefused { seq, reason },
            };
            service.resume_after_pause();
            shared.reply(reply);
        }
    }
}

/// The receiving side of the master link.
#[allow(async_fn_in_trait)]
pub trait ByteRx {
    /// Reads what arrived (at least one byte); `Err` after a framing, noise or overrun
    /// error (the link drops the partial frame).
    async fn read(&mut self, buf: &mut [u8]) -> Result<usize, ()>;
}

/// The sending side of the master link.
#[allow(async_fn_in_trait)]
pub trait ByteTx {
    /// Writes every byte of `frame`.
    async fn write_all(&mut self, frame: &[u8]);
}

/// The link's receive task: bytes -> frames -> requests for the control tick, replies the
/// link gives itself (HelloRefused UnsupportedVersion, NotConnected) for the send task. An
/// `EmergencyStop` message forces the outputs safe through `kill` before it is queued; a
/// full queue is answered `Busy`. `identity` seeds the session ids; with a `key`, frames
/// without a valid tag are dropped and counted.
pub async fn run_link_rx<R: ByteRx, K: SafeOutputs>(
    shared: &'static Shared,
    rx: &mut R,
    kill: &mut K,
    identity: BoardIdentity,
    key: Option<LinkKey>,
) -> ! {
    let mut link = LinkRx::with(identity, key);
    let mut buf = [0u8; 64];
    loop {
        let read = rx.read(&mut buf).await;
        link.set_uptime(Instant::now().as_micros());
        if let Some((session, seq)) = shared.session.lock(|c| c.take()) {
            link.open_session(session, seq);
        }
        match read {
            Ok(n) => {
                for byte in buf.iter().take(n) {
                    match link.push(*byte) {
                        Some(Inbound::Reply(reply)) => shared.reply(reply),
                        Some(Inbound::Geometry { seq, record }) => {
                            let queued = shared.geometry.lock(|g| {
                                let free = g.get().is_none();
                                if free {
                                    g.set(Some((seq, record)));
                                }
                                free
                            });
                            if !queued {
                                shared.reply(BoardToMaster::Nack {
                                    seq,
                                    reason: NackReason::Busy,
                                });
                            }
                        }
                        Some(Inbound::Request(req)) => {
                            if req.message == master_link::MasterToBoard::EmergencyStop {
                                // Do not wait for the next tick.
                                critical_section::with(|_| {
                                    emergency_stop_message(kill, &shared.estop)
                                });
                            }
                            if shared.commands.try_send(req).is_err() {
                                shared.reply(BoardToMaster::Nack {
                                    seq: req.seq,
                                    reason: NackReason::Busy,
                                });
                            }
                        }
                        None => {}
                    }
                }
            }
            Err(()) => link.resync(),
        }
        shared.connected.store(link.connected(), Ordering::Relaxed);
        let counters = link.counters();
        shared.link.lock(|c| c.set(Some(counters)));
    }
}

/// The link's send task: replies as they come, and the latest status every
/// `telemetry_ms` once a session is open, with the receiving side's counters; with a
/// `key`, every frame tagged.
pub async fn run_link_tx<T: ByteTx>(
    shared: &'static Shared,
    tx: &mut T,
    telemetry_ms: u64,
    key: Option<LinkKey>,
) -> ! {
    let mut link = LinkTx::with_key(key);
    let mut telemetry = Ticker::every(Duration::from_millis(telemetry_ms));
    let mut buf = [0u8; MAX_FRAME_LEN];
    loop {
        let msg = match select(shared.replies.receive(), telemetry.next()).await {
            Either::First(m) => m,
            Either::Second(()) => {
                if !shared.connected.load(Ordering::Relaxed)
                    || !shared.has_status.load(Ordering::Acquire)
                {
                    continue;
                }
                BoardToMaster::Status(shared.status.lock(|s| s.get()))
            }
        };
        let msg = match msg {
            BoardToMaster::Status(mut s) => {
                with_link(&mut s, shared.link.lock(|c| c.get()));
                BoardToMaster::Status(s)
            }
            other => other,
        };
        match link.encode(&msg, &mut buf) {
            Ok(n) => {
                if let Some(frame) = buf.get(..n) {
                    tx.write_all(frame).await;
                }
            }
            Err(_) => {
                shared.encode_errors.fetch_add(1, Ordering::Relaxed);
            }
        }
    }
}
