//! The scalar type: `f32` on the MCU, `f64` on the host.

use nalgebra::RealField;

/// A real scalar the kinematics can run on. Implemented for every nalgebra `RealField`
/// that is `Copy` (in practice `f32` and `f64`).
pub trait Real: RealField + Copy {}
impl<T: RealField + Copy> Real for T {}

/// Converts an `f64` literal into the scalar type.
#[inline]
pub fn lit<T: Real>(x: f64) -> T {
    nalgebra::convert(x)
}

/// Wraps an angle to (-π, π].
#[inline]
pub fn wrap_angle<T: Real>(a: T) -> T {
    let two_pi = T::two_pi();
    let pi = T::pi();
    let mut w = a - two_pi * ((a + pi) / two_pi).floor();
    // `w` is in [-π, π); the convention wants (-π, π].
    if w <= -pi {
        w += two_pi;
    }
    w
}

/// True when every element of the slice is finite.
#[inline]
pub fn all_finite<T: Real>(xs: &[T]) -> bool {
    xs.iter().all(|x| x.is_finite())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wrap_angle_lands_in_half_open_interval() {
        let pi = core::f64::consts::PI;
        assert_eq!(wrap_angle(pi), pi);
        assert_eq!(wrap_angle(-pi), pi);
        assert!((wrap_angle(3.0 * pi / 2.0) + pi / 2.0).abs() < 1e-15);
        assert!((wrap_angle(-7.0) - (-7.0 + 2.0 * pi)).abs() < 1e-15);
        assert!(wrap_angle(0.25f32) == 0.25);
    }
}
