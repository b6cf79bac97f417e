//! The integration tests of this crate in one binary: each file of `tests/` is a module
//! of it (one build and one link instead of one per file). A file left out would never
//! run: `tests/tests/test_binaries.rs` at the top fails then.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod certificate;
mod chain_geometry;
mod common;
mod condition;
mod fk_tracker;
mod guards;
mod imports;
mod line_geometry;
mod lu;
mod pose;
mod precision;
mod profile;
mod properties;
mod supervisor;
