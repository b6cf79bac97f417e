//! The design tools: `forces --path`, `ranges` and `workspace` (thesis chapter 8), through
//! the CLI and the library.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;
use common::{host_sim, ok, Table};
use host_sim::design::forces_path::{forces_along, peaks, tau_columns, PathSpec};
use host_sim::design::ranges;
use host_sim::design::workspace::{rho_max, section, Admissible, Scan};
use host_sim::task_box::TaskBox;
use kinematics_core::guards::{Guard, Limits, Subject};
use kinematics_core::{
    inverse, jacobian, Branch, Chain, Pose, Robot, RobotKind, RsprGeometry, UsrGeometry,
};
use nalgebra::{Vector3, Vector6};
use std::path::PathBuf;

fn out(name: &str) -> PathBuf {
    let d = PathBuf::from(env!("CARGO_TARGET_TMPDIR"))
        .join("design-tests")
        .join(name);
    let _ = std::fs::remove_dir_all(&d);
    d
}

fn is_png(path: &std::path::Path) -> bool {
    std::fs::read(path)
        .map(|b| b.starts_with(b"\x89PNG\r\n\x1a\n") && b.len() > 1000)
        .unwrap_or(false)
}

const ROT: &str = "11.547005383792516";

/// The path form writes 101 samples from [-20,-20,-10] to [20,20,10] mm about [0,0,hc]
/// with unit-suffixed force columns and a PNG, and its midpoint agrees with the
/// single-pose `forces` at [0, 0, hc] (which still works unchanged).
#[test]
fn forces_path_writes_the_diagonal_and_agrees_with_single_pose_forces() {
    for (robot, hc, cols) in [
        (
            "rspr",
            160.0,
            ["f1_n", "f2_n", "f3_n", "t1_nm", "t2_nm", "t3_nm"],
        ),
        (
            "usr",
            80.0,
            [
                "t_alpha1_nm",
                "t_alpha2_nm",
                "t_alpha3_nm",
                "t_beta1_nm",
                "t_beta2_nm",
                "t_beta3_nm",
            ],
        ),
    ] {
        let dir = out(&format!("forces-{robot}"));
        let d = dir.to_str().unwrap();
        ok(
            &["--robot", robot, "forces", "--path", "diagonal", "--out", d],
            "",
        );
        let text = std::fs::read_to_string(dir.join("forces_path.csv")).unwrap();
        let t = Table::parse(&text);
        assert_eq!(t.rows.len(), 101);
        let mut expected = vec!["s", "x_mm", "y_mm", "z_mm", "rx_deg", "ry_deg", "rz_deg"];
        expected.extend(cols);
        expected.push("error");
        assert_eq!(t.header, expected);
        assert_eq!(t.num(0, "x_mm"), -20.0);
        assert_eq!(t.num(0, "z_mm"), hc - 10.0);
        assert_eq!(t.num(100, "y_mm"), 20.0);
        assert_eq!(t.num(100, "z_mm"), hc + 10.0);
        assert!(is_png(&dir.join("forces_path.png")));
        for i in 0..101 {
            assert_eq!(t.text(i, "error"), "", "{robot} row {i}");
        }
        let pose = format!("0,0,{hc},{ROT},{ROT},{ROT}");
        let single = Table::parse(&ok(
            &[
                "--robot",
                robot,
                "forces",
                "--pose",
                &pose,
                "--wrench",
                "7,7,7,0.7,0.7,0.7",
            ],
            "",
        ));
        for (j, c) in cols.iter().enumerate() {
            let a = t.num(50, c);
            let b = single.num(0, &format!("tau{}", j + 1));
            assert!(
                (a - b).abs() <= 1e-8 * (1.0 + b.abs()),
                "{robot} {c}: {a} vs {b}"
            );
        }
    }
}

/// The path form conflicts with the batch form, and the row-wise forms still need a wrench.
#[test]
fn forces_forms_are_exclusive() {
    assert_ne!(
        host_sim(&["forces", "--path", "diagonal", "--csv"], "").code,
        Some(0)
    );
    assert_ne!(
        host_sim(&["forces", "--pose", "0,0,160,0,0,0"], "").code,
        Some(0)
    );
    assert_ne!(
        host_sim(
            &["forces", "--path", "diagonal", "--pose", "0,0,160,0,0,0"],
            ""
        )
        .code,
        Some(0)
    );
}

/// Along the diagonal, every sample satisfies virtual work: tau . (J xdot) = s_e . xdot,
/// and the peaks are the largest magnitudes of the samples.
#[test]
fn path_forces_satisfy_virtual_work() {
    for robot in [
        Robot::Rspr(RsprGeometry::reference()),
        Robot::Usr(UsrGeometry::reference()),
    ] {
        let spec = PathSpec {
            samples: 11,
            ..PathSpec::thesis_diagonal()
        };
        let samples = forces_along(&robot, &spec);
        let se = Vector6::from(spec.wrench);
        let xdot = Vector6::new(0.3, -0.2, 0.5, 0.7, -1.1, 0.4);
        for s in &samples {
            let tau = Vector6::from(*s.tau.as_ref().unwrap());
            let p = s.pose;
            let pose = Pose::from_position_rotation_vector(
                Vector3::new(p[0], p[1], p[2]) / 1000.0,
                Vector3::new(p[3], p[4], p[5]).map(f64::to_radians),
            )
            .unwrap();
            let sol = inverse(&robot, &pose, Branch::OUTER).unwrap();
            let j = jacobian(&robot, &sol).unwrap();
            let lhs = tau.dot(&(j.j * xdot));
            let rhs = se.dot(&xdot);
            assert!(
                (lhs - rhs).abs() < 1e-9 * (1.0 + rhs.abs()),
                "{lhs} vs {rhs}"
            );
        }
        let pk = peaks(&samples);
        for (k, p) in pk.iter().enumerate() {
            let m = samples
                .iter()
                .map(|s| s.tau.as_ref().unwrap()[k].abs())
                .fold(0.0, f64::max);
            assert_eq!(*p, m, "{:?}", tau_columns(robot.kind()));
        }
    }
}

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

/// USR: gamma_i and delta_i ranges are finite over the task; the delta range contains the
/// central pose's delta from the law of cosines (|e - p|^2 = l1^2 + l2^2 - 2 l1 l2 cos
/// delta); the CSV form lists every quantity at the three orientation keys.
#[test]
fn usr_ranges_have_gamma_and_delta() {
    let robot = Robot::Usr(UsrGeometry::reference());
    let r = ranges::evaluate(
        &robot,
        &TaskBox::thesis([3, 3, 3]),
        [7.0, 7.0, 7.0, 0.7, 0.7, 0.7],
        Branch::OUTER,
        1e-6,
    )
    .unwrap();
    for i in 1..=3 {
        for q in [format!("gamma{i}_deg"), format!("delta{i}_deg")] {
            let t = r.get(&q, "task").unwrap();
            assert!(
                t.min.is_finite() && t.max.is_finite() && t.poses == 54,
                "{q}"
            );
        }
    }
    // delta at the central pose from the law of cosines.
    let sol = inverse(&robot, &Pose::central(0.080), Branch::OUTER).unwrap();
    let c = &sol.chains[Chain::One];
    let (l1, l2, d) = ((c.b - c.e).norm(), (c.p - c.b).norm(), (c.e - c.p).norm());
    let delta = ((l1 * l1 + l2 * l2 - d * d) / (2.0 * l1 * l2))
        .acos()
        .to_degrees();
    let dr = r.get("delta1_deg", "parallel").unwrap();
    assert!(
        dr.min <= delta + 1e-9 && delta <= dr.max + 1e-9,
        "{delta} {dr:?}"
    );
    let csv = ok(
        &["--robot", "usr", "ranges", "--csv", "--grid", "2,2,2"],
        "",
    );
    let t = Table::parse(&csv);
    assert_eq!(
        t.header,
        ["quantity", "orientation", "min", "max", "span", "poses"]
    );
    assert_eq!(
        t.rows.len(),
        3 * ranges::quantity_names(RobotKind::Usr).len()
    );
    assert!(csv.contains("gamma2_deg,rotated,") && csv.contains("t_beta3_nm,task,"));
}

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

/// The CLI writes workspace.csv (orientation, rx_deg..rz_deg, z_mm, phi_deg, rho_max_mm)
/// and one PNG per orientation, and states the footprint verdict per section.
#[test]
fn workspace_cli_writes_csv_and_plots() {
    let dir = out("workspace");
    let d = dir.to_str().unwrap();
    let stdout = ok(
        &[
            "workspace",
            "--z-mm",
            "0,0,1",
            "--phi-step-deg",
            "45",
            "--out",
            d,
        ],
        "",
    );
    assert_eq!(stdout.matches("footprint inside").count(), 2, "{stdout}");
    let t = Table::parse(&std::fs::read_to_string(dir.join("workspace.csv")).unwrap());
    assert_eq!(
        t.header,
        [
            "orientation",
            "rx_deg",
            "ry_deg",
            "rz_deg",
            "z_mm",
            "phi_deg",
            "rho_max_mm"
        ]
    );
    assert_eq!(t.rows.len(), 16);
    assert!((0..16).all(|i| t.num(i, "rho_max_mm") > 20.0 && t.num(i, "z_mm") == 160.0));
    assert!(is_png(&dir.join("sections_parallel.png")));
    assert!(is_png(&dir.join("sections_rotated.png")));
    assert!(is_png(&dir.join("boundary_parallel.png")));
    assert!(is_png(&dir.join("boundary_rotated.png")));
    assert!(
        stdout.contains("(9702 points, 2.00 x 2.00 x 2.00 mm apart): NOT inside the workspace"),
        "{stdout}"
    );
}

/// The whole task box, checked on a 2 mm grid at both orientations (2 x 21 x 21 x 11
/// points), is not inside the reference RSPR's admissible workspace only because of the
/// 144 mm minimum stroke: the first failing point is on the rotated lower face with leg 1
/// short of 144 mm (the parallel orientation passes); with the minimum at 143 mm every
/// point is admissible.
#[test]
fn the_task_box_verdict_names_the_stroke_and_passes_without_it() {
    use host_sim::design::workspace::task_box_verdict;
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
