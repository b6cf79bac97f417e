//! The master's heartbeat: no heartbeat for `hold_after_us` -> [`Event::HeartbeatLate`]
//! (the robot holds); for `disable_after_us` -> the fault `HeartbeatTimeout` (SS1: the
//! robot stops, then brakes and torque off).
//! A heartbeat after a hold ends it ([`Event::HeartbeatRestored`]); after a disable the
//! master must enable again.

use master_link::FaultCause;

use crate::modes::Event;

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
            Some(Event::Fault(FaultCause::HeartbeatTimeout))
        } else if silence >= self.cfg.hold_after_us && self.level == HeartbeatLevel::Alive {
            self.level = HeartbeatLevel::Late;
            self.holds = self.holds.wrapping_add(1);
            Some(Event::HeartbeatLate)
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
