//! Platform pose x = (t, R): t the position of o_p in {0}, R = wRp.

use crate::scalar::{add3, axpy3, cross3, dot3, lit, Real};
use nalgebra::{Matrix3, Rotation3, Vector3};

/// A platform pose. At the edges it is written `x, y, z, rx, ry, rz` with (rx, ry, rz) the
/// rotation vector (axis × angle), R = exp(\[r\]×).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pose<T: Real> {
    /// Position of the platform centre o_p in {0} (m).
    pub t: Vector3<T>,
    /// Orientation wRp.
    pub r: Rotation3<T>,
}

/// A pose component that is not finite.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct NonFinitePose {
    /// Which component: 0..2 position x, y, z; 3..5 rotation vector.
    pub component: u8,
}

impl<T: Real> Pose<T> {
    /// Pose from a position and a rotation vector (axis × angle, rad). Refuses non-finite
    /// components.
    pub fn from_position_rotation_vector(
        t: Vector3<T>,
        rotvec: Vector3<T>,
    ) -> Result<Self, NonFinitePose> {
        for (k, v) in t.iter().chain(rotvec.iter()).enumerate() {
            if !v.is_finite() {
                return Err(NonFinitePose { component: k as u8 });
            }
        }
        // Rodrigues' formula (exp_so3), re-orthonormalised: nalgebra's from_scaled_axis
        // calls libm's sin and cos, software double precision on the Cortex-M4.
        let e = exp_so3(&rotvec);
        let c0 = Vector3::new(e.m11, e.m21, e.m31);
        let c1 = Vector3::new(e.m12, e.m22, e.m32);
        Ok(Pose {
            t,
            r: Rotation3::from_matrix_unchecked(orthonormal_frame(&c0, &c1)),
        })
    }

    /// The central configuration at height `hc`: platform parallel to the base, right above
    /// its centre (thesis section 8.2).
    pub fn central(hc: T) -> Self {
        Pose {
            t: Vector3::new(T::zero(), T::zero(), hc),
            r: Rotation3::identity(),
        }
    }

    /// The rotation vector (axis × angle, rad, angle in [0, π]).
    pub fn rotation_vector(&self) -> Vector3<T> {
        rotation_vector(&self.r)
    }

    /// True when every component is finite.
    pub fn is_finite(&self) -> bool {
        // x·0 is 0 for a finite x and NaN for an infinity or a NaN (no compiler may fold
        // it), so the sum of the twelve products is 0 exactly when all twelve are finite:
        // one test where a test per component costs four instructions each on the
        // Cortex-M4 (every inverse kinematics checks its pose).
        let z = T::zero();
        let [t] = &self.t.data.0;
        let [c0, c1, c2] = &self.r.matrix().data.0;
        let acc = t
            .iter()
            .chain(c0.iter())
            .chain(c1.iter())
            .chain(c2.iter())
            .fold(z, |acc, x| acc + *x * z);
        acc == z
    }

    /// This pose moved by a small twist displacement `[dv; dω]`: t + dv, exp(\[dω\]×) R.
    ///
    /// The product is re-orthonormalised: small rotations compose thousands of times per
    /// second in the supervisor and the FK, and in f32 the rounding would otherwise let the
    /// matrix drift away from a rotation (about 2.4e-8 per tick measured on the M4).
    pub fn displaced(&self, dv: &Vector3<T>, dw: &Vector3<T>) -> Self {
        let e = exp_so3(dw);
        let r = self.r.matrix();
        // The first two columns of exp([dω]×)·R, written out (the third follows from them).
        let col = |x: T, y: T, z: T| {
            Vector3::new(
                e.m11 * x + e.m12 * y + e.m13 * z,
                e.m21 * x + e.m22 * y + e.m23 * z,
                e.m31 * x + e.m32 * y + e.m33 * z,
            )
        };
        let c0 = col(r.m11, r.m21, r.m31);
        let c1 = col(r.m12, r.m22, r.m32);
        Pose {
            t: add3(&self.t, dv),
            r: Rotation3::from_matrix_unchecked(orthonormal_frame(&c0, &c1)),
        }
    }

    /// Converts the scalar type (e.g. f64 reference poses to f32 for the MCU), through f64.
    pub fn cast<U: Real>(&self) -> Pose<U> {
        let conv = |x: &T| crate::scalar::lit::<U>(crate::scalar::to_f64(*x));
        Pose {
            t: self.t.map(|x| conv(&x)),
            r: Rotation3::from_matrix_unchecked(self.r.matrix().map(|x| conv(&x))),
        }
    }
}

/// Rotation angle of `r` in [0, π], accurate near zero (atan2 of the skew and symmetric
/// parts rather than acos of the trace).
pub fn rotation_angle<T: Real>(r: &Rotation3<T>) -> T {
    let (v, c) = skew_and_cos(r);
    (crate::scalar::norm3(&v) / crate::scalar::lit(2.0)).atan2(c)
}

fn skew_and_cos<T: Real>(r: &Rotation3<T>) -> (Vector3<T>, T) {
    let m = r.matrix();
    let v = Vector3::new(m.m32 - m.m23, m.m13 - m.m31, m.m21 - m.m12);
    let half = crate::scalar::lit::<T>(0.5);
    (v, (m.m11 + m.m22 + m.m33 - T::one()) * half)
}

/// The rotation vector of `r`: v/2 · θ/sin θ from the skew part, exact to rounding for
/// small angles; near π (where the skew part vanishes) nalgebra's eigen-axis extraction.
pub fn rotation_vector<T: Real>(r: &Rotation3<T>) -> Vector3<T> {
    let (v, c) = skew_and_cos(r);
    let s = crate::scalar::norm3(&v) / crate::scalar::lit(2.0);
    let theta = s.atan2(c);
    if c > crate::scalar::lit(-0.5) {
        // θ < 120 deg: θ / sin θ is well conditioned (→ 1 as θ → 0).
        let k = if s > T::zero() { theta / s } else { T::one() };
        v * (k * crate::scalar::lit(0.5))
    } else {
        r.scaled_axis()
    }
}

/// exp(\[w\]×) by Rodrigues' formula, R = I + a \[w\]× + b \[w\]×² with a = sin θ / θ and
/// b = (1 - cos θ) / θ², θ = |w|. For θ < 0.1 rad (every control tick, every braking
/// distance) a and b come from their Taylor series to θ⁸ (truncation below 3e-18, under
/// f64 rounding), which avoids the trigonometric calls: libm's `sinf`/`cosf` compute in
/// double precision, in software on the Cortex-M4 (~1,200 instructions each), and
/// nalgebra's `from_scaled_axis` costs ~2,500.
pub fn exp_so3<T: Real>(w: &Vector3<T>) -> Matrix3<T> {
    let t2 = w.x * w.x + w.y * w.y + w.z * w.z;
    let (a, b) = if t2 < lit(1e-2) {
        // Horner form of 1 - θ²/3! + θ⁴/5! - θ⁶/7! + θ⁸/9! and 1/2! - θ²/4! + θ⁴/6! - ...
        let a = T::one()
            - t2 / lit(6.0)
                * (T::one()
                    - t2 / lit(20.0) * (T::one() - t2 / lit(42.0) * (T::one() - t2 / lit(72.0))));
        let b = lit::<T>(0.5)
            * (T::one()
                - t2 / lit(12.0)
                    * (T::one()
                        - t2 / lit(30.0)
                            * (T::one() - t2 / lit(56.0) * (T::one() - t2 / lit(90.0)))));
        (a, b)
    } else {
        let t = crate::scalar::sqrt(t2);
        let (sin, cos) = crate::scalar::sin_cos(t);
        (sin / t, (T::one() - cos) / t2)
    };
    // [w]×² = w wᵀ - θ² I.
    let (x, y, z) = (w.x, w.y, w.z);
    Matrix3::new(
        T::one() + b * (x * x - t2),
        b * x * y - a * z,
        b * x * z + a * y,
        b * x * y + a * z,
        T::one() + b * (y * y - t2),
        b * y * z - a * x,
        b * x * z - a * y,
        b * y * z + a * x,
        T::one() + b * (z * z - t2),
    )
}

/// The nearest rotation to a matrix that is one to rounding, from its first two columns
/// (Gram-Schmidt; the third column their cross product): keeps composed rotations
/// orthonormal.
fn orthonormal_frame<T: Real>(c0: &Vector3<T>, c1: &Vector3<T>) -> Matrix3<T> {
    let n0 = crate::scalar::norm3(c0);
    let x = Vector3::new(c0.x / n0, c0.y / n0, c0.z / n0);
    let y = axpy3(c1, &x, -dot3(&x, c1));
    let n1 = crate::scalar::norm3(&y);
    let y = Vector3::new(y.x / n1, y.y / n1, y.z / n1);
    let z = cross3(&x, &y);
    Matrix3::new(x.x, y.x, z.x, x.y, y.y, z.y, x.z, y.z, z.z)
}
