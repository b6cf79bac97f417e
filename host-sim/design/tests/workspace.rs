//! `workspace`: constant-height sections of the reachable workspace and the verdict on the
//! task box (the command itself: host-sim/tests/design.rs).
#![allow(clippy::unwrap_used, clippy::expect_used)]

use design::workspace::{rho_max, section, Admissible, Scan};
use kinematics_core::guards::{Guard, Limits, Subject};
use kinematics_core::{Branch, Chain, Robot, RsprGeometry};
use robot_config::task_box::TaskBox;

fn rspr_scan() -> (Robot<f64>, Admissible, Scan) {
    let robot = Robot::Rspr(RsprGeometry::reference());
    let adm = Admissible::new(&robot, Branch::OUTER, &Limits::reference()).unwrap();
    let scan = Scan {
        z_mm: vec![160.0],
        phi_step_deg: 5.0,
        step_mm: 1.0,
        tol_mm: 0.01,
        max_radius_mm: 150.0,
        footprint_half_mm: [20.0, 20.0],
    };
    (robot, adm, scan)
}

/// The reference RSPR's section at hc contains the 40 x 40 mm task footprint at both task
/// orientations; every rho_max is admissible and a point 1 mm further out along the ray
/// is not, up to the bisection tolerance (the boundary lies within tol of rho_max).
#[test]
fn rspr_section_at_hc_contains_the_footprint() {
    let (_, adm, scan) = rspr_scan();
    let c = 20.0 / std::f64::consts::SQRT_2;
    for (key, rot) in [("parallel", [0.0; 3]), ("rotated", [c, c, 0.0])] {
        let s = section(&adm, &scan, key, rot, 160.0);
        assert!(s.footprint_inside(), "{key}: {:?}", s.footprint_violation);
        assert_eq!(s.phi_deg.len(), 72);
        for (&p, &r) in s.phi_deg.iter().zip(&s.rho_max_mm) {
            let (sn, cs) = p.to_radians().sin_cos();
            assert!(
                adm.ok([r * cs, r * sn, 160.0, rot[0], rot[1], rot[2]]),
                "{key} {p}"
            );
            let fine = Scan {
                step_mm: 0.01,
                ..scan.clone()
            };
            // A fine march finds the same first boundary within the tolerance.
            let r2 = rho_max(&adm, &fine, 160.0, p, rot);
            assert!((r - r2).abs() <= 0.02, "{key} phi {p}: {r} vs {r2}");
        }
    }
}

/// The rotated task is not fully admissible at the box's lower face: at (20, 20, 150) mm
/// rotated +20 deg about [1,1,0] the stroke guard stops on chain 1 (l1 = 143.75 mm < 144),
/// so the section at z = 150 does not contain the footprint; the parallel one does.
#[test]
fn rotated_lower_face_corner_violates_the_stroke_by_a_quarter_millimetre() {
    let (_, adm, scan) = rspr_scan();
    let c = 20.0 / std::f64::consts::SQRT_2;
    let v = adm.violation([20.0, 20.0, 150.0, c, c, 0.0]).unwrap();
    assert_eq!(v.guard, Guard::Stroke);
    assert_eq!(v.subject, Subject::Chain(Chain::One));
    assert!((v.value * 1000.0 - 143.75).abs() < 0.01, "{}", v.value);
    assert!((v.limit - 0.144).abs() < 1e-12);
    assert!(!section(&adm, &scan, "rotated", [c, c, 0.0], 150.0).footprint_inside());
    assert!(section(&adm, &scan, "parallel", [0.0; 3], 150.0).footprint_inside());
}

/// The whole task box, checked on a 2 mm grid at both orientations (2 x 21 x 21 x 11
/// points), is not inside the reference RSPR's admissible workspace only because of the
/// 144 mm minimum stroke: the first failing point is on the rotated lower face with leg 1
/// short of 144 mm (the parallel orientation passes); with the minimum at 143 mm every
/// point is admissible.
#[test]
fn the_task_box_verdict_names_the_stroke_and_passes_without_it() {
    use design::workspace::task_box_verdict;
    let (robot, adm, _) = rspr_scan();
    let task = TaskBox::thesis([1, 1, 1]);
    let v = task_box_verdict(&adm, &task, 160.0, 2.0);
    assert_eq!(v.points, 9702);
    assert_eq!(v.spacing_mm, [2.0, 2.0, 2.0]);
    let why = v.first_violation.clone().unwrap();
    assert!(
        why.contains("150.0) mm, r (14.14, 14.14, 0.00) deg: stroke:1:")
            && why.ends_with(":144.000 mm"),
        "{why}"
    );
    assert_eq!(v.orientation_violations[0], None);
    assert_eq!(v.orientation_violations[1].as_ref(), Some(&why));
    let mut limits = Limits::reference();
    limits.stroke[0] = 0.143;
    let adm = Admissible::new(&robot, Branch::OUTER, &limits).unwrap();
    let v = task_box_verdict(&adm, &task, 160.0, 2.0);
    assert!(v.inside(), "{:?}", v.first_violation);
}
