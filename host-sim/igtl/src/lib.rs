//! OpenIGTLink for the RSPR robot: a codec of protocol versions 2 and 3 (header versions
//! 1 and 2) and a server through which 3D Slicer (OpenIGTLinkIF), PLUS and tracking
//! systems send target poses and receive the robot's measured pose and state.
//!
//! - [`header`], [`metadata`], [`content`], [`message`]: the wire format.
//! - [`stream`]: framing a byte stream, with recovery from bad input.
//! - [`pose`]: millimetres and float32 on the wire, SI inside; the registration.
//! - [`robot`]: the trait the robot side implements; [`fake_robot`] a simulated one.
//! - [`server`]: the server; [`counters`] what it counts.
//!
//! See the crate README for the frame, the device names, and how errors are answered.

#![forbid(unsafe_code)]
#![warn(missing_docs)]

pub mod content;
pub mod counters;
pub mod crc;
pub mod fake_robot;
pub mod header;
pub mod message;
pub mod metadata;
pub mod pose;
pub mod robot;
pub mod server;
pub mod status;
pub mod stream;
pub mod timestamp;

pub use counters::Counters;
pub use header::{Header, HeaderVersion};
pub use message::{Body, DataType, Message, QueryKind};
pub use pose::{PoseSi, Registration};
pub use robot::{Condition, Refusal, RefusalReason, Robot, RobotState, TargetPose};
pub use server::{PollReport, Server, ServerConfig, ServerError};
pub use status::StatusCode;
pub use stream::{DecoderLimits, Event, MalformedKind, StreamDecoder};
pub use timestamp::Timestamp;
