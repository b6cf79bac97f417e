#![allow(clippy::unwrap_used, clippy::expect_used)]
//! Single precision (the MCU's f32) against the f64 reference.

use crate::common;

use common::*;
use kinematics_core::*;

use proptest::prelude::*;

proptest! {
    #![proptest_config(proptest_config::cases(512))]

    /// In f32, IK then FK returns the pose to 1 µm and 1e-5 rad (outer branch, the
    /// prototype's, over and around the task box), warm-started as in the control loop.
    #[test]
    fn f32_ik_then_fk_returns_the_pose(pose in pose_near_box(0.160), (dv, dw) in perturbation()) {
        // Poses the robot cannot reach at all (in f64) are not this property's business.
        prop_assume!(inverse(&RsprGeometry::<f64>::reference(), &pose, Branch::OUTER).is_ok());
        let g32 = RsprGeometry::<f32>::reference();
        let p32: Pose<f32> = pose.cast();
        let sol = inverse(&g32, &p32, Branch::OUTER).map_err(|e| TestCaseError::fail(e.to_string()))?;
        let guess = p32.displaced(&dv.cast(), &dw.cast());
        prop_assume!(inverse(&g32, &guess, Branch::OUTER).is_ok());
        let fk = forward(&g32, &sol.q(), Branch::OUTER, &guess, &FkConfig::default())
            .map_err(|e| TestCaseError::fail(e.to_string()))?;
        let (dp, dr) = pose_error(&fk.pose.cast::<f64>(), &pose);
        prop_assert!(dp < 1e-6 && dr < 1e-5, "{dp:e} m, {dr:e} rad after {} iterations", fk.iterations);
    }
}

/// f32 against f64 over the task box: the worst joint error stays below the encoder
/// resolution (0.0015 mm on the legs, 0.005 deg on the rotating links).
#[test]
fn f32_joints_match_f64_below_encoder_resolution() {
    let g64 = RsprGeometry::<f64>::reference();
    let g32 = RsprGeometry::<f32>::reference();
    let (mut worst_len, mut worst_ang) = (0.0f64, 0.0f64);
    let mut worst_fk = (0.0f64, 0.0f64);
    for pose in task_grid(g64.hc, 9, 5) {
        let q64 = inverse(&g64, &pose, Branch::OUTER).unwrap().q();
        let sol32 = inverse(&g32, &pose.cast::<f32>(), Branch::OUTER).unwrap();
        let q32 = sol32.q();
        for i in 0..3 {
            worst_len = worst_len.max((f64::from(q32[i]) - q64[i]).abs());
            worst_ang = worst_ang.max(scalar::wrap_angle(f64::from(q32[i + 3]) - q64[i + 3]).abs());
        }
        // FK in f32 from the f64 joints rounded to f32, warm-started at the pose.
        let fk = forward(
            &g32,
            &q64.cast::<f32>(),
            Branch::OUTER,
            &pose.cast(),
            &FkConfig::default(),
        )
        .unwrap();
        let (dp, dr) = pose_error(&fk.pose.cast::<f64>(), &pose);
        worst_fk = (worst_fk.0.max(dp), worst_fk.1.max(dr));
    }
    println!(
        "f32 vs f64 over the task box (9x9x5 grid, both orientations): worst leg error {:.3e} mm, \
         worst link-angle error {:.3e} deg; f32 FK worst pose error {:.3e} mm, {:.3e} deg",
        worst_len * 1e3,
        worst_ang.to_degrees(),
        worst_fk.0 * 1e3,
        worst_fk.1.to_degrees()
    );
    assert!(worst_len < 1.5e-6, "leg error {worst_len:e} m");
    assert!(worst_ang < 0.005 * DEG, "angle error {worst_ang:e} rad");
}

/// Composing many small rotations in f32 (the supervisor does one per tick) keeps the
/// orientation a rotation: after 30 000 steps of about 1e-4 rad, ‖RᵀR − I‖ stays at rounding.
#[test]
fn f32_orientation_stays_orthonormal_over_many_small_steps() {
    let mut pose = Pose::<f32>::central(0.16);
    let dw = nalgebra::Vector3::new(1e-4f32, -0.5e-4, 0.3e-4);
    for _ in 0..30_000 {
        pose = pose.displaced(&nalgebra::Vector3::zeros(), &dw);
    }
    let m = pose.r.matrix();
    let err = (m.transpose() * m - nalgebra::Matrix3::identity()).norm();
    println!("orthonormality error after 30 000 f32 steps: {err:e}");
    assert!(err < 1e-5, "{err}");
}
