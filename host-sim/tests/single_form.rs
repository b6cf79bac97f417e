//! The single-pose forms: same output as the batch form; on error a non-zero exit with a
//! one-line message on stderr that says what was wrong. Whole-run CSV errors are named.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use crate::common;
use common::{host_sim, ok};

/// Asserts a failed run with exactly one stderr line containing every `needle`.
fn fails_with(args: &[&str], stdin: &str, needles: &[&str]) {
    let r = host_sim(args, stdin);
    assert_ne!(r.code, Some(0), "host-sim {args:?} should fail");
    assert_eq!(r.stdout, "", "nothing on stdout on error");
    assert_eq!(r.stderr.lines().count(), 1, "one line: {:?}", r.stderr);
    for n in needles {
        assert!(r.stderr.contains(n), "{:?} lacks {n:?}", r.stderr);
    }
}

#[test]
fn single_form_prints_the_batch_header_and_row() {
    let pose = "10,-5,170,5,-3,8";
    let csv = format!("x_mm,y_mm,z_mm,rx_deg,ry_deg,rz_deg,branch\n{pose},2\n");
    for cmd in ["ik", "jacobian", "singularity"] {
        let single = ok(&[cmd, "--pose", pose, "--branch", "2"], "");
        assert_eq!(single, ok(&[cmd, "--csv"], &csv), "{cmd}");
    }
    let single = ok(
        &[
            "forces",
            "--pose",
            pose,
            "--branch",
            "2",
            "--wrench",
            "7,7,7,0.7,0.7,0.7",
        ],
        "",
    );
    let batch = ok(
        &["forces", "--csv"],
        &format!(
            "x_mm,y_mm,z_mm,rx_deg,ry_deg,rz_deg,branch,fx_n,fy_n,fz_n,tx_nm,ty_nm,tz_nm\n\
             {pose},2,7,7,7,0.7,0.7,0.7\n"
        ),
    );
    assert_eq!(single, batch);
    // The reference prototype at its central pose: l = sqrt(60^2 + 160^2) = 170.880 mm.
    let central = ok(&["ik", "--pose", "0,0,160,0,0,0", "--branch", "0"], "");
    assert_eq!(
        central,
        "x_mm,y_mm,z_mm,rx_deg,ry_deg,rz_deg,branch,l1_mm,l2_mm,l3_mm,theta1_deg,theta2_deg,theta3_deg,guards,error\n\
         0,0,160,0,0,0,0,170.880074906,170.880074906,170.880074906,0.000000000,0.000000000,0.000000000,ok,\n"
    );
}

#[test]
fn single_form_errors_exit_non_zero_with_one_line() {
    fails_with(
        &["ik", "--pose", "0,0,160,0,0"],
        "",
        &[
            "error: --pose: expected 6 comma-separated numbers (x_mm,y_mm,z_mm,rx_deg,ry_deg,rz_deg), got 5",
        ],
    );
    fails_with(
        &["ik", "--pose", "1000,0,160,0,0,0"],
        "",
        &["error: ik: chain 2: no real root (pose out of reach)"],
    );
    fails_with(
        &["ik", "--pose", "0,0,abc,0,0,0"],
        "",
        &["error: --pose: z_mm: \"abc\" is not a number"],
    );
    fails_with(
        &["jacobian", "--pose", "0,0,160,0,0,0", "--branch", "8"],
        "",
        &["error: --branch: branch: 8 is out of range 0..=7"],
    );
    fails_with(
        &["fk", "--joints", "170,170,170,0,0"],
        "",
        &["--joints: expected 6", "theta3_deg"],
    );
    fails_with(
        &["--robot", "usr", "fk", "--joints", "0,0,0,22,22,nan"],
        "",
        &["--joints: beta3_deg: \"nan\" is not a finite number"],
    );
    fails_with(
        &["forces", "--pose", "0,0,160,0,0,0", "--wrench", "7,7,7"],
        "",
        &["--wrench: expected 6", "fx_n,fy_n,fz_n,tx_nm,ty_nm,tz_nm"],
    );
    // A pose that is out of reach for the USR.
    fails_with(
        &["--robot", "usr", "singularity", "--pose", "0,0,1000,0,0,0"],
        "",
        &["error: ik: chain 1: no real root"],
    );
}

#[test]
fn a_missing_csv_column_fails_the_run_and_is_named() {
    fails_with(
        &["ik", "--csv"],
        "x_mm,y_mm,z_mm,rx_deg,ry_deg,branch\n0,0,160,0,0,0\n",
        &["error: ik: the input has no column \"rz_deg\""],
    );
    fails_with(
        &["--robot", "usr", "fk", "--csv"],
        "branch,l1_mm,l2_mm,l3_mm,theta1_deg,theta2_deg,theta3_deg\n0,1,1,1,0,0,0\n",
        &["error: fk: the input has no column \"alpha1_deg\""],
    );
    fails_with(
        &["forces", "--csv"],
        "x_mm,y_mm,z_mm,rx_deg,ry_deg,rz_deg,branch\n0,0,160,0,0,0,0\n",
        &["no column \"fx_n\""],
    );
    fails_with(&["singularity", "--csv"], "", &["the input is empty"]);
}

#[test]
fn robot_and_geometry_conflict() {
    let r = host_sim(
        &[
            "--robot",
            "usr",
            "--geometry",
            "x.toml",
            "ik",
            "--pose",
            "0,0,80,0,0,0",
        ],
        "",
    );
    assert_eq!(r.code, Some(2));
    assert!(r.stderr.contains("cannot be used with"), "{}", r.stderr);
}
