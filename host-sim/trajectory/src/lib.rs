//! `trajectory`: what a master sends to the robot, as timed poses (SI inside, the edge
//! form mm/deg only in the settings).
//!
//! - [`Profile`]: a trapezoidal speed profile from rest to rest;
//! - [`Figure8`]: the laparoscope's closed figure-eight, by arc length;
//! - [`Piece`] and [`Trajectory`]: holds, straight moves ([`line()`], within the master's
//!   [`MasterLimits`]) and loops, one after the other; [`Phase`]: a stretch judged on its
//!   own;
//! - [`laparoscope()`]: the laparoscope path of `host-sim sim` and `host-sim teleop` from
//!   its settings ([`Laparoscope`]);
//! - [`Jump`], [`Stream`] and [`Sampler`]: what the master sends (a path sampled at its
//!   stream rate, or single targets) and when each target reaches the robot;
//! - [`pose_mm_deg`], [`offset_pose`]: poses from the settings' edge form;
//! - [`best_fitting_delay`]: the lag of the setpoints behind the stream ([`Lag`]).

pub mod figure8;
pub mod lag;
pub mod laparoscope;
pub mod path;
pub mod pose;
pub mod profile;
pub mod stream;

pub use figure8::Figure8;
pub use lag::{best_fitting_delay, Lag};
pub use laparoscope::{laparoscope, Laparoscope};
pub use path::{line, MasterLimits, Phase, Piece, Trajectory};
pub use pose::{offset_pose, pose_mm_deg};
pub use profile::Profile;
pub use stream::{Jump, Sampler, Stream};
