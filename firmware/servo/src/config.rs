//! Configuration of the whole servo layer.
//!
//! Each module has its six-joint configuration ([`PidConfig`], [`BacklashConfig`],
//! [`TrackingConfig`], [`EncoderConfig`](crate::EncoderConfig)) made of one per-joint
//! struct per joint, with `Default` values for the RSPR prototype's plant (legs `l1..l3`
//! then links `theta1..3`) and a `validate()` that names the first bad field and joint
//! ([`ConfigError`]).

use num_traits::Float;

use crate::backlash::BacklashConfig;
pub use crate::checks::ConfigError;
use crate::pid::PidConfig;
use crate::tracking::TrackingConfig;

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
