//! The shipped reference geometry files (`geometry/*.toml`) load from disk and equal the
//! built-in references (the command line on them: host-sim/tests/geometry_files.rs).
#![allow(clippy::unwrap_used, clippy::expect_used)]

use kinematics_core::{Robot, RsprGeometry, UsrGeometry};
use robot_config::geometry_file::load;
use std::path::PathBuf;

/// The path of a shipped geometry file.
fn geometry(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("geometry")
        .join(name)
}

/// A geometry file that cannot be read names the file.
#[test]
fn a_missing_file_is_named() {
    let e = load(&geometry("missing.toml")).unwrap_err().to_string();
    assert!(
        e.starts_with("geometry file ") && e.contains("missing.toml: cannot read: "),
        "{e}"
    );
}

#[test]
fn reference_files_equal_the_built_in_robots() {
    assert_eq!(
        load(&geometry("reference-rspr.toml")).unwrap(),
        Robot::Rspr(RsprGeometry::reference())
    );
    assert_eq!(
        load(&geometry("reference-usr.toml")).unwrap(),
        Robot::Usr(UsrGeometry::reference())
    );
}
