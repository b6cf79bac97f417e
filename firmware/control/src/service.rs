//! The tick service every board target runs around the [`Runtime`]: the e-stop latch of
//! the interrupt, the master's queued requests and their replies, the runtime's tick, the
//! tick's timing (jitter, execution time, missed periods), the deadline policy and the
//! watchdog's decision, and the status the telemetry sends. The targets supply the clock,
//! the cycle counter, the hardware and the queues (`firmware/cortex-m/board-tasks`); this
//! is the logic, tested on the host.
//!
//! **Deadline policy.** A tick that starts more than `max_lateness_us` after its period
//! (missed periods included: they are skipped, not run back to back), or the third tick
//! that runs longer than `max_execution_us` within any `overrun_window` consecutive ticks
//! (a sliding window: the overruns are counted wherever the window starts), is a missed
//! deadline: the fault `DeadlineMissed` is latched (its stop: STO with brakes) and the
//! watchdog is no longer fed, so that it resets the board (the fault log survives the
//! reset; the board then waits for the master to acknowledge it).

use hal::Hardware;
use kinematics_core::Mechanism;
use master_link::{BoardToMaster, FirmwareVersion, MasterToBoard, StatusReport, Warnings};

use crate::estop::EStopTrip;
use crate::link::Request;
use crate::modes::State;
use crate::monitors::Finding;
use crate::runtime::{Runtime, RuntimeTick};
use crate::scalar::Scalar;
use crate::watchdog::{TickTiming, WatchdogConfig, WatchdogPolicy};

/// The tick service's settings.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ServiceConfig {
    /// The core clock the cycle counts are in, Hz.
    pub cpu_hz: u32,
    /// The watchdog's feeding policy (its period is the control period).
    pub watchdog: WatchdogConfig,
    /// Execution time above which the status warns `CYCLE_OVERRUN`, µs (default 80 % of
    /// the period).
    pub exec_warn_us: u32,
    /// Overruns of `watchdog.max_execution_us` within `overrun_window` ticks that are a
    /// missed deadline (default 3; at most [`MAX_OVERRUNS`]).
    pub overruns_to_fault: u32,
    /// The window of the overrun count, ticks (default 100).
    pub overrun_window: u32,
    /// The firmware version sent in `HelloReply`.
    pub firmware: FirmwareVersion,
}

impl ServiceConfig {
    /// A control period of `period_us` on a core at `cpu_hz`: late by a quarter period is
    /// a missed deadline, a tick may run 80 % of the period.
    pub fn for_period(period_us: u32, cpu_hz: u32, firmware: FirmwareVersion) -> Self {
        let watchdog = WatchdogConfig {
            period_us,
            max_lateness_us: period_us / 4,
            max_execution_us: period_us / 5 * 4,
        };
        ServiceConfig {
            cpu_hz,
            watchdog,
            exec_warn_us: watchdog.max_execution_us,
            overruns_to_fault: 3,
            overrun_window: 100,
            firmware,
        }
    }
}

/// What the board does after a tick.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TickOutcome {
    /// Feed the independent watchdog.
    pub feed_watchdog: bool,
    /// The state changed on this tick (from, to).
    pub state_change: Option<(State, State)>,
    /// The state after the tick.
    pub state: State,
    /// The status to publish for the telemetry.
    pub status: StatusReport,
    /// This tick's execution time, µs.
    pub exec_us: u32,
    /// The fault log has new entries or a new count since the last tick (persist it).
    pub log_changed: bool,
    /// The event log's view changed since the last tick (keep it across a watchdog reset).
    pub events_changed: bool,
    /// The drives are off and the brakes applied: a flash erase may stall the core.
    pub drives_off: bool,
    /// A target the supervisor's path check refused after its `Ack`: send it to the
    /// master (`BoardToMaster::TargetRefused`).
    pub refused: Option<master_link::RefusedTarget>,
}

/// How the board's status LED shows the state: solid in `Fault`, fast blink while the
/// drives may move (enabled or homing), slow otherwise.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Indicator {
    /// On.
    Solid,
    /// Toggle every this many ticks.
    Blink(u32),
}

impl Indicator {
    /// The pattern of `state`.
    pub const fn of(state: State) -> Self {
        match state {
            State::Fault => Indicator::Solid,
            State::Enabled | State::Enabling | State::Homing => Indicator::Blink(100),
            _ => Indicator::Blink(500),
        }
    }
}

/// The most overruns [`ServiceConfig::overruns_to_fault`] may count.
pub const MAX_OVERRUNS: usize = 8;

/// The runtime and what the board measures around its ticks.
#[derive(Clone, Debug)]
pub struct TickService<S: Scalar, M: Mechanism<S> + Clone> {
    runtime: Runtime<S, M>,
    cfg: ServiceConfig,
    watchdog: WatchdogPolicy,
    timing: TickTiming,
    last_start_us: Option<u64>,
    tick_start_state: State,
    missed_periods: u64,
    /// Ticks so far, and the ticks of the last overruns (the newest last; `overrun_count`
    /// of them kept, at most [`MAX_OVERRUNS`]).
    ticks: u64,
    overruns: [u64; MAX_OVERRUNS],
    overrun_count: usize,
    /// A deadline was missed: the watchdog is starved from then on.
    starved: bool,
    /// The fault log's total, length and newest count at the last tick.
    log_mark: (u32, usize, u16),
    /// The event log's changes at the last tick.
    events_mark: u32,
    /// The session of the `Hello` the runtime accepted last (None: none yet).
    session: Option<u32>,
}

impl<S: Scalar, M: Mechanism<S> + Clone> TickService<S, M> {
    /// Around a runtime that has booted.
    pub fn new(runtime: Runtime<S, M>, cfg: ServiceConfig) -> Self {
        TickService {
            tick_start_state: runtime.state(),
            log_mark: log_mark(runtime.fault_log()),
            events_mark: runtime.events().changes(),
            session: None,
            runtime,
            cfg,
            watchdog: WatchdogPolicy::new(cfg.watchdog),
            timing: TickTiming::default(),
            last_start_us: None,
            missed_periods: 0,
            ticks: 0,
            overruns: [0; MAX_OVERRUNS],
            overrun_count: 0,
            starved: false,
        }
    }

    /// The runtime.
    pub fn runtime(&self) -> &Runtime<S, M> {
        &self.runtime
    }
    /// The runtime, to inject what the board detects outside the tick (tests too).
    pub fn runtime_mut(&mut self) -> &mut Runtime<S, M> {
        &mut self.runtime
    }
    /// The tick timing so far.
    pub fn timing(&self) -> &TickTiming {
        &self.timing
    }
    /// The watchdog policy (fed and withheld ticks).
    pub fn watchdog(&self) -> &WatchdogPolicy {
        &self.watchdog
    }
    /// Control periods skipped because a tick started more than a period late.
    pub fn missed_periods(&self) -> u64 {
        self.missed_periods
    }
    /// A deadline was missed: the watchdog is starved.
    pub fn starved(&self) -> bool {
        self.starved
    }
    /// The settings.
    pub fn config(&self) -> &ServiceConfig {
        &self.cfg
    }

    /// Start of a tick at `now_us`, `missed` control periods after the one scheduled
    /// before it (the scheduler does not run missed periods back to back); what tripped
    /// the e-stop latch since the last tick (the button's interrupt, an `EmergencyStop`
    /// message).
    pub fn begin(&mut self, now_us: u64, missed: u64, estop: EStopTrip) {
        self.tick_start_state = self.runtime.state();
        self.missed_periods = self.missed_periods.saturating_add(missed);
        let period = u64::from(self.cfg.watchdog.period_us);
        let (jitter, late) = match self.last_start_us {
            Some(prev) => {
                let interval = now_us.saturating_sub(prev);
                (
                    interval.abs_diff(period.saturating_mul(missed + 1)),
                    interval.saturating_sub(period),
                )
            }
            None => (0, 0),
        };
        self.last_start_us = Some(now_us);
        self.timing.last_jitter_us = u32::try_from(jitter).unwrap_or(u32::MAX);
        if estop.button || estop.message {
            self.runtime.outputs_forced_safe(now_us);
        }
        if estop.button {
            let f = Finding::board::<S>(master_link::FaultCause::EmergencyStopButton, S::one());
            self.runtime.fault(f, now_us);
        }
        if estop.message {
            let f = Finding::board::<S>(master_link::FaultCause::EmergencyStopMessage, S::zero());
            self.runtime.fault(f, now_us);
        }
        if late > u64::from(self.cfg.watchdog.max_lateness_us) {
            self.missed_deadline(late, now_us);
        }
    }

    /// Records an overrun at this tick: whether it is the `overruns_to_fault`-th within
    /// the last `overrun_window` ticks (counted from this one back, wherever the window
    /// starts). A fault starts the count afresh.
    fn overrun_in_window(&mut self) -> bool {
        let n = (self.cfg.overruns_to_fault as usize).clamp(1, MAX_OVERRUNS);
        if self.overrun_count == MAX_OVERRUNS {
            self.overruns.rotate_left(1);
            self.overrun_count -= 1;
        }
        if let Some(slot) = self.overruns.get_mut(self.overrun_count) {
            *slot = self.ticks;
            self.overrun_count += 1;
        }
        let oldest = self
            .overrun_count
            .checked_sub(n)
            .and_then(|i| self.overruns.get(i).copied());
        let full = oldest.is_some_and(|t| self.ticks - t < u64::from(self.cfg.overrun_window));
        if full {
            self.overrun_count = 0;
        }
        full
    }

    fn missed_deadline(&mut self, late_us: u64, now_us: u64) {
        self.runtime.deadline_missed(late_us, now_us);
        self.starved = true;
    }

    /// One queued master request: its reply.
    pub fn request(&mut self, req: &Request, now_us: u64) -> BoardToMaster {
        // A frame of a session that another master's `Hello` replaced after the link took
        // it (both queued for the same tick): its master no longer owns the board. An
        // emergency stop is taken from anyone.
        let foreign = req.session != 0
            && self.session != Some(req.session)
            && !matches!(
                req.message,
                MasterToBoard::Hello { .. } | MasterToBoard::EmergencyStop
            );
        if foreign {
            return req.reply(
                Err(master_link::NackReason::NotOwner),
                &self.runtime.status(),
                self.cfg.firmware,
            );
        }
        let _ = self.runtime.take_refused_now();
        let result = self.runtime.command(&req.message, now_us);
        if let (MasterToBoard::Hello { .. }, Ok(_)) = (&req.message, &result) {
            self.session = Some(req.session);
        }
        // A target the supervisor refused: the reply names the guard or rule, the value
        // and the limit.
        if let (Err(_), Some(refused)) = (result, self.runtime.take_refused_now()) {
            return BoardToMaster::TargetRefused(master_link::RefusedTarget {
                reply_to: Some(req.seq),
                ..refused
            });
        }
        req.reply(result, &self.runtime.status(), self.cfg.firmware)
    }

    /// A received calibrated geometry: its version when the runtime accepts it for
    /// storing (see `Runtime::check_geometry`), or why not.
    pub fn check_geometry(
        &self,
        record: &master_link::GeometryRecord,
    ) -> Result<u32, master_link::GeometryRefusal> {
        self.runtime.check_geometry(record)
    }

    /// After a pause of the control task that was not a missed deadline (the board
    /// writing its flash with the drives off, which stalls the core): the next tick
    /// starts the schedule afresh instead of counting as late.
    pub fn resume_after_pause(&mut self) {
        self.last_start_us = None;
        self.watchdog.restart();
    }

    /// The runtime's tick.
    pub fn tick<H: Hardware<S>>(&mut self, hw: &mut H, now_us: u64) -> RuntimeTick<S> {
        self.runtime.tick(hw, now_us)
    }

    /// End of the tick that began at `start_us` and ran `cycles` core cycles: the timing,
    /// the `CYCLE_OVERRUN` warning, the deadline policy, the watchdog's decision and the
    /// status.
    pub fn finish(&mut self, start_us: u64, cycles: u32) -> TickOutcome {
        let jitter = self.timing.last_jitter_us;
        self.timing.record(jitter, cycles);
        let exec_us = TickTiming::cycles_to_us(cycles, self.cfg.cpu_hz);
        if exec_us > self.cfg.watchdog.max_execution_us && self.overrun_in_window() {
            self.missed_deadline(u64::from(exec_us), start_us);
        }
        self.ticks = self.ticks.saturating_add(1);
        self.runtime
            .set_warning(Warnings::CYCLE_OVERRUN, exec_us > self.cfg.exec_warn_us);
        self.runtime.set_tick_timing(
            self.timing.worst_jitter_us,
            TickTiming::cycles_to_us(self.timing.worst_cycles, self.cfg.cpu_hz),
            u32::try_from(self.missed_periods).unwrap_or(u32::MAX),
        );
        let feed_watchdog = self.watchdog.on_tick(start_us, exec_us).feed() && !self.starved;
        let state = self.runtime.state();
        let from = self.tick_start_state;
        let mark = log_mark(self.runtime.fault_log());
        let log_changed = mark != self.log_mark;
        self.log_mark = mark;
        let events = self.runtime.events().changes();
        let events_changed = events != self.events_mark;
        self.events_mark = events;
        let out = self.runtime.outputs();
        TickOutcome {
            feed_watchdog,
            state_change: (from != state).then_some((from, state)),
            state,
            status: self.runtime.status(),
            exec_us,
            log_changed,
            events_changed,
            drives_off: !out.torque_on() && !out.brakes_released(),
            refused: self.runtime.take_refused_later(),
        }
    }
}

/// What says the fault log changed: its total, length and newest entry's count.
fn log_mark(log: &crate::faults::FaultLog) -> (u32, usize, u16) {
    (log.total(), log.len(), log.newest().map_or(0, |e| e.count))
}
