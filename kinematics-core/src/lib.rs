//! Kinematics of the RSPR and USR parallel robots (Simaan, thesis chapters 6, 7 and 10).
//!
//! `#![no_std]`, allocation-free and panic-free: every function returns a typed error
//! instead of panicking or producing NaN. Generic over the scalar (`f32` on the MCU, `f64`
//! on the host) through nalgebra's [`RealField`](nalgebra::RealField).
//!
//! Conventions (frames, units, joint order, branch numbering) follow the repository's
//! `CONVENTIONS.md`:
//! SI units everywhere, world frame at the base centre with x towards e_1, platform frame at
//! the platform centre with x towards p_1, joints `q = [l1, l2, l3, θ1, θ2, θ3]` (RSPR) or
//! `[α1, α2, α3, β1, β2, β3]` (USR), twists `[v; ω]` in the world frame.
//!
//! Like Klipper's kinematics, every robot offers the same few verbs and keeps the per-chain
//! part a small pure function ([`Mechanism::chain_ik`] and [`Mechanism::serial_block`]);
//! one generic implementation of the Jacobian ([`jacobian()`]), the forward kinematics
//! ([`fk`]), the statics ([`statics`]), the singularity measures ([`singularity`]) and the
//! spherical-joint tilt ([`tilt`]) serves both robots, and the RSPR with per-chain
//! dimensions and encoder zero offsets that a calibration identifies ([`chain_geometry`];
//! the symmetric robot is one instance of it).
#![no_std]
#![deny(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::indexing_slicing,
    clippy::unreachable,
    clippy::todo
)]
// `!(x > limit)` is deliberate throughout: unlike `x <= limit` it is also true for NaN, so
// a NaN can never pass a check.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod branch;
pub mod chain;
pub mod chain_geometry;
mod double_buffer;
pub mod fk;
pub mod geometry;
pub mod guards;
pub mod ik;
pub mod jacobian;
pub mod lu;
pub mod mechanism;
pub mod pose;
pub mod robot;
pub mod rspr;
pub mod scalar;
pub mod singularity;
pub mod statics;
pub mod supervisor;
pub mod tilt;
pub mod usr;
pub mod vectors;

pub use branch::Branch;
pub use chain::{Chain, PerChain};
pub use chain_geometry::{ChainDimensions, PerChainGeometry};
pub use fk::{forward, FkConfig, FkError, FkSolution, FkTracker, Tracked, TrackerCounts};
pub use geometry::{GeometryError, RsprGeometry, UsrGeometry};
pub use ik::{inverse, IkError, Solution};
pub use jacobian::{jacobian, JacobianError, Jacobians};
pub use mechanism::{ChainSolution, IkFailure, JointKind, Mechanism, SerialBlock};
pub use pose::Pose;
pub use robot::{Robot, RobotKind};
pub use scalar::Real;
pub use singularity::{measures, Measures, Nearest};
pub use statics::{actuator_forces, ForceError};
pub use tilt::{socket_axis, tilt_angles, SocketAxes};
pub use vectors::{Joints, Twist, Wrench};
