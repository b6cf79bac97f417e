//! The integration tests of this crate in one binary: each file of `tests/` is a module
//! of it (one build and one link instead of one per file). A file left out would never
//! run: `tests/tests/test_binaries.rs` at the top fails then.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod batch_errors;
mod calibrate;
mod check;
mod commission;
mod common;
mod compare;
mod dct;
mod design_synth;
mod design_tables;
#[path = "design.rs"]
mod design_tests;
mod faultlog;
mod front_ends_on_a_board;
mod geometry_files;
mod guards_column;
mod hand_controller;
#[path = "identify.rs"]
mod identify_tests;
mod jacobian_forces;
mod output_rule;
mod readme_commands;
mod report;
mod round_trip;
mod served_board;
mod sim;
mod single_form;
mod singularity_lines;
mod teleop_fake_board;
