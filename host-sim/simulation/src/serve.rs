//! The simulated board on a Unix socket, paced by the wall clock: a master (`host-sim
//! teleop`, the console, the OpenIGTLink bridge, `host-sim faultlog`) connects to it as to a
//! board on a desk. One master at a time; a new connection gets the same board (a master
//! that reconnects says Hello again, as with a real board).

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
    let mut stream: Option<UnixStream> = None;
    let mut buf = [0u8; 4096];
    while !stop.load(Ordering::Relaxed) {
        if let Ok((s, _)) = listener.accept() {
            s.set_nonblocking(true)?;
            stream = Some(s);
        }
        if let Some(s) = stream.as_mut() {
            match s.read(&mut buf) {
                Ok(0) => stream = None,
                Ok(n) => board.receive(buf.get(..n).unwrap_or_default()),
                Err(e) if e.kind() == ErrorKind::WouldBlock => {}
                Err(_) => stream = None,
            }
        }
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
            if let Some(s) = stream.as_mut() {
                if s.write_all(&out).is_err() {
                    stream = None;
                }
            }
        }
        std::thread::sleep(Duration::from_micros(500));
    }
    let _ = std::fs::remove_file(socket);
    Ok(())
}
