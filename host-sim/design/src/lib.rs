//! `design`: the design tools over the thesis's task (chapter 8).
//!
//! - [`forces_path`]: the actuator forces along a straight path (`host-sim forces --path`);
//! - [`ranges`]: the joint, tilt and force ranges over the task box (`host-sim ranges`,
//!   the columns of Tables 8.2/8.3);
//! - [`workspace`]: constant-height sections of the reachable workspace and the verdict on
//!   the task box (`host-sim workspace`);
//! - [`synth`]: the dimensional synthesis scan (`host-sim synth`) and its task file;
//! - [`compare`]: the RSPR with zero eccentricity against the RRPS (`host-sim compare`),
//!   with the RRPS kinematics in [`rrps`];
//! - [`dct`]: the planar circle-triangle mechanism of the double circular-triangular robot
//!   (Appendix A), its kinematics and Jacobian by virtual work;
//! - [`report`]: the readable report of a robot over the task box (`host-sim report`);
//! - [`files`]: the output directory and the CSV files.
//!
//! Every file goes to an output directory, by default `target/design/<command>/` (relative
//! to the working directory); mm, deg, N and N m at the edge, unit-suffixed column names.
//! A tool's run returns the text to print; nothing here prints.

pub mod compare;
pub mod dct;
pub mod dct_robot;
pub mod files;
pub mod forces_path;
pub mod ranges;
pub mod report;
pub mod rrps;
pub mod synth;
pub mod workspace;

pub use files::{FileError, OutputError};
pub use plots::PlotError;

use thiserror::Error;

/// Why a design tool stopped.
#[derive(Debug, Error)]
pub enum DesignError {
    /// An output file, directory or plot.
    #[error(transparent)]
    Output(#[from] OutputError),
    /// The ranges over the task.
    #[error(transparent)]
    Ranges(#[from] ranges::RangesError),
    /// The workspace scan's guards.
    #[error(transparent)]
    Workspace(#[from] workspace::WorkspaceError),
    /// The synthesis scan.
    #[error(transparent)]
    Synth(#[from] synth::SynthError),
    /// The robots of the comparison.
    #[error(transparent)]
    Pair(#[from] compare::PairError),
}

impl From<FileError> for DesignError {
    fn from(e: FileError) -> Self {
        DesignError::Output(e.into())
    }
}

impl From<PlotError> for DesignError {
    fn from(e: PlotError) -> Self {
        DesignError::Output(e.into())
    }
}
