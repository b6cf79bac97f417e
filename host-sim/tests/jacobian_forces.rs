//! `jacobian` agrees with a central finite difference of `ik` (both through the CLI), and
//! `forces` satisfies virtual work with `jacobian`: tau . (J xdot) = wrench . xdot.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use crate::common;
use common::{ok, pose_csv, Table, POSE, RSPR_JOINTS, USR_JOINTS};
use nalgebra::{Matrix6, Rotation3, Vector3, Vector6};

/// J (SI) of every row of a `jacobian` output.
fn jacobians(t: &Table) -> Vec<Matrix6<f64>> {
    (0..t.rows.len())
        .map(|i| {
            assert_eq!(t.text(i, "error"), "", "jacobian row {i}");
            Matrix6::from_fn(|r, c| t.num(i, &format!("j{}{}", r + 1, c + 1)))
        })
        .collect()
}

/// A pose displaced by a twist step [dv (mm); dw (rad, world frame)], in mm/deg.
fn displaced(p: [f64; 6], dv_mm: Vector3<f64>, dw: Vector3<f64>) -> [f64; 6] {
    let r0 = Vector3::new(p[3], p[4], p[5]).map(f64::to_radians);
    let r = (Rotation3::from_scaled_axis(dw) * Rotation3::from_scaled_axis(r0))
        .scaled_axis()
        .map(f64::to_degrees);
    [
        p[0] + dv_mm.x,
        p[1] + dv_mm.y,
        p[2] + dv_mm.z,
        r.x,
        r.y,
        r.z,
    ]
}

/// Checks J against central differences of ik at `pose` on `branch`, with steps h and h/2
/// combined by Richardson extrapolation (error O(h^4)).
fn finite_difference(
    robot: &[&str],
    joints: [&str; 6],
    linear: usize,
    pose: [f64; 6],
    branch: u32,
) {
    let args =
        |cmd: &'static str| -> Vec<&str> { robot.iter().copied().chain([cmd, "--csv"]).collect() };
    let j = jacobians(&Table::parse(&ok(
        &args("jacobian"),
        &pose_csv(&[(pose, branch)]),
    )))[0];
    // Steps: translation in m, rotation in rad; for each: k, then h and h/2, then +/-.
    let step = |k: usize| if k < 3 { 2e-4 } else { 2e-3 };
    let mut rows = Vec::new();
    for k in 0..6 {
        for h in [step(k), step(k) / 2.0] {
            for sign in [1.0, -1.0] {
                let mut dv = Vector3::zeros();
                let mut dw = Vector3::zeros();
                if k < 3 {
                    dv[k] = sign * h * 1e3;
                } else {
                    dw[k - 3] = sign * h;
                }
                rows.push((displaced(pose, dv, dw), branch));
            }
        }
    }
    let t = Table::parse(&ok(&args("ik"), &pose_csv(&rows)));
    // Joints in SI: the first `linear` are lengths in mm, the rest angles in deg.
    let q = |row: usize, i: usize| {
        assert_eq!(t.text(row, "error"), "");
        let v = t.num(row, joints[i]);
        if i < linear {
            v / 1e3
        } else {
            v.to_radians()
        }
    };
    let central = |row: usize, i: usize, h: f64| {
        let mut dq = q(row, i) - q(row + 1, i);
        if i >= linear {
            dq = (dq + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU)
                - std::f64::consts::PI;
        }
        dq / (2.0 * h)
    };
    for k in 0..6 {
        let h = step(k);
        for i in 0..6 {
            let coarse = central(4 * k, i, h);
            let fine = central(4 * k + 2, i, h / 2.0);
            let fd = (4.0 * fine - coarse) / 3.0;
            let jik = j[(i, k)];
            assert!(
                (fd - jik).abs() <= 1e-6 * (1.0 + jik.abs()),
                "{robot:?} branch {branch} J[{}][{}] = {jik}, finite difference {fd}",
                i + 1,
                k + 1
            );
        }
    }
}

#[test]
fn rspr_jacobian_matches_finite_differences_of_ik() {
    finite_difference(&[], RSPR_JOINTS, 3, [10.0, -5.0, 170.0, 5.0, -3.0, 8.0], 0);
    finite_difference(
        &[],
        RSPR_JOINTS,
        3,
        [-20.0, 20.0, 170.0, 14.142, 14.142, 0.0],
        0,
    );
    finite_difference(&[], RSPR_JOINTS, 3, [5.0, 5.0, 150.0, -4.0, 2.0, -6.0], 6);
}

#[test]
fn usr_jacobian_matches_finite_differences_of_ik() {
    let usr = ["--robot", "usr"];
    finite_difference(&usr, USR_JOINTS, 0, [5.0, -3.0, 85.0, 4.0, -2.0, 6.0], 0);
    finite_difference(&usr, USR_JOINTS, 0, [-8.0, 6.0, 75.0, -5.0, 7.0, -10.0], 5);
}

/// Runs `jacobian` and `forces` on the same rows and checks tau . (J xdot) = w . xdot for
/// the unit twists and a generic one.
fn virtual_work(robot: &[&str], poses: &[([f64; 6], u32)], wrench: [f64; 6]) {
    let args =
        |cmd: &'static str| -> Vec<&str> { robot.iter().copied().chain([cmd, "--csv"]).collect() };
    let js = jacobians(&Table::parse(&ok(&args("jacobian"), &pose_csv(poses))));
    let mut input = pose_csv(poses);
    let w: Vec<String> = wrench.iter().map(|x| x.to_string()).collect();
    input = input
        .lines()
        .enumerate()
        .map(|(i, l)| {
            if i == 0 {
                format!("{l},fx_n,fy_n,fz_n,tx_nm,ty_nm,tz_nm\n")
            } else {
                format!("{l},{}\n", w.join(","))
            }
        })
        .collect();
    let t = Table::parse(&ok(&args("forces"), &input));
    assert_eq!(t.rows.len(), poses.len());
    let w = Vector6::from(wrench);
    for (i, j) in js.iter().enumerate() {
        assert_eq!(t.text(i, "error"), "", "forces row {i}");
        for name in POSE {
            assert!(!t.text(i, name).is_empty());
        }
        // tau in q order: the six result columns before `guards`, their units named.
        let first = t.col("guards") - 6;
        let tau = Vector6::from_fn(|r, _| t.num(i, &t.header[first + r]));
        let generic = Vector6::new(0.3, -0.7, 0.2, 1.1, -0.4, 0.9);
        for xdot in (0..6)
            .map(|k| Vector6::from_fn(|r, _| f64::from(u8::from(r == k))))
            .chain([generic])
        {
            let qdot = j * xdot;
            let lhs = tau.dot(&qdot);
            let rhs = w.dot(&xdot);
            let scale = tau.abs().dot(&qdot.abs()) + w.abs().dot(&xdot.abs());
            assert!(
                (lhs - rhs).abs() <= 1e-8 * scale,
                "row {i}: tau.qdot = {lhs}, w.xdot = {rhs}"
            );
        }
    }
}

#[test]
fn rspr_forces_satisfy_virtual_work_with_the_jacobian() {
    virtual_work(
        &[],
        &[
            ([0.0, 0.0, 160.0, 0.0, 0.0, 0.0], 0),
            ([10.0, -5.0, 170.0, 5.0, -3.0, 8.0], 0),
            ([-20.0, 20.0, 170.0, 14.142, 14.142, 0.0], 0),
            ([5.0, 5.0, 150.0, -4.0, 2.0, -6.0], 5),
        ],
        [7.0, 7.0, 7.0, 0.7, 0.7, 0.7],
    );
}

#[test]
fn usr_forces_satisfy_virtual_work_with_the_jacobian() {
    virtual_work(
        &["--robot", "usr"],
        &[
            ([0.0, 0.0, 80.0, 0.0, 0.0, 0.0], 0),
            ([5.0, -3.0, 85.0, 4.0, -2.0, 6.0], 0),
            ([-8.0, 6.0, 75.0, -5.0, 7.0, -10.0], 3),
        ],
        [-3.0, 5.0, 12.0, 0.2, -0.5, 0.1],
    );
}
