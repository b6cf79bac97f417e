//! The integration tests of this crate in one binary: each file of `tests/` is a module
//! of it (one build and one link instead of one per file). A file left out would never
//! run: `every_test_file_is_a_module` fails then.
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
