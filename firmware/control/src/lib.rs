//! The control application of the RSPR robot (thesis section 11.4), hardware-agnostic so
//! that the same code runs on the STM32 board, under QEMU and on the host against the plant
//! model. Each control tick:
//!
//! ```text
//! read encoders -> joint positions -> forward kinematics (measured pose)
//!               -> supervisor (target -> safe, rate-limited setpoint; its IK and guards)
//!               -> per-joint PID with velocity feed-forward J·twist -> PWM duties
//! ```
//! The hardware sits behind the small traits of [`servo::hal`]. The tick has two halves
//! ([`Controller::into_parts`]): the [`Planner`] (supervisor, the tool's backlash flanks),
//! which depends only on the master's targets, and the [`Drive`] (encoders, measured pose,
//! joint servos, outputs); the board runs them in turn, the host simulation may run the
//! planner ahead on another core.
#![no_std]
#![deny(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::indexing_slicing
)]

pub mod controller;
pub mod failsafe;
pub mod link;
pub mod state;

pub use controller::{
    Controller, ControllerConfig, ControllerError, Drive, JogError, Plan, Planner, Sensed,
    TickReport, ToolLoad,
};
