//! # board-on-plant: the RSPR board and the robot around the plant model
//!
//! The one plant-backed implementation of the firmware's hardware traits (`hal`): the
//! plant model of the six actuated joints (`plant`) with what the plant leaves to its
//! user, so that the board application runs on it as on the robot:
//!
//! * **the board** ([`BoardOnPlant`]): the drivers (enable; current regulation and
//!   overcurrent protection are the plant's), the brakes' two coil groups (legs, links),
//!   the supply and the drivers' shared fault line (nFAULT), the counters (with an offset
//!   per joint), the current sense (with an offset per joint: a failed amplifier);
//! * **the hard-wired e-stop chain**: the button opens the safety relay, which removes the
//!   drivers' power (the bridges coast) and the brake coils' power (the springs apply the
//!   brakes) without the MCU; a relay welded shut, or stuck open without the button;
//! * **the mechanics** ([`Layout`]): home and limit switches (actuated at and below their
//!   position, or forced to a level: a failed switch) and hard stops, where the firmware's
//!   reference mechanics put them ([`Layout::reference`] from [`ReferenceMechanics`], plain
//!   data: this crate does not depend on the control application, whose tests run on it);
//!   a stop seizes the load side while the motor drives into it and frees it when driven
//!   back out;
//! * **the platform** ([`Platform`]): the true pose of the load-side joints, and the
//!   tool's weight ([`Tool`]) and a stiff wall ([`Wall`]) as joint loads through
//!   τ = J^-T s_e at that pose (Eq. 7.10).
//!
//! Users: the simulated board (`host-sim/simulation`, `board`), the control application's
//! integration tests, the fuzz harness's starting points, and the board emulator's
//! mechanics, which map the pins onto it ([`BoardOnPlant::set_outputs`]). (The closed-loop
//! simulation's engine drives the bare plant, without a board: its own two-trait adaptor.)
//! Not modelled: switch bounce and hysteresis, PWM ripple, the platform's inertia.

pub mod board;
pub mod layout;
pub mod platform;

pub use board::{AtStop, BoardOnPlant, Wiring, STEP_S};
pub use layout::{Layout, ReferenceMechanics, LEG_STOP_BEYOND_RANGE_M, LINK_SWITCH_ABOVE_STOP_RAD};
pub use platform::{Platform, PlatformError, Tool, Wall, GRAVITY_M_S2};
