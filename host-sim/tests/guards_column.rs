//! The row-wise kinematics commands guard their user: `ik`, `fk`, `jacobian` and `forces`
//! add the guards' verdict on the pose as a `guards` column (ok, or the first limit of the
//! worst severity broken with value and limit), and the batch form takes `--branch` for
//! an input without a `branch` column.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use crate::common;
use common::{ok, Table};

const POSES: &str = "x_mm,y_mm,z_mm,rx_deg,ry_deg,rz_deg\n0,0,160,0,0,0\n5,-5,165,3,0,0\n";

#[test]
fn ik_csv_without_a_branch_column_takes_the_branch_flag() {
    let implicit = Table::parse(&ok(&["ik", "--csv"], POSES));
    let explicit = Table::parse(&ok(
        &["ik", "--csv"],
        "x_mm,y_mm,z_mm,rx_deg,ry_deg,rz_deg,branch\n0,0,160,0,0,0,0\n5,-5,165,3,0,0,0\n",
    ));
    assert_eq!(implicit.header, explicit.header);
    assert_eq!(implicit.rows, explicit.rows);
    let inner = Table::parse(&ok(&["ik", "--csv", "--branch", "1"], POSES));
    assert_eq!(inner.text(0, "branch"), "1");
    assert!(
        (inner.num(0, "theta1_deg").abs() - 180.0).abs() < 1e-6,
        "branch 1 puts chain 1 inner: {}",
        inner.text(0, "theta1_deg")
    );
    // A branch column in the input wins over the flag, row by row.
    let given = Table::parse(&ok(
        &["ik", "--csv", "--branch", "1"],
        "x_mm,y_mm,z_mm,rx_deg,ry_deg,rz_deg,branch\n0,0,160,0,0,0,0\n",
    ));
    assert_eq!(given.num(0, "theta1_deg"), 0.0);
}

#[test]
fn a_pose_in_metres_is_solved_but_the_guards_column_says_stop() {
    let central = Table::parse(&ok(&["ik", "--pose", "0,0,160,0,0,0"], ""));
    assert_eq!(central.text(0, "guards"), "ok");
    let metres = Table::parse(&ok(&["ik", "--pose", "0,0,0.16,0,0,0"], ""));
    let verdict = metres.text(0, "guards");
    assert!(verdict.starts_with("stop: "), "{verdict}");
    assert!(verdict.contains(" mm, limit "), "{verdict}");
    // Legs of 404 mm (stroke 144 .. 210 mm): forward kinematics finds a pose, refused.
    let fk = Table::parse(&ok(&["fk", "--joints", "404,404,404,0,0,0"], ""));
    assert!(
        fk.text(0, "guards").starts_with("stop: "),
        "{}",
        fk.text(0, "guards")
    );
    // A platform below the base.
    let below = Table::parse(&ok(&["jacobian", "--pose", "0,0,-160,0,0,0"], ""));
    assert!(below.text(0, "guards").starts_with("stop: "));
}

#[test]
fn forces_columns_carry_their_units_and_the_verdict() {
    let t = Table::parse(&ok(
        &[
            "forces",
            "--pose",
            "10,-5,165,5,0,0",
            "--wrench",
            "7,7,7,0.7,0.7,0.7",
        ],
        "",
    ));
    let results: Vec<&str> = t.header[13..].iter().map(String::as_str).collect();
    assert_eq!(
        results,
        ["f1_n", "f2_n", "f3_n", "t1_nm", "t2_nm", "t3_nm", "guards", "error"]
    );
    assert_eq!(t.text(0, "guards"), "ok");
}

/// The CLI's refusal of a pose names the guard, the value and the limit with its unit:
/// one pose per guard the board refuses targets by (a leg below its stroke, the platform
/// tilted beyond its cone, the platform centre above the workspace), through the
/// single-pose form of `ik` (the guards column) and `check` (the violations).
#[test]
fn the_cli_names_guard_value_and_limit_of_each_refusal() {
    let cases = [
        (
            "20,20,146,0,24,0",
            "stop: stroke of chain 1 is 132.519 mm, limit 144.000 mm",
            "stroke:1:132.519:144.000",
        ),
        (
            "0,0,160,26,0,0",
            "stop: platform tilt is 26.000 deg, limit 25.000 deg",
            "tilt_cone:-:26.000:25.000",
        ),
        (
            "0,0,177,0,0,0",
            "stop: workspace along z is 17.000 mm, limit 15.000 mm",
            "workspace:z:17.000:15.000",
        ),
    ];
    for (pose, words, violation) in cases {
        let ik = Table::parse(&ok(&["ik", "--pose", pose], ""));
        let col = ik.header.iter().position(|h| h == "guards").unwrap();
        assert_eq!(ik.rows[0][col], words, "ik --pose {pose}");
        let check = Table::parse(&ok(&["check", "--pose", pose], ""));
        let col = check.header.iter().position(|h| h == "violations").unwrap();
        assert_eq!(check.rows[0][col], violation, "check --pose {pose}");
    }
}
