//! Cartesian poses and twists (SI: metres, radians, seconds), and the rotation
//! increments of the teleoperation mapping.
//!
//! A pose is CRTK's `cp` (Cartesian position): a position and an orientation. At the
//! edges (recordings, datagrams) it is written `x_mm, y_mm, z_mm, rx_deg, ry_deg, rz_deg`,
//! (rx, ry, rz) the rotation vector (axis × angle), as in the repository's `CONVENTIONS.md`.
//!
//! The rotation increment between two orientations ([`rotation_increment`]) is computed
//! so that it is **exactly** zero (bit for bit) when the two orientations are equal: the
//! teleoperation mapping relies on it for its zero-jump property on re-engagement.

use nalgebra::{Quaternion, UnitQuaternion, Vector3};
use thiserror::Error;

/// A component of a pose or twist that is not finite.
#[derive(Clone, Copy, Debug, Error, PartialEq, Eq)]
#[error("{what}: component {component} is not finite")]
pub struct NonFinite {
    /// What was being built ("pose", "twist", ...).
    pub what: &'static str,
    /// Index of the component (0..2 position or linear, 3..5 rotation or angular).
    pub component: usize,
}

/// A Cartesian pose: the position of a point and an orientation, both in one frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CartesianPose {
    /// Position, m.
    pub position_m: Vector3<f64>,
    /// Orientation (unit quaternion).
    pub orientation: UnitQuaternion<f64>,
}

impl Default for CartesianPose {
    fn default() -> Self {
        Self::identity()
    }
}

impl CartesianPose {
    /// The origin with the identity orientation.
    pub fn identity() -> Self {
        CartesianPose {
            position_m: Vector3::zeros(),
            orientation: UnitQuaternion::identity(),
        }
    }

    /// From a position (m) and a rotation vector (axis × angle, rad); refuses non-finite
    /// components.
    pub fn from_position_rotation_vector(
        position_m: [f64; 3],
        rotation_vector_rad: [f64; 3],
    ) -> Result<Self, NonFinite> {
        check_finite("pose", &position_m, &rotation_vector_rad)?;
        Ok(CartesianPose {
            position_m: Vector3::from(position_m),
            orientation: exp_rotation(&Vector3::from(rotation_vector_rad)),
        })
    }

    /// The rotation vector of the orientation (axis × angle, rad, angle in [0, π]).
    pub fn rotation_vector_rad(&self) -> Vector3<f64> {
        log_rotation(&self.orientation)
    }

    /// True when every component is finite.
    pub fn is_finite(&self) -> bool {
        self.position_m.iter().all(|v| v.is_finite())
            && self.orientation.coords.iter().all(|v| v.is_finite())
    }

    /// `[x_mm, y_mm, z_mm, rx_deg, ry_deg, rz_deg]`, the form at the edges.
    pub fn to_mm_deg(&self) -> [f64; 6] {
        let r = self.rotation_vector_rad();
        [
            self.position_m.x * 1e3,
            self.position_m.y * 1e3,
            self.position_m.z * 1e3,
            r.x.to_degrees(),
            r.y.to_degrees(),
            r.z.to_degrees(),
        ]
    }

    /// From `[x_mm, y_mm, z_mm, rx_deg, ry_deg, rz_deg]`; refuses non-finite values.
    pub fn from_mm_deg(v: [f64; 6]) -> Result<Self, NonFinite> {
        let [x, y, z, rx, ry, rz] = v;
        Self::from_position_rotation_vector(
            [x * 1e-3, y * 1e-3, z * 1e-3],
            [rx.to_radians(), ry.to_radians(), rz.to_radians()],
        )
    }
}

/// A twist `[v; ω]`: linear velocity (m/s) and angular velocity (rad/s), CRTK's `cv`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Twist {
    /// Linear velocity, m/s.
    pub linear_m_s: Vector3<f64>,
    /// Angular velocity, rad/s.
    pub angular_rad_s: Vector3<f64>,
}

impl Twist {
    /// The zero twist.
    pub fn zero() -> Self {
        Twist::default()
    }

    /// From `[vx, vy, vz, wx, wy, wz]` (m/s, rad/s); refuses non-finite components.
    pub fn from_array(v: [f64; 6]) -> Result<Self, NonFinite> {
        let [a, b, c, d, e, f] = v;
        check_finite("twist", &[a, b, c], &[d, e, f])?;
        Ok(Twist {
            linear_m_s: Vector3::new(a, b, c),
            angular_rad_s: Vector3::new(d, e, f),
        })
    }

    /// `[vx, vy, vz, wx, wy, wz]`.
    pub fn to_array(&self) -> [f64; 6] {
        let (v, w) = (self.linear_m_s, self.angular_rad_s);
        [v.x, v.y, v.z, w.x, w.y, w.z]
    }

    /// True when every component is finite.
    pub fn is_finite(&self) -> bool {
        self.to_array().iter().all(|v| v.is_finite())
    }
}

fn check_finite(what: &'static str, a: &[f64; 3], b: &[f64; 3]) -> Result<(), NonFinite> {
    match a.iter().chain(b.iter()).position(|v| !v.is_finite()) {
        Some(component) => Err(NonFinite { what, component }),
        None => Ok(()),
    }
}

/// exp of a rotation vector (axis × angle, rad); the zero vector gives the identity
/// exactly.
pub fn exp_rotation(r: &Vector3<f64>) -> UnitQuaternion<f64> {
    if r.x == 0.0 && r.y == 0.0 && r.z == 0.0 {
        UnitQuaternion::identity()
    } else {
        UnitQuaternion::from_scaled_axis(*r)
    }
}

/// The rotation vector of `q` (axis × angle, rad, angle in [0, π]); zero exactly when the
/// vector part of `q` is zero.
pub fn log_rotation(q: &UnitQuaternion<f64>) -> Vector3<f64> {
    rotation_vector_of(q.w, Vector3::new(q.i, q.j, q.k))
}

/// The rotation vector of the (unit) quaternion `(w, v)`, taking the shorter way.
fn rotation_vector_of(w: f64, v: Vector3<f64>) -> Vector3<f64> {
    let s = v.norm();
    if s == 0.0 {
        return Vector3::zeros();
    }
    // q and -q are the same rotation: take w >= 0 so that the angle is in [0, π].
    let (w, v) = if w < 0.0 { (-w, -v) } else { (w, v) };
    let angle = 2.0 * s.atan2(w);
    v * (angle / s)
}

/// The rotation increment from `from` to `to`, as a rotation vector in the fixed frame:
/// `to = exp(r) · from`, r = log(to · from⁻¹).
///
/// Exactly zero when `to == from` (bit for bit): each component of the vector part of
/// `to · from⁻¹` is written as a difference of two products that are then the same
/// floating-point numbers, e.g. `(w_f x_t − w_t x_f) − (y_t z_f − z_t y_f)`.
pub fn rotation_increment(from: &UnitQuaternion<f64>, to: &UnitQuaternion<f64>) -> Vector3<f64> {
    let (tw, tx, ty, tz) = (to.w, to.i, to.j, to.k);
    let (fw, fx, fy, fz) = (from.w, from.i, from.j, from.k);
    // to ⊗ conj(from) = (tw fw + t·f, fw t − tw f − t × f)
    let w = tw * fw + (tx * fx + ty * fy + tz * fz);
    let v = Vector3::new(
        (fw * tx - tw * fx) - (ty * fz - tz * fy),
        (fw * ty - tw * fy) - (tz * fx - tx * fz),
        (fw * tz - tw * fz) - (tx * fy - ty * fx),
    );
    rotation_vector_of(w, v)
}

/// `exp(r) · q`, renormalised; `q` itself (bit for bit) when `r` is zero.
pub fn rotate(q: &UnitQuaternion<f64>, r: &Vector3<f64>) -> UnitQuaternion<f64> {
    if r.x == 0.0 && r.y == 0.0 && r.z == 0.0 {
        *q
    } else {
        let p: Quaternion<f64> = exp_rotation(r).into_inner() * q.into_inner();
        UnitQuaternion::new_normalize(p)
    }
}

/// The angle between two orientations, rad, in [0, π].
pub fn angle_between(a: &UnitQuaternion<f64>, b: &UnitQuaternion<f64>) -> f64 {
    rotation_increment(a, b).norm()
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used)]
    use super::*;

    #[test]
    fn increment_of_equal_orientations_is_exactly_zero() {
        let q = UnitQuaternion::from_scaled_axis(Vector3::new(0.3, -1.1, 0.7));
        assert_eq!(rotation_increment(&q, &q), Vector3::zeros());
        assert_eq!(rotate(&q, &Vector3::zeros()), q);
    }

    #[test]
    fn increment_round_trips() {
        let a = UnitQuaternion::from_scaled_axis(Vector3::new(0.3, -1.1, 0.7));
        let r = Vector3::new(0.01, 0.2, -0.05);
        let b = rotate(&a, &r);
        assert!((rotation_increment(&a, &b) - r).norm() < 1e-14);
    }

    #[test]
    fn mm_deg_round_trip() {
        let p = CartesianPose::from_mm_deg([1.0, -2.0, 160.0, 10.0, 0.0, -5.0]).unwrap();
        let back = p.to_mm_deg();
        for (a, b) in back.iter().zip([1.0, -2.0, 160.0, 10.0, 0.0, -5.0]) {
            assert!((a - b).abs() < 1e-12, "{back:?}");
        }
    }
}
