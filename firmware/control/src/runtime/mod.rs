//! The runtime: the board application's one control object. It is always in one
//! [`Mode`], which owns the data valid in it (the homing procedure, the park move, the
//! brake check, the controller, the stop in force, the latched fault); around it the parts
//! every mode uses: the sensing, the monitors, the master session, the output stage and the
//! fault log and the event log. It turns master requests ([`Runtime::command`]) and control
//! ticks ([`Runtime::tick`]) into outputs and a status.
//!
//! One tick, in every mode:
//! ```text
//! sense     counters -> extended counts -> motors -> joints (less the servo's backlash
//!           offsets); the second position channel (where fitted); currents, supply,
//!           driver fault, switches, e-stop button, relay
//! monitors  safety chain, power stage, currents (overcurrent, overload, I²t), encoders
//!           (jump, dead), joint ranges and limit switches, standstill of a safe operating
//!           stop, forward kinematics, heartbeat: each finding is a fault with its cause,
//!           joint and value, and the stop the stop table names for it
//! mode      Homing: the homing step; Parking: the park move; Enabling: the brake check,
//!           then the release; Following, Holding: the controller (supervisor -> six
//!           servos); Stopping, Fault: the stop (the controller brakes, or zero duty)
//! stop      the stop's progress (standstill ends a deceleration; the brakes' engage time
//!           ends SS1)
//! outputs   duties capped by the current limit -> PWM; brakes; torque on or off
//! after     the measured pose (FK tracker), the controller's evaluation phase, the second
//!           position channel against the encoders (where the board has it)
//! status    from what the tick computed (no second evaluation)
//! ```
//! Every change of mode goes through [`crate::modes::next`] (`transitions.rs`).

mod commission;
mod config;
mod interlocks;
mod mode;
mod monitoring;
mod motion;
mod outputs;
mod status;
mod step;
mod tick;
mod transitions;

pub use config::{reference_config_for, reference_mechanics, RuntimeConfig, RuntimeError};
pub use mode::{Held, Jog, Latched, Mode, Stop, StopDrive, StopSequence};
pub use monitoring::{Inputs, Monitors};
pub use outputs::OutputStage;

use hal::Hardware;
use kinematics_core::Mechanism;
use master_link::{
    EventKind, EventLogPage, FaultCause, FaultLogPage, FaultRecord, MasterToBoard, NackReason,
    ResetCause, ResetStatus, Warnings,
};
use servo::NUM_JOINTS;

use crate::controller::Controller;
use crate::drive::{to_array, TickReport};
use crate::event_log::EventLog;
use crate::faults::FaultLog;
use crate::homing::{Homing, HomingStatus};
use crate::link::Answer;
use crate::modes::{Context, Event, ModeKind, Refusal, State};
use crate::monitors::Finding;
use crate::scalar::Scalar;
use crate::sensing::{Measured, Sensing};
use crate::session::{HelloFrom, MasterSession};
use crate::stops::StopPhase;

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

/// The board application (see the module documentation).
#[derive(Clone, Debug)]
pub struct Runtime<S: Scalar, M: Mechanism<S> + Clone> {
    robot: M,
    cfg: RuntimeConfig<S>,
    dt: S,
    mode: Mode<S, M>,
    sensing: Sensing<S, M>,
    monitors: Monitors<S>,
    session: MasterSession,
    outputs: OutputStage<S>,
    log: FaultLog,
    /// The non-volatile event log's RAM view (the target writes it to flash).
    events: EventLog,
    reset: ResetStatus,
    inputs: Inputs<S>,
    warnings: Warnings,
    /// Worst tick jitter and execution time, µs (from the board).
    tick_timing: (u32, u32),
    missed_ticks: u32,
    /// The stored calibrated geometry's version (0: none), for `HelloReply`.
    geometry_version: u32,
    /// Refused events so far.
    refusals: u32,
    /// When the last target (pose or jog) was accepted while following, or following
    /// began: `TARGET_STALE` beyond the supervisor's staleness age.
    last_target_us: u64,
    /// Targets refused with what was measured (see [`Refused`]).
    refused: Refused,
    /// A fault was latched since the last tick ended (the e-stop latch taken at a tick's
    /// start, a request): no status has reported it yet.
    unreported: bool,
}

/// Target refusals for the link: the supervisor's refusal of the target being submitted
/// (the reply to its frame) and those of its path check, which come after the target's
/// `Ack` (each sent on its own). The path check names a target by the board stamp it was
/// submitted with; the newest few stamps are kept with the master's to name it as the
/// master does.
#[derive(Clone, Debug, Default)]
struct Refused {
    /// The refusal of the target in hand (taken by the reply).
    now: Option<master_link::RefusedTarget>,
    /// Refusals of the path check not sent yet.
    later: heapless::Deque<master_link::RefusedTarget, 4>,
    /// (board stamp, master stamp) of the newest targets submitted, a ring.
    stamps: [(u64, u64); 4],
    next: usize,
    /// The supervisor's count of path refusals reported so far.
    path_seen: u32,
}

impl Refused {
    fn submitted(&mut self, board_us: u64, master_us: u64) {
        if let Some(slot) = self.stamps.get_mut(self.next) {
            *slot = (board_us, master_us);
        }
        self.next = (self.next + 1) % self.stamps.len();
    }

    fn master_stamp(&self, board_us: u64) -> u64 {
        self.stamps
            .iter()
            .find(|(b, _)| *b == board_us)
            .map_or(0, |(_, m)| *m)
    }
}

impl<S: Scalar, M: Mechanism<S> + Clone> Runtime<S, M> {
    /// In `Boot`; call [`Runtime::boot_done`] once the hardware is up.
    pub fn new(robot: M, cfg: RuntimeConfig<S>, now_us: u64) -> Result<Self, RuntimeError> {
        Homing::new(&cfg.homing, &cfg.controller.servo)?;
        let sensing = Sensing::new(
            robot.clone(),
            cfg.controller.branch,
            &cfg.controller.encoders,
            cfg.controller.fk,
        )
        .map_err(|e| RuntimeError::Sensing(crate::sensing::SensingError::Config(e)))?;
        let mut sensing = sensing;
        sensing.set_channel(cfg.channel_calibration);
        cfg.heartbeat.validate().map_err(RuntimeError::Heartbeat)?;
        let rate = cfg.controller.rate_hz;
        let lit = kinematics_core::scalar::lit::<S>;
        if !(rate >= lit(100.0) && rate <= lit(10_000.0)) {
            return Err(RuntimeError::Rate);
        }
        Ok(Runtime {
            robot,
            dt: S::one() / rate,
            mode: Mode::Boot,
            sensing,
            monitors: Monitors::new(&cfg),
            session: MasterSession::new(cfg.heartbeat, cfg.targets, now_us),
            outputs: OutputStage::new(),
            log: FaultLog::new(),
            events: EventLog::new(),
            reset: ResetStatus {
                cause: ResetCause::PowerOn,
                acknowledged: true,
            },
            inputs: Inputs::none(),
            warnings: Warnings::NOT_HOMED,
            tick_timing: (0, 0),
            missed_ticks: 0,
            geometry_version: 0,
            refusals: 0,
            last_target_us: 0,
            refused: Refused::default(),
            unreported: false,
            cfg,
        })
    }

    /// The mode, with its data.
    pub fn mode(&self) -> &Mode<S, M> {
        &self.mode
    }
    /// The state the status reports.
    pub fn state(&self) -> State {
        self.mode.kind().state(self.mode.homed())
    }
    /// The homing is trusted.
    pub fn homed(&self) -> bool {
        self.mode.homed()
    }
    /// The controller, while one exists (from the park move's end; while enabling,
    /// enabled, or stopping under it).
    pub fn controller(&self) -> Option<&Controller<S, M>> {
        self.mode.controller()
    }
    /// The homing procedure, while homing.
    pub fn homing(&self) -> Option<&Homing<S>> {
        self.mode.homing()
    }
    /// The master session (clutch, dead-man, heartbeat, target clock).
    pub fn session(&self) -> &MasterSession {
        &self.session
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
    /// The monitors (currents, encoders, motors, power stage, safety chain).
    pub fn monitors(&self) -> &Monitors<S> {
        &self.monitors
    }
    /// The output stage (what was last written).
    pub fn outputs(&self) -> &OutputStage<S> {
        &self.outputs
    }
    /// The latched fault (`FaultRecord::NONE` unless in `Fault`).
    pub fn latched_fault(&self) -> FaultRecord {
        self.mode.latched().map_or(FaultRecord::NONE, |l| l.record)
    }
    /// The fault log.
    pub fn fault_log(&self) -> &FaultLog {
        &self.log
    }
    /// The event log's RAM view.
    pub fn events(&self) -> &EventLog {
        &self.events
    }
    /// The event log's RAM view, for the target's flash writer (which marks what it wrote).
    pub fn events_mut(&mut self) -> &mut EventLog {
        &mut self.events
    }
    /// At boot, before [`Runtime::boot_done`]: the event log as the target's non-volatile
    /// store holds it (`event_log::boot`: a new boot started). When its newest entry says
    /// the relay test was pending, the last power cycle ended with it pending: the relay
    /// test is required again ([`Runtime::require_relay_test`]).
    pub fn restore_events(&mut self, events: EventLog) {
        self.events = events;
        if self.events.relay_test_pending() {
            self.require_relay_test();
        }
    }
    /// A page of the event log.
    pub fn event_log_page(&self, first: u16) -> EventLogPage {
        self.events.page(first)
    }
    /// Records `event` in the event log at `now_us` (ms of this boot).
    pub fn record_event(&mut self, event: EventKind, now_us: u64) {
        self.events.record(event, ms_of(now_us));
    }
    /// A master took charge of the board (its identifier: today a session's nonce): the
    /// event log records it (a repeat of the same master in this boot counts on its entry).
    pub fn master_changed(&mut self, id: u32, now_us: u64) {
        self.record_event(EventKind::Master { id }, now_us);
    }
    /// The target wrote a calibrated geometry to its flash: its version for `HelloReply`,
    /// and an entry of the event log.
    pub fn geometry_stored(&mut self, version: u32, now_us: u64) {
        self.geometry_version = version;
        self.record_event(EventKind::GeometryStored { version }, now_us);
    }
    /// The event log's relay test state follows the safety chain's: a change is an entry
    /// (before any entry that follows it, so that the flash holds the latch at least as
    /// early as the fault that set it).
    pub(super) fn sync_relay_test(&mut self, now_us: u64) {
        let pending = self.relay_test_pending();
        if pending != self.events.relay_test_pending() {
            self.events.set_relay_test_pending(pending);
            self.record_event(EventKind::RelayTest { pending }, now_us);
        }
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
    /// The robot.
    pub fn robot(&self) -> &M {
        &self.robot
    }
    /// The configuration.
    pub fn config(&self) -> &RuntimeConfig<S> {
        &self.cfg
    }
    /// The stop in force (`Running` without one).
    pub fn stop_phase(&self) -> StopPhase {
        self.mode.stop_phase()
    }
    /// The safety chain awaits its relay test (a safety-chain fault was latched in this
    /// power cycle, or in the last one and the test has not passed yet): the target keeps
    /// this in its non-volatile store and tells the next boot
    /// ([`Runtime::require_relay_test`]).
    pub fn relay_test_pending(&self) -> bool {
        !self.monitors.chain.trusted()
    }
    /// At boot: the last power cycle ended with the relay test pending.
    pub fn require_relay_test(&mut self) {
        self.monitors.chain.require_test();
    }
    /// Refused events so far.
    pub fn refusals(&self) -> u32 {
        self.refusals
    }
    /// The joints the drives hold or aim at (the controller's setpoint), if any.
    pub fn setpoint_joints(&self) -> Option<[S; NUM_JOINTS]> {
        self.controller()
            .map(|c| to_array(c.supervisor().setpoint_joints()))
    }

    /// What the table needs beyond the mode, now.
    fn context(&self, now_us: u64) -> Context {
        let powered = match &self.mode {
            Mode::Fault { stop, .. } => stop.powered(),
            _ => false,
        };
        Context {
            homed: self.mode.homed(),
            powered,
            cause_active: self.cause_still_present(now_us).is_some(),
            hold: self.session.hold(),
            reset_pending: !self.reset.acknowledged,
            chain_untrusted: !self.monitors.chain.trusted(),
            emergency_stop: self.emergency_stop_latched(),
            unreported: self.fault_unreported(),
        }
    }

    /// A received calibrated geometry (`StoreGeometry`): taken only with the drives off
    /// and no stop in force (`Disabled`, `Ready`), checked against this robot's nominal
    /// dimensions (e, rb = the length scale, rp, hc: an RSPR) and branch
    /// (`geometry_store::check`). Its version when it may be stored; the target writes it
    /// to flash outside the control tick.
    pub fn check_geometry(
        &self,
        record: &master_link::GeometryRecord,
    ) -> Result<u32, master_link::GeometryRefusal> {
        let cx = self.context(0);
        if crate::modes::next(self.mode.kind(), Event::StoreGeometry, cx).is_err() {
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

    /// Power-up done: the encoders' current counters become the (unhomed) reference; the
    /// reset cause the board read (an entry of the event log); the fault log kept across
    /// the reset, if any.
    pub fn boot_done(
        &mut self,
        raw: [u16; NUM_JOINTS],
        now_us: u64,
        reset: ResetCause,
        log: Option<FaultLog>,
    ) -> Result<ModeKind, Refusal> {
        self.sensing.boot(raw);
        self.reset = ResetStatus {
            cause: reset,
            acknowledged: !reset.needs_acknowledgement(),
        };
        if let Some(log) = log {
            self.log = log;
        }
        self.record_event(EventKind::Reset { cause: reset }, now_us);
        self.apply(Event::BootDone, now_us)
    }

    /// The fault of a missed control deadline (from the board's tick service).
    pub fn deadline_missed(&mut self, late_us: u64, now_us: u64) {
        let late = S::from(late_us).unwrap_or_else(S::infinity);
        self.fault(Finding::board(FaultCause::DeadlineMissed, late), now_us);
    }

    /// A master request (after the link layer): the answer, or why it is refused.
    pub fn command(&mut self, msg: &MasterToBoard, now_us: u64) -> Result<Answer, NackReason> {
        match *msg {
            MasterToBoard::Hello {
                nonce, clock_us, ..
            } => {
                // One owner (`modes::next`): the owner reconnects with its holds kept;
                // another master takes over only while the robot is disabled, and starts
                // with the clutch released and the operator absent.
                let from = self.session.hello_from(nonce, clock_us);
                if from == HelloFrom::Replay {
                    self.refusals = self.refusals.wrapping_add(1);
                    return Err(NackReason::ReplayedHello);
                }
                let owner = from == HelloFrom::Owner;
                self.apply(Event::Hello { owner }, now_us)?;
                if owner {
                    self.session.reconnect(clock_us, now_us);
                } else {
                    self.session.take_over(nonce, clock_us, now_us);
                    self.master_changed(nonce, now_us);
                }
                Ok(Answer::Hello {
                    nonce,
                    reset: self.reset,
                    geometry_version: self.geometry_version,
                })
            }
            MasterToBoard::Enable => self.ack(Event::Enable, now_us),
            MasterToBoard::Disable => self.ack(Event::Disable, now_us),
            MasterToBoard::Home { rehome } => self.ack(Event::Home { rehome }, now_us),
            MasterToBoard::Clutch { engaged } => self.ack(Event::Clutch { engaged }, now_us),
            MasterToBoard::OperatorPresent { present } => {
                self.ack(Event::OperatorPresent { present }, now_us)
            }
            MasterToBoard::EmergencyStop => {
                self.fault(
                    Finding::board::<S>(FaultCause::EmergencyStopMessage, S::zero()),
                    now_us,
                );
                Ok(Answer::Ack)
            }
            MasterToBoard::ClearFault => self.ack(Event::ClearFault, now_us),
            MasterToBoard::AcknowledgeReset => {
                self.apply(Event::AcknowledgeReset, now_us)?;
                self.reset.acknowledged = true;
                Ok(Answer::Ack)
            }
            MasterToBoard::FaultLogRequest { first } => {
                Ok(Answer::FaultLog(self.fault_log_page(first)))
            }
            MasterToBoard::EventLogRequest { first } => {
                Ok(Answer::EventLog(self.event_log_page(first)))
            }
            MasterToBoard::Heartbeat => {
                if let Some(ev) = self.session.beat(now_us) {
                    let _ = self.apply(ev, now_us);
                }
                Ok(Answer::Ack)
            }
            MasterToBoard::StatusRequest => Ok(Answer::Status),
            MasterToBoard::Jog { joint, velocity } => {
                self.jog(joint, velocity, now_us).map(|()| Answer::Ack)
            }
            MasterToBoard::PoseTarget {
                timestamp_us,
                position_m,
                rotation_vector_rad,
            } => self
                .target(timestamp_us, position_m, rotation_vector_rad, now_us)
                .map(|()| Answer::Ack),
            MasterToBoard::Commission { joint, confirm } => self.commission(joint, confirm, now_us),
            // The link hands a geometry to the target's store, never to the tick.
            MasterToBoard::StoreGeometry(_) => Err(NackReason::InvalidState),
        }
    }

    fn ack(&mut self, event: Event, now_us: u64) -> Result<Answer, NackReason> {
        self.apply(event, now_us)?;
        Ok(Answer::Ack)
    }

    /// A page of the fault log.
    pub fn fault_log_page(&self, first: u16) -> FaultLogPage {
        self.log.page(first)
    }

    /// One control tick (see the module documentation).
    pub fn tick<H: Hardware<S>>(&mut self, hw: &mut H, now_us: u64) -> RuntimeTick<S> {
        self.sense_and_monitor(hw, now_us);
        self.sync_relay_test(now_us);
        let step = self.step_mode(hw, now_us);
        self.advance_stop(now_us, step.standstill);
        let mut duty = step.duty;
        self.write_outputs(hw, &mut duty, now_us);
        // Once the outputs are written, what does not feed them: the measured pose, and
        // the controller's evaluation phase. Neither adds to the latency from the
        // readings to the outputs.
        self.sensing.follow_pose();
        if step.control.is_some() {
            if let Some(ctl) = self.mode.controller_mut() {
                ctl.evaluate();
            }
            self.note_path_refusal();
        }
        self.check_channel(now_us);
        self.update_warnings(now_us);
        // The status of this tick reports every fault latched so far.
        self.unreported = false;
        RuntimeTick {
            state: self.state(),
            control: step.control,
            homing: step.homing,
            drives_on: self.outputs.torque_on(),
        }
    }

    /// In `Fault`, with a fault latched since the last tick ended: no status has reported
    /// it, so a command answered now was sent before its master could know of the stop,
    /// and does not end it (`modes::Context::unreported`).
    pub fn fault_unreported(&self) -> bool {
        self.unreported && matches!(self.mode, Mode::Fault { .. })
    }

    /// The e-stop path put the outputs in their safe state behind the runtime's back
    /// ([`crate::estop`]): the bridges are off, so the next tick with torque enables them
    /// again instead of driving disabled bridges. The brakes were applied then too (at
    /// `now_us` at the latest).
    pub fn outputs_forced_safe(&mut self, now_us: u64) {
        self.outputs.forced_safe(now_us);
    }

    fn update_warnings(&mut self, now_us: u64) {
        let homed = self.mode.homed();
        let enabled = self.state() == State::Enabled;
        let late = enabled && self.session.heartbeat_is_late(now_us);
        let limited = self.monitors.current.limited().iter().any(|x| *x);
        let stale = matches!(self.mode, Mode::Following { .. })
            && now_us.saturating_sub(self.last_target_us)
                > self.cfg.controller.supervisor.stale_after_us;
        let w = &mut self.warnings;
        w.set(Warnings::NOT_HOMED, !homed);
        w.set(Warnings::HEARTBEAT_LATE, late);
        w.set(Warnings::VELOCITY_LIMITED, limited);
        w.set(Warnings::TARGET_STALE, stale);
    }

    /// Records the control tick's worst start jitter and execution time (µs) and the
    /// missed periods, measured by the board, for the status report.
    pub fn set_tick_timing(&mut self, worst_jitter_us: u32, worst_exec_us: u32, missed: u32) {
        self.tick_timing = (worst_jitter_us, worst_exec_us);
        self.missed_ticks = missed;
    }

    /// A refusal of the path check since the last tick, kept for the link with the
    /// master's stamp of its target.
    fn note_path_refusal(&mut self) {
        let Some(ctl) = self.mode.controller() else {
            return;
        };
        let sup = ctl.supervisor();
        let n = sup.counters().path_refused;
        if n < self.refused.path_seen {
            // A new controller: its count starts afresh.
            self.refused.path_seen = 0;
        }
        if n == self.refused.path_seen {
            return;
        }
        self.refused.path_seen = n;
        if let Some(r @ kinematics_core::supervisor::Refusal::Path { stamp_us, .. }) =
            sup.last_refusal()
        {
            let master = self.refused.master_stamp(*stamp_us);
            let refused = crate::wire::refused_target(r, sup.config(), master);
            if self.refused.later.is_full() {
                self.refused.later.pop_front();
            }
            let _ = self.refused.later.push_back(refused);
        }
    }

    /// The refusal of the target just submitted by [`Runtime::command`], if the
    /// supervisor refused it (taken: the reply to its frame carries it).
    pub fn take_refused_now(&mut self) -> Option<master_link::RefusedTarget> {
        self.refused.now.take()
    }

    /// The oldest refusal of the path check not sent yet (one target each).
    pub fn take_refused_later(&mut self) -> Option<master_link::RefusedTarget> {
        self.refused.later.pop_front()
    }

    /// Sets or clears extra warnings (e.g. `CYCLE_OVERRUN` from the board).
    pub fn set_warning(&mut self, w: Warnings, on: bool) {
        self.warnings.set(w, on);
    }
}

/// How far ahead of the setpoint a Jog aims at most, s: the dead-man time of a jog stream.
pub const JOG_HORIZON_S: f64 = 0.1;

/// Board time in the event log: ms since boot (wrapping after 49 days).
fn ms_of(now_us: u64) -> u32 {
    (now_us / 1000) as u32
}
