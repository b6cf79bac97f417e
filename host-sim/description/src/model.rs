//! The robot description as data: links with their shapes, joints with their frames and
//! axes, the way URDF states them; and the tree's own forward kinematics (each link's
//! frame in the base frame for given joint values), which is what a URDF consumer
//! (RViz's robot_state_publisher, Foxglove, yourdfpy, Slicer) computes from the file.

use nalgebra::{Isometry3, Translation3, Unit, UnitQuaternion, Vector3};
use std::collections::HashMap;

/// The kind of a joint, with the limits URDF requires for the bounded kinds (SI).
#[derive(Clone, Debug, PartialEq)]
pub enum JointType {
    /// A revolute joint within [lower, upper] rad.
    Revolute {
        lower: f64,
        upper: f64,
        effort: f64,
        velocity: f64,
    },
    /// A revolute joint without limits (a passive joint of the description).
    Continuous,
    /// A prismatic joint within [lower, upper] m.
    Prismatic {
        lower: f64,
        upper: f64,
        effort: f64,
        velocity: f64,
    },
    /// No motion.
    Fixed,
}

impl JointType {
    /// URDF's name of the kind.
    pub fn urdf_name(&self) -> &'static str {
        match self {
            JointType::Revolute { .. } => "revolute",
            JointType::Continuous => "continuous",
            JointType::Prismatic { .. } => "prismatic",
            JointType::Fixed => "fixed",
        }
    }
}

/// Whether a joint is driven by a motor or follows the closed chains.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Drive {
    /// One of the six actuated joints (named as in CONVENTIONS.md: `l1`, `theta1`, ...).
    Actuated,
    /// A passive joint (spherical joint components, the platform's revolute pins),
    /// computed by the kinematics.
    Passive,
    /// A fixed joint (no value).
    Fixed,
}

/// One joint: the child's frame is `origin * motion(value)` in the parent's frame, where
/// the motion is a rotation about `axis` (revolute, continuous) or a translation along it
/// (prismatic), URDF's semantics.
#[derive(Clone, Debug, PartialEq)]
pub struct Joint {
    pub name: String,
    pub kind: JointType,
    pub drive: Drive,
    pub parent: String,
    pub child: String,
    /// The joint frame in the parent link's frame.
    pub origin: Isometry3<f64>,
    /// The unit axis in the joint frame.
    pub axis: Vector3<f64>,
}

impl Joint {
    /// The child link's frame in the parent's for a joint value (rad or m).
    pub fn transform(&self, value: f64) -> Isometry3<f64> {
        let motion = match self.kind {
            JointType::Revolute { .. } | JointType::Continuous => Isometry3::from_parts(
                Translation3::identity(),
                UnitQuaternion::from_axis_angle(&Unit::new_normalize(self.axis), value),
            ),
            JointType::Prismatic { .. } => Isometry3::from_parts(
                Translation3::from(self.axis * value),
                UnitQuaternion::identity(),
            ),
            JointType::Fixed => Isometry3::identity(),
        };
        self.origin * motion
    }
}

/// A primitive shape at real dimensions (m).
#[derive(Clone, Debug, PartialEq)]
pub enum Shape {
    /// A cylinder along its frame's z, centred on its origin.
    Cylinder { radius: f64, length: f64 },
    /// A box centred on its origin.
    Box { size: [f64; 3] },
    /// A sphere centred on its origin.
    Sphere { radius: f64 },
}

/// A shape of a link, placed in the link's frame, with a colour by name.
#[derive(Clone, Debug, PartialEq)]
pub struct Visual {
    pub origin: Isometry3<f64>,
    pub shape: Shape,
    /// One of [`MATERIALS`].
    pub material: &'static str,
}

/// The colours of the description: name and RGBA.
pub const MATERIALS: [(&str, [f64; 4]); 5] = [
    ("base", [0.35, 0.35, 0.38, 1.0]),
    ("link", [0.20, 0.45, 0.80, 1.0]),
    ("joint", [0.85, 0.55, 0.15, 1.0]),
    ("leg", [0.70, 0.70, 0.72, 1.0]),
    ("platform", [0.25, 0.70, 0.35, 1.0]),
];

/// One link and its shapes.
#[derive(Clone, Debug, PartialEq)]
pub struct Link {
    pub name: String,
    pub visuals: Vec<Visual>,
}

/// A joint value the tree needs that was not given.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("joint {0} has no value (every moving joint of the description needs one)")]
pub struct MissingJoint(pub String);

/// The robot's tree: links and joints in URDF order (each joint after its parent link's
/// joint), rooted at [`crate::BASE_FRAME`].
#[derive(Clone, Debug, PartialEq)]
pub struct Tree {
    pub name: String,
    pub links: Vec<Link>,
    pub joints: Vec<Joint>,
}

impl Tree {
    /// Every link's frame in the base frame, for the values of every moving joint (rad,
    /// m): the tree walked from the root, joint by joint.
    pub fn link_poses(
        &self,
        values: &HashMap<String, f64>,
    ) -> Result<HashMap<String, Isometry3<f64>>, MissingJoint> {
        let mut poses = HashMap::new();
        poses.insert(crate::BASE_FRAME.to_string(), Isometry3::identity());
        for j in &self.joints {
            let value = match j.kind {
                JointType::Fixed => 0.0,
                _ => *values
                    .get(&j.name)
                    .ok_or_else(|| MissingJoint(j.name.clone()))?,
            };
            // Joints come after their parent's joint (built that way), so the parent's
            // pose is known.
            let parent = poses
                .get(&j.parent)
                .copied()
                .unwrap_or_else(Isometry3::identity);
            poses.insert(j.child.clone(), parent * j.transform(value));
        }
        Ok(poses)
    }
}
