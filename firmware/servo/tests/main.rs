//! The integration tests of this crate in one binary: each file of `tests/` is a module
//! of it (one build and one link instead of one per file). A file left out would never
//! run: `tests/tests/test_binaries.rs` at the top fails then.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod backlash;
mod common;
mod encoder;
mod joint_servo;
mod pid;
mod tracking;
