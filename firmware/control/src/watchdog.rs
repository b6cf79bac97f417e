//! The control tick's deadline: the independent watchdog is fed only after a control
//! tick that started on time and finished within its budget ([`WatchdogPolicy`]); late,
//! overrunning or missing ticks are not fed, so the watchdog resets the board. The tick's
//! jitter and execution time are recorded for the status ([`TickTiming`]).

/// Control-tick timing the watchdog is fed for, µs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct WatchdogConfig {
    /// The control period, µs (default: the board profile's).
    pub period_us: u32,
    /// Largest start delay against the schedule (default 250 µs).
    pub max_lateness_us: u32,
    /// Largest execution time of one tick (default 800 µs).
    pub max_execution_us: u32,
}

impl Default for WatchdogConfig {
    /// The reference board's period, a quarter of it late at most, 80 % of it to run.
    fn default() -> Self {
        let period_us = board_profile::BoardProfile::REFERENCE.control_period_us;
        WatchdogConfig {
            period_us,
            max_lateness_us: period_us / 4,
            max_execution_us: period_us / 5 * 4,
        }
    }
}

/// The decision after one tick.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FeedDecision {
    /// On time: feed.
    Feed,
    /// The tick started this late against the previous one (interval minus period), µs.
    Late(u64),
    /// The tick ran this long, µs.
    Overrun(u32),
}

impl FeedDecision {
    /// Feed the watchdog.
    pub fn feed(&self) -> bool {
        *self == FeedDecision::Feed
    }
}

/// Decides from tick timestamps whether to feed the independent watchdog.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct WatchdogPolicy {
    cfg: WatchdogConfig,
    last_start_us: Option<u64>,
    last_fed: bool,
    fed: u32,
    withheld: u32,
    worst_lateness_us: u64,
    worst_execution_us: u32,
}

impl WatchdogPolicy {
    /// No tick seen yet.
    pub const fn new(cfg: WatchdogConfig) -> Self {
        WatchdogPolicy {
            cfg,
            last_start_us: None,
            last_fed: false,
            fed: 0,
            withheld: 0,
            worst_lateness_us: 0,
            worst_execution_us: 0,
        }
    }

    /// Records a tick that started at `start_us` and ran `execution_us`; feed if
    /// [`FeedDecision::feed`]. The first tick only starts the schedule (fed if within
    /// budget).
    pub fn on_tick(&mut self, start_us: u64, execution_us: u32) -> FeedDecision {
        let lateness = match self.last_start_us {
            Some(prev) => start_us
                .saturating_sub(prev)
                .saturating_sub(u64::from(self.cfg.period_us)),
            None => 0,
        };
        self.last_start_us = Some(start_us);
        self.worst_lateness_us = self.worst_lateness_us.max(lateness);
        self.worst_execution_us = self.worst_execution_us.max(execution_us);
        let d = if lateness > u64::from(self.cfg.max_lateness_us) {
            FeedDecision::Late(lateness)
        } else if execution_us > self.cfg.max_execution_us {
            FeedDecision::Overrun(execution_us)
        } else {
            FeedDecision::Feed
        };
        self.last_fed = d.feed();
        if self.last_fed {
            self.fed = self.fed.wrapping_add(1);
        } else {
            self.withheld = self.withheld.wrapping_add(1);
        }
        d
    }

    /// Forgets the last tick's start: the next tick only starts the schedule again (after
    /// a planned pause, see `TickService::resume_after_pause`).
    pub fn restart(&mut self) {
        self.last_start_us = None;
    }

    /// For a feeder outside the tick: feed at `now_us` only if the last tick was fed and
    /// the next one is not overdue (a missing tick is never fed).
    pub fn should_feed(&self, now_us: u64) -> bool {
        let Some(last) = self.last_start_us else {
            return false;
        };
        let deadline = last + u64::from(self.cfg.period_us) + u64::from(self.cfg.max_lateness_us);
        self.last_fed && now_us <= deadline
    }

    /// The settings.
    pub fn config(&self) -> &WatchdogConfig {
        &self.cfg
    }
    /// Ticks fed.
    pub fn fed(&self) -> u32 {
        self.fed
    }
    /// Ticks not fed.
    pub fn withheld(&self) -> u32 {
        self.withheld
    }
    /// Worst start lateness seen, µs.
    pub fn worst_lateness_us(&self) -> u64 {
        self.worst_lateness_us
    }
    /// Worst execution time seen, µs.
    pub fn worst_execution_us(&self) -> u32 {
        self.worst_execution_us
    }
}

/// Jitter and execution-time statistics of the control tick (the board measures with the
/// DWT cycle counter and passes cycles).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TickTiming {
    /// Ticks measured.
    pub ticks: u32,
    /// Largest |start - scheduled start|, µs.
    pub worst_jitter_us: u32,
    /// Jitter of the last tick, µs.
    pub last_jitter_us: u32,
    /// Largest execution time, cycles.
    pub worst_cycles: u32,
    /// Execution time of the last tick, cycles.
    pub last_cycles: u32,
}

impl TickTiming {
    /// Records one tick.
    pub fn record(&mut self, jitter_us: u32, cycles: u32) {
        self.ticks = self.ticks.wrapping_add(1);
        self.last_jitter_us = jitter_us;
        self.worst_jitter_us = self.worst_jitter_us.max(jitter_us);
        self.last_cycles = cycles;
        self.worst_cycles = self.worst_cycles.max(cycles);
    }
    /// `cycles` at `cpu_hz` in µs.
    pub fn cycles_to_us(cycles: u32, cpu_hz: u32) -> u32 {
        if cpu_hz < 1_000_000 {
            return u32::MAX;
        }
        cycles / (cpu_hz / 1_000_000)
    }
}
