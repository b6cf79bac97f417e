//! What stops a teleoperation run.

use kinematics_core::IkError;
use master_link::Seq;
use std::path::PathBuf;
use thiserror::Error;

/// Why the master stopped (a failed check is not an error until the run's end:
/// [`TeleopError::ChecksFailed`]).
#[derive(Debug, Error)]
pub enum TeleopError {
    /// The socket or device cannot be found, opened or duplicated.
    #[error("{}: {source}", path.display())]
    Open {
        path: PathBuf,
        source: std::io::Error,
    },
    /// The socket refuses the connection.
    #[error("connect {}: {source}", path.display())]
    Connect {
        path: PathBuf,
        source: std::io::Error,
    },
    /// A message that does not fit a frame (`message` and `reason` as debug text).
    #[error("encode {message}: {reason}")]
    Encode { message: String, reason: String },
    /// A hand-made frame of the garbage check that cannot be built.
    #[error("{0}")]
    Frame(String),
    /// The board answered a request with something else than its answer.
    #[error("{request} answered with {reply}")]
    UnexpectedReply {
        request: &'static str,
        reply: String,
    },
    #[error("link write: {0}")]
    Write(std::io::Error),
    /// The board closed the link (end of stream, a read error).
    #[error("link closed: {0}")]
    Closed(String),
    #[error("link reader stopped")]
    ReaderStopped,
    #[error("the board has been silent for {0} s")]
    Silent(f64),
    #[error("no reply to request {seq} within {timeout_s} s")]
    NoReply { seq: Seq, timeout_s: f64 },
    #[error("no HelloReply within {0} s")]
    NoHello(f64),
    #[error("the link key file {} is not 64 hexadecimal digits", .0.display())]
    KeyFile(std::path::PathBuf),
    #[error("the board refused the Hello: {0:?}")]
    HelloRefused(master_link::NackReason),
    /// A step needs a status that has not arrived (`when` says which step).
    #[error("no status {0}")]
    NoStatus(&'static str),
    /// The central pose of the reference robot (a defect of the build).
    #[error("central pose: {0:?}")]
    CentralPose(IkError),
    /// The telemetry file.
    #[error("{}: {source}", path.display())]
    CreateDir {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{}: {source}", path.display())]
    Telemetry { path: PathBuf, source: csv::Error },
    #[error("{0}")]
    TelemetryRow(csv::Error),
    #[error("{0}")]
    TelemetryFlush(std::io::Error),
    /// The run's end: checks that failed.
    #[error("{} of {total} checks failed: {}", failed.len(), failed.join("; "))]
    ChecksFailed { failed: Vec<String>, total: usize },
}
