//! `ranges`: the joint, tilt and force ranges over the thesis's task (the command itself:
//! host-sim/tests/design.rs; Table 8.3: tables.rs).
#![allow(clippy::unwrap_used, clippy::expect_used)]

use design::ranges;
use kinematics_core::{Branch, Robot, RobotKind, RsprGeometry};
use robot_config::task_box::TaskBox;

/// `ranges` over the thesis task: the task row is the union of the two orientations, the
/// span is max - min, the parallel orientation is mirror-symmetric about the x-z plane
/// (chains 2 and 3), the central values lie inside, and the reference RSPR's shortest
/// prismatic length is l1 = 143.75 mm at the rotated corner (20, 20, 150) mm, 0.25 mm
/// below the 144 mm stroke.
#[test]
fn rspr_ranges_are_consistent() {
    let robot = Robot::Rspr(RsprGeometry::reference());
    let r = ranges::evaluate(
        &robot,
        &TaskBox::thesis([9, 9, 5]),
        [7.0, 7.0, 7.0, 0.7, 0.7, 0.7],
        Branch::OUTER,
        1e-6,
    )
    .unwrap();
    assert_eq!(r.poses, 810);
    assert!(r.failures.is_empty());
    for name in ranges::quantity_names(RobotKind::Rspr) {
        let [p, q, t] = ["parallel", "rotated", "task"].map(|o| r.get(&name, o).unwrap());
        assert_eq!(t.min, p.min.min(q.min), "{name}");
        assert_eq!(t.max, p.max.max(q.max), "{name}");
        assert_eq!(t.poses, 810);
        assert!((t.span() - (t.max - t.min)).abs() < 1e-12);
    }
    let g = |n: &str| r.get(n, "parallel").unwrap();
    assert!((g("l2_mm").min - g("l3_mm").min).abs() < 1e-9);
    assert!((g("l2_mm").max - g("l3_mm").max).abs() < 1e-9);
    assert!((g("theta2_deg").min + g("theta3_deg").max).abs() < 1e-9);
    assert!(g("l1_mm").min < 160.0 && g("theta1_deg").min < 0.0 && g("theta1_deg").max > 0.0);
    let l1 = r.get("l1_mm", "task").unwrap();
    assert!((l1.min - 143.75).abs() < 0.01, "{}", l1.min);
    assert!(r.get("tilt3_deg", "task").unwrap().max < 30.0);
}
