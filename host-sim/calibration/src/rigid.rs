//! Rigid transforms of the measurement chain: the tracker sees the marker at
//! `tracker_to_base · platform_pose · marker_to_platform`.

use kinematics_core::Pose;
use nalgebra::{Matrix3, Rotation3, Vector3};

/// A rigid transform x ↦ R x + t (a frame's pose in another).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rigid {
    /// Rotation.
    pub r: Rotation3<f64>,
    /// Translation, m.
    pub t: Vector3<f64>,
}

impl Rigid {
    /// The identity.
    pub fn identity() -> Self {
        Rigid {
            r: Rotation3::identity(),
            t: Vector3::zeros(),
        }
    }

    /// From a translation (m) and a rotation vector (rad).
    pub fn new(t: Vector3<f64>, rotation_vector: Vector3<f64>) -> Self {
        Rigid {
            r: Rotation3::from_scaled_axis(rotation_vector),
            t,
        }
    }

    /// From the edge form x_mm, y_mm, z_mm, rx_deg, ry_deg, rz_deg (rotation vector).
    pub fn from_mm_deg(v: [f64; 6]) -> Self {
        let [x, y, z, a, b, c] = v;
        Rigid::new(
            Vector3::new(x, y, z) * 1e-3,
            Vector3::new(a, b, c) * (std::f64::consts::PI / 180.0),
        )
    }

    /// The platform pose as a transform ({p} in {0}).
    pub fn from_pose(p: &Pose<f64>) -> Self {
        Rigid { r: p.r, t: p.t }
    }

    /// As a platform pose.
    pub fn to_pose(self) -> Pose<f64> {
        Pose {
            t: self.t,
            r: self.r,
        }
    }

    /// self ∘ other.
    pub fn then(&self, other: &Rigid) -> Rigid {
        Rigid {
            r: self.r * other.r,
            t: self.t + self.r * other.t,
        }
    }

    /// The inverse transform.
    pub fn inverse(&self) -> Rigid {
        let ri = self.r.inverse();
        Rigid {
            r: ri,
            t: -(ri * self.t),
        }
    }

    /// The rotation vector (rad).
    pub fn rotation_vector(&self) -> Vector3<f64> {
        rotation_vector(&self.r)
    }
}

/// The rotation vector (axis × angle, rad) of a rotation, accurate for small angles
/// (`kinematics_core::pose::rotation_vector`; nalgebra's goes through an arc cosine, which
/// loses half the digits near zero).
pub fn rotation_vector(r: &Rotation3<f64>) -> Vector3<f64> {
    kinematics_core::pose::rotation_vector(r)
}

/// The angle of a rotation, rad, accurate for small angles.
pub fn angle(r: &Rotation3<f64>) -> f64 {
    kinematics_core::pose::rotation_angle(r)
}

/// The rigid transform that best maps the points `from` onto `to` in the least-squares
/// sense (Kabsch/Horn, by the SVD of the cross-covariance); None with fewer than three
/// points or when they are collinear.
pub fn fit_points(from: &[Vector3<f64>], to: &[Vector3<f64>]) -> Option<Rigid> {
    let n = from.len().min(to.len());
    if n < 3 {
        return None;
    }
    let mean = |v: &[Vector3<f64>]| v.iter().take(n).sum::<Vector3<f64>>() / n as f64;
    let (ca, cb) = (mean(from), mean(to));
    let mut h = Matrix3::zeros();
    for (a, b) in from.iter().zip(to.iter()).take(n) {
        h += (a - ca) * (b - cb).transpose();
    }
    let svd = h.svd(true, true);
    let (u, vt) = (svd.u?, svd.v_t?);
    let s = &svd.singular_values;
    if s[1].is_nan() || s[1] <= 1e-12 * s[0].max(1e-300) {
        return None;
    }
    let mut d = Matrix3::identity();
    if (vt.transpose() * u.transpose()).determinant() < 0.0 {
        d[(2, 2)] = -1.0;
    }
    let r = Rotation3::from_matrix_unchecked(vt.transpose() * d * u.transpose());
    Some(Rigid { r, t: cb - r * ca })
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    /// Kabsch recovers a transform exactly from noise-free points, and composition with
    /// the inverse is the identity.
    #[test]
    fn fit_points_recovers_a_transform() {
        let t = Rigid::new(Vector3::new(0.3, -1.2, 0.8), Vector3::new(0.4, -1.1, 2.0));
        let pts: Vec<_> = (0..7)
            .map(|k| {
                Vector3::new(
                    k as f64 * 0.01,
                    (k * k) as f64 * 0.003,
                    (k % 3) as f64 * 0.02,
                )
            })
            .collect();
        let moved: Vec<_> = pts.iter().map(|p| t.r * p + t.t).collect();
        let f = fit_points(&pts, &moved).unwrap();
        assert!((f.t - t.t).norm() < 1e-12);
        assert!((f.r.inverse() * t.r).angle() < 1e-12);
        let id = t.then(&t.inverse());
        assert!(id.t.norm() < 1e-14 && angle(&id.r) < 1e-14);
    }
}
