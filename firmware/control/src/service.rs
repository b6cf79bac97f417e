//! The tick service every board target runs around the [`Runtime`]: the e-stop latch and
//! input level, the master's queued requests and their replies, the runtime's tick, the
//! tick's timing (jitter, execution time, missed periods), the watchdog's decision and
//! the status the telemetry sends. The targets supply the clock, the cycle counter, the
//! hardware and the queues (`firmware/cortex-m/board-tasks`); this is the logic, tested on
//! the host.

use hal::{CurrentSense, LimitSwitches, MotorOutputs, QuadratureCounter};
use kinematics_core::Mechanism;
use master_link::{BoardToMaster, StatusReport, Warnings};

use crate::controller::Scalar;
use crate::link::Request;
use crate::runtime::{Runtime, RuntimeTick};
use crate::state_machine::{Event, State};
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
}

impl ServiceConfig {
    /// A control period of `period_us` on a core at `cpu_hz`: the default watchdog
    /// policy for that period, the overrun warning at 80 % of it.
    pub fn for_period(period_us: u32, cpu_hz: u32) -> Self {
        let watchdog = WatchdogConfig {
            period_us,
            max_lateness_us: period_us / 4,
            max_execution_us: period_us / 5 * 4,
        };
        ServiceConfig {
            cpu_hz,
            watchdog,
            exec_warn_us: watchdog.max_execution_us,
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
            State::Enabled | State::Homing => Indicator::Blink(100),
            _ => Indicator::Blink(500),
        }
    }
}

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
}

impl<S: Scalar, M: Mechanism<S> + Clone> TickService<S, M> {
    /// Around a runtime that has booted.
    pub fn new(runtime: Runtime<S, M>, cfg: ServiceConfig) -> Self {
        TickService {
            tick_start_state: runtime.state(),
            runtime,
            cfg,
            watchdog: WatchdogPolicy::new(cfg.watchdog),
            timing: TickTiming::default(),
            last_start_us: None,
            missed_periods: 0,
        }
    }

    /// The runtime.
    pub fn runtime(&self) -> &Runtime<S, M> {
        &self.runtime
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
    /// The settings.
    pub fn config(&self) -> &ServiceConfig {
        &self.cfg
    }

    /// Start of a tick at `now_us`, `missed` control periods after the one scheduled
    /// before it (the scheduler does not run missed periods back to back): the e-stop
    /// latched by the interrupt since the last tick and the e-stop input's level.
    pub fn begin(&mut self, now_us: u64, missed: u64, estop_tripped: bool, estop_asserted: bool) {
        self.tick_start_state = self.runtime.state();
        self.missed_periods = self.missed_periods.saturating_add(missed);
        let period = u64::from(self.cfg.watchdog.period_us);
        let jitter = match self.last_start_us {
            Some(prev) => now_us
                .saturating_sub(prev)
                .abs_diff(period.saturating_mul(missed + 1)),
            None => 0,
        };
        self.last_start_us = Some(now_us);
        self.timing.last_jitter_us = u32::try_from(jitter).unwrap_or(u32::MAX);
        if estop_tripped {
            let _ = self.runtime.event(Event::EmergencyStop, now_us);
        }
        self.runtime.set_estop_input(estop_asserted, now_us);
    }

    /// One queued master request: its reply.
    pub fn request(&mut self, req: &Request, now_us: u64) -> BoardToMaster {
        let result = self.runtime.command(&req.command, now_us);
        req.reply(result, &self.runtime.status())
    }

    /// The runtime's tick.
    pub fn tick<H>(&mut self, hw: &mut H, now_us: u64) -> RuntimeTick<S>
    where
        H: QuadratureCounter + MotorOutputs<S> + LimitSwitches + CurrentSense<S>,
    {
        self.runtime.tick(hw, now_us)
    }

    /// End of the tick that began at `start_us` and ran `cycles` core cycles: the timing,
    /// the `CYCLE_OVERRUN` warning, the watchdog's decision and the status.
    pub fn finish(&mut self, start_us: u64, cycles: u32) -> TickOutcome {
        let jitter = self.timing.last_jitter_us;
        self.timing.record(jitter, cycles);
        let exec_us = TickTiming::cycles_to_us(cycles, self.cfg.cpu_hz);
        self.runtime
            .set_warning(Warnings::CYCLE_OVERRUN, exec_us > self.cfg.exec_warn_us);
        self.runtime.set_tick_timing(
            self.timing.worst_jitter_us,
            TickTiming::cycles_to_us(self.timing.worst_cycles, self.cfg.cpu_hz),
        );
        let feed_watchdog = self.watchdog.on_tick(start_us, exec_us).feed();
        let state = self.runtime.state();
        let from = self.tick_start_state;
        TickOutcome {
            feed_watchdog,
            state_change: (from != state).then_some((from, state)),
            state,
            status: self.runtime.status(),
            exec_us,
        }
    }
}
