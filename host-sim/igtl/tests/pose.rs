//! Wire poses (mm, float32) against SI poses, and the registration.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use common::proptest_config;
use igtl::content::{PositionContent, PositionOrientation, TransformContent};
use igtl::pose::{
    pose_from_transform, position_from_pose, target_from_position, transform_from_pose, PoseError,
    Registration, RegistrationError,
};
use igtl::PoseSi;
use kinematics_core::pose::Pose;
use nalgebra::{Rotation3, Vector3};
use proptest::prelude::*;

fn pose() -> impl Strategy<Value = PoseSi> {
    (
        prop::array::uniform3(-1.0f64..1.0),
        prop::array::uniform3(-3.0f64..3.0),
    )
        .prop_map(|(t, w)| Pose {
            t: Vector3::from(t),
            r: Rotation3::from_scaled_axis(Vector3::from(w)),
        })
}

/// The angle of the rotation between `a` and `b`, accurate near zero.
fn angle_between(a: &Rotation3<f64>, b: &Rotation3<f64>) -> f64 {
    kinematics_core::pose::rotation_angle(&(a.inverse() * b))
}

proptest! {
    #![proptest_config(proptest_config(512))]

    /// SI -> TRANSFORM (float32 mm) -> SI loses only float32 rounding: |t| <= 1 m is
    /// 1000 mm, float32 keeps 2^-24 relative, so 1000 * 2^-24 mm ~ 6e-8 m; each rotation
    /// entry is off by <= 2^-24, which moves the nearest rotation by well under 1e-6 rad.
    #[test]
    fn transform_round_trip_is_float32_exact(p in pose()) {
        let back = pose_from_transform(&transform_from_pose(&p)).unwrap();
        prop_assert!((back.t - p.t).norm() < 1e-7, "position off by {:e} m", (back.t - p.t).norm());
        let err = angle_between(&back.r, &p.r);
        prop_assert!(err < 1e-6, "angle off by {:e} rad", err);
    }

    /// The same through the 28-byte POSITION (quaternion with W >= 0).
    #[test]
    fn position_round_trip_is_float32_exact(p in pose()) {
        let c = position_from_pose(&p);
        let PositionOrientation::Quaternion(q) = c.orientation else { panic!("28-byte form expected") };
        prop_assert!(q[3] >= 0.0);
        let (t, r) = target_from_position(&c).unwrap();
        prop_assert!((t - p.t).norm() < 1e-7);
        let err = angle_between(&r.unwrap(), &p.r);
        prop_assert!(err < 1e-6, "angle off by {:e} rad", err);
    }

    /// The 24-byte POSITION (W left out, W >= 0 implied) gives the same rotation as the
    /// 28-byte one.
    #[test]
    fn position_quaternion3_equals_quaternion(p in pose()) {
        let c = position_from_pose(&p);
        let PositionOrientation::Quaternion([x, y, z, _]) = c.orientation else { panic!() };
        let c3 = PositionContent { orientation: PositionOrientation::Quaternion3([x, y, z]), ..c };
        let (_, r3) = target_from_position(&c3).unwrap();
        let (_, r4) = target_from_position(&c).unwrap();
        // Near W = 0 the recomputed W loses precision: sqrt of a float32 rounding.
        let err = angle_between(&r3.unwrap(), &r4.unwrap());
        prop_assert!(err < 1e-3, "angle off by {:e} rad", err);
    }

    /// The registration applied to a target and inverted on the way back gives the client's
    /// pose again (to f64 rounding): "applied both ways".
    #[test]
    fn registration_is_inverted_on_the_way_back(reg in pose(), p in pose()) {
        let r = Registration::from_pose(reg);
        let back = r.pose_to_client(&r.pose_to_base(&p));
        prop_assert!((back.t - p.t).norm() < 1e-12);
        let err = angle_between(&back.r, &p.r);
        prop_assert!(err < 1e-12, "angle off by {:e} rad", err);
    }

    /// A matrix scaled by more than the tolerance is refused, never taken as a pose.
    #[test]
    fn scaled_matrices_are_refused(p in pose(), scale in prop_oneof![0.5f32..0.999, 1.001f32..2.0]) {
        let mut c = transform_from_pose(&p);
        for row in &mut c.rotation { for v in row { *v *= scale; } }
        let refused = matches!(pose_from_transform(&c), Err(PoseError::NotRotation { .. }));
        prop_assert!(refused);
    }
}

#[test]
fn reflections_and_non_finite_numbers_are_refused() {
    let mirror = TransformContent {
        rotation: [[-1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
        translation_mm: [0.0; 3],
    };
    assert!(matches!(
        pose_from_transform(&mirror),
        Err(PoseError::Reflection { .. })
    ));
    let nan = TransformContent {
        translation_mm: [f32::NAN, 0.0, 0.0],
        ..mirror
    };
    assert!(matches!(
        pose_from_transform(&nan),
        Err(PoseError::NonFinite { .. })
    ));
    let inf_q = PositionContent {
        position_mm: [0.0; 3],
        orientation: PositionOrientation::Quaternion([f32::INFINITY, 0.0, 0.0, 1.0]),
    };
    assert!(matches!(
        target_from_position(&inf_q),
        Err(PoseError::NonFinite { .. })
    ));
}

#[test]
fn quaternions_must_have_unit_norm() {
    let q = |o| PositionContent {
        position_mm: [1.0, 2.0, 3.0],
        orientation: o,
    };
    assert!(matches!(
        target_from_position(&q(PositionOrientation::Quaternion([0.0, 0.0, 0.0, 0.9]))),
        Err(PoseError::NotUnitQuaternion { .. })
    ));
    assert!(matches!(
        target_from_position(&q(PositionOrientation::Quaternion3([0.9, 0.9, 0.0]))),
        Err(PoseError::NotUnitQuaternion { .. })
    ));
    // Position only: millimetres to metres, no orientation.
    let (t, r) = target_from_position(&q(PositionOrientation::None)).unwrap();
    assert_eq!(t, Vector3::new(0.001, 0.002, 0.003));
    assert!(r.is_none());
}

#[test]
fn registration_from_numbers_and_toml_with_translation_in_mm() {
    // A 90 deg turn about z and an offset of -160 mm in z.
    let numbers = "0,-1,0,10  1,0,0,-20  0,0,1,-160  0,0,0,1";
    let r = Registration::parse_numbers_mm(numbers).unwrap();
    let p = r.point_to_base(&Vector3::new(0.001, 0.0, 0.0));
    assert!((p - Vector3::new(0.010, -0.019, -0.160)).norm() < 1e-15);

    let toml =
        "image_to_base_mm = [[0, -1, 0, 10], [1, 0, 0, -20], [0, 0, 1, -160], [0, 0, 0, 1]]\n";
    let from_file = Registration::from_toml_str(toml, "<test>").unwrap();
    assert_eq!(from_file, r);

    assert!(matches!(
        Registration::parse_numbers_mm("1 0 0 0 0 1 0 0 0 0 1 0"),
        Err(RegistrationError::Count(12))
    ));
    assert!(matches!(
        Registration::parse_numbers_mm("1 0 0 0 0 1 0 0 0 0 1 0 0 0 1 1"),
        Err(RegistrationError::LastRow(_))
    ));
    assert!(matches!(
        Registration::parse_numbers_mm("2 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1"),
        Err(RegistrationError::NotRigid(_))
    ));
    assert!(matches!(
        Registration::parse_numbers_mm("1 0 0 0 0 1 0 0 0 0 1 zero 0 0 0 1"),
        Err(RegistrationError::Number { index: 11, .. })
    ));
    assert!(matches!(
        Registration::from_toml_str("image_to_base = []", "<test>"),
        Err(RegistrationError::Toml { .. })
    ));
}
