//! The search for counterexamples to the safety requirements (`control::safety`,
//! SR-1 .. SR-7): a sequence of [`Action`]s (the owning master's commands and target
//! streams, a second master's frames, replayed and forged frames, injected faults of every
//! kind, alone or two at once, the e-stop button, the tool, walls and pushes, silences)
//! carried out on the whole board application against the plant
//! ([`simulation::board::BoardSim`], in virtual time), with every requirement's oracle
//! ([`oracle`]) checked at every tick against the measured motion (the plant's truth) and
//! the board's status and wire replies, never its internals.
//!
//! [`run_case`] runs one sequence from a [`Start`] and returns the violations found; the
//! property test `host-sim/faults/tests/search.rs` generates the sequences (with
//! shrinking) and replays the counterexamples found once.
//!
//! Everything the oracles read of the simulated board is in [`probe`], so that the search
//! can be ported to an older board application by changing that module alone.
//!
//! Masters speak the board's session protocol: each `Hello` carries the master's nonce and
//! clock, the board issues the session; the second master's frames are in the session the
//! board gave it (none, when its `Hello` was refused). The oracles follow who owns the
//! board from the board's `HelloReply`s: a takeover is legal only while the robot is
//! disabled (SR-6), and from then on that master's frames are the owner's.
//!
//! # Running it
//!
//! - CI, the fixed-seed budget: `cargo test -p faults --test search` (400 generated
//!   sequences from the seed of `tests/proptest-config`, shrunk on failure; the named
//!   counterexamples; the foreign frames).
//! - The long search: `SEARCH_MINUTES=60 cargo test --release -p faults --test search --
//!   --ignored explore --nocapture` (fresh cases for an hour, not shrunk: every distinct
//!   violation printed with a case that shows it, then the cases, actions, virtual and
//!   wall time and the violations); `SEARCH_EXPLORE=N` runs N cases instead;
//!   `RSPR_PROPTEST_FRESH=1 RSPR_PROPTEST_SCALE=20 cargo test --release -p faults --test
//!   search` runs the property from fresh seeds with shrinking.
//! - A case tick by tick: set [`World::watch`] to a function of the board, called after
//!   every tick and its oracles, and replay the case's actions with [`World::act`].
//! - Against an older board application: a worktree of that commit
//!   (`git worktree add --detach ../old COMMIT`), `src/search/`, `tests/search.rs` and
//!   `control/src/safety.rs` copied into it, [`probe`] and the `Hello`'s fields ported to
//!   its board simulation and protocol, then `cargo test -p faults --test search --
//!   counterexamples --nocapture` (each named counterexample that breaks a requirement
//!   there is printed with the requirement, the time and the measured motion) and
//!   `SEARCH_EXPLORE=150 cargo test -p faults --test search -- --ignored explore
//!   --nocapture` (what the random search finds there).

pub mod inject;
pub mod oracle;
pub mod probe;

use std::collections::VecDeque;

use control::safety::Requirement;
use control::ToolLoad;
use master_link::{
    BoardToMaster, GeometryRecord, MasterDecoder, MasterToBoard, ResetCause, Seq, PROTOCOL_VERSION,
};
use nalgebra::Vector3;
use simulation::bench::{frame_in, SimMaster};
use simulation::board::{BoardSim, BoardSimConfig, BoardSimError, Wall};

pub use inject::Injection;
pub use oracle::{Oracle, Violation};

/// Where a case starts.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Start {
    /// Powered up, the owner's session open, not homed.
    Fresh,
    /// The owner just sent `Home`: the sequence runs during homing.
    Homing,
    /// Homed and parked, drives off (`Ready`).
    Ready,
    /// Enabled, following the owner at the park pose.
    Following,
}

impl Start {
    /// Every start.
    pub const ALL: [Start; 4] = [Start::Fresh, Start::Homing, Start::Ready, Start::Following];
}

/// A command of a master (its own session, next sequence number).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Cmd {
    /// `Hello` with the master's nonce and its clock now (the owner: a reconnect).
    Hello,
    /// `Enable`.
    Enable,
    /// `Disable`.
    Disable,
    /// `Home`.
    Home {
        /// Confirms rehoming.
        rehome: bool,
    },
    /// `Clutch`.
    Clutch(bool),
    /// `OperatorPresent`.
    Operator(bool),
    /// `ClearFault`.
    ClearFault,
    /// `AcknowledgeReset`.
    AckReset,
    /// `EmergencyStop`.
    EStop,
    /// `StatusRequest`.
    Status,
    /// `StoreGeometry` of the reference robot's nominal geometry.
    StoreGeometry,
}

impl Cmd {
    /// The message, a `Hello` with the nonce `nonce` and the clock `clock_us`.
    fn message(self, nonce: u32, clock_us: u64) -> MasterToBoard {
        match self {
            Cmd::Hello => MasterToBoard::Hello {
                protocol_version: PROTOCOL_VERSION,
                nonce,
                clock_us,
            },
            Cmd::Enable => MasterToBoard::Enable,
            Cmd::Disable => MasterToBoard::Disable,
            Cmd::Home { rehome } => MasterToBoard::Home { rehome },
            Cmd::Clutch(engaged) => MasterToBoard::Clutch { engaged },
            Cmd::Operator(present) => MasterToBoard::OperatorPresent { present },
            Cmd::ClearFault => MasterToBoard::ClearFault,
            Cmd::AckReset => MasterToBoard::AcknowledgeReset,
            Cmd::EStop => MasterToBoard::EmergencyStop,
            Cmd::Status => MasterToBoard::StatusRequest,
            Cmd::StoreGeometry => MasterToBoard::StoreGeometry(nominal_geometry()),
        }
    }
}

/// The reference robot's nominal geometry as a calibration record (version 1).
fn nominal_geometry() -> GeometryRecord {
    let g =
        kinematics_core::PerChainGeometry::from(kinematics_core::RsprGeometry::<f64>::reference());
    control::geometry_store::record_of(&g, 1)
}

/// Frames that are not the owning master's fresh commands.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Foreign {
    /// A second master asks for a session (its `Hello`, its nonce, its clock).
    SecondHello,
    /// A second master's command in its own session.
    SecondCommand(Cmd),
    /// A second master's pose target in its own session (8 mm off the owner's region in y).
    SecondTarget,
    /// The owner's frame sent `back` frames ago, replayed byte for byte.
    Replay {
        /// How far back (1: the last frame).
        back: u8,
    },
    /// A frame in the owner's session, its sequence number 30 000 ahead of the owner's.
    FarAhead(Cmd),
    /// A pose target in the owner's session stamped `ahead_ms` in the future (8 mm off
    /// the owner's region in -y).
    FutureTarget {
        /// How far ahead of the owner's clock, ms.
        ahead_ms: u16,
    },
    /// The owner's target, in its session with its next sequence number, stamped
    /// `u64::MAX` (the end of its clock).
    StampedMax,
    /// The owner's last `Hello` and the last `Enable` it sent, replayed byte for byte.
    ReplayHelloEnable,
}

/// One step of a case.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Action {
    /// `ms` control periods, the owner's heartbeat every 50 ms.
    Wait(u16),
    /// `ms` control periods without the owner's heartbeats (nor anything else of it).
    Silence(u16),
    /// The owner's command.
    Command(Cmd),
    /// The owner streams targets towards (x, z) = (`x_mm`, hc + `z_mm`) at `speed_mm_s`
    /// for `ms` (a target every 10 ms, stamped with its clock).
    Stream {
        /// Goal x, mm.
        x_mm: i8,
        /// Goal z above hc, mm.
        z_mm: i8,
        /// Speed, mm/s.
        speed_mm_s: u8,
        /// Duration, ms.
        ms: u16,
    },
    /// The owner jogs `joint` at `velocity` (mm/s on a leg, 10 mrad/s on a link), a `Jog`
    /// every 20 ms for `ms`.
    Jog {
        /// The joint.
        joint: u8,
        /// The velocity, in the joint's unit above.
        velocity: i8,
        /// Duration, ms.
        ms: u16,
    },
    /// Frames not from the owner.
    Foreign(Foreign),
    /// A fault injected into the board or the robot.
    Fault(Injection),
    /// Every injected fault removed (the plant's joints, the supply, the switches, the
    /// relay, the overruns); the e-stop button released.
    Repair,
    /// The e-stop button pressed (true) or released.
    Button(bool),
    /// The thesis's tool attached (true) or removed.
    Tool(bool),
    /// A stiff wall pressing into the platform along +x (`plus`) or -x by `depth_um` (a
    /// push of 100 N/mm x depth), or none (`depth_um` 0).
    Push {
        /// Towards +x.
        plus: bool,
        /// How far the wall's surface lies past o_p, µm (0: no wall).
        depth_um: u16,
    },
    /// A stiff wall `ahead_um` ahead of the platform along +x (`plus`) or -x.
    Wall {
        /// On the +x side.
        plus: bool,
        /// How far ahead of o_p, µm.
        ahead_um: u16,
    },
}

/// The owner's nonce.
pub const OWNER: u32 = 0x0A11_CE00;
/// The second master's nonce.
pub const SECOND: u32 = 0x0000_0B0B;
/// How far the second master's sequence numbers start from the owner's (so that the
/// board's answers name one master's frame).
const SECOND_SEQ: Seq = 40_000;
/// The owner's heartbeat period, µs.
const BEAT_US: u64 = 50_000;
/// The owner's region of targets in y, m: foreign targets aim 8 mm beyond it.
const FOREIGN_Y: f64 = 0.008;

/// Why a case could not be run (a failure of the set-up, not a counterexample).
#[derive(Debug, thiserror::Error)]
pub enum SearchError {
    /// The board simulation.
    #[error(transparent)]
    Board(#[from] BoardSimError),
    /// The start state was not reached.
    #[error("start {start:?} not reached: {why}")]
    Start {
        /// The start.
        start: Start,
        /// Why.
        why: String,
    },
}

/// A frame delivered to the board: who sent it, and what it asks.
#[derive(Clone, Copy, Debug)]
pub struct Delivered {
    /// Its sequence number.
    pub seq: Seq,
    /// The message.
    pub message: MasterToBoard,
    /// The nonce of the master whose fresh frame it is (None: a replay, a forgery).
    pub from: Option<u32>,
    /// A fresh frame of the master that owns the board as the replies showed it so far
    /// (else foreign: a master that does not own it, a replay, a forgery).
    pub owner: bool,
}

/// The board, the owning master, the second master and the oracles.
pub struct World {
    /// The board.
    pub board: BoardSim,
    /// The first master (the board's owner unless the second took it over).
    pub owner: SimMaster,
    /// The second master.
    pub second: SimMaster,
    /// The nonce of the master that owns the board, as its replies showed it.
    owns: Option<u32>,
    line: MasterDecoder,
    /// The first master's frames sent so far (the newest last), for replays.
    sent: VecDeque<(Seq, MasterToBoard, Vec<u8>)>,
    /// Its last `Hello` and its last `Enable`, as sent.
    last_hello: Option<(Seq, MasterToBoard, Vec<u8>)>,
    last_enable: Option<(Seq, MasterToBoard, Vec<u8>)>,
    /// Frames delivered since the last tick.
    pending: Vec<Delivered>,
    last_beat_us: u64,
    /// The owner's last target, m, and its clock's last stamp, µs.
    target: Vector3<f64>,
    last_stamp_us: u64,
    /// The oracles.
    pub oracle: Oracle,
    /// The park pose (the owner's centre).
    centre: Vector3<f64>,
    /// Called after every tick (and its oracles) with the board: a trace of a case.
    pub watch: Option<fn(&BoardSim)>,
}

impl World {
    /// The reference board powered up, the owner's session open.
    pub fn new() -> Result<Self, SearchError> {
        let cfg = BoardSimConfig::reference(None)?;
        let board = BoardSim::new(cfg, ResetCause::PowerOn, None)?;
        let oracle = Oracle::new(&board);
        let centre = probe::park_position(&board);
        let mut w = World {
            board,
            owner: SimMaster::new(OWNER),
            second: SimMaster::new(SECOND),
            owns: None,
            line: MasterDecoder::new(),
            sent: VecDeque::new(),
            last_hello: None,
            last_enable: None,
            pending: Vec::new(),
            last_beat_us: 0,
            target: centre,
            last_stamp_us: 0,
            oracle,
            centre,
            watch: None,
        };
        w.command(Cmd::Hello);
        w.run(50, true)?;
        Ok(w)
    }

    /// The world at `start`.
    pub fn at(start: Start) -> Result<Self, SearchError> {
        let mut w = World::new()?;
        let fail = |why: &str| SearchError::Start {
            start,
            why: why.to_string(),
        };
        if start == Start::Fresh {
            return Ok(w);
        }
        w.command(Cmd::Home { rehome: false });
        if start == Start::Homing {
            return Ok(w);
        }
        for _ in 0..120_000 {
            w.tick(true)?;
            if probe::state(&w.board) != master_link::RobotState::Homing {
                break;
            }
        }
        if probe::state(&w.board) != master_link::RobotState::Ready {
            return Err(fail("homing did not end in Ready"));
        }
        w.run(100, true)?;
        if start == Start::Ready {
            return Ok(w);
        }
        w.command(Cmd::Operator(true));
        w.command(Cmd::Enable);
        for _ in 0..2_000 {
            w.tick(true)?;
            if probe::state(&w.board) == master_link::RobotState::Enabled {
                return Ok(w);
            }
        }
        Err(fail("Enable did not end in Enabled"))
    }

    /// Virtual time, µs.
    pub fn now_us(&self) -> u64 {
        self.board.now_us()
    }

    fn deliver(&mut self, bytes: &[u8], seq: Seq, message: MasterToBoard, from: Option<u32>) {
        self.board.receive(bytes);
        self.pending.push(Delivered {
            seq,
            message,
            from,
            owner: from.is_some() && from == self.owns,
        });
    }

    /// The first master's command `c` (a `Hello` with its clock now).
    pub fn command(&mut self, c: Cmd) -> Seq {
        let clock = self.next_stamp();
        self.owner_send(&c.message(OWNER, clock))
    }

    /// The first master's clock for its next stamp: the board's time, after its last.
    fn next_stamp(&mut self) -> u64 {
        let stamp = self.board.now_us().max(self.last_stamp_us + 1);
        self.last_stamp_us = stamp;
        stamp
    }

    /// The first master sends `msg` (its session, its next sequence number).
    pub fn owner_send(&mut self, msg: &MasterToBoard) -> Seq {
        let (seq, bytes) = self.owner.frame(msg);
        self.deliver(&bytes, seq, *msg, Some(OWNER));
        match msg {
            MasterToBoard::Hello { .. } => self.last_hello = Some((seq, *msg, bytes.clone())),
            MasterToBoard::Enable => self.last_enable = Some((seq, *msg, bytes.clone())),
            _ => {}
        }
        self.sent.push_back((seq, *msg, bytes));
        if self.sent.len() > 64 {
            self.sent.pop_front();
        }
        seq
    }

    /// The second master sends `msg` (its session, its next sequence number).
    fn second_send(&mut self, msg: MasterToBoard) {
        // Its sequence numbers start SECOND_SEQ from the owner's.
        if self.second.next_seq() < SECOND_SEQ {
            for _ in 0..SECOND_SEQ {
                self.second.frame(&MasterToBoard::Heartbeat);
            }
        }
        let (seq, bytes) = self.second.frame(&msg);
        self.deliver(&bytes, seq, msg, Some(SECOND));
    }

    /// The owner's target at `p` (m), stamped with its clock.
    fn owner_target(&mut self, p: Vector3<f64>) {
        let stamp = self.next_stamp();
        self.target = p;
        self.owner_send(&MasterToBoard::PoseTarget {
            timestamp_us: stamp,
            position_m: [p.x as f32, p.y as f32, p.z as f32],
            rotation_vector_rad: [0.0; 3],
        });
    }

    fn foreign(&mut self, f: Foreign) {
        let now = self.board.now_us();
        let off_target = |y: f64, stamp: u64, centre: Vector3<f64>| MasterToBoard::PoseTarget {
            timestamp_us: stamp,
            position_m: [centre.x as f32, y as f32, centre.z as f32],
            rotation_vector_rad: [0.0; 3],
        };
        match f {
            Foreign::SecondHello => self.second_send(Cmd::Hello.message(SECOND, now)),
            Foreign::SecondCommand(c) => self.second_send(c.message(SECOND, now)),
            Foreign::SecondTarget => {
                let msg = off_target(self.centre.y + FOREIGN_Y, now, self.centre);
                self.second_send(msg);
            }
            Foreign::Replay { back } => {
                let n = self.sent.len();
                let k = usize::from(back.max(1));
                if let Some((seq, msg, bytes)) = n.checked_sub(k).and_then(|i| self.sent.get(i)) {
                    let (seq, msg, bytes) = (*seq, *msg, bytes.clone());
                    // A replayed emergency stop is taken by design (no filter drops one).
                    if msg != MasterToBoard::EmergencyStop {
                        self.deliver(&bytes, seq, msg, None);
                    }
                }
            }
            Foreign::ReplayHelloEnable => {
                for (seq, msg, bytes) in [self.last_hello.clone(), self.last_enable.clone()]
                    .into_iter()
                    .flatten()
                {
                    self.deliver(&bytes, seq, msg, None);
                }
            }
            Foreign::FarAhead(c) => {
                let seq = self.owner.next_seq().wrapping_add(30_000);
                let msg = c.message(OWNER, now);
                if msg != MasterToBoard::EmergencyStop {
                    let bytes = frame_in(&msg, self.owner.session, seq);
                    // A handshake is taken whatever its sequence number: a Hello with the
                    // owner's nonce and a clock newer than its last is the owner
                    // reconnecting (on a link without a key anyone may say it).
                    let from = matches!(c, Cmd::Hello).then_some(OWNER);
                    self.deliver(&bytes, seq, msg, from);
                }
            }
            Foreign::FutureTarget { ahead_ms } => {
                let stamp = self.last_stamp_us.max(now) + 200_000 + u64::from(ahead_ms) * 1000;
                let msg = off_target(self.centre.y - FOREIGN_Y, stamp, self.centre);
                // Sent by the owner's link (its next sequence number), so the frame is
                // taken: what is judged is the target's stamp.
                let (seq, bytes) = self.owner.frame(&msg);
                self.deliver(&bytes, seq, msg, None);
            }
            Foreign::StampedMax => {
                let p = self.target;
                let msg = MasterToBoard::PoseTarget {
                    timestamp_us: u64::MAX,
                    position_m: [p.x as f32, p.y as f32, p.z as f32],
                    rotation_vector_rad: [0.0; 3],
                };
                let (seq, bytes) = self.owner.frame(&msg);
                self.deliver(&bytes, seq, msg, None);
            }
        }
    }

    /// One control period: the owner's heartbeat when due (`beats`), the board's tick,
    /// its replies read off the line, every oracle.
    pub fn tick(&mut self, beats: bool) -> Result<(), SearchError> {
        let now = self.board.now_us();
        if beats && now >= self.last_beat_us + BEAT_US {
            self.last_beat_us = now;
            // The heartbeat of the master that owns the board.
            if self.owns == Some(SECOND) {
                self.second_send(MasterToBoard::Heartbeat);
            } else {
                self.owner_send(&MasterToBoard::Heartbeat);
            }
        }
        let delivered = std::mem::take(&mut self.pending);
        let stepped = self.board.tick();
        let out = self.board.take_output();
        self.owner.receive(self.board.now_us(), &out);
        self.second.receive(self.board.now_us(), &out);
        // Every frame the board sent, whichever session it is in.
        self.line.reset_sequence();
        let replies: Vec<BoardToMaster> = self
            .line
            .feed(&out)
            .filter_map(|r| r.ok().map(|(_, m)| m))
            .collect();
        for r in &replies {
            if let BoardToMaster::HelloReply { nonce, .. } = r {
                self.owns = Some(*nonce);
            }
        }
        match stepped {
            Ok(_) => {
                self.oracle.tick(&self.board, &delivered, &replies);
                if let Some(watch) = self.watch {
                    watch(&self.board);
                }
            }
            Err(e) => {
                self.oracle.broken(&self.board, &e.to_string());
                return Err(e.into());
            }
        }
        Ok(())
    }

    /// `ms` control periods.
    pub fn run(&mut self, ms: u32, beats: bool) -> Result<(), SearchError> {
        for _ in 0..ms {
            self.tick(beats)?;
        }
        Ok(())
    }

    /// Carries out one action.
    pub fn act(&mut self, a: &Action) -> Result<(), SearchError> {
        self.oracle.note(a, &self.board);
        match *a {
            Action::Wait(ms) => self.run(u32::from(ms), true)?,
            Action::Silence(ms) => self.run(u32::from(ms), false)?,
            Action::Command(c) => {
                self.command(c);
            }
            Action::Stream {
                x_mm,
                z_mm,
                speed_mm_s,
                ms,
            } => {
                let goal =
                    self.centre + Vector3::new(f64::from(x_mm) * 1e-3, 0.0, f64::from(z_mm) * 1e-3);
                let step = f64::from(speed_mm_s.max(1)) * 1e-3 * 0.010;
                for k in 0..u32::from(ms) {
                    if k % 10 == 0 {
                        let d = goal - self.target;
                        let p = if d.norm() <= step {
                            goal
                        } else {
                            self.target + d * (step / d.norm())
                        };
                        self.owner_target(p);
                    }
                    self.tick(true)?;
                }
            }
            Action::Jog {
                joint,
                velocity,
                ms,
            } => {
                let j = joint % 6;
                let v = if j < 3 {
                    f32::from(velocity) * 1e-3
                } else {
                    f32::from(velocity) * 1e-2
                };
                for k in 0..u32::from(ms) {
                    if k % 20 == 0 {
                        self.owner_send(&MasterToBoard::Jog {
                            joint: j,
                            velocity: v,
                        });
                    }
                    self.tick(true)?;
                }
            }
            Action::Foreign(f) => self.foreign(f),
            Action::Fault(i) => inject::inject(&mut self.board, i),
            Action::Repair => inject::repair(&mut self.board),
            Action::Button(p) => self.board.press_estop(p),
            Action::Tool(on) => self.board.set_tool(on.then(ToolLoad::thesis)),
            Action::Push { plus, depth_um } => {
                let wall = (depth_um > 0).then(|| {
                    let p = self.board.truth().pose.t;
                    // The wall's surface past o_p: it pushes towards the side it is on's
                    // opposite (a wall on the -x side pushes +x).
                    let s = if plus { -1.0 } else { 1.0 };
                    Wall {
                        point: Vector3::new(p.x - s * f64::from(depth_um) * 1e-6, 0.0, 0.0),
                        normal: Vector3::new(s, 0.0, 0.0),
                        stiffness_n_per_m: 1e5,
                        damping_n_s_per_m: 200.0,
                    }
                });
                self.board.set_wall(wall);
            }
            Action::Wall { plus, ahead_um } => {
                let p = self.board.truth().pose.t;
                let s = if plus { 1.0 } else { -1.0 };
                self.board.set_wall(Some(Wall {
                    point: Vector3::new(p.x + s * f64::from(ahead_um) * 1e-6, 0.0, 0.0),
                    normal: Vector3::new(-s, 0.0, 0.0),
                    stiffness_n_per_m: 1e5,
                    damping_n_s_per_m: 200.0,
                }));
            }
        }
        Ok(())
    }
}

/// What a case found.
#[derive(Clone, Debug, Default)]
pub struct Report {
    /// Every violation of a requirement not tolerated, in order.
    pub violations: Vec<Violation>,
    /// The violations of the tolerated requirements (known open holes), in order.
    pub tolerated: Vec<Violation>,
    /// Virtual time run, s.
    pub virtual_s: f64,
    /// The set-up failed (not a counterexample): why.
    pub setup: Option<String>,
}

impl Report {
    /// The first violation, as text.
    pub fn first(&self) -> Option<String> {
        self.violations.first().map(|v| v.to_string())
    }
}

/// A known open hole: the violations of `requirements` (any, if empty) whose text or
/// context names `involving` (any, if empty) are tolerated while the work that closes it
/// lands.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct OpenHole {
    /// The requirements.
    pub requirements: &'static [Requirement],
    /// What the violation involves (an injection's name, `foreign frames`), or "".
    pub involving: &'static str,
    /// Who closes it.
    pub closed_by: &'static str,
}

impl OpenHole {
    /// Whether `v` is this hole.
    pub fn covers(&self, v: &Violation) -> bool {
        (self.requirements.is_empty() || self.requirements.contains(&v.requirement))
            && (v.what.contains(self.involving) || v.context.contains(self.involving))
    }
}

/// Runs `actions` from `start`, then 600 ms more with the owner's heartbeats (so that
/// what the last action started shows), every oracle at every tick. Stops at the first
/// violation not covered by an `open` hole; the violations those cover are collected and
/// the case goes on.
pub fn run_case(start: Start, actions: &[Action], open: &[OpenHole]) -> Report {
    let mut w = match World::at(start) {
        Ok(w) => w,
        Err(e) => {
            return Report {
                setup: Some(e.to_string()),
                ..Report::default()
            }
        }
    };
    let t0 = w.now_us();
    let known = |v: &Violation| open.iter().any(|h| h.covers(v));
    let intolerable = |w: &World| w.oracle.violations().iter().any(|v| !known(v));
    for a in actions.iter().chain(std::iter::once(&Action::Wait(600))) {
        if w.act(a).is_err() || intolerable(&w) {
            break;
        }
    }
    let (tolerated, violations) = w
        .oracle
        .violations()
        .iter()
        .cloned()
        .partition(|v| known(v));
    Report {
        violations,
        tolerated,
        virtual_s: (w.now_us() - t0) as f64 * 1e-6,
        setup: None,
    }
}
