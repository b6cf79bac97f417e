//! Why an identification, a tuning or a run on the joint failed.

use thiserror::Error;

/// Why an identification, a tuning or a run on the joint failed. Every message names the
/// joint, the quantity or the setting that was wrong.
#[derive(Debug, Error, PartialEq)]
pub enum IdentifyError {
    /// A joint index outside `0..6`.
    #[error("joint {0} does not exist (joints 0..5: l1, l2, l3, theta1, theta2, theta3)")]
    NoSuchJoint(usize),
    /// A setting out of its range.
    #[error("{name} = {value} is out of range: {expected}")]
    Setting {
        /// The setting, with its unit.
        name: &'static str,
        /// The value given.
        value: f64,
        /// What it must be.
        expected: &'static str,
    },
    /// A prior parameter (the drawing's values the excitation is designed from) is not
    /// finite and positive.
    #[error("prior {name} = {value} must be finite and positive")]
    Prior {
        /// The parameter, with its unit.
        name: &'static str,
        /// The value given.
        value: f64,
    },
    /// The limits leave no room for an excitation.
    #[error("no excitation fits: {0}")]
    NoExcitation(String),
    /// The recording does not match its excitation or is not usable.
    #[error("recording: {0}")]
    Recording(String),
    /// The joint left its travel limit during a run on it: the run was stopped.
    #[error(
        "joint {joint}: moved {moved:.6} (m or rad) from its start, beyond the test travel \
         {limit:.6}: stopped at tick {tick}"
    )]
    TravelExceeded {
        /// The joint.
        joint: &'static str,
        /// How far it had moved.
        moved: f64,
        /// The limit.
        limit: f64,
        /// The control tick at which it was stopped.
        tick: usize,
    },
    /// The motor current went beyond the stated limit during the excitation: stopped.
    #[error(
        "joint {joint}: current {current:.3} A beyond the excitation's limit {limit:.3} A: \
         stopped at tick {tick}"
    )]
    CurrentExceeded {
        /// The joint.
        joint: &'static str,
        /// The current measured.
        current: f64,
        /// The limit.
        limit: f64,
        /// The control tick.
        tick: usize,
    },
    /// Too few usable rows for a least-squares problem.
    #[error("{what}: {rows} usable rows, at least {needed} needed (a longer excitation)")]
    TooFewRows {
        /// The problem.
        what: &'static str,
        /// Rows found.
        rows: usize,
        /// Rows needed.
        needed: usize,
    },
    /// A row that is not finite.
    #[error("{what}: row {row} is not finite")]
    BadRow {
        /// The problem.
        what: &'static str,
        /// The row.
        row: usize,
    },
    /// The data do not tell an unknown apart from the others.
    #[error("{what}: the excitation does not identify {unknown} (rank-deficient rows)")]
    Unidentifiable {
        /// The problem.
        what: &'static str,
        /// The unknown least determined.
        unknown: &'static str,
    },
    /// The recording leaves a parameter too uncertain to use.
    #[error(
        "the excitation leaves {name} uncertain by {:.0} % (one sigma, more than 25 %): \
         too few segments moved the joint (more travel or a longer excitation)",
        100.0 * relative_std
    )]
    Uncertain {
        /// The parameter.
        name: &'static str,
        /// Its standard deviation over its value.
        relative_std: f64,
    },
    /// An identified parameter came out without physical sense.
    #[error("{name} identified as {value}: not physical ({why})")]
    NotPhysical {
        /// The parameter.
        name: &'static str,
        /// Its estimate.
        value: f64,
        /// Why it cannot be.
        why: &'static str,
    },
    /// The tuning has no solution for the specification.
    #[error("tuning: {0}")]
    Tuning(String),
    /// The board's servo refused the gains or tripped.
    #[error("servo: {0}")]
    Servo(String),
    /// The plant refused its parameters.
    #[error("plant: {0}")]
    Plant(String),
}
