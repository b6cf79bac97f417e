//! The control application of the RSPR robot (thesis section 11.4), hardware-agnostic so
//! that the same code runs on the STM32 board, in the emulators and on the host against the
//! plant model. The hardware sits behind the small traits of the `hal` crate.
//!
//! One control tick ([`runtime::Runtime::tick`]), as the code runs it:
//! ```text
//! sensing     counters read once -> extended counts -> motors -> joints (less the backlash
//!             offsets) -> measured pose
//!             (FK tracker: one Newton step per tick while the joints move)
//! runtime     heartbeat timers; the state machine decides what runs:
//!   homing    switches, currents -> joint references -> outputs
//!   planner   master target -> supervisor (path check, guards, speed/accel profile)
//!             -> safe setpoint pose, its joints (IK) and feed-forward J·twist
//!   drive     six joint servos (PID, backlash, tracking monitor) -> PWM duties
//! telemetry   the status from what the tick computed
//! ```
//! The board targets run the [`service::TickService`] around the runtime (e-stop latch,
//! queued master requests, timing, watchdog decision, status).
//!
//! Modules, by concept:
//! - the tick's halves: [`sensing`], [`planner`], [`drive`], composed by [`controller`];
//! - the board's behaviour: [`state_machine`], [`homing`], [`runtime`], [`service`];
//! - safety: the stop categories and their table ([`stops`]), the holding brakes
//!   ([`brakes`]), the current limits ([`current`]), the plausibility monitors
//!   ([`monitors`]), the second position channel against the encoders ([`absolute`]), the
//!   fault log ([`faults`]) and the non-volatile event log ([`event_log`]), the heartbeat
//!   ([`heartbeat`]), the e-stop's interrupt path ([`estop`]) and the deadline
//!   ([`watchdog`]); the safety requirements all of it serves, with their bounds
//!   ([`safety`]);
//! - the calibrated geometry: [`geometry_store`] (the checks of a received
//!   record, its flash layout and log);
//! - the master link's board side: [`link`] (frames to requests, replies to frames),
//!   [`targets`] (target timestamps), [`wire`] (wire values), [`telemetry`] (the status).
#![no_std]
#![deny(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::indexing_slicing
)]
// `!(x <= limit)` is deliberate: unlike `x > limit` it is also true for NaN, so a NaN can
// never pass a check.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod absolute;
pub mod brakes;
pub mod commissioning;
pub mod controller;
pub mod current;
pub mod drive;
pub mod estop;
pub mod event_log;
pub mod faults;
pub mod geometry_store;
pub mod heartbeat;
pub mod homing;
pub mod homing_load;
pub mod link;
pub mod modes;
pub mod monitors;
pub mod park;
pub mod planner;
pub mod runtime;
pub mod safety;
pub mod scalar;
pub mod sensing;
pub mod service;
pub mod session;
pub mod stops;
pub mod targets;
pub mod telemetry;
pub mod watchdog;
pub mod wire;

pub use controller::{Controller, ControllerConfig, ControllerError, JogError};
pub use drive::{Drive, TickReport};
pub use planner::{Plan, Planner, ToolLoad};
pub use scalar::Scalar;
pub use sensing::{Measured, PoseStatus, Sensing, SensingError};
