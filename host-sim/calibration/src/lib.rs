//! `calibration`: kinematic calibration of the RSPR robot from external measurements
//! (thesis sections 11.5 and 12.2).
//!
//! The robot built to drawings is off by its machining and assembly tolerances. This crate
//! estimates its per-chain geometry ([`kinematics_core::PerChainGeometry`]: base pivots and
//! axes, link lengths, platform joints and axes, leg offsets, encoder zeros) from joint
//! readings paired with the platform marker's pose (or position) that an external tracker
//! measured, together with the unknown tracker-to-base and marker-to-platform transforms.
//!
//! - [`parameters`]: the 54 parameters, their names and tolerances (the scales);
//! - [`rigid`]: rigid transforms;
//! - [`measurements`]: the measurement CSV format;
//! - [`model`]: the measurement model, its residuals and Jacobian;
//! - [`identify`]: Levenberg-Marquardt with an optional robust loss, restricted to the
//!   combinations the SVD of the identification Jacobian says are determined;
//! - [`plan`]: the poses to measure, chosen to maximise the observability;
//! - [`simulate`]: a "true" robot perturbed within tolerances, a noisy tracker, and the
//!   pose error over the task box before and after calibration and its noise limit;
//! - [`report`]: the text report, the calibrated geometry file and the residual plots.

pub mod identify;
pub mod measurements;
pub mod model;
pub mod parameters;
pub mod plan;
pub mod report;
pub mod rigid;
pub mod simulate;

use kinematics_core::{FkError, GeometryError, IkError};
use thiserror::Error;

/// Why a calibration step failed.
#[derive(Debug, Error)]
pub enum CalibrationError {
    #[error(transparent)]
    Measurements(#[from] measurements::MeasurementError),
    #[error("calibration: the parameters give an invalid robot: {0}")]
    Geometry(GeometryError),
    #[error("calibration: forward kinematics of measurement row {row} failed: {error}")]
    Fk { row: usize, error: FkError },
    #[error("calibration: inverse kinematics at measurement row {row} failed: {error}")]
    Ik { row: usize, error: IkError },
    #[error("calibration: the robot is singular at measurement row {row}")]
    Singular { row: usize },
    #[error(
        "calibration: the marker positions are degenerate (fewer than 3 distinct, or collinear)"
    )]
    Degenerate,
    #[error("calibration: {0} measurement rows; at least 4 are needed (and many more for a useful result)")]
    TooFewRows(usize),
    #[error("calibration: the measurements determine no parameter combination to its tolerance")]
    NothingDetermined,
    #[error("calibration: the solver stopped: {0}")]
    Solver(String),
    /// The tracker's noise (`what`: position or rotation) is no standard deviation.
    #[error("calibration: the tracker's {what} noise: {error}")]
    Noise {
        what: &'static str,
        error: rand_distr::NormalError,
    },
    #[error("calibration: no candidate pose of the task box passes the guards")]
    NoCandidates,
    #[error("calibration: {wanted} poses asked, {available} candidates pass the guards")]
    TooFewCandidates { wanted: usize, available: usize },
    #[error("calibration: {0}")]
    Io(#[from] std::io::Error),
    #[error(transparent)]
    Plot(#[from] plots::PlotError),
    #[error(transparent)]
    GeometryFile(#[from] robot_config::GeometryFileError),
}
