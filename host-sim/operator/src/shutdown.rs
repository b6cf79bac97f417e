//! The one way out of a front end: whatever ends it (the person's quit, the end of its
//! script or duration, SIGINT, SIGTERM, an error of its own), a robot it may have enabled
//! is disabled before it closes the link.
//!
//! [`Shutdown::on_signals`] turns SIGINT and SIGTERM into a flag (signal-hook; a second
//! signal while the first is being handled ends the process at once, exit status 1: the
//! board's heartbeat timeout then stops the robot). The front end's loops end when the flag
//! is set, and every wait on the board ([`Board::set_interrupt`]) ends with
//! [`BoardError::Interrupted`]. [`with_board`] runs a front end's body and then, in every
//! case, [`disable`]: `Disable` sent unless the last status shows the drives off, and its
//! answer waited for at most [`DISABLE_TIMEOUT_S`], far inside the board's 500 ms
//! heartbeat timeout, so that a front end that ends is never taken for a lost master
//! (a `HeartbeatTimeout` fault that the next bring-up would find latched).

use crate::board::{Board, BoardError, Outcome};
use crate::error::OperatorError;
use master_link::RobotState;
use signal_hook::consts::{SIGINT, SIGTERM};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::Arc;

pub use teleop::ci::DISABLE_TIMEOUT_S;

/// The stop flag of a front end, set by SIGINT or SIGTERM (or by the front end itself).
#[derive(Clone, Debug)]
pub struct Shutdown {
    flag: Arc<AtomicBool>,
    signal: Arc<AtomicUsize>,
}

impl Shutdown {
    /// A flag no signal sets (the tests, a front end inside another program).
    pub fn manual() -> Self {
        Shutdown {
            flag: Arc::new(AtomicBool::new(false)),
            signal: Arc::new(AtomicUsize::new(0)),
        }
    }

    /// A flag set by SIGINT and SIGTERM; a second one ends the process at once.
    pub fn on_signals() -> Result<Self, OperatorError> {
        let s = Shutdown::manual();
        for sig in [SIGINT, SIGTERM] {
            let io = |source| OperatorError::Signals { source };
            // Order matters: the conditional exit sees the flag as the earlier signal
            // left it.
            signal_hook::flag::register_conditional_shutdown(sig, 1, Arc::clone(&s.flag))
                .map_err(io)?;
            signal_hook::flag::register(sig, Arc::clone(&s.flag)).map_err(io)?;
            signal_hook::flag::register_usize(sig, Arc::clone(&s.signal), sig as usize)
                .map_err(io)?;
        }
        Ok(s)
    }

    /// The flag (for the loops that poll it).
    pub fn flag(&self) -> &Arc<AtomicBool> {
        &self.flag
    }

    /// Sets the flag (a front end that ends itself, e.g. after its duration).
    pub fn request(&self) {
        self.flag.store(true, Ordering::Relaxed);
    }

    /// Whether a stop was asked.
    pub fn requested(&self) -> bool {
        self.flag.load(Ordering::Relaxed)
    }

    /// The signal that asked for the stop, if a signal did.
    pub fn signal(&self) -> Option<&'static str> {
        match self.signal.load(Ordering::Relaxed) {
            0 => None,
            x if x == SIGINT as usize => Some("SIGINT"),
            x if x == SIGTERM as usize => Some("SIGTERM"),
            _ => Some("a signal"),
        }
    }
}

/// Disables the robot unless the last status shows its drives off (`Boot`, `Disabled`,
/// `Ready`): `Disable`, its answer waited for at most [`DISABLE_TIMEOUT_S`]; `log` hears
/// what it came to.
pub fn disable(board: &mut Board, log: &mut dyn FnMut(&str)) {
    let state = board.status().map(|(_, s)| s.state);
    if matches!(
        state,
        Some(RobotState::Boot | RobotState::Disabled | RobotState::Ready)
    ) || board.hello_info().is_none()
    {
        board.set_interrupt(None);
        return;
    }
    match board.disable_within(DISABLE_TIMEOUT_S) {
        Ok(Outcome::Ack) => log(&format!(
            "robot disabled on the way out (was {})",
            state.map_or("?", board_words::state)
        )),
        Ok(o) => log(&format!("Disable on the way out: {}", o.words())),
        Err(e) => log(&format!("Disable on the way out: {e}")),
    }
}

/// Runs a front end's `body` on `board` with the waits interrupted by `shutdown`, then
/// [`disable`]s, whatever the body came to. An error that is only the stop asked by a
/// signal is no error: the front end ends as asked.
pub fn with_board<T: Default, E: From<BoardError>>(
    board: &mut Board,
    shutdown: &Shutdown,
    log: &mut dyn FnMut(&str),
    body: impl FnOnce(&mut Board) -> Result<T, E>,
    interrupted: impl Fn(&E) -> bool,
) -> Result<T, E> {
    board.set_interrupt(Some(Arc::clone(shutdown.flag())));
    let result = body(board);
    disable(board, log);
    match result {
        Err(e) if shutdown.requested() && interrupted(&e) => {
            log(&format!(
                "stopped by {}",
                shutdown.signal().unwrap_or("request")
            ));
            Ok(T::default())
        }
        r => r,
    }
}
