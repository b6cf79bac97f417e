//! Configuration of the whole servo layer and the error every `validate()` returns.
//!
//! Each module has its six-joint configuration ([`PidConfig`], [`BacklashConfig`],
//! [`TrackingConfig`], [`EncoderConfig`](crate::EncoderConfig)) made of one per-joint
//! struct per joint, with `Default` values for the RSPR prototype's plant (legs `l1..l3`
//! then links `theta1..3`) and a `validate()` that names the first bad field and joint.

use core::fmt;

use num_traits::Float;

use crate::backlash::BacklashConfig;
use crate::pid::PidConfig;
use crate::tracking::TrackingConfig;
use crate::{joint_name, NUM_JOINTS};

/// A configuration value out of its range: names the section, the field and the joint.
///
/// Displays as e.g. `pid.kp of joint 3 (theta1) must be finite and >= 0`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ConfigError {
    /// Configuration section: `"pid"`, `"backlash"`, `"tracking"` or `"encoder"`.
    pub section: &'static str,
    /// Field name inside the per-joint struct, e.g. `"kp"`.
    pub field: &'static str,
    /// Joint index 0..6 (joint order `l1, l2, l3, theta1, theta2, theta3`).
    pub joint: usize,
    /// What the value must satisfy, e.g. `"must be finite and >= 0"`.
    pub requirement: &'static str,
}

impl fmt::Display for ConfigError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{}.{} of joint {} ({}) {}",
            self.section,
            self.field,
            self.joint,
            joint_name(self.joint),
            self.requirement
        )
    }
}

impl core::error::Error for ConfigError {}

/// The field checks shared by the `validate()` functions.
pub(crate) struct Check {
    pub section: &'static str,
    pub joint: usize,
}

impl Check {
    fn err(&self, field: &'static str, requirement: &'static str) -> ConfigError {
        ConfigError {
            section: self.section,
            field,
            joint: self.joint,
            requirement,
        }
    }

    /// Finite and >= 0.
    pub fn non_negative<S: Float>(&self, field: &'static str, v: S) -> Result<(), ConfigError> {
        if v.is_finite() && v >= S::zero() {
            Ok(())
        } else {
            Err(self.err(field, "must be finite and >= 0"))
        }
    }

    /// Finite and > 0.
    pub fn positive<S: Float>(&self, field: &'static str, v: S) -> Result<(), ConfigError> {
        if v.is_finite() && v > S::zero() {
            Ok(())
        } else {
            Err(self.err(field, "must be finite and > 0"))
        }
    }

    /// In `(0, 1]`.
    pub fn unit_fraction<S: Float>(&self, field: &'static str, v: S) -> Result<(), ConfigError> {
        if v > S::zero() && v <= S::one() {
            Ok(())
        } else {
            Err(self.err(field, "must be in (0, 1]"))
        }
    }
}

/// Everything [`JointServo`](crate::JointServo) needs: PID gains, backlash compensation
/// and tracking-error limits, per joint. `Default` gives the values for the prototype's
/// plant (see each section's documentation).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ServoConfig<S> {
    /// PID gains and feed-forward, per joint.
    pub pid: PidConfig<S>,
    /// Lead-screw backlash compensation, per joint.
    pub backlash: BacklashConfig<S>,
    /// Tracking-error and stuck-encoder limits, per joint.
    pub tracking: TrackingConfig<S>,
}

impl<S: Float> Default for ServoConfig<S> {
    fn default() -> Self {
        ServoConfig {
            pid: PidConfig::default(),
            backlash: BacklashConfig::default(),
            tracking: TrackingConfig::default(),
        }
    }
}

impl<S: Float> ServoConfig<S> {
    /// Checks every section; the error names the first bad field and its joint.
    pub fn validate(&self) -> Result<(), ConfigError> {
        self.pid.validate()?;
        self.backlash.validate()?;
        self.tracking.validate()
    }
}

/// Joints 0..3 are the prismatic legs, 3..6 the rotating links.
pub(crate) fn is_leg(joint: usize) -> bool {
    joint < NUM_JOINTS / 2
}
