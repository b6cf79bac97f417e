//! The runtime: the board application's one control object. It owns the sensing, the
//! state machine, the homing, the controller (while enabled), the heartbeat and target
//! clocks, and turns master requests ([`Runtime::command`]) and control ticks
//! ([`Runtime::tick`]) into outputs and a status.
//!
//! One tick, in every state:
//! ```text
//! sensing: counters -> extended counts -> joints -> measured pose (FK tracker, once homed)
//! heartbeat timers
//! Homing:  homing step (switches, currents, references) -> outputs
//! Enabled: planner (supervisor: target -> safe setpoint) -> drive (six PIDs) -> outputs
//! other:   outputs off
//! status:  from what the tick computed (no second evaluation)
//! ```

use hal::{CurrentSense, LimitSwitches, MotorOutputs, QuadratureCounter};
use kinematics_core::{Joints, Mechanism};
use master_link::{Faults, NackReason, StatusReport, Warnings};
use servo::NUM_JOINTS;

use crate::controller::{Controller, ControllerConfig, ControllerError, JogError, Scalar};
use crate::drive::TickReport;
use crate::heartbeat::{HeartbeatConfig, HeartbeatMonitor};
use crate::homing::{Homing, HomingConfig, HomingError, HomingSetupError, HomingStatus};
use crate::link::Command;
use crate::sensing::{Measured, Sensing};
use crate::state_machine::{Event, Refusal, State, StateMachine, Transition};
use crate::targets::{TargetClock, TargetClockConfig};
use crate::wire;

/// Everything the runtime needs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RuntimeConfig<S: Scalar> {
    /// The control application (and the sensing's encoder and FK settings).
    pub controller: ControllerConfig<S>,
    /// Homing.
    pub homing: HomingConfig<S>,
    /// Heartbeat hold / disable times.
    pub heartbeat: HeartbeatConfig,
    /// Master target timestamps.
    pub targets: TargetClockConfig,
    /// Consecutive forward-kinematics failures that latch `FORWARD_KINEMATICS`.
    pub fk_failures_to_fault: u32,
}

/// What one runtime tick did.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RuntimeTick<S: Scalar> {
    /// The state after the tick.
    pub state: State,
    /// The controller's report, when it ran.
    pub control: Option<TickReport<S>>,
    /// The homing status, when homing.
    pub homing: Option<HomingStatus>,
    /// Outputs were driven (else they were forced off).
    pub drives_on: bool,
}

/// The board application: the sensing, the state machine, the fail-safe timers, homing
/// and the controller, driven by [`Runtime::tick`] (every control period) and
/// [`Runtime::command`] (every master request).
#[derive(Clone, Debug)]
pub struct Runtime<S: Scalar, M: Mechanism<S> + Clone> {
    robot: M,
    cfg: RuntimeConfig<S>,
    sm: StateMachine,
    sensing: Sensing<S, M>,
    homing: Homing<S>,
    controller: Option<Controller<S, M>>,
    /// The jog stream in progress: (joint, time of the last Jog, the joints it aims at).
    jog: Option<(usize, u64, Joints<S>)>,
    heartbeat: HeartbeatMonitor,
    targets: TargetClock,
    warnings: Warnings,
    /// Worst tick jitter and execution time, µs (from the board).
    tick_timing: (u32, u32),
    estop_input: bool,
    was_holding: bool,
    outputs_on: bool,
}

impl<S: Scalar, M: Mechanism<S> + Clone> Runtime<S, M> {
    /// In `Boot`; call [`Runtime::boot_done`] once the hardware is up.
    pub fn new(robot: M, cfg: RuntimeConfig<S>, now_us: u64) -> Result<Self, HomingSetupError> {
        let homing = Homing::new(&cfg.homing, &cfg.controller.servo)?;
        let sensing = Sensing::new(
            robot.clone(),
            cfg.controller.branch,
            &cfg.controller.encoders,
            cfg.controller.fk,
        )
        .map_err(HomingSetupError::Servo)?;
        cfg.heartbeat
            .validate()
            .map_err(|_| HomingSetupError::Homing(HomingError::Config { joint: 0 }))?;
        Ok(Runtime {
            robot,
            sm: StateMachine::new(),
            sensing,
            homing,
            controller: None,
            jog: None,
            heartbeat: HeartbeatMonitor::new(cfg.heartbeat, now_us),
            targets: TargetClock::new(cfg.targets),
            warnings: Warnings::NOT_HOMED,
            tick_timing: (0, 0),
            estop_input: false,
            was_holding: false,
            outputs_on: false,
            cfg,
        })
    }

    /// The state machine.
    pub fn machine(&self) -> &StateMachine {
        &self.sm
    }
    /// The state.
    pub fn state(&self) -> State {
        self.sm.state()
    }
    /// The controller, while enabled.
    pub fn controller(&self) -> Option<&Controller<S, M>> {
        self.controller.as_ref()
    }
    /// The homing procedure.
    pub fn homing(&self) -> &Homing<S> {
        &self.homing
    }
    /// The heartbeat monitor.
    pub fn heartbeat(&self) -> &HeartbeatMonitor {
        &self.heartbeat
    }
    /// The sensing (encoders, measured pose, counters).
    pub fn sensing(&self) -> &Sensing<S, M> {
        &self.sensing
    }
    /// This tick's measurements.
    pub fn measured(&self) -> &Measured<S> {
        self.sensing.measured()
    }
    /// The robot.
    pub fn robot(&self) -> &M {
        &self.robot
    }
    /// The configuration.
    pub fn config(&self) -> &RuntimeConfig<S> {
        &self.cfg
    }

    /// Applies an event and its side effects (controller, homing, heartbeat, sensing).
    pub fn event(&mut self, ev: Event, now_us: u64) -> Result<Transition, Refusal> {
        // Building the controller may refuse the enable (no pose, unsafe start pose).
        if ev == Event::Enable && self.sm.state() == State::Ready {
            match Controller::new(
                self.robot.clone(),
                self.cfg.controller,
                self.sensing.measured(),
            ) {
                Ok(c) => self.controller = Some(c),
                Err(ControllerError::NoPose | ControllerError::Supervisor(_)) => {
                    return Err(Refusal::UnsafeStart)
                }
                Err(_) => {
                    let _ = self.sm.handle(Event::Fault(Faults::INTERNAL));
                    return Err(Refusal::NotAllowed);
                }
            }
        }
        let t = self.sm.handle(ev)?;
        if t.changed() {
            if t.to == State::Enabled {
                self.heartbeat.rearm(now_us);
                self.targets.reset();
                self.was_holding = false;
            }
            if t.to == State::Homing {
                // The master just spoke: the heartbeat timing restarts.
                self.heartbeat.rearm(now_us);
                self.homing.start(
                    &self.sensing.measured().q,
                    &self.sensing.encoders().counts(),
                    now_us,
                );
            }
            if t.from == State::Homing && t.to != State::Ready {
                self.homing.abort();
            }
        }
        if !self.sm.homed() {
            self.sensing.lose_reference();
        }
        if t.to != State::Enabled {
            self.controller = None;
            self.jog = None;
        }
        Ok(t)
    }

    /// The e-stop input level (asserted = pressed or wire broken), sampled every tick;
    /// while asserted the robot is in `Fault` and `ClearFault` is refused.
    pub fn set_estop_input(&mut self, asserted: bool, now_us: u64) {
        self.estop_input = asserted;
        if asserted && !self.sm.faults().contains(Faults::EMERGENCY_STOP) {
            let _ = self.event(Event::EmergencyStop, now_us);
        }
    }

    /// Power-up done: the encoders' current counters become the (unhomed) reference.
    pub fn boot_done(
        &mut self,
        raw: [u16; NUM_JOINTS],
        now_us: u64,
    ) -> Result<Transition, Refusal> {
        self.sensing.boot(raw);
        self.event(Event::BootDone, now_us)
    }

    /// A master request (after the link layer): `Ok` to Ack, `Err` to Nack with.
    pub fn command(&mut self, cmd: &Command, now_us: u64) -> Result<(), NackReason> {
        let ev = match *cmd {
            Command::Enable => Event::Enable,
            Command::Disable => Event::Disable,
            Command::Home => Event::Home,
            Command::Clutch { engaged } => Event::Clutch { engaged },
            Command::EmergencyStop => Event::EmergencyStop,
            Command::ClearFault => Event::ClearFault {
                cause_active: self.estop_input,
            },
            Command::Heartbeat => {
                if let Some(ev) = self.heartbeat.beat(now_us) {
                    let _ = self.event(ev, now_us);
                }
                return Ok(());
            }
            Command::StatusRequest => return Ok(()),
            Command::Jog { joint, velocity } => return self.jog(joint, velocity, now_us),
            Command::Target {
                stamp_us,
                position_m,
                rotation_vector_rad,
            } => return self.target(stamp_us, position_m, rotation_vector_rad, now_us),
        };
        let cleared = matches!(ev, Event::ClearFault { .. }) && self.sm.state() == State::Fault;
        self.event(ev, now_us).map_err(NackReason::from)?;
        if cleared {
            self.warnings.remove(Warnings::HEARTBEAT_LATE);
        }
        Ok(())
    }

    /// Jog: while following (Enabled, not clutched), move joint `joint` at `velocity`
    /// (m/s or rad/s). The joint's target advances by velocity × the time since the last
    /// Jog of the same stream, and never leads the setpoint by more than velocity ×
    /// JOG_HORIZON_S: the master's repeated Jog is a dead-man, and when Jogs stop the robot
    /// stops within that horizon. The target passes the supervisor like any other (speed
    /// limits, path check, guards).
    fn jog(&mut self, joint: u8, velocity: f32, now_us: u64) -> Result<(), NackReason> {
        let j = usize::from(joint);
        if j >= NUM_JOINTS {
            return Err(NackReason::InvalidJoint);
        }
        if !velocity.is_finite() {
            return Err(NackReason::InvalidValue);
        }
        self.sm.target_gate().map_err(NackReason::from)?;
        let ctl = self.controller.as_mut().ok_or(NackReason::InvalidState)?;
        let setpoint = ctl.setpoint_joints().map_err(jog_reason)?;
        let horizon_us = (JOG_HORIZON_S * 1e6) as u64;
        // The other joints stay where the stream started, the jogged one advances.
        let (mut target, elapsed_us) = match self.jog {
            Some((jj, last, q)) if jj == j && now_us.saturating_sub(last) <= horizon_us => {
                (q, now_us.saturating_sub(last))
            }
            _ => (setpoint, horizon_us),
        };
        let here = setpoint.get(j).copied().ok_or(NackReason::InvalidJoint)?;
        let lit = kinematics_core::scalar::lit::<S>;
        let lead = lit(f64::from(velocity).abs() * JOG_HORIZON_S);
        let slot = target.get_mut(j).ok_or(NackReason::InvalidJoint)?;
        let advanced = *slot + lit(f64::from(velocity)) * lit(elapsed_us as f64 * 1e-6);
        *slot = num_traits::Float::min(num_traits::Float::max(advanced, here - lead), here + lead);
        let pose = ctl.joints_target(&target).map_err(jog_reason)?;
        let stamp = self.targets.board_stamp(now_us);
        ctl.submit(&pose, stamp, now_us)
            .map_err(|r| wire::refusal_reason(&r))?;
        self.jog = Some((j, now_us, target));
        Ok(())
    }

    fn target(
        &mut self,
        stamp_us: u64,
        position_m: [f32; 3],
        rotation_vector_rad: [f32; 3],
        now_us: u64,
    ) -> Result<(), NackReason> {
        let pose = wire::pose_from_wire::<S>(position_m, rotation_vector_rad)?;
        self.sm.target_gate().map_err(NackReason::from)?;
        let ctl = self.controller.as_mut().ok_or(NackReason::InvalidState)?;
        let board_stamp = self.targets.accept(stamp_us, now_us)?;
        ctl.submit(&pose, board_stamp, now_us)
            .map_err(|r| wire::refusal_reason(&r))?;
        // A Cartesian target ends any jog stream.
        self.jog = None;
        Ok(())
    }

    /// One control tick: the sensing first (every state), the fail-safe timers, then
    /// homing or the controller, and the outputs (forced off in every state but `Homing`
    /// and `Enabled`).
    pub fn tick<H>(&mut self, hw: &mut H, now_us: u64) -> RuntimeTick<S>
    where
        H: QuadratureCounter + MotorOutputs<S> + LimitSwitches + CurrentSense<S>,
    {
        // The sampling instant does not move with the work that follows.
        self.sensing.update(hw);
        if let Some(ev) = self.heartbeat.poll(now_us) {
            let _ = self.event(ev, now_us);
        }
        let mut control = None;
        let mut homing = None;
        if self.sm.drives_on() && !self.outputs_on {
            hw.enable();
            self.outputs_on = true;
        }
        match self.sm.state() {
            State::Homing => {
                let st = self.homing.step(hw, &mut self.sensing, now_us);
                homing = Some(st);
                match st {
                    HomingStatus::Done => {
                        // The references make a pose, or the homing failed.
                        let ev = match self.sensing.track_pose() {
                            Ok(_) => Event::HomingDone,
                            Err(_) => Event::HomingFailed,
                        };
                        let _ = self.event(ev, now_us);
                    }
                    HomingStatus::Failed(_) => {
                        let _ = self.event(Event::HomingFailed, now_us);
                    }
                    HomingStatus::Running(_) => {}
                }
            }
            State::Enabled => control = self.control_tick(hw, now_us),
            _ => {}
        }
        let drives_on = self.sm.drives_on();
        if !drives_on {
            hw.disable();
            self.outputs_on = false;
        }
        self.update_warnings(now_us);
        RuntimeTick {
            state: self.sm.state(),
            control,
            homing,
            drives_on,
        }
    }

    fn control_tick<H>(&mut self, hw: &mut H, now_us: u64) -> Option<TickReport<S>>
    where
        H: MotorOutputs<S>,
    {
        // Brake to a stop when a hold starts.
        let holding = self.sm.hold().is_some();
        if holding && !self.was_holding {
            if let Some(ctl) = self.controller.as_mut() {
                ctl.hold();
            }
        }
        self.was_holding = holding;
        let Some(ctl) = self.controller.as_mut() else {
            let _ = self.event(Event::Fault(Faults::INTERNAL), now_us);
            return None;
        };
        let report = ctl.tick(self.sensing.measured(), hw);
        let fk_failures_in_row = self.sensing.counters().fk_failures_in_row;
        if report.servo.fault.is_some() {
            let _ = self.event(Event::TrackingFault, now_us);
        } else if let Some(stop) = report.stop {
            let _ = self.event(Event::Fault(wire::guard_fault(stop.guard)), now_us);
        } else if fk_failures_in_row >= self.cfg.fk_failures_to_fault {
            let _ = self.event(Event::Fault(Faults::FORWARD_KINEMATICS), now_us);
        }
        Some(report)
    }

    fn update_warnings(&mut self, now_us: u64) {
        let w = &mut self.warnings;
        w.set(Warnings::NOT_HOMED, !self.sm.homed());
        w.set(
            Warnings::HEARTBEAT_LATE,
            self.sm.state() == State::Enabled && self.heartbeat.is_late(now_us),
        );
    }

    /// Records the control tick's worst start jitter and execution time (µs), measured by
    /// the board (DWT cycle counter), for the status report.
    pub fn set_tick_timing(&mut self, worst_jitter_us: u32, worst_exec_us: u32) {
        self.tick_timing = (worst_jitter_us, worst_exec_us);
    }

    /// Sets or clears extra warnings (e.g. `CYCLE_OVERRUN` from the board).
    pub fn set_warning(&mut self, w: Warnings, on: bool) {
        self.warnings.set(w, on);
    }

    /// The status report of the last tick: the measured pose and joints (NaN until
    /// homed), the singularity margins the supervisor measured near its setpoint (NaN
    /// while it does not run) with their warnings, faults, warnings and timing. The link
    /// counters are added as it goes out ([`crate::telemetry::with_link`]).
    pub fn status(&self) -> StatusReport {
        let m = self.sensing.measured();
        let nan3 = [f32::NAN; 3];
        let (position_m, rotation_vector_rad) =
            m.pose.map_or((nan3, nan3), |p| wire::pose_to_wire(&p));
        let mut joints = [0f32; NUM_JOINTS];
        for (o, q) in joints.iter_mut().zip(m.q.iter()) {
            *o = wire::to_f32(*q);
        }
        let mut warnings = self.warnings;
        let (mut serial, mut parallel) = (f32::NAN, f32::NAN);
        let mut refused = 0;
        if let Some(c) = self.controller.as_ref() {
            let sup = c.supervisor();
            let (margins, limits) = (sup.margins(), sup.guards().limits());
            serial = wire::to_f32(margins.serial);
            parallel = wire::to_f32(margins.parallel);
            warnings.set(
                Warnings::NEAR_SERIAL_SINGULARITY,
                margins.serial < limits.serial.warn,
            );
            warnings.set(
                Warnings::NEAR_PARALLEL_SINGULARITY,
                margins.parallel < limits.parallel.warn,
            );
            refused = sup.counters().refused();
        }
        StatusReport {
            state: self.sm.state(),
            position_m,
            rotation_vector_rad,
            joints,
            warnings,
            faults: self.sm.faults(),
            serial_singularity_margin: serial,
            parallel_singularity_margin: parallel,
            link: Default::default(),
            tick_jitter_max_us: self.tick_timing.0,
            tick_exec_max_us: self.tick_timing.1,
            targets_refused: refused,
        }
    }
}

fn jog_reason(e: JogError) -> NackReason {
    match e {
        JogError::NonFinite => NackReason::InvalidValue,
        JogError::NoSolution => NackReason::OutOfWorkspace,
    }
}

/// How far ahead of the setpoint a Jog aims at most, s: the dead-man time of a jog stream.
pub const JOG_HORIZON_S: f64 = 0.1;

/// The default configuration of `robot` assembled on `branch`: [`reference_config`] with
/// the robot's central configuration (its inverse kinematics at the central pose).
pub fn reference_config_for<S: Scalar, M: Mechanism<S>>(
    robot: &M,
    branch: kinematics_core::Branch,
) -> Result<RuntimeConfig<S>, kinematics_core::IkError> {
    let central =
        kinematics_core::inverse(robot, &kinematics_core::Pose::central(robot.hc()), branch)?;
    let mut cfg = reference_config(crate::drive::to_array(&central.q()));
    cfg.controller.branch = branch;
    Ok(cfg)
}

/// A default configuration for the reference robot: homing placeholders parking at the
/// central configuration `central_q`.
pub fn reference_config<S: Scalar>(central_q: [S; NUM_JOINTS]) -> RuntimeConfig<S> {
    let [_, _, _, t1, t2, t3] = central_q;
    RuntimeConfig {
        controller: ControllerConfig::default(),
        homing: HomingConfig::reference([t1, t2, t3], Some(central_q)),
        heartbeat: HeartbeatConfig::default(),
        targets: TargetClockConfig::default(),
        fk_failures_to_fault: 10,
    }
}
