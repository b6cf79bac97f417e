//! `host-sim compare`: the command prints the torque ratio of the RSPR with zero
//! eccentricity against the RRPS and writes its CSV and PNG (the comparison itself is
//! checked against an independent derivation in host-sim/design/tests/compare.rs).
#![allow(clippy::unwrap_used, clippy::expect_used)]

use crate::common;
use common::{ok, Table};
use std::path::PathBuf;

#[test]
fn compare_cli_prints_the_ratio_and_writes_csv_and_png() {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("compare-test");
    let _ = std::fs::remove_dir_all(&dir);
    let out = ok(&["compare", "--out", dir.to_str().unwrap()], "");
    assert!(out.contains("ratio RSPR/RRPS = 0.807"), "{out}");
    let t = Table::parse(&std::fs::read_to_string(dir.join("compare.csv")).unwrap());
    assert_eq!(t.rows.len(), 101);
    assert_eq!(t.header.len(), 7 + 12 + 1);
    assert_eq!(t.header[7], "rspr_f1_n");
    assert_eq!(t.header[18], "rrps_t3_nm");
    assert_eq!(t.num(0, "z_mm"), 150.0);
    for i in 0..101 {
        assert_eq!(t.text(i, "error"), "");
    }
    let png = std::fs::read(dir.join("compare.png")).unwrap();
    assert!(png.starts_with(b"\x89PNG\r\n\x1a\n") && png.len() > 1000);
    // The USR has no rb: refused.
    let r = common::host_sim(
        &["--robot", "usr", "compare", "--out", dir.to_str().unwrap()],
        "",
    );
    assert_ne!(r.code, Some(0));
}
