//! `robot-config`: the robot and its limits at the edge of the host tools.
//!
//! The core (`kinematics-core`) is SI; this crate is where millimetres and degrees meet it
//! (CONVENTIONS.md, "Units"). Modules:
//! - [`geometry_file`]: a robot's dimensions in TOML (`geometry/*.toml`);
//! - [`per_chain_file`]: a per-chain (calibrated) RSPR geometry in TOML;
//! - [`limits_file`]: the guards' limits in TOML (`limits/reference.toml`);
//! - [`selection`]: the robot and the limits a tool works with, and where they came from;
//! - [`mod@overlay`]: the one TOML overlay of a settings file onto its embedded defaults (the
//!   simulation's settings, the synthesis task);
//! - [`toml_error`]: a TOML error located in its text (line and key);
//! - [`units`]: mm/deg <-> SI and the number formats of the CSV and report output;
//! - [`edge`]: poses and joints in their edge form (unit-suffixed names, mm and deg);
//! - [`fields`]: the parser of input values (CSV fields by column name, numbers, branches);
//! - [`verdict`]: the guards' verdict on a pose and its texts in edge units;
//! - [`task_box`]: the thesis's task box and its grid.

pub mod edge;
pub mod fields;
pub mod geometry_file;
pub mod limits_file;
pub mod output;
pub mod overlay;
pub mod per_chain_file;
pub mod plausible;
pub mod selection;
pub mod task_box;
pub mod toml_error;
pub mod units;
pub mod verdict;

pub use geometry_file::{GeometryFileError, GeometryTextError};
pub use limits_file::{LimitsFileError, LimitsTextError};
pub use overlay::{overlay, OverlayError};
pub use selection::{kind_name, BuiltinRobot, SelectedLimits, SelectedRobot};
pub use task_box::{TaskBox, TaskBoxError};
pub use toml_error::TomlError;
