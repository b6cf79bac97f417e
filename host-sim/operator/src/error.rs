//! What stops an operator's front end.

use master_link::NackReason;
use std::path::PathBuf;
use thiserror::Error;

/// Why a front end stopped.
#[derive(Debug, Error)]
pub enum OperatorError {
    /// The link to the board (open, write, closed, silent).
    #[error(transparent)]
    Link(#[from] teleop::TeleopError),
    #[error("the board did not answer Hello within {timeout_s} s")]
    NoHello { timeout_s: f64 },
    #[error("the board speaks protocol version {board}, this master {master}")]
    Protocol { board: u8, master: u8 },
    #[error("no status from the board")]
    NoStatus,
    #[error("the board refused {request}: {reason:?} ({})", crate::board::refusal_text(*reason))]
    Refused { request: String, reason: NackReason },
    #[error("no answer to {request} within {} s", crate::board::REPLY_TIMEOUT_S)]
    NoReply { request: String },
    #[error("{what} did not finish within {timeout_s} s")]
    Timeout { what: &'static str, timeout_s: f64 },
    #[error("the board is {state}, not Enabled: enable it first")]
    NotEnabled { state: String },
    #[error("the board is in Fault: {cause}")]
    Faulted { cause: String },
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
