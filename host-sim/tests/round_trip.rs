//! `ik` then `fk` through the binary's CSV forms gives back the poses, on every branch.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use crate::common;
use common::{ok, pose_csv, Table, POSE};

/// Pipes `poses` through `ik --csv` and then `fk --csv` and checks that every row solved
/// and that fk's pose equals the input pose (echoed as in_<name>) to 1e-6 mm / deg.
fn round_trip(robot: &[&str], poses: &[([f64; 6], u32)]) {
    let ik_args: Vec<&str> = robot.iter().copied().chain(["ik", "--csv"]).collect();
    let fk_args: Vec<&str> = robot.iter().copied().chain(["fk", "--csv"]).collect();
    let ik_out = ok(&ik_args, &pose_csv(poses));
    let fk_out = ok(&fk_args, &ik_out);
    let t = Table::parse(&fk_out);
    assert_eq!(t.rows.len(), poses.len(), "one output row per input row");
    for (i, (pose, branch)) in poses.iter().enumerate() {
        assert_eq!(t.text(i, "in_error"), "", "ik row {i}");
        assert_eq!(t.text(i, "error"), "", "fk row {i}");
        assert_eq!(t.num(i, "branch"), f64::from(*branch));
        for (k, name) in POSE.iter().enumerate() {
            let back = t.num(i, name);
            let echoed = t.num(i, &format!("in_{name}"));
            assert!(
                (back - pose[k]).abs() < 1e-6 && (echoed - pose[k]).abs() < 1e-9,
                "row {i} (branch {branch}) {name}: in {} out {back}",
                pose[k]
            );
        }
        assert!(t.num(i, "iterations") <= 30.0);
    }
}

/// Poses around a centre height, each on every branch.
fn poses_around(hc: f64, reach: f64) -> Vec<([f64; 6], u32)> {
    let c = 20.0 / 2f64.sqrt();
    let base = [
        [0.0, 0.0, hc, 0.0, 0.0, 0.0],
        [
            0.25 * reach,
            -0.15 * reach,
            hc + 0.25 * reach,
            4.0,
            -2.0,
            6.0,
        ],
        [
            -0.4 * reach,
            0.3 * reach,
            hc - 0.2 * reach,
            -5.0,
            7.0,
            -10.0,
        ],
        [0.5 * reach, -0.5 * reach, hc + 0.5 * reach, c, c, 0.0],
    ];
    (0..8)
        .flat_map(|b| base.iter().map(move |p| (*p, b)))
        .collect()
}

#[test]
fn rspr_ik_then_fk_returns_the_poses_on_all_branches() {
    round_trip(&[], &poses_around(160.0, 20.0));
}

#[test]
fn usr_ik_then_fk_returns_the_poses_on_all_branches() {
    round_trip(&["--robot", "usr"], &poses_around(80.0, 20.0));
}

#[test]
fn fk_honours_an_initial_pose_and_single_form_matches_batch() {
    // The single form prints exactly the header and row the batch form prints.
    let single = ok(
        &[
            "fk",
            "--joints",
            "170.88,170.88,170.88,0,0,0",
            "--branch",
            "0",
            "--initial",
            "1,1,161,0,0,1",
        ],
        "",
    );
    let batch = ok(
        &["fk", "--csv"],
        "branch,l1_mm,l2_mm,l3_mm,theta1_deg,theta2_deg,theta3_deg,x0_mm,y0_mm,z0_mm,rx0_deg,ry0_deg,rz0_deg\n\
         0,170.88,170.88,170.88,0,0,0,1,1,161,0,0,1\n",
    );
    assert_eq!(single, batch);
    let t = Table::parse(&single);
    assert!((t.num(0, "z_mm") - 159.99992).abs() < 1e-4, "{single}");
    assert!(t.num(0, "x_mm").abs() < 1e-9);
}
