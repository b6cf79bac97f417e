//! `ros2`: the ROS 2 interface of a live board with CRTK names, on the pure-Rust
//! `ros2-client` (RustDDS): any ROS 2 node (rclcpp, rclpy, on any RMW over DDS) sees it,
//! and no ROS installation is needed to run it.
//!
//! - [`messages`]: the standard messages (and CRTK's) as serde structs in the IDL's layout;
//! - [`crtk`]: the CRTK operating state of a board status, the `state_command` words;
//! - [`convert`]: a status as the messages, a `servo_cp` as a target;
//! - [`node`]: the DDS participant (on the loopback by default), the node, its topics;
//! - [`bridge`]: the loop between the board and the node.
//!
//! Topics (relative to the namespace, `/rspr` by default):
//!
//! | topic | type | direction |
//! | --- | --- | --- |
//! | `measured_cp`, `setpoint_cp` | `geometry_msgs/PoseStamped` ({p} in `base`) | published, 100 Hz |
//! | `measured_js`, `setpoint_js` | `sensor_msgs/JointState` (l1..l3 m, theta1..3 rad) | published, 100 Hz |
//! | `/joint_states` | `sensor_msgs/JointState` (every joint of the URDF, passive ones computed, at the measured joints) | published, 100 Hz |
//! | `/tf` | `tf2_msgs/TFMessage` (every joint of the URDF: `base` → ... → `platform`) | published, 100 Hz |
//! | `operating_state` | `crtk_msgs/OperatingState` | published on change and at 10 Hz |
//! | `diagnostics` | `diagnostic_msgs/DiagnosticArray` (latched fault, guard margins) | published at 10 Hz |
//! | `refusal` | `std_msgs/String` (a refused command and its reason) | published |
//! | `servo_cp` | `geometry_msgs/PoseStamped` | subscribed: a target |
//! | `servo_jp` | `sensor_msgs/JointState` (the six actuated joints by name) | subscribed: its forward kinematics a target |
//! | `state_command` | `crtk_msgs/StringStamped` (enable, disable, home, pause, resume) | subscribed |

pub mod bridge;
pub mod convert;
pub mod crtk;
pub mod messages;
pub mod node;

pub use bridge::{Bridge, BridgeError, Counters};
pub use node::{Network, NodeConfig, NodeError, RosNode};
