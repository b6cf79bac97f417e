//! Master target timestamps against the board clock: the master's clock as its `Hello`
//! gave it, targets from the future refused, stale ones refused.

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
    /// How far a target's stamp may lead the master's clock as the board keeps it, µs
    /// (default 50 ms): further ahead is `TargetFromFuture`. The board's copy of the clock
    /// lags the master's by the `Hello`'s link delay (milliseconds), and the master's
    /// stamps of a paced clock run at most one status period (20 ms) ahead.
    pub max_lead_us: u64,
    /// How fast the board's copy of the master's clock may gain on the board's clock
    /// through accepted targets, parts per million (default 1000: any crystal's drift,
    /// while a sender that stamps every target ahead gains 1 ms a second at most).
    pub max_drift_ppm: u64,
}

impl Default for TargetClockConfig {
    fn default() -> Self {
        TargetClockConfig {
            max_latency_us: 50_000,
            window_us: 1_000_000,
            max_lead_us: 50_000,
            max_drift_ppm: 1000,
        }
    }
}

/// Relates the master's timestamps to the board clock without synchronised clocks: the
/// smallest `board time - master stamp` over the last one or two windows of the board
/// clock is taken as the pure link delay (windows that ended two windows ago or more are
/// forgotten); a target delayed by more than `max_latency_us` beyond it is stale,
/// one not newer than the last is out of order (both `StaleTarget`). Accepted targets get
/// a strictly increasing board timestamp for the supervisor.
///
/// **Targets from the future.** The master's clock is anchored at its `Hello`
/// ([`TargetClock::start_session`]: its `clock_us` at the board time the `Hello` arrived)
/// and runs on with the board's clock; a target stamped more than `max_lead_us` ahead of
/// it is refused (`TargetFromFuture`) before anything else looks at it, so it is never the
/// last stamp nor the fastest delay (one such stamp, `u64::MAX`, would otherwise make every
/// later target out of order). Accepted targets stamped ahead of the anchor's clock move
/// it forward by at most `max_drift_ppm` of the time since the last move, which follows
/// any real drift between the clocks. Without a `Hello` (the runtime driven directly) the
/// first target anchors the clock.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TargetClock {
    cfg: TargetClockConfig,
    /// The master's clock: (master µs, board µs) of the same instant.
    anchor: Option<(u64, u64)>,
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
            anchor: None,
            last_master_us: None,
            last_board_us: 0,
            min_now: None,
            min_prev: None,
            window_start_us: 0,
        }
    }

    /// Forgets the master's timing but its clock (on enable); board stamps stay
    /// increasing.
    pub fn reset(&mut self) {
        self.last_master_us = None;
        self.min_now = None;
        self.min_prev = None;
    }

    /// A session starts: the master's clock read `master_clock_us` when its `Hello`
    /// arrived at board time `now_us`; everything learnt of the previous session's timing
    /// is forgotten.
    pub fn start_session(&mut self, master_clock_us: u64, now_us: u64) {
        self.reset();
        self.anchor = Some((master_clock_us, now_us));
    }

    /// The master's clock at board time `now_us` as the board keeps it, if it has one.
    pub fn master_now_us(&self, now_us: u64) -> Option<u64> {
        self.anchor
            .map(|(m, b)| m.saturating_add(now_us.saturating_sub(b)))
    }

    /// The last master stamp taken, µs.
    pub fn last_master_us(&self) -> Option<u64> {
        self.last_master_us
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
        let master_now = match self.master_now_us(now_us) {
            Some(m) => m,
            None => {
                self.anchor = Some((master_us, now_us));
                master_us
            }
        };
        if master_us > master_now.saturating_add(self.cfg.max_lead_us) {
            return Err(NackReason::TargetFromFuture);
        }
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
        // Follow the master's clock where it runs ahead of the copy, at a bounded rate.
        if let (true, Some((_, b))) = (master_us > master_now, self.anchor) {
            let gain = now_us
                .saturating_sub(b)
                .saturating_mul(self.cfg.max_drift_ppm)
                / 1_000_000;
            let ahead = (master_us - master_now).min(gain);
            self.anchor = Some((master_now.saturating_add(ahead), now_us));
        }
        Ok(self.board_stamp(now_us))
    }
}
