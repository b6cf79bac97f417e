//! One output-folder rule for every tool: `--out DIR`, else `target/<tool>/` under the
//! current directory (not the binary's build directory); and `replay` refuses a file
//! that is not MCAP with that reason.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use crate::common;
use common::host_sim;
use std::process::Command;

/// A fresh empty directory under the test's temporary directory.
fn fresh(name: &str) -> std::path::PathBuf {
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join(name);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

#[test]
fn a_tool_without_out_writes_under_the_current_directory() {
    let cwd = fresh("output-rule-cwd");
    let out = Command::new(env!("CARGO_BIN_EXE_host-sim"))
        .args(["calibrate", "plan", "--poses", "12"])
        .current_dir(&cwd)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(cwd.join("target/calibration/plan.csv").is_file());
    let dir = fresh("output-rule-out");
    let out = Command::new(env!("CARGO_BIN_EXE_host-sim"))
        .args(["forces", "--path", "diagonal", "--samples", "5", "--out"])
        .arg(&dir)
        .current_dir(&cwd)
        .output()
        .unwrap();
    assert!(out.status.success());
    assert!(dir.join("forces_path.csv").is_file());
    assert!(!cwd.join("target/design/forces").exists());
}

#[test]
fn replay_of_a_csv_says_it_is_not_an_mcap_file() {
    let dir = fresh("replay-csv");
    let csv = dir.join("trace.csv");
    std::fs::write(&csv, "t_s,x_mm\n0,1\n").unwrap();
    let r = host_sim(&["replay", csv.to_str().unwrap()], "");
    assert_eq!(r.code, Some(1));
    assert!(r.stderr.contains("not an MCAP file"), "{}", r.stderr);
}
