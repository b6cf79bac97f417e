//! The guards that keep every setpoint safe (thesis 3.2 and 11.4).
//!
//! One [`Limits`] value holds every limit; [`Guards`] prepares it for one robot and branch
//! (socket axes, central joint values) and evaluates a pose. Every guard produces a
//! [`Reading`] with the measured value, the limit and the signed margin, so the same code
//! gives a [`Verdict`] (the violations, each with its severity) for the supervisor and the
//! worst margins for the design tools. Nothing here allocates or panics.
//!
//! - [`readings`]: the vocabulary (guards, subjects, severities, readings, verdicts);
//! - [`limits`]: the limits and their reference values;
//! - [`setup`]: the guards prepared for one robot and branch;
//! - [`pose`]: the pose guards (workspace, reach, joint ranges, tilt, collision,
//!   singularities, payload statics), in place ([`Guards::evaluate_pose_into`]) or as a
//!   convenience ([`Guards::evaluate_pose`], [`Guards::check_pose`]);
//! - [`staged`]: a full pose evaluation spread over several calls, one stage each;
//! - [`motion`]: the motion guards (speeds and accelerations of the platform and joints).

pub mod certificate;
pub mod limits;
pub mod motion;
pub mod pose;
pub mod readings;
pub mod setup;
pub mod staged;

pub use certificate::{Certificate, Constraint, FullEvaluation, GuardMinima, Rate};
pub use limits::{Levels, Limits, LimitsError};
pub use motion::MotionSample;
pub use pose::{orientation_distance, Depth, Evaluation, GuardMargins, Solved};
pub use readings::{Guard, Reading, Severity, Subject, Verdict, MAX_VIOLATIONS};
pub use setup::{GuardSetupError, Guards};
pub use staged::{Stage, Staged, MAX_STAGES};
