//! The CSV edge's column names and a row's fields found by column name: the parser is
//! `robot-config`'s ([`robot_config::fields`], shared with the Python module), the pose and
//! joint names and their conversions too ([`robot_config::edge`]).

pub use robot_config::edge::{
    joint_columns, joints_to_edge, pose_from_edge, pose_to_edge, EdgeError, POSE,
};
pub use robot_config::fields::*;
