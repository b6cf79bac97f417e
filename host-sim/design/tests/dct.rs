//! The planar circle-triangle mechanism of the double circular-triangular robot: the
//! inverse and direct kinematics invert each other, the Jacobian derived by virtual work
//! is the derivative of the inverse kinematics, the statics satisfy virtual work, and the
//! appendix's Eq. 11 as printed cannot be the Jacobian (its second column vanishes).
#![allow(clippy::unwrap_used, clippy::expect_used)]

use design::dct::{Planar, PlanarPose};
use nalgebra::{Vector2, Vector3};
use proptest::prelude::*;

/// Table 4.1's double planar robot: Rb = Rp = 199.138 mm, Lb = Lp = 460.320 mm.
fn table_4_1() -> Planar {
    Planar::new(0.199138, 0.460320).unwrap()
}

fn pose() -> impl Strategy<Value = PlanarPose> {
    (-0.04..0.04f64, -0.04..0.04f64, -3.1..3.1f64).prop_map(|(x, y, psi)| PlanarPose {
        p: Vector2::new(x, y),
        psi,
    })
}

fn wrapped(a: f64) -> f64 {
    let t = a.rem_euclid(2.0 * std::f64::consts::PI);
    if t > std::f64::consts::PI {
        t - 2.0 * std::f64::consts::PI
    } else {
        t
    }
}

proptest! {
    #![proptest_config(proptest_config::cases(256))]

    /// IK on every branch, then DK: one of the two assembly modes is the pose (1e-12 m,
    /// 1e-12 rad), and the IK of both modes gives back the joints.
    #[test]
    fn direct_kinematics_inverts_the_inverse(x in pose(), branch in 0u8..8) {
        let g = table_4_1();
        let phi = g.inverse(&x, branch).unwrap();
        let modes = g.direct(&phi).unwrap();
        let best = modes
            .iter()
            .map(|m| ((m.p - x.p).norm(), wrapped(m.psi - x.psi).abs()))
            .fold((f64::INFINITY, f64::INFINITY), |a, b| if b.0 + b.1 < a.0 + a.1 { b } else { a });
        prop_assert!(best.0 < 1e-12 && best.1 < 1e-12, "{best:?}");
        for m in &modes {
            // Each mode satisfies the three constraints: (t_i - p)·n_i = r.
            for (i, f) in phi.iter().enumerate() {
                let c = (g.pivot(*f) - m.p).dot(&Planar::normal(m.psi, i)) - g.inradius();
                prop_assert!(c.abs() < 1e-12, "{c}");
            }
        }
    }

    /// J̄ = dq/dx within 1e-6 relative of central differences of the inverse kinematics
    /// (q = rc φ), column by column.
    #[test]
    fn jacobian_is_the_derivative_of_the_inverse_kinematics(x in pose(), branch in 0u8..8) {
        let g = table_4_1();
        let phi = g.inverse(&x, branch).unwrap();
        let j = g.jacobian(&x, &phi).unwrap();
        let h = 1e-6;
        for k in 0..3 {
            let shift = |d: f64| {
                let mut y = x;
                match k {
                    0 => y.p.x += d,
                    1 => y.p.y += d,
                    _ => y.psi += d,
                }
                g.inverse(&y, branch).unwrap()
            };
            let (plus, minus) = (shift(h), shift(-h));
            let fd = Vector3::from_fn(|i, _| g.rc * wrapped(plus[i] - minus[i]) / (2.0 * h));
            let col = j.column(k).into_owned();
            let err = (fd - col).norm() / col.norm().max(1e-3);
            prop_assert!(err < 1e-6, "column {k}: {err:e}");
        }
    }

    /// τ = J̄⁻ᵀ w satisfies virtual work: τ·q̇ = w·ẋ with q̇ = J̄ ẋ, to 1e-9 relative.
    #[test]
    fn statics_satisfy_virtual_work(
        x in pose(),
        branch in 0u8..8,
        w in prop::array::uniform3(-10.0..10.0f64),
        xd in prop::array::uniform3(-1.0..1.0f64),
    ) {
        let g = table_4_1();
        let phi = g.inverse(&x, branch).unwrap();
        let (w, xd) = (Vector3::from(w), Vector3::from(xd));
        let tau = g.efforts(&x, &phi, &w).unwrap();
        let qd = g.jacobian(&x, &phi).unwrap() * xd;
        let (lhs, rhs) = (tau.dot(&qd), w.dot(&xd));
        let scale = tau.norm() * qd.norm() + w.norm() * xd.norm();
        prop_assert!((lhs - rhs).abs() <= 1e-9 * scale, "{lhs} vs {rhs}");
    }
}

/// Eq. 11 as printed: d_i = (x̂_ti·ŷ_0)(x̂_ti·(x̂_0 × t̂_i)), and x̂_0 × t̂_i is along ẑ_0
/// for every pivot in the plane, so the second column of the printed J̄ is zero and
/// Eq. 12's J̄⁻ᵀ does not exist: the printed formula cannot be the Jacobian.
#[test]
fn eq_11_as_printed_has_a_zero_column() {
    let g = table_4_1();
    let x = PlanarPose {
        p: Vector2::new(0.01, -0.02),
        psi: 0.3,
    };
    let phi = g.inverse(&x, 0).unwrap();
    for (i, f) in phi.iter().enumerate() {
        let n = Planar::normal(x.psi, i);
        let n3 = Vector3::new(n.x, n.y, 0.0);
        let t = Vector3::new(f.cos(), f.sin(), 0.0);
        let d_i = n3.y * n3.dot(&Vector3::x().cross(&t));
        assert_eq!(d_i, 0.0);
        // The derived row's second entry is n_y / s_i, not zero.
        let j = g.jacobian(&x, &phi).unwrap();
        assert!((j[(i, 1)] - n.y / n3.dot(&Vector3::z().cross(&t))).abs() < 1e-12);
    }
}

/// The appendix's conclusion on the Table 4.1 robot: it exceeds the 200 mm cube envelope
/// (its circles alone are 398.3 mm across), although the planar mechanisms reach the
/// task's ±20 mm and any rotation.
#[test]
fn table_4_1_robot_exceeds_the_envelope_but_reaches_the_task() {
    let g = table_4_1();
    assert!(2.0 * g.rc > 0.2, "diameter {} m", 2.0 * g.rc);
    for x in [-0.02, 0.0, 0.02] {
        for y in [-0.02, 0.0, 0.02] {
            for k in 0..36 {
                let p = PlanarPose {
                    p: Vector2::new(x, y),
                    psi: k as f64 * 10f64.to_radians(),
                };
                let phi = g.inverse(&p, 0).unwrap();
                assert!(g.jacobian(&p, &phi).is_ok());
            }
        }
    }
}

#[test]
fn bad_dimensions_and_unreachable_poses_are_refused() {
    assert!(Planar::new(0.0, 0.4).is_err());
    assert!(Planar::new(0.2, f64::NAN).is_err());
    let g = table_4_1();
    let far = PlanarPose {
        p: Vector2::new(0.5, 0.0),
        psi: 0.0,
    };
    let e = g.inverse(&far, 0).unwrap_err();
    assert!(e.to_string().contains("slider"), "{e}");
}
