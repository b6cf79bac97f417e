//! What stops an operator's front end.

use crate::board::BoardError;
use std::path::PathBuf;
use thiserror::Error;

/// Why a front end stopped.
#[derive(Debug, Error)]
pub enum OperatorError {
    /// The board: its link, its answers, its state.
    #[error(transparent)]
    Board(#[from] BoardError),
    /// An input device.
    #[error(transparent)]
    Device(#[from] masters::DeviceError),
    /// The teleoperation mapping's settings or input.
    #[error(transparent)]
    Teleop(#[from] masters::TeleopError),
    #[error(transparent)]
    Cue(#[from] masters::workspace_cue::EdgeCueError),
    #[error(transparent)]
    Rate(#[from] masters::rate::RateConfigError),
    #[error(transparent)]
    Keyboard(#[from] masters::keyboard::KeyboardConfigError),
    /// The session recording.
    #[error(transparent)]
    Recording(#[from] masters::recording::RecordingError),
    #[error("terminal: {0}")]
    Terminal(std::io::Error),
    /// The console's thread that draws the screen panicked.
    #[error("terminal: the console's drawing thread panicked")]
    DrawerPanicked,
    /// The OpenIGTLink server.
    #[error(transparent)]
    Igtl(#[from] igtl::ServerError),
    #[error(transparent)]
    Registration(#[from] igtl::pose::RegistrationError),
    #[error(transparent)]
    Plot(#[from] plots::PlotError),
    #[error("{}: {source}", path.display())]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error(
        "device `{0}`: expected spacemouse, spacenavd[:SOCKET], evdev[:PATH], udp:PORT or keyboard"
    )]
    DeviceSpec(String),
}
