//! `report` runs on the built-in robots and on a geometry file and prints every section
//! with numbers that agree with the row-wise commands.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use crate::common;
use common::{geometry, ok, Table};

const SECTIONS: [&str; 10] = [
    "Dimensions",
    "Inverse kinematics at the central pose",
    "Central pose, branch 0",
    "Task box: 40 x 40 x 20 mm",
    "Joint ranges over the task",
    "Jacobian conditioning",
    "Serial margins",
    "Spherical-joint tilt",
    "Actuator forces for the wrench (7, 7, 7) N, (0.7, 0.7, 0.7) N m",
    "Failures",
];

#[test]
fn rspr_report_prints_every_section() {
    let out = ok(&["report"], "");
    for s in SECTIONS {
        assert!(out.contains(s), "missing section {s:?}:\n{out}");
    }
    assert!(out.contains("rb_mm     90.000"), "{out}");
    // The 8 branches of the central pose: branch 7 is all inner (l = 200 mm, theta = 180).
    assert!(
        out.contains(
            "  7           200.000     200.000     200.000     180.000     180.000     180.000"
        ),
        "{out}"
    );
    assert!(out.contains("150 poses, 150 solved"), "{out}");
    assert!(out.contains("Failures\n  none"), "{out}");
    // The central pose's inv_cond agrees with `singularity`.
    let t = Table::parse(&ok(&["singularity", "--pose", "0,0,160,0,0,0"], ""));
    let inv_cond = t.num(0, "parallel_inv_cond");
    assert!(
        out.contains(&format!("parallel inv_cond {inv_cond:.4}")),
        "{out}"
    );
}

#[test]
fn usr_report_and_geometry_file_report_run() {
    let usr = ok(&["--robot", "usr", "report"], "");
    for s in SECTIONS {
        assert!(usr.contains(s), "missing section {s:?}:\n{usr}");
    }
    assert!(usr.contains("alpha1_deg") && usr.contains("mm^2"), "{usr}");
    let from_file = ok(
        &["--geometry", &geometry("reference-usr.toml"), "report"],
        "",
    );
    // Same numbers; only the source line differs.
    assert_eq!(
        usr.lines().skip(1).collect::<Vec<_>>(),
        from_file.lines().skip(1).collect::<Vec<_>>()
    );
}

#[test]
fn report_lists_failing_points() {
    // A box too large for the USR: some points are out of reach and are listed with the
    // chain that failed; the report still completes.
    let out = ok(
        &[
            "--robot",
            "usr",
            "report",
            "--box",
            "200,200,20",
            "--grid",
            "3,3,1",
        ],
        "",
    );
    assert!(out.contains("18 poses"), "{out}");
    assert!(out.contains(": ik: chain "), "{out}");
    assert!(!out.contains("Failures\n  none"), "{out}");
}
