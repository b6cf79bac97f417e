//! `robot-description`: the robot description (URDF) of the RSPR and USR robots, generated
//! from the geometry in use (the reference robots or a calibrated per-chain file), and the
//! full joint-state vector (every joint of the description, the passive ones computed by
//! the kinematics) for a platform pose or for the actuated joints. Independent of ROS: the
//! ROS 2 node publishes `/joint_states` with [`JointStates`], the Foxglove scene sends the
//! transforms of [`Description::link_poses`], and `host-sim describe --urdf` writes
//! [`to_urdf`]. See the crate README for the tree and the API.
//!
//! - [`model`]: links, joints, shapes, and the tree's forward kinematics;
//! - [`robot`]: the description of a robot and its joint states;
//! - [`urdf`]: the URDF text.

pub mod model;
pub mod robot;
pub mod urdf;

pub use model::{Drive, Joint, JointType, Link, MissingJoint, Shape, Tree, Visual};
pub use robot::{Description, DescriptionError, JointStates};
pub use urdf::to_urdf;

/// The base frame {0} of CONVENTIONS.md: the description's root link and the frame id of
/// every pose in {0}.
pub const BASE_FRAME: &str = "base";
/// The platform frame {p} of CONVENTIONS.md: the description's platform link.
pub const PLATFORM_FRAME: &str = "platform";
