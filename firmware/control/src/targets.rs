//! Master target timestamps against the board clock.

use master_link::NackReason;

/// Target timestamp checks.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TargetClockConfig {
    /// Largest extra delay of a target over the fastest one seen recently, µs (default
    /// 50 ms).
    pub max_latency_us: u64,
    /// Length of the window over which the fastest delay is tracked, µs (default 1 s;
    /// bounds the effect of clock drift).
    pub window_us: u64,
}

impl Default for TargetClockConfig {
    fn default() -> Self {
        TargetClockConfig {
            max_latency_us: 50_000,
            window_us: 1_000_000,
        }
    }
}

/// Relates the master's timestamps to the board clock without synchronised clocks: the
/// smallest `board time - master stamp` over the last one or two windows of the board
/// clock is taken as the pure link delay (windows that ended two windows ago or more are
/// forgotten); a target delayed by more than `max_latency_us` beyond it is stale,
/// one not newer than the last is out of order (both `StaleTarget`). Accepted targets get
/// a strictly increasing board timestamp for the supervisor.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TargetClock {
    cfg: TargetClockConfig,
    last_master_us: Option<u64>,
    last_board_us: u64,
    min_now: Option<i128>,
    min_prev: Option<i128>,
    window_start_us: u64,
}

impl TargetClock {
    /// Fresh (the first target is always in time).
    pub const fn new(cfg: TargetClockConfig) -> Self {
        TargetClock {
            cfg,
            last_master_us: None,
            last_board_us: 0,
            min_now: None,
            min_prev: None,
            window_start_us: 0,
        }
    }

    /// Forgets the master's timing (on enable); board stamps stay increasing.
    pub fn reset(&mut self) {
        self.last_master_us = None;
        self.min_now = None;
        self.min_prev = None;
    }

    /// A strictly increasing board timestamp at `now_us`.
    pub fn board_stamp(&mut self, now_us: u64) -> u64 {
        let s = now_us.max(self.last_board_us.saturating_add(1));
        self.last_board_us = s;
        s
    }

    /// Checks a master target stamped `master_us` arriving at board time `now_us`;
    /// returns the board timestamp to submit it with.
    pub fn accept(&mut self, master_us: u64, now_us: u64) -> Result<u64, NackReason> {
        if self.last_master_us.is_some_and(|last| master_us <= last) {
            return Err(NackReason::StaleTarget);
        }
        let offset = i128::from(now_us) - i128::from(master_us);
        // The windows follow the board clock, not the targets: after a silence of two
        // windows or more (a navigation system sending a target now and then) neither
        // window says anything about the link's delay now (the clocks drift), and the
        // target starts the measurement afresh, as the first one does.
        let elapsed = now_us.saturating_sub(self.window_start_us);
        if elapsed >= self.cfg.window_us.saturating_mul(2) {
            self.min_prev = None;
            self.min_now = None;
            self.window_start_us = now_us;
        } else if elapsed >= self.cfg.window_us {
            self.min_prev = self.min_now;
            self.min_now = None;
            self.window_start_us = now_us;
        }
        let m = self.min_now.map_or(offset, |m| m.min(offset));
        self.min_now = Some(m);
        let fastest = self.min_prev.map_or(m, |p| p.min(m));
        if offset - fastest > i128::from(self.cfg.max_latency_us) {
            return Err(NackReason::StaleTarget);
        }
        self.last_master_us = Some(master_us);
        Ok(self.board_stamp(now_us))
    }
}
