//! The whole board application on the plant, in virtual time: the firmware's tick service
//! (`control::service::TickService`: the runtime with its state machine, stops, brakes,
//! monitors, fault log, deadline policy) and its master link (`control::link`), exactly as
//! the board tasks run them (`firmware/cortex-m/board-tasks`), against the plant model with
//! the board around it:
//!
//! * the drivers (enable, current regulation: the plant's), the brakes' two coil groups,
//!   the supply, the drivers' fault line;
//! * the hard-wired e-stop chain: the button opens the safety relay, which removes the
//!   drivers' power and the brakes' coil power without the MCU; the button's interrupt
//!   forces the outputs safe and trips the latch the next tick takes; a welded or a stuck
//!   open relay for the campaign;
//! * the mechanics the plant lacks: the legs' home switches and bottom end stops (3 mm
//!   below the switches) and the links' hard stops where the firmware's reference
//!   mechanics put them (a stop seizes the load side while the motor pushes into it);
//! * the tool's weight and an optional stiff wall in the task space, mapped to joint loads
//!   through tau = J^-T s_e at the true pose (Eq. 7.10);
//! * the link: bytes in (`LinkRx`), requests queued for the next tick (8 deep, as on the
//!   board: a full queue answers `Busy`), replies and the status every 20 ms out
//!   (`LinkTx`); an `EmergencyStop` frame forces the outputs safe at once.
//!
//! The tick's execution time is not simulated: each tick reports a nominal 300 µs, plus
//! what a campaign injects ([`BoardSim::overrun_next_ticks`]).

use std::collections::VecDeque;

use control::estop::EStopLatch;
use control::link::{Inbound, LinkRx, LinkTx, Request};
use control::runtime::{reference_config_for, reference_mechanics, Runtime, RuntimeConfig};
use control::service::{ServiceConfig, TickOutcome, TickService};
use control::telemetry::with_link;
use control::ToolLoad;
use hal::{
    Brakes, CurrentSense, LimitSwitches, MotorOutputs, PowerStage, QuadratureCounter, SafetyChain,
};
use kinematics_core::guards::Limits;
use kinematics_core::statics::forces_with_inv_cond;
use kinematics_core::{forward, inverse, jacobian, Branch, FkConfig, Pose, RsprGeometry, Wrench};
use master_link::{
    BoardToMaster, FirmwareVersion, MasterToBoard, NackReason, ResetCause, MAX_FRAME_LEN,
};
use nalgebra::Vector3;
use plant::{JointFaults, Plant, PlantConfig, PlantError, NUM_JOINTS};
use thiserror::Error;

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
    #[error("the true pose (forward kinematics of the plant's joints) failed: {0:?}")]
    TruePose(kinematics_core::FkError),
}

/// A stiff wall in the task space: a half-space the platform centre `o_p` cannot enter
/// without the wall pushing back, `f = k δ + c max(0, -v_n)` along the wall's normal while
/// the penetration `δ > 0`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Wall {
    /// A point of the wall's surface, m, {0}.
    pub point: Vector3<f64>,
    /// The unit normal out of the wall (towards the free side).
    pub normal: Vector3<f64>,
    /// Stiffness, N/m.
    pub stiffness_n_per_m: f64,
    /// Damping while pressing in, N s/m.
    pub damping_n_s_per_m: f64,
}

impl Wall {
    /// The force the wall exerts on the platform with `o_p` at `p`, moving at `v`.
    pub fn force(&self, p: &Vector3<f64>, v: &Vector3<f64>) -> Vector3<f64> {
        let depth = (self.point - p).dot(&self.normal);
        if depth <= 0.0 {
            return Vector3::zeros();
        }
        let into = (-v.dot(&self.normal)).max(0.0);
        self.normal * (self.stiffness_n_per_m * depth + self.damping_n_s_per_m * into)
    }
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

/// The firmware version the simulated board reports.
pub const SIM_FIRMWARE: FirmwareVersion = FirmwareVersion {
    major: 0,
    minor: 1,
    patch: 0,
};

impl BoardSimConfig {
    /// The reference robot with the shipped plant, at rest at `rest` (None: legs 12 mm
    /// above their home switches and links 0.2 rad above their hard stops, as after a
    /// power-up), 1 kHz, 10 plant steps per tick, no tool, no wall.
    pub fn reference(rest: Option<[f64; NUM_JOINTS]>) -> Result<Self, BoardSimError> {
        let robot = RsprGeometry::<f64>::reference();
        let central = inverse(&robot, &Pose::central(robot.hc), Branch::OUTER)
            .map_err(BoardSimError::Central)?;
        let c = central.q();
        let mech = reference_mechanics(&[c[0], c[1], c[2], c[3], c[4], c[5]], &Limits::reference());
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
            service: ServiceConfig::for_period(1000, 168_000_000, SIM_FIRMWARE),
            steps_per_tick: 10,
            rest,
            tool: None,
            wall: None,
            telemetry_us: 20_000,
        })
    }
}

/// The plant with the board around it, behind the firmware's hardware traits.
#[derive(Clone, Debug)]
pub struct BoardHardware {
    /// The plant.
    pub plant: Plant,
    /// The MCU's driver enable output.
    pub enabled: bool,
    /// The MCU's brake outputs (both groups switch together in the firmware).
    pub brakes_released: bool,
    /// The e-stop button is pressed.
    pub estop: bool,
    /// The safety relay's contacts are welded (it stays closed with the button pressed).
    pub relay_welded: bool,
    /// The safety relay is open without the button (a failed coil, a cut wire).
    pub relay_stuck_open: bool,
    /// Each joint's switch closes at or below this position (the legs' home switches).
    pub switch_below: [Option<f64>; NUM_JOINTS],
    /// A switch forced to a level (a failed switch or a cut wire), whatever the joint does.
    pub switch_forced: [Option<bool>; NUM_JOINTS],
    /// Each joint's hard stop below this position (the links').
    pub stop_below: [Option<f64>; NUM_JOINTS],
    /// The hard stop holds the load side now.
    at_stop: [bool; NUM_JOINTS],
    /// A current-sense offset added to the readings, A (a failed amplifier).
    pub current_offset_a: [f64; NUM_JOINTS],
}

impl BoardHardware {
    fn relay_open(&self) -> bool {
        (self.estop && !self.relay_welded) || self.relay_stuck_open
    }

    /// What the MCU commands and the safety chain allows, to the plant.
    fn apply(&mut self) {
        let powered = !self.relay_open();
        self.plant.set_bridges_enabled(self.enabled && powered);
        self.plant
            .set_brakes_released([self.brakes_released && powered; NUM_JOINTS]);
    }

    /// The e-stop interrupt's register writes: PWM off, driver enable low, brakes applied.
    fn force_safe(&mut self) {
        self.enabled = false;
        self.brakes_released = false;
        let _ = self.plant.set_duty([0.0; NUM_JOINTS]);
        self.apply();
    }

    /// The hard stops after a plant step: a load side past its stop while the motor drives
    /// into it is held there; driven back out, it is free again.
    fn hard_stops(&mut self) -> Result<(), PlantError> {
        let q = self.plant.joint_positions();
        let duty = self.plant.duty();
        for j in 0..NUM_JOINTS {
            let Some(stop) = self.stop_below[j] else {
                continue;
            };
            let hit = !self.at_stop[j] && q[j] <= stop && duty[j] <= 0.0;
            let leave = self.at_stop[j] && duty[j] > 0.0;
            if hit || leave {
                let mut f: JointFaults = self.plant.faults(j)?;
                f.load_seized = hit;
                self.plant.set_faults(j, f)?;
                self.at_stop[j] = hit;
            }
        }
        Ok(())
    }
}

impl QuadratureCounter for BoardHardware {
    fn counts(&mut self) -> [u16; NUM_JOINTS] {
        self.plant.encoder_counts()
    }
}

impl MotorOutputs<f64> for BoardHardware {
    fn set_duties(&mut self, duty: &[f64; NUM_JOINTS]) {
        let d = if self.enabled {
            duty.map(|x| {
                if x.is_finite() {
                    x.clamp(-1.0, 1.0)
                } else {
                    0.0
                }
            })
        } else {
            [0.0; NUM_JOINTS]
        };
        // Finite duties in [-1, 1]: the plant accepts them.
        let _ = self.plant.set_duty(d);
    }
    fn disable(&mut self) {
        self.enabled = false;
        let _ = self.plant.set_duty([0.0; NUM_JOINTS]);
        self.apply();
    }
    fn enable(&mut self) {
        self.enabled = true;
        self.apply();
    }
}

impl Brakes for BoardHardware {
    fn set_brakes_released(&mut self, released: bool) {
        self.brakes_released = released;
        self.apply();
    }
}

impl PowerStage<f64> for BoardHardware {
    fn supply_voltage(&mut self) -> f64 {
        self.plant.supply_voltage()
    }
    fn driver_fault(&mut self) -> bool {
        self.plant.driver_fault()
    }
}

impl SafetyChain for BoardHardware {
    fn estop_pressed(&mut self) -> bool {
        self.estop
    }
    fn relay_open(&mut self) -> bool {
        BoardHardware::relay_open(self)
    }
}

impl LimitSwitches for BoardHardware {
    fn switches(&mut self) -> [bool; NUM_JOINTS] {
        let q = self.plant.joint_positions();
        std::array::from_fn(|j| {
            self.switch_forced[j].unwrap_or_else(|| self.switch_below[j].is_some_and(|s| q[j] <= s))
        })
    }
}

impl CurrentSense<f64> for BoardHardware {
    fn currents(&mut self) -> [f64; NUM_JOINTS] {
        let i = self.plant.currents();
        std::array::from_fn(|j| i[j] + self.current_offset_a[j])
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
    robot: RsprGeometry<f64>,
    cfg: BoardSimConfig,
    service: TickService<f64, RsprGeometry<f64>>,
    /// The hardware (public for fault injection).
    pub hw: BoardHardware,
    latch: EStopLatch,
    rx: LinkRx,
    tx: LinkTx,
    queue: VecDeque<Request>,
    /// A received calibrated geometry for the next tick (one at a time, as on the board).
    geometry_in: Option<(master_link::Seq, master_link::GeometryRecord)>,
    /// The board's reserved flash sector for the calibrated geometry.
    geometry_flash: SimGeometryFlash,
    outbox: Vec<u8>,
    t_us: u64,
    next_status_us: u64,
    overrun: Option<(u32, u32)>,
    fk: FkConfig<f64>,
    truth: Truth,
    /// When the truth was last updated, s.
    truth_t_s: f64,
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
        let robot = RsprGeometry::<f64>::reference();
        let mut plant = Plant::new(&cfg.plant).map_err(BoardSimError::Plant)?;
        plant.set_joint_positions(cfg.rest)?;
        let mech = cfg.runtime.mechanics;
        let c = cfg.runtime.homing.park.unwrap_or(cfg.rest);
        let mut hw = BoardHardware {
            plant,
            enabled: false,
            brakes_released: false,
            estop: false,
            relay_welded: false,
            relay_stuck_open: false,
            switch_below: [
                Some(mech.leg_switch_m),
                Some(mech.leg_switch_m),
                Some(mech.leg_switch_m),
                None,
                None,
                None,
            ],
            switch_forced: [None; NUM_JOINTS],
            // The legs' bottom end stop 3 mm below their home switch, the links' hard stops
            // where the homing expects them.
            stop_below: [
                Some(mech.leg_switch_m - 0.003),
                Some(mech.leg_switch_m - 0.003),
                Some(mech.leg_switch_m - 0.003),
                Some(c[3] - mech.link_stop_below_central_rad),
                Some(c[4] - mech.link_stop_below_central_rad),
                Some(c[5] - mech.link_stop_below_central_rad),
            ],
            at_stop: [false; NUM_JOINTS],
            current_offset_a: [0.0; NUM_JOINTS],
        };
        hw.apply();
        let mut rt = Runtime::new(robot, cfg.runtime, 0).map_err(BoardSimError::Runtime)?;
        // (Boot from Boot cannot be refused.)
        let _ = rt.boot_done(hw.counts(), 0, reset, log);
        let service = TickService::new(rt, cfg.service);
        let fk = FkConfig::default();
        let q = hw.plant.joint_positions();
        let pose = forward(
            &robot,
            &nalgebra::Vector6::from_row_slice(&q),
            Branch::OUTER,
            &Pose::central(robot.hc),
            &fk,
        )
        .map_err(BoardSimError::TruePose)?
        .pose;
        Ok(BoardSim {
            robot,
            service,
            hw,
            latch: EStopLatch::new(),
            rx: LinkRx::new(),
            tx: LinkTx::new(),
            queue: VecDeque::new(),
            geometry_in: None,
            geometry_flash: SimGeometryFlash::new(),
            outbox: Vec::new(),
            t_us: 0,
            next_status_us: 0,
            overrun: None,
            fk,
            truth: Truth {
                t_us: 0,
                pose,
                velocity: Vector3::zeros(),
                q,
                wall_force: Vector3::zeros(),
                peak_transmitted: [0.0; NUM_JOINTS],
                peak_motor_effort: [0.0; NUM_JOINTS],
            },
            last_outcome: None,
            truth_t_s: 0.0,
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
    }
    /// Puts a wall in the task space (or removes it).
    pub fn set_wall(&mut self, wall: Option<Wall>) {
        self.cfg.wall = wall;
    }

    /// Presses (or releases) the e-stop button: the relay opens (drivers' and brakes'
    /// power removed by hardware), and the button's interrupt forces the outputs safe and
    /// trips the latch for the next tick.
    pub fn press_estop(&mut self, pressed: bool) {
        let edge = pressed && !self.hw.estop;
        self.hw.estop = pressed;
        if edge {
            self.hw.force_safe();
            self.latch.trip();
        }
        self.hw.apply();
    }

    /// The next `ticks` ticks run `exec_us` each (an injected overrun: a stuck bus, a
    /// runaway loop), as the board's cycle counter would measure them.
    pub fn overrun_next_ticks(&mut self, ticks: u32, exec_us: u32) {
        self.overrun = Some((ticks, exec_us));
    }

    /// Bytes from the master: frames to requests (queued for the next tick), the link's
    /// own replies to the outbox; an `EmergencyStop` forces the outputs safe at once.
    pub fn receive(&mut self, bytes: &[u8]) {
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
        let outcome = self.service.finish(now, exec_us * 168);
        if self.rx.connected() && now >= self.next_status_us {
            self.next_status_us = now + self.cfg.telemetry_us;
            let mut st = outcome.status;
            with_link(&mut st, Some(self.rx.counters()));
            self.send(&BoardToMaster::Status(st));
        } else if !self.rx.connected() {
            self.next_status_us = now;
        }
        if let Some((seq, record)) = accepted_geometry {
            let reply = match control::geometry_store::store(&mut self.geometry_flash, &record) {
                Ok(_) => {
                    self.service
                        .runtime_mut()
                        .set_geometry_version(record.version);
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

    /// Jumps the board's clock forward to `t_us` (a period boundary at or before it)
    /// without simulating the time in between: the plant stands still (a served board
    /// whose host fell behind the wall clock).
    pub fn skip_to(&mut self, t_us: u64) {
        let period = u64::from(self.cfg.service.watchdog.period_us).max(1);
        let t = t_us / period * period;
        if t > self.t_us {
            self.t_us = t;
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
            if k == 0 || self.cfg.wall.is_some() {
                self.update_truth(t0 + f64::from(k) * dt)?;
                self.apply_loads()?;
            }
            self.hw.plant.step(dt)?;
            self.hw.hard_stops()?;
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

    /// The true pose of the plant's joints at `t_s` (FK warm-started from the last), and
    /// the velocity since the last update.
    fn update_truth(&mut self, t_s: f64) -> Result<(), BoardSimError> {
        let dt = t_s - self.truth_t_s;
        if dt <= 0.0 {
            return Ok(());
        }
        self.truth_t_s = t_s;
        let q = self.hw.plant.joint_positions();
        if q == self.truth.q && self.truth.t_us != 0 {
            self.truth.velocity = Vector3::zeros();
            self.truth.t_us = self.t_us;
            return Ok(());
        }
        let fk = forward(
            &self.robot,
            &nalgebra::Vector6::from_row_slice(&q),
            Branch::OUTER,
            &self.truth.pose,
            &self.fk,
        )
        .map_err(BoardSimError::TruePose)?;
        self.truth.velocity = (fk.pose.t - self.truth.pose.t) / dt;
        self.truth.pose = fk.pose;
        self.truth.q = q;
        self.truth.t_us = self.t_us;
        Ok(())
    }

    /// The joint loads of the tool and the wall at the true pose: -tau, tau = J^-T s_e
    /// (Eq. 7.10) for the wrench the platform exerts on them.
    fn apply_loads(&mut self) -> Result<(), BoardSimError> {
        let pose = self.truth.pose;
        let mut se = Wrench::<f64>::zeros();
        if let Some(tool) = &self.cfg.tool {
            se += tool.wrench(&pose);
        }
        let mut wall_force = Vector3::zeros();
        if let Some(w) = &self.cfg.wall {
            wall_force = w.force(&pose.t, &self.truth.velocity);
            // The platform pushes on the wall with -f (at o_p: no moment).
            se[0] -= wall_force.x;
            se[1] -= wall_force.y;
            se[2] -= wall_force.z;
        }
        self.truth.wall_force = wall_force;
        if se.iter().all(|x| *x == 0.0) {
            self.hw.plant.set_external_load([0.0; NUM_JOINTS])?;
            return Ok(());
        }
        let Ok(sol) = inverse(&self.robot, &pose, Branch::OUTER) else {
            return Ok(());
        };
        let Ok(jac) = jacobian(&self.robot, &sol) else {
            return Ok(());
        };
        if let Ok(st) = forces_with_inv_cond(&jac, &se, 1.0, 0.0) {
            let load: [f64; NUM_JOINTS] = std::array::from_fn(|j| -st.tau[j]);
            self.hw.plant.set_external_load(load)?;
        }
        Ok(())
    }
}
