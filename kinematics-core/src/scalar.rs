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
    /// (sin, cos) of an angle in radians (NaN for a non-finite angle).
    fn hw_sin_cos(self) -> (Self, Self);
}

impl HwMath for f64 {
    #[inline]
    fn hw_sqrt(self) -> f64 {
        nalgebra::ComplexField::sqrt(self)
    }
    #[inline]
    fn hw_sin_cos(self) -> (f64, f64) {
        nalgebra::ComplexField::sin_cos(self)
    }
}

impl HwMath for f32 {
    fn hw_sin_cos(self) -> (f32, f32) {
        sin_cos_f32(self)
    }
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

/// sin and cos in single precision without double-precision arithmetic. libm's `sinf` and
/// `cosf` reduce and evaluate in f64, which the Cortex-M4 computes in software (about
/// 1,250 instructions each, and 4.6 KB of code with the soft-float routines); here the
/// angle is reduced by π/2 with a three-part constant (Cody and Waite; the products are
/// exact for |x| < 4,096·π/2) and the sine and cosine on [-π/4, π/4] come from the
/// minimax polynomials of Cephes' `sinf`/`cosf` (Moshier). Error against the f64 functions:
/// 9.0e-8 at most for |x| ≤ 100 rad (under 1 ulp at 1; `tests/pose.rs`); beyond
/// 6,000 rad the reduction loses accuracy but the pair stays a sine and cosine of one
/// angle to rounding (sin² + cos² = 1). About 40 instructions on the Cortex-M4.
fn sin_cos_f32(x: f32) -> (f32, f32) {
    const FRAC_2_PI: f32 = core::f32::consts::FRAC_2_PI;
    // π/2 = P1 + P2 + P3, P1 and P2 with few significant bits.
    const P1: f32 = 1.570_312_5;
    const P2: f32 = 4.837_513e-4;
    const P3: f32 = 7.549_79e-8;
    if !x.is_finite() {
        return (f32::NAN, f32::NAN);
    }
    // Nearest multiple of π/2 (`as` saturates for huge |x|: the pair stays consistent).
    let y = x * FRAC_2_PI;
    let j = if y >= 0.0 {
        (y + 0.5) as i32
    } else {
        (y - 0.5) as i32
    };
    let jf = j as f32;
    let r = ((x - jf * P1) - jf * P2) - jf * P3;
    let z = r * r;
    let s = r + r * z * ((-1.951_529_6e-4 * z + 8.332_161e-3) * z - 1.666_665_5e-1);
    let c = 1.0 - 0.5 * z + z * z * ((2.443_315_7e-5 * z - 1.388_731_6e-3) * z + 4.166_664_6e-2);
    match j & 3 {
        0 => (s, c),
        1 => (c, -s),
        2 => (-s, -c),
        _ => (-c, s),
    }
}

/// sin and cos at hardware speed ([`HwMath::hw_sin_cos`]).
#[inline]
pub fn sin_cos<T: Real>(x: T) -> (T, T) {
    x.hw_sin_cos()
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

/// The larger of `acc` and `x` by one comparison, inlined (`f32::max` is a call to
/// libm's `fmaxf` on the Cortex-M4, about 12 instructions). As `fmaxf` in a running
/// maximum: a NaN `x` leaves `acc`.
#[inline]
pub fn larger<T: Real>(acc: T, x: T) -> T {
    if x > acc {
        x
    } else {
        acc
    }
}

/// The smaller of `acc` and `x` by one comparison (see [`larger`]).
#[inline]
pub fn smaller<T: Real>(acc: T, x: T) -> T {
    if x < acc {
        x
    } else {
        acc
    }
}

// 3-vector arithmetic written out component by component. nalgebra's operators are loops
// over the components; at the firmware's opt-level "s" LLVM does not unroll them, and a
// three-iteration loop costs about four times the arithmetic on the Cortex-M4 (measured
// in `firmware/cortex-m/on-target`). The control path's hot functions use these instead.

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

/// Best-effort conversion to `f64`, for error messages and counts (NaN when the scalar
/// has no `f64` value).
#[inline]
pub(crate) fn to_f64<T: Real>(v: T) -> f64 {
    // `RealField` offers no direct conversion; `to_subset` exists for f64 supersets.
    v.to_subset().unwrap_or(f64::NAN)
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

    /// `larger` and `smaller` agree with `f32::max` / `f32::min` (libm's fmaxf, fminf) on
    /// numbers and infinities, and a NaN candidate leaves the running value.
    #[test]
    fn larger_and_smaller_are_max_and_min() {
        let xs = [
            -f32::INFINITY,
            -2.5,
            -0.0,
            0.0,
            1e-30,
            3.0,
            f32::MAX,
            f32::INFINITY,
        ];
        for a in xs {
            for b in xs {
                assert_eq!(larger(a, b), a.max(b), "{a} {b}");
                assert_eq!(smaller(a, b), a.min(b), "{a} {b}");
            }
            assert_eq!(larger(a, f32::NAN), a);
            assert_eq!(smaller(a, f32::NAN), a);
        }
    }
}
