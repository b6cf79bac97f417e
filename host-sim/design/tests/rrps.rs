#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
//! The RRPS robot (Alizade, Tagiyev and Duffy): inverse kinematics, the Jacobian against
//! finite differences of the inverse kinematics, and the statics by virtual work.

use design::rrps::{
    rrps_actuator_forces, rrps_inverse, rrps_jacobian, RrpsFailure, RrpsGeometry, RrpsGeometryError,
};
use kinematics_core::scalar::wrap_angle;
use kinematics_core::{Branch, Pose, Wrench};
use nalgebra::{Matrix6, Vector3, Vector6};

fn pose(x_mm: f64, y_mm: f64, z_mm: f64, r_deg: [f64; 3]) -> Pose<f64> {
    let r = Vector3::from(r_deg).map(f64::to_radians);
    Pose::from_position_rotation_vector(Vector3::new(x_mm, y_mm, z_mm) * 1e-3, r).unwrap()
}

/// Poses in and around the task box, parallel and tilted.
fn poses() -> Vec<Pose<f64>> {
    let d = 11.547_005_383_792_516;
    vec![
        pose(0.0, 0.0, 160.0, [0.0; 3]),
        pose(-20.0, -20.0, 150.0, [d, d, d]),
        pose(20.0, 20.0, 170.0, [d, d, d]),
        pose(15.0, -10.0, 165.0, [14.1, 14.1, 0.0]),
        pose(-5.0, 18.0, 152.0, [-8.0, 3.0, 25.0]),
    ]
}

#[test]
fn comparison_geometry_validates_and_bad_ones_are_refused() {
    let g = RrpsGeometry::<f64>::comparison();
    assert_eq!(RrpsGeometry::new(g.e, g.rb, g.rp, g.hc), Ok(g));
    assert!(matches!(
        RrpsGeometry::new(0.0, -0.09, 0.05, 0.16),
        Err(RrpsGeometryError::NotPositive { field: "rb", .. })
    ));
    assert!(matches!(
        RrpsGeometry::new(f64::NAN, 0.09, 0.05, 0.16),
        Err(RrpsGeometryError::NonFinite { field: "e" })
    ));
    // e = rp puts every p_i on its first revolute axis at the central configuration.
    match RrpsGeometry::new(0.05, 0.09, 0.05, 0.16) {
        Err(RrpsGeometryError::NotAssemblable { error, .. }) => {
            assert_eq!(error.reason, RrpsFailure::OnPivotAxis)
        }
        other => panic!("{other:?}"),
    }
    let bad = Pose {
        t: Vector3::new(f64::NAN, 0.0, 0.16),
        r: nalgebra::Rotation3::identity(),
    };
    assert_eq!(
        rrps_inverse(&g, &bad, Branch::OUTER).unwrap_err().reason,
        RrpsFailure::NonFinite
    );
}

/// At the central configuration the outer links point radially (θ = 0), the inner ones
/// away (θ = π), and l = sqrt((rb ∓ rp)² + hc²).
#[test]
fn central_configuration_by_hand() {
    let g = RrpsGeometry::<f64>::comparison();
    let c = Pose::central(g.hc);
    let outer = rrps_inverse(&g, &c, Branch::OUTER).unwrap().q();
    let inner = rrps_inverse(&g, &c, Branch::new(7).unwrap()).unwrap().q();
    for i in 0..3 {
        assert!((outer[i] - (0.04f64.hypot(0.16))).abs() < 1e-12);
        assert!((inner[i] - (0.14f64.hypot(0.16))).abs() < 1e-12);
        assert!(outer[3 + i].abs() < 1e-12);
        assert!((inner[3 + i].abs() - core::f64::consts::PI).abs() < 1e-12);
    }
}

/// The closure equations hold at every solution: (p - b)·a = 0, |p - b| = l, |b - e| = rb,
/// a horizontal and perpendicular to the link.
#[test]
fn closure_equations_hold_on_every_branch() {
    let g = RrpsGeometry::<f64>::comparison();
    for p in poses() {
        for branch in Branch::ALL {
            let sol = rrps_inverse(&g, &p, branch).unwrap();
            for (chain, c) in sol.chains.iter() {
                let leg = c.p - c.b;
                assert!(leg.dot(&c.a).abs() < 1e-14, "{chain}");
                assert!((leg.norm() - c.l).abs() < 1e-14);
                assert!(((c.b - c.e).norm() - g.rb).abs() < 1e-14);
                assert!(c.a.z.abs() < 1e-15 && c.a.dot(&c.u).abs() < 1e-15);
                let expected = if branch.is_set(chain) { -1.0 } else { 1.0 };
                assert_eq!(c.rho.signum(), expected);
            }
        }
    }
}

fn q_at(g: &RrpsGeometry<f64>, p: &Pose<f64>, branch: Branch, d: &Vector6<f64>) -> Vector6<f64> {
    let p = p.displaced(
        &Vector3::new(d[0], d[1], d[2]),
        &Vector3::new(d[3], d[4], d[5]),
    );
    rrps_inverse(g, &p, branch).unwrap().q()
}

/// dq/dx by central differences of the inverse kinematics (angles wrapped).
fn fd_jacobian(g: &RrpsGeometry<f64>, p: &Pose<f64>, branch: Branch) -> Matrix6<f64> {
    let h = 1e-6;
    let mut j = Matrix6::zeros();
    for k in 0..6 {
        let mut d = Vector6::zeros();
        d[k] = h;
        let (qp, qm) = (q_at(g, p, branch, &d), q_at(g, p, branch, &-d));
        for r in 0..6 {
            let dq = if r < 3 {
                qp[r] - qm[r]
            } else {
                wrap_angle(qp[r] - qm[r])
            };
            j[(r, k)] = dq / (2.0 * h);
        }
    }
    j
}

#[test]
fn analytic_jacobian_matches_finite_differences_of_the_ik() {
    let g = RrpsGeometry::<f64>::comparison();
    for p in poses() {
        for branch in [
            Branch::OUTER,
            Branch::new(5).unwrap(),
            Branch::new(7).unwrap(),
        ] {
            let sol = rrps_inverse(&g, &p, branch).unwrap();
            let jac = rrps_jacobian(&g, &sol).unwrap();
            let fd = fd_jacobian(&g, &p, branch);
            let err = (jac.j - fd).abs().max();
            assert!(err < 1e-6, "branch {branch}: {err:e}\n{}\n{fd}", jac.j);
            // The serial block is diag(1, rho): the leg is perpendicular to a.
            for (c, blk) in jac.serial.iter() {
                assert!(blk.a12.abs() < 1e-14 && (blk.a22 - sol.chains[c].rho).abs() < 1e-15);
            }
        }
    }
}

/// τ·q̇ = s_e·[v; ω] for arbitrary twists, and τ_θ = ρ f_side.
#[test]
fn forces_satisfy_virtual_work() {
    let g = RrpsGeometry::<f64>::comparison();
    let se = Wrench::new(7.0, 7.0, 7.0, 0.7, 0.7, 0.7);
    for p in poses() {
        let sol = rrps_inverse(&g, &p, Branch::OUTER).unwrap();
        let jac = rrps_jacobian(&g, &sol).unwrap();
        let st = rrps_actuator_forces(&jac, g.rp, &se, 1e-6).unwrap();
        for k in 0..6 {
            let mut x = Vector6::zeros();
            x[k] = 1.0;
            let lhs = st.tau.dot(&(jac.j * x));
            assert!((lhs - se.dot(&x)).abs() < 1e-9, "{lhs} vs {}", se[k]);
        }
        for (c, ch) in sol.chains.iter() {
            let i = c.index();
            assert!((st.tau[3 + i] - ch.rho * st.f2[i]).abs() < 1e-12);
            assert_eq!(st.tau[i], st.f1[i]);
        }
    }
    let sol = rrps_inverse(&g, &Pose::central(g.hc), Branch::OUTER).unwrap();
    let jac = rrps_jacobian(&g, &sol).unwrap();
    let nan = Wrench::new(f64::NAN, 0.0, 0.0, 0.0, 0.0, 0.0);
    assert!(rrps_actuator_forces(&jac, g.rp, &nan, 1e-6).is_err());
}

/// f32 (the MCU's scalar) agrees with f64.
#[test]
fn f32_agrees_with_f64() {
    let g32 = RrpsGeometry::<f32>::comparison();
    let g64 = RrpsGeometry::<f64>::comparison();
    for p in poses() {
        let q64 = rrps_inverse(&g64, &p, Branch::OUTER).unwrap().q();
        let q32 = rrps_inverse(&g32, &p.cast::<f32>(), Branch::OUTER)
            .unwrap()
            .q();
        for i in 0..6 {
            assert!((q32[i] as f64 - q64[i]).abs() < 1e-5);
        }
    }
}
