//! The closed loop: the board's control application ([`control::Controller`]) driving
//! the plant model ([`plant::Plant`]) through the hardware traits, the plant stepped
//! `plant_steps_per_tick` times per control tick, and the tool's weight mapped to joint
//! loads at the true pose.

use crate::config::{PayloadUpdate, SimConfig};
use control::{
    Controller, ControllerConfig, ControllerError, Drive, Measured, Plan, Planner, Sensing,
    SensingError, TickReport, ToolLoad,
};
use hal::{MotorOutputs, QuadratureCounter};
use kinematics_core::guards::Limits;
use kinematics_core::statics::forces_with_inv_cond;
use kinematics_core::supervisor::TickOutput;
use kinematics_core::{
    forward, inverse, jacobian, Branch, FkConfig, FkSolution, ForceError, IkError, JacobianError,
    Joints, Pose, RsprGeometry,
};
use nalgebra::Vector3;
use plant::{Plant, PlantConfig, PlantError, NUM_JOINTS};
use servo::backlash::{BacklashConfig, BacklashRamp};
use std::time::Instant;
use thiserror::Error;

/// Why the closed loop cannot be set up or stepped.
#[derive(Debug, Error)]
pub enum EngineError {
    /// The shipped plant parameters (a defect of the build).
    #[error("{0}")]
    ShippedPlant(plant::ConfigError),
    /// The file of `plant.config_file`.
    #[error("plant.config_file: cannot read {path}: {source}")]
    ReadPlantFile {
        path: String,
        source: std::io::Error,
    },
    #[error("plant.config_file {path}: {error}")]
    PlantFile {
        path: String,
        error: plant::ConfigError,
    },
    /// The plant parameters with `plant.leg_backlash_mm`.
    #[error("plant.leg_backlash_mm: {0}")]
    LegBacklash(plant::ConfigError),
    /// The plant refused its parameters.
    #[error("{0}")]
    PlantConfig(plant::ConfigError),
    /// The plant refused an input (positions, loads, step, fault).
    #[error("{0}")]
    Plant(PlantError),
    #[error("the start pose has no inverse kinematics: {0}")]
    StartPose(IkError),
    #[error("sensing: {0}")]
    Sensing(SensingError),
    #[error("controller: {0}")]
    Controller(ControllerError<f64>),
    /// The payload's mapping to the joints at the true pose.
    #[error("payload: {0:?}")]
    PayloadJacobian(JacobianError),
    #[error("payload: {0}")]
    PayloadForces(ForceError),
}

impl From<PlantError> for EngineError {
    fn from(e: PlantError) -> Self {
        EngineError::Plant(e)
    }
}

/// The bare plant behind the two hardware traits the controller's halves use (counters,
/// duties): no board around it (for that, `board_on_plant::BoardOnPlant` and the
/// simulated board of [`crate::board`]). With no driver enable to drop,
/// [`MotorOutputs::disable`] zeroes the duties with the bridges on (the motors
/// short-braked, which the tests of tripped faults measure) until [`MotorOutputs::enable`].
struct PlantIo<'a> {
    plant: &'a mut Plant,
    enabled: &'a mut bool,
}

impl QuadratureCounter for PlantIo<'_> {
    fn counts(&mut self) -> [u16; NUM_JOINTS] {
        self.plant.encoder_counts()
    }
}

impl MotorOutputs<f64> for PlantIo<'_> {
    fn set_duties(&mut self, duty: &[f64; NUM_JOINTS]) {
        let d = if *self.enabled {
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
        *self.enabled = false;
        let _ = self.plant.set_duty([0.0; NUM_JOINTS]);
    }
    fn enable(&mut self) {
        *self.enabled = true;
    }
}

/// The tool: a weight on a lever fixed to the platform (the controller's own
/// [`ToolLoad`], so the plant's load and the controller's knowledge of it are one thing).
pub type Payload = ToolLoad<f64>;

/// The tool of the `[payload]` settings.
pub fn payload_from_config(cfg: &SimConfig) -> Payload {
    ToolLoad {
        mass_kg: cfg.payload.mass_kg,
        com_p_m: [
            cfg.payload.lever_mm[0] * 1e-3,
            cfg.payload.lever_mm[1] * 1e-3,
            cfg.payload.lever_mm[2] * 1e-3,
        ],
        gravity_m_s2: cfg.payload.gravity_m_s2,
        ..ToolLoad::thesis()
    }
}

/// What one control tick did, with the truth at the instant the encoders were read.
#[derive(Clone, Copy, Debug)]
pub struct TickSample {
    /// Time of the tick (when the encoders are read), s.
    pub t_s: f64,
    /// The supervisor's setpoint of the tick.
    pub setpoint: TickOutput<f64>,
    /// The tick's measurements (joints, measured pose).
    pub measured: Measured<f64>,
    /// The controller's report (duties, fault).
    pub report: TickReport<f64>,
    /// True load-side joints at `t_s`.
    pub true_q: [f64; NUM_JOINTS],
    /// True pose at `t_s` (forward kinematics of `true_q`).
    pub true_pose: Pose<f64>,
    /// Duties applied over the tick (0 while the outputs are off).
    pub duty: [f64; NUM_JOINTS],
    /// Largest |current| over the tick's plant steps, A.
    pub peak_current_a: [f64; NUM_JOINTS],
    /// Currents at the end of the tick, A.
    pub current_a: [f64; NUM_JOINTS],
    /// Joint loads applied at the start of the tick (+q direction), N or N m.
    pub load: [f64; NUM_JOINTS],
    /// The actuator efforts tau = J^-T s_e that hold the tool, N or N m.
    pub tau: [f64; NUM_JOINTS],
}

/// The closed loop.
#[derive(Clone, Debug)]
pub struct Sim {
    robot: RsprGeometry<f64>,
    plant: Plant,
    /// The controller's planning half (supervisor), ticked by [`Sim::tick`]; a run may
    /// tick a copy of it on another thread and hand its plans to [`Sim::tick_with`].
    planner: Planner<f64, RsprGeometry<f64>>,
    /// The sensing (encoders, measured pose).
    sensing: Sensing<f64, RsprGeometry<f64>>,
    /// The controller's servo half (joint servos).
    drive: Drive<f64>,
    plant_dt: f64,
    steps_per_tick: u32,
    control_dt: f64,
    payload: Payload,
    payload_on: bool,
    payload_update: PayloadUpdate,
    /// "moved": remap beyond this motion of o_p, m, ...
    refresh_m: f64,
    /// ... or beyond this rotation, as |R - R_last|_F^2 = 4 (1 - cos angle).
    refresh_frobenius_sq: f64,
    /// The true pose of the last mapping (None: map at the next tick).
    mapped_at: Option<Pose<f64>>,
    fk_cfg: FkConfig<f64>,
    fk_one_step: FkConfig<f64>,
    true_pose: Pose<f64>,
    /// The true pose of the tick before (for the extrapolated FK guess).
    prev_true_pose: Pose<f64>,
    /// The joints and the solution of the last true pose (reused while the joints have
    /// not moved at all, e.g. held by friction).
    last_truth: Option<([f64; NUM_JOINTS], FkSolution<f64>)>,
    true_fk_failures: u64,
    enabled: bool,
    ticks: u64,
    load: [f64; NUM_JOINTS],
    tau: [f64; NUM_JOINTS],
    timing: Timing,
}

/// The wall-clock parts of a tick are timed on every this many ticks ([`Timing`]).
pub const TIMING_EVERY: u64 = 8;

/// Where the wall-clock time of the ticks went, s (timed on every [`TIMING_EVERY`]-th
/// tick and scaled up: an estimate).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Timing {
    /// The controller's servo half (encoders, FK, servo), s.
    pub controller_s: f64,
    /// The controller's planning half (supervisor with its guards) when [`Sim::tick`]
    /// runs it, s.
    pub planner_s: f64,
    /// The plant's steps (with the payload mapping of every step when
    /// `plant.payload_update` is "step"), s.
    pub plant_s: f64,
    /// The true pose (FK of the load-side joints) and the payload mapping, s.
    pub truth_s: f64,
    /// Of `truth_s`, the payload mapping (tau = J^-T s_e and the plant's loads), s.
    pub payload_s: f64,
}

fn arr(q: &Joints<f64>) -> [f64; NUM_JOINTS] {
    [q[0], q[1], q[2], q[3], q[4], q[5]]
}

/// The plant parameters: the file of `plant.config_file` (or the shipped one) with the
/// legs' backlash replaced by `plant.leg_backlash_mm`.
pub fn plant_config(cfg: &SimConfig) -> Result<PlantConfig, EngineError> {
    let path = &cfg.plant.config_file;
    let mut pc = if path.is_empty() {
        PlantConfig::shipped().map_err(EngineError::ShippedPlant)?
    } else {
        let text = std::fs::read_to_string(path).map_err(|source| EngineError::ReadPlantFile {
            path: path.clone(),
            source,
        })?;
        PlantConfig::from_toml_str(&text).map_err(|error| EngineError::PlantFile {
            path: path.clone(),
            error,
        })?
    };
    for p in pc.prismatic.iter_mut() {
        p.backlash_mm = cfg.plant.leg_backlash_mm;
    }
    pc.validate().map_err(EngineError::LegBacklash)?;
    Ok(pc)
}

/// The controller's settings: the defaults with the rate, the limits and the backlash
/// compensation of the configuration.
pub fn controller_config(
    cfg: &SimConfig,
    limits: &Limits<f64>,
    compensation: bool,
) -> ControllerConfig<f64> {
    let mut cc = ControllerConfig::<f64> {
        rate_hz: cfg.control.rate_hz,
        limits: *limits,
        ..ControllerConfig::default()
    };
    let width = cfg.control.compensated_leg_backlash_mm * 1e-3;
    if compensation && width > 0.0 {
        for p in cc.servo.backlash.joints.iter_mut().take(3) {
            p.width = width;
            if let BacklashRamp::DistanceOrTime { time, .. } = p.ramp {
                p.ramp = BacklashRamp::DistanceOrTime {
                    distance: width,
                    time,
                };
            }
        }
    } else if !compensation {
        cc.servo.backlash = BacklashConfig::off();
    } else {
        // Compensation on with a zero leg width: the links keep theirs.
        for p in cc.servo.backlash.joints.iter_mut().take(3) {
            p.enabled = false;
        }
    }
    cc
}

impl Sim {
    /// The robot homed and at rest at `start`, the controller holding it.
    pub fn new(
        robot: &RsprGeometry<f64>,
        limits: &Limits<f64>,
        cfg: &SimConfig,
        start: &Pose<f64>,
        compensation: bool,
    ) -> Result<Self, EngineError> {
        let pc = plant_config(cfg)?;
        let mut plant = Plant::new(&pc).map_err(EngineError::PlantConfig)?;
        let sol = inverse(robot, start, Branch::OUTER).map_err(EngineError::StartPose)?;
        let q0 = arr(&sol.q());
        plant.set_joint_positions(q0)?;
        let cc = controller_config(cfg, limits, compensation);
        let sensing = Sensing::homed_at(
            *robot,
            cc.branch,
            &cc.encoders,
            cc.fk,
            plant.encoder_counts(),
            &q0,
        )
        .map_err(EngineError::Sensing)?;
        let (planner, drive) = Controller::new(*robot, cc, sensing.measured())
            .map_err(EngineError::Controller)?
            .into_parts();
        // 0.1 nm and 1 nrad on the joints: far below anything reported. The same
        // acceptance test (inverse kinematics of the pose reproduces the joints within
        // these) holds on both paths of `true_fk`.
        let fk_cfg = FkConfig {
            tol_linear: 1e-10,
            tol_angular: 1e-9,
            ..FkConfig::default()
        };
        Ok(Sim {
            robot: *robot,
            plant,
            planner,
            sensing,
            drive,
            plant_dt: cfg.plant_dt(),
            steps_per_tick: cfg.control.plant_steps_per_tick,
            control_dt: cfg.control_dt(),
            payload: payload_from_config(cfg),
            payload_on: false,
            payload_update: cfg.plant.payload_update(),
            refresh_m: cfg.plant.payload_refresh_mm * 1e-3,
            refresh_frobenius_sq: 4.0 * (1.0 - cfg.plant.payload_refresh_deg.to_radians().cos()),
            mapped_at: None,
            fk_cfg,
            fk_one_step: FkConfig {
                max_iterations: 1,
                ..fk_cfg
            },
            true_pose: *start,
            prev_true_pose: *start,
            last_truth: None,
            true_fk_failures: 0,
            enabled: true,
            ticks: 0,
            load: [0.0; NUM_JOINTS],
            tau: [0.0; NUM_JOINTS],
            timing: Timing::default(),
        })
    }

    /// The plant (faults, statistics).
    pub fn plant(&self) -> &Plant {
        &self.plant
    }
    /// The plant, mutable (fault injection).
    pub fn plant_mut(&mut self) -> &mut Plant {
        &mut self.plant
    }
    /// The controller's planning half (as [`Sim::tick`] advances it).
    pub fn planner(&self) -> &Planner<f64, RsprGeometry<f64>> {
        &self.planner
    }
    /// The controller's servo half.
    pub fn drive(&self) -> &Drive<f64> {
        &self.drive
    }
    /// The sensing (encoders, measured pose, its counters).
    pub fn sensing(&self) -> &Sensing<f64, RsprGeometry<f64>> {
        &self.sensing
    }
    /// The tool the controller is told about when the payload is `on`.
    pub fn tool(&self, on: bool) -> Option<ToolLoad<f64>> {
        on.then_some(self.payload)
    }
    /// The control period, s.
    pub fn control_dt(&self) -> f64 {
        self.control_dt
    }
    /// Control ticks run so far.
    pub fn ticks(&self) -> u64 {
        self.ticks
    }
    /// Time of the next tick, s.
    pub fn time_s(&self) -> f64 {
        self.ticks as f64 * self.control_dt
    }
    /// Time of the next tick on the controller's microsecond clock.
    pub fn now_us(&self) -> u64 {
        (self.time_s() * 1e6).round() as u64
    }
    /// Forward-kinematics failures on the true joints (the last true pose is kept).
    pub fn true_fk_failures(&self) -> u64 {
        self.true_fk_failures
    }
    /// Wall-clock time spent so far, by part.
    pub fn timing(&self) -> Timing {
        self.timing
    }
    /// Whether the motor outputs are on.
    pub fn outputs_enabled(&self) -> bool {
        self.enabled
    }

    /// Whether the tool is attached.
    pub fn payload_on(&self) -> bool {
        self.payload_on
    }

    /// Attaches (or removes) the tool.
    pub fn set_payload(&mut self, on: bool) {
        self.payload_on = on;
        self.mapped_at = None;
        // The controller knows the tool it carries (it sets the lead screws' flank).
        self.planner.set_tool(self.tool(on));
        if !on {
            self.load = [0.0; NUM_JOINTS];
            self.tau = [0.0; NUM_JOINTS];
            let _ = self.plant.set_external_load(self.load);
        }
    }

    /// Hands a master target to the controller, stamped `stamp_us` on the controller clock.
    pub fn submit(
        &mut self,
        pose: &Pose<f64>,
        stamp_us: u64,
    ) -> Result<(), kinematics_core::supervisor::Refusal<f64>> {
        let now = self.now_us();
        self.planner.submit(pose, stamp_us, now)
    }

    /// The true pose: forward kinematics of the plant's load-side joints.
    ///
    /// Joints that have not moved at all since the last tick (held by friction) keep the
    /// last pose. Otherwise one damped Newton step (Jtilde dx = Js dq, kinematics-core
    /// `fk`) from the pose extrapolated at constant velocity over the last two ticks
    /// (t + (t - t_prev), R R_prev^T R): that guess is off by about a dt^2 (0.25 um at the
    /// supervisor's 250 mm/s^2), so the quadratically convergent step lands far inside the
    /// tolerance (0.1 nm, 1 nrad on the joints), which `forward` checks by the inverse
    /// kinematics of its result. Only when that check fails (a jolt: a fault, a load step)
    /// does the full iteration run, from the last true pose.
    fn true_fk(&mut self) -> Option<FkSolution<f64>> {
        let joints = self.plant.joint_positions();
        if let Some((q_last, sol)) = &self.last_truth {
            if *q_last == joints {
                self.prev_true_pose = self.true_pose;
                return Some(*sol);
            }
        }
        let q = Joints::from_row_slice(&joints);
        let (now, before) = (&self.true_pose, &self.prev_true_pose);
        let rotation = now.r * before.r.inverse() * now.r;
        // `displaced` by nothing re-orthonormalises the product (through a unit
        // quaternion), so rounding cannot build up in the extrapolation from tick to tick.
        let guess = Pose {
            t: now.t * 2.0 - before.t,
            r: rotation,
        }
        .displaced(&Vector3::zeros(), &Vector3::zeros());
        let fast = forward(&self.robot, &q, Branch::OUTER, &guess, &self.fk_one_step);
        let result = fast.or_else(|_| {
            forward(
                &self.robot,
                &q,
                Branch::OUTER,
                &self.true_pose,
                &self.fk_cfg,
            )
        });
        match result {
            Ok(sol) => {
                self.prev_true_pose = self.true_pose;
                self.true_pose = sol.pose;
                self.last_truth = Some((joints, sol));
                Some(sol)
            }
            Err(_) => {
                self.true_fk_failures += 1;
                self.last_truth = None;
                None
            }
        }
    }

    /// Whether the true pose `pose` is within the "moved" thresholds of the pose of the
    /// last mapping.
    fn near_last_mapping(&self, pose: &Pose<f64>) -> bool {
        let Some(at) = &self.mapped_at else {
            return false;
        };
        // |R - R_last|_F^2 = 4 (1 - cos angle) for the rotation between the two.
        let frobenius_sq = (pose.r.matrix() - at.r.matrix()).norm_squared();
        (pose.t - at.t).norm() <= self.refresh_m && frobenius_sq <= self.refresh_frobenius_sq
    }

    /// Sets the plant's joint loads to -tau, tau = J^-T s_e at the true pose `sol`
    /// (Eq. 7.10; J = Js^-1 Jtilde, Eq. 7.18). In "moved" mode only when the pose has
    /// moved beyond the thresholds since the last mapping.
    fn apply_payload(&mut self, sol: Option<&FkSolution<f64>>) -> Result<(), EngineError> {
        if !self.payload_on {
            return Ok(());
        }
        // Without a true pose (FK failed) the last loads stay.
        let Some(sol) = sol else { return Ok(()) };
        if self.payload_update == PayloadUpdate::Moved && self.near_last_mapping(&sol.pose) {
            return Ok(());
        }
        let se = self.payload.wrench(&sol.pose);
        let jac = jacobian(&self.robot, &sol.solution).map_err(EngineError::PayloadJacobian)?;
        // The LU of Jtilde^T refuses a singular configuration; the guards keep the
        // setpoint far from one, so the SVD of `actuator_forces` is not needed here.
        let st = forces_with_inv_cond(&jac, &se, 1.0, 0.0).map_err(EngineError::PayloadForces)?;
        self.tau = arr(&st.tau);
        self.load = self.tau.map(|t| -t);
        self.mapped_at = Some(sol.pose);
        Ok(self.plant.set_external_load(self.load)?)
    }

    /// One control tick: the truth at the tick, the payload, the controller's tick and
    /// the plant over one control period.
    pub fn tick(&mut self) -> Result<TickSample, EngineError> {
        self.tick_planned(None)
    }

    /// [`Sim::tick`] with the plan of a planner ticked elsewhere (a copy of
    /// [`Sim::planner`] advanced in step, e.g. on another thread); this Sim's own planner
    /// is left alone. The controller's halves are independent within a tick (the plan
    /// depends only on the targets), so the results are those of [`Sim::tick`].
    pub fn tick_with(&mut self, plan: &Plan<f64>) -> Result<TickSample, EngineError> {
        self.tick_planned(Some(plan))
    }

    fn tick_planned(&mut self, plan: Option<&Plan<f64>>) -> Result<TickSample, EngineError> {
        let t_s = self.time_s();
        // The parts are timed on every TIMING_EVERY-th tick only (each clock read costs
        // about as much as 2 % of a tick) and the times scaled up.
        let timed = self.ticks.is_multiple_of(TIMING_EVERY);
        let now = || timed.then(Instant::now);
        let t0 = now();
        let sol = self.true_fk();
        let true_q = self.plant.joint_positions();
        let true_pose = self.true_pose;
        let tp = now();
        self.apply_payload(sol.as_ref())?;
        let load = self.load;
        let tau = self.tau;
        let t1 = now();
        let mut io = PlantIo {
            plant: &mut self.plant,
            enabled: &mut self.enabled,
        };
        // The controller's tick (`Runtime::tick` while enabled): sense, plan, act.
        let measured = *self.sensing.update(&mut io);
        let (plan, planned_s) = match plan {
            Some(p) => (*p, 0.0),
            None => {
                let tp = now();
                let p = self.planner.tick();
                (p, tp.map_or(0.0, |tp| tp.elapsed().as_secs_f64()))
            }
        };
        let report = self.drive.act(&measured, &plan);
        self.sensing.set_backlash(&self.drive.backlash_offsets());
        report.apply(&mut io);
        let t2 = now();
        let duty = self.plant.duty();
        let mut peak = [0.0f64; NUM_JOINTS];
        for k in 0..self.steps_per_tick {
            if self.payload_update == PayloadUpdate::Step && self.payload_on && k > 0 {
                let sol = self.true_fk();
                self.apply_payload(sol.as_ref())?;
            }
            self.plant.step(self.plant_dt)?;
            // (Currents are finite: the plant's step is stable for every dt.)
            for (p, i) in peak.iter_mut().zip(self.plant.currents()) {
                if i.abs() > *p {
                    *p = i.abs();
                }
            }
        }
        let t3 = now();
        if let (Some(t0), Some(tp), Some(t1), Some(t2), Some(t3)) = (t0, tp, t1, t2, t3) {
            let k = TIMING_EVERY as f64;
            self.timing.truth_s += (t1 - t0).as_secs_f64() * k;
            self.timing.payload_s += (t1 - tp).as_secs_f64() * k;
            self.timing.controller_s += ((t2 - t1).as_secs_f64() - planned_s) * k;
            self.timing.planner_s += planned_s * k;
            self.timing.plant_s += (t3 - t2).as_secs_f64() * k;
        }
        self.ticks += 1;
        Ok(TickSample {
            t_s,
            setpoint: plan.setpoint,
            measured,
            report,
            true_q,
            true_pose,
            duty,
            peak_current_a: peak,
            current_a: self.plant.currents(),
            load,
            tau,
        })
    }
}
