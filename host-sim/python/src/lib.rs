//! The kinematic analysis of the RSPR/USR robots from Python: the module `rspr` (PyO3,
//! built with maturin; see README.md). [`analysis`] (kinematics, singularities, the
//! guards' verdict) and [`design_tools`] (workspace, synthesis, comparison) are the
//! plain-Rust layer in edge units;
//! the bindings over it are compiled only with the feature `python`, which maturin turns
//! on, so the workspace's build and tests never compile or link PyO3.

pub mod analysis;
#[cfg(feature = "python")]
mod bindings;
pub mod design_tools;
