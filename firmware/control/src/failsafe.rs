//! The fail-safe rules.
//!
//! * **Heartbeat** ([`HeartbeatMonitor`]): no master heartbeat for `hold_after_us` ->
//!   [`Event::HeartbeatLost`] (the robot holds); for `disable_after_us` ->
//!   [`Event::HeartbeatLostLong`] (drives off). A heartbeat after a hold ends it
//!   ([`Event::HeartbeatRestored`]); after a disable the master must enable again.
//! * **Emergency stop** ([`emergency_stop_isr`]): the e-stop interrupt turns the PWM and the
//!   driver enable off at once through [`SafeOutputs`] (no allocation, no lock: register
//!   writes) and trips an [`EStopLatch`] (an atomic) that the control tick turns into
//!   [`Event::EmergencyStop`].
//! * **Watchdog** ([`WatchdogPolicy`]): the independent watchdog is fed only after a
//!   control tick that started on time and finished within its budget; late, overrunning
//!   or missing ticks are not fed, so the watchdog resets the board.
//! * **Safe outputs**: in every state but `Homing` and `Enabled`, and on any fault, every
//!   output is off ([`outputs_allowed`]; the runtime disables the bridges every tick).

use core::sync::atomic::{AtomicBool, AtomicU32, Ordering};

use crate::state::{Event, State, StateMachine};

/// Heartbeat timing, µs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct HeartbeatConfig {
    /// Silence after which the robot holds (default 100 ms).
    pub hold_after_us: u64,
    /// Silence after which the drives go off (default 500 ms); longer than the hold.
    pub disable_after_us: u64,
}

impl Default for HeartbeatConfig {
    fn default() -> Self {
        HeartbeatConfig {
            hold_after_us: 100_000,
            disable_after_us: 500_000,
        }
    }
}

/// A heartbeat setting that makes no sense.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct HeartbeatConfigError;

impl HeartbeatConfig {
    /// `0 < hold_after_us < disable_after_us`.
    pub fn validate(&self) -> Result<(), HeartbeatConfigError> {
        if self.hold_after_us > 0 && self.hold_after_us < self.disable_after_us {
            Ok(())
        } else {
            Err(HeartbeatConfigError)
        }
    }
}

/// How late the master's heartbeat is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum HeartbeatLevel {
    /// In time.
    Alive,
    /// Later than `hold_after_us`: hold.
    Late,
    /// Later than `disable_after_us`: drives off.
    Lost,
}

/// Watches the master's heartbeat.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct HeartbeatMonitor {
    cfg: HeartbeatConfig,
    last_us: u64,
    level: HeartbeatLevel,
    beats: u32,
    holds: u32,
    losses: u32,
}

impl HeartbeatMonitor {
    /// Armed at `now_us`, as if a heartbeat had just arrived.
    pub const fn new(cfg: HeartbeatConfig, now_us: u64) -> Self {
        HeartbeatMonitor {
            cfg,
            last_us: now_us,
            level: HeartbeatLevel::Alive,
            beats: 0,
            holds: 0,
            losses: 0,
        }
    }

    /// The settings.
    pub fn config(&self) -> &HeartbeatConfig {
        &self.cfg
    }

    /// A heartbeat arrived; ends a hold or a loss ([`Event::HeartbeatRestored`]).
    pub fn beat(&mut self, now_us: u64) -> Option<Event> {
        self.beats = self.beats.wrapping_add(1);
        self.last_us = now_us;
        let was = core::mem::replace(&mut self.level, HeartbeatLevel::Alive);
        (was != HeartbeatLevel::Alive).then_some(Event::HeartbeatRestored)
    }

    /// Restarts the timing at `now_us` (on entering `Enabled`) without counting a beat.
    pub fn rearm(&mut self, now_us: u64) {
        self.last_us = now_us;
        self.level = HeartbeatLevel::Alive;
    }

    /// Checks the silence; returns each escalation once.
    pub fn poll(&mut self, now_us: u64) -> Option<Event> {
        let silence = self.silence_us(now_us);
        if silence >= self.cfg.disable_after_us && self.level != HeartbeatLevel::Lost {
            self.level = HeartbeatLevel::Lost;
            self.losses = self.losses.wrapping_add(1);
            Some(Event::HeartbeatLostLong)
        } else if silence >= self.cfg.hold_after_us && self.level == HeartbeatLevel::Alive {
            self.level = HeartbeatLevel::Late;
            self.holds = self.holds.wrapping_add(1);
            Some(Event::HeartbeatLost)
        } else {
            None
        }
    }

    /// Time since the last heartbeat (or arming), µs.
    pub fn silence_us(&self, now_us: u64) -> u64 {
        now_us.saturating_sub(self.last_us)
    }
    /// The level at the last poll or beat.
    pub fn level(&self) -> HeartbeatLevel {
        self.level
    }
    /// Later than the hold time at `now_us`.
    pub fn is_late(&self, now_us: u64) -> bool {
        self.silence_us(now_us) >= self.cfg.hold_after_us
    }
    /// Heartbeats received.
    pub fn beats(&self) -> u32 {
        self.beats
    }
    /// Holds triggered.
    pub fn holds(&self) -> u32 {
        self.holds
    }
    /// Losses (disables) triggered.
    pub fn losses(&self) -> u32 {
        self.losses
    }
}

// ---------------------------------------------------------------------------------------
// Emergency stop
// ---------------------------------------------------------------------------------------

/// The outputs' safe state, reachable from an interrupt: PWM off and the driver enable
/// off. Implementations must not allocate, block or take locks (plain register writes).
pub trait SafeOutputs {
    /// Every PWM output off and the driver enable de-asserted, now.
    fn force_safe(&mut self);
}

impl<T: SafeOutputs + ?Sized> SafeOutputs for &mut T {
    fn force_safe(&mut self) {
        (**self).force_safe()
    }
}

/// Set by the e-stop interrupt, taken by the control tick. Lock-free (atomics), so it can
/// live in a `static` shared by the interrupt and the tasks.
#[derive(Debug, Default)]
pub struct EStopLatch {
    tripped: AtomicBool,
    count: AtomicU32,
}

impl EStopLatch {
    /// Not tripped.
    pub const fn new() -> Self {
        EStopLatch {
            tripped: AtomicBool::new(false),
            count: AtomicU32::new(0),
        }
    }
    /// Trips the latch (from the interrupt).
    pub fn trip(&self) {
        self.tripped.store(true, Ordering::Release);
        self.count.fetch_add(1, Ordering::Relaxed);
    }
    /// Takes the trip: `true` once per trip (from the control tick).
    pub fn take(&self) -> bool {
        self.tripped.swap(false, Ordering::AcqRel)
    }
    /// Tripped and not yet taken.
    pub fn is_tripped(&self) -> bool {
        self.tripped.load(Ordering::Acquire)
    }
    /// Trips since boot.
    pub fn count(&self) -> u32 {
        self.count.load(Ordering::Relaxed)
    }
}

/// What the e-stop interrupt calls: outputs safe first, then the latch. No allocation, no
/// lock, bounded time.
pub fn emergency_stop_isr<O: SafeOutputs + ?Sized>(outputs: &mut O, latch: &EStopLatch) {
    outputs.force_safe();
    latch.trip();
}

/// Whether the state lets the outputs drive (homing or enabled, no fault); every other
/// state keeps them in the safe state.
pub fn outputs_allowed(sm: &StateMachine) -> bool {
    sm.drives_on() && sm.faults().is_empty() && sm.state() != State::Fault
}

// ---------------------------------------------------------------------------------------
// Watchdog
// ---------------------------------------------------------------------------------------

/// Control-tick timing the watchdog is fed for, µs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct WatchdogConfig {
    /// The control period (default 1000 µs).
    pub period_us: u32,
    /// Largest start delay against the schedule (default 250 µs).
    pub max_lateness_us: u32,
    /// Largest execution time of one tick (default 800 µs).
    pub max_execution_us: u32,
}

impl Default for WatchdogConfig {
    fn default() -> Self {
        WatchdogConfig {
            period_us: 1000,
            max_lateness_us: 250,
            max_execution_us: 800,
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
