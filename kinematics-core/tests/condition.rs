#![allow(clippy::unwrap_used, clippy::expect_used)]
//! The parallel measure's warm-started Jacobi SVD ([`ConditionEstimator`]) agrees with
//! nalgebra's SVD (bidiagonalisation + implicit QR), from a cold start and along a path
//! of nearby poses (warm), in f64 and in f32.

use crate::common;

use common::*;
use kinematics_core::singularity::{parallel_inv_cond, ConditionEstimator};
use kinematics_core::*;
use nalgebra::{Matrix6, Vector3};
use proptest::prelude::*;

/// σ_min / σ_max of the column-scaled matrix by nalgebra's SVD (f64).
fn reference_inv_cond(jtilde: &Matrix6<f64>, rp: f64) -> f64 {
    let (min, max) = reference_extremes(jtilde, rp);
    min / max
}

/// σ_min and σ_max of the column-scaled matrix by nalgebra's SVD (f64).
fn reference_extremes(jtilde: &Matrix6<f64>, rp: f64) -> (f64, f64) {
    let mut a = *jtilde;
    for mut c in a.column_iter_mut().skip(3) {
        c /= rp;
    }
    let sv = a.svd(false, false).singular_values;
    (sv.min(), sv.max())
}

proptest! {
    #![proptest_config(proptest_config::cases(256))]

    /// Random matrices (entries in [-1, 1]): cold Jacobi = nalgebra's SVD to 1e-12
    /// relative in f64 (the inverse condition number and σ_max), and to 2e-5 in f32 (both
    /// against the f64 reference).
    #[test]
    fn cold_start_matches_nalgebra(entries in proptest::collection::vec(-1.0f64..1.0, 36)) {
        let m = Matrix6::from_column_slice(&entries);
        let want = reference_inv_cond(&m, 0.05);
        let got = parallel_inv_cond(&m, 0.05).unwrap();
        prop_assert!((got - want).abs() <= 1e-12 * want.max(1e-3), "f64 {got} vs {want}");
        // The estimator's σ_max (the certified regions use it): nalgebra's, to 1e-12 relative.
        let mut est = ConditionEstimator::new();
        est.inv_cond(&m, 0.05).unwrap();
        let (_, max) = reference_extremes(&m, 0.05);
        prop_assert!((est.sigma_max() - max).abs() <= 1e-12 * max, "σ_max {} vs {max}", est.sigma_max());
        let m32 = m.map(|x| x as f32);
        let got32 = f64::from(parallel_inv_cond(&m32, 0.05f32).unwrap());
        // f32 relative accuracy of σ_min degrades with the condition number.
        prop_assert!((got32 - want).abs() <= 2e-6 / want.max(1e-3), "f32 {got32} vs {want}");
    }

    /// Along a path through the task box (100 poses 0.1 mm and 0.02 deg apart), one warm
    /// estimator per scalar type agrees with nalgebra at every pose, and after the first
    /// pose needs at most 3 sweeps in f32 (the MCU) and 5 in f64 (whose tolerance is 1e-14) (a cold start needs about 6 to 8).
    #[test]
    fn warm_start_tracks_a_path(
        start in pose_near_box(0.16),
        dir in proptest::array::uniform3(-1.0f64..1.0),
        axis in proptest::array::uniform3(-1.0f64..1.0),
    ) {
        let g = RsprGeometry::<f64>::reference();
        let g32 = RsprGeometry::<f32>::reference();
        let d = Vector3::from(dir).normalize() * 1e-4;
        let w = Vector3::from(axis).normalize() * 0.02f64.to_radians();
        let (mut est, mut est32) = (ConditionEstimator::new(), ConditionEstimator::new());
        let mut pose = start;
        for k in 0..100 {
            let Ok(sol) = inverse(&g, &pose, Branch::OUTER) else { break };
            let jt = kinematics_core::jacobian::tripod_jacobian(&sol);
            let want = reference_inv_cond(&jt, g.rp);
            let got = est.inv_cond(&jt, g.rp).unwrap();
            prop_assert!((got - want).abs() <= 1e-12, "pose {k}: f64 {got} vs {want}");
            let sol32 = inverse(&g32, &pose.cast::<f32>(), Branch::OUTER).unwrap();
            let jt32 = kinematics_core::jacobian::tripod_jacobian(&sol32);
            let got32 = f64::from(est32.inv_cond(&jt32, g32.rp).unwrap());
            prop_assert!((got32 - want).abs() <= 1e-5, "pose {k}: f32 {got32} vs {want}");
            if k > 0 {
                prop_assert!(est.last_sweeps() <= 5, "f64 sweeps {}", est.last_sweeps());
                prop_assert!(est32.last_sweeps() <= 3, "f32 sweeps {}", est32.last_sweeps());
            }
            pose = pose.displaced(&d, &w);
        }
    }
}

/// A rank-deficient matrix gives 0 (to rounding), not an error or a NaN.
#[test]
fn rank_deficient_gives_zero() {
    let mut m = Matrix6::<f64>::identity();
    m.set_row(1, &m.row(0).into_owned());
    let got = parallel_inv_cond(&m, 1.0).unwrap();
    assert!(got < 1e-15, "{got}");
}

/// Non-finite input is an error, and the estimator starts cold again after it.
#[test]
fn non_finite_is_an_error() {
    let mut est = ConditionEstimator::<f64>::new();
    let mut m = Matrix6::<f64>::identity();
    m[(2, 3)] = f64::NAN;
    assert!(est.inv_cond(&m, 1.0).is_err());
    assert_eq!(est, ConditionEstimator::new());
}
