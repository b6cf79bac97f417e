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
//!
//! **The board's own clock.** An emulated board served with a shared clock
//! (`board-emulator serve --clock-lead-ms`, [`SharedClock`]) publishes its time beside its
//! socket; a master that finds it there ([`BoardClock::with_shared`]) reads its clock from
//! it instead of counting statuses: its clock *is* the board's, to the emulator's step
//! (1 ms), never ahead of it. A tick due beyond the board's time waits for the board (the
//! master's lead over the board is nil) rather than running on the host's time and
//! reaching the board early, several at once. In lockstep ([`BoardClock::set_lockstep`])
//! the master also writes back each reading, and the board runs at most its lead (2 ms in
//! the tests) beyond the master's last reading: a master its host holds up holds the board,
//! so the board never runs on while the master's input waits to be sent. Together, what
//! the master measures (input → target → setpoint) is in the board's time and does not move
//! with the host's load.

use master_link::shared_clock;
use std::cell::Cell;
use std::fs::File;
use std::os::unix::fs::FileExt;
use std::path::Path;
use std::sync::Arc;
use std::time::{Duration, SystemTime};

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

/// A shared clock older than this (its file not written for so long, by the host's
/// clock) is a board that no longer runs: a master ignores it, s.
pub const SHARED_CLOCK_STALE_S: f64 = 2.0;

/// The board's clock shared beside its socket (`master_link::shared_clock`).
#[derive(Debug)]
pub struct SharedClock {
    file: File,
}

impl SharedClock {
    /// The shared clock beside the board's socket `socket` (its path with
    /// `shared_clock::SUFFIX`), when there is one that a running board keeps (written
    /// within [`SHARED_CLOCK_STALE_S`]; a file left by a board that was killed is not).
    pub fn beside(socket: &Path) -> Option<SharedClock> {
        let mut name = socket.as_os_str().to_owned();
        name.push(shared_clock::SUFFIX);
        let file = File::options().read(true).write(true).open(name).ok()?;
        let meta = file.metadata().ok()?;
        if meta.len() < shared_clock::LEN {
            return None;
        }
        let age = SystemTime::now()
            .duration_since(meta.modified().ok()?)
            .unwrap_or(Duration::ZERO);
        (age.as_secs_f64() <= SHARED_CLOCK_STALE_S).then_some(SharedClock { file })
    }

    /// The board's time, µs since its boot (None: not written yet, or not readable now).
    pub fn board_us(&self) -> Option<u64> {
        let read = || {
            let mut b = [0u8; 8];
            self.file
                .read_exact_at(&mut b, shared_clock::BOARD_US)
                .ok()?;
            Some(shared_clock::decode(b))
        };
        // Two reads in a row that agree (the board's write may race a read).
        let mut last = read()?;
        for _ in 0..4 {
            let again = read()?;
            if again == last {
                return (again != 0).then_some(again);
            }
            last = again;
        }
        None
    }

    /// Tells the board this master has read its clock at `board_us` (lockstep).
    pub fn seen(&self, board_us: u64) {
        // Best effort: a reading that does not reach the board only holds it a little.
        let _ = self
            .file
            .write_all_at(&shared_clock::encode(board_us), shared_clock::MASTER_US);
    }
}

/// The clock of a master: the host's, paced by the board's telemetry, or the board's own
/// when it shares it.
#[derive(Clone, Debug, Default)]
pub struct BoardClock {
    /// The paced clock at the last status and the host time that status arrived, s.
    at_status: Option<(f64, f64)>,
    /// Host time of the last message received, s.
    last_rx_host_s: Option<f64>,
    /// The clock's last reading (it never goes back).
    last_read_s: Cell<Option<f64>>,
    /// The board's shared clock, when it shares one.
    shared: Option<Arc<SharedClock>>,
    /// The clock's reading and the board's time at the first reading of the shared clock
    /// (s, µs): the shared clock runs on from where this clock was.
    shared_origin: Cell<Option<(f64, u64)>>,
    /// Readings written back to the board (lockstep).
    lockstep: bool,
}

impl BoardClock {
    /// A clock that reads the board's own time from `shared` when paced.
    pub fn with_shared(shared: SharedClock) -> Self {
        BoardClock {
            shared: Some(Arc::new(shared)),
            ..BoardClock::default()
        }
    }

    /// The board shares its clock: paced, this clock is the board's own.
    pub fn shares_board_time(&self) -> bool {
        self.shared.is_some()
    }

    /// Lockstep on: each reading of the shared clock is written back, and the board runs
    /// at most its lead beyond this master's last reading. Without a shared clock, nothing.
    pub fn set_lockstep(&mut self, on: bool) {
        self.lockstep = on;
    }

    /// In lockstep with a board that shares its clock: the master must read the clock
    /// often (every millisecond or so), or the board waits for it.
    pub fn in_lockstep(&self) -> bool {
        self.lockstep && self.shared.is_some()
    }

    /// The shared clock's reading in this clock's terms, s (None: no shared clock, or no
    /// reading now); written back in lockstep.
    fn shared_now_s(&self, host_s: f64) -> Option<f64> {
        let shared = self.shared.as_ref()?;
        let us = shared.board_us()?;
        if self.lockstep {
            shared.seen(us);
        }
        let (t0, us0) = match self.shared_origin.get() {
            Some(o) => o,
            None => {
                let o = (self.last_read_s.get().map_or(host_s, |l| l.max(host_s)), us);
                self.shared_origin.set(Some(o));
                o
            }
        };
        Some(t0 + us.saturating_sub(us0) as f64 * 1e-6)
    }

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
    /// less than an earlier reading. Paced, it is the board's shared clock when there is
    /// one; else the statuses' count, and before the first status the host's.
    pub fn now_s(&self, host_s: f64, paced: bool) -> f64 {
        let shared = if paced {
            self.shared_now_s(host_s)
        } else {
            None
        };
        let t = match (paced, shared, self.at_status) {
            (true, Some(t), _) => t,
            (true, None, Some((board, at))) => board + (host_s - at).clamp(0.0, CLOCK_LEAD_S),
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
pub(crate) mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used)]
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

    /// A board's shared clock in a fresh temporary file: (the socket's path, the file).
    pub(crate) fn shared_file(name: &str, board_us: u64) -> (std::path::PathBuf, File) {
        let socket =
            std::env::temp_dir().join(format!("rspr-pacing-{}-{name}.sock", std::process::id()));
        let mut path = socket.as_os_str().to_owned();
        path.push(shared_clock::SUFFIX);
        let f = File::options()
            .read(true)
            .write(true)
            .create(true)
            .truncate(true)
            .open(path)
            .unwrap();
        f.set_len(shared_clock::LEN).unwrap();
        f.write_all_at(&shared_clock::encode(board_us), shared_clock::BOARD_US)
            .unwrap();
        (socket, f)
    }

    fn master_slot(f: &File) -> u64 {
        let mut b = [0u8; 8];
        f.read_exact_at(&mut b, shared_clock::MASTER_US).unwrap();
        shared_clock::decode(b)
    }

    /// With the board's shared clock the paced clock is the board's time from where the
    /// clock was: however much host time passes while the board stands, it does not move
    /// (a tick due then waits for the board), and statuses do not move it either; in
    /// lockstep each reading is written back for the board, otherwise nothing is.
    #[test]
    fn the_shared_clock_is_the_boards_time_and_never_runs_ahead() {
        for lockstep in [false, true] {
            let (socket, f) = shared_file(&format!("shared-{lockstep}"), 5_000_000);
            let mut c = BoardClock::with_shared(SharedClock::beside(&socket).unwrap());
            c.set_lockstep(lockstep);
            assert!(c.shares_board_time());
            assert_eq!(c.in_lockstep(), lockstep);
            assert_eq!(c.now_s(1.0, true), 1.0, "starts where the host's clock was");
            // The board stands for 2 s of host time, statuses or not.
            assert_eq!(c.now_s(3.0, true), 1.0);
            c.received(3.0, true);
            assert_eq!(c.now_s(3.5, true), 1.0);
            // The board runs 10 ms.
            f.write_all_at(&shared_clock::encode(5_010_000), shared_clock::BOARD_US)
                .unwrap();
            assert!((c.now_s(3.5, true) - 1.01).abs() < 1e-12);
            assert_eq!(master_slot(&f), if lockstep { 5_010_000 } else { 0 });
            // Not paced: the host's clock (ahead here), and never back after it.
            assert_eq!(c.now_s(4.0, false), 4.0);
            assert_eq!(c.now_s(4.0, true), 4.0);
            let _ = std::fs::remove_file(socket.with_extension("sock.clock"));
        }
    }

    /// A shared clock is taken only from a file its board keeps: one not written for
    /// longer than `SHARED_CLOCK_STALE_S` (a board killed without removing it), a short
    /// one, or none at all are not (the master then counts statuses).
    #[test]
    fn a_stale_or_missing_shared_clock_is_not_taken() {
        let (socket, f) = shared_file("stale", 1_000);
        assert!(SharedClock::beside(&socket).is_some(), "fresh: taken");
        let old = SystemTime::now() - Duration::from_secs_f64(SHARED_CLOCK_STALE_S + 1.0);
        f.set_times(std::fs::FileTimes::new().set_modified(old))
            .unwrap();
        assert!(SharedClock::beside(&socket).is_none(), "stale: not taken");
        f.set_len(8).unwrap();
        f.set_times(std::fs::FileTimes::new().set_modified(SystemTime::now()))
            .unwrap();
        assert!(SharedClock::beside(&socket).is_none(), "short: not taken");
        let _ = std::fs::remove_file(socket.with_extension("sock.clock"));
        assert!(SharedClock::beside(&socket).is_none(), "none: not taken");
        // A board that has not written its time yet gives no reading: statuses pace.
        let (socket, f) = shared_file("unwritten", 0);
        let mut c = BoardClock::with_shared(SharedClock::beside(&socket).unwrap());
        c.received(2.0, true);
        assert_eq!(c.now_s(2.005, true), 2.005);
        drop(f);
        let _ = std::fs::remove_file(socket.with_extension("sock.clock"));
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
