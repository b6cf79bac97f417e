#![allow(clippy::unwrap_used, clippy::expect_used)]
//! The pose update of the control path: `exp_so3` equals nalgebra's axis-angle rotation at
//! every angle (series branch and trigonometric branch), and `Pose::displaced` stays a
//! rotation over a long run of small f32 steps.

use kinematics_core::pose::exp_so3;
use kinematics_core::Pose;
use nalgebra::{Rotation3, Vector3};
use proptest::prelude::*;

proptest! {
    #![proptest_config(proptest_config::cases(1024))]

    /// exp([w]×) = Rotation3::from_scaled_axis(w) to 1e-15 for |w| from 1e-9 to 3 rad.
    #[test]
    fn exp_matches_nalgebra(axis in proptest::array::uniform3(-1.0f64..1.0), log_angle in -9.0f64..0.5) {
        let a = Vector3::from(axis);
        prop_assume!(a.norm() > 1e-3);
        let w = a.normalize() * 10f64.powf(log_angle);
        let got = exp_so3(&w);
        let want = Rotation3::from_scaled_axis(w);
        prop_assert!((got - want.matrix()).amax() < 1e-15, "{got} vs {want}");
    }
}

/// 100,000 f32 steps of 1 mrad (100 s of rotation at 1 kHz): the matrix stays orthonormal
/// to 1e-6 and the accumulated angle is right to 1e-3 rad.
#[test]
fn displaced_stays_a_rotation_in_f32() {
    let mut p = Pose::<f32>::central(0.16);
    let dw = Vector3::new(1e-3f32, 0.0, 0.0);
    for _ in 0..100_000 {
        p = p.displaced(&Vector3::zeros(), &dw);
    }
    let m = p.r.matrix();
    let err = (m.transpose() * m - nalgebra::Matrix3::identity()).amax();
    assert!(err < 1e-6, "orthonormality error {err}");
    let want = Rotation3::from_scaled_axis(Vector3::new(100.0f64, 0.0, 0.0));
    let got = p.r.cast::<f64>();
    assert!(
        got.angle_to(&want) < 1e-3,
        "angle error {}",
        got.angle_to(&want)
    );
}

/// The f32 sine and cosine of the control path (`scalar::sin_cos`, no double precision on
/// the MCU) against the f64 functions: within 1.2e-7 (1 ulp at 1) at 200,001 angles from
/// -100 to 100 rad and at the quadrant boundaries (measured 9.0e-8); sin² + cos² = 1 to 3e-7 up to
/// 1e7 rad; NaN for non-finite angles.
#[test]
fn f32_sin_cos_is_accurate() {
    use kinematics_core::scalar::sin_cos;
    let mut worst = 0.0f64;
    let mut check = |x: f32| {
        let (s, c) = sin_cos(x);
        let xd = f64::from(x);
        let e = (f64::from(s) - xd.sin())
            .abs()
            .max((f64::from(c) - xd.cos()).abs());
        worst = worst.max(e);
    };
    for k in -100_000..=100_000 {
        check(k as f32 * 1e-3);
    }
    for q in -64..=64 {
        let edge = q as f32 * std::f32::consts::FRAC_PI_4;
        for d in [-2e-7f32, -1e-7, 0.0, 1e-7, 2e-7] {
            check(edge + d);
        }
    }
    println!("f32 sin_cos: largest error {worst:.3e} over |x| <= 100 rad");
    assert!(worst < 1.2e-7, "{worst:e}");
    for x in [1e3f32, 1e4, 1e5, 1e6, 1e7, -3e6] {
        let (s, c) = sin_cos(x);
        assert!((s * s + c * c - 1.0).abs() < 3e-7, "{x}: {s} {c}");
    }
    for x in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
        let (s, c) = sin_cos(x);
        assert!(s.is_nan() && c.is_nan());
    }
}
