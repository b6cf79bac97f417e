//! `operator`: the operator's front ends on a live board, over the board's link (a Unix
//! socket: the simulated board of `host-sim board` or the emulator; or a serial device: a
//! real board; the same code path for all three).
//!
//! - [`board`]: the board as the front ends see it: requests tracked until answered, the
//!   latest status, heartbeats, the bring-up from any state the board is in (hello, a
//!   reset or a fault only with the person's say-so, homing when needed, enable);
//! - [`teleoperation`]: master-slave teleoperation with a hand controller ([`devices`]:
//!   SpaceMouse through spacenavd or evdev, a UDP position master, the keyboard), recorded
//!   to MCAP, with the latency measured;
//! - [`replay`]: a recorded session's summary and plots (`host-sim replay`);
//! - [`console`]: the terminal console (ratatui) a person drives the robot with;
//! - [`navigation`]: the OpenIGTLink bridge for 3D Slicer, PLUS and trackers;
//! - [`view`]: the live 3-D view for Foxglove (the robot description, its transforms, the
//!   poses, joints, margins and the latched fault on the Foxglove SDK's WebSocket server);
//! - [`shutdown`]: the one way out of every front end (SIGINT, SIGTERM, an error): the
//!   robot disabled.
//!
//! Names follow the dVRK/CRTK conventions: `measured_cp` (the measured pose),
//! `setpoint_cp` (the supervisor's setpoint), `servo_cp` (a target streamed at the servo
//! rate), clutch, operator present.

pub mod board;
pub mod console;
pub mod conversions;
pub mod devices;
pub mod error;
pub mod navigation;
pub mod replay;
pub mod shutdown;
pub mod teleoperation;
pub mod view;

pub use board::{Board, BoardError, BoardEvent, BringUpTimeouts, Outcome, Reply};
pub use error::OperatorError;
