//! The ROS 2 messages this node speaks, written out as plain structs whose serde layout is
//! the ROS 2 IDL's field order: serialized as CDR by `ros2-client`, they are what any ROS 2
//! node of that type reads. Each names its ROS 2 type ([`RosType`]): the DDS type name is
//! `<package>::msg::dds_::<Type>_` (ROS 2's type-name mangling, done by
//! `ros2_client::MessageTypeName`).
//!
//! Standard packages: `builtin_interfaces`, `std_msgs`, `geometry_msgs`, `sensor_msgs`,
//! `diagnostic_msgs`, `tf2_msgs`. The CRTK ones (`crtk_msgs/OperatingState`,
//! `crtk_msgs/StringStamped`) are those of the CRTK's own message package, as the dVRK
//! uses them for `operating_state` and `state_command`: a ROS 2 installation with
//! `crtk_msgs` built reads them as such, and DDS matches them by this name and layout.

use serde::{Deserialize, Serialize};

/// A message's ROS 2 type: package and type name (`geometry_msgs`, `PoseStamped`).
pub trait RosType {
    /// The package.
    const PACKAGE: &'static str;
    /// The type's name in the package.
    const NAME: &'static str;
}

macro_rules! ros_type {
    ($t:ty, $package:literal, $name:literal) => {
        impl RosType for $t {
            const PACKAGE: &'static str = $package;
            const NAME: &'static str = $name;
        }
    };
}

/// `builtin_interfaces/Time`: seconds and nanoseconds since the Unix epoch.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Time {
    pub sec: i32,
    pub nanosec: u32,
}

impl Time {
    /// The host's clock now (a clock before 1970 reads 0).
    pub fn now() -> Self {
        let d = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .unwrap_or_default();
        Time {
            sec: i32::try_from(d.as_secs()).unwrap_or(i32::MAX),
            nanosec: d.subsec_nanos(),
        }
    }
}

/// `std_msgs/Header`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Header {
    pub stamp: Time,
    pub frame_id: String,
}

/// `geometry_msgs/Point`, m.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Point {
    pub x: f64,
    pub y: f64,
    pub z: f64,
}

/// `geometry_msgs/Vector3`.
pub type Vector3 = Point;

/// `geometry_msgs/Quaternion` (x, y, z, w).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Quaternion {
    pub x: f64,
    pub y: f64,
    pub z: f64,
    pub w: f64,
}

impl Default for Quaternion {
    fn default() -> Self {
        Quaternion {
            x: 0.0,
            y: 0.0,
            z: 0.0,
            w: 1.0,
        }
    }
}

/// `geometry_msgs/Pose`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Pose {
    pub position: Point,
    pub orientation: Quaternion,
}

/// `geometry_msgs/PoseStamped`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct PoseStamped {
    pub header: Header,
    pub pose: Pose,
}
ros_type!(PoseStamped, "geometry_msgs", "PoseStamped");

/// `geometry_msgs/Transform`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Transform {
    pub translation: Vector3,
    pub rotation: Quaternion,
}

/// `geometry_msgs/TransformStamped`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct TransformStamped {
    pub header: Header,
    pub child_frame_id: String,
    pub transform: Transform,
}

/// `tf2_msgs/TFMessage` (the `/tf` topic).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct TfMessage {
    pub transforms: Vec<TransformStamped>,
}
ros_type!(TfMessage, "tf2_msgs", "TFMessage");

/// `sensor_msgs/JointState`: names, positions (m or rad), velocities, efforts.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct JointState {
    pub header: Header,
    pub name: Vec<String>,
    pub position: Vec<f64>,
    pub velocity: Vec<f64>,
    pub effort: Vec<f64>,
}
ros_type!(JointState, "sensor_msgs", "JointState");

/// `diagnostic_msgs/KeyValue`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct KeyValue {
    pub key: String,
    pub value: String,
}

/// `diagnostic_msgs/DiagnosticStatus`; `level` is one of the `LEVEL_*` constants.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct DiagnosticStatus {
    pub level: u8,
    pub name: String,
    pub message: String,
    pub hardware_id: String,
    pub values: Vec<KeyValue>,
}

impl DiagnosticStatus {
    /// `DiagnosticStatus.OK`.
    pub const OK: u8 = 0;
    /// `DiagnosticStatus.WARN`.
    pub const WARN: u8 = 1;
    /// `DiagnosticStatus.ERROR`.
    pub const ERROR: u8 = 2;
    /// `DiagnosticStatus.STALE`.
    pub const STALE: u8 = 3;
}

/// `diagnostic_msgs/DiagnosticArray`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct DiagnosticArray {
    pub header: Header,
    pub status: Vec<DiagnosticStatus>,
}
ros_type!(DiagnosticArray, "diagnostic_msgs", "DiagnosticArray");

/// `std_msgs/String`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct StdString {
    pub data: String,
}
ros_type!(StdString, "std_msgs", "String");

/// `crtk_msgs/OperatingState`: the CRTK operating state (`DISABLED`, `ENABLED`,
/// `PAUSED`, `FAULT`), whether the robot is homed and whether it is busy.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct OperatingState {
    pub header: Header,
    pub state: String,
    pub is_homed: bool,
    pub is_busy: bool,
}
ros_type!(OperatingState, "crtk_msgs", "OperatingState");

/// `crtk_msgs/StringStamped` (the dVRK's `state_command`).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct StringStamped {
    pub header: Header,
    pub string: String,
}
ros_type!(StringStamped, "crtk_msgs", "StringStamped");
