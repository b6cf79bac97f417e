//! The master's clock paced by the board: once the telemetry flows, it advances by the
//! board's status period (20 ms) per status received, and at most one period beyond the
//! last status ([`CLOCK_LEAD_S`]); it never goes back.
//!
//! A master on the host's clock and an emulated board that its host stalls drift apart:
//! the board pauses (its virtual time slips behind the wall clock), the master does not,
//! and the master's targets and heartbeats reach the board late by the board's clock
//! (stale targets, a master seemingly lost), while every latency the master measures
//! includes the pauses. On this clock the master pauses with the board instead: its
//! stream, heartbeats, target stamps, timeouts and figures follow the board's own time. On
//! a real board the two clocks agree.
//!
//! Used by the teleoperation session ([`crate::session::Session`]) and the operator's
//! front ends (`operator::Board`). A paced master cannot tell a stalled board from a dead
//! one by its own clock, which stops with the board: [`BoardClock::silent_for_s`] gives the
//! host time since the board last sent anything, for the master's silence limit.

use std::cell::Cell;

/// The board's telemetry period, s (`Status` every 20 ms once connected).
pub const STATUS_PERIOD_S: f64 = 0.02;
/// How far the paced clock runs on beyond the last status, s: one status period, to where
/// the next status is due; beyond it the board is late and the master waits for it.
///
/// It must stay well below the board's stale window (`TargetClockConfig::max_latency_us`,
/// 50 ms): the board takes the smallest `board time - stamp` it saw recently as the link's
/// delay, and a stall of the board lets the master's stamps run ahead by up to this lead,
/// so that the targets after it look late by as much. A lead of three periods (60 ms, until
/// this was found) made 22 of 222 targets stale after the emulated board's stalls (the
/// warm-up of `against-emulator.sh` under load); `a_stalled_board_takes_every_target`
/// checks it.
pub const CLOCK_LEAD_S: f64 = STATUS_PERIOD_S;
/// A master gives up on a board that has sent nothing for this long by the host's clock,
/// s (a paced clock stops with the board, so its own timeouts never fall due).
pub const SILENCE_LIMIT_S: f64 = 5.0;

/// The clock of a master: the host's, or paced by the board's telemetry.
#[derive(Clone, Debug, Default)]
pub struct BoardClock {
    /// The paced clock at the last status and the host time that status arrived, s.
    at_status: Option<(f64, f64)>,
    /// Host time of the last message received, s.
    last_rx_host_s: Option<f64>,
    /// The clock's last reading (it never goes back).
    last_read_s: Cell<Option<f64>>,
}

impl BoardClock {
    /// A message arrived at host time `host_s`; `status`: it is a status report.
    pub fn received(&mut self, host_s: f64, status: bool) {
        self.last_rx_host_s = Some(host_s);
        if status {
            self.at_status = Some(match self.at_status {
                Some((board, _)) => (board + STATUS_PERIOD_S, host_s),
                None => (host_s, host_s),
            });
        }
    }

    /// The clock at host time `host_s`: paced by the board (`paced`) or the host's, never
    /// less than an earlier reading. Before the first status the paced clock is the host's.
    pub fn now_s(&self, host_s: f64, paced: bool) -> f64 {
        let t = match (paced, self.at_status) {
            (true, Some((board, at))) => board + (host_s - at).clamp(0.0, CLOCK_LEAD_S),
            _ => host_s,
        };
        let t = self.last_read_s.get().map_or(t, |last| t.max(last));
        self.last_read_s.set(Some(t));
        t
    }

    /// Host time since the board last sent anything at host time `host_s`, s (None before
    /// the first message).
    pub fn silent_for_s(&self, host_s: f64) -> Option<f64> {
        self.last_rx_host_s.map(|t| host_s - t)
    }

    /// The board, once heard from, has been silent beyond [`SILENCE_LIMIT_S`] at host time
    /// `host_s`.
    pub fn silent_too_long(&self, host_s: f64) -> bool {
        self.silent_for_s(host_s)
            .is_some_and(|s| s > SILENCE_LIMIT_S)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Paced, the clock advances one status period per status, however late the statuses
    /// arrive by the host's clock, and by at most the lead beyond the last one.
    #[test]
    fn paced_clock_counts_statuses_and_runs_at_most_the_lead_beyond() {
        let mut c = BoardClock::default();
        assert_eq!(
            c.now_s(1.0, true),
            1.0,
            "the host's clock before any status"
        );
        c.received(2.0, true);
        assert_eq!(c.now_s(2.0, true), 2.0);
        // The board stalls: 1 s of host time, the clock stops at the lead.
        assert!((c.now_s(3.0, true) - (2.0 + CLOCK_LEAD_S)).abs() < 1e-12);
        // Five statuses arrive at once: 100 ms of board time, never back.
        for _ in 0..5 {
            c.received(3.0, true);
        }
        assert!((c.now_s(3.0, true) - 2.1).abs() < 1e-12);
        assert!((c.now_s(3.01, true) - 2.11).abs() < 1e-12);
        // Not paced: the host's clock (which is ahead here).
        assert_eq!(c.now_s(3.5, false), 3.5);
    }

    /// The clock never goes back, even when a reading on the host's clock ran ahead.
    #[test]
    fn the_clock_never_goes_back() {
        let mut c = BoardClock::default();
        c.received(0.0, true);
        assert_eq!(c.now_s(5.0, false), 5.0);
        c.received(5.0, true);
        assert_eq!(
            c.now_s(5.0, true),
            5.0,
            "0.02 s paced, held at 5.0 read before"
        );
    }

    /// A board that stalls (its clock stops, its statuses stop) and resumes takes every
    /// target of a master on this clock: the board's stale check (`TargetClock`, 50 ms
    /// beyond the fastest delay seen) passes for stalls of 40 ms to 1 s, at the start and
    /// in the middle of the stream, and link delays of 1 to 10 ms each way. With the old
    /// lead of three periods (60 ms) this fails.
    #[test]
    fn a_stalled_board_takes_every_target() {
        use control::targets::{TargetClock, TargetClockConfig};
        for stall_ms in [40u64, 60, 100, 300, 1000] {
            for stall_at_ms in [120u64, 1500] {
                for delay_ms in [1u64, 5, 10] {
                    // Host time in µs, 1 ms steps; the board's clock stops during the stall.
                    let board_us = |h: u64| {
                        let (a, b) = (stall_at_ms * 1000, (stall_at_ms + stall_ms) * 1000);
                        if h < a {
                            h
                        } else if h < b {
                            a
                        } else {
                            h - (b - a)
                        }
                    };
                    let mut clock = BoardClock::default();
                    let mut board = TargetClock::new(TargetClockConfig::default());
                    let mut next_status_us = 0u64;
                    // Statuses and targets in flight: (arrival host µs, board stamp or
                    // master stamp).
                    let mut statuses: Vec<u64> = Vec::new();
                    let mut targets: Vec<(u64, u64)> = Vec::new();
                    let delay_us = delay_ms * 1000;
                    let mut last_stamp = 0u64;
                    for h in (0..4_000_000u64).step_by(1000) {
                        let b = board_us(h);
                        // The board sends a status every 20 ms of its own time.
                        while b >= next_status_us {
                            statuses.push(h + delay_us);
                            next_status_us += 20_000;
                        }
                        statuses.retain(|&at| {
                            if at <= h {
                                clock.received(at as f64 * 1e-6, true);
                                false
                            } else {
                                true
                            }
                        });
                        // The master streams every 10 ms of host time, each stamp after
                        // the last (as `Session::send_target` and the operator's
                        // `Board::send_target` stamp).
                        if h % 10_000 == 0 {
                            let now = (clock.now_s(h as f64 * 1e-6, true) * 1e6) as u64;
                            last_stamp = now.max(last_stamp + 1);
                            targets.push((h + delay_us, last_stamp));
                        }
                        for &(_, stamp) in targets.iter().filter(|(at, _)| *at <= h) {
                            assert!(
                                board.accept(stamp, b).is_ok(),
                                "stall {stall_ms} ms at {stall_at_ms} ms, delay {delay_ms} ms: target stamped {stamp} us refused at board {b} us"
                            );
                        }
                        targets.retain(|(at, _)| *at > h);
                    }
                }
            }
        }
    }

    /// The silence is measured on the host's clock, from any message.
    #[test]
    fn silence_is_host_time_since_any_message() {
        let mut c = BoardClock::default();
        assert_eq!(c.silent_for_s(1.0), None);
        c.received(1.0, false);
        assert_eq!(c.silent_for_s(3.5), Some(2.5));
        c.received(4.0, true);
        assert_eq!(c.silent_for_s(4.25), Some(0.25));
        assert!(!c.silent_too_long(4.0 + SILENCE_LIMIT_S));
        assert!(c.silent_too_long(4.0 + SILENCE_LIMIT_S + 0.01));
    }
}
