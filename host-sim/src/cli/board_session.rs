//! A front end's session with a board: the SIGINT and SIGTERM flag, and the one way out
//! (`operator::shutdown`) that disables the robot whatever ends the session. Used by every
//! front end that holds a board: `teleop --device`, `console`, `igtl`, `view`, `ros2`.

use crate::error::CliError;
use operator::board::{Board, BringUpTimeouts};
use operator::shutdown::{self, Shutdown};
use teleop::start::StartOptions;

/// The SIGINT and SIGTERM flag of a front end (`operator::shutdown`).
pub(crate) fn shutdown_on_signals() -> Result<Shutdown, CliError> {
    Ok(Shutdown::on_signals()?)
}

/// Runs a front end's body on `board` through the one way out (`operator::shutdown`):
/// the robot disabled whatever ended it; the stop a signal asked is no error.
pub(crate) fn with_board<T: Default>(
    board: &mut Board,
    shutdown: &Shutdown,
    body: impl FnOnce(&mut Board) -> Result<T, CliError>,
) -> Result<T, CliError> {
    shutdown::with_board(
        board,
        shutdown,
        &mut |m| eprintln!("board: {m}"),
        body,
        |e| matches!(e, CliError::Operator(o) if o.is_interrupted()),
    )
}

/// Asks `shutdown` after `duration_s` (None: never): a front end's `--duration`.
pub(crate) fn stop_after(shutdown: &Shutdown, duration_s: Option<f64>) {
    if let Some(d) = duration_s {
        let s = shutdown.clone();
        std::thread::spawn(move || {
            std::thread::sleep(std::time::Duration::from_secs_f64(d.max(0.0)));
            s.request();
        });
    }
}

/// Brings the board where a serving front end (`igtl`, `ros2`) starts from: homed and
/// enabled with `enable`, else only connected, its state taken as `start` allows; each
/// step printed.
pub(crate) fn bring_up_or_connect(
    board: &mut Board,
    enable: bool,
    start: StartOptions,
) -> Result<(), CliError> {
    let log = &mut |m: &str| println!("board: {m}");
    if enable {
        board.bring_up(&BringUpTimeouts::default(), start, log)?;
    } else {
        board.connect(10.0, start, log)?;
    }
    Ok(())
}
