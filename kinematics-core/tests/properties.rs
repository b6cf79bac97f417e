#![allow(clippy::unwrap_used, clippy::expect_used)]
//! Property tests of the kinematics core over random poses in and around the task box, on
//! every branch, for both robots (f64, the host's reference precision).

use crate::common;

use common::*;
use kinematics_core::*;
use nalgebra::{Rotation3, Vector3, Vector6};
use proptest::prelude::*;

fn robots() -> [Robot<f64>; 2] {
    [
        Robot::Rspr(RsprGeometry::reference()),
        Robot::Usr(UsrGeometry::reference()),
    ]
}

/// q(x ⊕ δ) for a twist displacement δ = [dv; dω].
fn q_at(
    robot: &Robot<f64>,
    pose: &Pose<f64>,
    branch: Branch,
    d: &Vector6<f64>,
) -> Option<Joints<f64>> {
    let p = pose.displaced(
        &Vector3::new(d[0], d[1], d[2]),
        &Vector3::new(d[3], d[4], d[5]),
    );
    inverse(robot, &p, branch).ok().map(|s| s.q())
}

proptest! {
    #![proptest_config(proptest_config::cases(512))]

    /// IK then FK returns the pose (f64: 1e-9 m and 1e-9 rad), on every branch that has a
    /// solution outside the parallel-singularity stop level of the guards (inverse condition
    /// number ≥ 0.01; closer to a singularity the direct problem's solutions merge and a
    /// warm start 0.5 mm away may converge to the neighbouring one), warm-started from a pose
    /// up to 0.5 mm and 0.5 deg away.
    #[test]
    fn ik_then_fk_returns_the_pose(pose in pose_near_box(0.0), (dv, dw) in perturbation()) {
        for robot in robots() {
            let pose = Pose { t: pose.t + Vector3::new(0.0, 0.0, robot.hc()), r: pose.r };
            let mut solved = 0;
            for branch in Branch::ALL {
                let Ok(sol) = inverse(&robot, &pose, branch) else { continue };
                if measures(&robot, &sol).map_or(true, |m| m.parallel_inv_cond < 0.01) { continue }
                solved += 1;
                let guess = pose.displaced(&dv, &dw);
                // A warm start needs a guess the branch can reach (at the edge of the
                // workspace the perturbed pose may not be).
                if inverse(&robot, &guess, branch).is_err() { continue }
                let fk = forward(&robot, &sol.q(), branch, &guess, &FkConfig::default());
                let fk = fk.map_err(|e| TestCaseError::fail(format!("{:?} branch {branch}: {e}", robot.kind())))?;
                let (dp, dr) = pose_error(&fk.pose, &pose);
                prop_assert!(dp < 1e-9 && dr < 1e-9, "{:?} branch {branch}: {dp:e} m, {dr:e} rad", robot.kind());
            }
            // Inside the thesis's task (the box, tilts up to 20 deg) the RSPR has at least its
            // prototype branch well conditioned; outside it, and for the smaller reference
            // USR, some poses are out of reach on every branch.
            let d = pose.t - Vector3::new(0.0, 0.0, robot.hc());
            let in_task = d.x.abs() <= 0.02 && d.y.abs() <= 0.02 && d.z.abs() <= 0.01 && pose.r.angle() <= 20f64.to_radians();
            prop_assert!(solved >= 1 || robot.kind() == RobotKind::Usr || !in_task);
        }
    }

    /// The analytic J = Js⁻¹ Jtilde equals finite differences of the inverse kinematics
    /// along each twist direction (columns [v; ω]): central differences at h and h/2
    /// combined by Richardson extrapolation (error O(h⁴)), so that the check holds near
    /// serial singularities too, where the IK's higher derivatives grow (|J| in the
    /// hundreds) and plain central differences are off by 1e-4 relative.
    #[test]
    fn analytic_jacobian_matches_finite_differences(pose in pose_near_box(0.0)) {
        let h = 1e-6;
        for robot in robots() {
            let pose = Pose { t: pose.t + Vector3::new(0.0, 0.0, robot.hc()), r: pose.r };
            let central = |branch: Branch, k: usize, h: f64| {
                let mut d = Vector6::zeros();
                d[k] = h;
                let qp = q_at(&robot, &pose, branch, &d)?;
                let qm = q_at(&robot, &pose, branch, &(-d))?;
                let mut fd = (qp - qm) / (2.0 * h);
                for (i, kind) in robot.joint_kinds().iter().enumerate() {
                    if *kind == JointKind::Angular {
                        fd[i] = scalar::wrap_angle(qp[i] - qm[i]) / (2.0 * h);
                    }
                }
                Some(fd)
            };
            for branch in Branch::ALL {
                let Ok(sol) = inverse(&robot, &pose, branch) else { continue };
                let Ok(jac) = jacobian(&robot, &sol) else { continue };
                for k in 0..6 {
                    let (Some(coarse), Some(fine)) = (central(branch, k, h), central(branch, k, h / 2.0)) else { continue };
                    let fd = (fine * 4.0 - coarse) / 3.0;
                    let col = jac.j.column(k);
                    let err = (fd - col).norm();
                    prop_assert!(err <= 1e-5 * (1.0 + col.norm()),
                        "{:?} branch {branch} column {k}: |fd - J| = {err:e}, |J| = {}", robot.kind(), col.norm());
                }
            }
        }
    }

    /// Virtual work balances: τ·q̇ = s_e·[v; ω] with q̇ = J [v; ω] and τ = J⁻ᵀ s_e.
    #[test]
    fn virtual_work_balances(
        pose in pose_near_box(0.0),
        xdot in prop::array::uniform6(-1.0..1.0f64),
        se in prop::array::uniform6(-10.0..10.0f64),
    ) {
        let xdot = Vector6::from_row_slice(&xdot);
        let se = Vector6::from_row_slice(&se);
        for robot in robots() {
            let pose = Pose { t: pose.t + Vector3::new(0.0, 0.0, robot.hc()), r: pose.r };
            for branch in Branch::ALL {
                let Ok(sol) = inverse(&robot, &pose, branch) else { continue };
                let Ok(jac) = jacobian(&robot, &sol) else { continue };
                let Ok(st) = actuator_forces(&jac, robot.rp(), &se, 1e-6) else { continue };
                let qdot = jac.j * xdot;
                let lhs = st.tau.dot(&qdot);
                let rhs = se.dot(&xdot);
                let scale = st.tau.norm() * qdot.norm() + se.norm() * xdot.norm();
                prop_assert!((lhs - rhs).abs() <= 1e-9 * scale,
                    "{:?} branch {branch}: τ·q̇ = {lhs}, s_e·ẋ = {rhs}", robot.kind());
                // The same τ solves Jᵀ τ = s_e (Eq. 7.10).
                prop_assert!((jac.j.transpose() * st.tau - se).norm() <= 1e-8 * (1.0 + se.norm() + st.tau.norm()));
            }
        }
    }

    /// FK never returns a pose that does not reproduce the joints: for joints perturbed off
    /// a valid solution (possibly unreachable), FK either fails with a typed error or its
    /// pose's IK gives back the joints.
    #[test]
    fn fk_result_always_reproduces_the_joints(
        pose in pose_near_box(0.0),
        dq in prop::array::uniform6(-0.02..0.02f64),
    ) {
        for robot in robots() {
            let pose = Pose { t: pose.t + Vector3::new(0.0, 0.0, robot.hc()), r: pose.r };
            let Ok(sol) = inverse(&robot, &pose, Branch::OUTER) else { continue };
            let q = sol.q() + Vector6::from_row_slice(&dq) * 5.0;
            let cfg = FkConfig::default();
            if let Ok(fk) = forward(&robot, &q, Branch::OUTER, &pose, &cfg) {
                let back = inverse(&robot, &fk.pose, Branch::OUTER);
                prop_assert!(back.is_ok());
                if let Ok(back) = back {
                    for (i, kind) in robot.joint_kinds().iter().enumerate() {
                        let mut d = back.q()[i] - q[i];
                        let tol = match kind {
                            JointKind::Linear => cfg.tol_linear,
                            JointKind::Angular => { d = scalar::wrap_angle(d); cfg.tol_angular }
                        };
                        prop_assert!(d.abs() <= tol, "q{} off by {d:e}", i + 1);
                    }
                }
            }
        }
    }

    /// The spherical-joint tilt is zero at the central configuration of every branch and
    /// grows continuously: it is below the platform's own rotation plus the leg swing.
    #[test]
    fn tilt_is_zero_at_centre_and_bounded(pose in pose_near_box(0.0)) {
        for robot in robots() {
            let axes = SocketAxes::new(&robot).map_err(|e| TestCaseError::fail(e.to_string()))?;
            for branch in Branch::ALL {
                let central = inverse(&robot, &Pose::central(robot.hc()), branch)
                    .map_err(|e| TestCaseError::fail(e.to_string()))?;
                for (_, t) in tilt_angles(&central, &axes).iter() {
                    prop_assert!(t.abs() < 1e-12);
                }
                let pose = Pose { t: pose.t + Vector3::new(0.0, 0.0, robot.hc()), r: pose.r };
                if let Ok(sol) = inverse(&robot, &pose, branch) {
                    for (_, t) in tilt_angles(&sol, &axes).iter() {
                        prop_assert!(t.is_finite() && *t >= 0.0 && *t <= core::f64::consts::PI);
                    }
                }
            }
        }
    }
}

/// RSPR branch numbering: at the central configuration, bit clear = outer (θ_i = 0, the
/// larger t along v_i), bit set = inner (θ_i = 180 deg).
#[test]
fn rspr_branch_bits_select_outer_and_inner() {
    let g = RsprGeometry::<f64>::reference();
    for branch in Branch::ALL {
        let s = inverse(&g, &Pose::central(g.hc), branch).unwrap();
        for (c, cs) in s.chains.iter() {
            let expect = if branch.is_set(c) {
                core::f64::consts::PI
            } else {
                0.0
            };
            assert!(
                scalar::wrap_angle(cs.qb - expect).abs() < 1e-12,
                "branch {branch} {c}"
            );
            // l_i = |p_i - b_i|: outer sqrt(60² + 160²) mm, inner sqrt(120² + 160²) mm.
            let l = if branch.is_set(c) {
                0.2
            } else {
                (0.06f64.powi(2) + 0.16f64.powi(2)).sqrt()
            };
            assert!((cs.qa - l).abs() < 1e-12);
        }
    }
}

/// USR branch numbering: bit clear takes the larger wrapped γ_i (positive near the central
/// configuration), bit set the smaller.
#[test]
fn usr_branch_bits_select_larger_and_smaller_gamma() {
    let g = UsrGeometry::<f64>::reference();
    let central = Pose::central(g.hc);
    let outer = inverse(&g, &central, Branch::OUTER).unwrap();
    for branch in Branch::ALL {
        let s = inverse(&g, &central, branch).unwrap();
        for (c, cs) in s.chains.iter() {
            if branch.is_set(c) {
                assert!(cs.gamma < outer.chains[c].gamma);
            } else {
                assert!(cs.gamma > 0.0 && cs.gamma == outer.chains[c].gamma);
            }
        }
    }
}

/// Thesis Table 11.1: with parallel platforms on the outer branch, a 144 mm leg gives the
/// 130.9 mm height and the 201.2 mm height needs a 210 mm leg.
#[test]
fn thesis_table_11_1_height_range() {
    let g = RsprGeometry::<f64>::reference();
    let cfg = FkConfig::default();
    for (leg_mm, height_mm) in [(144.0, 130.9), (210.0, 201.2)] {
        let l = leg_mm * 1e-3;
        let q = Joints::new(l, l, l, 0.0, 0.0, 0.0);
        let fk = forward(&g, &q, Branch::OUTER, &Pose::central(g.hc), &cfg).unwrap();
        assert!(
            (fk.pose.t.z * 1e3 - height_mm).abs() < 0.05,
            "{leg_mm} mm leg gives {} mm",
            fk.pose.t.z * 1e3
        );
        assert!(fk.pose.t.xy().norm() < 1e-12 && fk.pose.r.angle() < 1e-12);
        let sol = inverse(&g, &Pose::central(height_mm * 1e-3), Branch::OUTER).unwrap();
        for (_, c) in sol.chains.iter() {
            assert!(
                (c.qa * 1e3 - leg_mm).abs() < 0.05,
                "{height_mm} mm needs {} mm",
                c.qa * 1e3
            );
        }
    }
}

/// FK from the central configuration (no warm start) converges over the whole task at both
/// orientations on the prototype's branch.
#[test]
fn fk_from_central_covers_the_task() {
    let g = RsprGeometry::<f64>::reference();
    let mut worst_iterations = 0;
    for pose in task_grid(g.hc, 5, 3) {
        let sol = inverse(&g, &pose, Branch::OUTER).unwrap();
        let fk = forward(
            &g,
            &sol.q(),
            Branch::OUTER,
            &Pose::central(g.hc),
            &FkConfig::default(),
        )
        .unwrap();
        let (dp, dr) = pose_error(&fk.pose, &pose);
        assert!(dp < 1e-9 && dr < 1e-9);
        worst_iterations = worst_iterations.max(fk.iterations);
    }
    println!("FK from the central pose: at most {worst_iterations} Newton steps over the task");
}

/// Bad input gives a typed error naming the chain and the reason, never NaN joints.
#[test]
fn failures_are_typed_and_name_the_chain() {
    let g = RsprGeometry::<f64>::reference();
    let bad = Pose {
        t: Vector3::new(f64::NAN, 0.0, 0.16),
        r: Rotation3::identity(),
    };
    assert_eq!(
        inverse(&g, &bad, Branch::OUTER).unwrap_err().reason,
        IkFailure::NonFiniteInput
    );
    assert!(Pose::<f64>::from_position_rotation_vector(
        Vector3::new(0.0, 0.0, 0.16),
        Vector3::new(0.0, f64::INFINITY, 0.0)
    )
    .is_err());
    // Far to the side: chain 1's line v_1 misses its link circle.
    let far = Pose {
        t: Vector3::new(0.4, 0.0, 0.16),
        r: Rotation3::identity(),
    };
    let e = inverse(&g, &far, Branch::OUTER).unwrap_err();
    assert_eq!(e.reason, IkFailure::NoRealRoot);
    // Platform standing perpendicular to the base: the leg plane is degenerate.
    let side = Pose {
        t: Vector3::new(0.0, 0.0, 0.16),
        r: Rotation3::from_scaled_axis(Vector3::new(0.0, core::f64::consts::FRAC_PI_2, 0.0)),
    };
    assert!(inverse(&g, &side, Branch::OUTER).is_err());
    // USR: out of reach above the links.
    let u = UsrGeometry::<f64>::reference();
    let high = Pose::central(0.5);
    assert_eq!(
        inverse(&u, &high, Branch::OUTER).unwrap_err().reason,
        IkFailure::NoRealRoot
    );
    // FK with NaN joints or an unreachable target.
    let q = Joints::new(f64::NAN, 0.17, 0.17, 0.0, 0.0, 0.0);
    assert_eq!(
        forward(
            &g,
            &q,
            Branch::OUTER,
            &Pose::central(g.hc),
            &FkConfig::default()
        )
        .unwrap_err(),
        FkError::NonFiniteInput { index: 0 }
    );
    let q = Joints::new(0.17, 0.17, 0.17, 3.0, -3.0, 1.5);
    let r = forward(
        &g,
        &q,
        Branch::OUTER,
        &Pose::central(g.hc),
        &FkConfig::default(),
    );
    assert!(
        matches!(
            r,
            Err(FkError::DidNotConverge { .. }
                | FkError::LeftBranch { .. }
                | FkError::SingularStep { .. })
        ),
        "{r:?}"
    );
    // Forces at an invalid wrench.
    let sol = inverse(&g, &Pose::central(g.hc), Branch::OUTER).unwrap();
    let jac = jacobian(&g, &sol).unwrap();
    let w = Vector6::new(f64::NAN, 0.0, 0.0, 0.0, 0.0, 0.0);
    assert_eq!(
        actuator_forces(&jac, g.rp, &w, 1e-6).unwrap_err(),
        ForceError::NonFiniteWrench
    );
}

/// A parallel-singular configuration is reported as an error by the statics, not as huge
/// forces: with the platform in the base plane at the base's size all lines ŝ1 are coplanar.
#[test]
fn singular_statics_is_an_error() {
    let g = RsprGeometry::<f64>::reference();
    let sol = inverse(&g, &Pose::central(g.hc), Branch::OUTER).unwrap();
    let mut jac = jacobian(&g, &sol).unwrap();
    // Make two rows equal: a rank-deficient Jtilde.
    let row = jac.jtilde.row(0).into_owned();
    jac.jtilde.set_row(1, &row);
    let e = actuator_forces(&jac, g.rp, &Vector6::repeat(1.0), 1e-6).unwrap_err();
    assert!(matches!(e, ForceError::ParallelSingular { .. }), "{e:?}");
}

/// The measures name the nearest singularity. The RSPR serial measure |Cn2_i| (Eq. 10.6)
/// vanishes where the leg plane is tangent to the link circle (case c of Eq. 10.7, the two
/// roots of Eq. 6.22 meet); a Jacobian at a serially singular chain is refused.
#[test]
fn serial_singularity_is_detected() {
    let g = RsprGeometry::<f64>::reference();
    // At the central configuration Cn2_i = rb (the revolute axis is tangent to the link
    // circle) and the parallel measure is the nearest.
    let sol = inverse(&g, &Pose::central(g.hc), Branch::OUTER).unwrap();
    let m = measures(&g, &sol).unwrap();
    for (_, s) in m.serial.iter() {
        assert!((s - g.rb).abs() < 1e-12);
    }
    assert_eq!(m.nearest, Nearest::Parallel);
    // Shifted by rb - δ along y0 with parallel platforms, chain 1's line v_1 (y = t_y)
    // almost touches its link circle: |Cn2_1| = sqrt(2 rb δ - δ²).
    let delta = 1e-9;
    let pose = Pose {
        t: Vector3::new(0.0, g.rb - delta, g.hc),
        r: Rotation3::identity(),
    };
    let sol = inverse(&g, &pose, Branch::OUTER).unwrap();
    let m = measures(&g, &sol).unwrap();
    let expect = (2.0 * g.rb * delta - delta * delta).sqrt();
    assert!(
        (m.serial[Chain::One] - expect).abs() < 1e-9,
        "{} vs {expect}",
        m.serial[Chain::One]
    );
    assert_eq!(m.nearest, Nearest::Serial(Chain::One));
    // Exactly tangent: the leg's revolute axis is parallel to the rotating link.
    let mut at = sol;
    at.chains[Chain::One].s2 = at.chains[Chain::One].lb.normalize();
    assert!(matches!(
        jacobian(&g, &at),
        Err(JacobianError::SerialSingular {
            chain: Chain::One,
            ..
        })
    ));
    // Beyond tangency the chain has no real root and IK names it.
    let pose = Pose {
        t: Vector3::new(0.0, g.rb + 1e-6, g.hc),
        r: Rotation3::identity(),
    };
    assert_eq!(
        inverse(&g, &pose, Branch::OUTER).unwrap_err(),
        IkError {
            chain: Chain::One,
            reason: IkFailure::NoRealRoot
        }
    );
}
