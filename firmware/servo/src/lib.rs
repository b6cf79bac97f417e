//! # servo: the per-joint servo building blocks of the RSPR surgical robot
//!
//! The control tick (1..10 kHz, on the STM32 and on the host against the plant model)
//! reads the six encoders (behind the `hal` crate's traits), computes the joint setpoints from the kinematics and calls
//! [`JointServo::update`], which returns the six H-bridge duties. This crate holds the
//! pieces of that chain:
//!
//! * [`encoder`]: extension of the wrapping 16-bit hardware counters to 64-bit counts,
//!   conversion to joint units and the homing offset;
//! * [`pid`]: a per-joint PID with derivative on the measurement through a low-pass
//!   filter, anti-windup, output saturation, velocity/acceleration/friction feed-forward,
//!   an error deadband and bumpless reset;
//! * [`backlash`]: the lead-screw backlash compensation (a ramped direction-reversal
//!   offset added to the position setpoint);
//! * [`tracking`]: the tracking-error (following-error) and stuck-encoder monitor with a
//!   latched, named fault;
//! * [`joint_servo`]: [`JointServo`], which composes the above for the six joints;
//! * [`config`]: the [`ConfigError`] every `validate()` returns and [`ServoConfig`].
//!
//! ## Conventions
//! * Joint order everywhere: `q = [l1, l2, l3, theta1, theta2, theta3]`: three prismatic
//!   lead-screw legs (m), then three rotating links (rad). SI units in every API
//!   (m, rad, s, m/s, rad/s, duty in [-1, 1], A).
//! * Positive duty drives the joint towards `+q` and makes its encoder count up.
//! * Generic over the scalar `S: num_traits::Float` (`f32` on the MCU, `f64` on the host).
//!
//! ## One control tick
//! ```
//! use hal::QuadratureCounter;
//! use servo::{EncoderConfig, Encoders, JointServo, ServoConfig};
//!
//! struct Counters([u16; 6]); // the timers in encoder mode
//! impl QuadratureCounter for Counters {
//!     fn counts(&mut self) -> [u16; 6] { self.0 }
//! }
//!
//! let mut encoders = Encoders::<f32>::new(&EncoderConfig::default()).unwrap();
//! let mut servo = JointServo::<f32>::new(&ServoConfig::default()).unwrap();
//! let mut hw = Counters([0; 6]);
//! encoders.set_positions(&[0.17, 0.17, 0.17, 0.0, 0.0, 0.0]); // homed
//!
//! // every 1 ms:
//! let measured = encoders.read(&mut hw);
//! let (setpoint, setpoint_velocity) = ([0.1701, 0.17, 0.17, 0.0, 0.0, 0.0], [0.0; 6]);
//! let out = servo.update(&setpoint, &setpoint_velocity, &measured, 1e-3);
//! assert!(out.fault.is_none() && out.duty[0] > 0.0); // drive l1 towards +q
//! // motors.set_duties(&out.duty); on a fault: motors.disable() and report out.fault
//! ```
//!
//! ## Guarantees
//! `#![no_std]`, no allocation, no `unsafe`, no panics (no `unwrap`/`expect`/indexing;
//! integer arithmetic wraps explicitly), constant work per call. Every output duty is
//! finite and inside its limit for every input; non-finite inputs give a zero duty and a
//! flag or a fault, never a NaN duty.
#![no_std]
#![forbid(unsafe_code)]
#![deny(missing_docs)]
#![deny(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::indexing_slicing
)]

pub mod backlash;
mod checks;
pub mod config;
pub mod encoder;
pub mod joint_servo;
mod num;
pub mod pid;
pub mod tracking;

/// Number of actuated joints (the hardware traits' [`hal::NUM_JOINTS`]).
pub const NUM_JOINTS: usize = hal::NUM_JOINTS;

/// Names of the joints, in joint order (used in error and fault messages).
pub const JOINT_NAMES: [&str; NUM_JOINTS] = ["l1", "l2", "l3", "theta1", "theta2", "theta3"];

/// Name of joint `joint`, or `"?"` outside `0..NUM_JOINTS`.
pub fn joint_name(joint: usize) -> &'static str {
    JOINT_NAMES.get(joint).copied().unwrap_or("?")
}

pub use backlash::{
    BacklashCompensator, BacklashConfig, BacklashOutput, BacklashParams, BacklashRamp, Direction,
};
pub use config::{ConfigError, ServoConfig};
pub use encoder::{CountExtender, EncoderConfig, Encoders, JointEncoder};
pub use joint_servo::{JointServo, ServoOutput};
pub use pid::{AntiWindup, InputError, Pid, PidConfig, PidGains, PidInput, PidOutput, PidTerms};
pub use tracking::{
    FaultKind, TrackingConfig, TrackingFault, TrackingLimits, TrackingMonitor, TrackingSample,
};
