//! What the command line reports on failure: one line, `error: <message>`, the message of
//! the library error that stopped the command.

use crate::batch::BatchError;
use crate::commands::check::CheckError;
use crate::commands::RowError;
use crate::flags::FlagError;
use design::compare::PairError;
use design::ranges::RangesError;
use design::synth::{SynthError, SynthTaskError};
use design::workspace::WorkspaceError;
use design::{DesignError, FileError};
use robot_config::{GeometryFileError, LimitsFileError};
use simulation::{ConfigError, OutputError, RunError, SimError, UnknownScenario};
use teleop::TeleopError;
use thiserror::Error;

/// Why a command failed.
#[derive(Debug, Error)]
pub enum CliError {
    #[error(transparent)]
    Flag(#[from] FlagError),
    /// A row-wise command: the input as a whole, or the single form's row.
    #[error(transparent)]
    Batch(#[from] BatchError<RowError>),
    #[error(transparent)]
    Check(#[from] CheckError),
    #[error(transparent)]
    Geometry(#[from] GeometryFileError),
    #[error(transparent)]
    Limits(#[from] LimitsFileError),
    #[error(transparent)]
    Design(#[from] DesignError),
    /// `dct`: the double circular-triangular robot has no solution at the pose.
    #[error("dct: {0}")]
    Dct(#[from] design::dct_robot::DctError),
    #[error(transparent)]
    SynthTask(#[from] SynthTaskError),
    #[error(transparent)]
    Sim(#[from] SimError),
    #[error(transparent)]
    Teleop(#[from] TeleopError),
    /// The operator's front ends (hand controller, console, OpenIGTLink, replay).
    #[error(transparent)]
    Operator(#[from] operator::OperatorError),
    /// The ROS 2 node could not be set up.
    #[error(transparent)]
    Ros2Node(#[from] ros2::NodeError),
    /// The ROS 2 side failed while serving (the board's errors are `Operator`'s).
    #[error(transparent)]
    Ros2(ros2::BridgeError),
    #[error(transparent)]
    Campaign(#[from] faults::CampaignError),
    #[error(transparent)]
    Report(#[from] faults::report::ReportError),
    #[error(transparent)]
    BoardSim(#[from] simulation::board::BoardSimError),
    #[error(transparent)]
    Serve(#[from] simulation::serve::ServeError),
    /// `describe`: the description, its input or its output.
    #[error("describe: {0}")]
    Describe(String),
    /// `ros2`: the robot description of the geometry in use.
    #[error("ros2: the robot description: {0}")]
    Ros2Description(String),
    /// `view`: its server, its recording or its flags.
    #[error("view: {0}")]
    View(String),
    #[error("unknown {what} `{name}`")]
    UnknownName { what: &'static str, name: String },
    #[error("cannot create {path}: {source}")]
    CreateDir {
        path: String,
        source: std::io::Error,
    },
    #[error("{0} cells of the campaign failed")]
    CampaignFailed(usize),
    #[error("compare needs an RSPR geometry (its rb, rp and hc are used with e = 0)")]
    CompareNeedsRspr,
    #[error("{0} robots: narrow the ranges (at most 200000)")]
    TooManyRobots(usize),
    #[error(transparent)]
    Calibration(#[from] calibration::CalibrationError),
    /// `identify`: the identification, the tuning or a run on the joint.
    #[error("identify: {0}")]
    Identify(#[from] identify::IdentifyError),
    #[error("calibrate needs an RSPR geometry (the nominal robot or an earlier calibration)")]
    CalibrateNeedsRspr,
    #[error("cannot write {}: {error}", path.display())]
    Output {
        path: std::path::PathBuf,
        error: String,
    },
    #[error("cannot read {}: {error}", path.display())]
    Input {
        path: std::path::PathBuf,
        error: String,
    },
    #[error("calibrate upload: the board {0}")]
    Upload(String),
    /// Measurement rows whose joints lie outside the robot's ranges.
    #[error(
        "{count} joint readings outside the robot's ranges (a typo or another robot): {first}; \
         fix them, or pass --drop-out-of-range to drop those rows"
    )]
    OutOfRange { count: usize, first: String },
    /// Measurements that determine too few combinations (written, not trusted).
    /// `commission`: a refusal, a fault or a bad flag, in words.
    #[error("commission: {0}")]
    Commission(String),
    #[error("calibrate: {0}; --force accepts the result anyway")]
    Underdetermined(String),
    /// `replay` of a file that does not start with MCAP's magic bytes.
    #[error(
        "{}: not an MCAP file (a session recording of `host-sim teleop --device` starts \
         with the MCAP magic bytes; this one starts with {first:?})",
        path.display()
    )]
    NotMcap {
        path: std::path::PathBuf,
        first: String,
    },
}

/// Library errors that reach the command line through their crate's error.
macro_rules! through {
    ($($error:ty => $via:ident),* $(,)?) => {
        $(impl From<$error> for CliError {
            fn from(e: $error) -> Self {
                CliError::$via(e.into())
            }
        })*
    };
}

through!(
    FileError => Design,
    design::OutputError => Design,
    WorkspaceError => Design,
    SynthError => Design,
    PairError => Design,
    RangesError => Design,
    ConfigError => Sim,
    UnknownScenario => Sim,
    RunError => Sim,
    OutputError => Sim,
    operator::BoardError => Operator,
);

impl From<ros2::BridgeError> for CliError {
    /// The board's errors as every front end's (a stop by a signal is recognised there).
    fn from(e: ros2::BridgeError) -> Self {
        match e {
            ros2::BridgeError::Board(b) => CliError::Operator(b.into()),
            other => CliError::Ros2(other),
        }
    }
}
