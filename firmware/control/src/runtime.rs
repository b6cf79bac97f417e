//! The runtime: the board application's one control object. It owns the sensing, the
//! monitors, the state machine, the stop sequencer, the homing, the controller, the
//! heartbeat and target clocks and the fault log, and turns master requests
//! ([`Runtime::command`]) and control ticks ([`Runtime::tick`]) into outputs and a status.
//!
//! One tick, in every state:
//! ```text
//! sensing   counters -> extended counts -> motors -> joints (less the servo's backlash
//!           offsets) -> measured pose (FK tracker, once homed)
//! inputs    currents, supply, driver fault, switches, e-stop button, safety relay
//! monitors  safety chain, power stage, currents (overcurrent, overload, I²t), encoders
//!           (jump, dead), joint ranges and limit switches, standstill of a hold,
//!           heartbeat: each finding is a fault with its cause, joint and value
//! stops     the fault's (or a hold's) reaction from the stop table: STO, SS1 or SS2
//! drive     Homing:   homing step (switches, currents, references), then the park move
//!           Enabling: the brake check against the closed brakes, then the release
//!           Enabled:  planner (supervisor) -> drive (six PIDs; its backlash offsets
//!                     go back to the sensing for the next tick)
//!           stops:    the supervisor brakes; the servo holds
//! outputs   duties capped by the current limit -> PWM; brakes; torque off
//! status    from what the tick computed (no second evaluation)
//! ```

use hal::Hardware;
use kinematics_core::{Branch, Joints, Mechanism, Pose};
use master_link::{
    FaultCause, FaultLogPage, FaultRecord, GuardMargins, NackReason, ResetCause, ResetStatus,
    StatusReport, Warnings,
};
use num_traits::Float;
use servo::NUM_JOINTS;

use crate::brakes::{BrakeCheck, BrakeCheckConfig, EnableStep};
use crate::controller::{Controller, ControllerConfig, ControllerError, JogError, Scalar};
use crate::current::{CurrentConfig, CurrentFault, CurrentMonitor};
use crate::drive::{to_array, TickReport};
use crate::faults::FaultLog;
use crate::heartbeat::{HeartbeatConfig, HeartbeatMonitor};
use crate::homing::{Homing, HomingConfig, HomingError, HomingSetupError, HomingStatus, Mechanics};
use crate::link::{Answer, Command};
use crate::monitors::{
    check_ranges, DriveSample, EncoderCheck, EncoderCheckConfig, Finding, MotorCheck, PowerCheck,
    PowerConfig, SafetyChainCheck, Standstill,
};
use crate::park::{ParkConfig, ParkMove, ParkRefusal, ParkStep};
use crate::sensing::{Measured, Sensing};
use crate::state_machine::{Event, Refusal, State, StateMachine, Transition};
use crate::stops::{StopConfig, StopEvent, StopPhase, Stopper};
use crate::targets::{TargetClock, TargetClockConfig};
use crate::wire;

/// Everything the runtime needs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RuntimeConfig<S: Scalar> {
    /// The control application (and the sensing's encoder and FK settings).
    pub controller: ControllerConfig<S>,
    /// Homing.
    pub homing: HomingConfig<S>,
    /// The board's mechanics (joint ranges).
    pub mechanics: Mechanics<S>,
    /// Heartbeat hold / disable times.
    pub heartbeat: HeartbeatConfig,
    /// Master target timestamps.
    pub targets: TargetClockConfig,
    /// Consecutive forward-kinematics failures that latch `FORWARD_KINEMATICS`.
    pub fk_failures_to_fault: u32,
    /// The stops' timing.
    pub stops: StopConfig,
    /// The brake check and release at enable.
    pub brakes: BrakeCheckConfig<S>,
    /// Motor currents: limits, I²t, trips.
    pub current: CurrentConfig<S>,
    /// Encoder plausibility.
    pub encoder_check: EncoderCheckConfig<S>,
    /// The power stage's supply range.
    pub power: PowerConfig<S>,
    /// Ticks the e-stop button and the safety relay may disagree (the relay's switching).
    pub relay_debounce_ticks: u16,
    /// The park move after homing (speeds, path check, settling).
    pub park: ParkConfig<S>,
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
    /// The drives produced torque.
    pub drives_on: bool,
}

/// The inputs read at the start of a tick.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Inputs<S> {
    /// Motor currents, A.
    pub currents: [S; NUM_JOINTS],
    /// Supply voltage, V.
    pub supply_v: S,
    /// A driver reports a fault.
    pub driver_fault: bool,
    /// Limit switches.
    pub switches: [bool; NUM_JOINTS],
    /// The e-stop button is pressed.
    pub estop_pressed: bool,
    /// The safety relay is open.
    pub relay_open: bool,
}

/// Encoder counts a holding servo may stand off its setpoint on each joint: a count
/// either side (see `Runtime::held_start`).
const HOLD_COUNTS: f64 = 2.0;

/// The board application: the sensing, the monitors, the state machine, the stops, the
/// fail-safe timers, homing and the controller, driven by [`Runtime::tick`] (every control
/// period) and [`Runtime::command`] (every master request).
#[derive(Clone, Debug)]
pub struct Runtime<S: Scalar, M: Mechanism<S> + Clone> {
    robot: M,
    cfg: RuntimeConfig<S>,
    dt: S,
    sm: StateMachine,
    sensing: Sensing<S, M>,
    homing: Homing<S>,
    parking: Option<ParkMove<S, M>>,
    controller: Option<Controller<S, M>>,
    /// The setpoint the last controller held when its stop completed (pose and joints),
    /// while the reference it was measured in stands: an enable may start from it (see
    /// `held_start`).
    held: Option<(Pose<S>, [S; NUM_JOINTS])>,
    enabling: Option<BrakeCheck<S>>,
    stopper: Stopper,
    standstill: Standstill<S>,
    current: CurrentMonitor<S>,
    encoder_check: EncoderCheck<S>,
    motor_check: MotorCheck<S>,
    power: PowerCheck<S>,
    chain: SafetyChainCheck,
    /// The jog stream in progress: (joint, time of the last Jog, the joints it aims at).
    jog: Option<(usize, u64, Joints<S>)>,
    heartbeat: HeartbeatMonitor,
    targets: TargetClock,
    warnings: Warnings,
    /// The latched fault (the first one since the last clear).
    fault: FaultRecord,
    /// The last fault handled: cause, joint, time (a repeat within the tick is one).
    last_fault: Option<(FaultCause, u8, u64)>,
    /// The causes raised since the fault was latched (bit = index in `FaultCause::ALL`).
    raised: u32,
    log: FaultLog,
    reset: ResetStatus,
    inputs: Inputs<S>,
    /// The duties applied over the last tick (the back-EMF check).
    last_duty: [S; NUM_JOINTS],
    torque_on: bool,
    outputs_on: bool,
    /// The brakes' release as last written, and when they were last applied (µs; the
    /// brake check waits for their engage time).
    brakes_out: bool,
    brakes_applied_at_us: Option<u64>,
    /// Worst tick jitter and execution time, µs (from the board).
    tick_timing: (u32, u32),
    missed_ticks: u32,
    /// The stored calibrated geometry's version (0: none), for `HelloReply`.
    geometry_version: u32,
}

fn lit<S: Scalar>(x: f64) -> S {
    kinematics_core::scalar::lit(x)
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
        let rate = cfg.controller.rate_hz;
        if !(rate >= lit(100.0) && rate <= lit(10_000.0)) {
            return Err(HomingSetupError::Homing(HomingError::Config { joint: 0 }));
        }
        Ok(Runtime {
            robot,
            dt: S::one() / rate,
            sm: StateMachine::new(),
            sensing,
            homing,
            parking: None,
            controller: None,
            held: None,
            enabling: None,
            stopper: Stopper::new(cfg.stops),
            standstill: Standstill::reference(),
            current: CurrentMonitor::new(cfg.current),
            encoder_check: EncoderCheck::new(cfg.encoder_check),
            motor_check: MotorCheck::new(&cfg.current.motors),
            power: PowerCheck::new(cfg.power),
            chain: SafetyChainCheck::new(cfg.relay_debounce_ticks),
            jog: None,
            heartbeat: HeartbeatMonitor::new(cfg.heartbeat, now_us),
            targets: TargetClock::new(cfg.targets),
            warnings: Warnings::NOT_HOMED,
            fault: FaultRecord::NONE,
            last_fault: None,
            raised: 0,
            log: FaultLog::new(),
            reset: ResetStatus {
                cause: ResetCause::PowerOn,
                acknowledged: true,
            },
            inputs: Inputs {
                currents: [S::zero(); NUM_JOINTS],
                supply_v: S::zero(),
                driver_fault: false,
                switches: [false; NUM_JOINTS],
                estop_pressed: false,
                relay_open: false,
            },
            last_duty: [S::zero(); NUM_JOINTS],
            torque_on: false,
            outputs_on: false,
            brakes_out: false,
            brakes_applied_at_us: None,
            tick_timing: (0, 0),
            missed_ticks: 0,
            geometry_version: 0,
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
    /// The controller, while it exists (from the park move after homing; while enabled or
    /// stopping).
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
    /// The inputs read at the start of the last tick.
    pub fn inputs(&self) -> &Inputs<S> {
        &self.inputs
    }
    /// The stop sequencer.
    pub fn stopper(&self) -> &Stopper {
        &self.stopper
    }
    /// The current monitor (peaks, heat).
    pub fn current(&self) -> &CurrentMonitor<S> {
        &self.current
    }
    /// The latched fault.
    pub fn latched_fault(&self) -> &FaultRecord {
        &self.fault
    }
    /// The fault log.
    pub fn fault_log(&self) -> &FaultLog {
        &self.log
    }
    /// The last reset and its acknowledgement.
    pub fn reset(&self) -> ResetStatus {
        self.reset
    }
    /// The stored calibrated geometry's version (0: none), reported in `HelloReply`.
    pub fn geometry_version(&self) -> u32 {
        self.geometry_version
    }
    /// Records the version of the calibrated geometry the board holds in flash (at boot,
    /// and after a store).
    pub fn set_geometry_version(&mut self, version: u32) {
        self.geometry_version = version;
    }

    /// A received calibrated geometry (`StoreGeometry`): taken only with the drives off
    /// (`Disabled`, `Ready`), checked against this robot's nominal dimensions (e, rb = the
    /// length scale, rp, hc: an RSPR) and branch (`geometry_store::check`). Its version
    /// when it may be stored; the target writes it to flash outside the control tick.
    pub fn check_geometry(
        &self,
        record: &master_link::GeometryRecord,
    ) -> Result<u32, master_link::GeometryRefusal> {
        if !matches!(self.sm.state(), State::Disabled | State::Ready) {
            return Err(master_link::GeometryRefusal::InvalidState);
        }
        let nominal = kinematics_core::RsprGeometry {
            e: self.robot.e(),
            rb: self.robot.length_scale(),
            rp: self.robot.rp(),
            hc: self.robot.hc(),
        };
        crate::geometry_store::check(
            record,
            &nominal,
            self.cfg.controller.branch,
            &crate::geometry_store::Plausible::default(),
        )
        .map(|_| record.version)
    }
    /// The robot.
    pub fn robot(&self) -> &M {
        &self.robot
    }
    /// The configuration.
    pub fn config(&self) -> &RuntimeConfig<S> {
        &self.cfg
    }

    /// Power-up done: the encoders' current counters become the (unhomed) reference; the
    /// reset cause the board read; the fault log kept across the reset, if any.
    pub fn boot_done(
        &mut self,
        raw: [u16; NUM_JOINTS],
        now_us: u64,
        reset: ResetCause,
        log: Option<FaultLog>,
    ) -> Result<Transition, Refusal> {
        self.sensing.boot(raw);
        self.reset = ResetStatus {
            cause: reset,
            acknowledged: !reset.needs_acknowledgement(),
        };
        if let Some(log) = log {
            self.log = log;
        }
        self.event(Event::BootDone, now_us)
    }

    /// Latches a fault (the first since the last clear is the one reported), logs it, and
    /// starts the stop the table names for it.
    pub fn fault(&mut self, finding: Finding, now_us: u64) {
        let record = finding.record(now_us);
        let already = self.sm.state() == State::Fault;
        // The same fault twice in one tick (an `EmergencyStop` message both latched and
        // queued) is one.
        if already && self.last_fault == Some((finding.cause, record.joint, now_us)) {
            return;
        }
        self.last_fault = Some((finding.cause, record.joint, now_us));
        if self.sm.handle(Event::Fault(finding.cause)).is_err() {
            return;
        }
        // (A heartbeat loss while nothing moves is no fault: the state did not change.)
        if self.sm.state() != State::Fault {
            return;
        }
        if !already {
            self.fault = record;
            self.raised = 0;
        }
        self.raised |= 1u32 << cause_index(finding.cause);
        self.stopper
            .request(StopEvent::Fault(finding.cause), now_us, self.torque_on);
        self.start_decelerating();
        self.log.record(record, self.stopper.status());
        self.enabling = None;
        self.parking = None;
        self.jog = None;
        if self.sm.state() == State::Fault && !self.sm.homed() {
            self.sensing.lose_reference();
            self.held = None;
        }
    }

    /// The fault of a missed control deadline (from the board's tick service).
    pub fn deadline_missed(&mut self, late_us: u64, now_us: u64) {
        let late = S::from(late_us).unwrap_or_else(S::infinity);
        self.fault(Finding::board(FaultCause::DeadlineMissed, late), now_us);
    }

    /// Applies an event and its side effects (controller, homing, heartbeat, stops).
    pub fn event(&mut self, ev: Event, now_us: u64) -> Result<Transition, Refusal> {
        if let Event::Fault(cause) = ev {
            self.fault(Finding::board::<S>(cause, S::zero()), now_us);
            return Ok(Transition {
                from: self.sm.state(),
                to: self.sm.state(),
                event: ev,
            });
        }
        if ev == Event::Enable && self.sm.state() == State::Ready {
            self.prepare_enable(now_us)?;
        }
        // A homed robot homed again: its joints are known, the travel windows start there.
        let known = self.sm.homed().then_some(self.sensing.measured().q);
        let t = self.sm.handle(ev)?;
        if t.changed() {
            match t.to {
                State::Enabling => {
                    self.heartbeat.rearm(now_us);
                    self.targets.reset();
                }
                State::Homing => {
                    // The master just spoke: the heartbeat timing restarts.
                    self.heartbeat.rearm(now_us);
                    self.sensing.lose_reference();
                    self.held = None;
                    self.controller = None;
                    self.stopper.clear();
                    self.homing.start(
                        &self.sensing.measured().q,
                        &self.sensing.measured().motor,
                        &self.sensing.encoders().counts(),
                        known.as_ref(),
                        now_us,
                    );
                }
                _ => {}
            }
            if t.from == State::Homing && t.to != State::Ready {
                self.homing.abort();
                self.parking = None;
            }
            // Drives off on request: SS1 (decelerate, brakes, torque off).
            if matches!(t.to, State::Ready | State::Disabled)
                && matches!(
                    t.from,
                    State::Enabling | State::Enabled | State::Homing | State::Fault
                )
            {
                self.stopper
                    .request(StopEvent::Disable, now_us, self.torque_on);
                self.start_decelerating();
                self.enabling = None;
            }
        }
        if !self.sm.homed() {
            self.sensing.lose_reference();
            self.held = None;
        }
        self.update_holds(now_us);
        Ok(t)
    }

    /// The checks before an enable and its start: the reset acknowledged, the safety chain
    /// sound, no stop still in progress, the controller at the measured pose, the brake
    /// check started.
    fn prepare_enable(&mut self, now_us: u64) -> Result<(), Refusal> {
        if !self.reset.acknowledged {
            return Err(Refusal::ResetNotAcknowledged);
        }
        if self.inputs.estop_pressed {
            return Err(Refusal::FaultStillActive);
        }
        if !SafetyChainCheck::agrees(self.inputs.estop_pressed, self.inputs.relay_open) {
            return Err(Refusal::SafetyRelayMismatch);
        }
        match self.stopper.phase() {
            StopPhase::Running | StopPhase::TorqueOff { .. } => {}
            _ => return Err(Refusal::Busy),
        }
        let measured = *self.sensing.measured();
        let mut built = Controller::new(self.robot.clone(), self.cfg.controller, &measured);
        if matches!(built, Err(ControllerError::Supervisor(_))) {
            if let Some(pose) = self.held_start(&measured.q) {
                built = Controller::starting_at(
                    self.robot.clone(),
                    self.cfg.controller,
                    &measured,
                    &pose,
                );
            }
        }
        match built {
            Ok(c) => self.controller = Some(c),
            Err(ControllerError::NoPose | ControllerError::Supervisor(_)) => {
                return Err(Refusal::UnsafeStart)
            }
            Err(_) => return Err(Refusal::NotAllowed),
        }
        self.stopper.clear();
        self.standstill.stop();
        self.current.reset_overload();
        self.enabling = Some(BrakeCheck::start(
            self.cfg.brakes,
            &self.sensing.measured().q,
            now_us,
            self.brakes_applied_at_us,
        ));
        Ok(())
    }

    /// Where an enable whose measured pose the supervisor refuses may start instead: the
    /// setpoint the last controller held, when the measured joints stand within
    /// `HOLD_COUNTS` encoder counts of its joints. A robot stopped at a limit (the
    /// workspace edge) holds there to within the servo's counts, and its measured pose may
    /// stand a count beyond the limit its setpoint keeps to: it is where the supervisor
    /// left it, not a robot moved out of its workspace, and it must be possible to enable
    /// it again (or it is stuck until re-homed). Further off, the start is refused.
    fn held_start(&self, q: &[S; NUM_JOINTS]) -> Option<Pose<S>> {
        let (pose, held_q) = self.held.as_ref()?;
        let cpu = &self.cfg.controller.encoders.counts_per_unit;
        let band: S = lit(HOLD_COUNTS);
        let near = (0..NUM_JOINTS).all(|j| match (q.get(j), held_q.get(j), cpu.get(j)) {
            (Some(a), Some(b), Some(c)) if *c > S::zero() => Float::abs(*a - *b) <= band / *c,
            _ => false,
        });
        near.then_some(*pose)
    }

    /// The supervisor brakes at the start of a deceleration (and refuses targets).
    fn start_decelerating(&mut self) {
        if self.stopper.outputs(true).decelerate {
            if let Some(ctl) = self.controller.as_mut() {
                ctl.hold();
            }
            self.jog = None;
        }
    }

    /// Starts or ends the holds (clutch, operator absent, heartbeat late) as stops SS2
    /// without a fault.
    fn update_holds(&mut self, now_us: u64) {
        let hold = self.sm.hold();
        let hold_event = self.stopper.event().filter(|e| {
            matches!(
                e,
                StopEvent::ClutchEngaged | StopEvent::OperatorAbsent | StopEvent::HeartbeatLate
            )
        });
        match (hold, hold_event) {
            (Some(h), None) if self.sm.state() == State::Enabled => {
                let event = if h.clutch {
                    StopEvent::ClutchEngaged
                } else if h.operator_absent {
                    StopEvent::OperatorAbsent
                } else {
                    StopEvent::HeartbeatLate
                };
                self.stopper.request(event, now_us, self.torque_on);
                self.start_decelerating();
            }
            (None, Some(_)) if self.sm.state() == State::Enabled => {
                // The hold is over: follow again from where the robot stands.
                self.stopper.clear();
                self.standstill.stop();
            }
            _ => {}
        }
    }

    /// A master request (after the link layer): the answer, or why it is refused.
    pub fn command(&mut self, cmd: &Command, now_us: u64) -> Result<Answer, NackReason> {
        let ev = match *cmd {
            Command::Hello { session } => {
                // A new master: its predecessor's clutch and dead-man no longer hold.
                self.sm.new_master();
                self.update_holds(now_us);
                return Ok(Answer::Hello {
                    session,
                    reset: self.reset,
                    geometry_version: self.geometry_version,
                });
            }
            Command::Enable => Event::Enable,
            Command::Disable => Event::Disable,
            Command::Home { rehome } => Event::Home { rehome },
            Command::Clutch { engaged } => Event::Clutch { engaged },
            Command::OperatorPresent { present } => Event::OperatorPresent { present },
            Command::EmergencyStop => {
                self.fault(
                    Finding::board::<S>(FaultCause::EmergencyStopMessage, S::zero()),
                    now_us,
                );
                return Ok(Answer::Ack);
            }
            Command::ClearFault => Event::ClearFault {
                cause_active: self.inputs.estop_pressed
                    || !SafetyChainCheck::agrees(self.inputs.estop_pressed, self.inputs.relay_open),
            },
            Command::AcknowledgeReset => {
                self.reset.acknowledged = true;
                return Ok(Answer::Ack);
            }
            Command::FaultLogRequest { first } => {
                return Ok(Answer::FaultLog(self.fault_log_page(first)))
            }
            Command::Heartbeat => {
                if let Some(ev) = self.heartbeat.beat(now_us) {
                    let _ = self.event(ev, now_us);
                }
                return Ok(Answer::Ack);
            }
            Command::StatusRequest => return Ok(Answer::Status),
            Command::Jog { joint, velocity } => {
                return self.jog(joint, velocity, now_us).map(|()| Answer::Ack)
            }
            Command::Target {
                stamp_us,
                position_m,
                rotation_vector_rad,
            } => {
                return self
                    .target(stamp_us, position_m, rotation_vector_rad, now_us)
                    .map(|()| Answer::Ack)
            }
        };
        let clearing = matches!(ev, Event::ClearFault { .. }) && self.sm.state() == State::Fault;
        self.event(ev, now_us).map_err(NackReason::from)?;
        if clearing {
            self.fault = FaultRecord::NONE;
            self.warnings.remove(Warnings::HEARTBEAT_LATE);
        }
        Ok(Answer::Ack)
    }

    /// A page of the fault log.
    pub fn fault_log_page(&self, first: u16) -> FaultLogPage {
        self.log.page(first)
    }

    /// Whether targets are taken now (following, no stop in force), or why not.
    fn target_gate(&self) -> Result<(), NackReason> {
        self.sm.target_gate().map_err(NackReason::from)?;
        if self.stopper.phase() != StopPhase::Running || self.enabling.is_some() {
            return Err(NackReason::InvalidState);
        }
        Ok(())
    }

    /// Jog: while following, move joint `joint` at `velocity` (m/s or rad/s). The joint's
    /// target advances by velocity × the time since the last Jog of the same stream, and
    /// never leads the setpoint by more than velocity × JOG_HORIZON_S: the master's
    /// repeated Jog is a dead-man, and when Jogs stop the robot stops within that horizon.
    /// The target passes the supervisor like any other (speed limits, path check, guards).
    fn jog(&mut self, joint: u8, velocity: f32, now_us: u64) -> Result<(), NackReason> {
        let j = usize::from(joint);
        if j >= NUM_JOINTS {
            return Err(NackReason::InvalidJoint);
        }
        if !velocity.is_finite() {
            return Err(NackReason::InvalidValue);
        }
        self.target_gate()?;
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
        let lead = lit::<S>(f64::from(velocity).abs() * JOG_HORIZON_S);
        let slot = target.get_mut(j).ok_or(NackReason::InvalidJoint)?;
        let advanced = *slot + lit::<S>(f64::from(velocity)) * lit::<S>(elapsed_us as f64 * 1e-6);
        *slot = Float::min(Float::max(advanced, here - lead), here + lead);
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
        self.target_gate()?;
        let ctl = self.controller.as_mut().ok_or(NackReason::InvalidState)?;
        let board_stamp = self.targets.accept(stamp_us, now_us)?;
        ctl.submit(&pose, board_stamp, now_us)
            .map_err(|r| wire::refusal_reason(&r))?;
        // A Cartesian target ends any jog stream.
        self.jog = None;
        Ok(())
    }

    /// Reads the inputs and runs the monitors: every new finding becomes a fault.
    fn sense_and_monitor<H: Hardware<S>>(&mut self, hw: &mut H, now_us: u64) {
        self.sensing.read(hw);
        self.inputs = Inputs {
            currents: hw.currents(),
            supply_v: hw.supply_voltage(),
            driver_fault: hw.driver_fault(),
            switches: hw.switches(),
            estop_pressed: hw.estop_pressed(),
            relay_open: hw.relay_open(),
        };
        let i = self.inputs;
        if let Some(ev) = self.heartbeat.poll(now_us) {
            let _ = self.event(ev, now_us);
        }
        let finding = i
            .estop_pressed
            .then(|| Finding::board::<S>(FaultCause::EmergencyStopButton, S::one()));
        let chain = self.chain.check(i.estop_pressed, i.relay_open);
        let power = self.power.check(i.supply_v, i.driver_fault, self.torque_on);
        let current = self
            .current
            .monitor(&i.currents, self.dt, self.torque_on, now_us)
            .map(|f| match f {
                CurrentFault::Overcurrent { joint, current_a } => {
                    Finding::joint(FaultCause::Overcurrent, joint, current_a)
                }
                CurrentFault::Overload { joint, current_a } => {
                    Finding::joint(FaultCause::Overload, joint, current_a)
                }
                CurrentFault::OverTemperature { joint, heat } => {
                    Finding::joint(FaultCause::OverTemperature, joint, heat)
                }
            });
        let counts = self.sensing.encoders().counts();
        let drive = DriveSample {
            duty: self.last_duty,
            current: i.currents,
            supply_v: i.supply_v,
            torque: self.torque_on,
        };
        let encoder = self
            .encoder_check
            .check(&counts, self.dt, &self.cfg.current.motors, &drive);
        let limits: [S; NUM_JOINTS] = core::array::from_fn(|j| self.current.peak_current(j));
        let motor = self.motor_check.check(
            &drive,
            self.encoder_check.qdot(),
            self.encoder_check.qdot_resolution(),
            &self.cfg.current.motors,
            &limits,
        );
        let q = self.sensing.measured().q;
        let ranges = check_ranges(
            &q,
            &self.cfg.mechanics.range,
            &i.switches,
            self.sm.homed(),
            self.sm.state() == State::Homing,
        );
        let standstill = if self.stopper.phase() == StopPhase::Holding {
            self.standstill.check(&q)
        } else {
            None
        };
        let fk = (self.sensing.counters().fk_failures_in_row >= self.cfg.fk_failures_to_fault)
            .then(|| {
                let n = self.sensing.counters().fk_failures_in_row;
                Finding::board(
                    FaultCause::ForwardKinematics,
                    S::from(n).unwrap_or_else(S::zero),
                )
            });
        // The motor check before the encoder check: an open circuit also looks like a dead
        // encoder to the back-EMF (both count from the fault's first tick; the motor check
        // names it right). Every finding is acted on, not only the first: a later one may
        // call for a stronger stop than one already latched (an SS1 over-temperature must
        // not mask an STO encoder jump). A cause already raised since the last clear is a
        // repeat (a monitor reports a lasting condition every tick): neither logged nor
        // acted on again.
        for f in [
            finding, chain, power, current, motor, encoder, ranges, standstill, fk,
        ]
        .into_iter()
        .flatten()
        {
            let bit = 1u32 << cause_index(f.cause);
            if self.sm.state() == State::Fault && self.raised & bit != 0 {
                continue;
            }
            self.fault(f, now_us);
        }
    }

    /// One control tick: the sensing and the monitors first (every state), then homing,
    /// enabling or the controller as the state and the stop in force say, then the
    /// outputs (duties within the current limit, brakes, torque); after them the measured
    /// pose ([`Sensing::follow_pose`]) and the controller's evaluation phase
    /// ([`Controller::evaluate`]) when it ran.
    pub fn tick<H: Hardware<S>>(&mut self, hw: &mut H, now_us: u64) -> RuntimeTick<S> {
        self.sense_and_monitor(hw, now_us);
        let mut out = self.stopper.outputs(self.sm.drives_on());
        let mut duty = [S::zero(); NUM_JOINTS];
        let mut control = None;
        let mut homing = None;
        let mut standstill = true;
        if out.torque {
            match (self.sm.state(), self.stopper.phase()) {
                (State::Homing, StopPhase::Running) => {
                    if self.parking.is_some() {
                        duty = self.park(now_us);
                    } else {
                        let (st, d) = self.homing.step(hw, &mut self.sensing, now_us);
                        homing = Some(st);
                        duty = d;
                        self.homing_status(st, now_us);
                    }
                }
                (State::Enabling, StopPhase::Running) => {
                    control = self.enabling_tick(now_us, &mut duty, &mut out.brakes_released);
                }
                _ => {
                    // Following, holding or stopping under the controller; without one (a
                    // stop during homing) the drives stop where they are.
                    if let Some(ctl) = self.controller.as_mut() {
                        let report = ctl.tick(self.sensing.measured());
                        self.sensing.set_backlash(&ctl.drive().backlash_offsets());
                        duty = report.servo.duty;
                        standstill = ctl.supervisor().twist().iter().all(|x| *x == S::zero());
                        self.control_faults(&report, now_us);
                        control = Some(report);
                    }
                }
            }
        }
        // The stop's progress: standstill ends a deceleration.
        let was = self.stopper.phase();
        if self.stopper.advance(now_us, standstill) {
            let f = Finding::board::<S>(FaultCause::StandstillLost, S::zero());
            self.fault(f, now_us);
        }
        if was != StopPhase::Holding && self.stopper.phase() == StopPhase::Holding {
            self.standstill.start(&self.sensing.measured().q);
        }
        if matches!(self.stopper.phase(), StopPhase::TorqueOff { .. })
            && !self.sm.drives_on()
            && self.parking.is_none()
        {
            // The stop is complete: the controller is rebuilt at the next enable, which may
            // start from the setpoint it held.
            if let Some(sup) = self.controller.as_ref().map(|c| c.supervisor()) {
                self.held = Some((*sup.setpoint(), to_array(sup.setpoint_joints())));
            }
            self.controller = None;
        }
        self.write_outputs(hw, &mut duty, now_us);
        // Once the outputs are written, what does not feed them: the measured pose, and
        // the controller's evaluation phase. Neither adds to the latency from the
        // readings to the outputs.
        self.sensing.follow_pose();
        if control.is_some() {
            if let Some(ctl) = self.controller.as_mut() {
                ctl.evaluate();
            }
        }
        self.update_warnings(now_us);
        RuntimeTick {
            state: self.sm.state(),
            control,
            homing,
            drives_on: self.torque_on,
        }
    }

    /// The e-stop path put the outputs in their safe state behind the runtime's back
    /// ([`crate::estop`]): the bridges are off, so the next tick with torque enables them
    /// again instead of driving disabled bridges (fuzz finding 3).
    /// The brakes were applied then too (at `now_us` at the latest).
    pub fn outputs_forced_safe(&mut self, now_us: u64) {
        self.outputs_on = false;
        if self.brakes_out {
            self.brakes_applied_at_us = Some(now_us);
        }
        self.brakes_out = false;
    }

    /// The outputs of the tick: the duties within the current limit, the brakes, torque.
    fn write_outputs<H: Hardware<S>>(
        &mut self,
        hw: &mut H,
        duty: &mut [S; NUM_JOINTS],
        now_us: u64,
    ) {
        let out = self.stopper.outputs(self.sm.drives_on());
        let brakes_released =
            out.brakes_released && self.enabling.as_ref().is_none_or(|e| e.brakes_released());
        if out.torque {
            if !self.outputs_on {
                hw.enable();
                self.outputs_on = true;
            }
            self.current
                .limit(duty, self.encoder_check.qdot(), self.inputs.supply_v);
            hw.set_duties(duty);
            self.last_duty = *duty;
        } else {
            hw.disable();
            self.outputs_on = false;
            self.last_duty = [S::zero(); NUM_JOINTS];
            self.current.reset_overload();
        }
        let released = brakes_released && out.torque;
        if self.brakes_out && !released {
            self.brakes_applied_at_us = Some(now_us);
        }
        self.brakes_out = released;
        hw.set_brakes_released(released);
        self.torque_on = out.torque;
    }

    /// The homing's status: a failure is a fault, the references start the park move.
    fn homing_status(&mut self, st: HomingStatus, now_us: u64) {
        match st {
            HomingStatus::Failed(e) => {
                let f = Finding {
                    cause: FaultCause::HomingFailed,
                    joint: e.joint(),
                    value: e.code(),
                };
                self.fault(f, now_us);
            }
            HomingStatus::Referenced if self.parking.is_none() && self.controller.is_none() => {
                self.start_park(now_us)
            }
            HomingStatus::Referenced => {}
            HomingStatus::Running(_) => {}
        }
    }

    /// A homing failure of the park move.
    fn park_failed(&mut self, reason: ParkRefusal<S>, now_us: u64) {
        let (joint, code) = match reason {
            ParkRefusal::Guard { reading, .. } => {
                let joint = match reading.subject {
                    kinematics_core::guards::Subject::Joint(j) => {
                        Some(usize::from(j).saturating_sub(1))
                    }
                    kinematics_core::guards::Subject::Chain(c) => Some(c.index()),
                    _ => None,
                };
                (joint, HomingError::Park { reason: 1 })
            }
            ParkRefusal::NoPose { .. } => (None, HomingError::Park { reason: 2 }),
            ParkRefusal::Invalid => (None, HomingError::Park { reason: 3 }),
            ParkRefusal::NotSettled { joint, .. } => (Some(joint), HomingError::Park { reason: 4 }),
        };
        let f = Finding {
            cause: FaultCause::HomingFailed,
            joint,
            value: code.code(),
        };
        self.fault(f, now_us);
    }

    /// Every joint referenced: the pose is solved, and the park move starts (its path is
    /// checked against the guards first), or, without a park position, the homing is done.
    fn start_park(&mut self, now_us: u64) {
        if self.sensing.track_pose().is_err() {
            return self.park_failed(ParkRefusal::NoPose { sample: 0 }, now_us);
        }
        let m = *self.sensing.measured();
        let (Some(park), Some(pose)) = (self.cfg.homing.park, m.pose) else {
            return self.finish_park(now_us);
        };
        let Ok(guards) = kinematics_core::guards::Guards::new(
            self.robot.clone(),
            self.cfg.controller.branch,
            self.cfg.controller.limits,
        ) else {
            return self.park_failed(ParkRefusal::Invalid, now_us);
        };
        self.parking = Some(ParkMove::new(
            guards,
            self.cfg.controller.fk,
            self.cfg.park,
            m.q,
            pose,
            park,
        ));
    }

    /// The park move done: the controller starts at the measured pose (its supervisor
    /// must accept it), and the homing is done.
    fn finish_park(&mut self, now_us: u64) {
        self.parking = None;
        if self.sensing.track_pose().is_err() {
            return self.park_failed(ParkRefusal::NoPose { sample: u16::MAX }, now_us);
        }
        match Controller::new(
            self.robot.clone(),
            self.cfg.controller,
            self.sensing.measured(),
        ) {
            Ok(c) => {
                self.controller = Some(c);
                if self.sm.state() == State::Homing {
                    let _ = self.event(Event::HomingDone, now_us);
                }
            }
            Err(_) => self.fault(
                Finding {
                    cause: FaultCause::HomingFailed,
                    joint: None,
                    value: HomingError::Park { reason: 5 }.code(),
                },
                now_us,
            ),
        }
    }

    /// One tick of the park move: the path check (holding), then the profile under the
    /// homing's servo; the duties.
    fn park(&mut self, now_us: u64) -> [S; NUM_JOINTS] {
        let (q, motor) = (self.sensing.measured().q, self.sensing.measured().motor);
        let Some(step) = self.parking.as_mut().map(|p| p.step(&q, now_us)) else {
            return [S::zero(); NUM_JOINTS];
        };
        let out = match step {
            ParkStep::Checking { .. } | ParkStep::Arrived => self.homing.hold(&motor, now_us),
            ParkStep::Move { q: sp, qdot } => self.homing.track(&sp, &qdot, &motor, now_us),
            ParkStep::Refused(r) => {
                self.park_failed(r, now_us);
                return [S::zero(); NUM_JOINTS];
            }
        };
        self.sensing.set_backlash(&self.homing.backlash_offsets());
        if let Some(f) = out.fault {
            let finding = match f.joint {
                Some(j) => Finding::joint(FaultCause::FollowingError, j, f.error),
                None => Finding::board(FaultCause::FollowingError, f.error),
            };
            self.fault(finding, now_us);
            return [S::zero(); NUM_JOINTS];
        }
        if step == ParkStep::Arrived {
            self.finish_park(now_us);
        }
        out.duty
    }

    /// One tick of an enable: the brake check, then the release under servo.
    fn enabling_tick(
        &mut self,
        now_us: u64,
        duty: &mut [S; NUM_JOINTS],
        brakes_released: &mut bool,
    ) -> Option<TickReport<S>> {
        let q = self.sensing.measured().q;
        let step = self.enabling.as_mut()?.step(&q, now_us);
        match step {
            EnableStep::Push(d) => {
                *duty = d;
                *brakes_released = false;
                None
            }
            EnableStep::Failed { joint, motion } => {
                self.fault(
                    Finding::joint(FaultCause::BrakeCheck, joint, motion),
                    now_us,
                );
                None
            }
            EnableStep::Hold | EnableStep::Released => {
                let ctl = self.controller.as_mut()?;
                let report = ctl.tick(self.sensing.measured());
                self.sensing.set_backlash(&ctl.drive().backlash_offsets());
                *duty = report.servo.duty;
                self.control_faults(&report, now_us);
                if step == EnableStep::Released && self.sm.state() == State::Enabling {
                    self.enabling = None;
                    let _ = self.event(Event::EnableDone, now_us);
                }
                Some(report)
            }
        }
    }

    /// The faults the controller's tick reports: the servo's, the supervisor's stop.
    fn control_faults(&mut self, report: &TickReport<S>, now_us: u64) {
        if let Some(f) = report.servo.fault {
            let cause = match f.kind {
                servo::tracking::FaultKind::FollowingError => FaultCause::FollowingError,
                servo::tracking::FaultKind::NoMotion => FaultCause::NoMotion,
                servo::tracking::FaultKind::NonFiniteInput
                | servo::tracking::FaultKind::InvalidTimeStep => FaultCause::NonFiniteInput,
            };
            let finding = match f.joint {
                Some(j) => Finding::joint(cause, j, f.error),
                None => Finding::board(cause, f.error),
            };
            if self.fault.cause != cause {
                self.fault(finding, now_us);
            }
        } else if let Some(stop) = report.stop {
            let cause = match wire::guard_fault(stop.guard) {
                f if f == master_link::Faults::SINGULARITY => FaultCause::Singularity,
                _ => FaultCause::GuardStop,
            };
            if self.sm.state() != State::Fault {
                let joint = match stop.subject {
                    kinematics_core::guards::Subject::Joint(j) => {
                        Some(usize::from(j).saturating_sub(1))
                    }
                    kinematics_core::guards::Subject::Chain(c) => Some(c.index()),
                    _ => None,
                };
                let finding = Finding {
                    cause,
                    joint,
                    value: wire::to_f32(stop.value),
                };
                self.fault(finding, now_us);
            }
        }
    }

    fn update_warnings(&mut self, now_us: u64) {
        let w = &mut self.warnings;
        w.set(Warnings::NOT_HOMED, !self.sm.homed());
        w.set(
            Warnings::HEARTBEAT_LATE,
            self.sm.state() == State::Enabled && self.heartbeat.is_late(now_us),
        );
        w.set(
            Warnings::VELOCITY_LIMITED,
            self.current.limited().iter().any(|x| *x),
        );
    }

    /// Records the control tick's worst start jitter and execution time (µs) and the
    /// missed periods, measured by the board, for the status report.
    pub fn set_tick_timing(&mut self, worst_jitter_us: u32, worst_exec_us: u32, missed: u32) {
        self.tick_timing = (worst_jitter_us, worst_exec_us);
        self.missed_ticks = missed;
    }

    /// Sets or clears extra warnings (e.g. `CYCLE_OVERRUN` from the board).
    pub fn set_warning(&mut self, w: Warnings, on: bool) {
        self.warnings.set(w, on);
    }

    /// The status report of the last tick: the measured pose and joints (NaN until
    /// homed), the setpoint and the guard margins at it (NaN while the supervisor does not
    /// run), the stop in force, the latched fault with its cause, joint and value, the
    /// reset, the currents and the supply, warnings and timing. The link counters are
    /// added as it goes out ([`crate::telemetry::with_link`]).
    pub fn status(&self) -> StatusReport {
        let m = self.sensing.measured();
        let nan3 = [f32::NAN; 3];
        let (position_m, rotation_vector_rad) =
            m.pose.map_or((nan3, nan3), |p| wire::pose_to_wire(&p));
        let f32s = |a: &[S; NUM_JOINTS]| a.map(wire::to_f32);
        let mut warnings = self.warnings;
        let nan = f32::NAN;
        let mut margins = GuardMargins {
            nearest: nan,
            serial: nan,
            parallel: nan,
            stroke: nan,
            tilt: nan,
            collision: nan,
            workspace: nan,
        };
        let (mut setpoint_p, mut setpoint_r) = (nan3, nan3);
        let mut refused = 0;
        if let Some(c) = self.controller.as_ref() {
            let sup = c.supervisor();
            let (sing, limits) = (sup.margins(), sup.guards().limits());
            let k = sup.setpoint_margins();
            let parallel =
                (sing.parallel - limits.parallel.stop) / (S::one() - limits.parallel.stop);
            margins = GuardMargins {
                nearest: nan,
                serial: wire::to_f32(k.serial),
                parallel: wire::to_f32(parallel),
                stroke: wire::to_f32(Float::min(k.stroke, k.link_angle)),
                tilt: wire::to_f32(k.tilt),
                collision: wire::to_f32(k.collision),
                workspace: wire::to_f32(k.workspace),
            };
            margins.nearest = [
                margins.serial,
                margins.parallel,
                margins.stroke,
                margins.tilt,
                margins.collision,
                margins.workspace,
            ]
            .iter()
            .fold(
                f32::INFINITY,
                |a, x| if *x < a || x.is_nan() { *x } else { a },
            );
            warnings.set(
                Warnings::NEAR_SERIAL_SINGULARITY,
                sing.serial < limits.serial.warn,
            );
            warnings.set(
                Warnings::NEAR_PARALLEL_SINGULARITY,
                sing.parallel < limits.parallel.warn,
            );
            warnings.set(
                Warnings::NEAR_JOINT_LIMIT,
                Float::min(k.stroke, k.link_angle) < lit(0.1),
            );
            (setpoint_p, setpoint_r) = wire::pose_to_wire(sup.setpoint());
            refused = sup.counters().refused();
        }
        let legacy = |x: f32| x;
        StatusReport {
            state: self.sm.state(),
            position_m,
            rotation_vector_rad,
            joints: f32s(&m.q),
            warnings,
            faults: self.sm.faults(),
            serial_singularity_margin: legacy(
                self.controller
                    .as_ref()
                    .map_or(nan, |c| wire::to_f32(c.supervisor().margins().serial)),
            ),
            parallel_singularity_margin: legacy(
                self.controller
                    .as_ref()
                    .map_or(nan, |c| wire::to_f32(c.supervisor().margins().parallel)),
            ),
            link: Default::default(),
            tick_jitter_max_us: self.tick_timing.0,
            tick_exec_max_us: self.tick_timing.1,
            targets_refused: refused,
            stop: self.stopper.status(),
            fault: self.fault,
            reset: self.reset,
            setpoint_position_m: setpoint_p,
            setpoint_rotation_vector_rad: setpoint_r,
            margins,
            currents_a: f32s(&self.inputs.currents),
            supply_v: wire::to_f32(self.inputs.supply_v),
            fault_log_len: u16::try_from(self.log.len()).unwrap_or(u16::MAX),
            missed_ticks: self.missed_ticks,
        }
    }

    /// The stop in force (for tests and logs).
    pub fn stop_phase(&self) -> StopPhase {
        self.stopper.phase()
    }

    /// The joints the drives hold or aim at (the controller's setpoint), if any.
    pub fn setpoint_joints(&self) -> Option<[S; NUM_JOINTS]> {
        self.controller
            .as_ref()
            .map(|c| to_array(c.supervisor().setpoint_joints()))
    }
}

/// The index of `cause` in `FaultCause::ALL` (+1; `None` is 0): its bit in the raised set.
fn cause_index(cause: FaultCause) -> u32 {
    FaultCause::ALL
        .iter()
        .position(|c| *c == cause)
        .map_or(0, |i| (i + 1) as u32)
        .min(31)
}

fn jog_reason(e: JogError) -> NackReason {
    match e {
        JogError::NonFinite => NackReason::InvalidValue,
        JogError::NoSolution => NackReason::OutOfWorkspace,
    }
}

/// How far ahead of the setpoint a Jog aims at most, s: the dead-man time of a jog stream.
pub const JOG_HORIZON_S: f64 = 0.1;

/// The reference robot's mechanics, placed around the guards' ranges `limits` (the
/// supervisor keeps every setpoint inside them; thesis chapter 11): the legs' home
/// switches 1 mm below the shortest stroke (143 mm for 144 .. 210 mm), the links' hard
/// stops 5 deg beyond their largest angle below the central angles (85 deg for ±80 deg); a
/// measured joint more than 2 mm or 3 deg beyond a guard range is a fault (the servo's
/// following error and the backlash stay well inside), which puts the switch and the stop
/// just outside the working range and inside the monitored one only while homing.
pub fn reference_mechanics<S: Scalar>(
    central: &[S; NUM_JOINTS],
    limits: &kinematics_core::guards::Limits<S>,
) -> Mechanics<S> {
    let deg = |d: f64| lit::<S>(d.to_radians());
    let at = |j: usize| central.get(j).copied().unwrap_or_else(S::zero);
    let [short, long] = limits.stroke;
    let leg = [short - lit(0.002), long + lit(0.002)];
    let reach = limits.link_angle_max + deg(3.0);
    let link = |j: usize| [at(j) - reach, at(j) + reach];
    Mechanics {
        leg_switch_m: short - lit(0.001),
        link_stop_below_central_rad: limits.link_angle_max + deg(5.0),
        range: [leg, leg, leg, link(3), link(4), link(5)],
    }
}

/// The default configuration of `robot` assembled on `branch` with the mechanics `mech`,
/// resting at `rest` before homing (None: at its central configuration, where it parks):
/// homing to the mechanics' switches and stops, parking at the central configuration.
pub fn reference_config_for<S: Scalar, M: Mechanism<S>>(
    robot: &M,
    branch: Branch,
    mech: Option<Mechanics<S>>,
    rest: Option<[S; NUM_JOINTS]>,
) -> Result<RuntimeConfig<S>, kinematics_core::IkError> {
    let central = kinematics_core::inverse(robot, &Pose::central(robot.hc()), branch)?;
    let central_q = to_array(&central.q());
    let controller = ControllerConfig {
        branch,
        ..ControllerConfig::default()
    };
    let mech = mech.unwrap_or_else(|| reference_mechanics(&central_q, &controller.limits));
    let rest = rest.unwrap_or(central_q);
    Ok(RuntimeConfig {
        encoder_check: EncoderCheckConfig::reference(controller.encoders.counts_per_unit),
        controller,
        homing: HomingConfig::for_mechanics(&mech, &central_q, &rest, Some(central_q)),
        mechanics: mech,
        heartbeat: HeartbeatConfig::default(),
        targets: TargetClockConfig::default(),
        fk_failures_to_fault: 10,
        stops: StopConfig::default(),
        brakes: BrakeCheckConfig::default(),
        current: CurrentConfig::default(),
        power: PowerConfig::default(),
        relay_debounce_ticks: 20,
        park: ParkConfig::default(),
    })
}
