//! The `commands` target: a structured scenario drives the board's side of the master link
//! (`control::link::LinkRx` / `LinkTx`) and a booted runtime inside the board's tick service
//! (`control::service::TickService`) on the fake hardware ([`crate::fake_hw`]), the way the
//! board's tasks do (`firmware/cortex-m/board-tasks`): received frames become requests,
//! queued for the next control tick; an `EmergencyStop` request forces the outputs safe and
//! trips the e-stop latch at once (`control::estop::emergency_stop_isr`); each tick begins
//! (timing, latch), answers the queued requests (`Runtime::command`, `Request::reply`),
//! runs the runtime's tick and finishes (deadline policy, status); every reply is encoded by
//! `LinkTx` and decoded by a master's `MasterDecoder`.
//!
//! Invariants, each an assertion (see [`Board`]'s checks):
//! * no panic, and bounded work (at most [`MAX_ACTIONS`] actions, [`MAX_BYTES`] bytes per
//!   action, [`MAX_TICKS`] ticks);
//! * every accepted frame gives exactly one inbound item (`frames_ok` grows by the number
//!   of items); an intact `EmergencyStop` frame or a `Hello` frame is always accepted;
//! * every request gets exactly one reply, of the kind its command calls for, carrying its
//!   sequence number; every reply encodes within `MAX_FRAME_LEN`, and the master's decoder
//!   accepts it (session, sequence) and decodes it to the same message;
//! * every duty written to the hardware is finite and within [-1, 1] (asserted in
//!   [`crate::fake_hw::FakeHw`]);
//! * after each tick: the runtime's torque flag matches the bridges; the brakes are only
//!   released while the bridges are on; the bridges are on only in `Homing`, `Enabling` or
//!   `Enabled` or during a stop under power (SS1/SS2 decelerating, SS1 braking, SOS
//!   holding); a nonzero duty with the brakes applied only in the brake check (`Enabling`,
//!   no stop in force, each duty within the check's) or in SS1's braking phase (IEC 61800-5-2:
//!   the brakes engage while the drives still hold);
//! * an `EmergencyStop` request leaves the runtime in `Fault` at once, and after the tick
//!   that handled it the bridges are off and the brakes applied; a pressed e-stop button
//!   gives, by the end of the tick that read it, `Fault`, torque off and brakes applied;
//! * no request answered in a tick whose start took the e-stop latch (the button's ISR, an
//!   `EmergencyStop` frame's receive path) leaves `Fault`: no status has reported the stop
//!   yet, so the request was sent before its master could know of it and does not end it
//!   (`control::modes`: a `ClearFault` of that tick is refused).

use std::sync::OnceLock;

use arbitrary::Arbitrary;
use board_profile::BoardProfile;
use control::estop::{emergency_stop_isr, emergency_stop_message, EStopLatch};
use control::link::{opened_session, Inbound, LinkRx, LinkTx, Request, FIRMWARE_VERSION};
use control::modes::{State, ALL_STATES};
use control::runtime::RuntimeTick;
use control::service::{ServiceConfig, TickService};
use control::stops::StopPhase;
use control::telemetry::with_link;
use hal::NUM_JOINTS;
use kinematics_core::RsprGeometry;
use master_link::MasterToBoard as Command;
use master_link::{
    decode_frame, encode, BoardToMaster, FaultCause, Header, MasterDecoder, MasterToBoard,
    NackReason, ResetCause, SeqCounter, MAX_FRAME_LEN, PROTOCOL_VERSION,
};

use crate::fake_hw::{Currents, FakeHw, HwInputs, Motion, NOMINAL_SUPPLY_V};
use crate::snapshots::{self, Snapshot, Snapshots};

/// Actions per input at most (the rest is ignored).
pub const MAX_ACTIONS: usize = 64;
/// Bytes per `Bytes` action at most.
pub const MAX_BYTES: usize = 256;
/// Control ticks per input at most (later `Tick` actions are ignored): about one second of
/// board time, past the heartbeat's disable time and the stops' deceleration timeout
/// (500 ms each), which only nominal periods reach (a later tick is a missed deadline).
pub const MAX_TICKS: u32 = 1024;
/// Ticks per `Tick` action at most.
pub const TICKS_PER_ACTION: u8 = 64;
/// The control period, µs (the board profile's).
pub const PERIOD_US: u64 = BoardProfile::REFERENCE.control_period_us as u64;
/// The board's core clock, Hz (the board profile's).
pub const CPU_HZ: u32 = BoardProfile::REFERENCE.cpu_hz;
/// Cycles per unit of `Tick::exec` (255 units: 910 µs at 168 MHz, above the 800 µs budget).
pub const CYCLES_PER_EXEC_UNIT: u32 = 600;
/// A tick's execution time when the input does not say, cycles (about 180 µs).
pub const NOMINAL_CYCLES: u32 = 30_000;

/// One input of the target.
#[derive(Arbitrary, Debug, Clone)]
pub struct Scenario {
    /// Where the runtime starts.
    pub start: Start,
    /// What happens, in order (at most [`MAX_ACTIONS`]).
    pub actions: Vec<Action>,
}

/// The starting runtime ([`Snapshots`]).
#[derive(Arbitrary, Debug, Clone, Copy, PartialEq, Eq)]
pub enum Start {
    /// Booted after a power-on reset: `Disabled`.
    Booted,
    /// Booted after this reset (watchdog and brown-out resets need an acknowledgement).
    Rebooted(Reset),
    /// In the middle of homing.
    Homing,
    /// Homed: `Ready`.
    Ready,
    /// In the brake check.
    Enabling,
    /// Enabled, holding.
    Enabled,
}

/// A reset cause.
#[derive(Arbitrary, Debug, Clone, Copy, PartialEq, Eq)]
pub enum Reset {
    /// Power-on.
    PowerOn,
    /// The reset pin.
    Pin,
    /// Software.
    Software,
    /// The independent watchdog.
    Watchdog,
    /// The window watchdog.
    WindowWatchdog,
    /// A brown-out.
    BrownOut,
    /// Low-power management.
    LowPower,
}

impl From<Reset> for ResetCause {
    fn from(r: Reset) -> Self {
        match r {
            Reset::PowerOn => ResetCause::PowerOn,
            Reset::Pin => ResetCause::Pin,
            Reset::Software => ResetCause::Software,
            Reset::Watchdog => ResetCause::Watchdog,
            Reset::WindowWatchdog => ResetCause::WindowWatchdog,
            Reset::BrownOut => ResetCause::BrownOut,
            Reset::LowPower => ResetCause::LowPower,
        }
    }
}

/// One step of a scenario.
#[derive(Arbitrary, Debug, Clone)]
pub enum Action {
    /// Raw bytes on the link (at most [`MAX_BYTES`]).
    Bytes(Vec<u8>),
    /// One well-formed frame of a master message, after a delimiter (so that a partial
    /// frame before it is dropped, not merged with it).
    Frame {
        /// The message.
        msg: Msg,
        /// Its header.
        header: HeaderChoice,
    },
    /// Control ticks.
    Tick {
        /// Time since the previous tick.
        period: Period,
        /// How many ticks (1 + count % [`TICKS_PER_ACTION`]).
        count: u8,
        /// Execution time reported to the service (`None`: nominal), in units of
        /// [`CYCLES_PER_EXEC_UNIT`] cycles.
        exec: Option<u8>,
        /// The e-stop button's interrupt fires before the first of them.
        estop_irq: bool,
    },
    /// New hardware inputs.
    Set(Inputs),
    /// A UART framing error: the link drops the partial frame.
    Resync,
}

/// The time between ticks.
#[derive(Arbitrary, Debug, Clone, Copy, PartialEq, Eq)]
pub enum Period {
    /// One control period.
    Nominal,
    /// This many µs (late, early or missed periods).
    Us(u16),
}

/// The header of a master frame.
#[derive(Arbitrary, Debug, Clone, Copy, PartialEq, Eq)]
pub enum HeaderChoice {
    /// The master's session and next sequence number.
    Next,
    /// The master's session and the last sequence number again (a replay).
    Replay,
    /// The master's session, skipping this many sequence numbers.
    Skip(u8),
    /// Another session, the next sequence number.
    Session(u32),
    /// Anything.
    Raw {
        /// Session.
        session: u32,
        /// Sequence number.
        seq: u16,
    },
}

/// A master message: any message of the command set as `master-link` defines it (built by
/// `arbitrary` from that one definition), or one of the messages whose values matter for
/// the board's behaviour drawn near the robot's workspace and the board's clock (raw values
/// stay reachable through [`Msg::Any`]).
#[derive(Arbitrary, Debug, Clone, Copy, PartialEq)]
pub enum Msg {
    /// Any message, raw.
    Any(MasterToBoard),
    /// Hello (`version: None`: the board's).
    Hello {
        /// Protocol version.
        version: Option<u8>,
        /// The master's nonce.
        nonce: u32,
        /// The master's clock in it.
        clock: Stamp,
    },
    /// A pose target near the workspace's centre.
    PoseTarget {
        /// Its stamp.
        stamp: Stamp,
        /// Position.
        position: Position,
        /// Orientation.
        rotation: Rotation,
    },
    /// Jog at a speed near the jog limits.
    Jog {
        /// Joint (any byte).
        joint: u8,
        /// Velocity.
        velocity: Velocity,
    },
}

/// A target's master timestamp.
#[derive(Arbitrary, Debug, Clone, Copy, PartialEq, Eq)]
pub enum Stamp {
    /// The board's time now.
    Now,
    /// This many µs after it.
    Ahead(u16),
    /// This many µs before it.
    Behind(u16),
    /// Anything.
    Raw(u64),
}

/// A target position.
#[derive(Arbitrary, Debug, Clone, Copy, PartialEq)]
pub enum Position {
    /// Offsets from the central pose, µm.
    Near([i16; 3]),
    /// Anything, m.
    Raw([f32; 3]),
}

/// A target orientation.
#[derive(Arbitrary, Debug, Clone, Copy, PartialEq)]
pub enum Rotation {
    /// A rotation vector, mrad.
    Near([i8; 3]),
    /// Anything, rad.
    Raw([f32; 3]),
}

/// A jog velocity.
#[derive(Arbitrary, Debug, Clone, Copy, PartialEq)]
pub enum Velocity {
    /// mm/s or mrad/s.
    Small(i8),
    /// Anything.
    Raw(f32),
}

/// The fake hardware's inputs.
#[derive(Arbitrary, Debug, Clone, Copy, PartialEq)]
pub struct Inputs {
    /// Limit switches, one bit per joint.
    pub switches: u8,
    /// The e-stop button is pressed.
    pub estop: bool,
    /// The safety relay's feedback is open.
    pub relay_open: bool,
    /// The drivers report a fault.
    pub driver_fault: bool,
    /// The supply voltage.
    pub supply: Supply,
    /// The current sensors.
    pub currents: Currents,
    /// The encoders' motion.
    pub motion: Motion,
    /// An encoder jump now, counts.
    pub jump: Option<[i16; NUM_JOINTS]>,
}

/// The supply voltage read.
#[derive(Arbitrary, Debug, Clone, Copy, PartialEq)]
pub enum Supply {
    /// 24 V.
    Nominal,
    /// Whole volts.
    Volts(u8),
    /// Anything.
    Raw(f64),
}

/// The service's settings: the board profile's period and core clock.
pub fn service_config() -> ServiceConfig {
    ServiceConfig::for_period(PERIOD_US as u32, CPU_HZ, FIRMWARE_VERSION)
}

/// Which known findings fail the checks. All three are fixed in the product, so by default
/// every one fails them (`Strict::ALL`); `RSPR_FUZZ_STRICT` can waive them again (`0` or
/// `none` every one, or the ones named: `duty` finding 1, `stops` finding 2, `isr` finding
/// 3, comma-separated, are the strict ones), to bisect an old product. Each waiver is as
/// narrow as its finding (see `fuzz/README.md`):
/// * finding 1: a duty outside [-1, 1] is accepted where the current limit set it;
/// * finding 2: a stop-table STO row (encoder jump, limit switch, joint range) not carried
///   out in its tick is accepted while an `OverTemperature` fault is latched;
/// * finding 3: the runtime's torque flag on with the bridges off (and the brakes released
///   without torque) is accepted while the e-stop path's `force_safe` has switched the
///   bridges off and the runtime has not switched them since.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Strict {
    /// Finding 1 fails the checks.
    pub duty: bool,
    /// Finding 2 fails the checks.
    pub stops: bool,
    /// Finding 3 fails the checks.
    pub isr: bool,
}

impl Strict {
    /// Every finding fails the checks.
    pub const ALL: Strict = Strict {
        duty: true,
        stops: true,
        isr: true,
    };

    /// From the value of `RSPR_FUZZ_STRICT`.
    pub fn parse(value: &str) -> Strict {
        let mut s = Strict::default();
        for part in value.split(',').map(str::trim) {
            match part {
                "1" | "all" => s = Strict::ALL,
                "duty" => s.duty = true,
                "stops" => s.stops = true,
                "isr" => s.isr = true,
                _ => {}
            }
        }
        s
    }
}

/// The strictness `RSPR_FUZZ_STRICT` asks for (read once).
pub fn strict() -> Strict {
    static STRICT: OnceLock<Strict> = OnceLock::new();
    *STRICT.get_or_init(|| {
        std::env::var("RSPR_FUZZ_STRICT").map_or(Strict::ALL, |v| Strict::parse(&v))
    })
}

/// The snapshots, taken once per process.
pub fn snapshots() -> &'static Snapshots {
    static SNAPSHOTS: OnceLock<Snapshots> = OnceLock::new();
    SNAPSHOTS.get_or_init(|| snapshots::build(service_config(), NOMINAL_CYCLES))
}

/// What a scenario reached (for the seed generator and the tests).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Outcome {
    /// States seen after ticks.
    pub states: Vec<State>,
    /// Replies sent, by kind: (HelloReply, Ack, Nack, Status, FaultLog or EventLog,
    /// Geometry*).
    pub replies: [u32; 6],
    /// Nack reasons seen.
    pub nacks: Vec<NackReason>,
    /// Ticks run.
    pub ticks: u32,
    /// Joints and ticks with a duty outside [-1, 1] from the current limit (finding 1;
    /// only counted when the checks are not strict).
    pub duty_over_range: u32,
    /// Ticks where an STO row of the stop table was not carried out while an
    /// `OverTemperature` fault was latched (finding 2; only counted when not strict).
    pub masked_stops: u32,
    /// Ticks where the runtime believed its bridges on after the e-stop path had forced
    /// them off (finding 3; only counted when not strict).
    pub stale_outputs: u32,
}

/// The board under test, with the master's side of the link.
pub struct Board {
    service: TickService<f64, RsprGeometry<f64>>,
    hw: FakeHw,
    rx: LinkRx,
    tx: LinkTx,
    queue: Vec<Request>,
    /// A received calibrated geometry for the next tick.
    geometry: Option<(master_link::Seq, master_link::GeometryRecord)>,
    latch: EStopLatch,
    now: u64,
    /// The master: its session, sequence numbers, decoder of the board's frames.
    session: u32,
    seq: SeqCounter,
    last_seq: u16,
    master_rx: MasterDecoder,
    /// The central pose's height, m.
    hc: f32,
    /// An `EmergencyStop` was handled in this tick: the drives must be off after it.
    estop_pending: bool,
    /// This tick's start took the e-stop latch: no request of the tick leaves `Fault`.
    estop_latched_now: bool,
    /// Which known findings fail the checks ([`Strict`]).
    strict: Strict,
    /// No tick since the boot: the encoder check has no earlier reading to compare with.
    first_reading: bool,
    requests: u32,
    answered: u32,
    outcome: Outcome,
}

impl Board {
    /// The board started at `start`; `strict`: see [`Strict`].
    pub fn new(start: Start, strict: Strict) -> Self {
        let s = snapshots();
        let snap: &Snapshot = match start {
            Start::Booted => &s.booted,
            Start::Rebooted(_) => &s.unbooted,
            Start::Homing => &s.homing,
            Start::Ready => &s.ready,
            Start::Enabling => &s.enabling,
            Start::Enabled => &s.enabled,
        };
        let service = match (&snap.service, start) {
            (Some(sv), _) => sv.clone(),
            (None, Start::Rebooted(reset)) => {
                let mut runtime = snap.runtime.clone();
                if let Err(e) = runtime.boot_done(snap.counts, snap.now_us, reset.into(), None) {
                    panic!("boot refused: {e:?}");
                }
                TickService::new(runtime, service_config())
            }
            (None, _) => panic!("snapshot {start:?} without its service"),
        };
        let runtime = service.runtime();
        let cfg = runtime.config();
        let mut hw = FakeHw::new(
            snap.counts,
            cfg.encoder_check.counts_per_unit,
            cfg.current.motors,
        );
        (hw.enabled, hw.duty, hw.brakes_released) = snap.outputs;
        hw.strict_duty = strict.duty;
        let hc = runtime.robot().hc as f32;
        // The master that brought the board up (from homing on) has its session open.
        let owned = !matches!(start, Start::Booted | Start::Rebooted(_));
        let mut rx = LinkRx::new();
        if owned {
            rx.open_session(snapshots::OWNER_SESSION, u16::MAX);
        }
        Board {
            service,
            hw,
            rx,
            tx: LinkTx::new(),
            queue: Vec::new(),
            geometry: None,
            latch: EStopLatch::new(),
            now: snap.now_us,
            session: if owned { snapshots::OWNER_SESSION } else { 0 },
            seq: SeqCounter::new(0),
            last_seq: 0,
            master_rx: MasterDecoder::new(),
            hc,
            estop_pending: false,
            estop_latched_now: false,
            strict,
            first_reading: matches!(start, Start::Booted | Start::Rebooted(_)),
            requests: 0,
            answered: 0,
            outcome: Outcome::default(),
        }
    }

    /// Runs a scenario with every check (strict as [`strict`] says); returns what it
    /// reached.
    pub fn run(scenario: &Scenario) -> Outcome {
        Self::run_with(scenario, strict())
    }

    /// Runs a scenario with every check, the known findings failing them as `strict` says.
    pub fn run_with(scenario: &Scenario, strict: Strict) -> Outcome {
        let mut board = Board::new(scenario.start, strict);
        for action in scenario.actions.iter().take(MAX_ACTIONS) {
            board.act(action);
        }
        // Every accepted request is answered: a last tick for those still queued.
        if !board.queue.is_empty() || board.geometry.is_some() {
            board.tick(PERIOD_US, NOMINAL_CYCLES, false);
        }
        assert_eq!(
            board.requests, board.answered,
            "requests accepted against requests answered"
        );
        board.outcome
    }

    fn act(&mut self, action: &Action) {
        match action {
            Action::Bytes(bytes) => {
                let n = bytes.len().min(MAX_BYTES);
                let bytes = bytes.get(..n).unwrap_or_default();
                self.receive(bytes);
            }
            Action::Frame { msg, header } => self.frame(msg, *header),
            Action::Tick {
                period,
                count,
                exec,
                estop_irq,
            } => {
                let dt = match period {
                    Period::Nominal => PERIOD_US,
                    Period::Us(us) => u64::from(*us),
                };
                let cycles = exec.map_or(NOMINAL_CYCLES, |e| u32::from(e) * CYCLES_PER_EXEC_UNIT);
                for i in 0..=(count % TICKS_PER_ACTION) {
                    if self.outcome.ticks >= MAX_TICKS {
                        break;
                    }
                    self.tick(dt, cycles, *estop_irq && i == 0);
                }
            }
            Action::Set(inputs) => self.set(inputs),
            Action::Resync => self.rx.resync(),
        }
    }

    fn set(&mut self, i: &Inputs) {
        self.hw.inputs = HwInputs {
            switches: std::array::from_fn(|j| i.switches & (1 << j) != 0),
            estop: i.estop,
            relay_open: i.relay_open,
            driver_fault: i.driver_fault,
            supply_v: match i.supply {
                Supply::Nominal => NOMINAL_SUPPLY_V,
                Supply::Volts(v) => f64::from(v),
                Supply::Raw(v) => v,
            },
            currents: i.currents,
            motion: i.motion,
        };
        if let Some(j) = i.jump {
            self.hw.jump(&j);
        }
    }

    /// The wire message of `msg` at board time `now`.
    fn message(&self, msg: &Msg) -> MasterToBoard {
        let stamp = |s: &Stamp| match s {
            Stamp::Now => self.now,
            Stamp::Ahead(d) => self.now.saturating_add(u64::from(*d)),
            Stamp::Behind(d) => self.now.saturating_sub(u64::from(*d)),
            Stamp::Raw(x) => *x,
        };
        match *msg {
            Msg::Hello {
                version,
                nonce,
                clock,
            } => MasterToBoard::Hello {
                protocol_version: version.unwrap_or(PROTOCOL_VERSION),
                nonce,
                clock_us: stamp(&clock),
            },
            Msg::PoseTarget {
                stamp: s,
                position,
                rotation,
            } => MasterToBoard::PoseTarget {
                timestamp_us: stamp(&s),
                position_m: match position {
                    Position::Near([x, y, z]) => [
                        f32::from(x) * 1e-6,
                        f32::from(y) * 1e-6,
                        self.hc + f32::from(z) * 1e-6,
                    ],
                    Position::Raw(p) => p,
                },
                rotation_vector_rad: match rotation {
                    Rotation::Near(r) => r.map(|x| f32::from(x) * 1e-3),
                    Rotation::Raw(r) => r,
                },
            },
            Msg::Jog { joint, velocity } => MasterToBoard::Jog {
                joint,
                velocity: match velocity {
                    Velocity::Small(v) => f32::from(v) * 1e-3,
                    Velocity::Raw(v) => v,
                },
            },
            Msg::Any(m) => m,
        }
    }

    /// Sends one well-formed frame (after a delimiter).
    fn frame(&mut self, msg: &Msg, choice: HeaderChoice) {
        let wire = self.message(msg);
        let header = match choice {
            HeaderChoice::Next => Header {
                session: self.session,
                seq: self.seq.next(),
            },
            HeaderChoice::Replay => Header {
                session: self.session,
                seq: self.last_seq,
            },
            HeaderChoice::Skip(n) => {
                for _ in 0..n {
                    self.seq.next();
                }
                Header {
                    session: self.session,
                    seq: self.seq.next(),
                }
            }
            HeaderChoice::Session(session) => Header {
                session,
                seq: self.seq.next(),
            },
            HeaderChoice::Raw { session, seq } => Header { session, seq },
        };
        self.last_seq = header.seq;
        let mut buf = [0u8; MAX_FRAME_LEN + 1];
        let n = match encode(&wire, header, buf.get_mut(1..).unwrap_or_default()) {
            Ok(n) => n,
            Err(e) => panic!("a master message does not encode ({e:?}): {wire:?}"),
        };
        let bytes = buf.get(..=n).unwrap_or_default().to_vec();
        let inbound = self.receive(&bytes);
        // No filter drops an intact emergency stop or a Hello.
        match wire {
            MasterToBoard::EmergencyStop => assert!(
                matches!(
                    inbound.as_slice(),
                    [Inbound::Request(Request {
                        message: Command::EmergencyStop,
                        ..
                    })]
                ),
                "an intact EmergencyStop frame ({header:?}) gave {inbound:?}"
            ),
            MasterToBoard::Hello { .. } => assert!(
                inbound.len() == 1,
                "an intact Hello frame ({header:?}) gave {inbound:?}"
            ),
            _ => assert!(inbound.len() <= 1, "one frame gave {inbound:?}"),
        }
    }

    /// Link bytes in: every accepted frame gives exactly one item; the link's own replies
    /// go out, requests are queued for the next tick (an emergency stop forces the outputs
    /// safe first, as the board's receive task does).
    fn receive(&mut self, bytes: &[u8]) -> Vec<Inbound> {
        let before = self.rx.counters();
        let mut inbound = Vec::new();
        for b in bytes {
            if let Some(i) = self.rx.push(*b) {
                inbound.push(i);
            }
        }
        let after = self.rx.counters();
        assert_eq!(
            u64::from(after.frames_ok - before.frames_ok),
            inbound.len() as u64,
            "accepted frames against inbound items"
        );
        for i in &inbound {
            match i {
                Inbound::Reply(reply) => {
                    assert!(
                        matches!(
                            reply,
                            BoardToMaster::Nack {
                                reason: NackReason::NotConnected,
                                ..
                            } | BoardToMaster::HelloRefused {
                                reason: NackReason::UnsupportedVersion,
                                ..
                            }
                        ),
                        "the link answered {reply:?}"
                    );
                    self.send(*reply);
                }
                Inbound::Geometry { seq, record } => {
                    // As the board's receive task: one calibrated geometry at a time.
                    if self.geometry.is_some() {
                        self.send(BoardToMaster::Nack {
                            seq: *seq,
                            reason: NackReason::Busy,
                        });
                    } else {
                        self.geometry = Some((*seq, *record));
                        self.requests += 1;
                    }
                }
                Inbound::Request(req) => {
                    if req.message == Command::EmergencyStop {
                        emergency_stop_message(&mut self.hw, &self.latch);
                    }
                    self.queue.push(*req);
                    self.requests += 1;
                }
            }
        }
        inbound
    }

    /// A reply out: encoded within `MAX_FRAME_LEN`, accepted by the master's decoder and
    /// decoded to the same message.
    fn send(&mut self, reply: BoardToMaster) {
        let msg = match reply {
            BoardToMaster::Status(mut s) => {
                with_link(&mut s, Some(self.rx.counters()));
                BoardToMaster::Status(s)
            }
            other => other,
        };
        let kind = match msg {
            BoardToMaster::HelloReply { .. } => 0,
            BoardToMaster::Ack { .. } => 1,
            BoardToMaster::Nack { reason, .. } => {
                if !self.outcome.nacks.contains(&reason) {
                    self.outcome.nacks.push(reason);
                }
                2
            }
            BoardToMaster::Status(_) => 3,
            BoardToMaster::FaultLog(_)
            | BoardToMaster::EventLog(_)
            | BoardToMaster::Commissioning(_) => 4,
            BoardToMaster::GeometryStored { .. } | BoardToMaster::GeometryRefused { .. } => 5,
            BoardToMaster::HelloRefused { reason, .. } => {
                if !self.outcome.nacks.contains(&reason) {
                    self.outcome.nacks.push(reason);
                }
                0
            }
            BoardToMaster::TargetRefused(r) => {
                if !self.outcome.nacks.contains(&r.reason) {
                    self.outcome.nacks.push(r.reason);
                }
                2
            }
        };
        if let Some(k) = self.outcome.replies.get_mut(kind) {
            *k += 1;
        }
        let mut buf = [0u8; MAX_FRAME_LEN];
        let n = match self.tx.encode(&msg, &mut buf) {
            Ok(n) => n,
            Err(e) => panic!("a reply does not encode ({e:?}): {msg:?}"),
        };
        assert!(n <= MAX_FRAME_LEN, "a reply of {n} bytes");
        let frame = buf.get(..n).unwrap_or_default();
        let mut content = frame.get(..n - 1).unwrap_or_default().to_vec();
        let (header, decoded) = match decode_frame::<BoardToMaster>(&mut content) {
            Ok(x) => x,
            Err(e) => panic!("a reply does not decode ({e:?}): {msg:?}"),
        };
        let mut again = [0u8; MAX_FRAME_LEN];
        let m = encode(&decoded, header, &mut again).unwrap_or(0);
        assert_eq!(
            again.get(..m),
            Some(frame),
            "a reply decodes to another message: {msg:?} -> {decoded:?}"
        );
        let mut results = Vec::new();
        for b in frame {
            if let Some(r) = self.master_rx.push(*b) {
                results.push(r);
            }
        }
        assert!(
            matches!(results.as_slice(), [Ok((seq, _))] if *seq == header.seq),
            "the master's decoder gave {results:?} for {msg:?} ({header:?})"
        );
        // The master (every Hello is the harness's) opens the session the board issued.
        if let BoardToMaster::HelloReply { session, .. } = msg {
            self.session = session;
            self.master_rx.open_session(session, header.seq);
        }
    }

    /// One control tick `dt_us` after the last, as the board's control task runs it.
    fn tick(&mut self, dt_us: u64, cycles: u32, estop_irq: bool) {
        if estop_irq {
            emergency_stop_isr(&mut self.hw, &self.latch);
        }
        self.hw
            .advance(dt_us as f64 * 1e-6, PERIOD_US as f64 * 1e-6);
        self.now += dt_us;
        let missed = (dt_us / PERIOD_US).saturating_sub(1);
        let now = self.now;
        self.estop_latched_now = self.latch.is_tripped();
        self.service.begin(now, missed, self.latch.take());
        for req in std::mem::take(&mut self.queue) {
            let reply = self.service.request(&req, now);
            self.answered += 1;
            self.check_reply(&req, &reply);
            // As the board: an accepted Hello's session opens before the reply goes out.
            if let Some(session) = opened_session(&reply) {
                self.rx.open_session(session, req.seq);
            }
            self.send(reply);
        }
        // As the board's control task: the runtime's checks, then the store (this board's
        // flash always takes it); refused while the drives are on.
        if let Some((seq, record)) = self.geometry.take() {
            self.answered += 1;
            let reply = match self.service.check_geometry(&record) {
                Ok(_) => {
                    let state = self.service.runtime().state();
                    assert!(
                        matches!(state, State::Disabled | State::Ready),
                        "a geometry accepted in {state:?}"
                    );
                    self.service
                        .runtime_mut()
                        .set_geometry_version(record.version);
                    BoardToMaster::GeometryStored {
                        seq,
                        version: record.version,
                    }
                }
                Err(reason) => BoardToMaster::GeometryRefused { seq, reason },
            };
            self.send(reply);
        }
        self.hw.over_range = [false; NUM_JOINTS];
        let before = (
            self.service.runtime().state(),
            self.service.runtime().homed(),
            self.service.runtime().latched_fault().cause,
        );
        let tick = self.service.tick(&mut self.hw, now);
        self.outcome.ticks += 1;
        self.check_tick(&tick, before);
        // The end of the tick: the deadline policy may latch a fault now (its stop acts on
        // the next tick's outputs).
        let outcome = self.service.finish(now, cycles);
        // As the board: a target its path check refused is sent on its own.
        if let Some(refused) = outcome.refused {
            assert_eq!(
                refused.reply_to, None,
                "a later refusal replies to no frame"
            );
            self.send(BoardToMaster::TargetRefused(refused));
        }
        let state = self.service.runtime().state();
        assert_eq!(outcome.state, state, "outcome state");
        assert_eq!(outcome.status.state, state, "status state");
    }

    /// The reply fits the request; an emergency stop faults at once.
    fn check_reply(&mut self, req: &Request, reply: &BoardToMaster) {
        let rt = self.service.runtime();
        let seq = req.seq;
        let ack = *reply == BoardToMaster::Ack { seq };
        let ack_or_nack = ack
            || matches!(reply, BoardToMaster::Nack { seq: s, .. } if *s == seq)
            || matches!(reply, BoardToMaster::TargetRefused(r) if r.reply_to == Some(seq)
                && matches!(req.message, Command::PoseTarget { .. } | Command::Jog { .. }));
        let not_owner = *reply
            == BoardToMaster::Nack {
                seq,
                reason: NackReason::NotOwner,
            };
        let fits = match req.message {
            // The session the link issued, the nonce echoed; or refused, echoed too.
            Command::Hello { nonce, .. } => match reply {
                BoardToMaster::HelloReply {
                    session,
                    nonce: n,
                    protocol_version,
                    ..
                } => {
                    *session == req.session
                        && *session != 0
                        && *n == nonce
                        && *protocol_version == PROTOCOL_VERSION
                }
                BoardToMaster::HelloRefused {
                    seq: s, nonce: n, ..
                } => *s == seq && *n == nonce,
                _ => false,
            },
            // Read only, yet a frame of a session a later Hello replaced is refused like any
            // other (`NotOwner`, the tick's session check).
            Command::StatusRequest => matches!(reply, BoardToMaster::Status(_)) || not_owner,
            Command::FaultLogRequest { .. } => {
                matches!(reply, BoardToMaster::FaultLog(_)) || not_owner
            }
            Command::EventLogRequest { .. } => {
                matches!(reply, BoardToMaster::EventLog(_)) || not_owner
            }
            // The record of the joint asked for, or refused (a replaced session's frame too).
            Command::Commission { joint, .. } => {
                matches!(reply, BoardToMaster::Commissioning(r) if r.joint == joint)
                    || matches!(reply, BoardToMaster::Nack { seq: s, .. } if *s == seq)
            }
            // An emergency stop is taken from anyone; a heartbeat of a replaced session is
            // refused like its other frames.
            Command::EmergencyStop => ack,
            Command::Heartbeat => ack || not_owner,
            // Taken only with the drives off (the transition table); refused otherwise.
            Command::AcknowledgeReset => {
                ack || not_owner
                    || *reply
                        == BoardToMaster::Nack {
                            seq,
                            reason: NackReason::InvalidState,
                        }
            }
            _ => ack_or_nack,
        };
        assert!(fits, "{:?} answered {reply:?}", req.message);
        assert_eq!(rt.status().state, rt.state(), "status state");
        assert!(
            !self.estop_latched_now || rt.state() == State::Fault,
            "{:?} ({reply:?}) ended the emergency stop latched at the start of its tick: {:?}",
            req.message,
            rt.state()
        );
        if req.message == Command::EmergencyStop {
            assert_eq!(rt.state(), State::Fault, "state after an EmergencyStop");
            self.estop_pending = true;
        }
    }

    /// The outputs after a tick (`before`: the state, whether homed and the latched fault's
    /// cause as the tick began).
    fn check_tick(&mut self, tick: &RuntimeTick<f64>, before: (State, bool, FaultCause)) {
        let rt = self.service.runtime();
        let (state, phase, hw) = (rt.state(), rt.stop_phase(), &self.hw);
        if !self.outcome.states.contains(&state) {
            self.outcome.states.push(state);
        }
        let ctx = || {
            format!(
                "state {state:?}, stop {phase:?}, bridges on {}, duty {:?}, brakes released {}, inputs {:?}",
                hw.enabled, hw.duty, hw.brakes_released, hw.inputs
            )
        };
        assert!(ALL_STATES.contains(&state));
        assert_eq!(tick.state, state, "tick state");
        // Finding 1 (README): the current limit can move a duty outside [-1, 1]. Unless
        // the checks are strict, a duty outside is accepted only where the current limit
        // set it this tick; anything else writing one is still caught.
        let limited = rt.monitors().current.limited();
        for (j, (over, lim)) in hw.over_range.iter().zip(limited.iter()).enumerate() {
            if *over {
                assert!(
                    *lim,
                    "duty outside [-1, 1] on joint {j}, not from the current limit: {}",
                    ctx()
                );
                self.outcome.duty_over_range += 1;
            }
        }
        // Finding 3 (README): after the e-stop path forced the outputs safe, the runtime may
        // go on believing its bridges are on. Unless strict, these two checks are waived
        // while that is so (the bridges forced off and not switched by the runtime since).
        let stale = hw.forced_safe && tick.drives_on && !hw.enabled;
        if stale && !self.strict.isr {
            self.outcome.stale_outputs += 1;
        } else {
            assert_eq!(
                tick.drives_on,
                hw.enabled,
                "the runtime's torque flag against the bridges: {}",
                ctx()
            );
            assert!(
                !hw.brakes_released || hw.enabled,
                "brakes released without torque: {}",
                ctx()
            );
        }
        let under_power = matches!(
            phase,
            StopPhase::Decelerating { .. } | StopPhase::Braking { .. } | StopPhase::Holding
        );
        if hw.enabled {
            assert!(
                matches!(
                    state,
                    State::Homing | State::Enabling | State::Enabled | State::Commissioning
                ) || under_power,
                "bridges on: {}",
                ctx()
            );
        }
        let commissioning = state == State::Commissioning;
        if commissioning {
            // One joint's open-loop test: only that joint driven, no more than the test's
            // duty against the applied brake, or its ramp's last duty with the brakes
            // released (or what the current limit made of it).
            let test = &rt.config().commission;
            // A joint the current limit gave a duty is not driven by the test: back-driven
            // faster than its limit allows at zero duty, the limit's range excludes zero,
            // and the duty it sets keeps that joint's current within the limit (the
            // current monitor's own property tests).
            let driven = hw
                .duty
                .iter()
                .zip(limited.iter())
                .filter(|(d, lim)| **d != 0.0 && !**lim)
                .count();
            assert!(
                driven <= 1,
                "commissioning drives {driven} joints: {}",
                ctx()
            );
            let most = if hw.brakes_released {
                test.max_duty
            } else {
                test.applied_duty
            };
            for ((d, m), lim) in hw.duty.iter().zip(most.iter()).zip(limited.iter()) {
                assert!(
                    d.abs() <= m.abs() * (1.0 + 1e-12) || *lim,
                    "commissioning's duty above the test's {most:?}: {}",
                    ctx()
                );
            }
        }
        let driving = hw.enabled && hw.duty.iter().any(|d| *d != 0.0);
        if driving && !hw.brakes_released {
            let brake_check = state == State::Enabling && phase == StopPhase::Running;
            assert!(
                brake_check || commissioning || matches!(phase, StopPhase::Braking { .. }),
                "driving against the applied brakes: {}",
                ctx()
            );
            if brake_check {
                // The check's duty, or what the current limit made of it (a joint turning
                // against its closed brake makes the limit's range exclude zero).
                let check = rt.config().brakes.duty;
                for ((d, c), lim) in hw.duty.iter().zip(check.iter()).zip(limited.iter()) {
                    assert!(
                        d.abs() <= c.abs() * (1.0 + 1e-12) || *lim,
                        "brake check duty above the check's {check:?}: {}",
                        ctx()
                    );
                }
            }
        }
        if self.estop_pending {
            assert!(
                state == State::Fault && !hw.enabled && !hw.brakes_released && !tick.drives_on,
                "the tick after an EmergencyStop: {}",
                ctx()
            );
            self.estop_pending = false;
        }
        // The stop table's STO rows that the fake hardware can cause, carried out in the tick
        // whose monitors see them: an encoder jump beyond the joint's top speed (with its
        // margin), a limit switch closed outside homing, a homed joint outside its range.
        let cfg = rt.config();
        let ec = &cfg.encoder_check;
        let dt = 1.0 / cfg.controller.rate_hz;
        let first = std::mem::replace(&mut self.first_reading, false);
        let jump = (0..NUM_JOINTS).filter(|_| !first).find(|&j| {
            let limit = ec.top_speed[j] * ec.jump_margin * dt * ec.counts_per_unit[j] + 2.0;
            f64::from(hw.read_delta[j]).abs() > limit
        });
        // Homing drives onto its switches; commissioning tests their sense.
        let switches_tested = matches!(before.0, State::Homing | State::Commissioning)
            || state == State::Commissioning;
        // Before the references, a switch closed where the board's counts put its joint
        // within the switch's travel of its home position is where a stopped or failed
        // homing left the joint, not the end of travel (firmware README, SR-1).
        let known = rt.known_joints();
        let left_by_homing = |j: usize| {
            !before.1
                && cfg.homing.joints.get(j).is_some_and(|h| {
                    known
                        .get(j)
                        .is_some_and(|q| (q - h.home_position).abs() <= h.switch_travel_max)
                })
        };
        let switch = !switches_tested
            && (0..NUM_JOINTS)
                .any(|j| hw.inputs.switches.get(j).copied().unwrap_or(false) && !left_by_homing(j));
        let q = rt.measured().q;
        let outside = before.1
            && q.iter()
                .zip(cfg.mechanics.range.iter())
                .any(|(x, [lo, hi])| !(*x >= *lo && *x <= *hi));
        if jump.is_some() || switch || outside {
            let sto =
                !hw.enabled && !hw.brakes_released && phase == StopPhase::TorqueOff { sto: true };
            if !sto {
                // Finding 2 (README): the latched OverTemperature's repeat masks the
                // monitors after the current monitor.
                let masked = rt.latched_fault().cause == FaultCause::OverTemperature;
                assert!(
                    masked && !self.strict.stops,
                    "STO row not carried out (encoder jump on {jump:?}, switch {switch}, outside range {outside}; q {q:?}; latched {:?}): {}",
                    rt.latched_fault(),
                    ctx()
                );
                self.outcome.masked_stops += 1;
            }
        }
        // And the converse, outside homing: a switch that homing left closed is not latched
        // as a limit (it would refuse every `ClearFault` while the joint rests there: the
        // robot locked out).
        let new_limit_fault = rt.latched_fault().cause == FaultCause::LimitSwitch
            && before.2 != FaultCause::LimitSwitch;
        let explained = switches_tested || switch || jump.is_some() || outside;
        assert!(
            !new_limit_fault || explained,
            "LimitSwitch latched with no switch a limit (known joints {known:?}; homed {}): {}",
            before.1,
            ctx()
        );
        if hw.inputs.estop {
            assert!(
                state == State::Fault
                    && !hw.enabled
                    && !hw.brakes_released
                    && matches!(phase, StopPhase::TorqueOff { .. }),
                "the e-stop button pressed: {}",
                ctx()
            );
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame(msg: Msg) -> Action {
        Action::Frame {
            msg,
            header: HeaderChoice::Next,
        }
    }

    fn ticks(count: u8) -> Action {
        Action::Tick {
            period: Period::Nominal,
            count,
            exec: None,
            estop_irq: false,
        }
    }

    /// The snapshots are in the states they are named after.
    #[test]
    fn snapshots_are_in_their_states() {
        let s = snapshots();
        assert_eq!(s.unbooted.runtime.state(), State::Boot);
        assert!(s.unbooted.service.is_none());
        assert_eq!(s.booted.runtime.state(), State::Disabled);
        assert_eq!(s.homing.runtime.state(), State::Homing);
        assert_eq!(s.ready.runtime.state(), State::Ready);
        assert_eq!(s.enabling.runtime.state(), State::Enabling);
        assert_eq!(s.enabled.runtime.state(), State::Enabled);
    }

    /// On the fake hardware the enabled robot keeps following: a session opens, a target
    /// 1 mm away is acknowledged and the robot stays enabled for 100 ms with heartbeats;
    /// then an emergency stop faults it and the drives go off.
    #[test]
    fn enabled_robot_follows_then_stops() {
        let mut actions = vec![
            // Another master's: refused (the robot is enabled); the owner carries on.
            frame(Msg::Hello {
                version: None,
                nonce: 77,
                clock: Stamp::Now,
            }),
            frame(Msg::PoseTarget {
                stamp: Stamp::Now,
                position: Position::Near([1000, 0, 0]),
                rotation: Rotation::Near([0, 0, 0]),
            }),
        ];
        for _ in 0..6 {
            actions.push(frame(Msg::Any(MasterToBoard::Heartbeat)));
            actions.push(ticks(15));
        }
        actions.push(frame(Msg::Any(MasterToBoard::StatusRequest)));
        actions.push(ticks(0));
        let s = Scenario {
            start: Start::Enabled,
            actions: actions.clone(),
        };
        let o = Board::run(&s);
        assert_eq!(o.states, vec![State::Enabled], "{o:?}");
        assert_eq!(o.replies, [1, 7, 0, 1, 0, 0], "{o:?}");
        actions.push(frame(Msg::Any(MasterToBoard::EmergencyStop)));
        actions.push(ticks(0));
        let o = Board::run(&Scenario {
            start: Start::Enabled,
            actions,
        });
        assert_eq!(o.states, vec![State::Enabled, State::Fault], "{o:?}");
    }

    /// From the booted runtime without a session, commands are refused `NotConnected`,
    /// but an emergency stop is taken.
    #[test]
    fn before_hello_only_the_emergency_stop_is_taken() {
        let s = Scenario {
            start: Start::Booted,
            actions: vec![
                frame(Msg::Any(MasterToBoard::Enable)),
                frame(Msg::Any(MasterToBoard::EmergencyStop)),
                ticks(0),
            ],
        };
        let o = Board::run(&s);
        assert_eq!(o.nacks, vec![NackReason::NotConnected]);
        assert_eq!(o.replies, [0, 1, 1, 0, 0, 0]);
        assert_eq!(o.states, vec![State::Fault]);
    }

    /// Finding 1 (README, fixed): leg 1 driven back at 1.19 times its no-load speed (300
    /// counts per period, 0.45 m/s; within the encoder-jump limit of 1.5 times) made the
    /// current limit command a duty below -1 on the first tick. Property: with every check
    /// strict, no duty leaves [-1, 1], at that speed and at 0.8 times it.
    #[test]
    fn finding_1_current_limit_keeps_duty_within_unit_range() {
        let mut inputs = Inputs {
            switches: 0,
            estop: false,
            relay_open: false,
            driver_fault: false,
            supply: Supply::Nominal,
            currents: Currents::Model,
            motion: Motion::Drift([-300, 0, 0, 0, 0, 0]),
            jump: None,
        };
        let scenario = |inputs: Inputs| Scenario {
            start: Start::Enabled,
            actions: vec![Action::Set(inputs), ticks(0)],
        };
        let o = Board::run_with(&scenario(inputs), Strict::ALL);
        assert_eq!(o.duty_over_range, 0, "{o:?}");
        inputs.motion = Motion::Drift([-200, 0, 0, 0, 0, 0]);
        let o = Board::run_with(&scenario(inputs), Strict::ALL);
        assert_eq!(o.duty_over_range, 0, "{o:?}");
    }

    /// Finding 2 (README, fixed): a one-sample current spike of 1e6 A on leg 1 while
    /// enabled latches `OverTemperature` (SS1); a limit switch closed in the next ticks (the
    /// table: STO) used to be masked by the latched fault's repeat. Property: with every
    /// check strict, each tick carries out the STO rows of its findings.
    #[test]
    fn finding_2_latched_over_temperature_no_longer_masks_sto_rows() {
        let mut inputs = Inputs {
            switches: 0,
            estop: false,
            relay_open: false,
            driver_fault: false,
            supply: Supply::Nominal,
            currents: Currents::Raw([1e6, 0.0, 0.0, 0.0, 0.0, 0.0]),
            motion: Motion::Follow,
            jump: None,
        };
        let mut actions = vec![Action::Set(inputs), ticks(0)];
        inputs.currents = Currents::Model;
        inputs.switches = 1;
        actions.extend([Action::Set(inputs), ticks(1)]);
        let s = Scenario {
            start: Start::Enabled,
            actions,
        };
        let o = Board::run_with(&s, Strict::ALL);
        assert_eq!(o.masked_stops, 0, "{o:?}");
        assert_eq!(o.duty_over_range, 0, "{o:?}");
        assert_eq!(o.states, vec![State::Fault], "{o:?}");
    }

    /// The libFuzzer inputs that found the three findings, and the one where the harness
    /// read a closed switch that a stopped homing left as a limit, byte for byte as the
    /// fuzzer wrote them (a new finding's input goes here: `xxd -i` prints it), parse as
    /// the target parses them and pass every check strict: the product's fixes hold on the
    /// inputs that found them.
    const REGRESSION_INPUTS: [(&str, &[u8]); 4] = [
        (
            "commands-finding-1-duty",
            &[
                0xff, 0x4f, 0x9b, 0xea, 0x03, 0xaa, 0xaa, 0xaa, 0xaa, 0xaa, 0xaa, 0xaa, 0x00, 0x00,
                0x00, 0x5b, 0x48, 0x39, 0xa3, 0xab, 0xdc, 0x81, 0xab, 0xab, 0xdc, 0x81, 0x1c, 0x32,
                0x7f, 0x6c, 0x01, 0x00, 0xff, 0xb6, 0xff, 0xff, 0x6c, 0xa0, 0xa3, 0xab, 0xab, 0xdc,
                0x81, 0x1c, 0x32, 0x7f, 0x6c, 0xa3, 0xab, 0x39, 0xa3, 0xab, 0xdc, 0x81, 0x1c, 0x32,
                0x7f, 0x6c, 0xa3, 0xab, 0xab, 0xdc, 0x81, 0x1c, 0x32, 0x7f, 0x6c,
            ],
        ),
        (
            "commands-finding-2-sto-masked",
            &[
                0x17, 0xa0, 0x7f, 0x2f, 0x97, 0x6d, 0x3d, 0x3a, 0x0f, 0x81, 0x4b, 0xd7, 0xa8, 0x63,
                0x96, 0xa1, 0xb7, 0x8b, 0xb4, 0x6e, 0x46, 0xfd, 0xbf, 0xfa, 0xcb, 0x2e, 0xff, 0x04,
                0x00, 0x2f, 0x82, 0x1d, 0xcb, 0x8e, 0x25, 0x6f, 0x29, 0x82, 0x1d, 0xcb, 0x8e, 0x29,
                0x82, 0x1d, 0xcb, 0x8e, 0x25, 0x6f, 0x82, 0x1d, 0xcb, 0x8e, 0x29, 0x82, 0x1d, 0xcb,
                0x8e, 0x25, 0x6f,
            ],
        ),
        (
            "commands-finding-3-stale-outputs",
            &[
                0x78, 0x62, 0xb6, 0x69, 0x31, 0x61, 0xad, 0xc8, 0x50, 0x36, 0x36, 0x87, 0x00, 0x64,
                0x34, 0xb6, 0xa0, 0xe2, 0xab, 0x96, 0xd8, 0x01, 0x5d, 0xa7, 0x89, 0x0b, 0x39, 0xb8,
                0xfe, 0x99, 0xae, 0xcd, 0xd5, 0xcc, 0x2f, 0x21, 0x00, 0x33, 0xda, 0x5f, 0xe9, 0xe9,
                0xba, 0x3c, 0x49, 0x91, 0x91, 0x91, 0x91, 0x91, 0x91, 0x91, 0x91, 0x91, 0x91, 0x91,
                0x26, 0x00, 0x00, 0x00, 0x3e, 0x91,
            ],
        ),
        (
            "commands-switch-left-by-homing",
            &[
                0x3d, 0x93, 0xa9, 0x44, 0xc2, 0xed, 0x89, 0x1d, 0x29, 0x0d, 0x8a, 0xaf, 0x3a, 0x6e,
                0x96, 0xdf, 0x01, 0x07, 0x54, 0xbf, 0x1a, 0x23, 0xf9, 0x1e, 0xf9, 0xb4, 0x9c, 0x0a,
                0x25, 0x22, 0xf1, 0xbb, 0xec, 0x2e, 0x66, 0xc2, 0x42, 0x3c, 0xa7, 0x83, 0xdc, 0xc6,
                0x19, 0x36, 0x8d, 0x1e, 0x08, 0x91, 0x1a, 0x80, 0xc9, 0x5b, 0x44, 0xdb, 0x73, 0x37,
                0xd2, 0x98, 0xd0, 0x13, 0xf9, 0x2e, 0x66, 0xc2, 0x42, 0x3c, 0xa7, 0x83, 0xdc, 0xc6,
                0x36, 0x8d, 0x1e, 0x08, 0x91, 0x1a, 0x80, 0xc9, 0x5b, 0x98, 0xdb, 0x73, 0x44, 0xf5,
                0x1b, 0x26, 0xcd, 0x59, 0x3e, 0x07, 0xad, 0xa8, 0x04, 0xf4, 0x45, 0x27, 0x1a, 0x09,
                0x1e, 0xf9, 0xb4, 0x9c, 0x0a, 0x25, 0x22, 0xf1, 0xbb, 0xec, 0x2e, 0x07, 0x09, 0x11,
                0x10, 0x55, 0x5e, 0x07, 0x07, 0x06, 0x01, 0xc9, 0x48, 0x8f, 0xfa, 0x00, 0x66, 0xc2,
                0x42, 0x3c, 0xa7, 0x83, 0xdc, 0xc6, 0x36, 0x8d, 0x1e, 0x08, 0x91, 0x1a, 0x80, 0xc9,
                0x5b, 0x98, 0xdb, 0x77, 0x44, 0xd2, 0x37, 0xd0, 0x13, 0x52, 0x66, 0xc2, 0x42, 0x8d,
                0x83, 0xa7, 0x36, 0xc6, 0x3c, 0xdc, 0x1e, 0x08, 0x91, 0x1a, 0x80, 0xc9, 0x5b, 0x98,
                0xdb, 0x73, 0x44, 0xd2, 0x37, 0xd0, 0x13, 0xff, 0x01, 0xb7, 0x98, 0x17, 0x6c, 0x45,
                0x85, 0x54, 0xd0,
            ],
        ),
    ];

    #[test]
    fn regression_inputs_pass_the_strict_checks() {
        for (name, bytes) in REGRESSION_INPUTS {
            let Ok(s) = Scenario::arbitrary_take_rest(arbitrary::Unstructured::new(bytes)) else {
                panic!("{name} does not parse");
            };
            let o = Board::run_with(&s, Strict::ALL);
            assert_eq!(
                (o.duty_over_range, o.masked_stops, o.stale_outputs),
                (0, 0, 0),
                "{name}: {o:?}"
            );
        }
    }

    /// Commissioning on the fake hardware: from `Ready`, a person confirming, joint 3's test
    /// runs to its end with heartbeats every 10 ms (the fake's encoders follow the duty once
    /// the brakes are released), then `Disable` ends the mode. Property: every check of the
    /// harness holds through the test (the bridges on in `Commissioning`, one joint driven,
    /// within the test's duties, against the applied brake only at its push's duty), and
    /// the record says the test ended with joint 3 moved by its own encoder, within the
    /// travel limit and with no finding (the fake is wired straight).
    #[test]
    fn a_joint_is_commissioned_within_the_checks() {
        use control::runtime::Mode;
        use master_link::CommissionFindings;
        let mut b = Board::new(Start::Ready, Strict::ALL);
        // `ticks(n)` runs n + 1 ticks.
        let per_10ms = u8::try_from(10_000 / PERIOD_US - 1).unwrap_or(u8::MAX);
        let commission = frame(Msg::Any(MasterToBoard::Commission {
            joint: 3,
            confirm: true,
        }));
        let record = |b: &Board| match b.service.runtime().mode() {
            Mode::Commissioning(test) => test.record(),
            other => panic!("not commissioning: {other:?} ({:?})", b.outcome),
        };
        b.act(&commission);
        b.act(&ticks(0));
        // Within the harness's ticks (`MAX_TICKS`), with room for the stop after it (20
        // heartbeats 10 ms apart: 220 ticks). The test pushes the joint, then returns it to
        // where it stood (561 ticks on the fake).
        while !record(&b).done && b.outcome.ticks < MAX_TICKS - 250 {
            b.act(&frame(Msg::Any(MasterToBoard::Heartbeat)));
            b.act(&ticks(per_10ms));
        }
        let record = record(&b);
        assert!(record.done, "{record:?} after {} ticks", b.outcome.ticks);
        assert_eq!(record.findings, CommissionFindings::NONE, "{record:?}");
        assert_eq!(record.moved_encoder, 3, "{record:?}");
        assert!(record.encoder_motion > 0.0, "{record:?}");
        assert!(record.peak_travel <= 1.0, "{record:?}");
        // The record read back is the one asked for; then the mode ends.
        b.act(&commission);
        b.act(&frame(Msg::Any(MasterToBoard::Disable)));
        for _ in 0..20 {
            b.act(&frame(Msg::Any(MasterToBoard::Heartbeat)));
            b.act(&ticks(per_10ms));
        }
        assert_eq!(
            b.service.runtime().state(),
            State::Disabled,
            "{:?}",
            b.outcome
        );
        assert!(b.outcome.states.contains(&State::Commissioning));
        assert!(b.outcome.nacks.is_empty(), "{:?}", b.outcome);
    }

    /// A master's frames sent after its `Hello` but before the board's reply carry the
    /// session that Hello replaced: the tick refuses them (`NotOwner`) while an emergency
    /// stop from the same queue is still taken. Property: after the reconnect, a `Disable`
    /// of the replaced session leaves the robot enabled and a stop of it stops the robot.
    #[test]
    fn frames_of_a_replaced_session_are_refused_but_a_stop_is_taken() {
        let hello = frame(Msg::Hello {
            version: None,
            nonce: snapshots::OWNER_NONCE,
            clock: Stamp::Now,
        });
        let mut b = Board::new(Start::Enabled, Strict::ALL);
        for a in [
            hello.clone(),
            frame(Msg::Any(MasterToBoard::Disable)),
            ticks(1),
        ] {
            b.act(&a);
        }
        assert_eq!(
            b.outcome.nacks,
            vec![NackReason::NotOwner],
            "{:?}",
            b.outcome
        );
        assert_eq!(b.service.runtime().state(), State::Enabled);
        for a in [
            hello,
            frame(Msg::Any(MasterToBoard::EmergencyStop)),
            ticks(1),
        ] {
            b.act(&a);
        }
        assert_eq!(b.service.runtime().state(), State::Fault, "{:?}", b.outcome);
    }

    /// Finding 3 (README, fixed): enabled and holding, the owner reconnects (its fresh
    /// session open from the next tick on, as the board issues it); `EmergencyStop`,
    /// `ClearFault` and `Enable` arrive before the following tick. The receive path forces the
    /// outputs safe (`emergency_stop_message`: bridges off, brakes applied); the tick takes
    /// the latch and the requests: `Fault`, and the `ClearFault` and `Enable` of that tick
    /// refused (sent before the master could know of the stop); sent again after it:
    /// cleared (`Ready`), `Enabling`. The runtime used to believe its bridges still on and
    /// drove disabled bridges until the open-motor monitor latched a `MotorOpen` the
    /// motors do not have. Property: with every check strict, the torque flag and the
    /// bridges agree, the enable goes on without a fault, and the message's e-stop is
    /// logged once, as the message's.
    #[test]
    fn finding_3_estop_path_is_seen_by_the_next_enable() {
        let actions = [
            // The owner reconnects (a fresh session, its operator still present).
            frame(Msg::Hello {
                version: None,
                nonce: snapshots::OWNER_NONCE,
                clock: Stamp::Now,
            }),
            // The master learns its session from the HelloReply; frames it sent before
            // that carry the replaced session and are refused (`NotOwner`).
            ticks(1),
            frame(Msg::Any(MasterToBoard::EmergencyStop)),
            frame(Msg::Any(MasterToBoard::ClearFault)),
            frame(Msg::Any(MasterToBoard::Enable)),
            ticks(1),
            frame(Msg::Any(MasterToBoard::ClearFault)),
            frame(Msg::Any(MasterToBoard::Enable)),
            ticks(18),
        ];
        let mut b = Board::new(Start::Enabled, Strict::ALL);
        for a in &actions {
            b.act(a);
        }
        let rt = b.service.runtime();
        // Still enabled after the reconnect; the stop's tick ends in `Fault`; enabling
        // again after the clear.
        assert_eq!(
            b.outcome.states,
            vec![State::Enabled, State::Fault, State::Enabling],
            "{:?}",
            b.outcome
        );
        assert_eq!(
            b.outcome.nacks,
            vec![NackReason::Busy, NackReason::Faulted],
            "the ClearFault and the Enable of the stop's tick: {:?}",
            b.outcome
        );
        assert_eq!(b.outcome.stale_outputs, 0, "{:?}", b.outcome);
        let log = rt.fault_log().page(0);
        let causes: Vec<FaultCause> = log
            .entries
            .iter()
            .take(usize::from(log.count))
            .map(|e| e.record.cause)
            .collect();
        assert_eq!(
            causes,
            vec![FaultCause::EmergencyStopMessage],
            "the fault log"
        );
    }
}
