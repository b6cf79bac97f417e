#![allow(clippy::unwrap_used, clippy::expect_used)]
//! The control path's 6×6 LU (`lu::Lu6`, written out) solves what nalgebra's LU solves:
//! A x = b and Aᵀ x = b on random matrices (backward stable in f64, and equal to nalgebra's
//! solutions within the conditioning), the robot's Jtilde in f32 over the task box against
//! f64, and it refuses singular and non-finite matrices.

mod common;

use common::*;
use kinematics_core::lu::Lu6;
use kinematics_core::*;
use nalgebra::{Matrix6, Vector6};
use proptest::prelude::*;

fn matrix() -> impl Strategy<Value = Matrix6<f64>> {
    proptest::collection::vec(-1.0f64..1.0, 36).prop_map(|v| Matrix6::from_column_slice(&v))
}

fn vector() -> impl Strategy<Value = Vector6<f64>> {
    proptest::array::uniform6(-1.0f64..1.0).prop_map(Vector6::from)
}

/// |A x - b| relative to |A| |x| + |b|.
fn backward_error(a: &Matrix6<f64>, x: &Vector6<f64>, b: &Vector6<f64>) -> f64 {
    (a * x - b).norm() / (a.norm() * x.norm() + b.norm())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]

    /// Random matrices: both solves are backward stable (error of a few ε) and agree with
    /// nalgebra's LU to the conditioning (difference below 1e-13 · cond · |x|).
    #[test]
    fn solves_like_nalgebra(a in matrix(), b in vector()) {
        let lu = Lu6::new(&a).expect("random matrices are regular");
        let x = lu.solve(&b);
        let xt = lu.solve_transposed(&b);
        prop_assert!(backward_error(&a, &x, &b) < 1e-14, "{}", backward_error(&a, &x, &b));
        prop_assert!(backward_error(&a.transpose(), &xt, &b) < 1e-14);
        let cond = a.norm() * a.try_inverse().unwrap().norm();
        let want = a.lu().solve(&b).unwrap();
        let want_t = a.transpose().lu().solve(&b).unwrap();
        prop_assert!((x - want).norm() <= 1e-13 * cond * want.norm());
        prop_assert!((xt - want_t).norm() <= 1e-13 * cond * want_t.norm());
    }

    /// The robot's Jtilde in f32 (as on the MCU): the f32 solutions of Jtilde Δx = b and
    /// Jtildeᵀ f = b are within 1e-5 (relative) of the f64 ones over the task box.
    #[test]
    fn f32_solves_jtilde_over_the_task_box(pose in pose_near_box(0.16), b in vector()) {
        prop_assume!(b.norm() > 0.1);
        let g = RsprGeometry::<f64>::reference();
        let g32 = RsprGeometry::<f32>::reference();
        let Ok(s) = inverse(&g, &pose, Branch::OUTER) else { return Ok(()) };
        let Ok(s32) = inverse(&g32, &pose.cast::<f32>(), Branch::OUTER) else { return Ok(()) };
        let jt = jacobian::tripod_jacobian(&s);
        let jt32 = jacobian::tripod_jacobian(&s32);
        let b32 = b.cast::<f32>();
        let (lu, lu32) = (Lu6::new(&jt).unwrap(), Lu6::new(&jt32).unwrap());
        for (x, x32) in [
            (lu.solve(&b), lu32.solve(&b32)),
            (lu.solve_transposed(&b), lu32.solve_transposed(&b32)),
        ] {
            let e = (x32.cast::<f64>() - x).norm() / x.norm();
            prop_assert!(e < 1e-5, "{e:e}");
        }
    }
}

/// Singular matrices (two equal rows, all zero) and non-finite ones have no factorisation;
/// a zero on the diagonal that pivoting moves away does.
#[test]
fn refuses_singular_and_non_finite() {
    let mut a = Matrix6::<f64>::identity();
    a.set_row(3, &a.row(1).clone_owned());
    assert!(Lu6::new(&a).is_none());
    assert!(Lu6::new(&a.transpose()).is_none());
    assert!(Lu6::new(&Matrix6::<f64>::zeros()).is_none());
    let mut b = Matrix6::<f64>::identity();
    b[(2, 2)] = f64::NAN;
    assert!(Lu6::new(&b).is_none());
    b[(2, 2)] = f64::INFINITY;
    assert!(Lu6::new(&b).is_none());
    // A cyclic permutation: every diagonal element is zero.
    let q = Matrix6::<f64>::from_fn(|i, j| if (i + 1) % 6 == j { 2.0 } else { 0.0 });
    let lu = Lu6::new(&q).unwrap();
    let v = Vector6::new(1.0, 2.0, 3.0, 4.0, 5.0, 6.0);
    assert!((q * lu.solve(&v) - v).norm() < 1e-15);
    assert!((q.transpose() * lu.solve_transposed(&v) - v).norm() < 1e-15);
}
