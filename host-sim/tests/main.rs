//! The integration tests of this crate in one binary: each file of `tests/` is a module
//! of it (one build and one link instead of one per file). A file left out would never
//! run: `every_test_file_is_a_module` fails then.
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

/// Property: every `tests/*.rs` file is a module of this binary.
#[test]
fn every_test_file_is_a_module() {
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/tests");
    let main = include_str!("main.rs");
    let entries = std::fs::read_dir(dir).unwrap_or_else(|e| panic!("{dir}: {e}"));
    for entry in entries.flatten() {
        let name = entry.file_name().to_string_lossy().into_owned();
        if let Some(stem) = name.strip_suffix(".rs").filter(|s| *s != "main") {
            assert!(
                main.contains(&format!("mod {stem};"))
                    || main.contains(&format!("#[path = \"{stem}.rs\"]")),
                "tests/{name} is not a module of tests/main.rs: its tests would never run"
            );
        }
    }
}
