//! The simulated board on a Unix socket, paced by the wall clock: a master (`host-sim
//! teleop`, the console, the OpenIGTLink bridge, `host-sim faultlog`) connects to it as to a
//! board on a desk.
//!
//! The board keeps its own, virtual, time ([`ServePacing`]): one control tick per
//! millisecond of it, never skipped. It follows the wall clock where the host lets it; a
//! host that falls behind makes the board pause (its clock slips), never jump, so that
//! what the board's deadline policy, heartbeat watch and current monitors measure is the
//! board's time, not the host's stalls. While a master is connected the board also runs at
//! most [`ServePacing::master_lead_us`] beyond the last bytes it received: a master its
//! host holds up holds the board with it (a master paced by the board's clock,
//! `teleop::pacing`, then sees no pause at all). With [`ServePacing::clock_lead_us`] the
//! board shares its clock beside the socket (`master_link::shared_clock`): a master that
//! reads it runs on the board's own time, and one that writes back its readings holds the
//! board within that lead of them (lockstep: the operator's `Board::set_lockstep`).
//!
//! Several connections at once are one shared line: each connection's
//! bytes reach the board frame by frame (a frame is never cut by another connection's),
//! and every connection hears everything the board sends. Who commands the robot is the
//! board's rule, not the socket's: the master that owns it (the last `Hello` it accepted)
//! keeps it while the robot is enabled, and a second connection cannot cut it off. A
//! master that reconnects says Hello again, as with a real board.

use std::io::{ErrorKind, Read, Write};
use std::os::unix::fs::FileExt;
use std::os::unix::net::{UnixListener, UnixStream};
use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use master_link::ResetCause;
use thiserror::Error;

use crate::board::{BoardSim, BoardSimConfig, BoardSimError};

/// Why the served board stopped.
#[derive(Debug, Error)]
pub enum ServeError {
    #[error("cannot listen on {path}: {source}")]
    Bind {
        path: String,
        source: std::io::Error,
    },
    #[error("socket: {0}")]
    Io(#[from] std::io::Error),
    #[error(transparent)]
    Board(#[from] BoardSimError),
}

/// How the served board's virtual clock follows the wall clock and its masters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ServePacing {
    /// How far behind the wall clock the board catches up at most, µs: further behind, its
    /// clock slips (the board pauses) instead of running fast or jumping.
    pub catch_up_us: u64,
    /// While a master is connected, the board runs at most this far beyond the board time
    /// it last received bytes at, µs (`None`: it does not wait for its masters). Below the
    /// board's heartbeat hold (100 ms), above the masters' heartbeat period (20 ms).
    pub master_lead_us: Option<u64>,
    /// How long, by the host's clock, the board waits for silent masters before it runs on
    /// without them (a master that stopped its heartbeats on purpose, or hangs with its
    /// socket open): a failure detector, not a deadline of the board's.
    pub master_wait: Duration,
    /// Share the board's clock beside the socket (`master_link::shared_clock`) and, while
    /// a connected master writes back its readings of it, run at most this far beyond the
    /// last one, µs (instead of `master_lead_us` for that master), as
    /// `board-emulator serve --clock-lead-ms` does (`None`: no shared clock).
    pub clock_lead_us: Option<u64>,
}

impl Default for ServePacing {
    /// Catch up at most 10 ms, a master lead of 50 ms, a master wait of 2 s.
    fn default() -> Self {
        ServePacing {
            catch_up_us: 10_000,
            master_lead_us: Some(50_000),
            master_wait: Duration::from_secs(2),
            clock_lead_us: None,
        }
    }
}

/// A master's connection and the bytes of its frame not yet complete.
struct Connection {
    stream: UnixStream,
    partial: Vec<u8>,
}

/// Serves a board built from `cfg` on `socket` until `stop` is set, paced as
/// [`ServePacing::default`]. `ready` is called once the socket listens.
pub fn serve(
    socket: &Path,
    cfg: BoardSimConfig,
    stop: &AtomicBool,
    ready: &dyn Fn(),
) -> Result<(), ServeError> {
    serve_paced(socket, cfg, ServePacing::default(), stop, ready)
}

/// Serves a board built from `cfg` on `socket` until `stop` is set: one control tick per
/// millisecond of the board's virtual time, which follows the wall clock and its masters
/// as `pacing` says. `ready` is called once the socket listens.
pub fn serve_paced(
    socket: &Path,
    cfg: BoardSimConfig,
    pacing: ServePacing,
    stop: &AtomicBool,
    ready: &dyn Fn(),
) -> Result<(), ServeError> {
    let _ = std::fs::remove_file(socket);
    // The shared clock before the socket: a master that connects finds it there.
    let clock = match pacing.clock_lead_us {
        Some(_) => Some(SharedClock::create(socket)?),
        None => None,
    };
    let listener = UnixListener::bind(socket).map_err(|source| ServeError::Bind {
        path: socket.display().to_string(),
        source,
    })?;
    listener.set_nonblocking(true)?;
    ready();
    let mut board = BoardSim::new(cfg, ResetCause::PowerOn, None)?;
    let period_us = u64::from(board.config().service.watchdog.period_us).max(1);
    // The wall instant of board time 0, moved on by what the board's clock slipped.
    let mut origin = Instant::now()
        .checked_sub(Duration::from_micros(board.now_us()))
        .unwrap_or_else(Instant::now);
    // The board time and the host instant of the masters' last bytes.
    let mut last_rx_us = board.now_us();
    let mut last_rx = Instant::now();
    // The masters' last reading of the shared clock, board µs.
    let mut last_reading: Option<u64> = None;
    let mut conns: Vec<Connection> = Vec::new();
    let mut buf = [0u8; 4096];
    while !stop.load(Ordering::Relaxed) {
        while let Ok((s, _)) = listener.accept() {
            s.set_nonblocking(true)?;
            if let Some(c) = &clock {
                c.forget_master()?;
                last_reading = None;
            }
            last_rx_us = board.now_us();
            last_rx = Instant::now();
            conns.push(Connection {
                stream: s,
                partial: Vec::new(),
            });
        }
        conns.retain_mut(|c| match c.stream.read(&mut buf) {
            Ok(0) => false,
            Ok(n) => {
                last_rx_us = board.now_us();
                last_rx = Instant::now();
                // Whole frames only: the bytes up to each delimiter.
                for &b in buf.get(..n).unwrap_or_default() {
                    c.partial.push(b);
                    // (A run longer than any frame is passed on as it is: the board's
                    // decoder counts it oversized.)
                    if b == 0 || c.partial.len() >= 2 * master_link::MAX_FRAME_LEN {
                        board.receive(&c.partial);
                        c.partial.clear();
                    }
                }
                true
            }
            Err(e) if e.kind() == ErrorKind::WouldBlock => true,
            Err(_) => false,
        });
        // Tick up to the wall clock; further behind than the catch-up, the clock slips.
        let wall_us = origin.elapsed().as_micros() as u64;
        let behind_us = wall_us.saturating_sub(board.now_us());
        if behind_us > pacing.catch_up_us {
            origin += Duration::from_micros(behind_us - pacing.catch_up_us);
        }
        let reading = clock.as_ref().and_then(SharedClock::master_reading_us);
        if reading.is_some() && reading != last_reading {
            // A new reading: the master runs.
            last_reading = reading;
            last_rx = Instant::now();
        }
        for _ in 0..behind_us.min(pacing.catch_up_us) / period_us {
            let quiet_us = |since: u64| board.now_us().saturating_sub(since);
            let beyond = match (pacing.clock_lead_us, reading) {
                (Some(lead), Some(r)) => quiet_us(r) >= lead,
                _ => pacing
                    .master_lead_us
                    .is_some_and(|lead| quiet_us(last_rx_us) >= lead),
            };
            let waits_for_master =
                !conns.is_empty() && beyond && last_rx.elapsed() < pacing.master_wait;
            if waits_for_master {
                // The board's clock stands until the master's next bytes (the wall time
                // this takes slips off the next round).
                break;
            }
            board.tick()?;
        }
        let out = board.take_output();
        if !out.is_empty() {
            conns.retain_mut(|c| c.stream.write_all(&out).is_ok());
        }
        // The board's time once what it sent until then is on its way.
        if let Some(c) = &clock {
            c.publish(board.now_us())?;
        }
        std::thread::sleep(Duration::from_micros(500));
    }
    let _ = std::fs::remove_file(socket);
    Ok(())
}

/// The board's clock shared with its masters (`master_link::shared_clock`): the file
/// beside the socket, created afresh and removed when the board ends.
struct SharedClock {
    file: std::fs::File,
    path: std::path::PathBuf,
}

impl SharedClock {
    fn create(socket: &Path) -> Result<Self, std::io::Error> {
        let mut name = socket.as_os_str().to_owned();
        name.push(master_link::shared_clock::SUFFIX);
        let path = std::path::PathBuf::from(name);
        let file = std::fs::File::options()
            .read(true)
            .write(true)
            .create(true)
            .truncate(true)
            .open(&path)?;
        file.set_len(master_link::shared_clock::LEN)?;
        Ok(SharedClock { file, path })
    }

    fn publish(&self, now_us: u64) -> Result<(), std::io::Error> {
        self.file.write_all_at(
            &master_link::shared_clock::encode(now_us),
            master_link::shared_clock::BOARD_US,
        )
    }

    fn forget_master(&self) -> Result<(), std::io::Error> {
        self.file.write_all_at(
            &master_link::shared_clock::encode(0),
            master_link::shared_clock::MASTER_US,
        )
    }

    /// The board time a master last read, µs (None: none written, or unreadable now; two
    /// reads in a row must agree, as a write may race a read).
    fn master_reading_us(&self) -> Option<u64> {
        let read = || {
            let mut b = [0u8; 8];
            self.file
                .read_exact_at(&mut b, master_link::shared_clock::MASTER_US)
                .ok()?;
            Some(master_link::shared_clock::decode(b))
        };
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
}

impl Drop for SharedClock {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.path);
    }
}
