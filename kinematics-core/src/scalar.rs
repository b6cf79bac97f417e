//! The scalar type: `f32` on the MCU, `f64` on the host.

use nalgebra::{RealField, Vector3};

/// A real scalar the kinematics can run on: `f32` or `f64` (nalgebra's `RealField`, plus
/// the few operations the control path needs at hardware speed, [`HwMath`]).
pub trait Real: RealField + Copy + HwMath {}
impl<T: RealField + Copy + HwMath> Real for T {}

/// Operations that must use the FPU instruction where there is one. On the Cortex-M4F,
/// `libm::sqrtf` (what nalgebra's `f32::sqrt` calls without `std`) is a software routine
/// of about 80 instructions; `VSQRT.F32` is one instruction with the same correctly
/// rounded IEEE 754 result (NaN for a negative input). The control tick takes about 200
/// square roots.
pub trait HwMath: Sized {
    /// The correctly rounded square root (NaN below zero).
    fn hw_sqrt(self) -> Self;
}

impl HwMath for f64 {
    #[inline]
    fn hw_sqrt(self) -> f64 {
        nalgebra::ComplexField::sqrt(self)
    }
}

impl HwMath for f32 {
    #[inline]
    fn hw_sqrt(self) -> f32 {
        #[cfg(all(target_arch = "arm", target_abi = "eabihf"))]
        {
            fpu::sqrt(self)
        }
        #[cfg(not(all(target_arch = "arm", target_abi = "eabihf")))]
        {
            nalgebra::ComplexField::sqrt(self)
        }
    }
}

/// `VSQRT.F32` on the hard-float ARM targets (the FPv4-SP of the Cortex-M4F).
#[cfg(all(target_arch = "arm", target_abi = "eabihf"))]
mod fpu {
    // A leaf function in the AAPCS-VFP calling convention: the argument and the result
    // are in s0. (Rust's `asm!` register class for s-registers needs a target feature
    // that stable Rust does not expose for this target; a global function does not.)
    core::arch::global_asm!(
        ".section .text.kinematics_core_vsqrt_f32,\"ax\",%progbits",
        ".global kinematics_core_vsqrt_f32",
        ".type kinematics_core_vsqrt_f32,%function",
        ".thumb_func",
        "kinematics_core_vsqrt_f32:",
        ".fpu fpv4-sp-d16",
        "vsqrt.f32 s0, s0",
        "bx lr",
        ".size kinematics_core_vsqrt_f32, . - kinematics_core_vsqrt_f32",
    );
    extern "C" {
        fn kinematics_core_vsqrt_f32(x: f32) -> f32;
    }
    #[inline]
    pub(super) fn sqrt(x: f32) -> f32 {
        // SAFETY: the function above reads s0 and writes s0 only (a leaf, no memory, no
        // stack), exactly the AAPCS-VFP contract of `extern "C" fn(f32) -> f32`.
        unsafe { kinematics_core_vsqrt_f32(x) }
    }
}

/// Square root at hardware speed ([`HwMath::hw_sqrt`]).
#[inline]
pub fn sqrt<T: Real>(x: T) -> T {
    x.hw_sqrt()
}

// 3-vector arithmetic written out component by component. nalgebra's operators are loops
// over the components; at the firmware's opt-level "s" LLVM does not unroll them, and a
// three-iteration loop costs about four times the arithmetic on the Cortex-M4 (measured
// in `firmware/qemu`). The control path's hot functions use these instead.

/// a + b.
#[inline]
pub fn add3<T: Real>(a: &Vector3<T>, b: &Vector3<T>) -> Vector3<T> {
    Vector3::new(a.x + b.x, a.y + b.y, a.z + b.z)
}

/// a - b.
#[inline]
pub fn sub3<T: Real>(a: &Vector3<T>, b: &Vector3<T>) -> Vector3<T> {
    Vector3::new(a.x - b.x, a.y - b.y, a.z - b.z)
}

/// a·k.
#[inline]
pub fn scale3<T: Real>(a: &Vector3<T>, k: T) -> Vector3<T> {
    Vector3::new(a.x * k, a.y * k, a.z * k)
}

/// a + b·k.
#[inline]
pub fn axpy3<T: Real>(a: &Vector3<T>, b: &Vector3<T>, k: T) -> Vector3<T> {
    Vector3::new(a.x + b.x * k, a.y + b.y * k, a.z + b.z * k)
}

/// a·b.
#[inline]
pub fn dot3<T: Real>(a: &Vector3<T>, b: &Vector3<T>) -> T {
    a.x * b.x + a.y * b.y + a.z * b.z
}

/// a × b.
#[inline]
pub fn cross3<T: Real>(a: &Vector3<T>, b: &Vector3<T>) -> Vector3<T> {
    Vector3::new(
        a.y * b.z - a.z * b.y,
        a.z * b.x - a.x * b.z,
        a.x * b.y - a.y * b.x,
    )
}

/// Euclidean norm of a 3-vector at hardware speed.
#[inline]
pub fn norm3<T: Real>(v: &Vector3<T>) -> T {
    sqrt(v.x * v.x + v.y * v.y + v.z * v.z)
}

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
    if a > -pi && a <= pi {
        // Already in range (residuals and rates, nearly always): no floor, which is a
        // libm call on the Cortex-M4.
        return a;
    }
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
