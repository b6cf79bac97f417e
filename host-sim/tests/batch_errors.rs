//! A batch with bad rows keeps one output row per input row: good rows are right, bad rows
//! carry a message naming the field or the chain, and the run still exits 0.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use crate::common;
use common::{host_sim, Table, RSPR_JOINTS, USR_JOINTS};
use kinematics_core::{inverse, Branch, Pose, Robot, RsprGeometry, UsrGeometry};
use nalgebra::Vector3;

const INPUT: &str = "note,x_mm,y_mm,z_mm,rx_deg,ry_deg,rz_deg,branch\n\
good,10,-5,170,5,-3,8,0\n\
text,abc,0,160,0,0,0,0\n\
nan,0,NaN,160,0,0,0,0\n\
branch9,0,0,160,0,0,0,9\n\
far,0,0,1000,0,0,0,0\n\
sideways,1000,0,160,0,0,0,0\n\
good2,-5,4,155,-3,2,1,3\n\
short,0,0,160\n";

/// The library's joints of a pose given in mm/deg, in mm/deg.
fn expected(robot: &Robot<f64>, p: [f64; 6], branch: u32) -> [f64; 6] {
    let pose = Pose::from_position_rotation_vector(
        Vector3::new(p[0], p[1], p[2]) / 1000.0,
        Vector3::new(p[3], p[4], p[5]).map(f64::to_radians),
    )
    .unwrap();
    let q = inverse(robot, &pose, Branch::new(branch).unwrap())
        .unwrap()
        .q();
    let mut out = [0.0; 6];
    for (k, o) in out.iter_mut().enumerate() {
        *o = if matches!(robot, Robot::Rspr(_)) && k < 3 {
            q[k] * 1000.0
        } else {
            q[k].to_degrees()
        };
    }
    out
}

fn check(robot_args: &[&str], robot: Robot<f64>, joints: [&str; 6], bad: &[(usize, &str)]) {
    let args: Vec<&str> = robot_args.iter().copied().chain(["ik", "--csv"]).collect();
    let r = host_sim(&args, INPUT);
    assert_eq!(
        r.code,
        Some(0),
        "batch exits 0 despite bad rows: {}",
        r.stderr
    );
    let t = Table::parse(&r.stdout);
    assert_eq!(t.rows.len(), 8, "one output row per input row");
    let bad_count = bad.len();
    assert!(
        r.stderr
            .contains(&format!("8 rows, {bad_count} with errors")),
        "{}",
        r.stderr
    );
    assert_eq!(
        r.stderr.lines().count(),
        1,
        "one summary line: {}",
        r.stderr
    );
    // Every row echoes its note.
    let notes: Vec<&str> = (0..8).map(|i| t.text(i, "note")).collect();
    assert_eq!(
        notes,
        ["good", "text", "nan", "branch9", "far", "sideways", "good2", "short"]
    );
    for (i, p, b) in [
        (0, [10.0, -5.0, 170.0, 5.0, -3.0, 8.0], 0),
        (6, [-5.0, 4.0, 155.0, -3.0, 2.0, 1.0], 3),
    ] {
        if bad.iter().any(|(row, _)| *row == i) {
            continue;
        }
        assert_eq!(t.text(i, "error"), "");
        let want = expected(&robot, p, b);
        for (k, name) in joints.iter().enumerate() {
            assert!((t.num(i, name) - want[k]).abs() < 1e-8, "row {i} {name}");
        }
    }
    for (i, message) in bad {
        assert_eq!(t.text(*i, "error"), *message, "row {i}");
        for name in joints {
            assert_eq!(t.text(*i, name), "", "row {i} {name} is empty on error");
        }
    }
}

#[test]
fn rspr_bad_rows_are_named_and_do_not_stop_the_batch() {
    check(
        &[],
        Robot::Rspr(RsprGeometry::reference()),
        RSPR_JOINTS,
        &[
            (1, "row 2: x_mm: \"abc\" is not a number"),
            (2, "row 3: y_mm: \"NaN\" is not a finite number"),
            (3, "row 4: branch: 9 is out of range 0..=7"),
            // z = 1000 mm is reachable for the RSPR (its prismatic legs have no stroke
            // limit in the kinematics); a 1 m sideways shift is not.
            (5, "row 6: ik: chain 2: no real root (pose out of reach)"),
            (7, "row 8: has 4 fields, the header has 8"),
        ],
    );
}

#[test]
fn usr_bad_rows_are_named_and_do_not_stop_the_batch() {
    // The USR input rows are far from its workspace except the two good ones, which are
    // re-centred at its hc = 80 mm.
    let input = INPUT.replace("170,5", "85,5").replace("155,-3", "75,-3");
    let r = host_sim(&["--robot", "usr", "ik", "--csv"], &input);
    assert_eq!(r.code, Some(0));
    let t = Table::parse(&r.stdout);
    assert_eq!(t.rows.len(), 8);
    let robot = Robot::Usr(UsrGeometry::reference());
    let want = expected(&robot, [10.0, -5.0, 85.0, 5.0, -3.0, 8.0], 0);
    for (k, name) in USR_JOINTS.iter().enumerate() {
        assert!((t.num(0, name) - want[k]).abs() < 1e-8, "{name}");
    }
    assert_eq!(t.text(6, "error"), "");
    assert_eq!(
        t.text(4, "error"),
        "row 5: ik: chain 1: no real root (pose out of reach)"
    );
    assert!(t.text(1, "error").contains("x_mm"));
}
