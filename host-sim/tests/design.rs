//! The design tools on the command line: `forces --path`, `ranges` and `workspace` (thesis
//! chapter 8); their libraries' own tests are in host-sim/design/tests.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use crate::common;
use common::{host_sim, ok, Table};
use design::ranges;
use kinematics_core::{inverse, Branch, Chain, Pose, Robot, RobotKind, UsrGeometry};
use robot_config::task_box::TaskBox;
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
        for c in cols.iter() {
            let a = t.num(50, c);
            let b = single.num(0, c);
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
