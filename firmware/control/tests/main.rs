//! The integration tests of this crate in one binary: each file of `tests/` is a module
//! of it (one build and one link instead of one per file). A file left out would never
//! run: `tests/tests/test_binaries.rs` at the top fails then.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod channel;
mod closed_loop;
mod commissioning;
mod common;
mod event_log;
mod events;
mod failsafe;
mod flags;
mod geometry_store;
mod link;
mod modes;
mod monitors;
mod position_channel_resolution;
mod readme;
mod session;
mod state;
mod stops;
