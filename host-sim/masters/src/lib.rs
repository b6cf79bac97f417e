//! `masters`: what the surgeon holds. Input devices behind one small trait ([`Master`]),
//! the teleoperation semantics ([`Teleop`]: clutch, motion scaling, operator presence,
//! tremor filter, velocity/acceleration limits; [`EdgeCue`]) and recorded sessions
//! ([`recording`], MCAP). Names follow the surgical-robotics community's conventions
//! (dVRK, CRTK): `measured_cp`, `servo_cp`, `setpoint_cp`, clutch, operator present.
//!
//! Devices:
//! - [`spacenav`]: a 3Dconnexion SpaceMouse through the spacenavd daemon's socket;
//! - [`evdev`]: the same device straight from `/dev/input/event*`;
//! - [`udp`]: a position master streaming its pose in UDP datagrams;
//! - [`keyboard`]: jogging from key events.
//!
//! SI units in every API; millimetres and degrees at the edges (recordings, datagrams),
//! as the repository's `CONVENTIONS.md` says. See the crate's README for the formats and a
//! SpaceMouse walkthrough.

pub mod device;
pub mod evdev;
pub mod keyboard;
pub mod latency;
pub mod limits;
pub mod pose;
pub mod rate;
pub mod recording;
pub mod script;
pub mod spacenav;
pub mod teleop;
pub mod tremor;
pub mod udp;
pub mod workspace_cue;

pub use device::{DeviceError, Master, MasterInput, MasterKind, MasterSample, OperatorButtons};
pub use limits::MotionLimits;
pub use pose::{CartesianPose, Twist};
pub use recording::{Recording, RecordingWriter};
pub use teleop::{
    HoldReason, MotionScale, Teleop, TeleopConfig, TeleopError, TeleopOutput, TeleopState,
};
pub use tremor::{TremorFilter, TremorFilterConfig};
pub use workspace_cue::{CueLevel, EdgeCue, EdgeCueConfig};
