//! The integration tests of this crate in one binary: each file of `tests/` is a module
//! of it (one build and one link instead of one per file). A file left out would never
//! run: `tests/tests/test_binaries.rs` at the top fails then.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod authority;
mod board;
mod channel;
mod clear_fault;
mod homing;
mod power_cycle;
mod refusals;
mod sim;
mod stop_precedence;
