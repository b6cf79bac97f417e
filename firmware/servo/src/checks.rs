//! The checks of the configurations and the error every `validate()` returns.

use core::fmt;

use num_traits::Float;

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
///
/// Each check is out of line: a configuration is validated once, off the control tick,
/// and a check inlined at each of its call sites (every field of every joint, the loops
/// unrolled) is some 200 bytes of a firmware image's text where a call is a dozen.
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
    #[inline(never)]
    pub fn non_negative<S: Float>(&self, field: &'static str, v: S) -> Result<(), ConfigError> {
        if v.is_finite() && v >= S::zero() {
            Ok(())
        } else {
            Err(self.err(field, "must be finite and >= 0"))
        }
    }

    /// Finite and > 0.
    #[inline(never)]
    pub fn positive<S: Float>(&self, field: &'static str, v: S) -> Result<(), ConfigError> {
        if v.is_finite() && v > S::zero() {
            Ok(())
        } else {
            Err(self.err(field, "must be finite and > 0"))
        }
    }

    /// In `(0, 1]`.
    #[inline(never)]
    pub fn unit_fraction<S: Float>(&self, field: &'static str, v: S) -> Result<(), ConfigError> {
        if v > S::zero() && v <= S::one() {
            Ok(())
        } else {
            Err(self.err(field, "must be in (0, 1]"))
        }
    }
}

/// Joints 0..3 are the prismatic legs, 3..6 the rotating links.
pub(crate) fn is_leg(joint: usize) -> bool {
    joint < NUM_JOINTS / 2
}
