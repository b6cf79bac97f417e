//! Shared test helpers: pose strategies, pose distances and the task grid.
#![allow(dead_code)]

use kinematics_core::{Pose, Real};
use nalgebra::{Rotation3, Vector3};
use proptest::prelude::*;

pub const DEG: f64 = core::f64::consts::PI / 180.0;

/// A pose in and around the task box centred at [0, 0, hc] (±30 mm in x and y, ±15 mm in
/// z; rotation vector components up to ±0.25 rad, i.e. tilts up to about 25 deg).
pub fn pose_near_box(hc: f64) -> impl Strategy<Value = Pose<f64>> {
    (
        -0.03..0.03f64,
        -0.03..0.03f64,
        -0.015..0.015f64,
        -0.25..0.25f64,
        -0.25..0.25f64,
        -0.25..0.25f64,
    )
        .prop_map(move |(x, y, z, a, b, c)| Pose {
            t: Vector3::new(x, y, hc + z),
            r: Rotation3::from_scaled_axis(Vector3::new(a, b, c)),
        })
}

/// A warm-start offset: up to ±0.5 mm and ±0.5 deg about each axis, twenty times what the
/// platform moves in one 1 ms control tick at the 25 mm/s task maximum.
pub fn perturbation() -> impl Strategy<Value = (Vector3<f64>, Vector3<f64>)> {
    (
        -0.0005..0.0005f64,
        -0.0005..0.0005f64,
        -0.0005..0.0005f64,
        -0.0087..0.0087f64,
        -0.0087..0.0087f64,
        -0.0087..0.0087f64,
    )
        .prop_map(|(x, y, z, a, b, c)| (Vector3::new(x, y, z), Vector3::new(a, b, c)))
}

/// Position error (m) and rotation error (rad) between two poses.
pub fn pose_error<T: Real>(a: &Pose<T>, b: &Pose<T>) -> (T, T) {
    (
        (a.t - b.t).norm(),
        kinematics_core::pose::rotation_angle(&(a.r.inverse() * b.r)),
    )
}

/// The thesis's task (CONVENTIONS.md): every point of a 40 x 40 x 20 mm box centred at
/// [0, 0, hc], with the platform parallel to the base and rotated +20 deg about [1,1,0].
pub fn task_grid(hc: f64, n_xy: usize, n_z: usize) -> Vec<Pose<f64>> {
    let axis = Vector3::new(1.0, 1.0, 0.0).normalize();
    let orientations = [Vector3::zeros(), axis * 20.0 * DEG];
    let mut poses = Vec::new();
    let lin = |n: usize, half: f64, k: usize| -half + 2.0 * half * k as f64 / (n - 1) as f64;
    for rv in orientations {
        for i in 0..n_xy {
            for j in 0..n_xy {
                for k in 0..n_z {
                    poses.push(Pose {
                        t: Vector3::new(
                            lin(n_xy, 0.02, i),
                            lin(n_xy, 0.02, j),
                            hc + lin(n_z, 0.01, k),
                        ),
                        r: Rotation3::from_scaled_axis(rv),
                    });
                }
            }
        }
    }
    poses
}
