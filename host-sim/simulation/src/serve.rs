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
//! `teleop::pacing`, then sees no pause at all).
//!
//! Several connections at once are one shared line: each connection's
//! bytes reach the board frame by frame (a frame is never cut by another connection's),
//! and every connection hears everything the board sends. Who commands the robot is the
//! board's rule, not the socket's: the master that owns it (the last `Hello` it accepted)
//! keeps it while the robot is enabled, and a second connection cannot cut it off. A
//! master that reconnects says Hello again, as with a real board.

use std::io::{ErrorKind, Read, Write};
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
}

impl Default for ServePacing {
    /// Catch up at most 10 ms, a master lead of 50 ms, a master wait of 2 s.
    fn default() -> Self {
        ServePacing {
            catch_up_us: 10_000,
            master_lead_us: Some(50_000),
            master_wait: Duration::from_secs(2),
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
    let mut conns: Vec<Connection> = Vec::new();
    let mut buf = [0u8; 4096];
    while !stop.load(Ordering::Relaxed) {
        while let Ok((s, _)) = listener.accept() {
            s.set_nonblocking(true)?;
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
        for _ in 0..behind_us.min(pacing.catch_up_us) / period_us {
            let waits_for_master = !conns.is_empty()
                && pacing
                    .master_lead_us
                    .is_some_and(|lead| board.now_us().saturating_sub(last_rx_us) >= lead)
                && last_rx.elapsed() < pacing.master_wait;
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
        std::thread::sleep(Duration::from_micros(500));
    }
    let _ = std::fs::remove_file(socket);
    Ok(())
}
