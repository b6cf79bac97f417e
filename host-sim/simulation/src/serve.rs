//! The simulated board on a Unix socket, paced by the wall clock: a master (`host-sim
//! teleop`, the console, the OpenIGTLink bridge, `host-sim faultlog`) connects to it as to a
//! board on a desk. Several connections at once are one shared line: each connection's
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

/// A master's connection and the bytes of its frame not yet complete.
struct Connection {
    stream: UnixStream,
    partial: Vec<u8>,
}

/// Serves a board built from `cfg` on `socket` until `stop` is set: every millisecond of
/// wall time one control tick (a tick that falls behind by more than 50 ms drops the
/// backlog: the board's own deadline policy is not what is simulated here). `ready` is
/// called once the socket listens.
pub fn serve(
    socket: &Path,
    cfg: BoardSimConfig,
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
    let start = Instant::now();
    let mut conns: Vec<Connection> = Vec::new();
    let mut buf = [0u8; 4096];
    while !stop.load(Ordering::Relaxed) {
        while let Ok((s, _)) = listener.accept() {
            s.set_nonblocking(true)?;
            conns.push(Connection {
                stream: s,
                partial: Vec::new(),
            });
        }
        conns.retain_mut(|c| match c.stream.read(&mut buf) {
            Ok(0) => false,
            Ok(n) => {
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
        // Tick up to the wall clock (at most 50 behind).
        let wall_us = start.elapsed().as_micros() as u64;
        let behind = wall_us.saturating_sub(board.now_us()) / 1000;
        let ticks = behind.min(50);
        for _ in 0..ticks {
            board.tick()?;
        }
        if behind > 50 {
            // Skip the backlog: the board's clock jumps with the wall clock.
            board.skip_to(wall_us);
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
