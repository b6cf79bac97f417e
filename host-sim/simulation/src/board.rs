//! The whole board application on the plant, in virtual time: the firmware's tick service
//! (`control::service::TickService`: the runtime with its state machine, stops, brakes,
//! monitors, fault log, deadline policy) and its master link (`control::link`), exactly as
//! the board tasks run them (`firmware/cortex-m/board-tasks`), on the board and the robot
//! of `sim/board-on-plant` ([`BoardOnPlant`]: the drivers, the brakes' two coil groups, the
//! supply, nFAULT, the hard-wired e-stop chain with its welded or stuck-open relay, the
//! switches and hard stops where the firmware's reference mechanics put them; [`Platform`]:
//! the tool's weight and an optional wall as joint loads at the true pose). What this
//! module adds is the MCU's side:
//!
//! * the button's interrupt: it forces the outputs safe and trips the latch the next tick
//!   takes;
//! * the link: bytes in (`LinkRx`), requests queued for the next tick (8 deep, as on the
//!   board: a full queue answers `Busy`), replies and the status every 20 ms out
//!   (`LinkTx`); an `EmergencyStop` frame forces the outputs safe at once;
//! * the flash sector of the calibrated geometry, and the event log's flash sectors with
//!   their writer after every tick (`control::event_log`: at most two words per period,
//!   an erase only with the drives off and the brakes applied), as the board's;
//! * a power cycle ([`BoardSim::power_cycle`]): a new board on the same flash.
//!
//! The tick's execution time is not simulated: each tick reports a nominal 300 µs, plus
//! what a campaign injects ([`BoardSim::overrun_next_ticks`]); nor is the flash's stall
//! (the emulated board, `firmware/board-emulator`, runs the release image on a model that
//! has it).

use std::collections::VecDeque;

use board_on_plant::{BoardOnPlant, Layout, Platform, PlatformError, ReferenceMechanics, Tool};
use control::estop::EStopLatch;
use control::link::{opened_session, BoardIdentity, Inbound, LinkRx, LinkTx, Request};
use control::runtime::{reference_config_for, reference_mechanics, Runtime, RuntimeConfig};
use control::service::{ServiceConfig, TickOutcome, TickService};
use control::telemetry::with_link;
use control::ToolLoad;
use hal::{QuadratureCounter, SafeOutputs};
use kinematics_core::guards::Limits;
use kinematics_core::{inverse, Branch, Pose, RsprGeometry};
use master_link::{
    BoardToMaster, FirmwareVersion, MasterToBoard, NackReason, ResetCause, MAX_FRAME_LEN,
};
use nalgebra::Vector3;
use plant::{Plant, PlantConfig, PlantError, NUM_JOINTS};
use thiserror::Error;

/// The board simulated: the reference board profile.
const PROFILE: board_profile::BoardProfile = board_profile::BoardProfile::REFERENCE;

pub use board_on_plant::Wall;

/// Why the board simulation cannot be set up or stepped.
#[derive(Debug, Error)]
pub enum BoardSimError {
    #[error("the shipped plant parameters: {0}")]
    Plant(plant::ConfigError),
    #[error("plant: {0}")]
    PlantInput(#[from] PlantError),
    #[error("the central configuration has no inverse kinematics: {0}")]
    Central(kinematics_core::IkError),
    #[error("the board application refused its configuration: {0:?}")]
    Runtime(control::runtime::RuntimeError),
    #[error(transparent)]
    Platform(#[from] PlatformError),
}

/// Everything the board simulation needs.
#[derive(Clone, Debug)]
pub struct BoardSimConfig {
    /// The plant.
    pub plant: PlantConfig,
    /// The board application's configuration (f64 on the host).
    pub runtime: RuntimeConfig<f64>,
    /// The tick service's (period, deadline policy, firmware version).
    pub service: ServiceConfig,
    /// Plant steps per control period (>= 10).
    pub steps_per_tick: u32,
    /// Where the robot rests at power-up (joints; the brakes held it there).
    pub rest: [f64; NUM_JOINTS],
    /// The tool's weight on the platform, when attached.
    pub tool: Option<ToolLoad<f64>>,
    /// A wall in the task space, if any.
    pub wall: Option<Wall>,
    /// Telemetry period, µs (the board's 20 ms).
    pub telemetry_us: u64,
    /// The event log's flash: sectors (the board's 2) and bytes per sector (the board's
    /// 128 KiB).
    pub event_flash: (usize, usize),
    /// The link key (a key file's; None: a board on a desk, frames without tags).
    pub key: Option<master_link::LinkKey>,
    /// The board has the second position channel fitted (it reads the plant's absolute
    /// position sensors, and `Home` restores the references from them).
    pub position_channel: bool,
    /// How the robot is wired to the board (straight, or the miswirings commissioning
    /// finds: `board_on_plant::Wiring`).
    pub wiring: board_on_plant::Wiring,
}

/// The simulated board's reserved flash sector for the calibrated geometry (16 slots of
/// [`control::geometry_store::SLOT_LEN`] bytes, erased to 0xFF; a write clears bits only,
/// as NOR flash does).
#[derive(Clone, Debug)]
struct SimGeometryFlash {
    bytes: Vec<u8>,
}

impl SimGeometryFlash {
    const SLOTS: usize = 16;
    fn new() -> Self {
        SimGeometryFlash {
            bytes: vec![0xFF; Self::SLOTS * control::geometry_store::SLOT_LEN],
        }
    }
}

impl control::geometry_store::GeometryFlash for SimGeometryFlash {
    fn slots(&self) -> usize {
        Self::SLOTS
    }
    fn read_slot(
        &mut self,
        i: usize,
        out: &mut [u8; control::geometry_store::SLOT_LEN],
    ) -> Result<(), control::geometry_store::FlashError> {
        let n = control::geometry_store::SLOT_LEN;
        let slot = self
            .bytes
            .get(i * n..(i + 1) * n)
            .ok_or(control::geometry_store::FlashError::Driver)?;
        out.copy_from_slice(slot);
        Ok(())
    }
    fn write_slot(
        &mut self,
        i: usize,
        bytes: &[u8; control::geometry_store::SLOT_LEN],
    ) -> Result<(), control::geometry_store::FlashError> {
        let n = control::geometry_store::SLOT_LEN;
        let slot = self
            .bytes
            .get_mut(i * n..(i + 1) * n)
            .ok_or(control::geometry_store::FlashError::Driver)?;
        for (d, s) in slot.iter_mut().zip(bytes.iter()) {
            *d &= *s;
        }
        Ok(())
    }
    fn erase(&mut self) -> Result<(), control::geometry_store::FlashError> {
        self.bytes.fill(0xFF);
        Ok(())
    }
}

/// The simulated board's event-log sectors: NOR flash erased to 0xFF whose programming
/// clears bits only; counts its operations.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SimEventFlash {
    sectors: Vec<Vec<u8>>,
    /// Words programmed so far.
    pub words_programmed: u64,
    /// Sectors erased so far.
    pub erases: u64,
}

impl SimEventFlash {
    /// `sectors` erased sectors of `len` bytes.
    pub fn new(sectors: usize, len: usize) -> Self {
        SimEventFlash {
            sectors: vec![vec![0xFF; len]; sectors],
            words_programmed: 0,
            erases: 0,
        }
    }
    /// The bytes of `sector`.
    pub fn sector(&self, sector: usize) -> Option<&[u8]> {
        self.sectors.get(sector).map(Vec::as_slice)
    }
}

impl control::event_log::EventFlash for SimEventFlash {
    fn sectors(&self) -> usize {
        self.sectors.len()
    }
    fn sector_len(&self) -> usize {
        self.sectors.first().map_or(0, Vec::len)
    }
    fn read(
        &mut self,
        sector: usize,
        offset: usize,
        out: &mut [u32; control::event_log::record::RECORD_WORDS],
    ) -> Result<(), control::geometry_store::FlashError> {
        let s = self
            .sectors
            .get(sector)
            .ok_or(control::geometry_store::FlashError::Driver)?;
        for (k, w) in out.iter_mut().enumerate() {
            let at = offset + 4 * k;
            let b = s
                .get(at..at + 4)
                .ok_or(control::geometry_store::FlashError::Driver)?;
            *w = u32::from_le_bytes([b[0], b[1], b[2], b[3]]);
        }
        Ok(())
    }
    fn program(
        &mut self,
        sector: usize,
        offset: usize,
        words: &[u32],
    ) -> Result<(), control::geometry_store::FlashError> {
        let s = self
            .sectors
            .get_mut(sector)
            .ok_or(control::geometry_store::FlashError::Driver)?;
        let bytes = s
            .get_mut(offset..offset + 4 * words.len())
            .ok_or(control::geometry_store::FlashError::Driver)?;
        for (d, b) in bytes
            .iter_mut()
            .zip(words.iter().flat_map(|w| w.to_le_bytes()))
        {
            *d &= b;
        }
        self.words_programmed += words.len() as u64;
        Ok(())
    }
    fn erase(&mut self, sector: usize) -> Result<(), control::geometry_store::FlashError> {
        self.sectors
            .get_mut(sector)
            .ok_or(control::geometry_store::FlashError::Driver)?
            .fill(0xFF);
        self.erases += 1;
        Ok(())
    }
}

/// The board's flash as a power cycle keeps it: the geometry's sector and the event log's.
#[derive(Clone, Debug)]
pub struct BoardFlash {
    geometry: SimGeometryFlash,
    /// The event log's sectors.
    pub events: SimEventFlash,
}

/// The firmware version the simulated board reports.
pub const SIM_FIRMWARE: FirmwareVersion = FirmwareVersion {
    major: 0,
    minor: 1,
    patch: 0,
};

impl BoardSimConfig {
    /// The reference robot with the shipped plant, at rest at `rest` (None: legs 12 mm
    /// above their home switches and links 0.2 rad above their hard stops, as after a
    /// power-up), on the reference board (its profile's period and clock), 10 plant steps
    /// per tick, no tool, no wall, no second position channel.
    pub fn reference(rest: Option<[f64; NUM_JOINTS]>) -> Result<Self, BoardSimError> {
        let robot = RsprGeometry::<f64>::reference();
        let central = inverse(&robot, &Pose::central(robot.hc), Branch::OUTER)
            .map_err(BoardSimError::Central)?;
        let c = central.q();
        let mech = reference_mechanics(&Limits::reference());
        let rest = rest.unwrap_or_else(|| {
            let sw = mech.leg_switch_m + 0.012;
            let stop = |j: usize| c[j] - mech.link_stop_below_central_rad + 0.2;
            [sw, sw + 0.001, sw - 0.001, stop(3), stop(4), stop(5)]
        });
        let runtime = reference_config_for(&robot, Branch::OUTER, Some(mech), Some(rest))
            .map_err(BoardSimError::Central)?;
        Ok(BoardSimConfig {
            plant: PlantConfig::shipped().map_err(BoardSimError::Plant)?,
            runtime,
            service: ServiceConfig::for_period(
                PROFILE.control_period_us,
                PROFILE.cpu_hz,
                SIM_FIRMWARE,
            ),
            steps_per_tick: 10,
            rest,
            tool: None,
            wall: None,
            telemetry_us: 20_000,
            position_channel: false,
            wiring: board_on_plant::Wiring::straight(),
            event_flash: (2, 128 * 1024),
            key: None,
        })
    }
}

/// The truth of the plant at a tick.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Truth {
    /// Time, µs.
    pub t_us: u64,
    /// The platform's true pose (forward kinematics of the load-side joints).
    pub pose: Pose<f64>,
    /// Its velocity (o_p), m/s.
    pub velocity: Vector3<f64>,
    /// The load-side joints.
    pub q: [f64; NUM_JOINTS],
    /// The force the wall exerts on the platform, N.
    pub wall_force: Vector3<f64>,
    /// Largest |effort| each transmission carried over the tick (N, N m).
    pub peak_transmitted: [f64; NUM_JOINTS],
    /// Largest |motor effort| `n Kt i` over the tick (N, N m).
    pub peak_motor_effort: [f64; NUM_JOINTS],
}

/// The board application on the plant, in virtual time.
pub struct BoardSim {
    cfg: BoardSimConfig,
    service: TickService<f64, RsprGeometry<f64>>,
    /// The board and the robot around the plant (public for fault injection).
    pub hw: BoardOnPlant,
    /// The platform: the true pose, the tool's and the wall's loads.
    platform: Platform,
    latch: EStopLatch,
    rx: LinkRx,
    tx: LinkTx,
    queue: VecDeque<Request>,
    /// A received calibrated geometry for the next tick (one at a time, as on the board).
    geometry_in: Option<(master_link::Seq, master_link::GeometryRecord)>,
    /// The board's flash: the calibrated geometry's sector, the event log's sectors.
    flash: BoardFlash,
    /// The event log's writer (None: its flash could not be read).
    event_store: Option<control::event_log::EventStore>,
    outbox: Vec<u8>,
    t_us: u64,
    next_status_us: u64,
    overrun: Option<(u32, u32)>,
    truth: Truth,
    last_outcome: Option<TickOutcome>,
}

/// Requests queued for a tick (the board's channel).
pub const COMMAND_QUEUE: usize = 8;

impl BoardSim {
    /// Powers the board up at `cfg.rest`: the runtime boots with `reset` and the fault
    /// log `log` kept across it (None after a power-on).
    pub fn new(
        cfg: BoardSimConfig,
        reset: ResetCause,
        log: Option<control::faults::FaultLog>,
    ) -> Result<Self, BoardSimError> {
        let (sectors, len) = cfg.event_flash;
        let flash = BoardFlash {
            geometry: SimGeometryFlash::new(),
            events: SimEventFlash::new(sectors, len),
        };
        let rest = cfg.rest;
        Self::on_flash(cfg, reset, log, flash, rest)
    }

    /// A power cycle: a new board (RAM lost, the surroundings as at power-up) on the same
    /// flash, the robot at rest at `cfg.rest` as at power-up (where the homing's settings
    /// expect it), booting with a power-on reset: the event log and the stored geometry
    /// are what the flash kept.
    pub fn power_cycle(self) -> Result<Self, BoardSimError> {
        let rest = self.cfg.rest;
        Self::on_flash(self.cfg, ResetCause::PowerOn, None, self.flash, rest)
    }

    /// The board's flash.
    pub fn flash(&self) -> &BoardFlash {
        &self.flash
    }
    /// The event log's writer.
    pub fn event_store(&self) -> Option<&control::event_log::EventStore> {
        self.event_store.as_ref()
    }

    /// Powers the board up on `flash` with the robot at `rest`: the event log mounted (a
    /// new boot; the relay test required when it was pending), the stored geometry's
    /// version read, the runtime booted with `reset` and the fault log `log` kept across it.
    fn on_flash(
        cfg: BoardSimConfig,
        reset: ResetCause,
        log: Option<control::faults::FaultLog>,
        mut flash: BoardFlash,
        rest: [f64; NUM_JOINTS],
    ) -> Result<Self, BoardSimError> {
        let robot = RsprGeometry::<f64>::reference();
        let plant = Plant::new(&cfg.plant).map_err(BoardSimError::Plant)?;
        let mech = cfg.runtime.mechanics;
        let central_q = cfg.runtime.homing.park.unwrap_or(cfg.rest);
        let layout = Layout::reference(&ReferenceMechanics {
            central_q,
            leg_switch_m: mech.leg_switch_m,
            link_stop_below_central_rad: mech.link_stop_below_central_rad,
            range: mech.range,
        });
        let mut hw = BoardOnPlant::at_rest(plant, rest)?.with_layout(&layout);
        hw.position_channel = cfg.position_channel;
        hw.wiring = cfg.wiring;
        let mut rt = Runtime::new(robot, cfg.runtime, 0).map_err(BoardSimError::Runtime)?;
        let (event_store, events) = control::event_log::boot(&mut flash.events, None);
        rt.restore_events(events);
        if let Ok(Some((_, stored))) = control::geometry_store::load_latest(&mut flash.geometry) {
            rt.set_geometry_version(stored.version);
        }
        // (Boot from Boot cannot be refused.)
        let _ = rt.boot_done(hw.counts(), 0, reset, log);
        let service = TickService::new(rt, cfg.service);
        let q = hw.plant.joint_positions();
        let mut platform = Platform::new(q, 0.0)?;
        platform.tool = cfg.tool.as_ref().map(tool_of);
        platform.wall = cfg.wall;
        Ok(BoardSim {
            service,
            hw,
            latch: EStopLatch::new(),
            rx: LinkRx::with(
                BoardIdentity::new(b"simulated board", cfg.key.as_ref()),
                cfg.key.clone(),
            ),
            tx: LinkTx::with_key(cfg.key.clone()),
            queue: VecDeque::new(),
            geometry_in: None,
            flash,
            event_store,
            outbox: Vec::new(),
            t_us: 0,
            next_status_us: 0,
            overrun: None,
            truth: Truth {
                t_us: 0,
                pose: *platform.pose(),
                velocity: Vector3::zeros(),
                q,
                wall_force: Vector3::zeros(),
                peak_transmitted: [0.0; NUM_JOINTS],
                peak_motor_effort: [0.0; NUM_JOINTS],
            },
            platform,
            last_outcome: None,
            cfg,
        })
    }

    /// Virtual time, µs.
    pub fn now_us(&self) -> u64 {
        self.t_us
    }
    /// The board application.
    pub fn runtime(&self) -> &Runtime<f64, RsprGeometry<f64>> {
        self.service.runtime()
    }
    /// The tick service.
    pub fn service(&self) -> &TickService<f64, RsprGeometry<f64>> {
        &self.service
    }
    /// The truth at the last tick.
    pub fn truth(&self) -> &Truth {
        &self.truth
    }
    /// The last tick's outcome.
    pub fn last_outcome(&self) -> Option<&TickOutcome> {
        self.last_outcome.as_ref()
    }
    /// The settings.
    pub fn config(&self) -> &BoardSimConfig {
        &self.cfg
    }
    /// The receiving side of the link (its counters).
    pub fn link_rx(&self) -> &LinkRx {
        &self.rx
    }

    /// Attaches (or removes) the tool.
    pub fn set_tool(&mut self, tool: Option<ToolLoad<f64>>) {
        self.cfg.tool = tool;
        self.platform.tool = tool.as_ref().map(tool_of);
    }
    /// Puts a wall in the task space (or removes it).
    pub fn set_wall(&mut self, wall: Option<Wall>) {
        self.cfg.wall = wall;
        self.platform.wall = wall;
    }

    /// Presses (or releases) the e-stop button: the relay opens (drivers' and brakes'
    /// power removed by hardware), and the button's interrupt forces the outputs safe and
    /// trips the latch for the next tick.
    pub fn press_estop(&mut self, pressed: bool) {
        let edge = pressed && !self.hw.estop;
        self.hw.press_estop(pressed);
        if edge {
            self.hw.force_safe();
            self.latch.trip();
        }
    }

    /// The next `ticks` ticks run `exec_us` each (an injected overrun: a stuck bus, a
    /// runaway loop), as the board's cycle counter would measure them.
    pub fn overrun_next_ticks(&mut self, ticks: u32, exec_us: u32) {
        self.overrun = Some((ticks, exec_us));
    }

    /// Bytes from the master: frames to requests (queued for the next tick), the link's
    /// own replies to the outbox; an `EmergencyStop` forces the outputs safe at once.
    pub fn receive(&mut self, bytes: &[u8]) {
        self.rx.set_uptime(self.t_us);
        for b in bytes {
            match self.rx.push(*b) {
                Some(Inbound::Reply(r)) => self.send(&r),
                Some(Inbound::Geometry { seq, record }) => {
                    if self.geometry_in.is_some() {
                        self.send(&BoardToMaster::Nack {
                            seq,
                            reason: NackReason::Busy,
                        });
                    } else {
                        self.geometry_in = Some((seq, record));
                    }
                }
                Some(Inbound::Request(req)) => {
                    if req.message == MasterToBoard::EmergencyStop {
                        self.hw.force_safe();
                        self.latch.trip_message();
                    }
                    if self.queue.len() >= COMMAND_QUEUE {
                        self.send(&BoardToMaster::Nack {
                            seq: req.seq,
                            reason: NackReason::Busy,
                        });
                    } else {
                        self.queue.push_back(req);
                    }
                }
                None => {}
            }
        }
    }

    /// The bytes the board sent since the last call.
    pub fn take_output(&mut self) -> Vec<u8> {
        std::mem::take(&mut self.outbox)
    }

    fn send(&mut self, msg: &BoardToMaster) {
        let mut buf = [0u8; MAX_FRAME_LEN];
        if let Ok(n) = self.tx.encode(msg, &mut buf) {
            self.outbox
                .extend_from_slice(buf.get(..n).unwrap_or_default());
        }
    }

    /// One control period: the tick as the board runs it (the e-stop latch, the queued
    /// requests and their replies, the runtime's tick, the deadline policy, the status),
    /// then the plant over the period with the tool's and the wall's loads.
    pub fn tick(&mut self) -> Result<TickOutcome, BoardSimError> {
        let now = self.t_us;
        self.service.begin(now, 0, self.latch.take());
        while let Some(req) = self.queue.pop_front() {
            let reply = self.service.request(&req, now);
            // An accepted Hello: its session opens on the receiving side before the
            // reply goes out.
            if let Some(session) = opened_session(&reply) {
                self.rx.open_session(session, req.seq);
            }
            self.send(&reply);
        }
        // As the board: a geometry the runtime accepts is stored after the tick.
        let mut accepted_geometry = None;
        if let Some((seq, record)) = self.geometry_in.take() {
            match self.service.check_geometry(&record) {
                Ok(_) => accepted_geometry = Some((seq, record)),
                Err(reason) => self.send(&BoardToMaster::GeometryRefused { seq, reason }),
            }
        }
        self.service.tick(&mut self.hw, now);
        let exec_us = match &mut self.overrun {
            Some((n, us)) if *n > 0 => {
                *n -= 1;
                *us
            }
            _ => 300,
        };
        let outcome = self
            .service
            .finish(now, exec_us * (PROFILE.cpu_hz / 1_000_000));
        if let Some(refused) = outcome.refused {
            self.send(&BoardToMaster::TargetRefused(refused));
        }
        if self.rx.connected() && now >= self.next_status_us {
            self.next_status_us = now + self.cfg.telemetry_us;
            let mut st = outcome.status;
            with_link(&mut st, Some(self.rx.counters()));
            self.send(&BoardToMaster::Status(st));
        } else if !self.rx.connected() {
            self.next_status_us = now;
        }
        self.store_events(now, outcome.drives_off);
        if let Some((seq, record)) = accepted_geometry {
            let reply = match control::geometry_store::store(&mut self.flash.geometry, &record) {
                Ok(_) => {
                    self.service
                        .runtime_mut()
                        .geometry_stored(record.version, now);
                    BoardToMaster::GeometryStored {
                        seq,
                        version: record.version,
                    }
                }
                Err(_) => BoardToMaster::GeometryRefused {
                    seq,
                    reason: master_link::GeometryRefusal::Flash,
                },
            };
            self.service.resume_after_pause();
            self.send(&reply);
        }
        self.step_plant()?;
        self.last_outcome = Some(outcome);
        Ok(outcome)
    }

    /// As the board after its tick: at most `WORDS_PER_PERIOD` words of the event log
    /// programmed, an erase only with the drives off (`drives_off`: and the brakes
    /// applied), after which the schedule restarts.
    fn store_events(&mut self, now_us: u64, drives_off: bool) {
        let Some(store) = self.event_store.as_mut() else {
            return;
        };
        let step = store.step(
            &mut self.flash.events,
            self.service.runtime_mut().events_mut(),
            (now_us / 1000) as u32,
            control::event_log::WORDS_PER_PERIOD,
            drives_off,
        );
        if let control::event_log::Step::Erased { .. } = step {
            self.service.resume_after_pause();
        }
    }

    /// Runs `ticks` control periods.
    pub fn run(&mut self, ticks: u32) -> Result<(), BoardSimError> {
        for _ in 0..ticks {
            self.tick()?;
        }
        Ok(())
    }

    /// The plant over one control period, the loads mapped at the true pose of each step
    /// while a wall is in contact (else once per period).
    fn step_plant(&mut self) -> Result<(), BoardSimError> {
        let period = u64::from(self.cfg.service.watchdog.period_us);
        let steps = self.cfg.steps_per_tick.max(1);
        let dt = period as f64 * 1e-6 / f64::from(steps);
        let mut peak_t = [0.0f64; NUM_JOINTS];
        let mut peak_m = [0.0f64; NUM_JOINTS];
        let t0 = self.t_us as f64 * 1e-6;
        for k in 0..steps {
            if k == 0 || self.platform.wall.is_some() {
                self.update_truth(t0 + f64::from(k) * dt)?;
                self.platform.apply_loads(&mut self.hw.plant)?;
                self.truth.wall_force = self.platform.wall_force();
            }
            self.hw.step(dt)?;
            let (t, m) = (
                self.hw.plant.transmitted_efforts(),
                self.hw.plant.motor_efforts(),
            );
            for j in 0..NUM_JOINTS {
                peak_t[j] = peak_t[j].max(t[j].abs());
                peak_m[j] = peak_m[j].max(m[j].abs());
            }
        }
        self.t_us += period;
        self.update_truth(self.t_us as f64 * 1e-6)?;
        self.truth.peak_transmitted = peak_t;
        self.truth.peak_motor_effort = peak_m;
        Ok(())
    }

    /// The true pose of the plant's joints at `t_s`, and the velocity since the last
    /// update.
    fn update_truth(&mut self, t_s: f64) -> Result<(), BoardSimError> {
        self.platform.update(self.hw.plant.joint_positions(), t_s)?;
        self.truth.pose = *self.platform.pose();
        self.truth.velocity = self.platform.velocity();
        self.truth.q = self.platform.q();
        self.truth.t_us = self.t_us;
        Ok(())
    }
}

/// The firmware's tool as the platform carries it.
fn tool_of(t: &ToolLoad<f64>) -> Tool {
    Tool {
        mass_kg: t.mass_kg,
        com_p_m: t.com_p_m,
        gravity_m_s2: t.gravity_m_s2,
    }
}
